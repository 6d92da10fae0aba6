"""Compiled propagation engine of the seed-003 filter (:class:`navsim.estimators.paper_ekf.PaperEkf`).

The continuous filter (14) between GNSS epochs, step by step as in the reference engine
(:mod:`~navsim.estimators.paper_ekf.python_engine`): at the start of each
covariance interval the coefficients of (14) at the current state (the stage values F and
Z_ax - H_a, A = dF/dY, dH_a/dY, Q, the correlation F1 D_A H_w^T and H_w D_a H_w^T; the
fused scalar pass with the analytic phi-derivatives on the sphere and the complex step on
the ellipsoid), the gain ``K = (R dH_a/dY^T + S) / sigma^2`` (zero without the observer
(13), option ``observer=False``), one RK4 step of the Riccati
equation written as ``R' = [R; I]^T H [R; I]`` with H frozen over the interval; then RK4 of
the state equation ``Y' = F(Y) + K (Z_ax - H_a(Y))`` with the gain held, the linear clock
and Gauss-Markov bias states by their exact transitions. The same expressions in the same
order as the reference engine; the matrix products are explicit loops, so the numbers
differ from the reference (whose products are BLAS calls) by rounding only.

The functions are plain Python written in the subset that numba compiles (arrays and
scalars, no Python objects); :func:`advance` is the compiled driver (numba, optional extra
``fast``; compiled on its first call and cached on disk); :func:`advance_py` runs the same
source uncompiled, slowly (tests; ``advance_uncompiled`` keeps it after compilation).
:func:`step_core` is one navigation step of the step-wise path (inputs, :func:`advance_py`,
outputs; with ``epoch`` a step that ends at a GNSS epoch, stopped before the update (16));
:func:`step_packed` is the same call with the constants, the work array and the state taken
from the two buffers of :func:`pack` (9 arguments instead of 22: numba's dispatcher checks
the type of every argument of every call).

:func:`advance_py` advances over a run of navigation steps and stops, handing control back
to the caller, at (a) a step whose start-up stiffness needs adaptive sub-steps (the gain
rate times the step exceeds the stiffness limit), (b) a step whose result is non-finite or
whose covariance has a negative diagonal (the state is left as before that step; the
reference engine then repeats the step and raises, which marks the divergence), and (c) a
GNSS epoch, after its propagation and before the discrete update (16). The caller does
(a), (b) and the update (16) with the reference code (they are rare: start-up, failure,
once per GNSS period).

References: [003] Sokolov S.V., Vdovichenko S.S., Nauchnoe Priborostroenie 2012, eqs.
(7)-(14), Appendix 2 (see :mod:`navsim.estimators.paper_ekf` for the model and its
corrections).
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from navsim.jit import available

__all__ = ["STATUS_DONE", "STATUS_SUBSTEPS", "STATUS_FAILED", "STATUS_EPOCH", "advance", "advance_py",
           "available", "work_size", "outputs", "outputs_compiled", "pack", "prepare_row", "step_core",
           "step_packed", "track_scalars", "track_scalars3"]

STATUS_DONE = 0  # all steps advanced
STATUS_SUBSTEPS = 1  # step i needs adaptive sub-steps (not advanced)
STATUS_FAILED = 2  # step i gave a non-finite or indefinite result (not advanced)
STATUS_EPOCH = 3  # step i advanced, its epoch update (16) is due

_CSTEP = 1e-20  # complex-step size, rad (as in paper_ekf)

# indices of the float constants ``c`` and integer constants ``ic`` (built by PaperEkf._kernel_args)
C_OM, C_A, C_E2, C_CENT, C_QD, C_QA, C_DT, C_LIMIT, C_TAU_A, C_TAU_G = range(10)
I_SPHERE, I_PRINTED, I_BIASES, I_CLOCK, I_IA, I_IG, I_ICLK, I_SPE, I_NC, I_SINGLE, I_ORDER, I_HALL, I_OBSERVER = range(13)


# ---------------------------------------------------------------------------- track
def _piece(breaks: np.ndarray, single: int, xr: float) -> int:
    if single:
        return 0
    i = int(np.searchsorted(breaks, xr, side="right")) - 1  # bisect_right - 1
    return 0 if i < 0 else i


def track_scalars(phi: Any, breaks: np.ndarray, lam_c: np.ndarray, h_c: np.ndarray, single: int,
                  order: int) -> tuple[Any, ...]:
    """(lam, lam', lam'', h, h') at phi: TrackFunctions.scalars (same expressions)."""
    i = _piece(breaks, single, phi.real)
    x = phi - breaks[i]
    if order == 4:
        a0, a1, a2, a3 = lam_c[i, 0], lam_c[i, 1], lam_c[i, 2], lam_c[i, 3]
        b0, b1, b2, b3 = h_c[i, 0], h_c[i, 1], h_c[i, 2], h_c[i, 3]
        return (a0 + x * (a1 + x * (a2 + x * a3)), a1 + x * (2.0 * a2 + 3.0 * a3 * x), 2.0 * a2 + 6.0 * a3 * x,
                b0 + x * (b1 + x * (b2 + x * b3)), b1 + x * (2.0 * b2 + 3.0 * b3 * x))
    if order == 6:
        a0, a1, a2, a3, a4, a5 = lam_c[i, 0], lam_c[i, 1], lam_c[i, 2], lam_c[i, 3], lam_c[i, 4], lam_c[i, 5]
        b0, b1, b2, b3, b4, b5 = h_c[i, 0], h_c[i, 1], h_c[i, 2], h_c[i, 3], h_c[i, 4], h_c[i, 5]
        return (a0 + x * (a1 + x * (a2 + x * (a3 + x * (a4 + x * a5)))),
                a1 + x * (2.0 * a2 + x * (3.0 * a3 + x * (4.0 * a4 + 5.0 * a5 * x))),
                2.0 * a2 + x * (6.0 * a3 + x * (12.0 * a4 + 20.0 * a5 * x)),
                b0 + x * (b1 + x * (b2 + x * (b3 + x * (b4 + x * b5)))),
                b1 + x * (2.0 * b2 + x * (3.0 * b3 + x * (4.0 * b4 + 5.0 * b5 * x))))
    lp, l1, l2 = _horner2(lam_c[i], x)
    hp, h1, _ = _horner2(h_c[i], x)
    return lp, l1, l2, hp, h1


def track_scalars3(phi: float, breaks: np.ndarray, lam_c: np.ndarray, h_c: np.ndarray, single: int,
                   order: int) -> tuple[float, ...]:
    """(lam, lam', lam'', lam''', h, h', h'') at a real phi: TrackFunctions.scalars3."""
    i = _piece(breaks, single, phi)
    x = phi - breaks[i]
    if order == 4:
        a0, a1, a2, a3 = lam_c[i, 0], lam_c[i, 1], lam_c[i, 2], lam_c[i, 3]
        b0, b1, b2, b3 = h_c[i, 0], h_c[i, 1], h_c[i, 2], h_c[i, 3]
        return (a0 + x * (a1 + x * (a2 + x * a3)), a1 + x * (2.0 * a2 + 3.0 * a3 * x), 2.0 * a2 + 6.0 * a3 * x,
                6.0 * a3, b0 + x * (b1 + x * (b2 + x * b3)), b1 + x * (2.0 * b2 + 3.0 * b3 * x),
                2.0 * b2 + 6.0 * b3 * x)
    l0, l1, l2, l3 = _horner3(lam_c[i], x)
    h0, h1, h2, _ = _horner3(h_c[i], x)
    return l0, l1, l2, l3, h0, h1, h2


def _horner2(c: np.ndarray, x: Any) -> tuple[Any, Any, Any]:
    p = 0.0 * x
    d1 = 0.0 * x
    d2 = 0.0 * x
    for j in range(len(c) - 1, -1, -1):
        d2 = d2 * x + 2.0 * d1
        d1 = d1 * x + p
        p = p * x + c[j]
    return p, d1, d2


def _horner3(c: np.ndarray, x: float) -> tuple[float, float, float, float]:
    p = 0.0
    d1 = 0.0
    d2 = 0.0
    d3 = 0.0
    for j in range(len(c) - 1, -1, -1):
        d3 = d3 * x + 3.0 * d2
        d2 = d2 * x + 2.0 * d1
        d1 = d1 * x + p
        p = p * x + c[j]
    return p, d1, d2, d3


# ---------------------------------------------------------------------------- model
def stage(a: Any, b: Any, g: Any, phi: Any, V: Any, t: float, wx: Any, wy: Any, wz: Any, fx: Any, fy: Any, fz: Any,
          c: np.ndarray, ic: np.ndarray, breaks: np.ndarray, lam_c: np.ndarray, h_c: np.ndarray) -> tuple[Any, ...]:
    """F(Y) and Z_ax - H_a at one point: PaperEkf._make_stage (same expressions).

    Complex-safe in phi (np.sin / np.cos / np.sqrt take both)."""
    om = c[C_OM]
    two_om = 2.0 * om
    om2 = om * om
    sa = np.sin(a)
    ca = np.cos(a)
    sb = np.sin(b)
    cb = np.cos(b)
    sg = np.sin(g)
    cg = np.cos(g)
    p = sg * wx + cg * wy
    q = cg * wx - sg * wy
    if ic[I_PRINTED]:
        da, db, dg = p / cb, q, p * sb / cb + wz
    else:
        da, db, dg = q, p / ca, p * sa / ca + wz
    d00 = sb * sa * sg + cb * cg
    d01 = ca * sg
    d02 = cb * sa * sg - sb * cg
    d10 = sb * sa * cg - cb * sg
    d11 = ca * cg
    d12 = cb * sa * cg + sb * sg
    fp0 = d00 * fx + d10 * fy + sb * ca * fz
    fp1 = d01 * fx + d11 * fy - sa * fz
    fp2 = d02 * fx + d12 * fy + cb * ca * fz
    lam, dlam, ddlam, hh, dh = track_scalars(phi, breaks, lam_c, h_c, ic[I_SINGLE], ic[I_ORDER])
    sp = np.sin(phi)
    cp = np.cos(phi)
    psi = lam + om * t
    ss = np.sin(psi)
    cs = np.cos(psi)
    a_e, e2 = c[C_A], c[C_E2]
    if ic[I_SPHERE]:
        rn = a_e + hh
        re = rn
        k = dlam * cp
        kphi = ddlam * cp - dlam * sp
        gn = c[C_CENT] * om2 * rn * cp * sp
    else:
        w = 1.0 - e2 * sp * sp
        r_e = a_e / np.sqrt(w)
        r_n = r_e * (1.0 - e2) / w
        rn = r_n + hh
        re = r_e + hh
        dre = r_e * e2 * sp * cp / w + dh
        drn = 3.0 * r_n * e2 * sp * cp / w + dh
        ratio = re / rn
        k = dlam * cp * ratio
        kphi = (ddlam * cp - dlam * sp) * ratio + dlam * cp * (dre - ratio * drn) / rn
        gn = 0.0 * rn
    m = dh / rn
    kv = k * V
    cor = two_om * sp + kv * sp / (cp * re)
    acc_n = -cor * kv - m * V * V / rn + gn
    acc_e = cor * V - (two_om * cp + kv / re) * m * V
    gterm = k * acc_n + kphi * V * V / rn - acc_e
    f_n = cp * fp1 - sp * (ss * fp0 + cs * fp2)
    f_e = cs * fp0 - ss * fp2
    w0 = d00 * (cs + k * sp * ss) - d01 * k * cp + d02 * (k * sp * cs - ss)
    return da, db, dg, V / rn, f_n + acc_n, (f_e - k * f_n - gterm) / w0


def _kphi(phi: float, c: np.ndarray, ic: np.ndarray, breaks: np.ndarray, lam_c: np.ndarray, h_c: np.ndarray) -> float:
    """d k / d phi on the ellipsoid: PaperEkf._kphi_c."""
    lam, dlam, ddlam, hh, dh = track_scalars(phi, breaks, lam_c, h_c, ic[I_SINGLE], ic[I_ORDER])
    sp, cp = math.sin(phi), math.cos(phi)
    e2 = c[C_E2]
    w = 1.0 - e2 * sp * sp
    r_e = c[C_A] / math.sqrt(w)
    r_n = r_e * (1.0 - e2) / w
    rn, re = r_n + hh, r_e + hh
    dre = r_e * e2 * sp * cp / w + dh
    drn = 3.0 * r_n * e2 * sp * cp / w + dh
    ratio = re / rn
    return (ddlam * cp - dlam * sp) * ratio + dlam * cp * (dre - ratio * drn) / rn


def fused(Y: np.ndarray, wx: Any, wy: Any, wz: Any, fx: Any, fy: Any, fz: Any, t: float, c: np.ndarray,
          ic: np.ndarray, breaks: np.ndarray, lam_c: np.ndarray, h_c: np.ndarray, first: np.ndarray,
          a_dyn: np.ndarray, hneg: np.ndarray, q_dyn: np.ndarray) -> tuple[float, float]:
    """The fused function of :mod:`~navsim.estimators.paper_ekf.mechanization` (same expressions): fills ``first`` (6), ``a_dyn``,
    ``hneg`` (n), ``q_dyn`` (7) and returns (s4, sig2)."""
    om = c[C_OM]
    two_om = 2.0 * om
    om2 = om * om
    a_e, e2 = c[C_A], c[C_E2]
    sphere = ic[I_SPHERE]
    printed_kin = ic[I_PRINTED]
    biases = ic[I_BIASES]
    ia, ig = ic[I_IA], ic[I_IG]
    single, order = ic[I_SINGLE], ic[I_ORDER]
    a, b, g, phi, V = Y[0], Y[1], Y[2], Y[3], Y[4]
    if biases:
        fx, fy, fz = fx - Y[ia], fy - Y[ia + 1], fz - Y[ia + 2]
        wx, wy, wz = wx - Y[ig], wy - Y[ig + 1], wz - Y[ig + 2]
    sa = math.sin(a)
    ca = math.cos(a)
    sb = math.sin(b)
    cb = math.cos(b)
    sg = math.sin(g)
    cg = math.cos(g)
    p = sg * wx + cg * wy
    q = cg * wx - sg * wy
    if printed_kin:
        da, db, dg = p / cb, q, p * sb / cb + wz
    else:
        da, db, dg = q, p / ca, p * sa / ca + wz
    d00 = sb * sa * sg + cb * cg
    d01 = ca * sg
    d02 = cb * sa * sg - sb * cg
    d10 = sb * sa * cg - cb * sg
    d11 = ca * cg
    d12 = cb * sa * cg + sb * sg
    d20 = sb * ca
    d22 = cb * ca
    fp0 = d00 * fx + d10 * fy + sb * ca * fz
    fp1 = d01 * fx + d11 * fy - sa * fz
    fp2 = d02 * fx + d12 * fy + cb * ca * fz
    if sphere:
        lam, dlam, ddlam, dddlam, hh, dh, ddh = track_scalars3(phi, breaks, lam_c, h_c, single, order)
    else:
        lam, dlam, ddlam, hh, dh = track_scalars(phi, breaks, lam_c, h_c, single, order)
        dddlam = ddh = 0.0
    sp = math.sin(phi)
    cp = math.cos(phi)
    psi = lam + om * t
    ss = math.sin(psi)
    cs = math.cos(psi)
    if sphere:
        rn = a_e + hh
        re = rn
        k = dlam * cp
        kphi = ddlam * cp - dlam * sp
        gn = c[C_CENT] * om2 * rn * cp * sp
    else:
        w_ = 1.0 - e2 * sp * sp
        r_e = a_e / math.sqrt(w_)
        r_n = r_e * (1.0 - e2) / w_
        rn = r_n + hh
        re = r_e + hh
        dre = r_e * e2 * sp * cp / w_ + dh
        drn = 3.0 * r_n * e2 * sp * cp / w_ + dh
        ratio = re / rn
        k = dlam * cp * ratio
        kphi = (ddlam * cp - dlam * sp) * ratio + dlam * cp * (dre - ratio * drn) / rn
        gn = 0.0
    m = dh / rn
    kv = k * V
    cor = two_om * sp + kv * sp / (cp * re)
    acc_n = -cor * kv - m * V * V / rn + gn
    acc_e = cor * V - (two_om * cp + kv / re) * m * V
    gterm = k * acc_n + kphi * V * V / rn - acc_e
    f_n = cp * fp1 - sp * (ss * fp0 + cs * fp2)
    f_e = cs * fp0 - ss * fp2
    w0s = d00 * (cs + k * sp * ss) - d01 * k * cp + d02 * (k * sp * cs - ss)
    innov = (f_e - k * f_n - gterm) / w0s
    first[0] = da
    first[1] = db
    first[2] = dg
    first[3] = V / rn
    first[4] = f_n + acc_n
    first[5] = innov
    # ---- Jacobian
    n_p0, n_p2 = -ss * sp, -cs * sp
    u_p0, u_p1, u_p2 = cs - k * n_p0, -k * cp, -ss - k * n_p2
    n_b0 = d00 * n_p0 + d01 * cp + d02 * n_p2
    n_b1 = d10 * n_p0 + d11 * cp + d12 * n_p2
    n_b2 = d20 * n_p0 - sa * cp + d22 * n_p2
    w0 = d00 * u_p0 + d01 * u_p1 + d02 * u_p2
    u_b1 = d10 * u_p0 + d11 * u_p1 + d12 * u_p2
    u_b2 = d20 * u_p0 - sa * u_p1 + d22 * u_p2
    y = innov * w0
    for j in range(len(hneg)):
        hneg[j] = 0.0
    zn0, zn1, zn2 = fy * n_b2 - fz * n_b1, fz * n_b0 - fx * n_b2, fx * n_b1 - fy * n_b0
    zu0, zu1, zu2 = fy * u_b2 - fz * u_b1, fz * w0 - fx * u_b2, fx * u_b1 - fy * w0
    ww = w0 * w0
    a40 = cg * zn0 - sg * zn1
    hneg[0] = ((cg * zu0 - sg * zu1) * w0 - y * (sg * u_b2)) / ww
    sgca, cgca = sg * ca, cg * ca
    a41 = sgca * zn0 + cgca * zn1 - sa * zn2
    hneg[1] = ((sgca * zu0 + cgca * zu1 - sa * zu2) * w0 - y * (-(cgca * u_b2 + sa * u_b1))) / ww
    a42 = zn2
    hneg[2] = (zu2 * w0 - y * u_b1) / ww
    if printed_kin:
        tb = sb / cb
        a_dyn[0], a_dyn[1], a_dyn[2], a_dyn[3], a_dyn[4] = p * sb / (cb * cb), q / cb, -p, p / (cb * cb), q * tb
        k00, k01, k02 = sg / cb, cg / cb, 0.0
        k10, k11, k12 = cg, -sg, 0.0
        k20, k21, k22 = sg * tb, cg * tb, 1.0
    else:
        ta = sa / ca
        a_dyn[0], a_dyn[1], a_dyn[2], a_dyn[3], a_dyn[4] = -p, p * sa / (ca * ca), q / ca, p / (ca * ca), q * ta
        k00, k01, k02 = cg, -sg, 0.0
        k10, k11, k12 = sg / ca, cg / ca, 0.0
        k20, k21, k22 = sg * ta, cg * ta, 1.0
    if sphere:
        rn2 = rn * rn
        a33 = -V * dh / rn2
        kphi_p = dddlam * cp - 2.0 * ddlam * sp - dlam * cp
        gn_p = c[C_CENT] * om2 * (dh * cp * sp + rn * (cp * cp - sp * sp))
        m_p = ddh / rn - dh * dh / rn2
        tphi = sp / (cp * rn)
        tphi_p = 1.0 / (cp * cp * rn) - sp * dh / (cp * rn2)
        cor_p = two_om * cp + V * (kphi * tphi + k * tphi_p)
        acc_n_p = -V * (cor_p * k + cor * kphi) - V * V * (m_p / rn - m * dh / rn2) + gn_p
        acc_e_p = cor_p * V - ((-two_om * sp + V * (kphi / rn - k * dh / rn2)) * m
                               + (two_om * cp + kv / rn) * m_p) * V
        gterm_p = kphi * acc_n + k * acc_n_p + V * V * (kphi_p / rn - kphi * dh / rn2) - acc_e_p
        xs = ss * fp0 + cs * fp2
        f_n_p = -sp * fp1 - cp * xs - sp * dlam * f_e
        f_e_p = -dlam * xs
        w0s_p = (d00 * (-ss * dlam + kphi * sp * ss + k * cp * ss + k * sp * cs * dlam)
                 - d01 * (kphi * cp - k * sp)
                 + d02 * (kphi * sp * cs + k * cp * cs - k * sp * ss * dlam - cs * dlam))
        a43 = f_n_p + acc_n_p
        hneg[3] = (f_e_p - kphi * f_n - k * f_n_p - gterm_p - innov * w0s_p) / w0s
    else:
        cp3, cp4, cp5 = _stage_cstep(a, b, g, phi, V, t, wx, wy, wz, fx, fy, fz, c, ic, breaks, lam_c, h_c)
        a33 = cp3
        a43 = cp4
        hneg[3] = cp5
        kphi = _kphi(phi, c, ic, breaks, lam_c, h_c)
    cor2 = two_om * sp + 2.0 * kv * sp / (cp * re)
    acc_n_v = -cor2 * k - 2.0 * m * V / rn
    acc_e_v = cor2 - (two_om * cp + 2.0 * kv / re) * m
    hneg[4] = -(k * acc_n_v + 2.0 * kphi * V / rn - acc_e_v) / w0
    a_dyn[5] = a33
    a_dyn[6] = 1.0 / rn
    a_dyn[7] = a40
    a_dyn[8] = a41
    a_dyn[9] = a42
    a_dyn[10] = a43
    a_dyn[11] = acc_n_v
    qd, qa = c[C_QD], c[C_QA]
    q_dyn[0] = qd * (k00 * k00 + k01 * k01 + k02 * k02)
    q_dyn[1] = qd * (k00 * k10 + k01 * k11 + k02 * k12)
    q_dyn[2] = qd * (k00 * k20 + k01 * k21 + k02 * k22)
    q_dyn[3] = qd * (k10 * k10 + k11 * k11 + k12 * k12)
    q_dyn[4] = qd * (k10 * k20 + k11 * k21 + k12 * k22)
    q_dyn[5] = qd * (k20 * k20 + k21 * k21 + k22 * k22)
    q_dyn[6] = qa
    s4 = qa * k / w0
    sig2 = qa * (1.0 + k * k) / ww
    if biases:
        a_dyn[12], a_dyn[13], a_dyn[14] = -k00, -k10, -k20
        a_dyn[15], a_dyn[16], a_dyn[17] = -k01, -k11, -k21
        a_dyn[18], a_dyn[19], a_dyn[20] = -k02, -k12, -k22
        a_dyn[21], a_dyn[22], a_dyn[23] = -n_b0, -n_b1, -n_b2
        hneg[ia] = -w0 / w0
        hneg[ia + 1] = -u_b1 / w0
        hneg[ia + 2] = -u_b2 / w0
    return s4, sig2


def _stage_cstep(a: Any, b: Any, g: Any, phi: Any, V: Any, t: float, wx: Any, wy: Any, wz: Any, fx: Any, fy: Any,
                 fz: Any, c: np.ndarray, ic: np.ndarray, breaks: np.ndarray, lam_c: np.ndarray,
                 h_c: np.ndarray) -> tuple[float, float, float]:
    """phi' , V_Y' and innovation derivatives in phi by the complex step (ellipsoid)."""
    z = stage(a, b, g, complex(phi, _CSTEP), V, t, wx, wy, wz, fx, fy, fz, c, ic, breaks, lam_c, h_c)
    return z[3].imag / _CSTEP, z[4].imag / _CSTEP, z[5].imag / _CSTEP


def _fill_h(H: np.ndarray, flat: np.ndarray, h_sup: np.ndarray, bar_idx: np.ndarray, bar_col: np.ndarray,
            a_dyn: np.ndarray, n_a: int, hneg: np.ndarray, q_dyn: np.ndarray, s4: float, sig2: float,
            h_all: bool) -> None:
    """PaperEkf._h_matrix: the state-dependent entries of H through the flat index array."""
    inv = 1.0 / sig2
    nh_len = len(hneg) if h_all else len(h_sup)
    si = s4 * inv
    for k in range(len(bar_idx)):
        a_dyn[bar_idx[k]] += si * hneg[bar_col[k]]
    Hf = H.reshape(-1)
    pos = 0
    for x in range(nh_len):
        hx = hneg[x] if h_all else hneg[h_sup[x]]
        nx = -hx * inv
        for yy in range(nh_len):
            hy = hneg[yy] if h_all else hneg[h_sup[yy]]
            Hf[flat[pos]] = nx * hy
            pos += 1
    for j in range(n_a):
        Hf[flat[pos]] = a_dyn[j]
        pos += 1
    for j in range(n_a):
        Hf[flat[pos]] = a_dyn[j]
        pos += 1
    q0, q1, q2, q3, q4, q5, qvv = q_dyn[0], q_dyn[1], q_dyn[2], q_dyn[3], q_dyn[4], q_dyn[5], q_dyn[6]
    Hf[flat[pos]] = q0
    Hf[flat[pos + 1]] = q1
    Hf[flat[pos + 2]] = q2
    Hf[flat[pos + 3]] = q3
    Hf[flat[pos + 4]] = q4
    Hf[flat[pos + 5]] = q5
    Hf[flat[pos + 6]] = q1
    Hf[flat[pos + 7]] = q2
    Hf[flat[pos + 8]] = q4
    Hf[flat[pos + 9]] = qvv - s4 * si


def _gain(P: np.ndarray, hneg: np.ndarray, s4: float, sig2: float, K: np.ndarray) -> float:
    """PaperEkf._gain: K = (R h + s) / sigma^2 (14) into K; returns |dH_a/dY K|."""
    inv = 1.0 / sig2
    n = len(hneg)
    for i in range(n):
        d = 0.0
        for j in range(n):
            d += P[i, j] * hneg[j]
        if i == 4:
            d -= s4
        K[i] = -d * inv
    r = 0.0
    for i in range(n):
        r += hneg[i] * K[i]
    return abs(r)


def _quad(Hh: np.ndarray, R: np.ndarray, HZ: np.ndarray, out: np.ndarray) -> None:
    """out = [R; I]^T Hh [R; I] (explicit loops; Hh is 2n x 2n)."""
    n = R.shape[0]
    for r in range(2 * n):
        for j in range(n):
            s = 0.0
            for cc in range(n):
                h = Hh[r, cc]
                if h != 0.0:
                    s += h * R[cc, j]
            HZ[r, j] = s + Hh[r, n + j]
    for i in range(n):
        for j in range(n):
            s = 0.0
            for r in range(n):
                s += R[r, i] * HZ[r, j]
            out[i, j] = s + HZ[n + i, j]


def riccati_rk4(P: np.ndarray, H: np.ndarray, tau: float, Hh: np.ndarray, top: np.ndarray, HZ: np.ndarray,
                m1: np.ndarray, m2: np.ndarray, m3: np.ndarray, m4: np.ndarray, out: np.ndarray) -> None:
    """_riccati_rk4_h of paper_ekf (the same stages in the same order) into ``out``."""
    n = P.shape[0]
    h2 = 0.5 * tau
    for i in range(2 * n):
        for j in range(2 * n):
            Hh[i, j] = H[i, j] * h2
    _quad(Hh, P, HZ, m1)
    for i in range(n):
        for j in range(n):
            top[i, j] = P[i, j] + m1[i, j]
    _quad(Hh, top, HZ, m2)
    for i in range(n):
        for j in range(n):
            top[i, j] = P[i, j] + m2[i, j]
    _quad(Hh, top, HZ, m3)
    for i in range(n):
        for j in range(n):
            top[i, j] = (m3[i, j] + m3[i, j]) + P[i, j]
    _quad(Hh, top, HZ, m4)
    for i in range(n):
        for j in range(n):
            s = m2[i, j] + m3[i, j]
            s = s + s
            s = s + m1[i, j]
            top[i, j] = s + m4[i, j]
    sixth = 1.0 / 6.0
    for i in range(n):
        for j in range(n):
            out[i, j] = (top[i, j] + top[j, i]) * sixth + P[i, j]


def _rows_ok(P: np.ndarray) -> bool:
    """_check_rows: finite and a non-negative diagonal."""
    n = P.shape[0]
    s = 0.0
    for i in range(n):
        r = 0.0
        for j in range(n):
            r += P[i, j]
        s += r
    if not math.isfinite(s):
        return False
    for i in range(n):
        if not P[i, i] >= 0.0:
            return False
    return True


def state_rk4(Y: np.ndarray, K: np.ndarray, row: np.ndarray, t0: float, tau: float, first: np.ndarray,
              have_first: bool, c: np.ndarray, ic: np.ndarray, breaks: np.ndarray, lam_c: np.ndarray,
              h_c: np.ndarray) -> None:
    """PaperEkf._state_rk4: RK4 of (14) over tau with the gain K held (in place)."""
    a, b, g, phi, V = Y[0], Y[1], Y[2], Y[3], Y[4]
    w1x, w1y, w1z, f1x, f1y, f1z = row[0], row[1], row[2], row[3], row[4], row[5]
    w2x, w2y, w2z, f2x, f2y, f2z = row[6], row[7], row[8], row[9], row[10], row[11]
    w3x, w3y, w3z, f3x, f3y, f3z = row[12], row[13], row[14], row[15], row[16], row[17]
    biases = ic[I_BIASES]
    ia, ig = ic[I_IA], ic[I_IG]
    if biases:
        bax, bay, baz, bgx, bgy, bgz = Y[ia], Y[ia + 1], Y[ia + 2], Y[ig], Y[ig + 1], Y[ig + 2]
        w1x, w1y, w1z, w2x, w2y, w2z, w3x, w3y, w3z = (
            w1x - bgx, w1y - bgy, w1z - bgz, w2x - bgx, w2y - bgy, w2z - bgz, w3x - bgx, w3y - bgy, w3z - bgz)
        f1x, f1y, f1z, f2x, f2y, f2z, f3x, f3y, f3z = (
            f1x - bax, f1y - bay, f1z - baz, f2x - bax, f2y - bay, f2z - baz, f3x - bax, f3y - bay, f3z - baz)
    k0, k1, k2, k3, k4 = K[0], K[1], K[2], K[3], K[4]
    h2 = 0.5 * tau
    tm = t0 + h2
    te = t0 + tau
    if have_first:
        d10, d11, d12, d13, d14, i1 = first[0], first[1], first[2], first[3], first[4], first[5]
    else:
        d10, d11, d12, d13, d14, i1 = stage(a, b, g, phi, V, t0, w1x, w1y, w1z, f1x, f1y, f1z, c, ic, breaks,
                                            lam_c, h_c)
    d20, d21, d22, d23, d24, i2 = stage(a + h2 * (d10 + k0 * i1), b + h2 * (d11 + k1 * i1), g + h2 * (d12 + k2 * i1),
                                        phi + h2 * (d13 + k3 * i1), V + h2 * (d14 + k4 * i1), tm,
                                        w2x, w2y, w2z, f2x, f2y, f2z, c, ic, breaks, lam_c, h_c)
    d30, d31, d32, d33, d34, i3 = stage(a + h2 * (d20 + k0 * i2), b + h2 * (d21 + k1 * i2), g + h2 * (d22 + k2 * i2),
                                        phi + h2 * (d23 + k3 * i2), V + h2 * (d24 + k4 * i2), tm,
                                        w2x, w2y, w2z, f2x, f2y, f2z, c, ic, breaks, lam_c, h_c)
    d40, d41, d42, d43, d44, i4 = stage(a + tau * (d30 + k0 * i3), b + tau * (d31 + k1 * i3),
                                        g + tau * (d32 + k2 * i3), phi + tau * (d33 + k3 * i3),
                                        V + tau * (d34 + k4 * i3), te,
                                        w3x, w3y, w3z, f3x, f3y, f3z, c, ic, breaks, lam_c, h_c)
    cc = tau / 6.0
    ibar = cc * (i1 + 2.0 * (i2 + i3) + i4)
    Y[0] = a + cc * (d10 + 2.0 * (d20 + d30) + d40) + k0 * ibar
    Y[1] = b + cc * (d11 + 2.0 * (d21 + d31) + d41) + k1 * ibar
    Y[2] = g + cc * (d12 + 2.0 * (d22 + d32) + d42) + k2 * ibar
    Y[3] = phi + cc * (d13 + 2.0 * (d23 + d33) + d43) + k3 * ibar
    Y[4] = V + cc * (d14 + 2.0 * (d24 + d34) + d44) + k4 * ibar
    if ic[I_CLOCK]:
        i = ic[I_ICLK]
        Y[i] = Y[i] + tau * Y[i + 1] + K[i] * ibar
        Y[i + 1] = Y[i + 1] + K[i + 1] * ibar
    if biases:
        fa = math.exp(-tau / c[C_TAU_A])
        fg = math.exp(-tau / c[C_TAU_G])
        for j in range(3):
            Y[ia + j] = fa * Y[ia + j] + K[ia + j] * ibar
            Y[ig + j] = fg * Y[ig + j] + K[ig + j] * ibar


# ---------------------------------------------------------------------------- driver
def work_size(n: int) -> int:
    """Length of the float work array of :func:`advance_py` and :func:`step_core` for n states."""
    return 200 + 30 * n + 16 * n * n


def advance_py(i0: int, inp: np.ndarray, t_end: np.ndarray, steps: np.ndarray, is_epoch: np.ndarray, Y: np.ndarray,
               P: np.ndarray, P_start: np.ndarray, K: np.ndarray, cov: np.ndarray, c: np.ndarray, ic: np.ndarray,
               breaks: np.ndarray, lam_c: np.ndarray, h_c: np.ndarray, H: np.ndarray, flat: np.ndarray,
               h_sup: np.ndarray, bar_idx: np.ndarray, bar_col: np.ndarray, out_y: np.ndarray, out_p: np.ndarray,
               work: np.ndarray) -> tuple[int, int]:
    """Advance steps i0, i0 + 1, ... of a batch; returns (i, status).

    State (modified in place): Y (n,), P (n, n) the covariance at the end of the current
    covariance interval, P_start its start, K (n,) the gain held over it, ``cov`` (3,) int:
    steps left in the interval, its length, the position in it. Outputs of each finished
    step into out_y[i] (n,) and out_p[i] (n, n) (linear in time inside an interval, as the
    reference engine). Stops with the statuses of the module docstring. ``work``: scratch
    array of at least :func:`work_size` (n) floats (no allocation per call).
    """
    n = Y.shape[0]
    nsteps = t_end.shape[0]
    dt = c[C_DT]
    limit = c[C_LIMIT]
    spe, n_c, h_all = ic[I_SPE], ic[I_NC], ic[I_HALL]
    n_a = 24 if ic[I_BIASES] else 12
    nn = n * n
    first = work[0:6]
    a_dyn = work[6:6 + n_a]
    q_dyn = work[30:37]
    o = 40
    hneg = work[o:o + n]
    K_new = work[o + n:o + 2 * n]
    Y_back = work[o + 2 * n:o + 3 * n]
    o += 3 * n
    P_new = work[o:o + nn].reshape((n, n))
    top = work[o + nn:o + 2 * nn].reshape((n, n))
    m1 = work[o + 2 * nn:o + 3 * nn].reshape((n, n))
    m2 = work[o + 3 * nn:o + 4 * nn].reshape((n, n))
    m3 = work[o + 4 * nn:o + 5 * nn].reshape((n, n))
    m4 = work[o + 5 * nn:o + 6 * nn].reshape((n, n))
    HZ = work[o + 6 * nn:o + 8 * nn].reshape((2 * n, n))
    Hh = work[o + 8 * nn:o + 12 * nn].reshape((2 * n, 2 * n))
    for i in range(i0, nsteps):
        row = inp[i]
        t0 = t_end[i] - dt
        for j in range(n):
            Y_back[j] = Y[j]
        new_interval = cov[0] <= 0
        L = 0
        if new_interval:
            s4, sig2 = fused(Y, row[0], row[1], row[2], row[3], row[4], row[5], t0, c, ic, breaks, lam_c, h_c,
                             first, a_dyn, hneg, q_dyn)
            if not ic[I_OBSERVER]:  # no (13): h = 0, S = 0 -> H = [[0, A^T], [A, Q]], K = 0
                for j in range(n):
                    hneg[j] = 0.0
                s4 = 0.0
            _fill_h(H, flat, h_sup, bar_idx, bar_col, a_dyn, n_a, hneg, q_dyn, s4, sig2, h_all)
            rate = _gain(P, hneg, s4, sig2, K_new)
            to_epoch = spe - (steps[i] % spe)
            L = min(n_c, to_epoch)
            if not math.isfinite(rate):
                return i, STATUS_FAILED
            if rate * dt > limit:
                return i, STATUS_SUBSTEPS
            if rate * L * dt > limit:
                L = max(1, int(limit / (rate * dt)))
            riccati_rk4(P, H, L * dt, Hh, top, HZ, m1, m2, m3, m4, P_new)
            if not _rows_ok(P_new):
                return i, STATUS_FAILED
            state_rk4(Y, K_new, row, t0, dt, first, True, c, ic, breaks, lam_c, h_c)
        else:
            state_rk4(Y, K, row, t0, dt, first, False, c, ic, breaks, lam_c, h_c)
        s = 0.0
        for j in range(n):
            s += Y[j]
        if not math.isfinite(s):
            for j in range(n):
                Y[j] = Y_back[j]
            return i, STATUS_FAILED
        # commit
        if new_interval:
            for a in range(n):
                for b in range(n):
                    P_start[a, b] = P[a, b]
                    P[a, b] = P_new[a, b]
            for j in range(n):
                K[j] = K_new[j]
            cov[0] = L
            cov[1] = L
            cov[2] = 0
        cov[0] -= 1
        cov[2] += 1
        if is_epoch[i]:
            return i, STATUS_EPOCH
        for j in range(n):
            out_y[i, j] = Y[j]
        if cov[0] > 0 and cov[1] > 1:
            fr = cov[2] / cov[1]
            for a in range(n):
                for b in range(n):
                    out_p[i, a, b] = P_start[a, b] + fr * (P[a, b] - P_start[a, b])
        else:
            for a in range(n):
                for b in range(n):
                    out_p[i, a, b] = P[a, b]
    return nsteps, STATUS_DONE


advance_uncompiled = advance_py  # the driver's source, never replaced by its compiled form (tests)


def prepare_row(dtheta_r: np.ndarray, dv_r: np.ndarray, lvec: np.ndarray, dt_pow: np.ndarray,
                row: np.ndarray) -> None:
    """PaperEkf._prepare for one step: omega and f at s = 0, 1/2, 1 and the mean f (21)."""
    R = dtheta_r.shape[0]
    for s in range(3):
        for kind in range(2):
            src = dtheta_r if kind == 0 else dv_r
            for ax in range(3):
                acc = lvec[s, 0] * (src[0, ax] / dt_pow[0])
                for r in range(1, R):
                    acc = acc + lvec[s, r] * (src[r, ax] / dt_pow[r])
                row[6 * s + 3 * kind + ax] = acc
    for ax in range(3):
        row[18 + ax] = dv_r[0, ax] / dt_pow[0]


def _ek(a: float, b: float, g: float, D: np.ndarray) -> None:
    """euler_krylov_matrix (Appendix 1 of 003) into D (3, 3)."""
    sa, ca = math.sin(a), math.cos(a)
    sb, cb = math.sin(b), math.cos(b)
    sg, cg = math.sin(g), math.cos(g)
    D[0, 0], D[0, 1], D[0, 2] = sb * sa * sg + cb * cg, ca * sg, cb * sa * sg - sb * cg
    D[1, 0], D[1, 1], D[1, 2] = sb * sa * cg - cb * sg, ca * cg, cb * sa * cg + sb * sg
    D[2, 0], D[2, 1], D[2, 2] = sb * ca, -sa, cb * ca


def _clip1(x: float) -> float:
    if x > 1.0:
        return 1.0
    if x < -1.0:
        return -1.0
    return x


def output_row(Y: np.ndarray, P: np.ndarray, t: float, c: np.ndarray, ic: np.ndarray, breaks: np.ndarray,
               lam_c: np.ndarray, h_c: np.ndarray, sol: np.ndarray, cov: np.ndarray, J: np.ndarray, JP: np.ndarray,
               D: np.ndarray, B: np.ndarray, M: np.ndarray) -> None:
    """PaperEkf.outputs for one state: the solution (9) and its 9 x 9 covariance J P J^T."""
    n = Y.shape[0]
    a, b, g, phi, V = Y[0], Y[1], Y[2], Y[3], Y[4]
    if not math.isfinite(a + b + g + phi + V):
        for i in range(9):
            sol[i] = np.nan
            for j in range(9):
                cov[i, j] = np.nan
        return
    nb = breaks.shape[0]
    i = np.searchsorted(breaks, phi, side="right") - 1
    i = 0 if i < 0 else (nb - 1 if i > nb - 1 else i)
    x = phi - breaks[i]
    lam, dlam, ddlam = _horner2(lam_c[i], x)
    hh, dh, ddh = _horner2(h_c[i], x)
    sp, cp = math.sin(phi), math.cos(phi)
    a_e, e2 = c[C_A], c[C_E2]
    if ic[I_SPHERE]:
        rn = a_e + hh
        re = rn
        drn = dh
        dre = dh
    else:
        w = 1.0 - e2 * sp * sp
        r_e = a_e / math.sqrt(w)
        r_n = r_e * (1.0 - e2) / w
        rn, re = r_n + hh, r_e + hh
        dre = r_e * e2 * sp * cp / w + dh
        drn = 3.0 * r_n * e2 * sp * cp / w + dh
    ratio = re / rn
    k = dlam * cp * ratio
    kphi = (ddlam * cp - dlam * sp) * ratio + dlam * cp * (dre - ratio * drn) / rn
    m = dh / rn
    mphi = ddh / rn - dh * drn / rn ** 2
    _ek(a, b, g, D)
    _ek(-phi, lam + c[C_OM] * t, 0.0, B)
    for r in range(3):  # mat_nb = B D^T
        for q in range(3):
            M[r, q] = B[r, 0] * D[q, 0] + B[r, 1] * D[q, 1] + B[r, 2] * D[q, 2]
    sol[0], sol[1], sol[2] = phi, lam, hh
    sol[3], sol[4], sol[5] = k * V, V, m * V
    sol[6] = math.atan2(M[0, 1], M[1, 1])
    sol[7] = math.asin(_clip1(M[2, 1]))
    sol[8] = math.atan2(-M[2, 0], M[2, 2])
    for r in range(9):
        for q in range(n):
            J[r, q] = 0.0
    J[0, 3] = re * cp * dlam
    J[1, 3] = rn
    J[2, 3] = dh
    J[3, 3], J[3, 4] = kphi * V, k
    J[4, 4] = 1.0
    J[5, 3], J[5, 4] = mphi * V, m
    sg, cg, sa, ca = math.sin(g), math.cos(g), math.sin(a), math.cos(a)
    # columns a_alpha, a_beta, a_gamma of the angle axes; J[6:9, 0:3] = mat_nb @ axes
    for r in range(3):
        J[6 + r, 0] = M[r, 0] * cg + M[r, 1] * (-sg)
        J[6 + r, 1] = M[r, 0] * (sg * ca) + M[r, 1] * (cg * ca) + M[r, 2] * (-sa)
        J[6 + r, 2] = M[r, 2]
    J[6, 3] = 1.0
    J[7, 3] = -dlam * cp
    J[8, 3] = -dlam * sp
    for r in range(9):
        for q in range(n):
            acc = 0.0
            for j in range(n):
                acc += J[r, j] * P[j, q]
            JP[r, q] = acc
    for r in range(9):
        for q in range(r, 9):
            acc = 0.0
            for j in range(n):
                acc += JP[r, j] * J[q, j]
            cov[r, q] = acc
            cov[q, r] = acc


def outputs(Ys: np.ndarray, Ps: np.ndarray, t: np.ndarray, c: np.ndarray, ic: np.ndarray, breaks: np.ndarray,
            lam_c: np.ndarray, h_c: np.ndarray, sol: np.ndarray, cov: np.ndarray) -> None:
    """output_row over a batch: Ys (n, ns), Ps (n, ns, ns), t (n,) -> sol (n, 9), cov (n, 9, 9)."""
    ns = Ys.shape[1]
    J = np.zeros((9, ns))
    JP = np.zeros((9, ns))
    D = np.zeros((3, 3))
    B = np.zeros((3, 3))
    M = np.zeros((3, 3))
    for i in range(Ys.shape[0]):
        output_row(Ys[i], Ps[i], t[i], c, ic, breaks, lam_c, h_c, sol[i], cov[i], J, JP, D, B, M)


def input_offset(n: int) -> int:
    """Start in ``work`` of the stage inputs (21,) of the step :func:`step_core` prepared."""
    return 64 + 3 * n + 12 * n * n


def step_core(dtheta_r: np.ndarray, dv_r: np.ndarray, t: float, step: int, epoch: bool, state: np.ndarray,
              cov: np.ndarray, c: np.ndarray, ic: np.ndarray, breaks: np.ndarray, lam_c: np.ndarray, h_c: np.ndarray,
              H: np.ndarray, flat: np.ndarray, h_sup: np.ndarray, bar_idx: np.ndarray, bar_col: np.ndarray,
              lvec: np.ndarray, dt_pow: np.ndarray, work: np.ndarray, sol: np.ndarray, cov9: np.ndarray) -> int:
    """One navigation step of the step-wise path: the stage inputs (:func:`prepare_row`),
    :func:`advance_py` over the step, the outputs (:func:`output_row`).

    ``state`` = [Y, K, P, P_start] flat (2n + 2n^2), ``cov`` the interval counters, ``work``
    as in advance_py (at least :func:`work_size` floats). Returns the status of advance_py;
    the outputs (sol (9), cov9 (9, 9)) only when it is STATUS_DONE. With ``epoch`` True the
    step ends at a GNSS epoch: advance_py stops with STATUS_EPOCH after the propagation (the
    state advanced, no outputs) and the caller does the update (16) and the outputs; the
    stage inputs of the step stay in ``work`` from :func:`input_offset` (21 floats)."""
    n = H.shape[0] // 2
    nn = n * n
    Y = state[0:n]
    K = state[n:2 * n]
    P = state[2 * n:2 * n + nn].reshape((n, n))
    P_start = state[2 * n + nn:].reshape((n, n))
    o = 64 + 3 * n + 12 * nn  # after advance_py's part of work
    inp = work[o:o + 21].reshape((1, 21))
    t_end = work[o + 21:o + 22]
    t_end[0] = t
    out_y = work[o + 22:o + 22 + n].reshape((1, n))
    o += 22 + n
    out_p = work[o:o + nn].reshape((1, n, n))
    J = work[o + nn:o + nn + 9 * n].reshape((9, n))
    JP = work[o + nn + 9 * n:o + nn + 18 * n].reshape((9, n))
    o += nn + 18 * n
    D = work[o:o + 9].reshape((3, 3))
    B = work[o + 9:o + 18].reshape((3, 3))
    M = work[o + 18:o + 27].reshape((3, 3))
    steps = np.full(1, step)
    is_epoch = np.zeros(1, dtype=np.bool_)
    is_epoch[0] = epoch
    prepare_row(dtheta_r, dv_r, lvec, dt_pow, inp[0])
    _, status = advance_py(0, inp, t_end, steps, is_epoch, Y, P, P_start, K, cov, c, ic, breaks, lam_c, h_c,
                           H, flat, h_sup, bar_idx, bar_col, out_y, out_p, work)
    if status == STATUS_DONE:
        output_row(out_y[0], out_p[0], t, c, ic, breaks, lam_c, h_c, sol, cov9, J, JP, D, B, M)
    return status


# ---------------------------------------------------------------------------- packed arguments
# Header of the int buffer of :func:`step_packed` (made by :func:`pack`): sizes, then the start
# of each float section (in order c, breaks, lam_c, h_c, H, lvec, dt_pow, work, state, end) and
# of each int section (in order ic, flat, h_sup, bar_idx, bar_col, cov, end).
P_N, P_R, P_NB, P_ORDER = range(4)
P_F0 = 4  # 10 float section starts follow
P_I0 = P_F0 + 10  # 7 int section starts follow
P_HEADER = P_I0 + 7


def pack(c: np.ndarray, ic: np.ndarray, breaks: np.ndarray, lam_c: np.ndarray, h_c: np.ndarray, H: np.ndarray,
         flat: np.ndarray, h_sup: np.ndarray, bar_idx: np.ndarray, bar_col: np.ndarray, lvec: np.ndarray,
         dt_pow: np.ndarray, n_work: int, n: int) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
    """One float64 and one int64 buffer holding the constants, the work array and the state
    of :func:`step_core` (copies of the arguments), and their views in the buffers.

    Returns ``(fbuf, ibuf, views)`` with ``views`` = (c, ic, breaks, lam_c, h_c, H, flat, h_sup,
    bar_idx, bar_col, lvec, dt_pow, work, state, cov): C-contiguous views of the buffers with
    the shapes of the arguments (``work`` of ``n_work`` floats, ``state`` of 2n + 2n^2 floats
    and ``cov`` of 3 ints, both uninitialised). The caller uses the views in place of its own
    arrays, so the batch engine and :func:`step_packed` share the same memory."""
    fparts: list[np.ndarray] = [np.ravel(c), np.ravel(breaks), np.ravel(lam_c), np.ravel(h_c), np.ravel(H), np.ravel(lvec),
              np.ravel(dt_pow), np.zeros(n_work), np.zeros(2 * n + 2 * n * n)]
    iparts: list[np.ndarray] = [np.ravel(ic), np.ravel(flat), np.ravel(h_sup), np.ravel(bar_idx), np.ravel(bar_col),
              np.zeros(3, dtype=np.int64)]
    fstart = np.cumsum([0] + [len(x) for x in fparts])
    istart = np.cumsum([P_HEADER] + [len(x) for x in iparts])
    fbuf = np.empty(int(fstart[-1]))
    ibuf = np.zeros(int(istart[-1]), dtype=np.int64)
    ibuf[P_N], ibuf[P_R], ibuf[P_NB], ibuf[P_ORDER] = n, len(dt_pow), len(breaks), lam_c.shape[1]
    ibuf[P_F0:P_F0 + 10] = fstart
    ibuf[P_I0:P_I0 + 7] = istart
    fv: list[np.ndarray] = [fbuf[fstart[k]:fstart[k + 1]] for k in range(9)]
    iv: list[np.ndarray] = [ibuf[istart[k]:istart[k + 1]] for k in range(6)]
    for view, part in zip(fv + iv, fparts + iparts):
        view[:] = part
    shapes = [np.shape(c), np.shape(breaks), np.shape(lam_c), np.shape(h_c), np.shape(H), np.shape(lvec),
              np.shape(dt_pow), (n_work,), (2 * n + 2 * n * n,)]
    fv = [v.reshape(shape) for v, shape in zip(fv, shapes)]
    c_v, breaks_v, lam_v, h_v, H_v, lvec_v, dt_pow_v, work_v, state_v = fv
    ic_v, flat_v, h_sup_v, bar_idx_v, bar_col_v, cov_v = iv
    return fbuf, ibuf, (c_v, ic_v, breaks_v, lam_v, h_v, H_v, flat_v, h_sup_v, bar_idx_v, bar_col_v, lvec_v,
                        dt_pow_v, work_v, state_v, cov_v)


def step_packed(dtheta_r: np.ndarray, dv_r: np.ndarray, t: float, step: int, epoch: bool, fbuf: np.ndarray,
                ibuf: np.ndarray, sol: np.ndarray, cov9: np.ndarray) -> int:
    """:func:`step_core` with its constants, work array and state taken from the buffers of
    :func:`pack` (few arguments: the compiled dispatcher checks the type of each argument
    on every call). The same function on the same arrays: the same numbers."""
    n, R, nb, order = ibuf[P_N], ibuf[P_R], ibuf[P_NB], ibuf[P_ORDER]
    f = ibuf[P_F0:P_F0 + 10]
    i = ibuf[P_I0:P_I0 + 7]
    c = fbuf[f[0]:f[1]]
    breaks = fbuf[f[1]:f[2]]
    lam_c = fbuf[f[2]:f[3]].reshape((nb, order))
    h_c = fbuf[f[3]:f[4]].reshape((nb, order))
    H = fbuf[f[4]:f[5]].reshape((2 * n, 2 * n))
    lvec = fbuf[f[5]:f[6]].reshape((3, R))
    dt_pow = fbuf[f[6]:f[7]]
    work = fbuf[f[7]:f[8]]
    state = fbuf[f[8]:f[9]]
    return step_core(dtheta_r, dv_r, t, step, epoch, state, ibuf[i[5]:i[6]], c, ibuf[i[0]:i[1]], breaks, lam_c, h_c, H,
                    ibuf[i[1]:i[2]], ibuf[i[2]:i[3]], ibuf[i[3]:i[4]], ibuf[i[4]:i[5]], lvec, dt_pow, work, sol,
                    cov9)


_compiled: list[Callable[..., Any]] = []


def _compile() -> tuple[Callable[..., Any], ...]:
    import numba

    jit = numba.njit(cache=True, error_model="numpy")
    g = globals()
    for name in ("_piece", "track_scalars", "track_scalars3", "_horner2", "_horner3", "stage", "_kphi", "fused",
                 "_stage_cstep", "_fill_h", "_gain", "_quad", "riccati_rk4", "_rows_ok", "state_rk4", "advance_py",
                 "prepare_row", "_ek", "_clip1", "output_row", "step_core"):
        g[name] = jit(g[name])
    return g["advance_py"], jit(outputs), jit(step_packed)


def _get(i: int) -> Callable[..., Any]:
    if not _compiled:
        _compiled.extend(_compile())
    return _compiled[i]


def advance(*args: Any) -> tuple[int, int]:
    """:func:`advance_py` compiled by numba (compiled on the first call, cached on disk)."""
    return _get(0)(*args)


def outputs_compiled(*args: Any) -> None:
    """:func:`outputs` compiled."""
    return _get(1)(*args)


def step_packed_dispatcher() -> Callable[..., int]:
    """The compiled :func:`step_packed` (numba's dispatcher, compiled on first use)."""
    return _get(2)
