"""Loop-free free-inertial integration: prefix products and a fixed point per window.

The sequential integrator :func:`navsim.strapdown.ins.integrate` (``method="sequential"``)
advances one navigation step at a time in Python. This module computes *the same discrete
solution* without a per-step loop: every step's equations are evaluated for a whole window
of steps at once with numpy, and the recursions are solved with prefix operations.

The discrete system (one step k -> k+1, see :mod:`navsim.strapdown.ins`) is::

    q(k+1)   = q(-zeta_k) o q(k) o q(Phi_k)                       attitude
    v(k+1)   = v(k) + u_k - zeta_k x r_k + (gc_k + gc1_k) dt/2     velocity
    lat(k+1) = lat(k) + D_N / mean(R_N + h),  lon, h alike        position

where ``u_k = C(q(k)) dV_k`` and ``zeta_k``, ``gc_k``, ``gc1_k`` and the radii come from
the Earth model at the state ``x_k`` and at the predictor point built from ``x_k``.
The body-frame terms ``Phi_k``, ``dV_k``, ``dS_k`` do not depend on the state; the
navigation-frame terms depend on it only weakly (Earth rate 7.3e-5 rad/s, transport rate
v/R, Coriolis 2 Omega, gravity gradient 2 g/R). Hence, for a window of N steps starting
from a known state:

1. Body prefix products (once per window): ``P_k = q(0) o q(Phi_0) o ... o q(Phi_k-1)``
   by a work-efficient pairwise parallel scan (the Blelloch up-sweep/down-sweep in the
   odd/even form: 2N quaternion products, log2 N vectorised levels). Quaternion
   multiplication is associative, so this is exact up to rounding.
2. A fixed-point (Picard) iteration on the state trajectory ``x_0..x_N``. From the
   current guess every step's navigation-frame terms are evaluated at once; then

   * attitude ``q(k) = Z_k o P_k`` with the navigation-frame product
     ``Z_k+1 = q(-zeta_k) o Z_k``, ``Z_0 = 1``, written as
     ``Z_k+1 = 1 + sum_j<=k (q(-zeta_j) - 1) o Z_j`` (a cumulative sum over the previous
     guess of Z: its increments are of order |zeta| ~ 1e-6, so this is computed with
     small-number precision, and the guess error shrinks by sum |zeta|/2 per iteration);
   * velocity: cumulative sum of the per-step increments;
   * position: cumulative sum of the per-step increments of lat, lon, h relative to
     the window start, added once to the start value (error-free transformation
     ``Fast2Sum``: the compensation carried in :class:`InsState` is the exact rounding
     error of that addition, the quantity the sequential Kahan sums carry).

   The fixed point of the iteration is the sequential solution: at the fixed point
   every step's equation holds exactly as written above. The iteration stops when the
   change of velocity, attitude and position from one iteration to the next is at the
   rounding level of those quantities (see :func:`integrate_scan`); the error left
   is the change times the contraction factor of the iteration, below 1e-2 for the
   default window of 50 s at 100 Hz (Coriolis 2 Omega T, Schuler g T^2 / 2R, sum |zeta| / 2).
   If a window does not converge within ``max_iterations`` it is split in two and
   each half is solved in turn (high dynamics, very long windows).

Accuracy: with the same body terms the scan solution differs from the sequential one by
rounding only.

Chunking: windows start at the first step of each call and have ``window`` steps
(the last one fewer). Splitting a run into calls at multiples of ``window`` steps gives
*exactly* the numbers of one call (the iteration of a window depends only on its start
state and its data). Splitting elsewhere moves the window boundaries and changes the
numbers at the rounding level.

References
----------
.. [1] Blelloch G.E. (1990), Prefix sums and their applications, CMU-CS-90-190
       (work-efficient parallel scan of any associative operator).
.. [2] Hillis W.D., Steele G.L. (1986), Data parallel algorithms, CACM 29(12).
.. [3] Lelarasmee E., Ruehli A.E., Sangiovanni-Vincentelli A.L. (1982), The waveform
       relaxation method for time-domain analysis of large scale integrated circuits,
       IEEE TCAD 1(3) (Picard iteration on whole time windows).
.. [4] Dekker T.J. (1971), A floating-point technique for extending the available
       precision, Numer. Math. 18 (Fast2Sum).
.. [5] Litmanovich Yu.A. (2002), seed 000; Savage P.G. (2007), Strapdown Analytics,
       ch. 7: the discrete mechanisation this module solves (see :mod:`.ins`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..earth import EarthModel
from .state import InsSolution, InsState

# The helpers below take quaternion / matrix components as tuples of floats or of arrays
# (the same expressions serve one step and a whole window): typed Any.

__all__ = ["DEFAULT_WINDOW", "prefix_quat_products", "integrate_scan"]

DEFAULT_WINDOW = 5000
"""Default window length in navigation steps (50 s at 100 Hz; 4-5 iterations per window measured)."""

_EPS = np.finfo(float).eps


# ----------------------------------------------------------------------------- quaternions
def _qmul(a: Any, b: Any) -> tuple[Any, Any, Any, Any]:
    """Hamilton product of quaternion component tuples/arrays (scalar first), row-wise."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return (
        a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
        a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
        a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
        a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
    )


