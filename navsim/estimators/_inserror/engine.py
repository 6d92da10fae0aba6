"""Shared error-state INS machinery: the 15-state ENU error model and a propagation engine.

Used by the INS-only, loosely coupled and (optionally) tightly coupled estimators. Two
layers:

* pure functions of the linearised error model: :func:`error_dynamics` (the continuous
  matrix F), :func:`noise_density` (Qc), :func:`transition` (Phi and Qd over a time span by
  the series below), :func:`joseph_update`, :func:`correct_state`,
  :func:`compensate_increments`, :func:`solution_rows`, :func:`lever_arm_terms` (the
  GNSS antenna's offset, velocity and their error partials (LA.3) for the aided filters);
* :class:`ErrorStateIns`, a stateful engine: the INS mechanisation of
  :func:`navsim.strapdown.ins.integrate` on bias-compensated increments, the 15 x 15
  covariance propagated once per *covariance interval*, and closed-loop (feedback)
  measurement updates. An estimator owns one engine, calls :meth:`ErrorStateIns.advance`
  with the IMU data of one or many steps and :meth:`ErrorStateIns.update` with a linear
  (linearised) measurement of the error state;
* :class:`AuxStateIns`, the same engine with auxiliary error states whose dynamics do not
  involve the INS errors (random walks: e.g. a wheel-odometer scale factor), and
  :func:`body_velocity_terms`, the body-frame velocity and its error partials of the
  odometer / non-holonomic-constraint updates.

Error state (15,), every navigation error "estimate minus truth" as in
:mod:`navsim.estimators.base`::

    x = [dE, dN, dU (m),  dvE, dvN, dvU (m/s),  psiE, psiN, psiU (rad),
         eg_x, eg_y, eg_z (rad/s),  ea_x, ea_y, ea_z (m/s^2)]

``psi``: ``mat_nb_est = (I + [psi x]) mat_nb_true``. ``eg``, ``ea``: the *residual* gyro and
accelerometer biases in body axes, ``b_true - b_est``, i.e. what is left in the compensated
outputs ``omega_est = omega_true + eg``, ``f_est = f_true + ea``. The feedback adds the
estimated residual to the bias estimate (``b_est += eg_hat``) and removes the navigation
errors from the INS (``lat -= dN / (R_N + h)`` ..., ``mat_nb <- (I - [psi x]) mat_nb``).

Error dynamics (derived here in ENU with metric position errors; Groves 2013 eqs.
(14.63)-(14.71) give the NED/curvilinear form of the same model)::

    psi'  = -omega_in x psi - d omega_in + C eg                         (a)
    dv'   = -f_n x psi + C ea - (2 omega_ie + omega_en) x dv
            - (2 d omega_ie + d omega_en) x v + dg                       (b)
    dN'   = dvN + vU/RN' dN - vN/RN' dU                                 (c)
    dE'   = dvE + (R_E,lat L'/RE' + vU/RE' - tan(L) L') dE
            - vE (R_E,lat/RE' - tan L) dN/RN' - vE/RE' dU                (d)
    dU'   = dvU
    eg'   = -eg / tau_g + w_g,    ea' = -ea / tau_a + w_a               (e)

with ``RN' = R_N + h``, ``RE' = R_E + h``, ``L' = vN / RN'``, ``R_E,lat = dR_E/dlat``,
``C = mat_nb``, ``f_n = C f_b`` and ``d omega``, ``dg`` the first-order changes of the Earth
rate, transport rate and gravity with dL = dN/RN', dh = dU, dv. (a) follows from
differentiating ``C_est = (I + Psi) C`` with both attitude equations of
:mod:`navsim.strapdown.ins`; (c), (d) from ``dN = RN' dlat``, ``dE = RE' cos(L) dlon``.
tests/estimators/test_loosely.py checks F against finite differences of the nonlinear
mechanisation equations.

Noise: white gyro and accelerometer noise enter (a), (b) through C with PSDs ARW^2 and
VRW^2 (isotropic, so C drops out of Qc); the biases are first-order Gauss-Markov with the
nominal sigma and correlation time, driving PSD ``2 sigma^2 / tau``, plus the
rate-random-walk PSD (``tau = inf`` makes them random walks / random constants).

Covariance intervals (the speed device)
---------------------------------------
Propagating a 15 x 15 covariance at every 100 Hz step costs more than the INS itself. The
engine builds F once per *interval* (at most ``interval_steps`` navigation steps, ended
early by a measurement update) from the state at the interval start and the mean
specific force ``f_n`` of the previous interval, and uses over the interval

    Phi(tau) = I + F tau + F^2 tau^2/2 + F^3 tau^3/6 + F^4 tau^4/24     (4th-order series)
    Qd(tau)  = int_0^tau Phi(s) Qc Phi(s)^T ds   with Phi(s) to 2nd order:
             = Qc tau + A tau^2/2 + B tau^3/3 + C3 tau^4/4 + D tau^5/5,
      A = F Qc + Qc F^T,  B = F Qc F^T + (F^2 Qc + Qc F^2T)/2,
      C3 = (F^2 Qc F^T + F Qc F^2T)/2,  D = F^2 Qc F^2T / 4
    P(tau)   = Phi(tau) P0 Phi(tau)^T + Qd(tau)                          # P = F P F^T + Q

The reported covariance at every step inside the interval is this P(tau) (so NEES is
meaningful between GNSS epochs too), and the covariance at the interval end starts the
next one. The chain position <- velocity <- attitude <- gyro bias is cubic in tau; the
fourth-order term carries its coupling with the bias correlation time and the Earth and
transport rates (tests: Phi within 1e-5 relative of expm(F tau) over 1 s). Everything used at step j of an interval is known
at step j, so stepping one step at a time and advancing many steps at once give the same
numbers (to rounding): the contract of ``step_batch``.

Bias compensation: the biases are constant between updates. :func:`body_terms` computes
the body-frame strapdown terms of a whole batch once from the raw IMU data (the same
registry methods and second-order rotation terms as :func:`navsim.strapdown.ins.integrate`),
and :meth:`BodyTerms.compensated` removes the current bias estimates from them linearly,
exact to first order in the biases and for the bilinear rotation terms (derivation there);
the remainder is of order ``b x omega' T^3`` per step. The sequential loop is the
strapdown module's own (:func:`navsim.strapdown.ins.integrate_body_terms`, run with
``method="sequential"``). :func:`compensate_increments` removes constant
biases from raw increments exactly (``b dt^r / r!`` per order), the reference the tests
compare the linear form with.

References
----------
.. [1] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., Artech House, 2013: sections 14.2 (INS error propagation,
       local-navigation-frame form), 14.1.3 (closed-loop correction), 3.2.2 and 3.4
       (discrete system and process noise, Joseph form).
.. [2] Savage P.G., Strapdown Analytics, 2nd ed., 2007, ch. 12 (error equations).
.. [3] Van Loan C.F. (1978), Computing integrals involving the matrix exponential, IEEE
       TAC 23(3): the integral that the Qd series above truncates.
.. [4] Groves (2013) [1], sections 14.2.3 and 14.3.3: the antenna lever arm in the
       measurement models (:func:`lever_arm_terms`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from ...errors import ConfigError
from ...rotations import mat_nb_from_hpr, mat_to_quat, quat_from_rotvec, quat_to_mat
from ...strapdown import compiled as _compiled
from ...strapdown import ins as _ins
from ...strapdown import onestep as _one
from ...strapdown.ins import InsState
from ..base import NominalImu

__all__ = [
    "N_STATES",
    "POS",
    "VEL",
    "ATT",
    "BG",
    "BA",
    "NAV",
    "ImuNoise",
    "error_dynamics",
    "noise_density",
    "transition",
    "joseph_update",
    "correct_state",
    "lever_arm_terms",
    "compensate_increments",
    "solution_rows",
    "state_from_prior",
    "BodyTerms",
    "StepTerms",
    "body_terms",
    "ErrorStateIns",
    "AuxStateIns",
    "body_velocity_terms",
    "nis_threshold",
]

N_STATES = 15
POS, VEL, ATT, BG, BA = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15)
NAV = slice(0, 9)


# ============================================================================ noise model
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
    """

    gyro_psd: float = 0.0
    accel_psd: float = 0.0
    gyro_bias_sigma: float = 0.0
    accel_bias_sigma: float = 0.0
    gyro_bias_tau_s: float = math.inf
    accel_bias_tau_s: float = math.inf
    gyro_rrw_psd: float = 0.0
    accel_rrw_psd: float = 0.0

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


