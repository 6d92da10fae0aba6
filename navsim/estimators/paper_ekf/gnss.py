"""The GNSS measurement model of seed 003's filter (9) and the discrete epoch update (16).

Pseudoranges and Dopplers of every valid satellite (satellite ECEF position r_s, m, and
velocity v_s, m/s) predicted from the state, without the clock states::

    H_R = |r_s - r(phi)|,   H_V = (r_s - r)/|r_s - r| . (v_s - V_Y t_e(phi))        (9), (2)-(3)
    r(phi) = [(R_E + h) cos phi cos lambda, (R_E + h) cos phi sin lambda,
              (R_E (1 - e^2) + h) sin phi]                                     (4)
    t_e = B^T [k, 1, m]   (the ECEF velocity per unit V_Y, (5))

the clock bias and drift added in extended mode. With a lever arm l (navsim extension,
option ``lever_arm``) the antenna's observables (LA.1)-(LA.2) of
:mod:`navsim.estimators.paper_ekf`: ``r_a = r + C_eb l``, ``v_a = V_Y t_e + C_eb (omega x
l) - omega_ie x C_eb l``, ``C_eb = C_ep(t) D^T``. The Jacobian: the phi column by the
complex step, the V_Y column ``-u . t_e`` (u the unit line of sight), the attitude and
gyro-bias columns of the arm (LA.4), the clock columns 1.

The update (16) stacks, as in (15), all valid pseudoranges (variance ``sigma_rho^2``,
m^2) and Dopplers (``sigma_rhodot^2``, m^2/s^2) and, when ``accel_in_update``, the
accelerometer observation Z_ax of the epoch's step with the variance ``H_w D_a H_w^T /
dt`` of a step-mean sample (the printed (16) weighs it with the intensity D_a); the
Kalman update in Joseph form, NIS and its degrees of freedom returned.

References: [003] eqs. (2)-(5), (9), (15), (16); [5] Groves P.D., Principles of GNSS,
Inertial, and Multisensor Integrated Navigation Systems, 2nd ed., 2013, 14.2.3, 14.3.3.
"""

from __future__ import annotations

import cmath
import math
from typing import Any, Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ...rotations import euler_krylov_matrix
from .covariance import Covariance
from .numerics import CSTEP, check_rows, cross

__all__ = ["GnssUpdate"]

_Fn = Callable[[Any], Any]


def _functions(phi: float | complex) -> tuple[_Fn, _Fn, _Fn]:
    """sin, cos, sqrt of :mod:`cmath` for a complex phi (the complex step), else of :mod:`math`."""
    return (cmath.sin, cmath.cos, cmath.sqrt) if isinstance(phi, complex) else (math.sin, math.cos, math.sqrt)


