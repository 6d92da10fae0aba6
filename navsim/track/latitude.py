"""Tracks written as lambda(phi), h(phi), seed 003's spatial track model.

:class:`PolynomialTrack`: longitude a polynomial of latitude, lambda(P, phi), and height
h(A, lambda, phi) = sum a_ij lambda^i phi^j composed into h(A, P, phi) (003, introduction),
or directly a polynomial h(phi); :class:`PiecewisePolynomialTrack`: its piecewise (spline)
generalisation produced by :func:`navsim.track.fit_polynomial_track`. The parameter of the
arc-length engine is u = |phi - phi_start|.
"""


import math
from typing import Any, Sequence

import numpy as np
from numpy.polynomial import Polynomial
from numpy.typing import ArrayLike
from scipy.interpolate import (
    PPoly,
)

from ..earth import SPHERICAL, EarthModel
from ..errors import ConfigError, TrackError
from .arclength import ArcLengthTrack, default_table
from .base import CantModel, TrackSegment


class _LatitudeTrack(ArcLengthTrack):
    """Tracks written as lambda(phi), h(phi) (003): u = |phi - phi_start|."""

    phi_start: float
    phi_end: float

    def lam(self, phi: ArrayLike, nu: int = 0) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def height(self, phi: ArrayLike, nu: int = 0) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    @property
    def phi_range(self) -> tuple[float, float]:
        """(phi_start, phi_end), rad: s = 0 at phi_start; phi_end < phi_start is southbound."""
        return self.phi_start, self.phi_end

    @property
    def direction(self) -> int:
        """+1 if latitude grows with s (northbound), -1 if southbound."""
        return 1 if self.phi_end > self.phi_start else -1

    def _curve(self, u: np.ndarray, order: int) -> list[np.ndarray]:
        d = self.direction
        phi = self.phi_start + d * u
        out = []
        for nu in range(order + 1):
            sign = d**nu
            lat = phi if nu == 0 else (np.full_like(phi, float(d)) if nu == 1 else np.zeros_like(phi))
            out.append(np.stack([lat, sign * self.lam(phi, nu), sign * self.height(phi, nu)], axis=-1))
        return out

    def phi_at(self, s: ArrayLike) -> np.ndarray:
        """Latitude at arc length s, rad."""
        s = self._check_s(s)
        return self.phi_start + self.direction * self._u_of_s(s)

    def arc_length_at(self, phi: ArrayLike) -> np.ndarray:
        """Arc length s at latitude phi (within the track's range), m."""
        phi = np.asarray(phi, dtype=float)
        u = self.direction * (phi - self.phi_start)
        if np.any(u < -1e-12) or np.any(u > self._u_breaks[-1] * (1 + 1e-12)):
            raise TrackError(f"track {self.name!r}: latitude outside [{self.phi_start}, {self.phi_end}] rad")
        return self._s_of_u(u)

    def _setup_latitude(self, phi_start: float, phi_end: float, max_step_m: float,
                        extra_breaks: np.ndarray | None = None) -> None:
        for fld, value in (("phi_start", phi_start), ("phi_end", phi_end)):
            if not (isinstance(value, (int, float, np.floating)) and math.isfinite(value)
                    and abs(value) < math.pi / 2):
                raise ConfigError(fld, "a latitude in (-pi/2, pi/2) rad", value)
        if phi_start == phi_end:
            raise ConfigError("phi_end", f"a latitude different from phi_start = {phi_start}", phi_end)
        self.phi_start, self.phi_end = float(phi_start), float(phi_end)
        span = abs(self.phi_end - self.phi_start)
        # estimate ds/du on a coarse grid to choose the table step
        probe = np.linspace(0.0, span, 65)
        speed = float(np.max(self._sigma_at(probe)))
        breaks = default_table(0.0, span, speed, max_step_m)
        if extra_breaks is not None and len(extra_breaks):
            extra = self.direction * (np.asarray(extra_breaks, dtype=float) - self.phi_start)
            extra = extra[(extra > 0) & (extra < span)]
            breaks = np.unique(np.concatenate([breaks, extra]))
            breaks = breaks[np.concatenate([[True], np.diff(breaks) > 1e-12 * span])]
        self._build_table(breaks)
        mid = 0.5 * (self.phi_start + self.phi_end)
        self._plan_ref = (mid, float(self.height(np.array(mid))))
        self._set_plan_scale(*self._plan_ref)