def _prefix(q: np.ndarray) -> np.ndarray:
    """Inclusive prefix products ``q[0] o q[1] o ... o q[k]`` of a (4, n) array."""
    n = q.shape[1]
    if n <= 16:  # short tails: a plain loop on Python floats is cheaper than numpy calls
        out = np.empty_like(q)
        acc = tuple(float(x) for x in q[:, 0])
        out[:, 0] = acc
        cols = q.T.tolist()
        for k in range(1, n):
            acc = _qmul(acc, cols[k])
            out[:, k] = acc
        return out
    m = n // 2
    even, odd = q[:, 0:2 * m:2], q[:, 1:2 * m:2]
    pairs = np.array(_qmul(even, odd))  # q[2i] o q[2i+1]
    pp = _prefix(pairs)  # q[0] o ... o q[2i+1]
    out = np.empty_like(q)
    out[:, 0] = q[:, 0]
    out[:, 1:2 * m:2] = pp
    ne = (n - 1) // 2  # even indices 2, 4, ..., 2 ne
    if ne:
        out[:, 2:2 * ne + 1:2] = _qmul(pp[:, :ne], q[:, 2:2 * ne + 1:2])
    return out


def prefix_quat_products(quat: np.ndarray) -> np.ndarray:
    """Inclusive prefix products of a sequence of quaternions by a parallel scan.

    Parameters
    ----------
    quat : array_like, shape (n, 4)
        Quaternions, scalar first.

    Returns
    -------
    ndarray, shape (n, 4)
        Row k is ``quat[0] o quat[1] o ... o quat[k]`` (Hamilton product), computed with
        2n products in ceil(log2 n) vectorised levels; equal to the sequential product
        up to rounding (|error| ~ sqrt(log-depth) ulp per level).
    """
    q = np.asarray(quat, dtype=float)
    if q.ndim != 2 or q.shape[1] != 4:
        raise ValueError(f"quat must have shape (n, 4), got {q.shape}")
    if len(q) == 0:
        return q.copy()
    return _prefix(np.ascontiguousarray(q.T)).T.copy()


