"""Tracks: the known spatial path a vehicle moves along.

A track is a smooth curve in geodetic coordinates (latitude, longitude, height on an
:class:`~navsim.earth.EarthModel`) parameterised by its *true* arc length s, with
annotations (tunnels, stations, urban canyons) by arc length and a cant (superelevation)
profile. Every track satisfies the :class:`Track` protocol that the motion module codes
against; :func:`track_frame` turns a track into the tangent, heading, pitch, curvature and
cant the truth is built from.

Two families:

* :class:`PolynomialTrack` - the spatial track model of seed 003: longitude as a polynomial
  of latitude, lambda(P, phi), and height h(A, lambda, phi) = sum a_ij lambda^i phi^j
  composed into h(A, P, phi) = h(A, lambda(P, phi), phi) (003, introduction), or directly
  a polynomial h(phi). :class:`PiecewisePolynomialTrack` is its piecewise (spline)
  generalisation produced by :func:`fit_polynomial_track`.
* :class:`SplineTrack` - a quintic B-spline (C^4) through or near waypoints
  (lat, lon, h), e.g. from a GeoJSON / GPX / CSV file (:mod:`navsim.trackio`).

Arc length
----------
Each track is first a curve X(u) = [lat, lon, h](u) in some convenient parameter u
(latitude for the polynomial tracks, cumulative chord length for splines). Its speed
sigma(u) = ds/du = |[(R_N + h) lat', (R_E + h) cos(lat) lon', h']| is integrated by
composite 8-point Gauss-Legendre quadrature on a fine table of u; the inverse u(s) starts
from a quintic Hermite interpolant of that table (it uses du/ds = 1/sigma and
d2u/ds2 = -sigma'/sigma^3 at the nodes), already within ~1e-11 m on the bundled tracks,
and is refined by one Newton step on the exact integral (quadratic convergence), so
``geodetic(s)`` is exact to rounding (|s(u(s)) - s| < 4e-12 m on the 35 km mountain
railway). The derivatives with respect to s follow by the chain rule::

    d1 = X' / sigma,    d2 = X'' / sigma^2 - X' sigma' / sigma^3

and are analytic (no finite differences anywhere).

Cant
----
:class:`CantModel`: none, or railway design cant from curvature,
tan(cant) = v_design^2 kappa / g, saturated smoothly at ``max_cant``
(``c = x / (1 + (x / c_max)^8)^(1/8)``, C-infinity, within 0.05 % of x for
|x| < c_max / 2) so the cant stays as smooth as the curvature. The curvature used for cant
is the geodesic curvature of the horizontal projection computed with the radii frozen at
the track's reference point (relative error ~ (h + Delta R) / R < 1e-4 against the exact
:attr:`TrackFrame.curvature`; it needs only third derivatives of the curve).
Positive cant = roll right side down, i.e. a right-hand curve (positive curvature) has
positive cant.

Sign conventions: heading clockwise from north, pitch = grade angle (up positive),
curvature positive turning right; see :class:`TrackFrame`.

References
----------
.. [1] Sokolov S.V., Vdovichenko S.S. (2012), seed 003: the spatial track models
       lambda(P, phi), h(A, lambda, phi), h(A, P, phi) and the derivatives the filter uses
       (V_X = dlambda/dphi V_Y cos(phi), V_Z = dh/dphi V_Y / (r + h)).
.. [2] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., 2013, sec. 2.4: curvilinear position, radii of curvature.
.. [3] Lindahl M., Track geometry for high-speed railways, KTH report, 2001: transition
       curves and the cant-curvature relation tan(cant) = v^2 / (g R).
.. [4] de Boor C., A Practical Guide to Splines, 2001 (B-splines; least-squares splines).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Any, Protocol, Sequence, Union, runtime_checkable

import numpy as np
from numpy.polynomial import Polynomial
from numpy.polynomial import polynomial as npoly
from numpy.typing import ArrayLike
from scipy.interpolate import (
    BSpline,
    PPoly,
    make_interp_spline,
    make_lsq_spline,
    make_splprep,
)

from ..earth import SPHERICAL, WGS84, EarthModel
from ..errors import ConfigError, TrackError

__all__ = [
    "Track",
    "TrackSegment",
    "TrackFrame",
    "CantModel",
    "PolynomialTrack",
    "PiecewisePolynomialTrack",
    "SplineTrack",
    "PolynomialFit",
    "track_frame",
    "fit_polynomial_track",
    "with_cant",
    "segment_mask",
]

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_NEWTON_STEPS = 1
_SOFTCLIP_POWER = 8


# ======================================================================== public types
@dataclass(frozen=True, slots=True)
class TrackSegment:
    """An annotation of the track between two arc lengths.

    Parameters
    ----------
    kind : str
        ``"tunnel"``, ``"cutting"``, ``"urban"``, ``"bridge"``, ``"station"``, ...
    s_start, s_end : float
        Arc length at the start and the end, m, ``s_start <= s_end``.
    name : str
        Optional label.
    """

    kind: str
    s_start: float
    s_end: float
    name: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.kind, str) or not self.kind:
            raise ConfigError("segment.kind", "a non-empty string", self.kind)
        for fld in ("s_start", "s_end"):
            value = getattr(self, fld)
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise ConfigError(f"segment.{fld}", "a number (m)", value) from None
            if not math.isfinite(number):
                raise ConfigError(f"segment.{fld}", "a finite number (m)", value)
            object.__setattr__(self, fld, number)
        if self.s_end < self.s_start:
            raise ConfigError("segment.s_end", f"s_end >= s_start = {self.s_start}", self.s_end)


@runtime_checkable
class Track(Protocol):
    """What the motion module needs from a track (all tracks here satisfy it)."""

    earth: EarthModel
    length: float
    segments: tuple[TrackSegment, ...]

    def geodetic(self, s: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """pos, d1, d2, each ``np.shape(s) + (3,)``: [lat, lon, h] (rad, rad, m) and
        their first and second derivatives with respect to true arc length s."""
        ...

    def cant(self, s: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Cant as a roll angle (rad, right side down positive) and d cant / ds (rad/m)."""
        ...


