"""The 15-state ENU error model of the shared error-state INS: the state layout, the noise model
(:class:`ImuNoise`, :func:`noise_density`), the continuous matrix F of (a)-(e)
(:func:`error_dynamics`), the transition series Phi, Qd over a covariance interval
(:func:`transition`), the Joseph update, the closed-loop correction, the antenna lever-arm
terms (LA.3) and the solution rows. Equations: :mod:`navsim.estimators._inserror`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ...errors import ConfigError
from ...rotations import mat_nb_from_hpr, mat_to_quat
from ...strapdown.ins import InsState
from ..base import NominalImu

if TYPE_CHECKING:
    from ...earth import EarthModel
    from ...types import Prior

N_STATES = 15
POS, VEL, ATT, BG, BA = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15)
NAV = slice(0, 9)

Vector = Sequence[float] | np.ndarray
"""A few numbers read one by one: a tuple or list of floats, or a 1-d array."""


@dataclass(frozen=True, slots=True)
class ImuNoise:
    """Process-noise model of the error state (per axis, isotropic).

    Parameters
    ----------
    gyro_psd : float
        White gyro noise PSD (ARW^2), rad^2/s.
    accel_psd : float
        White accelerometer noise PSD (VRW^2), m^2/s^3.
    gyro_bias_sigma, accel_bias_sigma : float
        Stationary sigma of the bias states, rad/s and m/s^2 (also their initial sigma).
    gyro_bias_tau_s, accel_bias_tau_s : float
        Gauss-Markov correlation times, s (``inf``: random constant / random walk).
    gyro_rrw_psd, accel_rrw_psd : float
        Rate-random-walk PSDs, rad^2/s^3 and m^2/s^5.
    gyro_scale_sigma : float
        1-sigma of each element of the gyros' unmodelled scale-factor/misalignment matrix
        S (dimensionless; 0: not modelled, the default). Covered as rate-proportional
        attitude noise (RS.1) of the engine, not as states.
    accel_scale_sigma : float
        The same for the accelerometers (RS.2).
    scale_tau_s : float
        Correlation time of the S omega and S_a a terms in (RS.1), (RS.2), s.
    """

    gyro_psd: float = 0.0
    accel_psd: float = 0.0
    gyro_bias_sigma: float = 0.0
    accel_bias_sigma: float = 0.0
    gyro_bias_tau_s: float = math.inf
    accel_bias_tau_s: float = math.inf
    gyro_rrw_psd: float = 0.0
    accel_rrw_psd: float = 0.0
    gyro_scale_sigma: float = 0.0
    accel_scale_sigma: float = 0.0
    scale_tau_s: float = 5.0

    def __post_init__(self) -> None:
        for name in ImuNoise.__slots__:
            value = float(getattr(self, name))
            if name.endswith("tau_s"):
                if not value > 0.0:
                    raise ConfigError(f"noise.{name}", "a positive time (s) or inf", value)
            elif not (value >= 0.0 and math.isfinite(value)):
                raise ConfigError(f"noise.{name}", "a non-negative finite number", value)
            object.__setattr__(self, name, value)

    @classmethod
    def from_nominal(cls, nominal: NominalImu, *, noise_scale: float = 1.0, bias_scale: float = 1.0) -> ImuNoise:
        """The model of a :class:`NominalImu`: PSDs are squared densities; the bias sigma
        (turn-on plus instability, as the context reports it) becomes a Gauss-Markov
        process with the nominal correlation time. ``noise_scale``, ``bias_scale``
        multiply the sigmas (tuning)."""
        for name, value in (("noise_scale", noise_scale), ("bias_scale", bias_scale)):
            if not (value > 0.0 and math.isfinite(value)):
                raise ConfigError(name, "a positive finite factor", value)
        return cls(
            gyro_psd=(noise_scale * nominal.gyro_arw) ** 2,
            accel_psd=(noise_scale * nominal.accel_vrw) ** 2,
            gyro_bias_sigma=bias_scale * nominal.gyro_bias_sigma,
            accel_bias_sigma=bias_scale * nominal.accel_bias_sigma,
            gyro_bias_tau_s=nominal.gyro_bias_tau_s,
            accel_bias_tau_s=nominal.accel_bias_tau_s,
            gyro_rrw_psd=(bias_scale * nominal.gyro_rrw) ** 2,
            accel_rrw_psd=(bias_scale * nominal.accel_rrw) ** 2,
        )


def _gravity_partials(earth: EarthModel, lat: float, h: float) -> tuple[float, float, float, float]:
    """d g_N/d lat, d g_N/d h, d g_U/d lat, d g_U/d h of :meth:`EarthModel.gravity_n`."""
    s, c = math.sin(lat), math.cos(lat)
    if earth.name == "spherical":
        w2 = earth.rate**2
        return -w2 * (earth.a + h) * (c * c - s * s), -w2 * c * s, -2.0 * w2 * (earth.a + h) * c * s, w2 * c * c
    a, f, e2 = earth.a, earth.f, earth.e2
    gamma_e, k_som = 9.7803253359, 0.00193185265241  # TR8350.2, as in earth.gravity_n
    m = earth.rate**2 * a**2 * a * (1.0 - f) / earth.gm
    s2 = s * s
    w2 = 1.0 - e2 * s2
    gamma = gamma_e * (1.0 + k_som * s2) / math.sqrt(w2)
    dgamma = gamma_e * (2.0 * k_som * s * c / math.sqrt(w2) + (1.0 + k_som * s2) * e2 * s * c / w2**1.5)
    factor = 1.0 - 2.0 / a * (1.0 + f + m - 2.0 * f * s2) * h + 3.0 / a**2 * h * h
    dfactor_lat = 8.0 * f * s * c * h / a
    dfactor_h = -2.0 / a * (1.0 + f + m - 2.0 * f * s2) + 6.0 * h / a**2
    return 0.0, 0.0, -(dgamma * factor + gamma * dfactor_lat), -gamma * dfactor_h


def error_dynamics(lat: float, h: float, velocity_n: Vector, mat_nb: ArrayLike, specific_force_n: Vector,
                   earth: EarthModel, noise: ImuNoise) -> np.ndarray:
    """Continuous-time error dynamics matrix F (15, 15) of the module's error state.

    Parameters
    ----------
    lat, h : float
        Latitude (rad) and height (m) of the INS.
    velocity_n : array_like, shape (3,)
        ENU velocity, m/s.
    mat_nb : array_like, shape (3, 3)
        Body-to-ENU attitude matrix C.
    specific_force_n : array_like, shape (3,)
        Specific force in ENU, m/s^2 (about ``[0, 0, +g]`` at rest).
    earth : EarthModel
    noise : ImuNoise
        Only the bias correlation times are used.

    Returns
    -------
    ndarray, shape (15, 15)
        ``x' = F x + noise``; equations (a)-(e) of the module docstring.
    """
    ve, vn, vu = (float(x) for x in velocity_n)
    fe, fn, fu = (float(x) for x in specific_force_n)
    C = np.asarray(mat_nb, dtype=float)
    rate = earth.rate
    s, c = math.sin(lat), math.cos(lat)
    t = s / c
    r_n, r_e = (float(x) for x in earth.radii(lat))
    dr_n, dr_e = (float(x) for x in earth.radii_derivative(lat))
    rnh, reh = r_n + h, r_e + h
    lat_rate = vn / rnh
    w_ie = (0.0, rate * c, rate * s)
    w_en = (-vn / rnh, ve / reh, ve * t / reh)
    w_in = (w_ie[0] + w_en[0], w_ie[1] + w_en[1], w_ie[2] + w_en[2])
    cor = (2 * w_ie[0] + w_en[0], 2 * w_ie[1] + w_en[1], 2 * w_ie[2] + w_en[2])

    # first-order changes of the rates: rows (E, N, U), columns (dlat, dh, dvE, dvN)
    d_wie = np.array([[0.0, 0.0, 0.0, 0.0], [-rate * s, 0.0, 0.0, 0.0], [rate * c, 0.0, 0.0, 0.0]])
    d_wen = np.array([
        [vn * dr_n / rnh**2, vn / rnh**2, 0.0, -1.0 / rnh],
        [-ve * dr_e / reh**2, -ve / reh**2, 1.0 / reh, 0.0],
        [ve / (c * c * reh) - ve * t * dr_e / reh**2, -ve * t / reh**2, t / reh, 0.0],
    ])
    # map (dlat, dh, dvE, dvN) to the state: dlat = dN / RN', dh = dU
    to_state = np.zeros((4, N_STATES))
    to_state[0, 1] = 1.0 / rnh
    to_state[1, 2] = 1.0
    to_state[2, 3] = 1.0
    to_state[3, 4] = 1.0
    d_win = (d_wie + d_wen) @ to_state  # (3, 15)
    d_cor = (2.0 * d_wie + d_wen) @ to_state

    F = np.zeros((N_STATES, N_STATES))
    # (c), (d): position
    F[0, 0] = dr_e * lat_rate / reh + vu / reh - t * lat_rate
    F[0, 1] = -ve * (dr_e / reh - t) / rnh
    F[0, 2] = -ve / reh
    F[0, 3] = 1.0
    F[1, 1] = vu / rnh
    F[1, 2] = -vn / rnh
    F[1, 4] = 1.0
    F[2, 5] = 1.0
    # (b): velocity
    vel = np.array([ve, vn, vu])
    # -(2 d w_ie + d w_en) x v = v x d_cor
    F[VEL] += np.cross(vel, d_cor.T).T
    dgn_dlat, dgn_dh, dgu_dlat, dgu_dh = _gravity_partials(earth, lat, h)
    F[4, 1] += dgn_dlat / rnh
    F[4, 2] += dgn_dh
    F[5, 1] += dgu_dlat / rnh
    F[5, 2] += dgu_dh
    # -(2 w_ie + w_en) x dv
    F[VEL, VEL] -= skew3(cor)
    # -f_n x psi
    F[VEL, ATT] = -skew3((fe, fn, fu))
    F[VEL, BA] = C
    # (a): attitude
    F[ATT, ATT] = -skew3(w_in)
    F[ATT] -= d_win
    F[ATT, BG] = C
    # (e): biases
    F[BG, BG] = -np.eye(3) / noise.gyro_bias_tau_s
    F[BA, BA] = -np.eye(3) / noise.accel_bias_tau_s
    return F


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (n, 3) arrays (np.cross is slow on small arrays)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def skew3(v: Vector) -> np.ndarray:
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def lever_arm_terms(mat_nb: ArrayLike, omega_ib_b: ArrayLike, lever_arm_b: ArrayLike, omega_ie_n: ArrayLike
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The antenna's offset from the INS in ENU, its velocity, and their error partials.

    Parameters
    ----------
    mat_nb : array_like (3, 3)
        Estimated body-to-ENU attitude C.
    omega_ib_b : array_like (3,)
        Estimated (bias-compensated) body rate, rad/s.
    lever_arm_b : array_like (3,)
        Antenna relative to the IMU in body axes, m.
    omega_ie_n : array_like (3,)
        Earth rate in ENU at the INS position, rad/s.

    Returns
    -------
    arm_n : (3,) m
        ``C l``: the antenna is at ``r + arm_n`` (ENU axes at the INS).
    arm_velocity_n : (3,) m/s
        ``C (omega_ib_b x l) - omega_ie_n x C l``: the antenna moves at ``v_n +
        arm_velocity_n`` relative to the Earth (ENU components of the ECEF-frame
        velocity; :func:`navsim.sensors.gnss.antenna_state`, (LA.1)-(LA.2)).
    L : (6, 15)
        ``[r_a; v_a](estimate) - [r_a; v_a](truth) = L x`` to first order in the error
        state x of this module::

            L_pos = [I, 0, -[arm_n x], 0, 0]                                  (LA.3)
            L_vel = [0, I, -[a x] + [omega_ie x][arm_n x], -C [l x], 0],  a = C (omega x l)

        from ``C_est = (I + [psi x]) C`` and ``omega_est = omega + eg``; the change of
        omega_ie with the position error (~1e-11 m/s per metre) is left out.
        tests/estimators/test_loosely.py checks L against finite differences through
        :func:`correct_state`.
    """
    C = np.asarray(mat_nb, dtype=float)
    lever = np.asarray(lever_arm_b, dtype=float)
    w = np.asarray(omega_ib_b, dtype=float)
    w_ie = np.asarray(omega_ie_n, dtype=float)
    arm_n = C @ lever
    turn_n = C @ np.array([w[1] * lever[2] - w[2] * lever[1], w[2] * lever[0] - w[0] * lever[2],
                           w[0] * lever[1] - w[1] * lever[0]])  # C (omega x l)
    skew_arm = skew3(arm_n)
    skew_ie = skew3(w_ie)
    arm_velocity_n = turn_n - skew_ie @ arm_n
    L = np.zeros((6, N_STATES))
    L[0:3, POS] = np.eye(3)
    L[0:3, ATT] = -skew_arm  # (LA.3)
    L[3:6, VEL] = np.eye(3)
    L[3:6, ATT] = -skew3(turn_n) + skew_ie @ skew_arm
    L[3:6, BG] = -C @ skew3(lever)
    return arm_n, arm_velocity_n, L


