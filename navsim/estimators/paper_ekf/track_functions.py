"""lambda(phi), h(phi) of a track for the seed-003 filter (:class:`TrackFunctions`).

Seed 003 writes the track as longitude and height functions of latitude (its eq. (6) and
Appendix 2 need lambda, lambda', lambda'', h, h' at the filter's latitude). Polynomial
tracks are used exactly, piecewise polynomials of degree <= 3 piece by piece, any other
track by local quintic Hermite interpolation in latitude (value, slope and curvature
matched at nodes every ``node_step_m``). All functions are complex-safe (the filter takes
phi-derivatives by the complex step, Martins et al. 2003).
"""

from __future__ import annotations

import bisect
import math
from typing import Any, Callable, Sequence

import numpy as np
from numpy.polynomial import Polynomial

from ...errors import ConfigError

__all__ = ["TrackFunctions"]


class TrackFunctions:
    """lambda(phi), h(phi) and derivatives as fast scalar (complex-safe) and array functions.

    Built from a :class:`~navsim.track.PolynomialTrack` (exact), a
    :class:`~navsim.track.PiecewisePolynomialTrack` of degree <= 3 (exact, piece by piece),
    or any other track (e.g. a :class:`~navsim.track.SplineTrack`) by *local* quintic
    Hermite interpolation in latitude: at nodes every ``node_step_m`` of arc length the
    track's exact value, slope and curvature in phi (from ``track.geodetic(s)`` and its
    s-derivatives, ``lambda' = lon_s / lat_s``, ``lambda'' = (lon_ss lat_s - lon_s lat_ss) /
    lat_s^3``, the same for h) are matched, so lambda(phi) is C^2 and its second
    derivative - which enters the accelerometer observer as the centripetal term
    ``k_phi V_Y^2 / (r + h)`` - is accurate to O(step^4). A least-squares fit
    (:func:`navsim.track.fit_polynomial_track`) is not used for this: on the bundled
    mountain railway a cubic fit within 0.1 m has lateral-acceleration errors of
    2.5e-3 m/s^2 (median) to 0.1 m/s^2 at 19 m/s, thousands of times the accelerometer
    noise the observer trusts.

    Attributes
    ----------
    breaks : list of float
        Left latitude of each piece, ascending (rad).
    hermite : bool
        True when the pieces interpolate a non-polynomial track.
    """

    track: Any
    breaks: list[float]
    lam_c: list[tuple[float, ...]]
    h_c: list[tuple[float, ...]]
    order: int  # coefficients per piece (4: cubic, 6: quintic)
    single: bool
    hermite: bool

    def __init__(self, track: Any, node_step_m: float = 10.0) -> None:
        from ...track import PiecewisePolynomialTrack, PolynomialTrack

        self.track = track
        self.hermite = False
        if isinstance(track, PolynomialTrack):
            lam = Polynomial(track.lam_coeffs)
            if track.h_coeffs.ndim == 1:
                hp = Polynomial(track.h_coeffs)
            else:  # h(lambda, phi) composed with lambda(phi) (003, introduction)
                hp, lam_pow = Polynomial([0.0]), Polynomial([1.0])
                for row in track.h_coeffs:
                    hp = hp + lam_pow * Polynomial(row)
                    lam_pow = lam_pow * lam
            lam_c = [float(c) for c in lam.coef]
            lam_c[0] += track.lam0
            self.breaks = [track.phi0]
            self.lam_c = [tuple(float(c) for c in lam_c)]
            self.h_c = [tuple(float(c) for c in hp.coef)]
        elif isinstance(track, PiecewisePolynomialTrack) and track.degree <= 3:
            xs = [float(x) for x in track.breakpoints]
            self.breaks = xs[:-1]
            self.lam_c, self.h_c = [], []
            for x in self.breaks:
                self.lam_c.append(tuple(float(track.lam(x, j)) / math.factorial(j) for j in range(4)))
                self.h_c.append(tuple(float(track.height(x, j)) / math.factorial(j) for j in range(4)))
        else:
            self._hermite(track, node_step_m)
        # pad to a fixed degree (explicit Horner for cubics and quintics)
        deg = max(max(len(c) for c in self.lam_c), max(len(c) for c in self.h_c))
        self.order = 4 if deg <= 4 else (6 if deg <= 6 else deg)
        self.lam_c = [tuple(c) + (0.0,) * (self.order - len(c)) for c in self.lam_c]
        self.h_c = [tuple(c) + (0.0,) * (self.order - len(c)) for c in self.h_c]
        self.single = len(self.breaks) == 1
        self._lam_arr = np.array(self.lam_c)
        self._h_arr = np.array(self.h_c)
        self._breaks_arr = np.array(self.breaks)

    def _hermite(self, track: Any, node_step_m: float) -> None:
        n = max(int(math.ceil(track.length / node_step_m)), 2)
        s = np.linspace(0.0, track.length, n + 1)
        pos, d1, d2 = track.geodetic(s)
        lat_s, lat_ss = d1[:, 0], d2[:, 0]
        if not (np.all(lat_s > 0) or np.all(lat_s < 0)):
            i = int(np.flatnonzero(np.sign(lat_s) != np.sign(lat_s[0]))[0])
            raise ConfigError("track", "a track whose latitude is monotonic (seed 003 writes lambda(phi), h(phi)); "
                              "use an arc-length estimator such as 'along-track' otherwise",
                              f"{getattr(track, 'name', 'track')}: latitude turns back near s = {s[i]:.0f} m")
        vals: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        for col in (1, 2):  # lon, h as functions of lat
            f_s, f_ss = d1[:, col], d2[:, col]
            vals.append((pos[:, col], f_s / lat_s, (f_ss * lat_s - f_s * lat_ss) / lat_s ** 3))
        phi = pos[:, 0]
        order = np.argsort(phi)
        phi = phi[order]
        vals = [(p[order], d[order], dd[order]) for p, d, dd in vals]
        width = np.diff(phi)
        coeffs = [_quintic_hermite(p[:-1], d[:-1], dd[:-1], p[1:], d[1:], dd[1:], width) for p, d, dd in vals]
        self.breaks = phi[:-1].tolist()
        self.lam_c = [tuple(row) for row in coeffs[0].tolist()]
        self.h_c = [tuple(row) for row in coeffs[1].tolist()]
        self.hermite = True

    def _piece(self, phi: float | complex) -> int:
        if self.single:
            return 0
        i = bisect.bisect_right(self.breaks, phi.real) - 1
        return 0 if i < 0 else i

    def scalars(self, phi: Any) -> tuple[Any, Any, Any, Any, Any]:
        """(lam, lam', lam'', h, h') at one latitude (float or complex), rad / m."""
        i = self._piece(phi)
        x = phi - self.breaks[i]
        if self.order == 4:
            a0, a1, a2, a3 = self.lam_c[i]
            b0, b1, b2, b3 = self.h_c[i]
            return (a0 + x * (a1 + x * (a2 + x * a3)), a1 + x * (2.0 * a2 + 3.0 * a3 * x), 2.0 * a2 + 6.0 * a3 * x,
                    b0 + x * (b1 + x * (b2 + x * b3)), b1 + x * (2.0 * b2 + 3.0 * b3 * x))
        if self.order == 6:
            a0, a1, a2, a3, a4, a5 = self.lam_c[i]
            b0, b1, b2, b3, b4, b5 = self.h_c[i]
            return (a0 + x * (a1 + x * (a2 + x * (a3 + x * (a4 + x * a5)))),
                    a1 + x * (2.0 * a2 + x * (3.0 * a3 + x * (4.0 * a4 + 5.0 * a5 * x))),
                    2.0 * a2 + x * (6.0 * a3 + x * (12.0 * a4 + 20.0 * a5 * x)),
                    b0 + x * (b1 + x * (b2 + x * (b3 + x * (b4 + x * b5)))),
                    b1 + x * (2.0 * b2 + x * (3.0 * b3 + x * (4.0 * b4 + 5.0 * b5 * x))))
        lam = _horner2(self.lam_c[i], x)
        hh = _horner2(self.h_c[i], x)
        return lam[0], lam[1], lam[2], hh[0], hh[1]

    def scalar_function(self) -> Callable[[Any], tuple[Any, ...]]:
        """:meth:`scalars` as a closure; for a single cubic piece with the coefficients bound
        (the same expressions, no piece look-up: the hot path of the stage function)."""
        if not (self.single and self.order == 4):
            return self.scalars
        x0 = self.breaks[0]
        a0, a1, a2, a3 = self.lam_c[0]
        b0, b1, b2, b3 = self.h_c[0]

        def scalars(phi: Any) -> tuple[Any, ...]:
            x = phi - x0
            return (a0 + x * (a1 + x * (a2 + x * a3)), a1 + x * (2.0 * a2 + 3.0 * a3 * x), 2.0 * a2 + 6.0 * a3 * x,
                    b0 + x * (b1 + x * (b2 + x * b3)), b1 + x * (2.0 * b2 + 3.0 * b3 * x))

        return scalars

    def scalars3(self, phi: float) -> tuple[float, ...]:
        """(lam, lam', lam'', lam''', h, h', h'') at one real latitude: one order more than
        :meth:`scalars`, for the analytic phi-derivatives of the covariance coefficients."""
        i = self._piece(phi)
        x = phi - self.breaks[i]
        if self.order == 4:
            a0, a1, a2, a3 = self.lam_c[i]
            b0, b1, b2, b3 = self.h_c[i]
            return (a0 + x * (a1 + x * (a2 + x * a3)), a1 + x * (2.0 * a2 + 3.0 * a3 * x), 2.0 * a2 + 6.0 * a3 * x,
                    6.0 * a3, b0 + x * (b1 + x * (b2 + x * b3)), b1 + x * (2.0 * b2 + 3.0 * b3 * x),
                    2.0 * b2 + 6.0 * b3 * x)
        lam = _horner3(self.lam_c[i], x)
        hh = _horner3(self.h_c[i], x)
        return lam[0], lam[1], lam[2], lam[3], hh[0], hh[1], hh[2]

    def arrays(self, phi: np.ndarray) -> tuple[np.ndarray, ...]:
        """(lam, lam', lam'', h, h', h'') over an array of latitudes."""
        phi = np.asarray(phi, dtype=float)
        idx = np.clip(np.searchsorted(self._breaks_arr, phi, side="right") - 1, 0, len(self.breaks) - 1)
        x = phi - self._breaks_arr[idx]
        out = []
        for arr in (self._lam_arr, self._h_arr):
            c = arr[idx]  # (n, deg)
            p = np.zeros_like(x)
            d1 = np.zeros_like(x)
            d2 = np.zeros_like(x)
            for j in range(c.shape[-1] - 1, -1, -1):
                d2 = d2 * x + 2.0 * d1
                d1 = d1 * x + p
                p = p * x + c[..., j]
            out.append((p, d1, d2))
        (lam, dlam, ddlam), (hh, dh, ddh) = out
        return lam, dlam, ddlam, hh, dh, ddh