def _as_coeffs(name: str, values: ArrayLike, ndim: int | tuple[int, ...]) -> np.ndarray:
    try:
        arr = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(name, "numeric coefficients", values) from None
    ndims = (ndim,) if isinstance(ndim, int) else ndim
    if arr.ndim not in ndims or arr.size == 0 or not np.all(np.isfinite(arr)):
        raise ConfigError(name, f"a non-empty finite array with ndim in {ndims}", values)
    return arr


def _shift_2d(a: np.ndarray, lam_shift: float, phi_shift: float) -> np.ndarray:
    """Coefficients b of sum b_ij L^i F^j equal to sum a_ij (L + lam_shift)^i (F + phi_shift)^j."""
    ni, nj = a.shape
    b = np.zeros_like(a)
    for i in range(ni):
        for j in range(nj):
            if a[i, j] == 0.0:
                continue
            for p in range(i + 1):
                for q in range(j + 1):
                    b[p, q] += a[i, j] * math.comb(i, p) * math.comb(j, q) * lam_shift ** (i - p) * phi_shift ** (j - q)
    return b


class PolynomialTrack(_LatitudeTrack):
    """The polynomial spatial track model of seed 003.

    lambda(phi) = lam0 + sum_k lam_coeffs[k] (phi - phi0)^k
    h(lambda, phi) = sum_ij h_coeffs[i, j] (lambda - lam0)^i (phi - phi0)^j   (2-D form), or
    h(phi) = sum_j h_coeffs[j] (phi - phi0)^j                                 (1-D form)

    With ``phi0 = lam0 = 0`` these are exactly the printed forms
    lambda(P, phi) = sum p_k phi^k and h(A, lambda, phi) = sum a_ij lambda^i phi^j of 003;
    a nonzero reference point is only an equivalent re-expansion (binomial theorem, see
    :meth:`printed_coefficients`) that keeps the coefficients well conditioned: with
    phi ~ 0.8 rad and track spans of 3e-3 rad the printed coefficients of a gentle curve
    are ~1e2-1e6 and cancel to 1e-13 relative. The composed height
    h(A, P, phi) = h(A, lambda(P, phi), phi) is itself a polynomial in (phi - phi0),
    formed exactly once.

    Parameters
    ----------
    lam_coeffs : array_like (K,)
        Coefficients of lambda - lam0 in powers of (phi - phi0): rad / rad^k.
    h_coeffs : array_like (J,) or (I, J)
        Height coefficients, m / rad^(i+j).
    phi_start, phi_end : float
        Latitudes (rad) at s = 0 and s = length; phi_end < phi_start runs south.
    phi0, lam0 : float, optional
        Reference point of the expansion, rad. Default phi0 = phi_start, lam0 = 0.
    earth : EarthModel
        Default the spherical Earth of 003.
    segments : sequence of TrackSegment
    cant_model : CantModel
        Default no cant (003 has none).
    name : str
    max_step_m : float
        Arc-length table step (accuracy is set by the Newton refinement, not by this).
    """

    def __init__(
        self,
        lam_coeffs: ArrayLike,
        h_coeffs: ArrayLike,
        phi_start: float,
        phi_end: float,
        *,
        phi0: float | None = None,
        lam0: float = 0.0,
        earth: EarthModel = SPHERICAL,
        segments: Sequence[TrackSegment] = (),
        cant_model: CantModel = CantModel(),
        name: str = "polynomial",
        max_step_m: float = 50.0,
    ) -> None:
        self.earth = earth
        self.name = name
        self.cant_model = cant_model
        self.phi0 = float(phi_start if phi0 is None else phi0)
        self.lam0 = float(lam0)
        if not (math.isfinite(self.phi0) and math.isfinite(self.lam0)):
            raise ConfigError("phi0/lam0", "finite reference angles (rad)", (phi0, lam0))
        self.lam_coeffs = _as_coeffs("lam_coeffs", lam_coeffs, 1)
        self.h_coeffs = _as_coeffs("h_coeffs", h_coeffs, (1, 2))
        self._lam_poly = Polynomial(self.lam_coeffs)
        if self.h_coeffs.ndim == 1:
            self._h_poly = Polynomial(self.h_coeffs)
        else:
            # h(A, P, phi) = h(A, lambda(P, phi), phi): compose exactly (003, introduction)
            total = Polynomial([0.0])
            lam_pow = Polynomial([1.0])
            for i in range(self.h_coeffs.shape[0]):
                total = total + lam_pow * Polynomial(self.h_coeffs[i])
                lam_pow = lam_pow * self._lam_poly
            self._h_poly = total
        self._lam_derivs = [self._lam_poly.deriv(m) if m else self._lam_poly for m in range(4)]
        self._h_derivs = [self._h_poly.deriv(m) if m else self._h_poly for m in range(4)]
        self._setup_latitude(phi_start, phi_end, max_step_m)
        self.segments = self._check_segments(segments)

    def lam(self, phi: ArrayLike, nu: int = 0) -> np.ndarray:
        """lambda(P, phi) (rad) or its nu-th derivative d^nu lambda / d phi^nu, nu = 0..3."""
        phi = np.asarray(phi, dtype=float)
        if nu not in (0, 1, 2, 3):
            raise ConfigError("nu", "0, 1, 2 or 3", nu)
        value = self._lam_derivs[nu](phi - self.phi0)
        return value + self.lam0 if nu == 0 else value

    def height(self, phi: ArrayLike, nu: int = 0) -> np.ndarray:
        """h(A, P, phi) (m) or d^nu h / d phi^nu (m/rad^nu) of the composed height, nu = 0..3."""
        phi = np.asarray(phi, dtype=float)
        if nu not in (0, 1, 2, 3):
            raise ConfigError("nu", "0, 1, 2 or 3", nu)
        return self._h_derivs[nu](phi - self.phi0)

    def printed_coefficients(self) -> tuple[np.ndarray, np.ndarray]:
        """The same model in the printed form of 003 (phi0 = lam0 = 0).

        Returns
        -------
        P : ndarray (K,)
            lambda(P, phi) = sum_k P[k] phi^k, rad.
        A : ndarray (I, J)
            h(A, lambda, phi) = sum_ij A[i, j] lambda^i phi^j, m (a 1-D height model is
            returned as a single row, i = 0).
        """
        # p(phi - phi0) re-expanded about 0
        shifted = Polynomial(self.lam_coeffs)(Polynomial([-self.phi0, 1.0]))
        P: np.ndarray = shifted.coef.copy()  # any shape: np.pad below returns the general type
        P[0] += self.lam0
        P = np.pad(P, (0, max(0, self.lam_coeffs.size - P.size)))
        a = self.h_coeffs if self.h_coeffs.ndim == 2 else self.h_coeffs[None, :]
        A = _shift_2d(np.asarray(a, dtype=float), -self.lam0, -self.phi0)
        return P, A

    @classmethod
    def from_printed(cls, P: ArrayLike, A: ArrayLike, phi_start: float, phi_end: float, *,
                     phi0: float | None = None, lam0: float | None = None, **kwargs: Any) -> "PolynomialTrack":
        """Build from the printed coefficients of 003 (expansions about phi = lambda = 0),
        re-expanded about (phi0, lam0) (default phi_start and lambda(phi_start))."""
        P = _as_coeffs("P", P, 1)
        A = _as_coeffs("A", A, (1, 2))
        phi0 = float(phi_start if phi0 is None else phi0)
        p_shift: np.ndarray = Polynomial(P)(Polynomial([phi0, 1.0])).coef
        p_shift = np.pad(p_shift, (0, max(0, P.size - p_shift.size)))
        if lam0 is None:
            lam0 = float(p_shift[0])
        p_shift = p_shift.copy()
        p_shift[0] -= lam0
        a = A if A.ndim == 2 else A[None, :]
        a_shift = _shift_2d(a, lam0, phi0)
        if A.ndim == 1:
            a_shift = a_shift[0]
        return cls(p_shift, a_shift, phi_start, phi_end, phi0=phi0, lam0=lam0, **kwargs)


