"""Compiled sequential strapdown loop (``method="compiled"`` of :func:`navsim.strapdown.ins.integrate_body_terms`).

The predictor-corrector step of :mod:`navsim.strapdown.ins` (steps 1-5 of its module
notes: Earth terms at ``x_k`` and at the predictor point, attitude
``q(k+1) = q(-zeta) o q(k) o q(Phi)``, velocity with the frame-rotation correction,
position by the named rule with compensated sums) as one loop over arrays, written in the
subset of Python that numba compiles. The expressions and their order are those of
:func:`navsim.strapdown.ins.sequential_rows`, so the solution is the sequential one bit for
bit wherever the C library's ``sin``/``cos`` are those Python calls
(``tests/strapdown/test_ins_compiled.py``), and the scan solution to rounding.

:func:`run` is the plain-Python source; :func:`kernel` returns it compiled (numba, optional
extra ``fast``; compiled on the first call and cached on disk), or None without numba.

One navigation step of the error-state INS (the step-wise estimators between GNSS epochs):
:func:`one_step` (strapdown terms, bias removal, one step of :func:`run`, solution row and
specific force) and :func:`step_row`, the same step on a work array (:func:`work_array`:
constants, biases, state, the specific-force sum; the input layout recorded by
:func:`set_layout` and checked on every call) that also copies the covariance block of the
step; :func:`step_kernel` and :func:`row_kernel` return them compiled.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from navsim.jit import available

if TYPE_CHECKING:  # type hints only
    from navsim.earth import EarthModel

__all__ = ["available", "earth_constants", "kernel", "one_step", "row_kernel", "run", "set_layout", "step_constants",
           "step_kernel", "step_row", "work_array"]


def earth_constants(earth: EarthModel) -> np.ndarray:
    """The Earth model's constants as the float array :func:`run` takes."""
    a, e2, rate, f = earth.a, earth.e2, earth.rate, earth.f
    m_som = rate**2 * a**2 * a * (1.0 - f) / earth.gm
    return np.array([a, e2, rate, f, earth.g0, 9.7803253359, 0.00193185265241, m_som,
                     1.0 if earth.name == "spherical" else 0.0, 1.0 if earth.f == 0.0 else 0.0])


def _evaluate(c: np.ndarray | tuple[float, ...], lat: float, h: float, ve: float, vn: float,
              vu: float) -> tuple[float, float, float, float, float, float, float, float, float]:
    # radii, rates and gc = g - (2 w_ie + w_en) x v at one point (as ins.sequential_rows)
    a, e2, rate, f, g0, gamma_e, k_som, m_som = c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]
    spherical, flat = c[8] != 0.0, c[9] != 0.0
    sl, cl = math.sin(lat), math.cos(lat)
    if flat:
        rnh = a + h
        reh = rnh
    else:
        w2 = 1.0 - e2 * sl * sl
        w = math.sqrt(w2)
        reh = a / w + h
        rnh = a * (1.0 - e2) / (w2 * w) + h
    if spherical:
        rc = rate * rate * (a + h) * cl
        gn, gu = -rc * sl, rc * cl - g0
    else:
        s2 = sl * sl
        gamma = gamma_e * (1.0 + k_som * s2) / math.sqrt(1.0 - e2 * s2)
        gn = 0.0
        gu = -gamma * (1.0 - 2.0 / a * (1.0 + f + m_som - 2.0 * f * s2) * h + 3.0 / (a * a) * h * h)
    wie_n, wie_u = rate * cl, rate * sl
    wen_e, wen_n = -vn / rnh, ve / reh
    wen_u = wen_n * sl / cl
    cn, cu = 2.0 * wie_n + wen_n, 2.0 * wie_u + wen_u
    gce = -(cn * vu - cu * vn)
    gcn = gn - (cu * ve - wen_e * vu)
    gcu = gu - (wen_e * vn - cn * ve)
    return rnh, reh, cl, wen_e, wie_n + wen_n, wie_u + wen_u, gce, gcn, gcu


