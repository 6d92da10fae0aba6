"""The seed-003 estimator :class:`PaperEkf`: set-up, the continuous filter (14), the epoch update (16), outputs.

The model, the equations with their numbers, the corrections of the printed formulas, the
modes, the lever-arm extension and the numerical choices are described in
:mod:`navsim.estimators.paper_ekf`; the options in :mod:`~navsim.estimators.paper_ekf.config`.
:func:`paper_state` maps a navigation solution onto the paper's state (eq. (8)).
"""

from __future__ import annotations

import cmath
import math
import operator
from typing import Iterable

import numpy as np

from ...earth import SPHERICAL, EarthModel
from ...errors import ConfigError
from ...rotations import euler_krylov_from_matrix, euler_krylov_matrix, hpr_from_mat_nb, mat_nb_from_hpr
from ..base import Context, Estimate, EstimateBatch, Measurement, MeasurementBatch, NoiseScalable, Prior, StepRow, row_of
from . import kernel as _kernel
from .config import PaperEkfConfig
from .numerics import CSTEP, check_rows, cross, input_polynomial_matrix, riccati_rk4_h
from .track_functions import TrackFunctions

__all__ = ["PaperEkf", "paper_state"]


def paper_state(lat, lon, velocity_n, heading, pitch, roll, t, earth_rate: float) -> np.ndarray:
    """The paper's state [alpha, beta, gamma, phi, V_Y] of a navigation solution, (n, 5).

    alpha, beta, gamma from ``D = mat_nb^T B(lat, lon + Omega t)`` (body relative to the
    inertial frame, paper axes); phi = lat; V_Y = north velocity. Vectorised (truth or
    estimates; used for the 5-state NEES).
    """
    lat = np.atleast_1d(np.asarray(lat, dtype=float))
    lon = np.atleast_1d(np.asarray(lon, dtype=float))
    t = np.broadcast_to(np.asarray(t, dtype=float), lat.shape)
    velocity_n = np.asarray(velocity_n, dtype=float).reshape(-1, 3)
    mat_nb = mat_nb_from_hpr(heading, pitch, roll).reshape(-1, 3, 3)
    b = euler_krylov_matrix(-lat, lon + earth_rate * t, 0.0)
    d = np.swapaxes(mat_nb, -1, -2) @ b
    alpha, beta, gamma = euler_krylov_from_matrix(d)
    return np.column_stack([alpha, beta, gamma, lat, velocity_n[:, 1]])