# ----------------------------------------------------------------------------- Earth terms
class _Earth:
    """Constants of :func:`navsim.strapdown.ins._run`'s ``evaluate``, vectorised."""

    def __init__(self, earth: EarthModel) -> None:
        self.a, self.e2, self.rate, self.f = earth.a, earth.e2, earth.rate, earth.f
        self.spherical = earth.name == "spherical"
        self.flat = earth.f == 0.0
        self.g0 = earth.g0
        self.gamma_e, self.k_som = 9.7803253359, 0.00193185265241  # TR8350.2, as in earth.gravity_n
        self.m_som = self.rate**2 * self.a**2 * self.a * (1.0 - self.f) / earth.gm
        self.rate2 = self.rate * self.rate

    def evaluate(self, lat: Any, h: Any, ve: Any, vn: Any, vu: Any) -> tuple[Any, ...]:
        """Radii, rates and gc = g - (2 w_ie + w_en) x v (mirrors ins._run.evaluate)."""
        a, e2 = self.a, self.e2
        sl, cl = np.sin(lat), np.cos(lat)
        s2 = sl * sl
        if self.flat:
            rnh = reh = a + h
        else:
            w2 = 1.0 - e2 * s2
            w = np.sqrt(w2)
            reh = a / w + h
            rnh = a * (1.0 - e2) / (w2 * w) + h
        if self.spherical:
            rc = self.rate2 * (a + h) * cl
            gn, gu = -rc * sl, rc * cl - self.g0
        else:
            gamma = self.gamma_e * (1.0 + self.k_som * s2) / np.sqrt(1.0 - e2 * s2)
            gn = 0.0
            gu = -gamma * (1.0 - 2.0 / a * (1.0 + self.f + self.m_som - 2.0 * self.f * s2) * h
                           + 3.0 / (a * a) * h * h)
        wie_n, wie_u = self.rate * cl, self.rate * sl
        wen_e, wen_n = -vn / rnh, ve / reh
        wen_u = wen_n * sl / cl
        cn, cu = 2.0 * wie_n + wen_n, 2.0 * wie_u + wen_u
        gce = -(cn * vu - cu * vn)
        gcn = gn - (cu * ve - wen_e * vu)
        gcu = gu - (wen_e * vn - cn * ve)
        return rnh, reh, cl, wen_e, wie_n + wen_n, wie_u + wen_u, gce, gcn, gcu


def _mat(q0: Any, q1: Any, q2: Any, q3: Any) -> tuple[Any, ...]:
    """Rows of mat_nb from quaternion components (as in ins._run)."""
    s0, s1, s2, s3 = q0 * q0, q1 * q1, q2 * q2, q3 * q3
    c00 = s0 + s1 - s2 - s3
    c11 = s0 - s1 + s2 - s3
    c22 = s0 - s1 - s2 + s3
    p12, p03 = q1 * q2, q0 * q3
    p13, p02 = q1 * q3, q0 * q2
    p23, p01 = q2 * q3, q0 * q1
    return (c00, 2 * (p12 - p03), 2 * (p13 + p02),
            2 * (p12 + p03), c11, 2 * (p23 - p01),
            2 * (p13 - p02), 2 * (p23 + p01), c22)


def _rotate(c: tuple[Any, ...], x: Any, y: Any, z: Any) -> tuple[Any, Any, Any]:
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = c
    return (c00 * x + c01 * y + c02 * z, c10 * x + c11 * y + c12 * z, c20 * x + c21 * y + c22 * z)


def _zrot(z: Any, v: Any) -> tuple[Any, Any, Any]:
    """C(Z) v for a unit quaternion Z near 1: v + w t + z x t, t = 2 z x v."""
    w, x, y, zc = z
    vx, vy, vz = v
    tx, ty, tz = 2.0 * (y * vz - zc * vy), 2.0 * (zc * vx - x * vz), 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - zc * ty), vy + w * ty + (zc * tx - x * tz), vz + w * tz + (x * ty - y * tx))


def _cumsum_from(start: float, increments: np.ndarray) -> np.ndarray:
    """[start, start + d0, start + d0 + d1, ...] (n + 1 values)."""
    out = np.empty(len(increments) + 1)
    out[0] = 0.0
    np.cumsum(increments, out=out[1:])
    out += start
    out[0] = start
    return out