@dataclass(frozen=True, slots=True)
class TrackFrame:
    """Geometry of a track at arc lengths s (every array has the shape of s, or + (3,)).

    Attributes
    ----------
    lat, lon, h : ndarray
        Geodetic position, rad, rad, m.
    tangent_n : ndarray (..., 3)
        Unit tangent in ENU, t = [(R_E+h) cos(lat) lon', (R_N+h) lat', h'].
    dtangent_n_ds : ndarray (..., 3)
        d/ds of the ENU components of the unit tangent, 1/m (product rule with the radii
        derivatives; it includes the rotation of the ENU frame along the track).
    heading, pitch : ndarray
        atan2(t_E, t_N) clockwise from north, and asin(t_U) (grade angle, up positive), rad.
    dheading_ds, dpitch_ds : ndarray
        Their derivatives, rad/m: (t_N t'_E - t_E t'_N) / (t_E^2 + t_N^2), t'_U / sqrt(1 - t_U^2).
    cant, dcant_ds : ndarray
        Cant (roll, right side down positive), rad, and its derivative, rad/m.
    curvature : ndarray
        Signed geodesic curvature of the horizontal projection, 1/m, positive turning
        right: (dheading_ds - t_E tan(lat) / (R_E + h)) / cos(pitch). The second term
        removes the rotation of the ENU frame about Up (meridian convergence) so that a
        geodesic has zero curvature and a small circle of radius r has ~1/r.
    """

    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    tangent_n: np.ndarray
    dtangent_n_ds: np.ndarray
    heading: np.ndarray
    pitch: np.ndarray
    dheading_ds: np.ndarray
    dpitch_ds: np.ndarray
    cant: np.ndarray
    dcant_ds: np.ndarray
    curvature: np.ndarray