class PaperEkf(NoiseScalable):
    """Seed 003's reduced-state track-model filter (14)/(16); see the module docstring.

    Parameters
    ----------
    mode : {"faithful", "extended"}
        faithful: the paper's model (spherical Earth, 5 states, no clock); extended: clock,
        WGS-84 and bias states where the context needs them.
    as_printed : bool or iterable of {"kinematics", "centrifugal"}
        faithful mode only: keep the printed kinematic matrix and/or centrifugal sign.
    cov_step_s : float, optional
        Riccati RK4 step (a divisor of the GNSS period), default the navigation step.
    input_model : {"polynomial", "mean"}, optional
        omega(t), f(t) inside a step from all multiple integrals, or dtheta/dt, dv/dt.
        Default: polynomial in faithful mode, mean in extended mode.
    accel_in_update : bool, optional
        Stack Z_ax into the epoch update (16). Default: faithful yes, extended no.
    bias_states : {"auto", "on", "off"}
        Gauss-Markov accelerometer and gyro bias states (extended mode; "auto": when the
        nominal IMU has bias sigmas).
    node_step_m : float
        Node spacing of the lambda(phi) interpolation of non-polynomial tracks, m.
    stiffness_limit : float
        Largest gain-rate x interval per RK4 step (start-up stiffness, see module).
    lever_arm : {"auto", "none"}
        "auto": compensate the antenna lever arm of ``context.gnss.lever_arm_b_m`` (a navsim
        extension, in both modes, active only when that arm is non-zero; see the module
        docstring); "none": predict the observables at the track point (003's eq. (2)).
    observer : bool
        True (default): the accelerometer observer (13) runs between epochs (14) and Z_ax
        is stacked into (16) as configured; False: the same track-model filter on GNSS
        alone (no (13): zero gain between epochs, ``R' = A R + R A^T + Q``), the ablation
        of the paper's central claim.
    engine : {"auto", "python", "compiled"}
        Propagation engine between GNSS epochs: "python" the reference (plain Python and
        NumPy), "compiled" :mod:`navsim.estimators.paper_ekf.kernel` (numba, optional extra
        ``fast``; the same equations, equal to rounding), "auto" the compiled one when
        numba is installed.

    Notes
    -----
    ``Estimate.extra`` holds ``state`` (the state vector), ``state_cov``, ``diverged``
    and, when present, ``clock_bias_m``, ``clock_drift_mps``, ``accel_bias``,
    ``gyro_bias``. After :meth:`step_batch`, ``last_states`` / ``last_state_cov`` hold
    the batch's state vectors (n, ns) and covariances (n, ns, ns).
    """

    NOISE_PROCESS = ('_qd', '_qa')
    NOISE_MEASUREMENT_VARIANCE = ('_r_code', '_r_dopp')
    # where set_noise_scale finds Q and R after reset (navsim.estimators.base.NoiseScalable)

    def __init__(self, mode: str = "faithful", as_printed: bool | Iterable[str] = False,
                 cov_step_s: float | None = None, input_model: str | None = None,
                 accel_in_update: bool | None = None, bias_states: str = "auto",
                 node_step_m: float = 10.0, stiffness_limit: float = 0.5, lever_arm: str = "auto",
                 observer: bool = True, engine: str = "auto") -> None:
        self.config = PaperEkfConfig(mode, as_printed, cov_step_s, input_model, accel_in_update,
                                     bias_states, node_step_m, stiffness_limit, lever_arm, observer, engine)
        self._ready = False

    # ------------------------------------------------------------------ set-up
    def reset(self, context: Context, prior: Prior) -> None:
        """Start an episode: model constants from the context, state from the prior."""
        cfg = self.config
        self.context = context
        earth: EarthModel = context.earth
        faithful = cfg.mode == "faithful"
        # --- Earth used by the filter
        if faithful or earth.f == 0.0:
            sph = earth if earth.f == 0.0 else SPHERICAL
            self._sphere, self._a, self._e2 = True, float(sph.a), 0.0
            self._omega = float(sph.rate)
        else:
            self._sphere, self._a, self._e2 = False, float(earth.a), float(earth.e2)
            self._omega = float(earth.rate)
        self._filter_earth = EarthModel("filter", self._a, 0.0 if self._sphere else earth.f, self._omega, earth.gm)
        printed = cfg.as_printed
        self._printed_kin = "kinematics" in printed
        # (7): printed +Omega^2 (r+h) cos sin; physics (plumb line) -; WGS-84 normal gravity: 0
        self._cent = (1.0 if "centrifugal" in printed else -1.0) if self._sphere else 0.0
        self.track_functions = TrackFunctions(context.track, cfg.node_step_m)
        # --- noise
        imu, gnss = context.imu, context.gnss
        self._qd = float(imu.gyro_arw) ** 2  # D_d, rad^2/s
        self._qa = float(imu.accel_vrw) ** 2  # D_a, m^2/s^3
        if self._qa <= 0.0:
            self._qa = (1e-6) ** 2  # an ideal accelerometer would make (14) singular
        self._r_code = max(float(gnss.pseudorange_sigma_m), 1e-3) ** 2
        self._r_dopp = max(float(gnss.doppler_sigma_mps), 1e-4) ** 2
        # --- antenna lever arm (navsim extension; zero arm: the paper's track-point model)
        arm = getattr(gnss, "lever_arm_b_m", (0.0, 0.0, 0.0)) if cfg.lever_arm == "auto" else (0.0, 0.0, 0.0)
        self.lever_arm_b = np.array(arm, dtype=float)
        self._lever = bool(np.any(self.lever_arm_b != 0.0))
        # --- extra states
        self._clock = (not faithful) and bool(gnss.clock_modelled)
        if faithful or cfg.bias_states == "off":
            biases = False
        elif cfg.bias_states == "on":
            biases = True
        else:
            biases = imu.accel_bias_sigma > 0.0 or imu.gyro_bias_sigma > 0.0
        self._biases = biases
        self._accel_in_update = faithful if cfg.accel_in_update is None else bool(cfg.accel_in_update)
        self._observer = bool(cfg.observer)
        if not self._observer:  # no (13): Z_ax is not an observation anywhere
            self._accel_in_update = False
        n = 5
        self._i_clk = n if self._clock else None
        n += 2 if self._clock else 0
        self._i_ba = n if biases else None
        n += 3 if biases else 0
        self._i_bg = n if biases else None
        n += 3 if biases else 0
        self.n_states = n
        # --- time base
        dt = float(context.nav_period_s)
        self._dt = dt
        spe = context.gnss_period_s / dt
        self._spe = max(int(round(spe)), 1)
        cov_step = dt if cfg.cov_step_s is None else float(cfg.cov_step_s)
        n_c = cov_step / dt
        if abs(n_c - round(n_c)) > 1e-9 or round(n_c) < 1 or self._spe % int(round(n_c)) != 0:
            raise ConfigError("cov_step_s", f"a whole multiple of the navigation step {dt} s dividing the GNSS "
                              f"period {context.gnss_period_s} s", cfg.cov_step_s)
        self._n_c = int(round(n_c))
        R = int(context.orders)
        input_model = cfg.input_model or ("polynomial" if faithful else "mean")
        if input_model == "mean" or R == 1:
            minv = np.zeros((R, R))
            minv[0, 0] = 1.0
        else:
            minv = input_polynomial_matrix(R)
        self._minv = minv
        s_pts = np.array([0.0, 0.5, 1.0])
        self._lvec = (s_pts[:, None] ** np.arange(R)[None, :]) @ minv  # (3, R)
        self._dt_pow = np.array([dt ** (r + 1) for r in range(R)])
        # --- stage functions
        scalars = self.track_functions.scalar_function()
        self._stage = self._make_stage(math.sin, math.cos, math.sqrt, scalars)
        self._stage_c = self._make_stage(cmath.sin, cmath.cos, cmath.sqrt, scalars)
        self._fused = self._make_fused()
        self._riccati_layout()
        self._kpack: tuple | None = None  # the compiled engine's packed buffers (kernel.pack), made by _kernel_args
        self._kargs = self._kernel_args() if cfg.engine != "python" and _kernel.available() else None
        self._kstate = None  # the compiled engine's state arrays while they hold the state
        self._kstep_one = None  # kernel.step_packed's compiled dispatcher, fetched on first use
        # --- initial state
        y0, p0 = self._state_from_prior(prior)
        self._Y = y0
        self._P = p0
        self._P_rows = p0.tolist()
        self._K = None
        self._cov_left = 0
        self._P_start = p0.copy()
        self._cov_len = 1
        self._cov_pos = 0
        self._diverged = False
        self._t_prev = float(prior.t)
        self.substeps = 0
        self._ready = True

    def _state_from_prior(self, prior) -> tuple[list, np.ndarray]:
        tf = self.track_functions
        p9 = np.asarray(prior.covariance, dtype=float)
        phi = float(prior.lat)
        w_pos = np.linalg.inv(p9[:3, :3])
        g_phi = np.zeros(3)
        for _ in range(4):  # Gauss-Newton projection of the prior position on the track
            lam, dlam, _, hh, dh = tf.scalars(phi)
            rn, re = self._radii(phi, hh, dh)[:2]
            cp = math.cos(phi)
            resid = np.array([(prior.lon - lam) * re * cp, (prior.lat - phi) * rn, prior.h - hh])
            jac = np.array([re * cp * dlam, rn, dh])
            info = jac @ w_pos @ jac
            g_phi = (w_pos @ jac) / info
            phi += float(g_phi @ resid)
        lam, dlam, _, hh, dh = tf.scalars(phi)
        rn, re, k, _, m = self._radii(phi, hh, dh, dlam)
        tv = np.array([k, 1.0, m])
        w_vel = np.linalg.inv(p9[3:6, 3:6])
        g_v = (w_vel @ tv) / (tv @ w_vel @ tv)
        v = float(g_v @ np.asarray(prior.velocity_n, dtype=float))
        mat_nb = mat_nb_from_hpr(prior.heading, prior.pitch, prior.roll)
        bmat = euler_krylov_matrix(-phi, lam + self._omega * prior.t, 0.0)
        alpha, beta, gamma = (float(x) for x in euler_krylov_from_matrix(mat_nb.T @ bmat))
        # psi (ENU small angles) -> body rotation mat_bn psi -> angle increments Phi(alpha, gamma)
        j_att = self._kin_matrix(alpha, beta, gamma, printed=False) @ mat_nb.T
        g = np.zeros((5, 9))
        g[0:3, 6:9] = j_att
        g[3, 0:3] = g_phi
        g[4, 3:6] = g_v
        p5 = g @ p9 @ g.T
        n = self.n_states
        p = np.zeros((n, n))
        p[:5, :5] = 0.5 * (p5 + p5.T)
        y = [alpha, beta, gamma, phi, v] + [0.0] * (n - 5)
        ctx = self.context
        if self._clock:
            i = self._i_clk
            p[i, i] = max(ctx.gnss.clock_bias_sigma_m, 1.0) ** 2
            p[i + 1, i + 1] = max(ctx.gnss.clock_drift_sigma_mps, 0.01) ** 2
        if self._biases:
            for i in range(3):
                p[self._i_ba + i, self._i_ba + i] = max(ctx.imu.accel_bias_sigma, 1e-6) ** 2
                p[self._i_bg + i, self._i_bg + i] = max(ctx.imu.gyro_bias_sigma, 1e-9) ** 2
        return y, p

    def _radii(self, phi, hh, dh, dlam=0.0):
        """(rho_N, rho_E, k, k unused, m) at phi: rho = R + h, k = V_E / V_N, m = V_U / V_N."""
        if self._sphere:
            rn = re = self._a + hh
        else:
            s = math.sin(phi)
            w = 1.0 - self._e2 * s * s
            r_e = self._a / math.sqrt(w)
            rn, re = r_e * (1.0 - self._e2) / w + hh, r_e + hh
        k = dlam * math.cos(phi) * re / rn
        return rn, re, k, None, dh / rn

    def _kin_matrix(self, a, b, g, printed: bool | None = None) -> np.ndarray:
        """The kinematic matrix of the model: corrected Phi(alpha, gamma) or printed Phi(beta, gamma)."""
        sg, cg = math.sin(g), math.cos(g)
        if self._printed_kin if printed is None else printed:  # (1) as printed
            cb, tb = math.cos(b), math.tan(b)
            return np.array([[sg / cb, cg / cb, 0.0], [cg, -sg, 0.0], [sg * tb, cg * tb, 1.0]])
        ca, ta = math.cos(a), math.tan(a)
        return np.array([[cg, -sg, 0.0], [sg / ca, cg / ca, 0.0], [sg * ta, cg * ta, 1.0]])

    # ------------------------------------------------------------------ the model
    def _make_stage(self, sin, cos, sqrt, track_scalars):
        """The right-hand side of (14) without the gain: F(Y) and the innovation (Z_ax - H_a).

        Returns ``stage(a, b, g, phi, V, t, wx, wy, wz, fx, fy, fz) -> (alpha', beta',
        gamma', phi', V_Y', innov)`` with ``innov = (u_b . f - G) / u_b,x`` = Z_ax - H_a.
        Complex-safe when built with cmath functions (complex step in phi).
        """
        om = self._omega
        two_om = 2.0 * om
        om2 = om * om
        sphere = self._sphere
        a_e, e2 = self._a, self._e2
        cent = self._cent
        printed_kin = self._printed_kin

        def stage(a, b, g, phi, V, t, wx, wy, wz, fx, fy, fz):
            sa = sin(a)
            ca = cos(a)
            sb = sin(b)
            cb = cos(b)
            sg = sin(g)
            cg = cos(g)
            p = sg * wx + cg * wy
            q = cg * wx - sg * wy
            if printed_kin:  # (1) printed Phi(beta, gamma)
                da, db, dg = p / cb, q, p * sb / cb + wz
            else:  # Phi(alpha, gamma), the kinematics of D (Appendix 1)
                da, db, dg = q, p / ca, p * sa / ca + wz
            # D of Appendix 1
            d00 = sb * sa * sg + cb * cg
            d01 = ca * sg
            d02 = cb * sa * sg - sb * cg
            d10 = sb * sa * cg - cb * sg
            d11 = ca * cg
            d12 = cb * sa * cg + sb * sg
            # f in the inertial (paper) axes: D^T f_b
            fp0 = d00 * fx + d10 * fy + sb * ca * fz
            fp1 = d01 * fx + d11 * fy - sa * fz
            fp2 = d02 * fx + d12 * fy + cb * ca * fz
            lam, dlam, ddlam, hh, dh = track_scalars(phi)
            sp = sin(phi)
            cp = cos(phi)
            psi = lam + om * t
            ss = sin(psi)
            cs = cos(psi)
            if sphere:
                rn = re = a_e + hh
                k = dlam * cp  # V_X = lambda' cos(phi) V_Y
                kphi = ddlam * cp - dlam * sp
                gn = cent * om2 * rn * cp * sp
            else:
                w = 1.0 - e2 * sp * sp
                r_e = a_e / sqrt(w)
                r_n = r_e * (1.0 - e2) / w
                rn = r_n + hh
                re = r_e + hh
                dre = r_e * e2 * sp * cp / w + dh
                drn = 3.0 * r_n * e2 * sp * cp / w + dh
                ratio = re / rn
                k = dlam * cp * ratio
                kphi = (ddlam * cp - dlam * sp) * ratio + dlam * cp * (dre - ratio * drn) / rn
                gn = 0.0
            m = dh / rn
            kv = k * V
            cor = two_om * sp + kv * sp / (cp * re)  # 2 Omega sin(phi) + V_X tan(phi) / (r + h)
            # (7): V_Y' = f_N + acc_n
            acc_n = -cor * kv - m * V * V / rn + gn
            # (12): V_X' = f_E + acc_e
            acc_e = cor * V - (two_om * cp + kv / re) * m * V
            # (10)-(12): f_E - k f_N = G
            gterm = k * acc_n + kphi * V * V / rn - acc_e
            f_n = cp * fp1 - sp * (ss * fp0 + cs * fp2)
            f_e = cs * fp0 - ss * fp2
            # u = e - k n in paper axes; u_b,x = (D u)_x = c11 - k c12
            w0 = d00 * (cs + k * sp * ss) - d01 * k * cp + d02 * (k * sp * cs - ss)
            return da, db, dg, V / rn, f_n + acc_n, (f_e - k * f_n - gterm) / w0  # (13): Z_ax - H_a

        return stage

    def _coefficients(self, Y, w, f, t):
        """Riccati coefficients at (Y, inputs): A = dF/dY, dinnov/dY = -dH_a/dY, Q, S, sigma^2.

        Returns (A (n, n), hneg (n,), Q (n, n), s (n,), sig2, first) with ``hneg`` =
        d(Z_ax - H_a)/dY and ``first`` the stage values (F, innovation) at (Y, inputs, t),
        which is also the first RK4 stage of the step.
        """
        n = self.n_states
        a, b, g, phi, V = Y[0], Y[1], Y[2], Y[3], Y[4]
        wx, wy, wz = w
        fx, fy, fz = f
        if self._biases:
            ia, ig = self._i_ba, self._i_bg
            fx, fy, fz = fx - Y[ia], fy - Y[ia + 1], fz - Y[ia + 2]
            wx, wy, wz = wx - Y[ig], wy - Y[ig + 1], wz - Y[ig + 2]
        sa, ca, sb, cb, sg, cg = math.sin(a), math.cos(a), math.sin(b), math.cos(b), math.sin(g), math.cos(g)
        dmat = ((sb * sa * sg + cb * cg, ca * sg, cb * sa * sg - sb * cg),
                (sb * sa * cg - cb * sg, ca * cg, cb * sa * cg + sb * sg),
                (sb * ca, -sa, cb * ca))
        lam, dlam, ddlam, hh, dh = self.track_functions.scalars(phi)
        psi = lam + self._omega * t
        sp, cp, ss, cs = math.sin(phi), math.cos(phi), math.sin(psi), math.cos(psi)
        rn, re, k, _, m = self._radii(phi, hh, dh, dlam)
        n_p = (-ss * sp, cp, -cs * sp)  # north row of B in paper axes
        u_p = (cs - k * n_p[0], -k * cp, -ss - k * n_p[2])  # e - k n
        d0, d1, d2 = dmat
        n_b = (d0[0] * n_p[0] + d0[1] * n_p[1] + d0[2] * n_p[2], d1[0] * n_p[0] + d1[1] * n_p[1] + d1[2] * n_p[2],
               d2[0] * n_p[0] + d2[1] * n_p[1] + d2[2] * n_p[2])
        u_b = (d0[0] * u_p[0] + d0[1] * u_p[1] + d0[2] * u_p[2], d1[0] * u_p[0] + d1[1] * u_p[1] + d1[2] * u_p[2],
               d2[0] * u_p[0] + d2[1] * u_p[1] + d2[2] * u_p[2])
        real = self._stage(a, b, g, phi, V, t, wx, wy, wz, fx, fy, fz)
        cplx = self._stage_c(a, b, g, complex(phi, CSTEP), V, t, wx, wy, wz, fx, fy, fz)
        d_phi = [z.imag / CSTEP for z in cplx]
        innov = real[5]
        w0 = u_b[0]
        y = innov * w0
        zero = [0.0] * n
        A = [list(zero) for _ in range(n)]
        hneg = list(zero)
        # --- kinematics rows (angles relative to inertial space: no phi, V dependence)
        p = sg * wx + cg * wy
        q = cg * wx - sg * wy
        if self._printed_kin:
            tb = sb / cb
            A[0][1], A[0][2] = p * sb / (cb * cb), q / cb
            A[1][2] = -p
            A[2][1], A[2][2] = p / (cb * cb), q * tb
        else:
            ta = sa / ca
            A[0][2] = -p
            A[1][0], A[1][2] = p * sa / (ca * ca), q / ca
            A[2][0], A[2][2] = p / (ca * ca), q * ta
        # --- angle derivatives: dD/dtheta_i = -[a_i x] D
        axes = ((cg, -sg, 0.0), (sg * ca, cg * ca, -sa), (0.0, 0.0, 1.0))
        zf = (fx, fy, fz)
        z_x_n = cross(zf, n_b)
        z_x_u = cross(zf, u_b)
        row4 = A[4]
        for i, ax in enumerate(axes):
            row4[i] = ax[0] * z_x_n[0] + ax[1] * z_x_n[1] + ax[2] * z_x_n[2]  # d f_N / d theta_i
            dy = ax[0] * z_x_u[0] + ax[1] * z_x_u[1] + ax[2] * z_x_u[2]
            dw0 = -(ax[1] * u_b[2] - ax[2] * u_b[1])
            hneg[i] = (dy * w0 - y * dw0) / (w0 * w0)
        # --- phi (complex step) and V_Y (analytic)
        A[3][3] = d_phi[3]
        A[3][4] = 1.0 / rn
        row4[3] = d_phi[4]
        kv = k * V
        two_om = 2.0 * self._omega
        if self._sphere:
            kphi = ddlam * cp - dlam * sp
        else:
            kphi = float(self._kphi_c(phi))
        acc_n_v = -(two_om * sp + 2.0 * kv * sp / (cp * re)) * k - 2.0 * m * V / rn
        acc_e_v = (two_om * sp + 2.0 * kv * sp / (cp * re)) - (two_om * cp + 2.0 * kv / re) * m
        g_v = k * acc_n_v + 2.0 * kphi * V / rn - acc_e_v
        row4[4] = acc_n_v
        hneg[3] = d_phi[5]
        hneg[4] = -g_v / w0
        # --- process noise F1 D_xi F1^T and correlation F1 D_A H_w^T
        Q = [list(zero) for _ in range(n)]
        if self._printed_kin:
            tb = sb / cb
            kin = ((sg / cb, cg / cb, 0.0), (cg, -sg, 0.0), (sg * tb, cg * tb, 1.0))
        else:
            ta = sa / ca
            kin = ((cg, -sg, 0.0), (sg / ca, cg / ca, 0.0), (sg * ta, cg * ta, 1.0))
        qd = self._qd
        for i in range(3):
            for j in range(3):
                Q[i][j] = qd * (kin[i][0] * kin[j][0] + kin[i][1] * kin[j][1] + kin[i][2] * kin[j][2])
        Q[4][4] = self._qa  # |C_(2)| = 1
        s = list(zero)
        s[4] = self._qa * k / w0  # -C_(2) D_a H_w^T, with n . u = -k
        sig2 = self._qa * (1.0 + k * k) / (w0 * w0)  # H_w D_a H_w^T, |u| = sqrt(1 + k^2)
        # --- extra states
        if self._clock:
            i = self._i_clk
            A[i][i + 1] = 1.0
            Q[i][i] = self.context.gnss.clock_phase_psd
            Q[i + 1][i + 1] = self.context.gnss.clock_freq_psd
        if self._biases:
            imu = self.context.imu
            ia, ig = self._i_ba, self._i_bg
            for j in range(3):
                for i in range(3):
                    A[i][ig + j] = -kin[i][j]
                row4[ia + j] = -n_b[j]
                hneg[ia + j] = -u_b[j] / w0
                A[ia + j][ia + j] = -1.0 / imu.accel_bias_tau_s
                A[ig + j][ig + j] = -1.0 / imu.gyro_bias_tau_s
                Q[ia + j][ia + j] = 2.0 * imu.accel_bias_sigma ** 2 / imu.accel_bias_tau_s + imu.accel_rrw ** 2
                Q[ig + j][ig + j] = 2.0 * imu.gyro_bias_sigma ** 2 / imu.gyro_bias_tau_s + imu.gyro_rrw ** 2
        return np.array(A), np.array(hneg), np.array(Q), np.array(s), sig2, real

    def _make_fused(self):
        """The fast form of :meth:`_coefficients` (same quantities, one scalar pass).

        Returns ``fused(Y, w, f, t) -> (first, a_dyn, hneg, q_dyn, s4, sig2)``: ``first``
        the stage values of :meth:`_make_stage` (the same expressions, so the same numbers),
        ``a_dyn`` the state-dependent entries of A = dF/dY in the order of ``self._a_pos``,
        ``hneg`` = d(Z_ax - H_a)/dY (n,), ``q_dyn`` the kinematic 3 x 3 block of Q (upper
        triangle, row by row) and Q_VV, ``s4`` the V_Y entry of the correlation F1 D_A H_w^T
        (its only non-zero entry), ``sig2`` = H_w D_a H_w^T. The stage values and their
        angle and V_Y derivatives share the trigonometry; on the sphere the phi-derivatives
        are analytic (chain rule through lambda(phi), h(phi), the radii and psi = lambda +
        Omega t) instead of a second, complex-step evaluation of the stage; on the ellipsoid
        the complex step is kept. :meth:`_coefficients` stays the reference (tests).
        """
        om = self._omega
        two_om = 2.0 * om
        om2 = om * om
        sphere = self._sphere
        a_e, e2 = self._a, self._e2
        cent = self._cent
        printed_kin = self._printed_kin
        n = self.n_states
        scal3 = self.track_functions.scalars3
        scal = self.track_functions.scalars
        stage_c = self._stage_c
        kphi_c = self._kphi_c
        sin, cos, sqrt = math.sin, math.cos, math.sqrt
        biases = self._biases
        ia, ig = self._i_ba, self._i_bg
        zeros = [0.0] * n
        obj = self

        def fused(Y, w, f, t):
            a, b, g, phi, V = Y[0], Y[1], Y[2], Y[3], Y[4]
            wx, wy, wz = w
            fx, fy, fz = f
            if biases:
                fx, fy, fz = fx - Y[ia], fy - Y[ia + 1], fz - Y[ia + 2]
                wx, wy, wz = wx - Y[ig], wy - Y[ig + 1], wz - Y[ig + 2]
            # ---- the stage (expressions as in _make_stage)
            sa = sin(a)
            ca = cos(a)
            sb = sin(b)
            cb = cos(b)
            sg = sin(g)
            cg = cos(g)
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
                lam, dlam, ddlam, dddlam, hh, dh, ddh = scal3(phi)
            else:
                lam, dlam, ddlam, hh, dh = scal(phi)
            sp = sin(phi)
            cp = cos(phi)
            psi = lam + om * t
            ss = sin(psi)
            cs = cos(psi)
            if sphere:
                rn = re = a_e + hh
                k = dlam * cp
                kphi = ddlam * cp - dlam * sp
                gn = cent * om2 * rn * cp * sp
            else:
                w_ = 1.0 - e2 * sp * sp
                r_e = a_e / sqrt(w_)
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
            first = (da, db, dg, V / rn, f_n + acc_n, innov)
            # ---- Jacobian (as in _coefficients)
            n_p0, n_p2 = -ss * sp, -cs * sp
            u_p0, u_p1, u_p2 = cs - k * n_p0, -k * cp, -ss - k * n_p2
            n_b0 = d00 * n_p0 + d01 * cp + d02 * n_p2
            n_b1 = d10 * n_p0 + d11 * cp + d12 * n_p2
            n_b2 = d20 * n_p0 - sa * cp + d22 * n_p2
            w0 = d00 * u_p0 + d01 * u_p1 + d02 * u_p2
            u_b1 = d10 * u_p0 + d11 * u_p1 + d12 * u_p2
            u_b2 = d20 * u_p0 - sa * u_p1 + d22 * u_p2
            y = innov * w0
            hneg = list(zeros)
            # f x n_b and f x u_b
            zn0, zn1, zn2 = fy * n_b2 - fz * n_b1, fz * n_b0 - fx * n_b2, fx * n_b1 - fy * n_b0
            zu0, zu1, zu2 = fy * u_b2 - fz * u_b1, fz * w0 - fx * u_b2, fx * u_b1 - fy * w0
            ww = w0 * w0
            # axes (cg, -sg, 0), (sg ca, cg ca, -sa), (0, 0, 1); dw0 = -(ax1 u_b2 - ax2 u_b1)
            a40 = cg * zn0 - sg * zn1
            hneg[0] = ((cg * zu0 - sg * zu1) * w0 - y * (sg * u_b2)) / ww
            sgca, cgca = sg * ca, cg * ca
            a41 = sgca * zn0 + cgca * zn1 - sa * zn2
            hneg[1] = ((sgca * zu0 + cgca * zu1 - sa * zu2) * w0 - y * (-(cgca * u_b2 + sa * u_b1))) / ww
            a42 = zn2
            hneg[2] = (zu2 * w0 - y * u_b1) / ww
            # kinematics rows
            if printed_kin:
                tb = sb / cb
                kin_a = (p * sb / (cb * cb), q / cb, -p, p / (cb * cb), q * tb)
                kin = ((sg / cb, cg / cb, 0.0), (cg, -sg, 0.0), (sg * tb, cg * tb, 1.0))
            else:
                ta = sa / ca
                kin_a = (-p, p * sa / (ca * ca), q / ca, p / (ca * ca), q * ta)
                kin = ((cg, -sg, 0.0), (sg / ca, cg / ca, 0.0), (sg * ta, cg * ta, 1.0))
            # ---- phi derivatives
            if sphere:
                rn2 = rn * rn
                a33 = -V * dh / rn2
                kphi_p = dddlam * cp - 2.0 * ddlam * sp - dlam * cp
                gn_p = cent * om2 * (dh * cp * sp + rn * (cp * cp - sp * sp))
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
                cplx = stage_c(a, b, g, complex(phi, CSTEP), V, t, wx, wy, wz, fx, fy, fz)
                a33 = cplx[3].imag / CSTEP
                a43 = cplx[4].imag / CSTEP
                hneg[3] = cplx[5].imag / CSTEP
                kphi = float(kphi_c(phi))
            # ---- V_Y derivatives
            cor2 = two_om * sp + 2.0 * kv * sp / (cp * re)
            acc_n_v = -cor2 * k - 2.0 * m * V / rn
            acc_e_v = cor2 - (two_om * cp + 2.0 * kv / re) * m
            hneg[4] = -(k * acc_n_v + 2.0 * kphi * V / rn - acc_e_v) / w0
            a_dyn = [*kin_a, a33, 1.0 / rn, a40, a41, a42, a43, acc_n_v]
            # ---- process noise, correlation, measurement intensity
            qd, qa = obj._qd, obj._qa
            k0, k1, k2 = kin
            q_dyn = [qd * (k0[0] * k0[0] + k0[1] * k0[1] + k0[2] * k0[2]),
                     qd * (k0[0] * k1[0] + k0[1] * k1[1] + k0[2] * k1[2]),
                     qd * (k0[0] * k2[0] + k0[1] * k2[1] + k0[2] * k2[2]),
                     qd * (k1[0] * k1[0] + k1[1] * k1[1] + k1[2] * k1[2]),
                     qd * (k1[0] * k2[0] + k1[1] * k2[1] + k1[2] * k2[2]),
                     qd * (k2[0] * k2[0] + k2[1] * k2[1] + k2[2] * k2[2]), qa]
            s4 = qa * k / w0
            sig2 = qa * (1.0 + k * k) / ww
            if biases:
                for j in range(3):
                    a_dyn.extend((-k0[j], -k1[j], -k2[j]))
                a_dyn.extend((-n_b0, -n_b1, -n_b2))
                hneg[ia] = -w0 / w0
                hneg[ia + 1] = -u_b1 / w0
                hneg[ia + 2] = -u_b2 / w0
            return first, a_dyn, hneg, q_dyn, s4, sig2

        return fused

    def _riccati_layout(self) -> None:
        """Index maps of the Hamiltonian-like matrix H of :func:`riccati_rk4_h` (set-up).

        ``H = [[-g g^T, Abar^T], [Abar, Qbar]]`` (2n x 2n) with ``g = h / sigma``, ``Abar = A -
        s h^T / sigma^2``, ``Qbar = Q - s s^T / sigma^2``: then ``[R; I]^T H [R; I]`` is the
        right-hand side ``A R + R A^T + Q - (R h + s)(R h + s)^T / sigma^2`` of (14)'s Riccati
        equation (s has only its V_Y entry). Constant entries (clock, bias time constants and
        PSDs) are written once; the state-dependent ones are written per coefficient update
        through one flat index array.
        """
        n = self.n_states
        kin_pos = ([(0, 1), (0, 2), (1, 2), (2, 1), (2, 2)] if self._printed_kin
                   else [(0, 2), (1, 0), (1, 2), (2, 0), (2, 2)])
        a_pos = kin_pos + [(3, 3), (3, 4), (4, 0), (4, 1), (4, 2), (4, 3), (4, 4)]
        h_sup = [0, 1, 2, 3, 4]
        H = np.zeros((2 * n, 2 * n))
        if self._biases:
            ia, ig = self._i_ba, self._i_bg
            for j in range(3):
                a_pos += [(0, ig + j), (1, ig + j), (2, ig + j)]
            a_pos += [(4, ia), (4, ia + 1), (4, ia + 2)]
            h_sup += [ia, ia + 1, ia + 2]
            imu = self.context.imu
            for j in range(3):
                for i, tau_s in ((ia + j, imu.accel_bias_tau_s), (ig + j, imu.gyro_bias_tau_s)):
                    H[n + i, i] = H[i, n + i] = -1.0 / tau_s
                H[n + ia + j, n + ia + j] = 2.0 * imu.accel_bias_sigma ** 2 / imu.accel_bias_tau_s + imu.accel_rrw ** 2
                H[n + ig + j, n + ig + j] = 2.0 * imu.gyro_bias_sigma ** 2 / imu.gyro_bias_tau_s + imu.gyro_rrw ** 2
        if self._clock:
            i = self._i_clk
            H[n + i, i + 1] = H[i + 1, n + i] = 1.0
            H[n + i, n + i] = self.context.gnss.clock_phase_psd
            H[n + i + 1, n + i + 1] = self.context.gnss.clock_freq_psd
        self._a_pos = a_pos
        self._h_sup = h_sup
        self._h_all = h_sup == list(range(n))
        # row-4 entries of A that become Abar (index in a_dyn, column)
        self._bar_fix = [(idx, j) for idx, (i, j) in enumerate(a_pos) if i == 4]
        flat = []
        flat += [i * 2 * n + j for i in h_sup for j in h_sup]  # -g g^T
        flat += [(n + i) * 2 * n + j for i, j in a_pos]  # Abar
        flat += [j * 2 * n + n + i for i, j in a_pos]  # Abar^T
        q_pos = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
        flat += [(n + i) * 2 * n + n + j for i, j in q_pos] + [(n + j) * 2 * n + n + i for i, j in q_pos if i != j]
        flat += [(n + 4) * 2 * n + n + 4]
        self._h_flat_idx = np.array(flat)
        self._H = H
        self._Z = np.zeros((2 * n, n))
        self._Z[n:] = np.eye(n)
        m = np.zeros((4, n, n))
        self._work = (self._Z, self._Z[:n], self._Z.T, np.zeros((2 * n, n)), m[0], m[1], m[2], m[3])

    def _h_matrix(self, a_dyn, hneg, q_dyn, s4, sig2) -> np.ndarray:
        """Fill H (see :meth:`_riccati_layout`) from the coefficients; returns the shared array.
        ``a_dyn`` is modified (it becomes Abar)."""
        inv = 1.0 / sig2
        hs = hneg if self._h_all else [hneg[j] for j in self._h_sup]
        nh = [-x * inv for x in hs]
        si = s4 * inv
        for idx, j in self._bar_fix:
            a_dyn[idx] += si * hneg[j]
        q0, q1, q2, q3, q4, q5, qvv = q_dyn
        self._H.put(self._h_flat_idx, [x * y for x in nh for y in hs] + a_dyn + a_dyn
                    + [q0, q1, q2, q3, q4, q5, q1, q2, q4, qvv - s4 * si])
        return self._H

    def _gain(self, hneg, s4, sig2):
        """K = (R h + s) / sigma^2 (14) from the cached rows of R, and the rate |dH_a/dY K|."""
        inv = 1.0 / sig2
        mul = operator.mul
        dots = [sum(map(mul, r, hneg)) for r in self._P_rows]
        dots[4] -= s4
        K = [-d * inv for d in dots]
        return K, abs(sum(map(mul, hneg, K)))

    def _riccati(self, P, H, tau):
        """RK4 of (14)'s Riccati equation with H frozen (:func:`riccati_rk4_h`), checked."""
        P = riccati_rk4_h(P, H, tau, self._work)
        rows = P.tolist()
        check_rows(rows)
        return P, rows

    def _kphi_c(self, phi):
        """d k / d phi on the ellipsoid, by the same formula as in the stage function."""
        lam, dlam, ddlam, hh, dh = self.track_functions.scalars(phi)
        sp, cp = math.sin(phi), math.cos(phi)
        e2 = self._e2
        w = 1.0 - e2 * sp * sp
        r_e = self._a / math.sqrt(w)
        r_n = r_e * (1.0 - e2) / w
        rn, re = r_n + hh, r_e + hh
        dre = r_e * e2 * sp * cp / w + dh
        drn = 3.0 * r_n * e2 * sp * cp / w + dh
        ratio = re / rn
        return (ddlam * cp - dlam * sp) * ratio + dlam * cp * (dre - ratio * drn) / rn

    # ------------------------------------------------------------------ GNSS (9)
    def antenna_offset(self, alpha: float, beta: float, gamma: float, t: float, omega_ib_b):
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

    def gnss_model(self, phi, V, sat_pos_e, sat_vel_e, arm_e=None, arm_velocity_e=None):
        """Predicted pseudoranges H_R(phi) and Dopplers H_V(phi, V_Y) without clock, (m,) each.

        Complex-safe in phi (used for the complex-step Jacobian). Returns (h_r, h_v,
        t_e) with t_e the ECEF velocity per unit V_Y. ``arm_e``, ``arm_velocity_e`` (3,):
        the antenna's offset from the track point and its velocity (:meth:`antenna_offset`);
        the observables are then the antenna's (LA.1)-(LA.2) - a navsim extension, 003's
        (2)-(3) measure at the track point (None, the default).
        """
        lam, dlam, _, hh, dh = self.track_functions.scalars(phi)
        sin, cos = (cmath.sin, cmath.cos) if isinstance(phi, complex) else (math.sin, math.cos)
        sp, cp, sl, cl = sin(phi), cos(phi), sin(lam), cos(lam)
        if self._sphere:
            rn = re = self._a + hh
            rz = re
        else:
            sqrt = cmath.sqrt if isinstance(phi, complex) else math.sqrt
            w = 1.0 - self._e2 * sp * sp
            r_e = self._a / sqrt(w)
            rn, re = r_e * (1.0 - self._e2) / w + hh, r_e + hh
            rz = r_e * (1.0 - self._e2) + hh
        pos = np.array([re * cp * cl, re * cp * sl, rz * sp])  # (4) in ECEF axes
        k = dlam * cp * re / rn
        m = dh / rn
        # (5): V_G = B^T V_S, V_S = [k, 1, m] V_Y; B^T columns are e, n, u in ECEF
        t_e = np.array([-sl * k + (-sp * cl) + cp * cl * m, cl * k + (-sp * sl) + cp * sl * m, cp + sp * m])
        if arm_e is not None:  # (LA.1)-(LA.2)
            d = sat_pos_e - (pos + arm_e)
            rho = np.sqrt(np.sum(d * d, axis=1))
            h_v = np.sum(d * (sat_vel_e - V * t_e - arm_velocity_e), axis=1) / rho
            return rho, h_v, t_e
        d = sat_pos_e - pos
        rho = np.sqrt(np.sum(d * d, axis=1))
        h_v = np.sum(d * (sat_vel_e - V * t_e), axis=1) / rho  # (3)
        return rho, h_v, t_e

    # ------------------------------------------------------------------ inputs
    def _prepare(self, dtheta_r: np.ndarray, dv_r: np.ndarray):
        """Stage inputs (n, 21): omega and f at s = 0, 1/2, 1 and the step-mean f."""
        dtheta_r = np.asarray(dtheta_r, dtype=float)
        dv_r = np.asarray(dv_r, dtype=float)
        R = self._minv.shape[0]
        cols = []
        scaled_w = [dtheta_r[:, r, :] / self._dt_pow[r] for r in range(R)]
        scaled_f = [dv_r[:, r, :] / self._dt_pow[r] for r in range(R)]
        for s in range(3):
            for scaled in (scaled_w, scaled_f):
                acc = self._lvec[s, 0] * scaled[0]
                for r in range(1, R):
                    acc = acc + self._lvec[s, r] * scaled[r]
                cols.append(acc)
        cols.append(scaled_f[0])
        # order: w0 f0 w1 f1 w2 f2 fmean -> (n, 21)
        return np.concatenate(cols, axis=1)

    def _coef(self, dtheta_r, dv_r):
        """Polynomial coefficients (R, 3) of omega(s) and f(s) of one step (sub-steps)."""
        R = self._minv.shape[0]
        sw = np.array([dtheta_r[r] / self._dt_pow[r] for r in range(R)])
        sf = np.array([dv_r[r] / self._dt_pow[r] for r in range(R)])
        return self._minv @ sw, self._minv @ sf

    # ------------------------------------------------------------------ core loop
    @property
    def engine(self) -> str:
        """The propagation engine in use after :meth:`reset`: "compiled" or "python"."""
        return "compiled" if getattr(self, "_kargs", None) is not None else "python"

    def _propagate(self, t_end, inp, dtheta_r, dv_r, epochs: dict, steps):
        if self._kargs is None:
            return self._run(t_end, inp, dtheta_r, dv_r, epochs, steps)
        return self._run_compiled(t_end, inp, dtheta_r, dv_r, epochs, steps)

    def _kernel_args(self) -> tuple:
        """Constants of :func:`navsim.estimators.paper_ekf.kernel.advance_py` (set-up)."""
        k = _kernel
        imu = self.context.imu
        c = np.zeros(10)
        c[k.C_OM], c[k.C_A], c[k.C_E2], c[k.C_CENT] = self._omega, self._a, self._e2, self._cent
        c[k.C_QD], c[k.C_QA], c[k.C_DT], c[k.C_LIMIT] = self._qd, self._qa, self._dt, self.config.stiffness_limit
        if self._biases:
            c[k.C_TAU_A], c[k.C_TAU_G] = imu.accel_bias_tau_s, imu.gyro_bias_tau_s
        tf = self.track_functions
        ic = np.zeros(13, dtype=np.int64)
        ic[k.I_OBSERVER] = self._observer
        ic[k.I_SPHERE], ic[k.I_PRINTED], ic[k.I_BIASES], ic[k.I_CLOCK] = (
            self._sphere, self._printed_kin, self._biases, self._clock)
        ic[k.I_IA] = -1 if self._i_ba is None else self._i_ba
        ic[k.I_IG] = -1 if self._i_bg is None else self._i_bg
        ic[k.I_ICLK] = -1 if self._i_clk is None else self._i_clk
        ic[k.I_SPE], ic[k.I_NC], ic[k.I_SINGLE], ic[k.I_ORDER], ic[k.I_HALL] = (
            self._spe, self._n_c, tf.single, tf.order, self._h_all)
        bar_idx = np.array([i for i, _ in self._bar_fix], dtype=np.int64)
        bar_col = np.array([j for _, j in self._bar_fix], dtype=np.int64)
        # every array of the engine is a view of two buffers (kernel.pack): the step-wise path
        # hands the compiled step_packed 8 arguments instead of step_one's 21
        fbuf, ibuf, views = _kernel.pack(
            c, ic, np.asarray(tf._breaks_arr, dtype=float), np.asarray(tf._lam_arr, dtype=float),
            np.asarray(tf._h_arr, dtype=float), self._H, self._h_flat_idx.astype(np.int64),
            np.array(self._h_sup, dtype=np.int64), bar_idx, bar_col, np.asarray(self._lvec, dtype=float),
            np.asarray(self._dt_pow, dtype=float), _kernel.work_size(self.n_states), self.n_states)
        self._H = views[5]  # the reference engine's H (_h_matrix) is the engine's, as before
        self._kwork = views[12]
        self._kpack = (fbuf, ibuf, views[13], views[14])
        return views[:10]

    def _k_arrays(self):
        """The compiled engine's state: (flat [Y, K, P, P_start], cov counters, Y, K, P, P_start
        views), loaded from the reference engine's attributes when those hold the state."""
        st = self._kstate
        if st is None:
            ns = self.n_states
            pk = self._kpack
            flat = np.empty(2 * ns + 2 * ns * ns) if pk is None else pk[2]
            Y, K = flat[:ns], flat[ns:2 * ns]
            P = flat[2 * ns:2 * ns + ns * ns].reshape(ns, ns)
            P_start = flat[2 * ns + ns * ns:].reshape(ns, ns)
            Y[:] = self._Y
            K[:] = 0.0 if self._K is None else self._K
            P[:] = self._P
            P_start[:] = self._P_start
            cov = np.empty(3, dtype=np.int64) if pk is None else pk[3]
            cov[:] = (self._cov_left, self._cov_len, self._cov_pos)
            st = self._kstate = (flat, cov, Y, K, P, P_start)
        return st

    def _k_release(self) -> None:
        """Hand the state back to the reference engine's attributes (before its code runs)."""
        st = self._kstate
        if st is not None:
            _, cov, Y, K, P, P_start = st
            self._Y = Y.tolist()
            self._K = K.tolist()
            self._P = P.copy()
            self._P_rows = self._P.tolist()
            self._P_start = P_start.copy()
            self._cov_left, self._cov_len, self._cov_pos = (int(x) for x in cov)
            self._kstate = None

    def _run_compiled(self, t_end, inp, dtheta_r, dv_r, epochs: dict, steps):
        """:meth:`_run` with the runs of steps between epochs advanced by the compiled engine.

        The steps it hands back (start-up sub-steps, failures, epoch updates) are done here
        by the reference code; the filter state is passed both ways at each hand-over."""
        n = len(t_end)
        ns = self.n_states
        out_y = np.full((n, ns), np.nan)
        out_p = np.full((n, ns, ns), np.nan)
        nis = np.full(n, np.nan)
        dof = np.zeros(n, dtype=int)
        is_epoch = np.zeros(n, dtype=bool)
        is_epoch[list(epochs)] = True
        t_end = np.ascontiguousarray(t_end, dtype=float)
        inp = np.ascontiguousarray(inp, dtype=float)
        steps = np.ascontiguousarray(steps, dtype=np.int64)
        advance = _kernel.advance
        i = 0
        while i < n and not self._diverged:
            _, cov, Y, K, P, P_start = self._k_arrays()
            i, status = advance(i, inp, t_end, steps, is_epoch, Y, P, P_start, K, cov, *self._kargs, out_y, out_p,
                                self._kwork)
            if status == _kernel.STATUS_DONE:
                break
            self._k_release()
            self._reference_step(i, inp[i].tolist(), float(t_end[i]), int(steps[i]), dtheta_r, dv_r,
                                 epochs.get(i), status != _kernel.STATUS_EPOCH, out_y, out_p, nis, dof)
            i += 1
        return out_y, out_p, nis, dof

    def _reference_step(self, i, row, t, step, dtheta_r, dv_r, obs, propagate: bool, out_y, out_p, nis, dof):
        """One step of :meth:`_run`'s loop (propagation unless done, epoch update, outputs)."""
        try:
            if propagate:
                self._one_step(row, t, step, dtheta_r, dv_r, i)
            if obs is not None:
                self._cov_left = 0
                res = self._epoch_update(obs, row[18:21], t, dtheta_r[i][0] / self._dt if self._lever else None)
                if res is not None:
                    nis[i], dof[i] = res
            y = self._Y
            if not math.isfinite(sum(y)):
                raise FloatingPointError("non-finite state")
            out_y[i] = y
            if self._cov_left > 0 and self._cov_len > 1:
                p0 = self._P_start
                out_p[i] = p0 + (self._cov_pos / self._cov_len) * (self._P - p0)
            else:
                out_p[i] = self._P
        except (ArithmeticError, ValueError, np.linalg.LinAlgError):
            self._diverged = True
            out_y[i] = np.nan
            out_p[i] = np.nan

    def _run(self, t_end: np.ndarray, inp: np.ndarray, dtheta_r, dv_r, epochs: dict, steps: np.ndarray):
        n = len(t_end)
        ns = self.n_states
        nan_row = [math.nan] * ns
        out_y = []
        # covariance output per step: P at the interval start and at its end (indices into
        # mats, the distinct matrices of the batch) and the fraction; interpolated at the end
        nan_p = np.full((ns, ns), np.nan)
        mats = [nan_p]
        index = {id(nan_p): 0}
        ids0 = [0] * n
        ids1 = [0] * n
        frac = [0.0] * n
        nis = np.full(n, np.nan)
        dof = np.zeros(n, dtype=int)
        rows = inp.tolist()
        times = t_end.tolist()
        step_list = np.asarray(steps).tolist()
        one_step = self._one_step
        isfinite = math.isfinite
        last_p, last_k = None, 0
        for i in range(n):
            if self._diverged:
                out_y.append(nan_row)
                continue
            try:
                row = rows[i]
                one_step(row, times[i], step_list[i], dtheta_r, dv_r, i)
                obs = epochs.get(i)
                if obs is not None:
                    self._cov_left = 0
                    res = self._epoch_update(obs, row[18:21], times[i],
                                             dtheta_r[i][0] / self._dt if self._lever else None)
                    if res is not None:
                        nis[i], dof[i] = res
                y = self._Y
                if not isfinite(sum(y)):
                    raise FloatingPointError("non-finite state")
                out_y.append(list(y))
                P = self._P
                if P is not last_p:
                    last_p = P
                    last_k = index.get(id(P))
                    if last_k is None:
                        last_k = index[id(P)] = len(mats)
                        mats.append(P)
                ids0[i] = ids1[i] = last_k
                if self._cov_left > 0 and self._cov_len > 1:  # inside a covariance interval: linear in time
                    p0 = self._P_start
                    k0 = index.get(id(p0))
                    if k0 is None:
                        k0 = index[id(p0)] = len(mats)
                        mats.append(p0)
                    ids0[i] = k0
                    frac[i] = self._cov_pos / self._cov_len
            except (ArithmeticError, ValueError, np.linalg.LinAlgError):
                self._diverged = True
                out_y.append(nan_row)
                ids0[i] = ids1[i] = 0
                frac[i] = 0.0
        stack = np.array(mats)
        p_start = stack[ids0]
        out_p = p_start + np.array(frac)[:, None, None] * (stack[ids1] - p_start)
        return np.array(out_y, dtype=float).reshape(n, ns), out_p, nis, dof

    def _cov_coefficients(self, w, f, t):
        """Coefficients at the current state for a covariance interval: (first stage
        values, hneg, H filled, gain K (list), rate |dH_a/dY K|)."""
        first, a_dyn, hneg, q_dyn, s4, sig2 = self._fused(self._Y, w, f, t)
        if not self._observer:  # no (13): h = 0, S = 0 -> H = [[0, A^T], [A, Q]], K = 0
            hneg = [0.0] * len(hneg)
            s4 = 0.0
        H = self._h_matrix(a_dyn, hneg, q_dyn, s4, sig2)
        K, rate = self._gain(hneg, s4, sig2)
        return first, H, K, rate

    def _one_step(self, row, t1, step, dtheta_r, dv_r, i):
        dt = self._dt
        t0 = t1 - dt
        if self._cov_left <= 0:
            limit = self.config.stiffness_limit
            coeffs = self._cov_coefficients(row[0:3], row[3:6], t0)
            first, H, K, rate = coeffs
            to_epoch = self._spe - (step % self._spe)
            L = min(self._n_c, to_epoch)
            if rate * dt > limit:
                self._substeps(t0, dtheta_r[i], dv_r[i], coeffs)
                self._cov_left = 0
                self._cov_len = 1
                return
            if rate * L * dt > limit:
                L = max(1, int(limit / (rate * dt)))
            self._P_start = self._P
            self._P, self._P_rows = self._riccati(self._P, H, L * dt)
            self._K = K
            self._cov_left = L
            self._cov_len = L
            self._cov_pos = 0
        else:
            first = None
        self._state_rk4(row, t0, dt, first)
        self._cov_left -= 1
        self._cov_pos += 1

    def _substeps(self, t0, dtheta_r, dv_r, coeffs):
        """Adaptive sub-steps inside one navigation step (start-up stiffness)."""
        dt = self._dt
        limit = self.config.stiffness_limit
        cw, cf = self._coef(dtheta_r, dv_r)
        R = cw.shape[0]

        def at(c, s):
            powers = np.array([s ** j for j in range(R)])
            return (powers @ c).tolist()

        s_done = 0.0
        while s_done < 1.0 - 1e-12:
            if coeffs is None:
                coeffs = self._cov_coefficients(at(cw, s_done), at(cf, s_done), t0 + s_done * dt)
            first, H, K, rate = coeffs
            coeffs = None
            tau = min((1.0 - s_done) * dt, limit / max(rate, 1e-300))
            s_mid = s_done + 0.5 * tau / dt
            s_end = s_done + tau / dt
            row = at(cw, s_done) + at(cf, s_done) + at(cw, s_mid) + at(cf, s_mid) + at(cw, s_end) + at(cf, s_end)
            self._P, self._P_rows = self._riccati(self._P, H, tau)
            self._K = K
            self._state_rk4(row, t0 + s_done * dt, tau, first)
            s_done = s_end
            self.substeps += 1

    def _state_rk4(self, row, t0, tau, first=None):
        """RK4 of (14) over tau with the gain K held: Y' = F(Y) + K (Z_ax - H_a(Y))."""
        Y = self._Y
        K = self._K
        stage = self._stage
        a, b, g, phi, V = Y[0], Y[1], Y[2], Y[3], Y[4]
        w1x, w1y, w1z, f1x, f1y, f1z, w2x, w2y, w2z, f2x, f2y, f2z, w3x, w3y, w3z, f3x, f3y, f3z = row[:18]
        if self._biases:
            ia, ig = self._i_ba, self._i_bg
            bax, bay, baz, bgx, bgy, bgz = Y[ia], Y[ia + 1], Y[ia + 2], Y[ig], Y[ig + 1], Y[ig + 2]
            w1x, w1y, w1z, w2x, w2y, w2z, w3x, w3y, w3z = (
                w1x - bgx, w1y - bgy, w1z - bgz, w2x - bgx, w2y - bgy, w2z - bgz, w3x - bgx, w3y - bgy, w3z - bgz)
            f1x, f1y, f1z, f2x, f2y, f2z, f3x, f3y, f3z = (
                f1x - bax, f1y - bay, f1z - baz, f2x - bax, f2y - bay, f2z - baz, f3x - bax, f3y - bay, f3z - baz)
        k0, k1, k2, k3, k4 = K[0], K[1], K[2], K[3], K[4]
        h2 = 0.5 * tau
        tm = t0 + h2
        te = t0 + tau
        d1 = stage(a, b, g, phi, V, t0, w1x, w1y, w1z, f1x, f1y, f1z) if first is None else first
        i1 = d1[5]
        d2 = stage(a + h2 * (d1[0] + k0 * i1), b + h2 * (d1[1] + k1 * i1), g + h2 * (d1[2] + k2 * i1),
                   phi + h2 * (d1[3] + k3 * i1), V + h2 * (d1[4] + k4 * i1), tm, w2x, w2y, w2z, f2x, f2y, f2z)
        i2 = d2[5]
        d3 = stage(a + h2 * (d2[0] + k0 * i2), b + h2 * (d2[1] + k1 * i2), g + h2 * (d2[2] + k2 * i2),
                   phi + h2 * (d2[3] + k3 * i2), V + h2 * (d2[4] + k4 * i2), tm, w2x, w2y, w2z, f2x, f2y, f2z)
        i3 = d3[5]
        d4 = stage(a + tau * (d3[0] + k0 * i3), b + tau * (d3[1] + k1 * i3), g + tau * (d3[2] + k2 * i3),
                   phi + tau * (d3[3] + k3 * i3), V + tau * (d3[4] + k4 * i3), te, w3x, w3y, w3z, f3x, f3y, f3z)
        i4 = d4[5]
        c = tau / 6.0
        ibar = c * (i1 + 2.0 * (i2 + i3) + i4)
        Y[0] = a + c * (d1[0] + 2.0 * (d2[0] + d3[0]) + d4[0]) + k0 * ibar
        Y[1] = b + c * (d1[1] + 2.0 * (d2[1] + d3[1]) + d4[1]) + k1 * ibar
        Y[2] = g + c * (d1[2] + 2.0 * (d2[2] + d3[2]) + d4[2]) + k2 * ibar
        Y[3] = phi + c * (d1[3] + 2.0 * (d2[3] + d3[3]) + d4[3]) + k3 * ibar
        Y[4] = V + c * (d1[4] + 2.0 * (d2[4] + d3[4]) + d4[4]) + k4 * ibar
        if self.n_states > 5:  # linear extra states: exact transition + gain x integrated innovation
            if self._clock:
                i = self._i_clk
                Y[i] = Y[i] + tau * Y[i + 1] + K[i] * ibar
                Y[i + 1] = Y[i + 1] + K[i + 1] * ibar
            if self._biases:
                imu = self.context.imu
                fa = math.exp(-tau / imu.accel_bias_tau_s)
                fg = math.exp(-tau / imu.gyro_bias_tau_s)
                for j in range(3):
                    Y[ia + j] = fa * Y[ia + j] + K[ia + j] * ibar
                    Y[ig + j] = fg * Y[ig + j] + K[ig + j] * ibar

    # ------------------------------------------------------------------ (16)
    def _epoch_update(self, obs, f_mean, t, omega_mean=None):
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

    def gnss_observation(self, Y, t: float, sat_pos_e, sat_vel_e, gyro_rate_b=None):
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

    def _ecef(self, phi) -> np.ndarray:
        lam, _, _, hh, _ = self.track_functions.scalars(phi)
        sp, cp = math.sin(phi), math.cos(phi)
        if self._sphere:
            re = rz = self._a + hh
        else:
            r_e = self._a / math.sqrt(1.0 - self._e2 * sp * sp)
            re, rz = r_e + hh, r_e * (1.0 - self._e2) + hh
        return np.array([re * cp * math.cos(lam), re * cp * math.sin(lam), rz * sp])

    # ------------------------------------------------------------------ outputs
    def outputs(self, Y: np.ndarray, P: np.ndarray, t: np.ndarray):
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

    # ------------------------------------------------------------------ interface
    def _require(self):
        if not self._ready:
            raise RuntimeError("call PaperEkf.reset(context, prior) first")

    def _outputs(self, y, p, t):
        """:meth:`outputs`, by the compiled engine when it is in use (the same expressions)."""
        if self._kargs is None:
            return self.outputs(y, p, t)
        n = len(y)
        sol = np.empty((n, 9))
        cov = np.empty((n, 9, 9))
        c, ic, breaks, lam_c, h_c = self._kargs[:5]
        _kernel.outputs_compiled(np.ascontiguousarray(y), np.ascontiguousarray(p), np.ascontiguousarray(t, dtype=float),
                                 c, ic, breaks, lam_c, h_c, sol, cov)
        return sol, cov

    def _row_compiled(self, measurement: Measurement) -> tuple[np.ndarray, np.ndarray] | None:
        """The step-wise path of the compiled engine for a step without an epoch: (solution
        row (9,), covariance (9, 9)); None when the step needs the general path (sub-steps,
        a failure), the state then unchanged."""
        if self._kstate is None:  # the state into the packed buffers (views of kernel.pack)
            self._k_arrays()
        sol = np.empty(9)
        cov9 = np.empty((9, 9))
        step_one = self._kstep_one
        if step_one is None:  # the compiled dispatcher itself (no wrapper call per step)
            step_one = self._kstep_one = _kernel.step_packed_dispatcher()
        fbuf, ibuf = self._kpack[:2]
        status = step_one(np.ascontiguousarray(measurement.dtheta_r, dtype=float),
                          np.ascontiguousarray(measurement.dv_r, dtype=float), float(measurement.t),
                          int(measurement.step), False, fbuf, ibuf, sol, cov9)
        if status != _kernel.STATUS_DONE:
            return None
        return sol, cov9

    def _row_epoch(self, measurement: Measurement) -> StepRow | None:
        """The step-wise path of the compiled engine for a step that ends at a GNSS epoch: the
        propagation by the compiled :func:`~navsim.estimators.paper_ekf.kernel.step_core`, then
        the update (16) and the outputs by the code of :meth:`_run_compiled` for a one-step
        batch (:meth:`_reference_step`, :meth:`_outputs`), so the numbers of
        :meth:`_step_general`, without its array preparation and :class:`Estimate`. None when
        the step needs the general path (sub-steps, a failure), the state then unchanged."""
        if self._kstate is None:
            self._k_arrays()
        step_one = self._kstep_one
        if step_one is None:
            step_one = self._kstep_one = _kernel.step_packed_dispatcher()
        fbuf, ibuf = self._kpack[:2]
        dtheta_r = np.ascontiguousarray(measurement.dtheta_r, dtype=float)
        t = float(measurement.t)
        status = step_one(dtheta_r, np.ascontiguousarray(measurement.dv_r, dtype=float), t, int(measurement.step),
                          True, fbuf, ibuf, np.empty(9), np.empty((9, 9)))
        if status != _kernel.STATUS_EPOCH:
            return None
        ns = self.n_states
        o = _kernel.input_offset(ns)
        row = self._kwork[o:o + 21].tolist()
        self._k_release()
        out_y = np.full((1, ns), np.nan)
        out_p = np.full((1, ns, ns), np.nan)
        nis = np.full(1, np.nan)
        dof = np.zeros(1, dtype=int)
        self._reference_step(0, row, t, int(measurement.step), dtheta_r[None], None, measurement.gnss, False,
                             out_y, out_p, nis, dof)
        sol, cov = self._outputs(out_y, out_p, np.array([t]))
        return (sol[0], cov[0], None if math.isnan(nis[0]) else float(nis[0]),
                None if dof[0] == 0 else int(dof[0]))

    def _step_compiled(self, measurement: Measurement):
        """:meth:`_row_compiled` as an :class:`Estimate` (None: the general path)."""
        done = self._row_compiled(measurement)
        if done is None:
            return None
        sol, cov9 = done
        st = self._kstate
        y = st[2].copy()
        extra = {"state": y, "state_cov": st[4].copy(), "diverged": False}
        if self.n_states > 5:
            extra.update(self._extra_states(y))
        lat, lon, h, _, _, _, heading, pitch, roll = sol.tolist()  # the floats of float(sol[i]), in one call
        return Estimate(t=float(measurement.t), lat=lat, lon=lon, h=h, velocity_n=sol[3:6], heading=heading,
                        pitch=pitch, roll=roll, covariance=cov9, nis=None, nis_dof=None, extra=extra)

    def step(self, measurement: Measurement) -> Estimate:
        """One navigation step: (14) over the step, (16) if an epoch ends it."""
        self._require()
        if self._kargs is not None and measurement.gnss is None and not self._diverged:
            est = self._step_compiled(measurement)
            if est is not None:
                return est
        return self._step_general(measurement)

    def step_row(self, measurement: Measurement) -> StepRow:
        """:meth:`step` as ``(row (9,), covariance (9, 9), nis, nis_dof)`` (the
        :class:`~navsim.estimators.base.RowStepping` protocol): the same numbers; a step of
        the compiled path builds no :class:`Estimate` and no ``extra``."""
        self._require()
        if self._kargs is not None and not self._diverged:
            if measurement.gnss is None:
                done = self._row_compiled(measurement)
                if done is not None:
                    return done[0], done[1], None, None
            else:
                at_epoch = self._row_epoch(measurement)
                if at_epoch is not None:
                    return at_epoch
        return row_of(self._step_general(measurement))

    def _step_general(self, measurement: Measurement) -> Estimate:
        """:meth:`step` by (14) and (16) on arrays (every step the compiled path does not take)."""
        inp = self._prepare(measurement.dtheta_r[None], measurement.dv_r[None])
        epochs = {} if measurement.gnss is None else {0: measurement.gnss}
        t = np.array([measurement.t])
        y, p, nis, dof = self._propagate(t, inp, measurement.dtheta_r[None], measurement.dv_r[None], epochs,
                                         np.array([measurement.step]))
        sol, cov = self._outputs(y, p, t)
        extra = {"state": y[0].copy(), "state_cov": p[0].copy(), "diverged": self._diverged}
        extra.update(self._extra_states(y[0]))
        s = sol[0]
        return Estimate(t=float(measurement.t), lat=float(s[0]), lon=float(s[1]), h=float(s[2]),
                        velocity_n=s[3:6].copy(), heading=float(s[6]), pitch=float(s[7]), roll=float(s[8]),
                        covariance=cov[0], nis=None if math.isnan(nis[0]) else float(nis[0]),
                        nis_dof=None if dof[0] == 0 else int(dof[0]), extra=extra)

    def step_batch(self, batch: MeasurementBatch) -> EstimateBatch:
        """Many steps at once; the same numbers as repeated :meth:`step`."""
        self._require()
        inp = self._prepare(batch.dtheta_r, batch.dv_r)
        epochs = {int(j): obs for j, obs in batch.gnss}
        t = np.asarray(batch.t, dtype=float)
        y, p, nis, dof = self._propagate(t, inp, batch.dtheta_r, batch.dv_r, epochs, np.asarray(batch.step))
        sol, cov = self._outputs(y, p, t)
        self.last_states, self.last_state_cov = y, p
        return EstimateBatch(solution=sol, covariance=cov, nis=nis, nis_dof=dof)

    def _extra_states(self, y) -> dict:
        out = {}
        if self._clock:
            out["clock_bias_m"] = float(y[self._i_clk])
            out["clock_drift_mps"] = float(y[self._i_clk + 1])
        if self._biases:
            out["accel_bias"] = y[self._i_ba:self._i_ba + 3].copy()
            out["gyro_bias"] = y[self._i_bg:self._i_bg + 3].copy()
        return out

    @property
    def diverged(self) -> bool:
        return self._diverged