class GnssUpdate(Covariance):
    """(9) and the epoch update (16) (a layer of :class:`PaperEkf`)."""

    def antenna_offset(self, alpha: float, beta: float, gamma: float, t: float, omega_ib_b: Sequence[float] | np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The antenna's ECEF offset from the track point, its velocity, and their partials.

        Parameters
        ----------
        alpha, beta, gamma : float
            Euler-Krylov angles of the body relative to the inertial frame, rad.
        t : float
            Time since the inertial frame coincided with the Greenwich frame, s.
        omega_ib_b : array_like (3,)
            Body rate relative to inertial space (the filter's gyro rate), rad/s.

        Returns
        -------
        arm_e : (3,) m
            ``C_eb l`` (LA.1), with ``C_eb = C_ne C_nb = C_ep(t) D^T`` (the ENU frame drops
            out: ``C_ne(phi, lambda) B(phi, lambda + Omega t) = C_ep(t)``, the inertial paper
            axes xi, eta, zeta = y, z, x turned by the Earth's rotation, whatever phi).
        arm_velocity_e : (3,) m/s
            ``C_eb (omega_ib_b x l) - omega_ie x C_eb l`` (LA.2).
        d_arm_e : (3, 3)
            Columns d arm_e / d(alpha, beta, gamma): ``C_ep D^T (a_i x l)``, from
            ``dD/dtheta_i = -[a_i x] D`` (a_i the angle axes in body components).
        d_arm_velocity_e : (3, 3)
            Columns d arm_velocity_e / d(alpha, beta, gamma).
        d_arm_velocity_bg : (3, 3)
            Columns d arm_velocity_e / d(gyro bias): ``-C_eb (e_j x l)`` (omega = gyro - bias).
        """
        lx, ly, lz = (float(v) for v in self.lever_arm_b)
        wx, wy, wz = (float(v) for v in omega_ib_b)
        ot = self._omega * t
        so, co = math.sin(ot), math.cos(ot)
        c_ep = np.array([[so, 0.0, co], [co, 0.0, -so], [0.0, 1.0, 0.0]])
        c_eb = c_ep @ euler_krylov_matrix(alpha, beta, gamma).T
        sa, ca, sg, cg = math.sin(alpha), math.cos(alpha), math.sin(gamma), math.cos(gamma)
        axes = ((cg, -sg, 0.0), (sg * ca, cg * ca, -sa), (0.0, 0.0, 1.0))
        lever = (lx, ly, lz)
        turn = cross((wx, wy, wz), lever)  # omega_ib_b x l
        arm_e = c_eb @ np.array(lever)
        turn_e = c_eb @ np.array(turn)
        om = self._omega
        arm_velocity_e = turn_e - np.array([-om * arm_e[1], om * arm_e[0], 0.0])  # (LA.2)
        d_arm = c_eb @ np.array([cross(ax, lever) for ax in axes]).T
        d_vel = c_eb @ np.array([cross(ax, turn) for ax in axes]).T
        d_vel -= np.array([-om * d_arm[1], om * d_arm[0], np.zeros(3)])
        d_bias = -(c_eb @ np.array([cross(e, lever) for e in np.eye(3).tolist()]).T)
        return arm_e, arm_velocity_e, d_arm, d_vel, d_bias

    def gnss_model(self, phi: float | complex, V: float, sat_pos_e: np.ndarray, sat_vel_e: np.ndarray,
                   arm_e: np.ndarray | None = None, arm_velocity_e: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predicted pseudoranges H_R(phi) and Dopplers H_V(phi, V_Y) without clock, (m,) each.

        Complex-safe in phi (used for the complex-step Jacobian). Returns (h_r, h_v,
        t_e) with t_e the ECEF velocity per unit V_Y. ``arm_e``, ``arm_velocity_e`` (3,):
        the antenna's offset from the track point and its velocity (:meth:`antenna_offset`);
        the observables are then the antenna's (LA.1)-(LA.2) - a navsim extension, 003's
        (2)-(3) measure at the track point (None, the default).
        """
        lam, dlam, _, hh, dh = self.track_functions.scalars(phi)
        sin, cos, sqrt = _functions(phi)
        sp, cp, sl, cl = sin(phi), cos(phi), sin(lam), cos(lam)
        if self._sphere:
            rn = re = self._a + hh
            rz = re
        else:
            w = 1.0 - self._e2 * sp * sp
            r_e = self._a / sqrt(w)
            rn, re = r_e * (1.0 - self._e2) / w + hh, r_e + hh
            rz = r_e * (1.0 - self._e2) + hh
        pos = np.array([re * cp * cl, re * cp * sl, rz * sp])  # (4) in ECEF axes
        k = dlam * cp * re / rn
        m = dh / rn
        # (5): V_G = B^T V_S, V_S = [k, 1, m] V_Y; B^T columns are e, n, u in ECEF
        t_e = np.array([-sl * k + (-sp * cl) + cp * cl * m, cl * k + (-sp * sl) + cp * sl * m, cp + sp * m])
        if arm_e is not None and arm_velocity_e is not None:  # (LA.1)-(LA.2)
            d = sat_pos_e - (pos + arm_e)
            rho = np.sqrt(np.sum(d * d, axis=1))
            h_v = np.sum(d * (sat_vel_e - V * t_e - arm_velocity_e), axis=1) / rho
            return rho, h_v, t_e
        d = sat_pos_e - pos
        rho = np.sqrt(np.sum(d * d, axis=1))
        h_v = np.sum(d * (sat_vel_e - V * t_e), axis=1) / rho  # (3)
        return rho, h_v, t_e

    def gnss_observation(self, Y: Sequence[float], t: float, sat_pos_e: np.ndarray, sat_vel_e: np.ndarray,
                         gyro_rate_b: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predicted observables of (9) at the state Y and their Jacobian (16).

        Parameters
        ----------
        Y : sequence (n_states,)
            Filter state.
        t : float
            Epoch time, s.
        sat_pos_e, sat_vel_e : ndarray (m, 3)
            Satellite ECEF positions (m) and velocities (m/s).
        gyro_rate_b : array_like (3,), optional
            Measured body rate of the epoch's step (dtheta_1 / dt), rad/s; the gyro-bias
            states are subtracted here. Used only with a lever arm.

        Returns
        -------
        h_r, h_v : ndarray (m,)
            Pseudoranges (m) and Dopplers (m/s) without the clock states: of the track point
            (003's H_R(phi), H_V(phi, V_Y)), or of the antenna with a lever arm (LA.1)-(LA.2).
        H : ndarray (2 m, n_states)
            d[h_r + clock bias; h_v + clock drift] / dY: the phi column by the complex step,
            the V_Y column ``-u . t_e``, with a lever arm the attitude columns (LA.4)::

                d rho / d theta_i = -u . c_i,    c_i = d arm_e / d theta_i
                d rhodot / d theta_i = -(rel . c_i - (u . c_i)(u . rel)) / rho - u . d arm_velocity_e / d theta_i

            (u the unit line of sight from the antenna, rel the satellite velocity relative
            to the antenna) and the gyro-bias columns ``-u . d arm_velocity_e / d b_g``;
            the clock columns (1).
        """
        ns = self.n_states
        phi, V = Y[3], Y[4]
        m = len(sat_pos_e)
        if self._lever:  # (LA.1)-(LA.2): the observables are the antenna's
            omega_b = np.asarray(gyro_rate_b, dtype=float)
            if self._biases:
                omega_b = omega_b - np.asarray(Y[self._i_bg:self._i_bg + 3], dtype=float)
            arm = self.antenna_offset(Y[0], Y[1], Y[2], t, omega_b)
            h_r, h_v, t_e = self.gnss_model(phi, V, sat_pos_e, sat_vel_e, arm[0], arm[1])
            h_rc, h_vc, _ = self.gnss_model(complex(phi, CSTEP), V, sat_pos_e, sat_vel_e, arm[0], arm[1])
            d = sat_pos_e - (self._ecef(phi) + arm[0])
        else:
            h_r, h_v, t_e = self.gnss_model(phi, V, sat_pos_e, sat_vel_e)
            h_rc, h_vc, _ = self.gnss_model(complex(phi, CSTEP), V, sat_pos_e, sat_vel_e)
            d = sat_pos_e - self._ecef(phi)
        los = d / h_r[:, None]
        H = np.zeros((2 * m, ns))
        H[:m, 3] = h_rc.imag / CSTEP
        H[m:, 3] = h_vc.imag / CSTEP
        H[m:, 4] = -(los @ t_e)
        if self._lever:  # (LA.4) the arm's attitude (and gyro-bias) columns
            d_arm, d_turn, d_bias = arm[2], arm[3], arm[4]
            rel = sat_vel_e - V * t_e - arm[1]  # satellite velocity relative to the antenna
            u_rel = np.sum(los * rel, axis=1)
            u_da = los @ d_arm  # (m, 3): u . dr_a/dtheta_i
            H[:m, 0:3] = -u_da
            H[m:, 0:3] = -(rel @ d_arm - u_rel[:, None] * u_da) / h_r[:, None] - los @ d_turn
            if self._biases:
                H[m:, self._i_bg:self._i_bg + 3] = -(los @ d_bias)
        if self._clock:
            i = self._i_clk
            H[:m, i] = 1.0
            H[m:, i + 1] = 1.0
        return h_r, h_v, H

    def _ecef(self, phi: float) -> np.ndarray:
        lam, _, _, hh, _ = self.track_functions.scalars(phi)
        sp, cp = math.sin(phi), math.cos(phi)
        if self._sphere:
            re = rz = self._a + hh
        else:
            r_e = self._a / math.sqrt(1.0 - self._e2 * sp * sp)
            re, rz = r_e + hh, r_e * (1.0 - self._e2) + hh
        return np.array([re * cp * math.cos(lam), re * cp * math.sin(lam), rz * sp])

    def _epoch_update(self, obs: Any, f_mean: Sequence[float], t: float, omega_mean: np.ndarray | None = None
                      ) -> tuple[float, int] | None:
        """Discrete update (16) with all valid pseudoranges and Dopplers (+ Z_ax).

        ``omega_mean``: the step-mean gyro rate dtheta_1/dt of the epoch's step (rad/s),
        needed only with a lever arm (LA.2)."""
        valid = np.asarray(obs.valid, dtype=bool)
        if not valid.any():
            return None
        Y = self._Y
        ns = self.n_states
        sat_pos = np.asarray(obs.sat_pos_e, dtype=float)[valid]
        sat_vel = np.asarray(obs.sat_vel_e, dtype=float)[valid]
        m = len(sat_pos)
        h_r, h_v, H_g = self.gnss_observation(Y, t, sat_pos, sat_vel, omega_mean)
        rows = []
        resid = []
        var = []
        if self._accel_in_update:
            wmean = [0.0, 0.0, 0.0]  # gyro values do not enter H_a or its Jacobian
            first, _, hneg, _, _, sig2 = self._fused(Y, wmean, f_mean, t)
            rows.append([-x for x in hneg])
            resid.append(first[5])
            var.append(sig2 / self._dt)
        H = np.zeros((len(rows) + 2 * m, ns))
        if rows:
            H[0] = rows[0]
        j0 = len(rows)
        H[j0:] = H_g
        z_r = np.asarray(obs.pseudorange_m, dtype=float)[valid] - h_r
        z_v = np.asarray(obs.pseudorange_rate_mps, dtype=float)[valid] - h_v
        if self._clock:
            i = self._i_clk
            z_r = z_r - Y[i]
            z_v = z_v - Y[i + 1]
        nu = np.concatenate([np.array(resid), z_r, z_v])
        r_diag = np.concatenate([np.array(var), np.full(m, self._r_code), np.full(m, self._r_dopp)])
        P = self._P
        PHt = P @ H.T
        S = H @ PHt + np.diag(r_diag)
        S = 0.5 * (S + S.T)
        Kt = np.linalg.solve(S, PHt.T)  # K^T = S^-1 H P
        dx = Kt.T @ nu
        for j in range(ns):
            Y[j] += float(dx[j])
        ikh = np.eye(ns) - Kt.T @ H
        P = ikh @ P @ ikh.T + (Kt.T * r_diag) @ Kt  # Joseph form
        self._P = 0.5 * (P + P.T)
        self._P_rows = self._P.tolist()
        check_rows(self._P_rows)
        return float(nu @ np.linalg.solve(S, nu)), int(len(nu))