# ============================================================================ the model
def _gravity_partials(earth, lat: float, h: float) -> tuple[float, float, float, float]:
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


def error_dynamics(lat: float, h: float, velocity_n, mat_nb, specific_force_n, earth,
                   noise: ImuNoise) -> np.ndarray:
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
    F[VEL, VEL] -= _skew3(cor)
    # -f_n x psi
    F[VEL, ATT] = -_skew3((fe, fn, fu))
    F[VEL, BA] = C
    # (a): attitude
    F[ATT, ATT] = -_skew3(w_in)
    F[ATT] -= d_win
    F[ATT, BG] = C
    # (e): biases
    F[BG, BG] = -np.eye(3) / noise.gyro_bias_tau_s
    F[BA, BA] = -np.eye(3) / noise.accel_bias_tau_s
    return F


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (n, 3) arrays (np.cross is slow on small arrays)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _skew3(v) -> np.ndarray:
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def lever_arm_terms(mat_nb, omega_ib_b, lever_arm_b, omega_ie_n) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
    skew_arm = _skew3(arm_n)
    skew_ie = _skew3(w_ie)
    arm_velocity_n = turn_n - skew_ie @ arm_n
    L = np.zeros((6, N_STATES))
    L[0:3, POS] = np.eye(3)
    L[0:3, ATT] = -skew_arm  # (LA.3)
    L[3:6, VEL] = np.eye(3)
    L[3:6, ATT] = -_skew3(turn_n) + skew_ie @ skew_arm
    L[3:6, BG] = -C @ _skew3(lever)
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
class _Series:
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
    def build(cls, F: np.ndarray, Qc: np.ndarray) -> _Series:
        F2 = F @ F
        FQ = F @ Qc
        F2Q = F2 @ Qc
        A = FQ + FQ.T
        B = FQ @ F.T + 0.5 * (F2Q + F2Q.T)
        C3 = F2Q @ F.T
        C3 = 0.5 * (C3 + C3.T)
        D = 0.25 * F2Q @ F2.T
        return cls(F, 0.5 * F2, F2 @ F / 6.0, F2 @ F2 / 24.0, Qc, 0.5 * A, B / 3.0, 0.25 * C3, 0.2 * D)

    def phi(self, tau: np.ndarray, rows=slice(None)) -> np.ndarray:
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

    def qd(self, tau: np.ndarray, block=slice(None)) -> np.ndarray:
        """Qd(tau) block, shape (k, n, n)."""
        tau = tau[:, None, None]
        b = (block, block)
        return tau * (self.q1[b] + tau * (self.q2[b] + tau * (self.q3[b] + tau * (self.q4[b] + tau * self.q5[b]))))


