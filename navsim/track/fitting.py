"""Least-squares polynomial fits lambda(phi), h(phi) of a track (:func:`fit_polynomial_track`,
:class:`PolynomialFit`): global or piecewise polynomials in latitude (de Boor 2001, least-
squares splines), with the fit errors in metres.
"""


import math
from dataclasses import dataclass
from typing import Any, Iterable, Union

import numpy as np
from numpy.polynomial import polynomial as npoly
from scipy.interpolate import (
    BSpline,
    PPoly,
    make_lsq_spline,
)

from ..earth import SPHERICAL, EarthModel
from ..errors import ConfigError, TrackError
from .base import TrackSegment
from .latitude import PiecewisePolynomialTrack, PolynomialTrack
from .spline import check_waypoints


@dataclass(frozen=True, slots=True)
class PolynomialFit:
    """The result of :func:`fit_polynomial_track`.

    Attributes
    ----------
    track : PolynomialTrack or PiecewisePolynomialTrack
    degree : int
    n_pieces : int
    breakpoints : ndarray
        Latitudes of the piece boundaries including both ends, rad, ascending.
    max_cross_track_m, rms_cross_track_m : float
        Horizontal distance of the data points from the fitted curve (east error at the
        same latitude times |cos(heading)|), m.
    max_height_m, rms_height_m : float
        Height error at the same latitude, m.
    n_points : int
        Number of data points fitted.
    """

    track: Union[PolynomialTrack, PiecewisePolynomialTrack]
    degree: int
    n_pieces: int
    breakpoints: np.ndarray
    max_cross_track_m: float
    rms_cross_track_m: float
    max_height_m: float
    rms_height_m: float
    n_points: int

    @property
    def max_error_m(self) -> float:
        return max(self.max_cross_track_m, self.max_height_m)


