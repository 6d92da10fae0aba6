"""The arc-length engine every track is built on (:class:`ArcLengthTrack`).

A curve X(u) = [lat, lon, h](u) in a convenient parameter u is re-parameterised by its true
arc length s: the speed sigma(u) = ds/du = |[(R_N + h) lat', (R_E + h) cos(lat) lon', h']|
(Groves 2013, sec. 2.4) is integrated by composite 8-point Gauss-Legendre quadrature on a
fine table of u; u(s) starts from a quintic Hermite interpolant of that table and is refined
by Newton steps on the exact integral. The s-derivatives follow by the chain rule,
``d1 = X' / sigma``, ``d2 = X'' / sigma^2 - X' sigma' / sigma^3`` (analytic).
"""


import copy
import math
from typing import Literal, Sequence, TypeVar, overload

import numpy as np
from numpy.typing import ArrayLike

from ..earth import EarthModel
from ..errors import ConfigError, TrackError
from .base import CantModel, TrackSegment

_Self = TypeVar("_Self", bound="ArcLengthTrack")  # the with_* copies keep the subclass

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_NEWTON_STEPS = 1


class ArcLengthTrack:
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
    _plan_ref: tuple[float, float]  # (lat, h) of the plan-curvature scale, set by the subclass

    # -------------------------------------------------------------- to implement
    def _curve(self, u: np.ndarray, order: int) -> list[np.ndarray]:  # pragma: no cover
        raise NotImplementedError

    # -------------------------------------------------------------- metric speed
    @overload
    def _sigma(self, x: list[np.ndarray], with_derivative: Literal[False] = ...) -> np.ndarray: ...

    @overload
    def _sigma(self, x: list[np.ndarray], with_derivative: Literal[True]) -> tuple[np.ndarray, np.ndarray]: ...

    def _sigma(self, x: list[np.ndarray],
               with_derivative: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
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

    def _geodetic_at(self, x: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        sig, dsig = self._sigma(x, with_derivative=True)
        inv = (1.0 / sig)[..., None]
        d1 = x[1] * inv
        d2 = x[2] * inv * inv - x[1] * (dsig / sig**3)[..., None]
        return x[0], d1, d2

    def _geodetic_and_cant(self, s: ArrayLike) -> tuple[np.ndarray, ...]:
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

    def _plan_curvature_at(self, x: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
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

    def with_cant_model(self: _Self, cant_model: CantModel) -> _Self:
        """A copy of this track with another cant model (geometry shared)."""
        if not isinstance(cant_model, CantModel):
            raise ConfigError("cant_model", "a CantModel", cant_model)
        new = copy.copy(self)
        new.cant_model = cant_model
        return new

    def with_segments(self: _Self, segments: Sequence[TrackSegment]) -> _Self:
        """A copy of this track with other segments."""
        new = copy.copy(self)
        new.segments = new._check_segments(segments)
        return new

    def with_earth(self: _Self, earth: EarthModel) -> _Self:
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


def default_table(u0: float, u1: float, speed_estimate: float, max_step_m: float) -> np.ndarray:
    n = max(4, int(math.ceil(abs(u1 - u0) * speed_estimate / max_step_m)))
    return np.linspace(u0, u1, n + 1)