def _quintic_hermite(p0: np.ndarray, d0: np.ndarray, dd0: np.ndarray, p1: np.ndarray, d1: np.ndarray,
                     dd1: np.ndarray, width: np.ndarray) -> np.ndarray:
    """Coefficients (n, 6) in x = phi - phi0 of the quintics matching value, slope and
    second derivative at both ends of intervals of the given widths."""
    H = width
    c0, c1, c2 = p0, d0, 0.5 * dd0
    d = p1 - (c0 + H * (c1 + H * c2))
    e = d1 - (c1 + 2.0 * c2 * H)
    f = dd1 - 2.0 * c2
    c3 = (10.0 * d - 4.0 * e * H + 0.5 * f * H * H) / H ** 3
    c4 = (-15.0 * d + 7.0 * e * H - f * H * H) / H ** 4
    c5 = (6.0 * d - 3.0 * e * H + 0.5 * f * H * H) / H ** 5
    return np.column_stack([c0, c1, c2, c3, c4, c5])


def _horner3(c: Sequence[float], x: float) -> tuple[float, float, float, float]:
    """Value and first three derivatives of sum c_j x^j."""
    p = d1 = d2 = d3 = 0.0
    for cj in reversed(c):
        d3 = d3 * x + 3.0 * d2
        d2 = d2 * x + 2.0 * d1
        d1 = d1 * x + p
        p = p * x + cj
    return p, d1, d2, d3


def _horner2(c: Sequence[float], x: Any) -> tuple[Any, Any, Any]:
    """Value, first and second derivative of sum c_j x^j."""
    p = 0.0 * x
    d1 = 0.0 * x
    d2 = 0.0 * x
    for cj in reversed(c):
        d2 = d2 * x + 2.0 * d1
        d1 = d1 * x + p
        p = p * x + cj
    return p, d1, d2