def noise_density(noise: ImuNoise) -> np.ndarray:
    """Qc = G Q G^T (15, 15), the white-noise PSD matrix of the error state.

    Isotropic sensor noise makes ``C q C^T = q I``, so Qc is diagonal and constant.
    """
    q = np.zeros(N_STATES)
    q[VEL] = noise.accel_psd
    q[ATT] = noise.gyro_psd
    q[BG] = 2.0 * noise.gyro_bias_sigma**2 / noise.gyro_bias_tau_s + noise.gyro_rrw_psd
    q[BA] = 2.0 * noise.accel_bias_sigma**2 / noise.accel_bias_tau_s + noise.accel_rrw_psd
    return np.diag(q)


@dataclass(frozen=True, slots=True)
class TransitionSeries:
    """Series coefficients of Phi(tau) and Qd(tau) for one F (see the module notes)."""

    F: np.ndarray
    F2h: np.ndarray  # F^2 / 2
    F3s: np.ndarray  # F^3 / 6
    F4s: np.ndarray  # F^4 / 24
    q1: np.ndarray  # Qc
    q2: np.ndarray  # A / 2
    q3: np.ndarray  # B / 3
    q4: np.ndarray  # C3 / 4
    q5: np.ndarray  # D / 5

    @classmethod
    def build(cls, F: np.ndarray, Qc: np.ndarray) -> TransitionSeries:
        F2 = F @ F
        FQ = F @ Qc
        F2Q = F2 @ Qc
        A = FQ + FQ.T
        B = FQ @ F.T + 0.5 * (F2Q + F2Q.T)
        C3 = F2Q @ F.T
        C3 = 0.5 * (C3 + C3.T)
        D = 0.25 * F2Q @ F2.T
        return cls(F, 0.5 * F2, F2 @ F / 6.0, F2 @ F2 / 24.0, Qc, 0.5 * A, B / 3.0, 0.25 * C3, 0.2 * D)

    def phi(self, tau: np.ndarray, rows: slice = slice(None)) -> np.ndarray:
        """Phi(tau) rows, shape (k, len(rows), 15)."""
        tau = tau[:, None, None]
        eye = np.eye(N_STATES)[rows]
        return eye + tau * (self.F[rows] + tau * (self.F2h[rows] + tau * (self.F3s[rows] + tau * self.F4s[rows])))

    def nav_polynomial(self, P0: np.ndarray) -> np.ndarray:
        """Coefficients (9, 81) of the navigation block of P(tau) = Phi P0 Phi^T + Qd as a
        polynomial in tau: ``P9(tau) = (tau^p)_p @ coefficients`` (p = 0..8)."""
        M = (np.eye(N_STATES)[NAV], self.F[NAV], self.F2h[NAV], self.F3s[NAV], self.F4s[NAV])  # Phi9 = sum tau^a M_a
        MP = [m @ P0 for m in M]
        coef = np.zeros((9, 9, 9))
        for a in range(5):
            for b in range(5):
                coef[a + b] += MP[a] @ M[b].T
        b9 = (NAV, NAV)
        for p, q in enumerate((self.q1, self.q2, self.q3, self.q4, self.q5), start=1):
            coef[p] += q[b9]
        return coef.reshape(9, 81)

    def qd(self, tau: np.ndarray, block: slice = slice(None)) -> np.ndarray:
        """Qd(tau) block, shape (k, n, n)."""
        tau = tau[:, None, None]
        b = (block, block)
        return tau * (self.q1[b] + tau * (self.q2[b] + tau * (self.q3[b] + tau * (self.q4[b] + tau * self.q5[b]))))