def run(c: np.ndarray | tuple[float, ...], start: np.ndarray, quat_body: np.ndarray, dv_body: np.ndarray, ds_body: np.ndarray,
        exact: bool, trapezoid: bool, dt: float, pos: np.ndarray, vel: np.ndarray, quat: np.ndarray,
        comp: np.ndarray) -> None:
    """Integrate n steps; fills ``pos`` (3, n+1: rows lat, lon, h), ``vel`` (n+1, 3), ``quat`` (n+1, 4),
    ``comp`` (3,).

    ``c`` from :func:`earth_constants`; ``start`` = (lat, lon, h, k_lat, k_lon, k_h, vE, vN,
    vU, q0, q1, q2, q3); ``ds_body`` is read only when ``exact``.
    """
    # the constants as a tuple of floats: registers in the compiled loop (an array's loads
    # cannot be hoisted past the stores into the outputs), so the Earth model's invariant
    # subexpressions are computed once
    c = (c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9])
    lat, lon, h = start[0], start[1], start[2]
    k_lat, k_lon, k_h = start[3], start[4], start[5]
    ve, vn, vu = start[6], start[7], start[8]
    q0, q1, q2, q3 = start[9], start[10], start[11], start[12]
    half_dt, dt2_6, third = 0.5 * dt, dt * dt / 6.0, 1.0 / 3.0
    inv_dt = 1.0 / dt
    pos[0, 0], pos[1, 0], pos[2, 0] = lat, lon, h
    vel[0, 0], vel[0, 1], vel[0, 2] = ve, vn, vu
    quat[0, 0], quat[0, 1], quat[0, 2], quat[0, 3] = q0, q1, q2, q3
    rnh, reh, cl, wx, wy, wz, ge, gn, gu = _evaluate(c, lat, h, ve, vn, vu)
    for k in range(dv_body.shape[0]):
        b0, b1, b2, b3 = quat_body[k, 0], quat_body[k, 1], quat_body[k, 2], quat_body[k, 3]
        dx, dy, dz = dv_body[k, 0], dv_body[k, 1], dv_body[k, 2]
        c00 = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
        c11 = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
        c22 = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
        c01, c10 = 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q2 + q0 * q3)
        c02, c20 = 2 * (q1 * q3 + q0 * q2), 2 * (q1 * q3 - q0 * q2)
        c12, c21 = 2 * (q2 * q3 - q0 * q1), 2 * (q2 * q3 + q0 * q1)
        ue = c00 * dx + c01 * dy + c02 * dz
        un = c10 * dx + c11 * dy + c12 * dz
        uu = c20 * dx + c21 * dy + c22 * dz
        ze, zn, zu = wx * half_dt, wy * half_dt, wz * half_dt
        pe = ve + ue - (zn * uu - zu * un) + ge * dt
        pn = vn + un - (zu * ue - ze * uu) + gn * dt
        pu = vu + uu - (ze * un - zn * ue) + gu * dt
        lat_p = lat + (vn + pn) * half_dt / rnh
        h_p = h + (vu + pu) * half_dt
        rnh1, reh1, cl1, wx1, wy1, wz1, ge1, gn1, gu1 = _evaluate(c, lat_p, h_p, pe, pn, pu)
        ze, zn, zu = (wx + wx1) * half_dt, (wy + wy1) * half_dt, (wz + wz1) * half_dt
        se = sn = su = 0.0
        if exact:
            d0, d1, d2 = ds_body[k, 0], ds_body[k, 1], ds_body[k, 2]
            se = c00 * d0 + c01 * d1 + c02 * d2
            sn = c10 * d0 + c11 * d1 + c12 * d2
            su = c20 * d0 + c21 * d1 + c22 * d2
            re_, rn_, ru_ = ue - se * inv_dt, un - sn * inv_dt, uu - su * inv_dt
        else:
            re_, rn_, ru_ = 0.5 * ue, 0.5 * un, 0.5 * uu
        ve1 = ve + ue - (zn * ru_ - zu * rn_) + (ge + ge1) * half_dt
        vn1 = vn + un - (zu * re_ - ze * ru_) + (gn + gn1) * half_dt
        vu1 = vu + uu - (ze * rn_ - zn * re_) + (gu + gu1) * half_dt
        if exact:
            de = ve * dt + se - third * (zn * su - zu * sn) + dt2_6 * (2.0 * ge + ge1)
            dn = vn * dt + sn - third * (zu * se - ze * su) + dt2_6 * (2.0 * gn + gn1)
            du = vu * dt + su - third * (ze * sn - zn * se) + dt2_6 * (2.0 * gu + gu1)
        elif trapezoid:
            de, dn, du = (ve + ve1) * half_dt, (vn + vn1) * half_dt, (vu + vu1) * half_dt
        else:
            de, dn, du = ve * dt, vn * dt, vu * dt
        y = 2.0 * dn / (rnh + rnh1) - k_lat
        s = lat + y
        k_lat = (s - lat) - y
        lat = s
        y = 2.0 * de / ((reh + reh1) * 0.5 * (cl + cl1)) - k_lon
        s = lon + y
        k_lon = (s - lon) - y
        lon = s
        y = du - k_h
        s = h + y
        k_h = (s - h) - y
        h = s
        ve, vn, vu = ve1, vn1, vu1
        a0 = q0 * b0 - q1 * b1 - q2 * b2 - q3 * b3
        a1 = q0 * b1 + q1 * b0 + q2 * b3 - q3 * b2
        a2 = q0 * b2 - q1 * b3 + q2 * b0 + q3 * b1
        a3 = q0 * b3 + q1 * b2 - q2 * b1 + q3 * b0
        z2 = ze * ze + zn * zn + zu * zu
        n0 = 1.0 - z2 / 8.0 + z2 * z2 / 384.0
        sc = -0.5 + z2 / 48.0
        n1, n2, n3 = sc * ze, sc * zn, sc * zu
        q0 = n0 * a0 - n1 * a1 - n2 * a2 - n3 * a3
        q1 = n0 * a1 + n1 * a0 + n2 * a3 - n3 * a2
        q2 = n0 * a2 - n1 * a3 + n2 * a0 + n3 * a1
        q3 = n0 * a3 + n1 * a2 - n2 * a1 + n3 * a0
        s = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0, q1, q2, q3 = q0 * s, q1 * s, q2 * s, q3 * s
        pos[0, k + 1], pos[1, k + 1], pos[2, k + 1] = lat, lon, h
        vel[k + 1, 0], vel[k + 1, 1], vel[k + 1, 2] = ve, vn, vu
        quat[k + 1, 0], quat[k + 1, 1], quat[k + 1, 2], quat[k + 1, 3] = q0, q1, q2, q3
        rnh, reh, cl, wx, wy, wz, ge, gn, gu = _evaluate(c, lat, h, ve, vn, vu)
    comp[0], comp[1], comp[2] = k_lat, k_lon, k_h


