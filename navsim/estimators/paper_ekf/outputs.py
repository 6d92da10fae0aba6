"""The outputs of seed 003's filter: the navigation solution and its 9 x 9 covariance from the state.

::

    lat = phi,  lon = lambda(phi),  h = h(phi),  velocity_n = [k V_Y, V_Y, m V_Y] (m/s)
    mat_nb = B(phi, lambda + Omega t) D^T(alpha, beta, gamma) -> heading, pitch, roll (rad)
    covariance = J R J^T

J is the Jacobian of that conversion (rank 5: position errors only along the track; the
attitude errors psi about the ENU axes, ``psi = mat_nb sum_i a_i dtheta_i - theta_n dphi``
with ``theta_n = [-1, lambda' cos phi, lambda' sin phi] dphi`` the rotation of the ENU
frame with phi). The metrics' convention for the covariance is that of
:mod:`navsim.estimators.base` (position m, velocity m/s, attitude rad).

References: [003] eqs. (5), (8), Appendix 1.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...rotations import euler_krylov_matrix, hpr_from_mat_nb
from .gnss import GnssUpdate

__all__ = ["Outputs"]


class Outputs(GnssUpdate):
    """Solutions and covariances from states; the extra states of an Estimate (a layer of :class:`PaperEkf`)."""

    def outputs(self, Y: np.ndarray, P: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Navigation solutions (n, 9) and 9 x 9 covariances (n, 9, 9) from states (n, ns)."""
        Y = np.asarray(Y, dtype=float)
        t = np.asarray(t, dtype=float)
        a, b, g, phi, V = Y[:, 0], Y[:, 1], Y[:, 2], Y[:, 3], Y[:, 4]
        lam, dlam, ddlam, hh, dh, ddh = self.track_functions.arrays(phi)
        sp, cp = np.sin(phi), np.cos(phi)
        if self._sphere:
            rn = re = self._a + hh
            drn = dre = dh
        else:
            w = 1.0 - self._e2 * sp * sp
            r_e = self._a / np.sqrt(w)
            r_n = r_e * (1.0 - self._e2) / w
            rn, re = r_n + hh, r_e + hh
            dre = r_e * self._e2 * sp * cp / w + dh
            drn = 3.0 * r_n * self._e2 * sp * cp / w + dh
        ratio = re / rn
        k = dlam * cp * ratio
        kphi = (ddlam * cp - dlam * sp) * ratio + dlam * cp * (dre - ratio * drn) / rn
        m = dh / rn
        mphi = ddh / rn - dh * drn / rn ** 2
        velocity_n = np.column_stack([k * V, V, m * V])
        dmat = euler_krylov_matrix(a, b, g)
        bmat = euler_krylov_matrix(-phi, lam + self._omega * t, 0.0)
        mat_nb = bmat @ np.swapaxes(dmat, -1, -2)  # C^T = B D^T
        heading, pitch, roll = hpr_from_mat_nb(mat_nb)
        sol = np.column_stack([phi, lam, hh, velocity_n, heading, pitch, roll])
        n = len(phi)
        J = np.zeros((n, 9, self.n_states))
        J[:, 0, 3] = re * cp * dlam
        J[:, 1, 3] = rn
        J[:, 2, 3] = dh
        J[:, 3, 3], J[:, 3, 4] = kphi * V, k
        J[:, 4, 4] = 1.0
        J[:, 5, 3], J[:, 5, 4] = mphi * V, m
        sg, cg, sa, ca = np.sin(g), np.cos(g), np.sin(a), np.cos(a)
        zero = np.zeros_like(a)
        axes = np.stack([np.stack([cg, -sg, zero], -1), np.stack([sg * ca, cg * ca, -sa], -1),
                         np.stack([zero, zero, zero + 1.0], -1)], axis=-1)  # columns a_alpha, a_beta, a_gamma
        J[:, 6:9, 0:3] = mat_nb @ axes
        J[:, 6, 3] = 1.0  # -theta_n: rotation of the ENU frame with phi
        J[:, 7, 3] = -dlam * cp
        J[:, 8, 3] = -dlam * sp
        cov = J @ P @ np.swapaxes(J, -1, -2)
        return sol, 0.5 * (cov + np.swapaxes(cov, -1, -2))

    def _extra_states(self, y: np.ndarray) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self._clock:
            out["clock_bias_m"] = float(y[self._i_clk])
            out["clock_drift_mps"] = float(y[self._i_clk + 1])
        if self._biases:
            out["accel_bias"] = y[self._i_ba:self._i_ba + 3].copy()
            out["gyro_bias"] = y[self._i_bg:self._i_bg + 3].copy()
        return out
