"""Seed 003's printed formulas transcribed literally, for the checks of the corrected ones.

:func:`printed_state_rhs` is Appendix 2's F(Y, t) with the printed kinematic matrix
Phi(beta, gamma) and the printed ``+Omega^2 (r+h) cos(phi) sin(phi)`` centrifugal term;
:func:`printed_observer_13` is (13) with the c_ij of ``C = D B^T`` (spherical Earth). The
filter (:mod:`navsim.estimators.paper_ekf.mechanization`) is tested against them; the corrections
and their evidence are listed in :mod:`navsim.estimators.paper_ekf`.
"""

from __future__ import annotations

import math

import numpy as np

from ...rotations import euler_krylov_matrix
from .track_functions import TrackFunctions

__all__ = ["printed_state_rhs", "printed_observer_13"]


def printed_state_rhs(Y: np.ndarray, omega_b: np.ndarray, f_b: np.ndarray, t: float, track_functions: TrackFunctions, r: float,
                      omega_earth: float) -> np.ndarray:
    """Appendix 2's F(Y, t) transcribed literally (printed Phi(beta, gamma), printed +centrifugal).

    For checks only (spherical Earth). Y = [alpha, beta, gamma, phi, V_Y].
    """
    a, b, g, phi, V = (float(x) for x in Y)
    sg, cg, cb, tb = math.sin(g), math.cos(g), math.cos(b), math.tan(b)
    phi_printed = np.array([[sg / cb, cg / cb, 0.0], [cg, -sg, 0.0], [sg * tb, cg * tb, 1.0]])
    lam, dlam, _, hh, dh = track_functions.scalars(phi)
    C = euler_krylov_matrix(a, b, g) @ euler_krylov_matrix(-phi, lam + omega_earth * t, 0.0).T
    rh = r + hh
    vdot = (C.T[1] @ f_b - (2 * omega_earth + dlam * V / rh) * dlam * V * math.cos(phi) * math.sin(phi)
            - dh * V ** 2 / rh ** 2 + omega_earth ** 2 * rh * math.cos(phi) * math.sin(phi))
    return np.concatenate([phi_printed @ omega_b, [V / rh, vdot]])


def printed_observer_13(Y: np.ndarray, f_b: np.ndarray, t: float, track_functions: TrackFunctions, r: float, omega_earth: float,
                        centrifugal_sign: float = 1.0) -> tuple[float, np.ndarray]:
    """(13) transcribed literally: H_a(Y, t) and H_w (1 x 3), with the c_ij of C = D B^T.

    ``centrifugal_sign=+1`` as printed; -1 for the physical sign. Spherical Earth. For checks.
    """
    a, b, g, phi, V = (float(x) for x in Y)
    lam, dlam, ddlam, hh, dh = track_functions.scalars(phi)
    C = euler_krylov_matrix(a, b, g) @ euler_krylov_matrix(-phi, lam + omega_earth * t, 0.0).T
    c = lambda i, j: C[i - 1, j - 1]  # noqa: E731 - c_ij as printed (1-based)
    rh = r + hh
    sp, cp = math.sin(phi), math.cos(phi)
    k = dlam * cp
    zay, zaz = f_b[1], f_b[2]
    den = c(1, 1) - k * c(1, 2)
    bracket = (-(2 * omega_earth + dlam * V / rh) * dlam * V * cp * sp - dh * V ** 2 / rh ** 2
               + centrifugal_sign * omega_earth ** 2 * rh * cp * sp)
    d_k = ddlam * cp - dlam * sp  # d/dphi (lambda' cos phi)
    h_a = ((k * c(2, 2) - c(2, 1)) * zay + (k * c(3, 2) - c(3, 1)) * zaz + k * bracket + d_k * V ** 2 / rh
           - (2 * omega_earth + dlam * V / rh) * V * (sp - dh / rh * cp)) / den
    h_w = (C.T[0] - k * C.T[1]) / den
    return float(h_a), h_w