def step_constants(dt: float) -> np.ndarray:
    """The coefficients of :func:`navsim.strapdown.onestep.one_step_terms` for step ``dt``
    (computed here in Python, with the same ``**`` as there), in the order :func:`one_step` reads."""
    t = float(dt)
    return np.array([44.0 / t**2, 6.0 / t, 12.0 / t**2, 18.0 / t**2, 1.5 / t, 30.0 / t**3,
                     2.0 * t / 3.0, 0.5 * t, 6.0 / t**2, 12.0 / t**3, 4.0 / t, 6.0 / t**2, 12.0 / t**3,
                     t / 24.0, t * t, 0.5 * t * t, t / 6.0])


def one_step(c: np.ndarray, k: np.ndarray, dtheta_r: np.ndarray, dv_r: np.ndarray, dtheta_sub: np.ndarray,
             dv_sub: np.ndarray, use_sub: bool, gyro_bias: np.ndarray, accel_bias: np.ndarray, state: np.ndarray,
             dt: float, out: np.ndarray) -> None:
    """One navigation step of the error-state INS on the raw increments of the step.

    The float forms of :func:`navsim.strapdown.onestep.one_step_terms` (coning
    ``invariant``, sculling ``invariant-4.4``, position ``exact-invariant``), of
    :meth:`navsim.estimators._inserror.StepTerms.compensated` (bias removal),
    :func:`navsim.strapdown.onestep.quat_from_rotvec`, then one step of :func:`run` and the
    solution row and specific force of ``ErrorStateIns._advance_step``: the same operations
    in the same order, so the same numbers as the array path (the coefficients ``k`` from
    :func:`step_constants`, computed by Python as there).

    ``state`` (13,) = (lat, lon, h, k_lat, k_lon, k_h, vE, vN, vU, q0..q3) is advanced in
    place; ``out`` (12,) receives the solution row (lat, lon, h, vE, vN, vU, heading,
    pitch, roll) and ``C(k+1) (DV - b_a T)`` (3,), the specific-force increment in ENU.
    """
    c44, c6, c12, c18, c15, c30 = k[0], k[1], k[2], k[3], k[4], k[5]
    k23, k12, s6, s12 = k[6], k[7], k[8], k[9]
    r4, r6, r12, q24 = k[10], k[11], k[12], k[13]
    TT, h2, t6 = k[14], k[15], k[16]
    a1, b1, c1 = dtheta_r[0, 0], dtheta_r[0, 1], dtheta_r[0, 2]
    a2, b2, c2 = dtheta_r[1, 0], dtheta_r[1, 1], dtheta_r[1, 2]
    a3, b3, c3 = dtheta_r[2, 0], dtheta_r[2, 1], dtheta_r[2, 2]
    a4, b4, c4 = dtheta_r[3, 0], dtheta_r[3, 1], dtheta_r[3, 2]
    e1, f1, g1 = dv_r[0, 0], dv_r[0, 1], dv_r[0, 2]
    e2, f2, g2 = dv_r[1, 0], dv_r[1, 1], dv_r[1, 2]
    e3, f3, g3 = dv_r[2, 0], dv_r[2, 1], dv_r[2, 2]
    e4, f4, g4 = dv_r[3, 0], dv_r[3, 1], dv_r[3, 2]
    # coning (4.8)
    ux, uy, uz = c44 * a3 - 3.0 * a1, c44 * b3 - 3.0 * b1, c44 * c3 - 3.0 * c1
    wx, wy, wz = a1 - c6 * a2 + c12 * a3, b1 - c6 * b2 + c12 * b3, c1 - c6 * c2 + c12 * c3
    p0 = a1 + (c18 * (b1 * c3 - c1 * b3) - c15 * (b2 * uz - c2 * uy) - c30 * (wy * c4 - wz * b4))
    p1 = b1 + (c18 * (c1 * a3 - a1 * c3) - c15 * (c2 * ux - a2 * uz) - c30 * (wz * a4 - wx * c4))
    p2 = c1 + (c18 * (a1 * b3 - b1 * a3) - c15 * (a2 * uy - b2 * ux) - c30 * (wx * b4 - wy * a4))
    # sculling (4.4)
    ux, uy, uz = a2 - k23 * a1, b2 - k23 * b1, c2 - k23 * c1
    wx, wy, wz = a2 - k12 * a1, b2 - k12 * b1, c2 - k12 * c1
    v0 = e1 + ((b1 * g1 - c1 * f1) + s6 * (uy * g2 - uz * f2) - s12 * (wy * g3 - wz * f3))
    v1 = f1 + ((c1 * e1 - a1 * g1) + s6 * (uz * e2 - ux * g2) - s12 * (wz * e3 - wx * g3))
    v2 = g1 + ((a1 * f1 - b1 * e1) + s6 * (ux * f2 - uy * e2) - s12 * (wx * f3 - wy * e3))
    # position (5.2)-(5.4)
    ux, uy, uz = r4 * a1 - r6 * a2, r4 * b1 - r6 * b2, r4 * c1 - r6 * c2
    wx, wy, wz = r6 * a1 - r12 * a2, r6 * b1 - r12 * b2, r6 * c1 - r12 * c2
    s0 = e2 + ((b1 * g2 - c1 * f2) - 2.0 * (uy * g3 - uz * f3) + 3.0 * (wy * g4 - wz * f4))
    s1 = f2 + ((c1 * e2 - a1 * g2) - 2.0 * (uz * e3 - ux * g3) + 3.0 * (wz * e4 - wx * g4))
    s2 = g2 + ((a1 * f2 - b1 * e2) - 2.0 * (ux * f3 - uy * e3) + 3.0 * (wx * f4 - wy * e4))
    # first-order increments: sums of the sub-sample increments in time order, else DT1, DV1
    if use_sub:
        t0, t1, t2 = dtheta_sub[0, 0], dtheta_sub[0, 1], dtheta_sub[0, 2]
        for i in range(1, dtheta_sub.shape[0]):
            t0, t1, t2 = t0 + dtheta_sub[i, 0], t1 + dtheta_sub[i, 1], t2 + dtheta_sub[i, 2]
        d0, d1, d2 = dv_sub[0, 0], dv_sub[0, 1], dv_sub[0, 2]
        for i in range(1, dv_sub.shape[0]):
            d0, d1, d2 = d0 + dv_sub[i, 0], d1 + dv_sub[i, 1], d2 + dv_sub[i, 2]
    else:
        t0, t1, t2 = a1, b1, c1
        d0, d1, d2 = e1, f1, g1
    x0, x1, x2 = p1 * d2 - p2 * d1, p2 * d0 - p0 * d2, p0 * d1 - p1 * d0
    n0, n1, n2 = p1 * x2 - p2 * x1, p2 * x0 - p0 * x2, p0 * x1 - p1 * x0
    dvb0, dvb1, dvb2 = v0 + n0 / 6.0, v1 + n1 / 6.0, v2 + n2 / 6.0
    dsb0, dsb1, dsb2 = s0 + q24 * n0, s1 + q24 * n1, s2 + q24 * n2
    # bias compensation (StepTerms.compensated)
    T = dt
    g0_, g1_, g2_ = gyro_bias[0], gyro_bias[1], gyro_bias[2]
    a0_, a1_, a2_ = accel_bias[0], accel_bias[1], accel_bias[2]
    ph0, ph1, ph2 = p0 - g0_ * T, p1 - g1_ * T, p2 - g2_ * T
    m0 = T * ((g1_ * d2 - g2_ * d1) + (t1 * a2_ - t2 * a1_)) - TT * (g1_ * a2_ - g2_ * a1_)
    m1 = T * ((g2_ * d0 - g0_ * d2) + (t2 * a0_ - t0 * a2_)) - TT * (g2_ * a0_ - g0_ * a2_)
    m2 = T * ((g0_ * d1 - g1_ * d0) + (t0 * a1_ - t1 * a0_)) - TT * (g0_ * a1_ - g1_ * a0_)
    quat_b = np.empty((1, 4))
    dv_b = np.empty((1, 3))
    ds_b = np.empty((1, 3))
    dv_b[0, 0], dv_b[0, 1], dv_b[0, 2] = dvb0 - a0_ * T - 0.5 * m0, dvb1 - a1_ * T - 0.5 * m1, dvb2 - a2_ * T - 0.5 * m2
    ds_b[0, 0] = dsb0 - a0_ * h2 - t6 * m0
    ds_b[0, 1] = dsb1 - a1_ * h2 - t6 * m1
    ds_b[0, 2] = dsb2 - a2_ * h2 - t6 * m2
    f0, f1_, f2_ = d0 - a0_ * T, d1 - a1_ * T, d2 - a2_ * T
    # quat_from_rotvec
    angle2 = ph0 * ph0 + ph1 * ph1 + ph2 * ph2
    angle = math.sqrt(angle2)
    if angle < 1e-4:
        half_sinc = 0.5 - angle2 / 48.0 + angle2 * angle2 / 3840.0
    else:
        half_sinc = math.sin(0.5 * angle) / angle
    quat_b[0, 0], quat_b[0, 1] = math.cos(0.5 * angle), half_sinc * ph0
    quat_b[0, 2], quat_b[0, 3] = half_sinc * ph1, half_sinc * ph2
    pos, vel, quat, comp = np.empty((3, 2)), np.empty((2, 3)), np.empty((2, 4)), np.empty(3)
    _run(c, state, quat_b, dv_b, ds_b, True, False, dt, pos, vel, quat, comp)
    lat, lon, h = pos[0, 1], pos[1, 1], pos[2, 1]
    ve, vn, vu = vel[1, 0], vel[1, 1], vel[1, 2]
    q0, q1, q2, q3 = quat[1, 0], quat[1, 1], quat[1, 2], quat[1, 3]
    state[0], state[1], state[2] = lat, lon, h
    state[3], state[4], state[5] = comp[0], comp[1], comp[2]
    state[6], state[7], state[8] = ve, vn, vu
    state[9], state[10], state[11], state[12] = q0, q1, q2, q3
    c01 = 2.0 * (q1 * q2 - q0 * q3)
    c11 = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    c20 = 2.0 * (q1 * q3 - q0 * q2)
    c21 = 2.0 * (q2 * q3 + q0 * q1)
    c22 = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
    out[0], out[1], out[2], out[3], out[4], out[5] = lat, lon, h, ve, vn, vu
    out[6] = math.atan2(c01, c11)
    out[7] = math.asin(min(max(c21, -1.0), 1.0))
    out[8] = math.atan2(-c20, c22)
    u0, u1, u2 = 2.0 * (q2 * f2_ - q3 * f1_), 2.0 * (q3 * f0 - q1 * f2_), 2.0 * (q1 * f1_ - q2 * f0)
    out[9] = f0 + q0 * u0 + (q2 * u2 - q3 * u1)
    out[10] = f1_ + q0 * u1 + (q3 * u0 - q1 * u2)
    out[11] = f2_ + q0 * u2 + (q1 * u1 - q2 * u0)