def transition(F: np.ndarray, Qc: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """Phi(tau) (15, 15) and Qd(tau) (15, 15) by the series of the module docstring."""
    series = _Series.build(np.asarray(F, dtype=float), np.asarray(Qc, dtype=float))
    t = np.array([float(tau)])
    return series.phi(t)[0], series.qd(t)[0]


def joseph_update(P: np.ndarray, H: np.ndarray, R: np.ndarray, innovation: np.ndarray):
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


def correct_state(state: InsState, dx_nav, earth) -> InsState:
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
    return InsState(lat_new, lon_new, h - du, (v[0] - dve, v[1] - dvn, v[2] - dvu), quat, state.compensation)


def compensate_increments(dtheta_sub, dv_sub, dtheta_r, dv_r, gyro_bias, accel_bias, nav_period_s: float):
    """Remove constant biases (rad/s, m/s^2, body axes) from the IMU data of n steps.

    ``dtheta_r[:, r-1] -= b dt^r / r!`` (the r-fold integral of a constant over the
    step dt); ``dtheta_sub -= b dt / m`` for m sub-samples. Arrays may be None.
    Returns the four arrays (new arrays; inputs are not modified).
    """
    out = []
    for arr, bias in ((dtheta_sub, gyro_bias), (dv_sub, accel_bias)):
        if arr is None:
            out.append(None)
        else:
            arr = np.asarray(arr, dtype=float)
            out.append(arr - np.asarray(bias) * (nav_period_s / arr.shape[-2]))
    for arr, bias in ((dtheta_r, gyro_bias), (dv_r, accel_bias)):
        if arr is None:
            out.append(None)
        else:
            arr = np.asarray(arr, dtype=float)
            orders = arr.shape[-2]
            kern = np.array([nav_period_s**r / math.factorial(r) for r in range(1, orders + 1)])
            out.append(arr - kern[:, None] * np.asarray(bias)[None, :])
    return out[0], out[1], out[2], out[3]


def solution_rows(lat, lon, h, velocity_n, quat_nb) -> np.ndarray:
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


def state_from_prior(prior) -> InsState:
    """The INS state of a :class:`navsim.simulator.Prior`."""
    quat = mat_to_quat(mat_nb_from_hpr(prior.heading, prior.pitch, prior.roll))
    return InsState(prior.lat, prior.lon, prior.h, np.asarray(prior.velocity_n, dtype=float), quat)


# ============================================================================ body terms
@dataclass(frozen=True, slots=True)
class BodyTerms:
    """Raw body-frame strapdown terms of n navigation steps (no bias removed).

    Attributes
    ----------
    phi : (n, 3) rotation vector over each step, rad (coning algorithm).
    dv_b : (n, 3) velocity increment DeltaV + deltaV_s + second-order rotation term, m/s.
    ds_b : (n, 3) or None, body-frame double integral of the exact position forms, m.
    rule : "rectangle", "trapezoid" or None (exact forms).
    dtheta1, dv1 : (n, 3) first-order increments over each step (rad, m/s).
    dt : float, step, s.
    """

    phi: np.ndarray
    dv_b: np.ndarray
    ds_b: np.ndarray | None
    rule: str | None
    dtheta1: np.ndarray
    dv1: np.ndarray
    dt: float

    def __len__(self) -> int:
        return len(self.phi)

    def compensated(self, gyro_bias, accel_bias, start: int = 0, stop: int | None = None):
        """Terms of steps start:stop with constant biases removed, to first order in the bias.

        For a constant rate omega and force f over the step the exact terms are
        ``Phi = omega T``, ``dV = f T + (omega x f) T^2/2 + ...`` and
        ``dS = f T^2/2 + (omega x f) T^3/6 + ...``, so replacing omega, f by
        omega - b_g, f - b_a changes them by::

            dPhi = -b_g T
            ddV  = -b_a T - T (b_g x DV + DTheta x b_a) / 2                  (first-order sculling)
            ddS  = -b_a T^2/2 - T^2 (b_g x DV + DTheta x b_a) / 6

        (with ``- T b_g x b_a`` added inside the brackets: the bilinear remainder).

        (DTheta, DV the raw first-order increments). What is left is of order
        ``b x omega' T^3`` per step: for 1e-3 rad/s of bias (consumer MEMS) and a 0.01 s
        step below 1e-10 rad or m/s per step. Compensating the raw increments instead
        (:func:`compensate_increments`, then the strapdown algorithms) agrees to that order
        (tests/estimators/test_ins_only.py); this form lets one batch of body terms serve
        every bias estimate of the batch.

        Returns
        -------
        quat_body (k, 4), dv_body (k, 3), ds_body (k, 3) or None, dv_first (k, 3)
        """
        sl = slice(start, stop)
        T = self.dt
        bg = np.asarray(gyro_bias, dtype=float)
        ba = np.asarray(accel_bias, dtype=float)
        th, dv = self.dtheta1[sl], self.dv1[sl]
        phi = self.phi[sl] - bg * T
        cross = T * (_cross(np.broadcast_to(bg, dv.shape), dv) + _cross(th, np.broadcast_to(ba, th.shape)))
        cross = cross - (T * T) * np.cross(bg, ba)  # the bilinear remainder (b_g T) x (b_a T)
        dv_b = self.dv_b[sl] - ba * T - 0.5 * cross
        ds_b = None if self.ds_b is None else self.ds_b[sl] - ba * (0.5 * T * T) - (T / 6.0) * cross
        return quat_from_rotvec(phi), dv_b, ds_b, dv - ba * T


def body_terms(dtheta_sub=None, dv_sub=None, dtheta_r=None, dv_r=None, dt: float = 0.01, coning=None,
               sculling=None, position=None) -> BodyTerms:
    """The body-frame terms of :func:`navsim.strapdown.ins.integrate` for n steps.

    The same computation as the strapdown module's (registry methods chosen by
    :func:`navsim.strapdown.ins.resolve_methods`, plus the second-order rotation terms
    ``Phi x (Phi x DV) / 6`` and ``dt Phi x (Phi x DV) / 24``), but returning the rotation
    vector (not its quaternion) so that biases can be removed linearly afterwards.
    tests/estimators/test_ins_only.py checks that with zero bias
    :meth:`ErrorStateIns.advance` reproduces ``integrate`` exactly.
    """
    t = _ins.body_terms(dtheta_sub, dv_sub, dtheta_r, dv_r, dt, coning, sculling, position)
    return BodyTerms(t.rotvec_body, t.dv_body, t.ds_body, t.rule, t.dtheta_first, t.dv_first, float(dt))


@dataclass(frozen=True, slots=True)
class StepTerms:
    """:class:`BodyTerms` of ONE step as Python floats (3-tuples), for the step-wise path.

    Computed by :func:`navsim.strapdown.onestep.one_step_terms` with the operations of the
    array forms, so :meth:`ErrorStateIns.advance_body` gives the numbers of a
    :class:`BodyTerms` batch of one. ``dtheta1`` is the (1, 3) array view callers index.
    """

    phi: tuple
    dv_b: tuple
    ds_b: tuple | None
    rule: str | None
    theta1: tuple
    dv1: tuple
    dt: float

    def __len__(self) -> int:
        return 1

    @property
    def dtheta1(self) -> np.ndarray:
        """(1, 3) first-order angle increment, rad (as :attr:`BodyTerms.dtheta1`)."""
        return np.array([self.theta1])

    def compensated(self, gyro_bias, accel_bias):
        """:meth:`BodyTerms.compensated` of the step on floats (the same operations).

        Returns q(Phi) (4-tuple), dV_b, dS_b (or None), DV - b_a T (3-tuples).
        """
        T = self.dt
        g0, g1, g2 = gyro_bias
        a0, a1, a2 = accel_bias
        t0, t1, t2 = self.theta1
        v0, v1, v2 = self.dv1
        phi = self.phi
        phi = (phi[0] - g0 * T, phi[1] - g1 * T, phi[2] - g2 * T)
        TT = T * T
        # T (b_g x DV + DTheta x b_a) - T^2 b_g x b_a, component by component
        c0 = T * ((g1 * v2 - g2 * v1) + (t1 * a2 - t2 * a1)) - TT * (g1 * a2 - g2 * a1)
        c1 = T * ((g2 * v0 - g0 * v2) + (t2 * a0 - t0 * a2)) - TT * (g2 * a0 - g0 * a2)
        c2 = T * ((g0 * v1 - g1 * v0) + (t0 * a1 - t1 * a0)) - TT * (g0 * a1 - g1 * a0)
        d = self.dv_b
        dv_b = (d[0] - a0 * T - 0.5 * c0, d[1] - a1 * T - 0.5 * c1, d[2] - a2 * T - 0.5 * c2)
        ds_b = None
        if self.ds_b is not None:
            d, h2, t6 = self.ds_b, 0.5 * T * T, T / 6.0
            ds_b = (d[0] - a0 * h2 - t6 * c0, d[1] - a1 * h2 - t6 * c1, d[2] - a2 * h2 - t6 * c2)
        return _one.quat_from_rotvec(phi), dv_b, ds_b, (v0 - a0 * T, v1 - a1 * T, v2 - a2 * T)


# ============================================================================ the engine
class ErrorStateIns:
    """INS mechanisation plus a 15-state error covariance with closed-loop feedback.

    Parameters
    ----------
    context : navsim.estimators.base.Context
        Earth model and time base (``nav_period_s``).
    prior : navsim.simulator.Prior
        Initial state; its 9 x 9 covariance starts the navigation block of P, the bias
        block starts at ``diag(sigma^2)`` of ``noise``.
    noise : ImuNoise
    interval_steps : int
        Navigation steps per covariance interval (see the module notes).
    coning, sculling, position : str or None
        Strapdown methods (None: the most accurate the data allow).
    estimate_biases : bool
        False keeps the bias estimates at zero (the bias states still shape P).

    Attributes
    ----------
    state : InsState
        The corrected INS state at the last processed step.
    gyro_bias, accel_bias : ndarray (3,)
        Current bias estimates (body axes), rad/s and m/s^2.
    steps : int
        Navigation steps processed since the reset.
    diverged : bool
        Set when the covariance lost symmetry/positive definiteness or became non-finite
        (it is then repaired: symmetrised, eigenvalues floored), or the state became
        non-finite.
    """

    # The Kalman arithmetic of a measurement update, (P, H, R, innovation) -> (dx, P_new,
    # nis); replaceable per instance (navsim.estimators.filterpy_based hands it to filterpy).
    kalman_update = staticmethod(joseph_update)

    def __init__(self, context, prior, noise: ImuNoise, *, interval_steps: int = 100, coning=None,
                 sculling=None, position=None, estimate_biases: bool = True) -> None:
        if int(interval_steps) != interval_steps or interval_steps < 1:
            raise ConfigError("interval_steps", "a positive integer number of navigation steps", interval_steps)
        self.earth = context.earth
        self.dt = float(context.nav_period_s)
        self.noise = noise
        self.interval_steps = int(interval_steps)
        self.methods = dict(coning=coning, sculling=sculling, position=position)
        self._resolved: dict = {}  # input shapes -> resolved (coning, sculling, position)
        self._kernel = None  # (compiled one-step kernel, Earth constants, step constants, dummy), on first use
        self._vec = None  # (13,) state array of the compiled one-step path, when it holds the state
        self.estimate_biases = bool(estimate_biases)
        self.Qc = noise_density(noise)
        self.state = state_from_prior(prior)
        self.gyro_bias = np.zeros(3)
        self.accel_bias = np.zeros(3)
        P = np.zeros((N_STATES, N_STATES))
        P[NAV, NAV] = np.asarray(prior.covariance, dtype=float)
        P[BG, BG] = np.eye(3) * noise.gyro_bias_sigma**2
        P[BA, BA] = np.eye(3) * noise.accel_bias_sigma**2
        self.steps = 0
        self.diverged = False
        g = self.earth.gravity_n(self.state.lat, self.state.h)
        self._f_n = -np.asarray(g, dtype=float)  # at rest until measured
        self._f_sum = np.zeros(3)
        self._f_count = 0
        self._start_interval(P)

    # -- the INS state ----------------------------------------------------------------
    @property
    def state(self) -> InsState:
        """The corrected INS state at the last processed step."""
        if self._state is None:  # built on demand after steps of the one-step path
            lat, lon, h, velocity, quat, compensation = self._flat
            self._state = InsState(lat, lon, h, np.array(velocity), np.array(quat), compensation)
        return self._state

    @state.setter
    def state(self, value: InsState) -> None:
        self._state = value
        self._flat = None
        self._vec = None

    def _floats(self) -> tuple:
        """The state as Python floats: (lat, lon, h, velocity (3,), quat (4,), compensation)."""
        if self._flat is None:
            st = self._state
            self._flat = (st.lat, st.lon, st.h, st.velocity_n.tolist(), st.quat_nb.tolist(), st.compensation)
        return self._flat

    # -- covariance intervals ----------------------------------------------------------
    def _start_interval(self, P: np.ndarray) -> None:
        """Begin a covariance interval at the current step with covariance P."""
        if self._f_count:  # mean specific force of the interval that ends here
            self._f_n = np.asarray(self._f_sum) / (self._f_count * self.dt)
        self._f_sum = np.zeros(3)
        self._f_count = 0
        self._P0 = P
        self._pending = None
        self._j = 0  # steps into the interval
        st = self.state
        F = error_dynamics(st.lat, st.h, st.velocity_n, quat_to_mat(st.quat_nb), self._f_n, self.earth, self.noise)
        self._series = _Series.build(F, self.Qc)
        self._poly = None  # navigation-block polynomial of P(tau), built on first use
        self._nav_block = None  # P9 at every step of the interval, for the one-step path

    def _full_covariance(self, j: int) -> np.ndarray:
        """P(tau = j dt) of the current interval (15, 15), symmetrised and guarded."""
        tau = np.array([j * self.dt])
        phi = self._series.phi(tau)[0]
        P = phi @ self._P0 @ phi.T + self._series.qd(tau)[0]  # P = F P F^T + Q
        return self._guard(0.5 * (P + P.T))

    def _guard(self, P: np.ndarray) -> np.ndarray:
        d = np.diag(P)
        if np.all(np.isfinite(P)) and np.all(d >= 0.0):
            return P
        self.diverged = True
        if not np.all(np.isfinite(P)):
            return np.diag(np.where(np.isfinite(d) & (d > 0), d, 1e6))
        w, v = np.linalg.eigh(P)
        return (v * np.maximum(w, 1e-12 * max(float(w.max()), 1e-300))) @ v.T

    @property
    def dynamics(self) -> np.ndarray:
        """F (15, 15) of the current covariance interval (frozen at its start)."""
        return self._series.F

    @property
    def covariance(self) -> np.ndarray:
        """The full 15 x 15 covariance at the last processed step."""
        if self._pending is not None:
            return self._pending
        return self._P0 if self._j == 0 else self._full_covariance(self._j)

    # -- propagation -------------------------------------------------------------------
    def prepare(self, dtheta_sub=None, dv_sub=None, dtheta_r=None, dv_r=None) -> BodyTerms | StepTerms:
        """Raw (uncompensated) body-frame strapdown terms of n steps, for :meth:`advance_body`.

        One step with multiple integrals gives :class:`StepTerms` when the resolved methods
        have a float form (:mod:`navsim.strapdown.onestep`): the same numbers at a
        fraction of the array forms' fixed cost.
        """
        if dtheta_r is not None and dv_r is not None and len(dtheta_r) == 1:
            return self.prepare_step(None if dtheta_sub is None else dtheta_sub[0],
                                     None if dv_sub is None else dv_sub[0], dtheta_r[0], dv_r[0])
        return body_terms(dtheta_sub, dv_sub, dtheta_r, dv_r, self.dt, **self.methods)

    def prepare_step(self, dtheta_sub, dv_sub, dtheta_r, dv_r) -> BodyTerms | StepTerms:
        """:meth:`prepare` of one step from its (m, 3) / (R, 3) arrays (a
        :class:`~navsim.estimators.base.Measurement`'s fields)."""
        key = (None if dtheta_sub is None else dtheta_sub.shape, None if dv_sub is None else dv_sub.shape,
               dtheta_r.shape, dv_r.shape)
        methods = self._resolved.get(key)
        if methods is None:
            arrays = [None if a is None else np.asarray(a)[None] for a in (dtheta_sub, dv_sub, dtheta_r, dv_r)]
            methods = self._resolved[key] = _ins.resolve_methods(self.methods["coning"], self.methods["sculling"],
                                                                 self.methods["position"], *arrays)
        terms = _one.one_step_terms(methods, dtheta_r.tolist(), dv_r.tolist(),
                                    None if dtheta_sub is None else dtheta_sub.tolist(),
                                    None if dv_sub is None else dv_sub.tolist(), self.dt)
        if terms is None:
            return body_terms(*(None if a is None else np.asarray(a)[None] for a in (dtheta_sub, dv_sub, dtheta_r, dv_r)),
                              self.dt, **self.methods)
        return StepTerms(*terms[:3], None, *terms[3:], self.dt)

    def advance_step(self, dtheta_sub, dv_sub, dtheta_r, dv_r) -> tuple[np.ndarray, np.ndarray]:
        """``advance_body(prepare_step(...))`` of one step from a
        :class:`~navsim.estimators.base.Measurement`'s arrays: rows (1, 9), covariance (1, 9, 9).

        With numba and the methods of :data:`navsim.strapdown.onestep.ONE_STEP_METHODS`
        (the default with multiple integrals of order >= 4) the whole step (strapdown terms,
        bias removal, the INS step, the solution row and the specific force) is one
        compiled call, :func:`navsim.strapdown.compiled.one_step`: the operations of the
        float path in the same order, so the same numbers; otherwise the float path.
        """
        key = (None if dtheta_sub is None else dtheta_sub.shape, None if dv_sub is None else dv_sub.shape,
               dtheta_r.shape, dv_r.shape)
        methods = self._resolved.get(key)
        if (methods is None or (dtheta_sub is None) != (dv_sub is None) or tuple(methods) not in _one.ONE_STEP_METHODS
                or key[2][0] < 4 or key[3][0] < 4 or not _compiled.available()):
            return self.advance_body(self.prepare_step(dtheta_sub, dv_sub, dtheta_r, dv_r))
        if self._pending is not None:
            self._start_interval(self._pending)
        kern = self._kernel
        if kern is None:
            kern = self._kernel = (_compiled.step_kernel(), _compiled.earth_constants(self.earth),
                                   _compiled.step_constants(self.dt), np.zeros((1, 3)))
        vec = self._vec
        if vec is None:
            lat, lon, h, velocity, quat, compensation = self._floats()
            vec = np.array([lat, lon, h, *compensation, *velocity, *quat], dtype=float)
        out = np.empty(12)
        use_sub = dtheta_sub is not None
        kern[0](kern[1], kern[2], dtheta_r, dv_r, dtheta_sub if use_sub else kern[3], dv_sub if use_sub else kern[3],
                use_sub, self.gyro_bias, self.accel_bias, vec, self.dt, out)
        v = vec.tolist()
        self._flat = (v[0], v[1], v[2], v[6:9], v[9:13], (v[3], v[4], v[5]))
        self._state = None
        self._vec = vec
        if not all(map(math.isfinite, v[:3] + v[6:9])):
            self._vec = None
            self.state  # noqa: B018  (validates: the error of the array path)
        f = out[9:].tolist()
        fs = self._f_sum if isinstance(self._f_sum, list) else self._f_sum.tolist()
        self._f_sum = [fs[0] + f[0], fs[1] + f[1], fs[2] + f[2]]
        self._f_count += 1
        cov = self._step_covariance()
        self._after_steps(1)
        return out[None, :9], cov

    def _after_steps(self, n: int) -> None:
        """Hook of subclasses whose own means follow the INS steps (called by the compiled
        one-step path; their ``advance_body`` calls it too)."""

    def advance(self, dtheta_sub=None, dv_sub=None, dtheta_r=None, dv_r=None) -> tuple[np.ndarray, np.ndarray]:
        """Process n navigation steps of IMU data (arrays as in :class:`MeasurementBatch`).

        Returns
        -------
        solution : ndarray (n, 9)
            ``[lat, lon, h, vE, vN, vU, heading, pitch, roll]`` at each step end.
        covariance : ndarray (n, 9, 9)
            Navigation block of P at each step end.
        """
        return self.advance_body(self.prepare(dtheta_sub, dv_sub, dtheta_r, dv_r))

    def advance_body(self, body: BodyTerms, start: int = 0, stop: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`advance` over steps ``start:stop`` of precomputed :class:`BodyTerms`
        (compute them once per batch with :meth:`prepare`; the current bias estimates are
        applied here). A :class:`StepTerms` (one step) takes the float path of
        :meth:`_advance_step`, with the same operations."""
        if isinstance(body, StepTerms):
            if start != 0 or stop not in (None, 1):
                raise ConfigError("advance_body", "steps 0:1 of a one-step StepTerms", (start, stop))
            return self._advance_step(body)
        if self._pending is not None:
            self._start_interval(self._pending)
        quat_b, dv_b, ds_b, dv_first = body.compensated(self.gyro_bias, self.accel_bias, start, stop)
        # the loop, explicitly: keeps stepping and batch bit-for-bit equal (compiled when
        # numba is installed: the same loop bit for bit, navsim.strapdown.compiled)
        sol = _ins.integrate_body_terms(self.state, quat_b, dv_b, ds_b, body.rule, self.dt, self.earth,
                                        method="compiled" if _compiled.available() else "sequential")
        n = len(sol) - 1
        rows = solution_rows(sol.lat[1:], sol.lon[1:], sol.h[1:], sol.velocity_n[1:], sol.quat_nb[1:])
        # specific force in ENU per step, C(k+1) dV_k / dt (for F of the next interval)
        q = sol.quat_nb[1:]
        t2 = 2.0 * _cross(q[:, 1:], dv_first)  # C dv = dv + q0 t + q_v x t, t = 2 q_v x dv
        f_dv = dv_first + q[:, :1] * t2 + _cross(q[:, 1:], t2)
        cov = np.empty((n, 9, 9))
        i = 0
        while i < n:
            take = min(self.interval_steps - self._j, n - i)
            tau = (self._j + 1 + np.arange(take)) * self.dt
            if self._poly is None:
                self._poly = self._series.nav_polynomial(self._P0)
            powers = tau[:, None] ** np.arange(9)  # P9(tau) = sum_p tau^p coef_p
            cov[i:i + take] = (powers @ self._poly).reshape(take, 9, 9)
            self._f_sum = self._f_sum + f_dv[i:i + take].sum(axis=0)
            self._f_count += take
            self._j += take
            i += take
            if self._j == self.interval_steps:
                # the interval ends: its end covariance starts the next one (state there);
                # at the end of the data the start waits for the next call (an update
                # may come first and restart the interval anyway)
                P_end = self._full_covariance(self._j)
                if i < n:
                    self.state = sol.state(i)
                    self._start_interval(P_end)
                else:
                    self._pending = P_end
        self.state = sol.final
        self.steps += n
        if not (math.isfinite(self.state.lat) and np.all(np.isfinite(self.state.velocity_n))):
            self.diverged = True
        return rows, cov

    def _advance_step(self, body: StepTerms) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`advance_body` of one step on Python floats: every operation of the array
        path for a batch of one, in the same order (so the same numbers), without its
        per-call array set-up; the :class:`InsState` is built only when read."""
        if self._pending is not None:
            self._start_interval(self._pending)
        quat_b, dv_b, ds_b, dv_first = body.compensated(self.gyro_bias.tolist(), self.accel_bias.tolist())
        lat, lon, h, velocity, quat, compensation = self._floats()
        pos, vel, quats, compensation = _ins.sequential_rows(
            lat, lon, h, velocity, quat, compensation, (quat_b,), (dv_b,), None if ds_b is None else (ds_b,),
            body.rule, self.dt, self.earth)
        (lat, lon, h), velocity, quat = pos[1], vel[1], quats[1]
        self._flat = (lat, lon, h, velocity, quat, compensation)
        self._state = None
        self._vec = None
        ve, vn, vu = velocity
        if not (math.isfinite(lat) and math.isfinite(lon) and math.isfinite(h) and math.isfinite(ve)
                and math.isfinite(vn) and math.isfinite(vu)):
            self.state  # noqa: B018  (validates: the error of the array path)
        q0, q1, q2, q3 = quat
        c01 = 2.0 * (q1 * q2 - q0 * q3)
        c11 = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
        c20 = 2.0 * (q1 * q3 - q0 * q2)
        c21 = 2.0 * (q2 * q3 + q0 * q1)
        c22 = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
        rows = np.array([[lat, lon, h, ve, vn, vu, math.atan2(c01, c11), math.asin(min(max(c21, -1.0), 1.0)),
                          math.atan2(-c20, c22)]])
        # specific force in ENU, C(k+1) dV_k / dt (see advance_body)
        d0, d1, d2 = dv_first
        u0, u1, u2 = 2.0 * (q2 * d2 - q3 * d1), 2.0 * (q3 * d0 - q1 * d2), 2.0 * (q1 * d1 - q2 * d0)
        fs = self._f_sum if isinstance(self._f_sum, list) else self._f_sum.tolist()
        self._f_sum = [fs[0] + (d0 + q0 * u0 + (q2 * u2 - q3 * u1)), fs[1] + (d1 + q0 * u1 + (q3 * u0 - q1 * u2)),
                       fs[2] + (d2 + q0 * u2 + (q1 * u1 - q2 * u0))]
        self._f_count += 1
        return rows, self._step_covariance()

    def _step_covariance(self) -> np.ndarray:
        """The navigation block (1, 9, 9) of P after one more step of the interval (one-step paths)."""
        if self._nav_block is None:
            # P9(tau) = (tau^p)_p @ coefficients at every step of the interval in one product,
            # as advance_body does for the steps of a batch
            if self._poly is None:
                self._poly = self._series.nav_polynomial(self._P0)
            tau = (1 + np.arange(self.interval_steps)) * self.dt
            self._nav_block = ((tau[:, None] ** np.arange(9)) @ self._poly).reshape(-1, 1, 9, 9)
        cov = self._nav_block[self._j].copy()
        self._j += 1
        if self._j == self.interval_steps:
            self._pending = self._full_covariance(self._j)
        self.steps += 1
        return cov

    # -- measurement update --------------------------------------------------------------
    def _feed_back(self, dx: np.ndarray) -> None:
        """Closed-loop feedback of the 15 INS error states of dx (in place: the bias
        entries are zeroed when biases are not estimated)."""
        if not self.estimate_biases:
            dx[BG] = 0.0
            dx[BA] = 0.0
        self.state = correct_state(self.state, dx[NAV], self.earth)
        self.gyro_bias = self.gyro_bias + dx[BG]
        self.accel_bias = self.accel_bias + dx[BA]

    def update(self, H: np.ndarray, R: np.ndarray, innovation: np.ndarray) -> tuple[float, np.ndarray]:
        """Closed-loop Kalman update at the current step.

        Parameters
        ----------
        H : (m, 15). R : (m, m). innovation : (m,) measurement minus its prediction from
        the current (corrected) INS state, i.e. ``y = H x + v`` for the error state x.

        Returns
        -------
        nis : float
        dx : (15,) the estimated error that was fed back.

        The covariance interval restarts here with the updated covariance and the
        corrected state.
        """
        P = self.covariance
        try:
            dx, P_new, nis = self.kalman_update(P, H, R, innovation)
        except np.linalg.LinAlgError:
            self.diverged = True
            self._start_interval(P)
            return math.nan, np.zeros(N_STATES)
        if not np.all(np.isfinite(dx)):
            self.diverged = True
            self._start_interval(P)
            return math.nan, np.zeros(N_STATES)
        self._feed_back(dx)
        self._start_interval(self._guard(P_new))
        return nis, dx

    def current_row(self) -> np.ndarray:
        """The solution row (9,) of the current state."""
        st = self.state
        return solution_rows(np.array([st.lat]), np.array([st.lon]), np.array([st.h]),
                             st.velocity_n[None], st.quat_nb[None])[0]


def body_velocity_terms(mat_nb, velocity_n) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame velocity ``v_b = C^T v_n`` and its partials over the error state.

    From ``C_est = (I + [psi x]) C`` and ``v_est = v + dv``::

        v_b(est) - v_b(true) = C^T dv + C^T [v_n x] psi                          (OD.6)

    (first order; ``-[psi x] v = [v x] psi``). Used by the wheel-odometer forward-speed
    update and the non-holonomic constraint (zero lateral and vertical body velocity of
    a vehicle on its wheels); tests/estimators/test_odometer_aiding.py checks it against
    finite differences through :func:`correct_state`.

    Returns
    -------
    velocity_b : (3,) m/s.  J : (3, 15) rows x (right), y (forward), z (up).
    """
    C = np.asarray(mat_nb, dtype=float)
    v = np.asarray(velocity_n, dtype=float)
    J = np.zeros((3, N_STATES))
    J[:, VEL] = C.T
    J[:, ATT] = C.T @ _skew3(v)  # (OD.6)
    return C.T @ v, J


class AuxBlocksIns(ErrorStateIns):
    """:class:`ErrorStateIns` plus ``n_aux`` auxiliary error states that neither drive nor
    are driven by the INS errors (receiver clock, atmospheric delays, odometer scale
    factor, the slowly varying error of a GNSS fix).

    F and Qc are then block diagonal and over a covariance interval ``Phi = diag(Phi_15,
    Phi_a)``: the engine keeps propagating its 15 x 15 block untouched, and this class
    carries the auxiliary block and the cross-covariance from the interval start,
    ``P_na(tau) = Phi_15(tau) P_na Phi_a(tau)^T`` and ``P_aa(tau) = Phi_a P_aa Phi_a^T +
    Qd_a``, with the engine's own ``Phi_15`` (nothing of its series is duplicated). The
    full matrix is assembled at updates only. Subclasses give ``_aux_transition(tau) ->
    (Phi_a, Qd_a)`` (full n_aux-square matrices) and may carry their estimates over an
    interval in ``_carry_means``.
    """

    def _init_aux(self, variances) -> None:
        """Set up ``n_aux`` states with the given initial variances (before ``super().__init__``)."""
        self.n_aux = len(variances)
        self.n_states = N_STATES + self.n_aux
        self.P_na = np.zeros((N_STATES, self.n_aux))
        self.P_aa = np.diag(variances) if self.n_aux else np.zeros((0, 0))
        self._fresh = True  # the next interval start carries no auxiliary propagation

    def _aux_transition(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def _aux_blocks(self) -> tuple[np.ndarray, np.ndarray]:
        """P_na and P_aa at the current step of the interval."""
        tau = self._j * self.dt
        if tau == 0.0:
            return self.P_na, self.P_aa
        phi = self._series.phi(np.array([tau]))[0]
        phi_a, q_a = self._aux_transition(tau)
        return phi @ self.P_na @ phi_a.T, phi_a @ self.P_aa @ phi_a.T + q_a

    def _carry_means(self) -> None:
        """Carry the auxiliary estimates to the current step (default: they are constant)."""

    def _start_interval(self, P: np.ndarray) -> None:
        if self.n_aux and not self._fresh:
            # the engine restarts an interval on its own: carry the auxiliary blocks to here
            self._carry_means()
            self.P_na, self.P_aa = self._aux_blocks()
        self._fresh = False
        super()._start_interval(P)

    def _restart_after_update(self, P_new: np.ndarray) -> None:
        """Keep the updated auxiliary blocks and restart the interval from P_new."""
        self.P_na, self.P_aa = P_new[:N_STATES, N_STATES:].copy(), P_new[N_STATES:, N_STATES:].copy()
        self._fresh = True
        self._start_interval(P_new[:N_STATES, :N_STATES].copy())

    def full_covariance(self) -> np.ndarray:
        """The (15 + n_aux)-square covariance at the current step."""
        P = self.covariance
        if not self.n_aux:
            return P
        P_na, P_aa = self._aux_blocks()
        full = np.empty((self.n_states, self.n_states))
        full[:N_STATES, :N_STATES] = P
        full[:N_STATES, N_STATES:] = P_na
        full[N_STATES:, :N_STATES] = P_na.T
        full[N_STATES:, N_STATES:] = P_aa
        return full


class AuxStateIns(AuxBlocksIns):
    """:class:`ErrorStateIns` plus ``n_aux`` auxiliary error states (random walks or
    first-order Gauss-Markov processes).

    The auxiliary states (e.g. the wheel-odometer scale factor, the slowly varying error
    of a GNSS fix) are independent of each other; the interval bookkeeping is that of
    :class:`AuxBlocksIns`. Every :meth:`update` is made on the full state; a 15-column H
    is padded with zeros.

    Per auxiliary state i with correlation time ``T_i`` and driving PSD ``q_i``
    (``x_i' = -x_i / T_i + w_i``)::

        phi_i(tau) = exp(-tau / T_i),   Qd_i(tau) = q_i T_i / 2 (1 - exp(-2 tau / T_i))   (AX.1)

    (the exact discretisation; stationary variance ``q_i T_i / 2``, so ``q_i = 2 sigma_i^2
    / T_i``), and for ``T_i = inf`` (the default) the random walk ``phi_i = 1``, ``Qd_i =
    q_i tau``. The estimate of a Gauss-Markov state decays with the same ``phi_i``
    between updates (the conditional mean of the process; :meth:`aux_now`). Without
    ``aux_tau_s`` (or with every ``T_i`` infinite) the code is the random-walk engine of
    before, number for number.

    Parameters
    ----------
    aux_variance : (n_aux,) initial variances. aux_psd : (n_aux,) driving PSDs (per
    second). aux_tau_s : (n_aux,) correlation times, s (``inf``: random walk), or None
    (all random walks). Other parameters as :class:`ErrorStateIns`.

    Attributes
    ----------
    aux : ndarray (n_aux,)
        The estimates of the auxiliary quantities at the start of the current covariance
        interval (:meth:`aux_now` at the current step); the error state is ``aux - truth``
        and the feedback subtracts the estimated error.
    """

    def __init__(self, context, prior, noise: ImuNoise, *, aux_variance, aux_psd, aux_tau_s=None, **kw):
        var = np.asarray(aux_variance, dtype=float).reshape(-1)
        self.aux_psd = np.asarray(aux_psd, dtype=float).reshape(-1)
        if len(self.aux_psd) != len(var):
            raise ConfigError("aux_psd", f"{len(var)} driving PSDs", len(self.aux_psd))
        tau = np.full(len(var), math.inf) if aux_tau_s is None else np.asarray(aux_tau_s, dtype=float).reshape(-1)
        if len(tau) != len(var) or not np.all(tau > 0.0):
            raise ConfigError("aux_tau_s", f"{len(var)} positive correlation times, s (inf: random walk)",
                              aux_tau_s)
        self.aux_tau_s = tau
        self._markov = bool(np.any(np.isfinite(tau)))
        self.aux = np.zeros(len(var))
        self._init_aux(var)
        super().__init__(context, prior, noise, **kw)

    def _aux_decay(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """(phi_i, Qd_i) per auxiliary state over tau seconds (AX.1)."""
        T = self.aux_tau_s
        finite = np.isfinite(T)
        Tf = np.where(finite, T, 1.0)
        phi = np.where(finite, np.exp(-tau / Tf), 1.0)
        qd = np.where(finite, 0.5 * self.aux_psd * Tf * -np.expm1(-2.0 * tau / Tf), self.aux_psd * tau)
        return phi, qd

    def _aux_transition(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """Diagonal (Phi_a, Qd_a) over tau seconds (AX.1)."""
        phi, qd = self._aux_decay(tau)
        return np.diag(phi), np.diag(qd)

    def aux_now(self) -> np.ndarray:
        """The auxiliary estimates at the current step (Gauss-Markov ones decayed)."""
        if not self._markov or self._j == 0:
            return self.aux.copy()
        return self.aux * self._aux_decay(self._j * self.dt)[0]

    def _carry_means(self) -> None:
        if self._markov:
            self.aux = self.aux_now()

    def update(self, H: np.ndarray, R: np.ndarray, innovation: np.ndarray) -> tuple[float, np.ndarray]:
        """Closed-loop update on the full state (H (m, 15) or (m, 15 + n_aux))."""
        H = np.asarray(H, dtype=float)
        if H.shape[1] == N_STATES:
            H = np.concatenate([H, np.zeros((H.shape[0], self.n_aux))], axis=1)
        P = self.full_covariance()
        try:
            dx, P_new, nis = self.kalman_update(P, H, R, innovation)
        except np.linalg.LinAlgError:
            self.diverged = True
            return math.nan, np.zeros(self.n_states)
        if not np.all(np.isfinite(dx)):
            self.diverged = True
            return math.nan, np.zeros(self.n_states)
        self._feed_back(dx)
        self.aux = (self.aux_now() if self._markov else self.aux) - dx[N_STATES:]
        self._restart_after_update(self._guard(P_new))
        return nis, dx


def nis_threshold(dof: int, probability: float = 1e-6) -> float:
    """Chi-square quantile exceeded with ``probability`` (innovation-test helper)."""
    return float(chi2.isf(probability, dof))
