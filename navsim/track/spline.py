"""A quintic B-spline track (C^4) through or near waypoints (lat, lon, h) (de Boor 2001),
e.g. from a GeoJSON / GPX / CSV file (:mod:`navsim.trackio`), and the waypoint checks.
"""


import math
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import (
    BSpline,
    make_interp_spline,
    make_splprep,
)

from ..earth import WGS84, EarthModel
from ..errors import ConfigError, TrackError
from .arclength import ArcLengthTrack
from .base import CantModel, TrackSegment


class SplineTrack(ArcLengthTrack):
    """A quintic B-spline track (C^4) through, or near, waypoints.

    The spline is built in scaled coordinates y = [(lat - lat_ref) c_n, (lon - lon_ref) c_e, h]
    (c_n, c_e the metres per radian at the first waypoint, constants - so lat and lon
    remain exact linear functions of the spline and the smoothing tolerance is in metres),
    parameterised by u = cumulative ECEF chord length between waypoints, then
    re-parameterised by true arc length.

    Parameters
    ----------
    lat, lon, h : array_like (N,)
        Waypoints, rad, rad, m (heights above the Earth model). N >= 2; with N < 6 the
        degree drops to N - 1 (a single polynomial, still C-infinity).
    earth : EarthModel
        Default WGS-84.
    segments : sequence of TrackSegment
    cant_model : CantModel
    smoothing_m : float
        0 interpolates the waypoints; > 0 fits a smoothing quintic spline whose RMS
        distance from the waypoints is about ``smoothing_m`` metres (scipy make_splprep
        with s = N smoothing_m^2).
    name : str
    """

    def __init__(
        self,
        lat: ArrayLike,
        lon: ArrayLike,
        h: ArrayLike,
        *,
        earth: EarthModel = WGS84,
        segments: Sequence[TrackSegment] = (),
        cant_model: CantModel = CantModel(),
        smoothing_m: float = 0.0,
        name: str = "spline",
        max_step_m: float = 25.0,
    ) -> None:
        self.earth = earth
        self.name = name
        self.cant_model = cant_model
        lat, lon, h = check_waypoints(lat, lon, h, name)
        try:
            smoothing_m = float(smoothing_m)
        except (TypeError, ValueError):
            raise ConfigError("smoothing_m", "a number >= 0 (m)", smoothing_m) from None
        if not (math.isfinite(smoothing_m) and smoothing_m >= 0):
            raise ConfigError("smoothing_m", "a number >= 0 (m)", smoothing_m)
        xyz = earth.geodetic_to_ecef(lat, lon, h)
        chord = np.linalg.norm(np.diff(xyz, axis=0), axis=1)
        bad = np.flatnonzero(chord < 1e-3)
        if bad.size:
            i = int(bad[0])
            raise TrackError(
                f"track {name!r}: waypoints {i} and {i + 1} coincide (distance {chord[i]:.3g} m < 1 mm); "
                "remove duplicate consecutive points"
            )
        if lat.size < MIN_SPLINE_WAYPOINTS:
            raise TrackError(f"track {name!r}: a spline track needs at least {MIN_SPLINE_WAYPOINTS} waypoints "
                             f"(its third derivative is used), got {lat.size}")
        d = np.diff(xyz, axis=0) / chord[:, None]
        turn = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", d[:-1], d[1:]), -1.0, 1.0)))
        bad = np.flatnonzero(turn > MAX_WAYPOINT_TURN_DEG)
        if bad.size:
            i = int(bad[0]) + 1
            raise TrackError(f"track {name!r}: the track turns by {turn[i - 1]:.0f} deg at waypoint {i} "
                             f"(at most {MAX_WAYPOINT_TURN_DEG:g} deg between consecutive chords): "
                             "it doubles back on itself")
        u = np.concatenate([[0.0], np.cumsum(chord)])
        self.lat_ref, self.lon_ref = float(lat[0]), float(lon[0])
        r_n, r_e = earth.radii(np.array(self.lat_ref))
        self._c_n = float(r_n)
        self._c_e = float(r_e) * math.cos(self.lat_ref)
        y = np.stack([(lat - self.lat_ref) * self._c_n, (lon - self.lon_ref) * self._c_e, h], axis=-1)
        self.degree = int(min(5, lat.size - 1))
        if smoothing_m > 0 and lat.size > self.degree + 1:
            spline, _ = make_splprep(list(y.T), u=u, k=self.degree, s=lat.size * smoothing_m**2)
            c = np.asarray(spline.c)
            if c.shape[-1] != 3:  # make_splprep returns c with the dimension last
                c = c.T
            self._spline = BSpline(spline.t, c, spline.k)
        else:
            self._spline = make_interp_spline(u, y, k=self.degree)
        self._derivs = [self._spline] + [self._spline.derivative(m) for m in range(1, 4)]
        self._scale = np.array([1.0 / self._c_n, 1.0 / self._c_e, 1.0])
        self.smoothing_m = smoothing_m
        self.waypoint_u = u
        # table: the spline's knots, subdivided to at most max_step_m
        knots = np.unique(self._spline.t[(self._spline.t >= u[0]) & (self._spline.t <= u[-1])])
        pieces = [np.linspace(a, b, max(1, int(math.ceil((b - a) / max_step_m))) + 1)[:-1]
                  for a, b in zip(knots[:-1], knots[1:])]
        self._build_table(np.concatenate(pieces + [[knots[-1]]]))
        self._plan_ref = (self.lat_ref, float(h[0]))
        self._set_plan_scale(*self._plan_ref)
        self.segments = self._check_segments(segments)

    def _curve(self, u: np.ndarray, order: int) -> list[np.ndarray]:
        out = []
        for nu in range(order + 1):
            y = self._derivs[nu](u) * self._scale
            if nu == 0:
                y = y + np.array([self.lat_ref, self.lon_ref, 0.0])
            out.append(y)
        return out

    @property
    def knot_s(self) -> np.ndarray:
        """Arc lengths (m) of the spline's distinct knots strictly inside the track: the
        quintic pieces join C^4 there, so the design cant (which uses the third derivative
        through the curvature rate) has a kink in its rate."""
        u = self._u_breaks
        t = np.unique(self._spline.t)
        inner = t[(t > u[0]) & (t < u[-1])]
        return self._s_of_u(inner)

    @property
    def waypoint_s(self) -> np.ndarray:
        """Arc length at each waypoint (on the smoothed curve: at its parameter), m."""
        return self._s_of_u(self.waypoint_u)