# offsets into the work array of step_row (work_array): Earth constants (10), step constants
# (17), dt, gyro bias (3), accelerometer bias (3), state (13), specific-force sum (3), the
# input layout the array was set up for (5: rows of dtheta_r, dv_r, dtheta_sub, dv_sub, and
# 1.0 with sub-sample increments, 0.0 without)
W_EARTH, W_STEP, W_DT, W_GYRO, W_ACCEL, W_STATE, W_FSUM, W_LAYOUT, W_SIZE = 0, 10, 27, 28, 31, 34, 47, 50, 55


def work_array(earth: EarthModel, dt: float) -> np.ndarray:
    """The work array of :func:`step_row` for ``earth`` and step ``dt``: constants filled,
    biases, state and specific-force sum zero, no input layout (every call mismatches
    until :func:`set_layout`)."""
    w = np.zeros(W_SIZE)
    w[W_EARTH:W_STEP] = earth_constants(earth)
    w[W_STEP:W_DT] = step_constants(dt)
    w[W_DT] = float(dt)
    w[W_LAYOUT:W_SIZE] = -1.0
    return w


def set_layout(w: np.ndarray, dtheta_r_rows: int, dv_r_rows: int, dtheta_sub_rows: int | None,
               dv_sub_rows: int | None) -> None:
    """Record in ``w`` the input layout :func:`step_row` accepts (None: no sub-sample increments)."""
    sub = dtheta_sub_rows is not None and dv_sub_rows is not None
    w[W_LAYOUT:W_SIZE] = (dtheta_r_rows, dv_r_rows, dtheta_sub_rows if sub else 0, dv_sub_rows if sub else 0,
                          1.0 if sub else 0.0)


