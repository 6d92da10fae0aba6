"""A conventional full-state EKF on seed 003's navigation equations (1), no track model.

Seed 003 argues against filters built on the full "differential model of the object" (1):
nine states, whose covariance needs 45 equations (9 + 45 = 54 equations in all, against
5 + 15 = 20 for the reduced track-model filter of :mod:`navsim.estimators.paper_ekf`).
:class:`FullStateEkf` is that filter, built like the paper's: continuous-discrete, the
state and the Riccati equation integrated by RK4 between epochs, the same GNSS update
(16) with the pseudorange and Doppler of every valid satellite. It knows nothing of the
track (the map is not used): it is the comparison the paper's accuracy and cost claims
are about.

State and equations (1), corrected as in :mod:`navsim.estimators.paper_ekf`
---------------------------------------------------------------------------
::

    x = [alpha, beta, gamma, lambda, phi, h, V_X, V_Y, V_Z]                     (FS.0)

alpha, beta, gamma the Euler-Krylov angles of the body relative to the inertial frame
(Appendix 1; ``D(alpha, beta, gamma)`` maps the inertial paper axes xi, eta, zeta to the
body), lambda, phi, h longitude, latitude, height, V = [V_X, V_Y, V_Z] the velocity
relative to the Earth in East-North-Up axes. With R = r + h, W = 2 omega_ie + omega_en
and the spherical Earth of the example (r, Omega, g of the context; plumb-line gravity
with the physical centrifugal sign)::

    [alpha', beta', gamma'] = Phi(alpha, gamma) omega_ib_b                      (FS.1)
    lambda' = V_X / (R cos phi),  phi' = V_Y / R,  h' = V_Z                     (FS.2)
    V' = B D^T f_b + g_n(phi, h) - W x V                                        (FS.3)
    W = [-V_Y / R, 2 Omega cos phi + V_X / R, 2 Omega sin phi + V_X tan phi / R]
    g_n = [0, -Omega^2 R cos phi sin phi, Omega^2 R cos^2 phi - g]

``B = D(-phi, lambda + Omega t, 0)`` (the inertial frame to ENU) and ``Phi(alpha, gamma)``
the kinematic matrix of D (Phi(beta, gamma) as printed is wrong; see
:mod:`navsim.rotations`). omega_ib_b, f_b: the gyro and accelerometer outputs, white
noise of intensities D_d, D_a (the nominal ARW and VRW squared), so the process noise is
``Q = diag(D_d Phi Phi^T, 0_3, D_a I_3)`` (``B D^T`` is a rotation).

Filter
------
* Between epochs: RK4 of (FS.1)-(FS.3) every navigation step with the inputs inside the
  step as in the paper filter (``input_model="polynomial"``: the degree R-1 polynomial
  matching all multiple integrals, evaluated at the step's start, middle and end;
  ``"mean"``: dtheta_1/dt, dv_1/dt), and RK4 of ``P' = F P + P F^T + Q`` with the analytic
  Jacobian ``F = df/dx`` (FS.4, written out in :meth:`FullStateEkf.jacobian`; the tests
  compare it with central finite differences) frozen over each covariance interval of
  ``cov_step_s`` (default: the navigation step, as paper-ekf's default).
* At GNSS epochs, (16): the pseudoranges and Dopplers (003 (2)-(3)) of the valid
  satellites, ``rho = |r_s - r_a|``, ``rhodot = u . (v_s - v_a)``, with the track point
  ``r = R [cos phi cos lambda, cos phi sin lambda, sin phi]`` and ``v = C_en V``, or,
  with the antenna lever arm l of the context (``lever_arm="auto"``), the antenna's
  ``r_a = r + C_eb l``, ``v_a = v + C_eb (omega_ib_b x l) - omega_ie x C_eb l`` (as
  paper-ekf's (LA.1)-(LA.2)). Jacobian by the complex step over all nine states (exact to
  rounding; once per epoch); Joseph-form update.
* Prior: the 9 x 9 prior over ENU position (m), velocity and attitude (small ENU angles
  psi) mapped to (FS.0) by the first-order conversion; output: the navigation solution and
  its 9 x 9 covariance ``J P J^T`` (psi = C_nb sum_i a_i dtheta_i - theta_n, theta_n =
  [-dphi, cos phi dlambda, sin phi dlambda], as in paper-ekf).

Scope: the model of (1) - spherical Earth, no receiver clock, no sensor biases - as the
paper's filter in faithful mode; it is the comparison filter for the seed-003 scenarios
(``paper-2012`` and its variants). On a WGS-84 scenario it still uses a sphere of the
context's equatorial radius (a model error), and with a modelled receiver clock it is
refused (ConfigError).

References
----------
.. [003] Sokolov S.V., Vdovichenko S.S., Nauchnoe Priborostroenie, 2012 (seed 003):
   eq. (1), (2)-(3), (16), Appendix 1.
.. [G] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
   Systems, 2nd ed., 2013, sec. 5.4 (local-level mechanisation), 14.2 (EKF).
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ConfigError
from ..option_checks import check_auto_none, check_choice, check_optional_positive_finite
from ..rotations import euler_krylov_from_matrix, euler_krylov_matrix, hpr_from_mat_nb, mat_nb_from_hpr
from .base import Context, Estimate, EstimateBatch, GnssObservation, Measurement, MeasurementBatch, NoiseScalable, Prior
from .paper_ekf import input_polynomial_matrix

__all__ = ["FullStateEkf"]

_CSTEP = 1e-20
_N = 9


def _dmat(a: complex, b: complex, g: complex, lib: ModuleType = math) -> tuple[tuple[Any, Any, Any], ...]:
    """D(alpha, beta, gamma) of Appendix 1 (rows), complex-safe with lib=cmath/numpy."""
    sa, ca, sb, cb, sg, cg = lib.sin(a), lib.cos(a), lib.sin(b), lib.cos(b), lib.sin(g), lib.cos(g)
    return ((sb * sa * sg + cb * cg, ca * sg, cb * sa * sg - sb * cg),
            (sb * sa * cg - cb * sg, ca * cg, cb * sa * cg + sb * sg),
            (sb * ca, -sa, cb * ca))


class FullStateEkf(NoiseScalable):
    """Nine-state continuous-discrete EKF on (1) of seed 003; see the module docstring.

    Parameters
    ----------
    cov_step_s : float, optional
        Riccati RK4 step (a divisor of the GNSS period), default the navigation step.
    input_model : {"polynomial", "mean"}
        omega(t), f(t) inside a step from all multiple integrals, or the step means.
    lever_arm : {"auto", "none"}
        "auto": the observables are the antenna's (``context.gnss.lever_arm_b_m``); "none":
        predicted at the IMU (003's (2)-(3)).

    Notes
    -----
    ``Estimate.extra`` holds ``state`` and ``state_cov``. After :meth:`step_batch`,
    ``last_states`` / ``last_state_cov`` hold the batch's states (n, 9) and covariances.
    """

    NOISE_PROCESS = ('_qd', '_qa')
    NOISE_MEASUREMENT_VARIANCE = ('_r_code', '_r_dopp')
    # where set_noise_scale finds Q and R after reset (navsim.estimators.base.NoiseScalable)

    n_states = _N

    def __init__(self, cov_step_s: float | None = None, input_model: str = "polynomial",
                 lever_arm: str = "auto") -> None:
        check_optional_positive_finite("cov_step_s", cov_step_s, "None or a positive step (s)")
        check_choice("input_model", input_model, ("polynomial", "mean"))
        check_auto_none("lever_arm", lever_arm)
        self.cov_step_s = cov_step_s
        self.input_model = input_model
        self.lever_arm = lever_arm
        self._ready = False

    # ------------------------------------------------------------------ set-up
    def reset(self, context: Context, prior: Prior) -> None:
        """Start an episode: model constants from the context, state from the prior."""
        if context.gnss.clock_modelled:
            raise ConfigError("full-state-ekf", "a scenario without a receiver clock (the model of 003 (1)-(3))",
                              "context.gnss.clock_modelled = True")
        earth = context.earth
        self.context = context
        self._a = float(earth.a)
        self._omega = float(earth.rate)
        self._g0 = float(getattr(earth, "g0", 9.81) or 9.81)
        self._qd = float(context.imu.gyro_arw) ** 2
        self._qa = max(float(context.imu.accel_vrw) ** 2, 1e-12)
        self._r_code = max(float(context.gnss.pseudorange_sigma_m), 1e-3) ** 2
        self._r_dopp = max(float(context.gnss.doppler_sigma_mps), 1e-4) ** 2
        arm = context.gnss.lever_arm_b_m if self.lever_arm == "auto" else (0.0, 0.0, 0.0)
        self.lever_arm_b = np.array(arm, dtype=float)
        self._lever = bool(np.any(self.lever_arm_b != 0.0))
        dt = float(context.nav_period_s)
        self._dt = dt
        self._spe = max(int(round(context.gnss_period_s / dt)), 1)
        cov = dt if self.cov_step_s is None else float(self.cov_step_s)
        n_c = cov / dt
        if abs(n_c - round(n_c)) > 1e-9 or round(n_c) < 1 or self._spe % int(round(n_c)) != 0:
            raise ConfigError("cov_step_s", f"a whole multiple of the navigation step {dt} s dividing the GNSS "
                              f"period {context.gnss_period_s} s", self.cov_step_s)
        self._n_c = int(round(n_c))
        R = int(context.orders)
        if self.input_model == "mean" or R == 1:
            minv = np.zeros((R, R))
            minv[0, 0] = 1.0
        else:
            minv = input_polynomial_matrix(R)
        s_pts = np.array([0.0, 0.5, 1.0])
        self._lvec = (s_pts[:, None] ** np.arange(R)[None, :]) @ minv  # (3, R)
        self._dt_pow = np.array([dt ** (r + 1) for r in range(R)])
        self._x, self._P = self._from_prior(prior)
        self._cov_left = 0
        self._F = None
        self._diverged = False
        self._ready = True

    def _from_prior(self, prior: Prior) -> tuple[list[float], np.ndarray]:
        lat, lon, h = float(prior.lat), float(prior.lon), float(prior.h)
        mat_nb = mat_nb_from_hpr(prior.heading, prior.pitch, prior.roll)
        bmat = euler_krylov_matrix(-lat, lon + self._omega * float(prior.t), 0.0)
        a, b, g = (float(v) for v in euler_krylov_from_matrix(mat_nb.T @ bmat))
        x = [a, b, g, lon, lat, h, *(float(v) for v in prior.velocity_n)]
        # first-order map of the prior error [dE, dN, dU, dV, psi] to dx (inverse of _jac_out)
        rr = self._a + h
        cp, tp = math.cos(lat), math.tan(lat)
        G = np.zeros((_N, 9))
        G[3, 0] = 1.0 / (rr * cp)
        G[4, 1] = 1.0 / rr
        G[5, 2] = 1.0
        G[6:9, 3:6] = np.eye(3)
        j_att = self._kin(a, g) @ mat_nb.T  # dtheta = Phi C_bn (psi + theta_n)
        theta_n = np.array([[0.0, -1.0 / rr, 0.0], [1.0 / rr, 0.0, 0.0], [tp / rr, 0.0, 0.0]])
        G[0:3, 6:9] = j_att
        G[0:3, 0:3] = j_att @ theta_n
        p = G @ np.asarray(prior.covariance, dtype=float) @ G.T
        return x, 0.5 * (p + p.T)

    @staticmethod
    def _kin(a: float, g: float) -> np.ndarray:
        sg, cg, ca, ta = math.sin(g), math.cos(g), math.cos(a), math.tan(a)
        return np.array([[cg, -sg, 0.0], [sg / ca, cg / ca, 0.0], [sg * ta, cg * ta, 1.0]])

    # ------------------------------------------------------------------ the model (FS.1)-(FS.3)
    def rhs(self, x: Sequence[float], t: float, w: Sequence[float], f: Sequence[float]) -> tuple[float, ...]:
        """f(x, t) of (FS.1)-(FS.3) at the gyro rate w and specific force f (body axes)."""
        return self._rhs(x, t, w, f, False)[0]

    def jacobian(self, x: Sequence[float], t: float, w: Sequence[float], f: Sequence[float]) -> np.ndarray:
        """F = df/dx (FS.4), analytic, (9, 9)."""
        return np.array(self._rhs(x, t, w, f, True)[1])

    def _rhs(self, x: Sequence[float], t: float, w: Sequence[float], f: Sequence[float], jac: bool
             ) -> tuple[tuple[float, ...], list[list[float]] | None]:
        a, b, g, lam, phi, h, ve, vn, vu = x
        wx, wy, wz = w
        fx, fy, fz = f
        sin, cos = math.sin, math.cos
        sa, ca, sb, cb, sg, cg = sin(a), cos(a), sin(b), cos(b), sin(g), cos(g)
        p = sg * wx + cg * wy
        q = cg * wx - sg * wy
        ta = sa / ca
        da, db, dg = q, p / ca, p * ta + wz
        d00, d01, d02 = sb * sa * sg + cb * cg, ca * sg, cb * sa * sg - sb * cg
        d10, d11, d12 = sb * sa * cg - cb * sg, ca * cg, cb * sa * cg + sb * sg
        d20, d21, d22 = sb * ca, -sa, cb * ca
        fp0 = d00 * fx + d10 * fy + d20 * fz  # D^T f: inertial paper axes
        fp1 = d01 * fx + d11 * fy + d21 * fz
        fp2 = d02 * fx + d12 * fy + d22 * fz
        sp, cp = sin(phi), cos(phi)
        psi = lam + self._omega * t
        ss, cs = sin(psi), cos(psi)
        # B rows: east (cs, 0, -ss), north (-ss sp, cp, -cs sp), up (ss cp, sp, cs cp)
        f_e = cs * fp0 - ss * fp2
        f_n = cp * fp1 - sp * (ss * fp0 + cs * fp2)
        f_u = sp * fp1 + cp * (ss * fp0 + cs * fp2)
        om = self._omega
        rr = self._a + h
        tp = sp / cp
        w0, w1, w2 = -vn / rr, 2.0 * om * cp + ve / rr, 2.0 * om * sp + ve * tp / rr
        om2r = om * om * rr
        gn, gu = -om2r * cp * sp, om2r * cp * cp - self._g0
        cx = w1 * vu - w2 * vn  # W x V
        cy = w2 * ve - w0 * vu
        cz = w0 * vn - w1 * ve
        out = (da, db, dg, ve / (rr * cp), vn / rr, vu, f_e - cx, f_n + gn - cy, f_u + gu - cz)
        if not jac:
            return out, None
        F = [[0.0] * _N for _ in range(_N)]
        # (FS.1)
        F[0][2] = -p
        F[1][0], F[1][2] = p * sa / (ca * ca), q / ca
        F[2][0], F[2][2] = p / (ca * ca), q * ta
        # (FS.2)
        F[3][4] = ve * sp / (rr * cp * cp)
        F[3][5] = -ve / (rr * rr * cp)
        F[3][6] = 1.0 / (rr * cp)
        F[4][5] = -vn / (rr * rr)
        F[4][7] = 1.0 / rr
        F[5][8] = 1.0
        # (FS.3): d(B D^T f)/dtheta_i = B D^T (a_i x f), a_i the angle axes in body axes
        axes = ((cg, -sg, 0.0), (sg * ca, cg * ca, -sa), (0.0, 0.0, 1.0))
        for i, (ax, ay, az) in enumerate(axes):
            c0, c1, c2 = ay * fz - az * fy, az * fx - ax * fz, ax * fy - ay * fx
            q0 = d00 * c0 + d10 * c1 + d20 * c2
            q1 = d01 * c0 + d11 * c1 + d21 * c2
            q2 = d02 * c0 + d12 * c1 + d22 * c2
            F[6][i] = cs * q0 - ss * q2
            F[7][i] = cp * q1 - sp * (ss * q0 + cs * q2)
            F[8][i] = sp * q1 + cp * (ss * q0 + cs * q2)
        # the ENU frame turns with lambda (about the Earth axis [0, cp, sp]) and phi (about
        # -East): components of a fixed vector change by f_n x theta
        # W and W x V partials
        dw_phi = (0.0, -2.0 * om * sp, 2.0 * om * cp + ve / (rr * cp * cp))
        dw_h = (vn / (rr * rr), -ve / (rr * rr), -ve * tp / (rr * rr))
        dw_ve = (0.0, 1.0 / rr, tp / rr)
        dw_vn = (-1.0 / rr, 0.0, 0.0)

        def cross_v(dw: tuple[float, float, float]) -> tuple[float, float, float]:  # dW x V
            return (dw[1] * vu - dw[2] * vn, dw[2] * ve - dw[0] * vu, dw[0] * vn - dw[1] * ve)

        c_phi, c_h, c_ve, c_vn = cross_v(dw_phi), cross_v(dw_h), cross_v(dw_ve), cross_v(dw_vn)
        # W x e_E = (0, w2, -w1), W x e_N = (-w2, 0, w0), W x e_U = (w1, -w0, 0)
        c_ve = (c_ve[0], c_ve[1] + w2, c_ve[2] - w1)
        c_vn = (c_vn[0] - w2, c_vn[1], c_vn[2] + w0)
        c_vu = (w1, -w0, 0.0)
        fl = (f_n * sp - f_u * cp, -f_e * sp, f_e * cp)  # f_n x [0, cp, sp]
        fph = (0.0, -f_u, f_n)  # f_n x [-1, 0, 0]
        g_phi = (0.0, -om2r * (cp * cp - sp * sp), -2.0 * om2r * cp * sp)
        g_h = (0.0, -om * om * cp * sp, om * om * cp * cp)
        for r in range(3):
            row = F[6 + r]
            row[3] = fl[r]
            row[4] = fph[r] + g_phi[r] - c_phi[r]
            row[5] = g_h[r] - c_h[r]
            row[6] = -c_ve[r]
            row[7] = -c_vn[r]
            row[8] = -c_vu[r]
        return out, F

    def _process_noise(self, x: Sequence[float]) -> np.ndarray:
        k = self._kin(x[0], x[2])
        Q = np.zeros((_N, _N))
        Q[0:3, 0:3] = self._qd * (k @ k.T)
        Q[6:9, 6:9] = self._qa * np.eye(3)
        return Q

    # ------------------------------------------------------------------ GNSS (2)-(3), (16)
    def observables(self, x: Sequence[complex], t: float, sat_pos_e: np.ndarray, sat_vel_e: np.ndarray,
                    gyro_rate_b: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Predicted pseudoranges and Dopplers (m,) of 003 (2)-(3) at the state x
        (complex-safe: numpy functions throughout), at the antenna with a lever arm."""
        a, b, g, lam, phi, h, ve, vn, vu = x
        sp, cp, sl, cl = np.sin(phi), np.cos(phi), np.sin(lam), np.cos(lam)
        rr = self._a + h
        pos = np.array([rr * cp * cl, rr * cp * sl, rr * sp])
        e_ax = np.array([-sl, cl, 0.0 * sl])
        n_ax = np.array([-sp * cl, -sp * sl, cp])
        u_ax = np.array([cp * cl, cp * sl, sp])
        vel = ve * e_ax + vn * n_ax + vu * u_ax
        if self._lever:
            ot = self._omega * t
            so, co = math.sin(ot), math.cos(ot)
            c_ep = np.array([[so, 0.0, co], [co, 0.0, -so], [0.0, 1.0, 0.0]])
            dm = np.array(_dmat(a, b, g, np))
            c_eb = c_ep @ dm.T
            lever = self.lever_arm_b
            arm = c_eb @ lever
            turn = c_eb @ np.cross(np.asarray(gyro_rate_b, dtype=float), lever)
            pos = pos + arm
            vel = vel + turn - np.array([-self._omega * arm[1], self._omega * arm[0], 0.0 * arm[2]])
        d = sat_pos_e - pos
        rho = np.sqrt(np.sum(d * d, axis=1))
        rate = np.sum(d * (sat_vel_e - vel), axis=1) / rho
        return rho, rate

    def gnss_observation(self, x: Sequence[float], t: float, sat_pos_e: np.ndarray, sat_vel_e: np.ndarray,
                         gyro_rate_b: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(h_r, h_v, H): observables and their Jacobian (2m, 9) by the complex step."""
        h_r, h_v = self.observables(x, t, sat_pos_e, sat_vel_e, gyro_rate_b)
        m = len(h_r)
        H = np.zeros((2 * m, _N))
        cols = range(_N) if self._lever else range(3, _N)
        for j in cols:
            xc = [complex(v) for v in x]
            xc[j] += 1j * _CSTEP
            cr, cv = self.observables(xc, t, sat_pos_e, sat_vel_e, gyro_rate_b)
            H[:m, j] = cr.imag / _CSTEP
            H[m:, j] = cv.imag / _CSTEP
        return h_r.real, h_v.real, H

    def _update(self, obs: GnssObservation, t: float, gyro_rate_b: np.ndarray | None) -> tuple[float, int] | None:
        valid = np.asarray(obs.valid, dtype=bool)
        if not valid.any():
            return None
        sat_pos = np.asarray(obs.sat_pos_e, dtype=float)[valid]
        sat_vel = np.asarray(obs.sat_vel_e, dtype=float)[valid]
        m = len(sat_pos)
        h_r, h_v, H = self.gnss_observation(self._x, t, sat_pos, sat_vel, gyro_rate_b)
        nu = np.concatenate([np.asarray(obs.pseudorange_m, dtype=float)[valid] - h_r,
                             np.asarray(obs.pseudorange_rate_mps, dtype=float)[valid] - h_v])
        r_diag = np.concatenate([np.full(m, self._r_code), np.full(m, self._r_dopp)])
        P = self._P
        PHt = P @ H.T
        S = H @ PHt + np.diag(r_diag)
        S = 0.5 * (S + S.T)
        Kt = np.linalg.solve(S, PHt.T)
        dx = Kt.T @ nu
        self._x = [xi + float(d) for xi, d in zip(self._x, dx)]
        ikh = np.eye(_N) - Kt.T @ H
        P = ikh @ P @ ikh.T + (Kt.T * r_diag) @ Kt
        self._P = 0.5 * (P + P.T)
        self._cov_left = 0
        return float(nu @ np.linalg.solve(S, nu)), 2 * m

    # ------------------------------------------------------------------ propagation
    def _inputs(self, dtheta_r: ArrayLike, dv_r: ArrayLike) -> np.ndarray:
        """(n, 18): omega and f at s = 0, 1/2, 1 of each step."""
        angle = np.asarray(dtheta_r, dtype=float)
        velocity = np.asarray(dv_r, dtype=float)
        R = self._lvec.shape[1]
        sw = [angle[:, r, :] / self._dt_pow[r] for r in range(R)]
        sf = [velocity[:, r, :] / self._dt_pow[r] for r in range(R)]
        cols = []
        for s in range(3):
            for scaled in (sw, sf):
                acc = self._lvec[s, 0] * scaled[0]
                for r in range(1, R):
                    acc = acc + self._lvec[s, r] * scaled[r]
                cols.append(acc)
        return np.concatenate(cols, axis=1)

    def _propagate(self, row: Sequence[float], t0: float, step: int) -> None:
        dt = self._dt
        x = self._x
        w1, f1, w2, f2, w3, f3 = row[0:3], row[3:6], row[6:9], row[9:12], row[12:15], row[15:18]
        if self._cov_left <= 0:
            k1, F = self._rhs(x, t0, w1, f1, True)
            to_epoch = self._spe - (step % self._spe)
            L = min(self._n_c, to_epoch)
            self._P = _riccati_rk4(self._P, np.array(F), self._process_noise(x), L * dt)
            self._cov_left = L
        else:
            k1 = self._rhs(x, t0, w1, f1, False)[0]
        h2 = 0.5 * dt
        rhs = self._rhs
        k2 = rhs([xi + h2 * ki for xi, ki in zip(x, k1)], t0 + h2, w2, f2, False)[0]
        k3 = rhs([xi + h2 * ki for xi, ki in zip(x, k2)], t0 + h2, w2, f2, False)[0]
        k4 = rhs([xi + dt * ki for xi, ki in zip(x, k3)], t0 + dt, w3, f3, False)[0]
        c = dt / 6.0
        self._x = [xi + c * (a + 2.0 * (b + d) + e) for xi, a, b, d, e in zip(x, k1, k2, k3, k4)]
        self._cov_left -= 1

    def _run(self, t: np.ndarray, inp: np.ndarray, dtheta1: np.ndarray, epochs: dict[int, GnssObservation],
             steps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        n = len(t)
        xs = np.full((n, _N), np.nan)
        ps = np.full((n, _N, _N), np.nan)
        nis = np.full(n, np.nan)
        dof = np.zeros(n, dtype=int)
        rows = inp.tolist()
        times = np.asarray(t, dtype=float).tolist()
        step_list = np.asarray(steps).tolist()
        for i in range(n):
            if self._diverged:
                continue
            try:
                self._propagate(rows[i], times[i] - self._dt, step_list[i])
                obs = epochs.get(i)
                if obs is not None:
                    res = self._update(obs, times[i], dtheta1[i] / self._dt if self._lever else None)
                    if res is not None:
                        nis[i], dof[i] = res
                if not (math.isfinite(sum(self._x)) and np.all(np.isfinite(self._P))):
                    raise FloatingPointError("non-finite state")
                xs[i] = self._x
                ps[i] = self._P
            except (ArithmeticError, ValueError, np.linalg.LinAlgError):
                self._diverged = True
        return xs, ps, nis, dof

    # ------------------------------------------------------------------ outputs
    def outputs(self, X: np.ndarray, P: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Navigation solutions (n, 9) and 9 x 9 covariances from states (n, 9)."""
        X = np.asarray(X, dtype=float)
        t = np.asarray(t, dtype=float)
        a, b, g, lam, phi, h = (X[:, j] for j in range(6))
        dmat = euler_krylov_matrix(a, b, g)
        bmat = euler_krylov_matrix(-phi, lam + self._omega * t, 0.0)
        mat_nb = bmat @ np.swapaxes(dmat, -1, -2)
        heading, pitch, roll = hpr_from_mat_nb(mat_nb)
        sol = np.column_stack([phi, lam, h, X[:, 6:9], heading, pitch, roll])
        n = len(phi)
        rr = self._a + h
        cp, sp = np.cos(phi), np.sin(phi)
        J = np.zeros((n, 9, _N))
        J[:, 0, 3] = rr * cp
        J[:, 1, 4] = rr
        J[:, 2, 5] = 1.0
        J[:, 3:6, 6:9] = np.eye(3)
        sg, cg, sa, ca = np.sin(g), np.cos(g), np.sin(a), np.cos(a)
        zero = np.zeros_like(a)
        axes = np.stack([np.stack([cg, -sg, zero], -1), np.stack([sg * ca, cg * ca, -sa], -1),
                         np.stack([zero, zero, zero + 1.0], -1)], axis=-1)
        J[:, 6:9, 0:3] = mat_nb @ axes
        J[:, 6, 4] = 1.0  # -theta_n
        J[:, 7, 3] = -cp
        J[:, 8, 3] = -sp
        cov = J @ P @ np.swapaxes(J, -1, -2)
        return sol, 0.5 * (cov + np.swapaxes(cov, -1, -2))

    # ------------------------------------------------------------------ interface
    def _require(self) -> None:
        if not self._ready:
            raise RuntimeError("call FullStateEkf.reset(context, prior) first")

    def step(self, measurement: Measurement) -> Estimate:
        """One navigation step: (FS.1)-(FS.3) and the Riccati equation over the step, (16)
        if an epoch ends it."""
        self._require()
        inp = self._inputs(measurement.dtheta_r[None], measurement.dv_r[None])
        epochs = {} if measurement.gnss is None else {0: measurement.gnss}
        t = np.array([measurement.t])
        x, p, nis, dof = self._run(t, inp, np.asarray(measurement.dtheta_r)[None, 0], epochs,
                                   np.array([measurement.step]))
        sol, cov = self.outputs(x, p, t)
        s = sol[0]
        return Estimate(t=float(measurement.t), lat=float(s[0]), lon=float(s[1]), h=float(s[2]),
                        velocity_n=s[3:6].copy(), heading=float(s[6]), pitch=float(s[7]), roll=float(s[8]),
                        covariance=cov[0], nis=None if math.isnan(nis[0]) else float(nis[0]),
                        nis_dof=None if dof[0] == 0 else int(dof[0]),
                        extra={"state": x[0].copy(), "state_cov": p[0].copy(), "diverged": self._diverged})

    def step_batch(self, batch: MeasurementBatch) -> EstimateBatch:
        """Many steps at once; the same numbers as repeated :meth:`step`."""
        self._require()
        inp = self._inputs(batch.dtheta_r, batch.dv_r)
        epochs = {int(j): obs for j, obs in batch.gnss}
        t = np.asarray(batch.t, dtype=float)
        x, p, nis, dof = self._run(t, inp, np.asarray(batch.dtheta_r)[:, 0], epochs, np.asarray(batch.step))
        sol, cov = self.outputs(x, p, t)
        self.last_states, self.last_state_cov = x, p
        return EstimateBatch(solution=sol, covariance=cov, nis=nis, nis_dof=dof)

    @property
    def diverged(self) -> bool:
        return self._diverged


def _riccati_rk4(P: np.ndarray, F: np.ndarray, Q: np.ndarray, tau: float) -> np.ndarray:
    """RK4 of P' = F P + P F^T + Q with F, Q frozen over tau."""
    def rhs(X: np.ndarray) -> np.ndarray:
        FX = F @ X
        return FX + FX.T + Q

    k1 = rhs(P)
    k2 = rhs(P + (0.5 * tau) * k1)
    k3 = rhs(P + (0.5 * tau) * k2)
    k4 = rhs(P + tau * k3)
    out = P + (tau / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
    return 0.5 * (out + out.T)
