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
"""

from __future__ import annotations

import importlib.util
import math

import numpy as np

__all__ = ["available", "earth_constants", "kernel", "run"]


def earth_constants(earth) -> np.ndarray:
    """The Earth model's constants as the float array :func:`run` takes."""
    a, e2, rate, f = earth.a, earth.e2, earth.rate, earth.f
    m_som = rate**2 * a**2 * a * (1.0 - f) / earth.gm
    return np.array([a, e2, rate, f, earth.g0, 9.7803253359, 0.00193185265241, m_som,
                     1.0 if earth.name == "spherical" else 0.0, 1.0 if earth.f == 0.0 else 0.0])


def _evaluate(c, lat, h, ve, vn, vu):
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


def run(c, start, quat_body, dv_body, ds_body, exact, trapezoid, dt, pos, vel, quat, comp):
    """Integrate n steps; fills ``pos`` (n+1, 3), ``vel`` (n+1, 3), ``quat`` (n+1, 4), ``comp`` (3,).

    ``c`` from :func:`earth_constants`; ``start`` = (lat, lon, h, k_lat, k_lon, k_h, vE, vN,
    vU, q0, q1, q2, q3); ``ds_body`` is read only when ``exact``.
    """
    lat, lon, h = start[0], start[1], start[2]
    k_lat, k_lon, k_h = start[3], start[4], start[5]
    ve, vn, vu = start[6], start[7], start[8]
    q0, q1, q2, q3 = start[9], start[10], start[11], start[12]
    half_dt, dt2_6, third = 0.5 * dt, dt * dt / 6.0, 1.0 / 3.0
    inv_dt = 1.0 / dt
    pos[0, 0], pos[0, 1], pos[0, 2] = lat, lon, h
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
        pos[k + 1, 0], pos[k + 1, 1], pos[k + 1, 2] = lat, lon, h
        vel[k + 1, 0], vel[k + 1, 1], vel[k + 1, 2] = ve, vn, vu
        quat[k + 1, 0], quat[k + 1, 1], quat[k + 1, 2], quat[k + 1, 3] = q0, q1, q2, q3
        rnh, reh, cl, wx, wy, wz, ge, gn, gu = _evaluate(c, lat, h, ve, vn, vu)
    comp[0], comp[1], comp[2] = k_lat, k_lon, k_h


_found: list[bool] = []
_compiled: list = []


def available() -> bool:
    """True when numba is installed (it is not imported here)."""
    if not _found:
        _found.append(importlib.util.find_spec("numba") is not None)
    return _found[0]


def kernel():
    """:func:`run` compiled by numba, or None without numba."""
    if not available():
        return None
    if not _compiled:
        import numba

        global _evaluate
        _evaluate = numba.njit(cache=True, inline="always")(_evaluate)
        _compiled.append(numba.njit(cache=True, nogil=True)(run))
    return _compiled[0]