def step_row(w: np.ndarray, dtheta_r: np.ndarray, dv_r: np.ndarray, dtheta_sub: np.ndarray, dv_sub: np.ndarray,
             use_sub: bool, blocks: np.ndarray, j: int, row: np.ndarray, cov: np.ndarray) -> int:
    """One step of the error-state INS with everything but the increments in one array.

    :func:`one_step` on the constants, biases and state held in ``w``
    (:func:`work_array`; the state advanced in place), then the bookkeeping of
    ``ErrorStateIns.advance_row`` that needs no Python object: the solution row into
    ``row`` (9,), the specific-force increment added to the sum ``w[W_FSUM:W_FSUM + 3]``
    component by component (``s + f``, as the float path adds), and the navigation block
    ``blocks[j]`` (9, 9) of the covariance copied into ``cov``. ``dtheta_sub``, ``dv_sub``
    are read only when ``use_sub``.

    Returns 1 without touching anything when the input layout is not the one recorded in
    ``w`` (:func:`set_layout`: the caller then takes its general path), 2 when the new
    position and velocity sum to a non-finite number (the caller validates the state),
    else 0.
    """
    if (dtheta_r.shape[0] != w[W_LAYOUT] or dv_r.shape[0] != w[W_LAYOUT + 1] or dtheta_r.shape[1] != 3
            or dv_r.shape[1] != 3 or (1.0 if use_sub else 0.0) != w[W_LAYOUT + 4]):
        return 1
    if use_sub and (dtheta_sub.shape[0] != w[W_LAYOUT + 2] or dv_sub.shape[0] != w[W_LAYOUT + 3]
                    or dtheta_sub.shape[1] != 3 or dv_sub.shape[1] != 3):
        return 1
    out = np.empty(12)
    _one_step(w[W_EARTH:W_STEP], w[W_STEP:W_DT], dtheta_r, dv_r, dtheta_sub, dv_sub, use_sub, w[W_GYRO:W_ACCEL],
              w[W_ACCEL:W_STATE], w[W_STATE:W_FSUM], w[W_DT], out)
    for i in range(9):
        row[i] = out[i]
    w[W_FSUM] = w[W_FSUM] + out[9]
    w[W_FSUM + 1] = w[W_FSUM + 1] + out[10]
    w[W_FSUM + 2] = w[W_FSUM + 2] + out[11]
    for a in range(9):
        for b in range(9):
            cov[a, b] = blocks[j, a, b]
    return 0 if math.isfinite(out[0] + out[1] + out[2] + out[3] + out[4] + out[5]) else 2