# ----------------------------------------------------------------------------- one window
def _solve_window(start: tuple[Any, ...], qb: np.ndarray, dvb: np.ndarray, dsb: np.ndarray | None, rule: str | None,
                  dt: float, E: _Earth, max_iterations: int) -> tuple[Any, ...] | None:
    """Solve N steps from ``start`` = (lat, lon, h, comp(3), v(3), q(4)).

    Returns (lat, lon, h, ve, vn, vu, q (4, N+1), comp (3,), iterations) or None if the
    iteration did not converge.
    """
    lat0, lon0, h0, (k_lat, k_lon, k_h), (ve0, vn0, vu0), qs = start
    n = qb.shape[1]
    half_dt, dt2_6, third, inv_dt = 0.5 * dt, dt * dt / 6.0, 1.0 / 3.0, 1.0 / dt
    exact = dsb is not None
    trapezoid = rule == "trapezoid"
    dx, dy, dz = dvb
    # 1. body prefix products P_k = q0 o q(Phi_0) o ... o q(Phi_k-1), k = 0..n
    seq = np.empty((4, n + 1))
    seq[:, 0] = qs
    seq[:, 1:] = qb
    P: Any = _prefix(seq)  # (4, n + 1), then a tuple of its rows
    s = 1.0 / np.sqrt(P[0] * P[0] + P[1] * P[1] + P[2] * P[2] + P[3] * P[3])
    P *= s
    P = (P[0], P[1], P[2], P[3])
    # 2. initial guess: the navigation-frame terms frozen at the window start. Z_k is then
    #    a rotation about a fixed axis (closed form), velocity and position are sums.
    one = np.ones(1)
    rnh0, reh0, cl0, wx0, wy0, wz0, ge0, gn0, gu0 = (
        float(np.asarray(x).reshape(-1)[0]) for x in E.evaluate(lat0 * one, h0 * one, ve0 * one, vn0 * one, vu0 * one))
    rate0 = math.sqrt(wx0 * wx0 + wy0 * wy0 + wz0 * wz0)
    half = (0.5 * dt * rate0) * np.arange(n + 1)
    zw = np.cos(half)
    sn_ = -np.sin(half) / rate0 if rate0 > 0.0 else np.zeros(n + 1)
    zx, zy, zz = sn_ * wx0, sn_ * wy0, sn_ * wz0
    # u = C(q) dV = C(Z) C(P) dV: C(P) dV (and C(P) dS) once per window
    c = _mat(*(x[:n] for x in P))
    u_body = _rotate(c, dx, dy, dz)
    s_body = _rotate(c, *dsb) if dsb is not None else None  # (dsb is not None: exact)
    u = _zrot((zw[:n], zx[:n], zy[:n], zz[:n]), u_body)
    ve, vn, vu = _cumsum_from(ve0, u[0] + ge0 * dt), _cumsum_from(vn0, u[1] + gn0 * dt), _cumsum_from(vu0, u[2] + gu0 * dt)
    y_lat = _cumsum_from(-k_lat, vn[:n] * (dt / rnh0))
    y_lon = _cumsum_from(-k_lon, ve[:n] * (dt / (reh0 * cl0)))
    y_h = _cumsum_from(-k_h, vu[:n] * dt)
    lat, lon, h = lat0 + y_lat, lon0 + y_lon, h0 + y_h
    tol_q = 64.0 * _EPS
    previous = math.inf
    for it in range(1, max_iterations + 1):
        # navigation-frame terms along the guess (ins._run steps 1-2)
        rnh, reh, cl, wx, wy, wz, ge, gn, gu = E.evaluate(lat[:n], h[:n], ve[:n], vn[:n], vu[:n])
        ue, un, uu = u
        ze, zn, zu = wx * half_dt, wy * half_dt, wz * half_dt
        pe = ve[:n] + ue - (zn * uu - zu * un) + ge * dt
        pn = vn[:n] + un - (zu * ue - ze * uu) + gn * dt
        pu = vu[:n] + uu - (ze * un - zn * ue) + gu * dt
        lat_p = lat[:n] + (vn[:n] + pn) * half_dt / rnh
        h_p = h[:n] + (vu[:n] + pu) * half_dt
        rnh1, reh1, cl1, wx1, wy1, wz1, ge1, gn1, gu1 = E.evaluate(lat_p, h_p, pe, pn, pu)
        ze, zn, zu = (wx + wx1) * half_dt, (wy + wy1) * half_dt, (wz + wz1) * half_dt  # zeta
        # attitude: Z_k+1 = Z_k + (q(-zeta_k) - 1) o Z_k on the guess of Z, q = Z o P
        z2 = ze * ze + zn * zn + zu * zu
        m0 = z2 * (z2 / 384.0 - 0.125)  # cos(|zeta|/2) - 1
        sc = -0.5 + z2 / 48.0  # -sin(|zeta|/2)/|zeta|
        n1, n2, n3 = sc * ze, sc * zn, sc * zu
        w_, x_, y_, z_ = zw[:n], zx[:n], zy[:n], zz[:n]
        dw, dxq, dyq, dzq = _qmul((m0, n1, n2, n3), (w_, x_, y_, z_))
        zw_new = _cumsum_from(1.0, dw)
        zx_new, zy_new, zz_new = _cumsum_from(0.0, dxq), _cumsum_from(0.0, dyq), _cumsum_from(0.0, dzq)
        # velocity (ins._run step 4) with the new attitude: C(q) = C(Z) C(P)
        z_new = (zw_new[:n], zx_new[:n], zy_new[:n], zz_new[:n])
        ue, un, uu = u_new = _zrot(z_new, u_body)
        if exact:
            se, sn, su = _zrot(z_new, s_body)
            re_, rn_, ru_ = ue - se * inv_dt, un - sn * inv_dt, uu - su * inv_dt
        else:
            re_, rn_, ru_ = 0.5 * ue, 0.5 * un, 0.5 * uu
        ve_new = _cumsum_from(ve0, ue - (zn * ru_ - zu * rn_) + (ge + ge1) * half_dt)
        vn_new = _cumsum_from(vn0, un - (zu * re_ - ze * ru_) + (gn + gn1) * half_dt)
        vu_new = _cumsum_from(vu0, uu - (ze * rn_ - zn * re_) + (gu + gu1) * half_dt)
        # position (ins._run step 5)
        if exact:
            de = ve_new[:n] * dt + se - third * (zn * su - zu * sn) + dt2_6 * (2.0 * ge + ge1)
            dn = vn_new[:n] * dt + sn - third * (zu * se - ze * su) + dt2_6 * (2.0 * gn + gn1)
            du = vu_new[:n] * dt + su - third * (ze * sn - zn * se) + dt2_6 * (2.0 * gu + gu1)
        elif trapezoid:
            de = (ve_new[:n] + ve_new[1:]) * half_dt
            dn = (vn_new[:n] + vn_new[1:]) * half_dt
            du = (vu_new[:n] + vu_new[1:]) * half_dt
        else:
            de, dn, du = ve_new[:n] * dt, vn_new[:n] * dt, vu_new[:n] * dt
        d_lat = 2.0 * dn / (rnh + rnh1)
        d_lon = 2.0 * de / ((reh + reh1) * 0.5 * (cl + cl1))
        y_lat_new = _cumsum_from(-k_lat, d_lat)
        y_lon_new = _cumsum_from(-k_lon, d_lon)
        y_h_new = _cumsum_from(-k_h, du)
        lat_new, lon_new, h_new = lat0 + y_lat_new, lon0 + y_lon_new, h0 + y_h_new
        # change from the guess
        vmax = max(1.0, float(np.abs(ve_new).max()), float(np.abs(vn_new).max()), float(np.abs(vu_new).max()))
        dv = max(float(np.abs(ve_new - ve).max()), float(np.abs(vn_new - vn).max()), float(np.abs(vu_new - vu).max()))
        dq = max(float(np.abs(a - b).max()) for a, b in ((zw_new, zw), (zx_new, zx), (zy_new, zy), (zz_new, zz)))
        dp_m = max(float(np.abs(y_lat_new - y_lat).max()) * E.a, float(np.abs(y_lon_new - y_lon).max()) * E.a,
                   float(np.abs(y_h_new - y_h).max()))
        y_lat, y_lon, y_h = y_lat_new, y_lon_new, y_h_new
        lat, lon, h = lat_new, lon_new, h_new
        ve, vn, vu = ve_new, vn_new, vu_new
        zw, zx, zy, zz = zw_new, zx_new, zy_new, zz_new
        u = u_new
        tol_v = 64.0 * _EPS * vmax
        # change relative to the rounding-level tolerances; stop when it is below them, or
        # when the next change, predicted from the ratio of the last two (the iteration
        # converges at least linearly, in practice faster), is below 1/16 of them
        change = max(dv / tol_v, dq / tol_q, dp_m / (max(1.0, n * dt) * tol_v))
        if change <= 1.0 or (it >= 2 and change * change <= previous / 16.0):
            comp = ((lat[-1] - lat0) - y_lat[-1], (lon[-1] - lon0) - y_lon[-1], (h[-1] - h0) - y_h[-1])
            q = np.array(_qmul((zw, zx, zy, zz), P))
            q *= 1.0 / np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
            return lat, lon, h, ve, vn, vu, q, comp, it
        previous = change
    return None