@dataclass(frozen=True, slots=True)
class CantModel:
    """How a track's cant (superelevation, a roll angle) is made.

    Parameters
    ----------
    mode : str
        ``"none"`` (zero cant) or ``"design"``: tan(cant) = v_design^2 kappa / g with kappa
        the horizontal curvature, smoothly limited to ``max_cant``.
    design_speed_mps : float
        Design speed v_design, m/s (mode ``"design"``).
    max_cant : float
        Largest cant angle, rad. 150 mm of cant on standard gauge (1435 mm; 1500 mm between
        rail-head centres) is asin(0.150 / 1.500) = 0.1002 rad; see :meth:`from_mm`.
    gravity_mps2 : float
        g in the design formula, m/s^2.
    """

    mode: str = "none"
    design_speed_mps: float = 0.0
    max_cant: float = math.asin(0.150 / 1.500)
    gravity_mps2: float = 9.81

    def __post_init__(self) -> None:
        if self.mode == "zero":
            object.__setattr__(self, "mode", "none")
        if self.mode not in ("none", "design"):
            raise ConfigError("cant.mode", "'none' or 'design'", self.mode)
        if self.mode == "design":
            for fld in ("design_speed_mps", "max_cant", "gravity_mps2"):
                value = getattr(self, fld)
                if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                    raise ConfigError(f"cant.{fld}", "a positive finite number", value)
            if self.max_cant >= math.pi / 4:
                raise ConfigError("cant.max_cant", "an angle below pi/4 rad", self.max_cant)

    @classmethod
    def from_mm(cls, design_speed_mps: float, max_cant_mm: float = 150.0,
                rail_spacing_mm: float = 1500.0) -> "CantModel":
        """Design cant with the limit given as rail-height difference over rail spacing."""
        if not 0 < max_cant_mm < rail_spacing_mm:
            raise ConfigError("cant.max_cant_mm", f"in (0, {rail_spacing_mm}) mm", max_cant_mm)
        return cls("design", design_speed_mps, math.asin(max_cant_mm / rail_spacing_mm))

    @classmethod
    def from_dict(cls, data: dict[str, Any] | None, source: str | None = None) -> "CantModel":
        """From a file's ``cant`` table: ``mode``, ``design_speed_mps`` and either
        ``max_cant_deg`` or ``max_cant_mm`` (with optional ``rail_spacing_mm``)."""
        if not data:
            return cls()
        if not isinstance(data, dict):
            raise ConfigError("cant", "a table/object", data, source)
        known = {"mode", "design_speed_mps", "max_cant_deg", "max_cant_mm", "rail_spacing_mm",
                 "gravity_mps2"}
        extra = set(data) - known
        if extra:
            raise ConfigError("cant", f"only keys {sorted(known)}", sorted(extra), source)
        mode = data.get("mode", "none")
        if mode in ("none", "zero"):
            return cls()
        try:
            speed = float(data["design_speed_mps"])
            if "max_cant_deg" in data:
                max_cant = math.radians(float(data["max_cant_deg"]))
            else:
                spacing = float(data.get("rail_spacing_mm", 1500.0))
                max_cant = math.asin(float(data.get("max_cant_mm", 150.0)) / spacing)
            return cls(mode, speed, max_cant, float(data.get("gravity_mps2", 9.81)))
        except KeyError as exc:
            raise ConfigError(f"cant.{exc.args[0]}", "present for mode 'design'", None, source) from None
        except (TypeError, ValueError) as exc:
            if isinstance(exc, ConfigError):
                raise ConfigError(exc.field, exc.expected, exc.got, source) from None
            raise ConfigError("cant", "numbers for design_speed_mps / max_cant_*", data, source) from None

    def to_dict(self) -> dict[str, Any]:
        if self.mode == "none":
            return {"mode": "none"}
        return {"mode": "design", "design_speed_mps": self.design_speed_mps,
                "max_cant_deg": math.degrees(self.max_cant), "gravity_mps2": self.gravity_mps2}

    def evaluate(self, kappa: np.ndarray, dkappa_ds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cant and d cant / ds from curvature (1/m) and its derivative (1/m^2)."""
        kappa = np.asarray(kappa, dtype=float)
        if self.mode == "none":
            return np.zeros_like(kappa), np.zeros_like(kappa)
        gain = self.design_speed_mps**2 / self.gravity_mps2
        x = gain * kappa
        raw = np.arctan(x)  # tan(cant) = v^2 kappa / g
        draw = gain * np.asarray(dkappa_ds, dtype=float) / (1.0 + x * x)
        q = (raw / self.max_cant) ** _SOFTCLIP_POWER
        p = 1.0 / _SOFTCLIP_POWER
        return raw * (1.0 + q) ** (-p), draw * (1.0 + q) ** (-p - 1.0)


# ======================================================================== the engine
class _ArcLengthTrack:
    """A curve X(u) = [lat, lon, h](u) re-parameterised by true arc length.

    Subclasses set ``earth``, ``segments``, ``name``, ``cant_model`` and implement
    ``_curve(u, order)`` returning [X, X', ..., X^(order)] (each (..., 3)) for order <= 3,
    then call ``_build_table(u_breaks)`` with breakpoints fine enough that sigma is smooth
    and slowly varying on each interval (the curve's own breakpoints must be among them).
    """

    earth: EarthModel
    length: float
    segments: tuple[TrackSegment, ...]
    name: str
    cant_model: CantModel

    # -------------------------------------------------------------- to implement
    def _curve(self, u: np.ndarray, order: int) -> list[np.ndarray]:  # pragma: no cover
        raise NotImplementedError

    # -------------------------------------------------------------- metric speed
    def _sigma(self, x: list[np.ndarray], with_derivative: bool = False):
        """sigma = ds/du and (optionally) d sigma / du from [X, X', X'']."""
        x0, x1 = x[0], x[1]
        lat, h = x0[..., 0], x0[..., 2]
        r_n, r_e = self.earth.radii(lat)
        clat = np.cos(lat)
        m_n = r_n + h
        m_e = (r_e + h) * clat
        v_n = m_n * x1[..., 0]
        v_e = m_e * x1[..., 1]
        v_u = x1[..., 2]
        sigma = np.sqrt(v_n * v_n + v_e * v_e + v_u * v_u)
        if not with_derivative:
            return sigma
        x2 = x[2]
        dr_n, dr_e = self.earth.radii_derivative(lat)
        dm_n = dr_n * x1[..., 0] + x1[..., 2]
        dm_e = (dr_e * x1[..., 0] + x1[..., 2]) * clat - (r_e + h) * np.sin(lat) * x1[..., 0]
        # sigma sigma' = sum m m' x'^2 + m^2 x' x''
        dsigma = (
            v_n * (dm_n * x1[..., 0] + m_n * x2[..., 0])
            + v_e * (dm_e * x1[..., 1] + m_e * x2[..., 1])
            + v_u * x2[..., 2]
        ) / sigma
        return sigma, dsigma

    def _sigma_at(self, u: np.ndarray) -> np.ndarray:
        return self._sigma(self._curve(u, 1))

    # -------------------------------------------------------------- table
    def _build_table(self, u_breaks: np.ndarray) -> None:
        u_breaks = np.asarray(u_breaks, dtype=float)
        if u_breaks.ndim != 1 or u_breaks.size < 2 or np.any(np.diff(u_breaks) <= 0):
            raise TrackError("internal: arc-length table breakpoints must increase")
        a, b = u_breaks[:-1], u_breaks[1:]
        half = 0.5 * (b - a)
        nodes = 0.5 * (a + b)[:, None] + half[:, None] * _GL_X
        sig_nodes = self._sigma_at(nodes)
        if not np.all(np.isfinite(sig_nodes)) or np.any(sig_nodes <= 0):
            raise TrackError(f"track {self.name!r}: the curve is singular (zero or non-finite speed ds/du)")
        ds = half * (sig_nodes @ _GL_W)  # composite Gauss-Legendre
        s_breaks = np.concatenate([[0.0], np.cumsum(ds)])
        sig, dsig = self._sigma(self._curve(u_breaks, 2), with_derivative=True)
        self._u_breaks = u_breaks
        self._s_breaks = s_breaks
        self._du_ds = 1.0 / sig
        self._d2u_ds2 = -dsig / sig**3
        self.length = float(s_breaks[-1])

    def _s_of_u(self, u: np.ndarray) -> np.ndarray:
        """Arc length at parameter u (table value plus Gauss-Legendre on the remainder)."""
        ub = self._u_breaks
        u = np.clip(np.asarray(u, dtype=float), ub[0], ub[-1])
        k = np.clip(np.searchsorted(ub, u, side="right") - 1, 0, ub.size - 2)
        half = 0.5 * (u - ub[k])
        nodes = (ub[k] + half)[..., None] + half[..., None] * _GL_X
        return self._s_breaks[k] + half * (self._sigma_at(nodes) @ _GL_W)

    def _check_s(self, s: ArrayLike) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        tol = 1e-9 * max(1.0, self.length)
        if not np.all(np.isfinite(s)):
            raise TrackError(f"track {self.name!r}: arc length s must be finite")
        if s.size and (s.min() < -tol or s.max() > self.length + tol):
            raise TrackError(
                f"track {self.name!r}: arc length s must lie in [0, {self.length:.6f}] m, "
                f"got values in [{s.min():.6f}, {s.max():.6f}] m"
            )
        return np.clip(s, 0.0, self.length)

    def _u_of_s(self, s: np.ndarray) -> np.ndarray:
        """u(s): quintic Hermite start, then Newton steps on the exact integral."""
        sb, ub = self._s_breaks, self._u_breaks
        k = np.clip(np.searchsorted(sb, s, side="right") - 1, 0, sb.size - 2)
        s0, s1 = sb[k], sb[k + 1]
        dh = s1 - s0
        t = (s - s0) / dh
        t2, t3 = t * t, t * t * t
        t4, t5 = t3 * t, t3 * t2
        u = (
            (1 - 10 * t3 + 15 * t4 - 6 * t5) * ub[k]
            + (t - 6 * t3 + 8 * t4 - 3 * t5) * dh * self._du_ds[k]
            + 0.5 * (t2 - 3 * t3 + 3 * t4 - t5) * dh * dh * self._d2u_ds2[k]
            + (10 * t3 - 15 * t4 + 6 * t5) * ub[k + 1]
            + (-4 * t3 + 7 * t4 - 3 * t5) * dh * self._du_ds[k + 1]
            + 0.5 * (t3 - 2 * t4 + t5) * dh * dh * self._d2u_ds2[k + 1]
        )
        ua = ub[k]
        for _ in range(_NEWTON_STEPS):
            half = 0.5 * (u - ua)
            nodes = np.concatenate(
                [(ua + half)[..., None] + half[..., None] * _GL_X, u[..., None]], axis=-1
            )
            sig = self._sigma_at(nodes)
            residual = s0 + half * (sig[..., :-1] @ _GL_W) - s  # s(u) - s
            u = u - residual / sig[..., -1]
        return u

    # -------------------------------------------------------------- the protocol
    def geodetic(self, s: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position [lat, lon, h] and its first and second derivatives in true arc length.

        Parameters
        ----------
        s : array_like
            Arc length, m, within [0, length].

        Returns
        -------
        pos, d1, d2 : ndarray, each ``np.shape(s) + (3,)``
            [lat, lon, h] in rad, rad, m; d1 in rad/m, rad/m, m/m; d2 in rad/m^2, 1/m.
            The metric norm |[(R_N+h) lat', (R_E+h) cos(lat) lon', h']| of d1 is 1.
        """
        s = self._check_s(s)
        u = self._u_of_s(s)
        return self._geodetic_at(self._curve(u, 2))

    def _geodetic_at(self, x: list[np.ndarray]):
        sig, dsig = self._sigma(x, with_derivative=True)
        inv = (1.0 / sig)[..., None]
        d1 = x[1] * inv
        d2 = x[2] * inv * inv - x[1] * (dsig / sig**3)[..., None]
        return x[0], d1, d2

    def _geodetic_and_cant(self, s: ArrayLike):
        """geodetic(s) and cant(s) sharing one inversion u(s) (used by track_frame)."""
        s = self._check_s(s)
        u = self._u_of_s(s)
        if self.cant_model.mode == "none":
            pos, d1, d2 = self._geodetic_at(self._curve(u, 2))
            return pos, d1, d2, np.zeros_like(s), np.zeros_like(s)
        x = self._curve(u, 3)
        pos, d1, d2 = self._geodetic_at(x)
        return (pos, d1, d2) + self.cant_model.evaluate(*self._plan_curvature_at(x))

    def cant(self, s: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Cant (rad, right side down positive) and d cant / ds (rad/m) at arc lengths s."""
        s = self._check_s(s)
        if self.cant_model.mode == "none":
            return np.zeros_like(s), np.zeros_like(s)
        kappa, dkappa = self.plan_curvature(s)
        return self.cant_model.evaluate(kappa, dkappa)

    def plan_curvature(self, s: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Horizontal geodesic curvature (1/m, right positive) and its derivative (1/m^2).

        Computed with the radii frozen at the track's reference point (see the module
        docstring); this is the curvature the design cant uses.
        """
        s = self._check_s(s)
        return self._plan_curvature_at(self._curve(self._u_of_s(s), 3))

    def _plan_curvature_at(self, x: list[np.ndarray]):
        sig = self._sigma(x)
        c_n, c_e = self._plan_scale
        lat = x[0][..., 0]
        f1, f2, f3 = x[1][..., 0], x[2][..., 0], x[3][..., 0]
        l1, l2, l3 = x[1][..., 1], x[2][..., 1], x[3][..., 1]
        sl, cl = np.sin(lat), np.cos(lat)
        te = c_e * cl * l1
        tn = c_n * f1
        dte = c_e * (cl * l2 - sl * f1 * l1)
        dtn = c_n * f2
        d2te = c_e * (cl * l3 - 2 * sl * f1 * l2 - cl * f1 * f1 * l1 - sl * f2 * l1)
        d2tn = c_n * f3
        q = te * te + tn * tn
        dq = 2 * (te * dte + tn * dtn)
        num = tn * dte - te * dtn
        dnum = tn * d2te - te * d2tn
        conv = sl * l1  # rotation of ENU about Up per unit u (meridian convergence)
        dconv = cl * f1 * l1 + sl * l2
        g = num / q - conv
        dg = dnum / q - num * dq / (q * q) - dconv
        rq = np.sqrt(q)
        kappa = g / rq
        dkappa_du = dg / rq - 0.5 * g * dq / (q * rq)
        return kappa, dkappa_du / sig

    # -------------------------------------------------------------- smoothness
    @property
    def knot_s(self) -> np.ndarray:
        """Arc lengths (m, increasing) strictly inside the track where the curve's pieces
        join, so that some derivative of the geometry (and of the design cant) jumps.

        Empty for a curve that is analytic over the whole track. Read-only: the fast truth
        generator (:mod:`navsim.truthgen`) splits its interpolation intervals there.
        """
        return np.zeros(0)

    # -------------------------------------------------------------- helpers
    def _set_plan_scale(self, lat_ref: float, h_ref: float) -> None:
        r_n, r_e = self.earth.radii(np.array(lat_ref))
        self._plan_scale = (float(r_n) + h_ref, float(r_e) + h_ref)

    def _check_segments(self, segments: Sequence[TrackSegment]) -> tuple[TrackSegment, ...]:
        out = []
        tol = 1e-6 * max(1.0, self.length) + 1e-3
        for i, seg in enumerate(segments):
            if not isinstance(seg, TrackSegment):
                raise ConfigError(f"segments[{i}]", "a TrackSegment", seg)
            if seg.s_start < -tol or seg.s_end > self.length + tol:
                raise TrackError(
                    f"track {self.name!r}: segment {i} ({seg.kind} {seg.name!r}) spans "
                    f"[{seg.s_start}, {seg.s_end}] m, outside the track [0, {self.length:.3f}] m"
                )
            out.append(TrackSegment(seg.kind, max(0.0, seg.s_start), min(self.length, seg.s_end), seg.name))
        return tuple(sorted(out, key=lambda g: (g.s_start, g.s_end)))

    def with_cant_model(self, cant_model: CantModel):
        """A copy of this track with another cant model (geometry shared)."""
        if not isinstance(cant_model, CantModel):
            raise ConfigError("cant_model", "a CantModel", cant_model)
        new = copy.copy(self)
        new.cant_model = cant_model
        return new

    def with_segments(self, segments: Sequence[TrackSegment]):
        """A copy of this track with other segments."""
        new = copy.copy(self)
        new.segments = new._check_segments(segments)
        return new

    def with_earth(self, earth: EarthModel):
        """The same curve (same lat, lon, h functions) on another Earth model.

        The arc length changes with the metric, so the table is rebuilt and the segments
        are moved to the new arc lengths of the same points.
        """
        if not isinstance(earth, EarthModel):
            raise ConfigError("earth", "an EarthModel", earth)
        if earth == self.earth:
            return self
        new = copy.copy(self)
        new.earth = earth
        new._build_table(self._u_breaks)
        new._set_plan_scale(*self._plan_ref)
        ends = np.array([[g.s_start, g.s_end] for g in self.segments]).reshape(-1, 2)
        ends_new = new._s_of_u(self._u_of_s(ends)) if ends.size else ends
        new.segments = new._check_segments(
            [TrackSegment(g.kind, float(a), float(b), g.name) for g, (a, b) in zip(self.segments, ends_new)]
        )
        return new

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(name={self.name!r}, length={self.length:.3f} m, "
                f"earth={self.earth.name}, segments={len(self.segments)}, cant={self.cant_model.mode})")


def _default_table(u0: float, u1: float, speed_estimate: float, max_step_m: float) -> np.ndarray:
    n = max(4, int(math.ceil(abs(u1 - u0) * speed_estimate / max_step_m)))
    return np.linspace(u0, u1, n + 1)


# ======================================================================== latitude tracks
class _LatitudeTrack(_ArcLengthTrack):
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
        breaks = _default_table(0.0, span, speed, max_step_m)
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
        P = shifted.coef.copy()
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
        p_shift = Polynomial(P)(Polynomial([phi0, 1.0])).coef
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


# ======================================================================== spline track
class SplineTrack(_ArcLengthTrack):
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
        lat, lon, h = _check_waypoints(lat, lon, h, name)
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


def _check_waypoints(lat: ArrayLike, lon: ArrayLike, h: ArrayLike, name: str):
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


# ======================================================================== frame
def track_frame(track: Track, s: ArrayLike) -> TrackFrame:
    """Tangent, heading, pitch, curvature and cant of a track at arc lengths s (m).

    See :class:`TrackFrame` for the definitions; everything is analytic in the track's
    first and second derivatives.
    """
    if isinstance(track, _ArcLengthTrack):
        pos, d1, d2, cant, dcant = track._geodetic_and_cant(s)
    else:
        pos, d1, d2 = track.geodetic(s)
        cant, dcant = track.cant(s)
    earth = track.earth
    lat, lon, h = pos[..., 0], pos[..., 1], pos[..., 2]
    lat1, lon1, h1 = d1[..., 0], d1[..., 1], d1[..., 2]
    lat2, lon2, h2 = d2[..., 0], d2[..., 1], d2[..., 2]
    r_n, r_e = earth.radii(lat)
    dr_n, dr_e = earth.radii_derivative(lat)
    sl, cl = np.sin(lat), np.cos(lat)
    t_e = (r_e + h) * cl * lon1
    t_n = (r_n + h) * lat1
    t_u = h1
    dt_e = (dr_e * lat1 + h1) * cl * lon1 - (r_e + h) * sl * lat1 * lon1 + (r_e + h) * cl * lon2
    dt_n = (dr_n * lat1 + h1) * lat1 + (r_n + h) * lat2
    dt_u = h2
    horiz2 = t_e * t_e + t_n * t_n
    horiz = np.sqrt(horiz2)
    heading = np.arctan2(t_e, t_n)
    pitch = np.arcsin(np.clip(t_u, -1.0, 1.0))
    dheading = (t_n * dt_e - t_e * dt_n) / horiz2
    dpitch = dt_u / horiz  # sqrt(1 - t_U^2) = horizontal norm for a unit tangent
    curvature = (dheading - t_e * np.tan(lat) / (r_e + h)) / horiz
    return TrackFrame(
        lat=lat, lon=lon, h=h,
        tangent_n=np.stack([t_e, t_n, t_u], axis=-1),
        dtangent_n_ds=np.stack([dt_e, dt_n, dt_u], axis=-1),
        heading=heading, pitch=pitch, dheading_ds=dheading, dpitch_ds=dpitch,
        cant=cant, dcant_ds=dcant, curvature=curvature,
    )


def segment_mask(track: Track, s: ArrayLike, kind: str | Sequence[str]) -> np.ndarray:
    """True where s lies inside a segment of the given kind(s), shape of s."""
    s = np.asarray(s, dtype=float)
    kinds = {kind} if isinstance(kind, str) else set(kind)
    mask = np.zeros(s.shape, dtype=bool)
    for seg in track.segments:
        if seg.kind in kinds:
            mask |= (s >= seg.s_start) & (s <= seg.s_end)
    return mask


def with_cant(track: Track, mode: str = "none", design_speed: float = 0.0,
              max_cant: float = math.asin(0.150 / 1.500)) -> Track:
    """The track with another cant model: ``mode`` "none" or "design" (design speed m/s,
    maximum cant rad). "track" returns the track unchanged."""
    if mode == "track":
        return track
    model = CantModel() if mode in ("none", "zero") else CantModel(mode, float(design_speed), float(max_cant))
    if not hasattr(track, "with_cant_model"):
        raise ConfigError("track", "a navsim track that supports with_cant_model", type(track).__name__)
    return track.with_cant_model(model)  # type: ignore[attr-defined]


# ======================================================================== fitting
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


def _fit_errors(earth, phi, lam, h, lam_fit, dlam_fit, h_fit):
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
        phi, lam, h = _check_waypoints(phi, lam, h, "fit")
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


def _clip_segments(segments, length):
    out = []
    for g in segments:
        if g.s_start <= length:
            out.append(TrackSegment(g.kind, max(0.0, g.s_start), min(length, g.s_end), g.name))
    return tuple(out)


def _make_fit(track, degree, breakpoints, cross, dh, n_points) -> PolynomialFit:
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