class PiecewisePolynomialTrack(_LatitudeTrack):
    """lambda(phi), h(phi) as piecewise polynomials of one degree d joined with C^(d-1)
    continuity (a least-squares spline in latitude, see :func:`fit_polynomial_track`).

    Degree 2 pieces join with continuous slope only: the curvature steps at the
    breakpoints, so such a track is meant as the estimator's map; a truth track should
    have degree >= 3 (C^2) - the protocol's requirement.

    Parameters
    ----------
    lam_pp, h_pp : scipy.interpolate.PPoly
        lambda - lam0 (rad) and h (m) as functions of latitude (rad), breakpoints ascending.
    phi_start, phi_end : float
        Latitudes at s = 0 and s = length, rad, inside the breakpoint range.
    lam0 : float
        Longitude offset, rad.
    """

    def __init__(
        self,
        lam_pp: PPoly,
        h_pp: PPoly,
        phi_start: float,
        phi_end: float,
        *,
        lam0: float = 0.0,
        earth: EarthModel = SPHERICAL,
        segments: Sequence[TrackSegment] = (),
        cant_model: CantModel = CantModel(),
        name: str = "piecewise-polynomial",
        max_step_m: float = 50.0,
    ) -> None:
        if not isinstance(lam_pp, PPoly) or not isinstance(h_pp, PPoly):
            raise ConfigError("lam_pp/h_pp", "scipy.interpolate.PPoly objects", (type(lam_pp), type(h_pp)))
        self.earth = earth
        self.name = name
        self.cant_model = cant_model
        self.lam0 = float(lam0)
        self._lam_pp = lam_pp
        self._h_pp = h_pp
        self._lam_d = [lam_pp] + [lam_pp.derivative(m) for m in (1, 2, 3)]
        self._h_d = [h_pp] + [h_pp.derivative(m) for m in (1, 2, 3)]
        lo, hi = min(phi_start, phi_end), max(phi_start, phi_end)
        tol = 1e-12 + 1e-9 * (hi - lo)
        if lo < lam_pp.x[0] - tol or hi > lam_pp.x[-1] + tol:
            raise ConfigError("phi_start/phi_end", f"inside the breakpoints [{lam_pp.x[0]}, {lam_pp.x[-1]}] rad",
                              (phi_start, phi_end))
        self.breakpoints = np.unique(np.concatenate([lam_pp.x, h_pp.x]))
        self._setup_latitude(phi_start, phi_end, max_step_m, extra_breaks=self.breakpoints)
        self.segments = self._check_segments(segments)

    @property
    def degree(self) -> int:
        return int(self._lam_pp.c.shape[0] - 1)

    @property
    def knot_s(self) -> np.ndarray:
        """Arc lengths (m) of the breakpoints strictly inside the track (C^(degree-1) joins)."""
        inner = self.breakpoints[(self.breakpoints > min(self.phi_range)) & (self.breakpoints < max(self.phi_range))]
        return np.sort(self._s_of_u(self.direction * (inner - self.phi_start)))

    @property
    def n_pieces(self) -> int:
        inner = self.breakpoints[(self.breakpoints > min(self.phi_range)) & (self.breakpoints < max(self.phi_range))]
        return int(inner.size + 1)

    def lam(self, phi: ArrayLike, nu: int = 0) -> np.ndarray:
        """lambda(phi) (rad) or d^nu lambda / d phi^nu, nu = 0..3."""
        if nu not in (0, 1, 2, 3):
            raise ConfigError("nu", "0, 1, 2 or 3", nu)
        value = self._lam_d[nu](np.asarray(phi, dtype=float))
        return value + self.lam0 if nu == 0 else value

    def height(self, phi: ArrayLike, nu: int = 0) -> np.ndarray:
        """h(phi) (m) or d^nu h / d phi^nu, nu = 0..3."""
        if nu not in (0, 1, 2, 3):
            raise ConfigError("nu", "0, 1, 2 or 3", nu)
        return self._h_d[nu](np.asarray(phi, dtype=float))