def integrate_scan(state: InsState, quat_body: np.ndarray, dv_body: np.ndarray, ds_body: np.ndarray | None,
                   rule: str | None, dt: float, earth: EarthModel, window: int = DEFAULT_WINDOW,
                   max_iterations: int = 12, stats: dict | None = None) -> InsSolution:
    """Free-inertial navigation from precomputed body terms without a per-step loop.

    Parameters
    ----------
    state : navsim.strapdown.ins.InsState
        State at t_0.
    quat_body : ndarray, shape (n, 4)
        ``q(Phi_k)``, the body rotation over each step.
    dv_body : ndarray, shape (n, 3)
        Velocity increments in body axes at t_k, m/s.
    ds_body : ndarray, shape (n, 3) or None
        Body-frame double integrals of the exact position forms, m (None for the
        "rectangle" and "trapezoid" rules).
    rule : {"rectangle", "trapezoid", None}
    dt : float
        Navigation step, s.
    earth : EarthModel
    window : int
        Steps per window (see the module notes on chunking).
    max_iterations : int
        Fixed-point iterations per window before the window is split in two.
    stats : dict, optional
        Filled with ``windows`` (count), ``iterations`` (total) and ``splits``.

    Returns
    -------
    navsim.strapdown.ins.InsSolution
        n + 1 rows; the same discrete solution as the sequential integrator up to
        rounding.
    """
    E = _Earth(earth)
    n = len(dv_body)
    qb = np.ascontiguousarray(np.asarray(quat_body, dtype=float).T)
    dvb = np.ascontiguousarray(np.asarray(dv_body, dtype=float).T)
    dsb = None if ds_body is None else np.ascontiguousarray(np.asarray(ds_body, dtype=float).T)
    lat = np.empty(n + 1)
    lon = np.empty(n + 1)
    h = np.empty(n + 1)
    vel = np.empty((n + 1, 3))
    quat = np.empty((n + 1, 4))
    lat[0], lon[0], h[0] = state.lat, state.lon, state.h
    vel[0] = state.velocity_n
    quat[0] = state.quat_nb
    current = (state.lat, state.lon, state.h, tuple(state.compensation), tuple(float(x) for x in state.velocity_n),
               tuple(float(x) for x in state.quat_nb))
    info = {"windows": 0, "iterations": 0, "splits": 0}
    pending = [(i, min(i + window, n)) for i in range(0, n, window)][::-1]
    while pending:
        a, b = pending.pop()
        res = _solve_window(current, qb[:, a:b], dvb[:, a:b], None if dsb is None else dsb[:, a:b], rule, dt, E,
                            max_iterations)
        if res is None:
            if b - a < 2:
                raise RuntimeError("scan integration did not converge on a single step")
            mid = (a + b) // 2
            pending += [(mid, b), (a, mid)]
            info["splits"] += 1
            continue
        la, lo, hh, ve, vn, vu, q, comp, it = res
        info["windows"] += 1
        info["iterations"] += it
        lat[a + 1:b + 1], lon[a + 1:b + 1], h[a + 1:b + 1] = la[1:], lo[1:], hh[1:]
        vel[a + 1:b + 1, 0], vel[a + 1:b + 1, 1], vel[a + 1:b + 1, 2] = ve[1:], vn[1:], vu[1:]
        quat[a + 1:b + 1] = q[:, 1:].T
        current = (float(la[-1]), float(lo[-1]), float(hh[-1]), tuple(float(x) for x in comp),
                   (float(ve[-1]), float(vn[-1]), float(vu[-1])), tuple(float(x) for x in q[:, -1]))
    if stats is not None:
        stats.update(info)
    final_comp: Any = current[3] if n else tuple(state.compensation)  # 3 floats
    return InsSolution(lat, lon, h, vel, quat, final_comp)