_run = run
_one_step = one_step
_compiled: list[Callable[..., Any]] = []
_compiled_step: list[Callable[..., Any]] = []
_compiled_row: list[Callable[..., Any]] = []


def kernel() -> Callable[..., None] | None:
    """:func:`run` compiled by numba, or None without numba."""
    if not available():
        return None
    if not _compiled:
        import numba

        global _evaluate, _run
        _evaluate = numba.njit(cache=True, inline="always")(_evaluate)
        _run = numba.njit(cache=True, nogil=True)(run)
        _compiled.append(_run)
    return _compiled[0]


def step_kernel() -> Callable[..., None] | None:
    """:func:`one_step` compiled by numba (calling the compiled :func:`run`), or None without numba."""
    if not available():
        return None
    if not _compiled_step:
        import numba

        global _one_step
        kernel()
        _one_step = numba.njit(cache=True, nogil=True)(one_step)
        _compiled_step.append(_one_step)
    return _compiled_step[0]


def row_kernel() -> Callable[..., int] | None:
    """:func:`step_row` compiled by numba (calling the compiled :func:`one_step`), or None without numba."""
    if not available():
        return None
    if not _compiled_row:
        import numba

        step_kernel()
        _compiled_row.append(numba.njit(cache=True, nogil=True)(step_row))
    return _compiled_row[0]