def _fit_errors(earth: EarthModel, phi: np.ndarray, lam: np.ndarray, h: np.ndarray, lam_fit: np.ndarray, dlam_fit: np.ndarray,
                h_fit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r_n, r_e = earth.radii(phi)
    east = (lam - lam_fit) * (r_e + h) * np.cos(phi)
    slope = dlam_fit * (r_e + h) * np.cos(phi) / (r_n + h)  # tan(heading)
    cross = np.abs(east) / np.sqrt(1.0 + slope * slope)
    dh = h - h_fit
    return cross, dh


def fit_polynomial_track(
    source: Any,
    degree: int = 2,
    max_error_m: float = 1.0,
    *,
    earth: EarthModel | None = None,
    sample_step_m: float = 10.0,
    max_pieces: int = 256,
    name: str | None = None,
) -> PolynomialFit:
    """Fit the 003 track model lambda(phi), h(phi) to waypoints or to a track.

    One least-squares polynomial of ``degree`` first (numpy.polynomial on a scaled
    latitude); if its cross-track or height error exceeds ``max_error_m``, a least-squares
    spline in latitude of the same degree (pieces joined C^(degree-1)), with knots inserted
    where the error is worst until the tolerance is met.

    Parameters
    ----------
    source : Track, or array_like (N, 3), or tuple (lat, lon, h)
        A track (sampled every ``sample_step_m`` of arc length) or waypoints in rad, rad, m.
    degree : int
        Polynomial degree, 1..7 (003 uses 2).
    max_error_m : float
        Tolerance on the maximum cross-track and height error, m.
    earth : EarthModel, optional
        The Earth of the result; default the source track's, else the spherical one of 003.
    max_pieces : int
        Give up (TrackError) beyond this many pieces.

    Returns
    -------
    PolynomialFit

    Raises
    ------
    TrackError
        If latitude is not strictly monotonic along the data (the track turns back: it
        cannot be written as lambda(phi)); the message says where. Or if the tolerance
        cannot be met with ``max_pieces``.
    """
    if not isinstance(degree, (int, np.integer)) or not 1 <= degree <= 7:
        raise ConfigError("degree", "an integer in 1..7", degree)
    max_error_m = float(max_error_m)
    if not max_error_m > 0:
        raise ConfigError("max_error_m", "a positive tolerance (m)", max_error_m)
    s_data = None
    if hasattr(source, "geodetic") and hasattr(source, "length"):
        n = max(int(math.ceil(source.length / sample_step_m)), 4 * (degree + 1))
        s_data = np.linspace(0.0, source.length, n + 1)
        pos = source.geodetic(s_data)[0]
        phi, lam, h = pos[:, 0], pos[:, 1], pos[:, 2]
        earth = earth or source.earth
        segments = tuple(source.segments)
        name = name or f"{getattr(source, 'name', 'track')}-fit"
    else:
        if isinstance(source, tuple) and len(source) == 3:
            phi, lam, h = (np.asarray(a, dtype=float) for a in source)
        else:
            arr = np.asarray(source, dtype=float)
            if arr.ndim != 2 or arr.shape[1] != 3:
                raise ConfigError("source", "a Track, an (N, 3) array [lat, lon, h] or a tuple (lat, lon, h)", arr.shape)
            phi, lam, h = arr[:, 0], arr[:, 1], arr[:, 2]
        phi, lam, h = check_waypoints(phi, lam, h, "fit")
        earth = earth or SPHERICAL
        segments = ()
        name = name or "fit"
    if phi.size < degree + 1:
        raise TrackError(f"fit: {phi.size} points cannot determine a degree-{degree} polynomial")
    dphi = np.diff(phi)
    direction = 1.0 if phi[-1] > phi[0] else -1.0
    bad = np.flatnonzero(direction * dphi <= 0)
    if bad.size:
        i = int(bad[0])
        where = f" (s ~ {s_data[i]:.1f} m)" if s_data is not None else ""
        raise TrackError(
            f"{name}: latitude is not monotonic along the track - it turns back at point {i}{where}, "
            f"lat {math.degrees(phi[i]):.7f} deg, lon {math.degrees(lam[i]):.7f} deg; such a track cannot "
            "be written as lambda(phi) (003): split it there or use a SplineTrack"
        )
    order = np.argsort(phi)
    phi_a, lam_a, h_a = phi[order], lam[order], h[order]
    phi_start, phi_end = float(phi[0]), float(phi[-1])
    lam0 = float(lam[0])
    span = phi_a[-1] - phi_a[0]
    # ---- one polynomial (numpy.polynomial on x = (phi - phi_start) / span)
    x = (phi - phi_start) / span
    c_lam = npoly.polyfit(x, lam - lam0, degree)
    c_h = npoly.polyfit(x, h, degree)
    scale = span ** -np.arange(degree + 1)
    single = PolynomialTrack(c_lam * scale, c_h * scale, phi_start, phi_end, phi0=phi_start, lam0=lam0,
                             earth=earth, name=name)
    cross, dh = _fit_errors(earth, phi, lam, h, single.lam(phi), single.lam(phi, 1), single.height(phi))
    err = np.maximum(cross, np.abs(dh))
    if err.max() <= max_error_m:
        return _make_fit(single.with_segments(_clip_segments(segments, single.length)), degree, np.array([phi_a[0], phi_a[-1]]),
                         cross, dh, phi.size)
    # ---- piecewise: least-squares spline in latitude, knots where the error is worst
    k = int(degree)
    inner: list[float] = []
    y = np.stack([lam_a - lam0, h_a], axis=-1)
    while True:
        if len(inner) + 1 > max_pieces:
            raise TrackError(
                f"{name}: cannot fit lambda(phi), h(phi) of degree {degree} within {max_error_m} m "
                f"with {max_pieces} pieces (best max error {err.max():.3g} m)"
            )
        knots = np.concatenate([[phi_a[0]] * (k + 1), np.sort(inner), [phi_a[-1]] * (k + 1)])
        try:
            spl = make_lsq_spline(phi_a, y, knots, k=k)
        except (ValueError, np.linalg.LinAlgError):
            raise TrackError(f"{name}: too few points between knots to fit {len(inner) + 1} pieces "
                             f"within {max_error_m} m; sample the track more densely") from None
        lam_fit, h_fit = spl(phi_a).T
        dlam_fit = spl.derivative(1)(phi_a)[:, 0]
        cross_a, dh_a = _fit_errors(earth, phi_a, lam_a, h_a, lam_fit + lam0, dlam_fit, h_fit)
        err = np.maximum(cross_a, np.abs(dh_a))
        if err.max() <= max_error_m:
            break
        # split every interval whose error exceeds the tolerance at the median of its points
        bounds = np.concatenate([[phi_a[0]], np.sort(inner), [phi_a[-1]]])
        new = []
        for a, b in zip(bounds[:-1], bounds[1:]):
            sel = (phi_a >= a) & (phi_a <= b)
            if np.any(err[sel] > max_error_m) and sel.sum() > 2 * (k + 1):
                new.append(float(np.median(phi_a[sel])))
        if not new:
            raise TrackError(f"{name}: cannot refine the fit further (too few points per piece); "
                             f"best max error {err.max():.3g} m")
        inner.extend(new)
    lam_pp = PPoly.from_spline(BSpline(spl.t, spl.c[:, 0], k))
    h_pp = PPoly.from_spline(BSpline(spl.t, spl.c[:, 1], k))
    # drop the zero-length pieces of the repeated end knots
    keep = np.diff(lam_pp.x) > 0
    xs = np.concatenate([lam_pp.x[:-1][keep], [lam_pp.x[-1]]])
    lam_pp = PPoly(lam_pp.c[:, keep], xs)
    h_pp = PPoly(h_pp.c[:, keep], xs)
    track = PiecewisePolynomialTrack(lam_pp, h_pp, phi_start, phi_end, lam0=lam0, earth=earth, name=name)
    track = track.with_segments(_clip_segments(segments, track.length))
    cross_o, dh_o = cross_a, dh_a
    return _make_fit(track, degree, xs, cross_o, dh_o, phi.size)


def _clip_segments(segments: Iterable[TrackSegment], length: float) -> tuple[TrackSegment, ...]:
    out = []
    for g in segments:
        if g.s_start <= length:
            out.append(TrackSegment(g.kind, max(0.0, g.s_start), min(length, g.s_end), g.name))
    return tuple(out)


def _make_fit(track: Any, degree: int, breakpoints: np.ndarray, cross: np.ndarray, dh: np.ndarray,
              n_points: int) -> PolynomialFit:
    return PolynomialFit(
        track=track,
        degree=int(degree),
        n_pieces=int(len(breakpoints) - 1),
        breakpoints=np.asarray(breakpoints, dtype=float),
        max_cross_track_m=float(np.max(cross)),
        rms_cross_track_m=float(np.sqrt(np.mean(cross**2))),
        max_height_m=float(np.max(np.abs(dh))),
        rms_height_m=float(np.sqrt(np.mean(dh**2))),
        n_points=int(n_points),
    )