MIN_SPLINE_WAYPOINTS = 4
"""Waypoints a spline track needs: degree >= 3, since its third derivative is used."""
MAX_WAYPOINT_TURN_DEG = 150.0
"""Largest turn between consecutive waypoint chords; more is a track doubling back."""


def check_waypoints(lat: ArrayLike, lon: ArrayLike, h: ArrayLike, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    arrays = []
    for fld, value in (("lat", lat), ("lon", lon), ("h", h)):
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ConfigError(fld, "numeric waypoints", value, name) from None
        if arr.ndim != 1:
            raise ConfigError(fld, "a 1-D array of waypoints", arr.shape, name)
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise ConfigError(f"{fld}[{bad[0]}]", "a finite number", arr[bad[0]], name)
        arrays.append(arr)
    lat, lon, h = arrays
    if not (lat.size == lon.size == h.size):
        raise ConfigError("lat/lon/h", "arrays of equal length", (lat.size, lon.size, h.size), name)
    if lat.size < 2:
        raise TrackError(f"track {name!r}: at least 2 waypoints are needed, got {lat.size}")
    bad = np.flatnonzero(np.abs(lat) >= math.pi / 2)
    if bad.size:
        raise ConfigError(f"lat[{bad[0]}]", "a latitude in (-pi/2, pi/2) rad", lat[bad[0]], name)
    return lat, lon, h