def transition(F: np.ndarray, Qc: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """Phi(tau) (15, 15) and Qd(tau) (15, 15) by the series of the module docstring."""
    series = TransitionSeries.build(np.asarray(F, dtype=float), np.asarray(Qc, dtype=float))
    t = np.array([float(tau)])
    return series.phi(t)[0], series.qd(t)[0]


def joseph_update(P: np.ndarray, H: np.ndarray, R: np.ndarray, innovation: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, float]:
    """Kalman update of a zero-mean error state in Joseph form.

    Parameters
    ----------
    P : (n, n) prior covariance. H : (m, n). R : (m, m). innovation : (m,) = z - H x
    with x = 0 (the closed-loop error state).

    Returns
    -------
    dx : (n,) the error-state estimate K y.
    P_new : (n, n) ``(I - K H) P (I - K H)^T + K R K^T``, symmetrised.
    nis : float, ``y^T S^-1 y``.
    """
    # S = H P H^T + R
    PHt = P @ H.T
    S = H @ PHt + R
    # K = P H^T S^-1 (Cholesky solve; S is SPD)
    cho = np.linalg.cholesky(S)
    K = np.linalg.solve(cho.T, np.linalg.solve(cho, PHt.T)).T
    w = np.linalg.solve(cho, innovation)
    nis = float(w @ w)
    dx = K @ innovation
    # P = (I - K H) P (I - K H)^T + K R K^T
    IKH = np.eye(P.shape[0]) - K @ H
    P_new = IKH @ P @ IKH.T + K @ R @ K.T
    return dx, 0.5 * (P_new + P_new.T), nis


def correct_state(state: InsState, dx_nav: Vector, earth: EarthModel) -> InsState:
    """Remove an estimated navigation error ``dx_nav`` (9,) from an INS state (feedback).

    Position ``lat -= dN / (R_N + h)``, ``lon -= dE / ((R_E + h) cos lat)``, ``h -= dU``;
    velocity ``v -= dv``; attitude ``mat_nb <- exp(-[psi x]) mat_nb`` (the inverse of the
    error definition, applied on the ENU side of the quaternion).
    """
    de, dn, du, dve, dvn, dvu, pe, pn, pu = (float(x) for x in dx_nav)
    lat, h = state.lat, state.h
    r_n, r_e = earth.radii(lat)
    lat_new = lat - dn / (float(r_n) + h)
    lon_new = state.lon - de / ((float(r_e) + h) * math.cos(lat))
    v = state.velocity_n
    # q(-psi) o q_nb
    angle = math.sqrt(pe * pe + pn * pn + pu * pu)
    half = 0.5 * angle
    k = -(math.sin(half) / angle if angle > 1e-12 else 0.5 - angle * angle / 48.0)
    r0, r1, r2, r3 = math.cos(half), k * pe, k * pn, k * pu
    q0, q1, q2, q3 = (float(x) for x in state.quat_nb)
    quat = np.array([
        r0 * q0 - r1 * q1 - r2 * q2 - r3 * q3,
        r0 * q1 + r1 * q0 + r2 * q3 - r3 * q2,
        r0 * q2 - r1 * q3 + r2 * q0 + r3 * q1,
        r0 * q3 + r1 * q2 - r2 * q1 + r3 * q0,
    ])
    quat /= math.sqrt(float(quat @ quat))
    return InsState(lat_new, lon_new, h - du, np.array((v[0] - dve, v[1] - dvn, v[2] - dvu)), quat, state.compensation)


def compensate_increments(dtheta_sub: ArrayLike | None, dv_sub: ArrayLike | None, dtheta_r: ArrayLike | None,
                          dv_r: ArrayLike | None, gyro_bias: ArrayLike, accel_bias: ArrayLike, nav_period_s: float
                          ) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """Remove constant biases (rad/s, m/s^2, body axes) from the IMU data of n steps.

    ``dtheta_r[:, r-1] -= b dt^r / r!`` (the r-fold integral of a constant over the
    step dt); ``dtheta_sub -= b dt / m`` for m sub-samples. Arrays may be None.
    Returns the four arrays (new arrays; inputs are not modified).
    """
    out: list[np.ndarray | None] = []
    for data, bias in ((dtheta_sub, gyro_bias), (dv_sub, accel_bias)):
        if data is None:
            out.append(None)
        else:
            arr = np.asarray(data, dtype=float)
            out.append(arr - np.asarray(bias) * (nav_period_s / arr.shape[-2]))
    for data, bias in ((dtheta_r, gyro_bias), (dv_r, accel_bias)):
        if data is None:
            out.append(None)
        else:
            arr = np.asarray(data, dtype=float)
            orders = arr.shape[-2]
            kern = np.array([nav_period_s**r / math.factorial(r) for r in range(1, orders + 1)])
            out.append(arr - kern[:, None] * np.asarray(bias)[None, :])
    return out[0], out[1], out[2], out[3]


def solution_rows(lat: ArrayLike, lon: ArrayLike, h: ArrayLike, velocity_n: ArrayLike, quat_nb: ArrayLike) -> np.ndarray:
    """(n, 9) rows ``[lat, lon, h, vE, vN, vU, heading, pitch, roll]`` of INS outputs.

    Heading, pitch and roll as :func:`navsim.rotations.hpr_from_mat_nb`, from the five
    matrix entries they need (``C01, C11, C20, C21, C22`` of ``quat_to_mat``).
    """
    q = np.asarray(quat_nb, dtype=float)
    q0, q1, q2, q3 = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    out = np.empty((len(q), 9))
    out[:, 0], out[:, 1], out[:, 2] = lat, lon, h
    out[:, 3:6] = velocity_n
    c01 = 2.0 * (q1 * q2 - q0 * q3)
    c11 = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    c20 = 2.0 * (q1 * q3 - q0 * q2)
    c21 = 2.0 * (q2 * q3 + q0 * q1)
    c22 = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
    out[:, 6] = np.arctan2(c01, c11)
    out[:, 7] = np.arcsin(np.clip(c21, -1.0, 1.0))
    out[:, 8] = np.arctan2(-c20, c22)
    return out


def state_from_prior(prior: Prior) -> InsState:
    """The INS state of a :class:`navsim.simulator.Prior`."""
    quat = mat_to_quat(mat_nb_from_hpr(prior.heading, prior.pitch, prior.roll))
    return InsState(prior.lat, prior.lon, prior.h, np.asarray(prior.velocity_n, dtype=float), quat)
