"""A reference strapdown integrator for tests: independent of navsim.strapdown.

It integrates in the inertial frame i (coincident with ECEF at t = 0):
    q_ib' = 1/2 q_ib * [0, omega_ib_b],   v_i' = C_ib f_b + G_i(r_i, t),   r_i' = v_i,
with classical RK4 over each navigation step. Inside a step omega_ib_b(t) and f_b(t) are
the cubic polynomials whose r-fold integrals r = 1..4 equal the IMU's multiple-integral
increments (seed 000 eq. 1.14): an exact inversion, so the only approximations are the
cubic model of the motion within a step and RK4.
"""

from __future__ import annotations

import math

import numpy as np

from navsim.earth import mat_en
from navsim.rotations import quat_multiply, quat_to_mat, mat_to_quat


def cubic_from_multiple_integrals(increments: np.ndarray, h: float) -> np.ndarray:
    """Coefficients c (n, 4, 3) of g(tau) = sum c_k (tau/h)^k from r-fold integrals (n, 4, 3)."""
    moments = np.array([[math.factorial(k) / math.factorial(k + r) for k in range(4)] for r in range(1, 5)])
    scaled = increments / (h ** np.arange(1, 5))[None, :, None]
    return np.einsum("kr,nrc->nkc", np.linalg.inv(moments), scaled)


def _gravitation_i(earth, r_i, t):
    ang = earth.rate * t
    c, s = math.cos(ang), math.sin(ang)
    rot_ei = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # i -> e
    r_e = rot_ei @ r_i
    lat, lon, h = earth.ecef_to_geodetic(r_e)
    gravity_e = mat_en(lat, lon).T @ earth.gravity_n(lat, h)
    omega = np.array([0.0, 0.0, earth.rate])
    centrifugal_e = -np.cross(omega, np.cross(omega, r_e))
    return rot_ei.T @ (gravity_e - centrifugal_e)


def integrate(earth, truth0, dtheta_r, dv_r, h, checkpoints=()):
    """Integrate from the true state at t = 0; return {step: (r_e, v_e, mat_eb)} at checkpoints."""
    omega_c = cubic_from_multiple_integrals(dtheta_r, h)
    force_c = cubic_from_multiple_integrals(dv_r, h)
    r = truth0.position_e[0].copy()
    omega_e = np.array([0.0, 0.0, earth.rate])
    v = truth0.velocity_e[0] + np.cross(omega_e, r)
    mat_eb = mat_en(truth0.lat[0], truth0.lon[0]).T @ truth0.mat_nb[0]
    q = mat_to_quat(mat_eb)
    wanted = set(checkpoints)
    out = {}

    def deriv(q, v, r, tau, k, t):
        x = tau / h
        powers = np.array([1.0, x, x * x, x * x * x])
        w = powers @ omega_c[k]
        f = powers @ force_c[k]
        qdot = 0.5 * quat_multiply(q, np.concatenate([[0.0], w]))
        vdot = quat_to_mat(q) @ f + _gravitation_i(earth, r, t + tau)
        return qdot, vdot, v

    for k in range(len(dtheta_r)):
        t = k * h
        k1 = deriv(q, v, r, 0.0, k, t)
        k2 = deriv(q + 0.5 * h * k1[0], v + 0.5 * h * k1[1], r + 0.5 * h * k1[2], 0.5 * h, k, t)
        k3 = deriv(q + 0.5 * h * k2[0], v + 0.5 * h * k2[1], r + 0.5 * h * k2[2], 0.5 * h, k, t)
        k4 = deriv(q + h * k3[0], v + h * k3[1], r + h * k3[2], h, k, t)
        q = q + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        q = q / np.linalg.norm(q)
        v = v + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        r = r + h / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2])
        if k + 1 in wanted:
            t1 = (k + 1) * h
            ang = earth.rate * t1
            c, s = math.cos(ang), math.sin(ang)
            rot_ei = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
            r_e = rot_ei @ r
            out[k + 1] = (r_e, rot_ei @ v - np.cross(omega_e, r_e), rot_ei @ quat_to_mat(q))
    return out
