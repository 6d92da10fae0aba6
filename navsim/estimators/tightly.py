"""Tightly coupled INS/GNSS filters on pseudoranges and pseudorange rates.

:class:`TightlyCoupledEkf` and :class:`TightlyCoupledUkf` are closed-loop error-state
filters around navsim's strapdown INS (:func:`navsim.strapdown.ins.integrate` on
bias-compensated increments). They share the 15-state INS error model and engine of
:mod:`navsim.estimators._inserror` (F, Qc, the per-interval series transition, the
feedback) and append two receiver-clock states:

    x = [dE dN dU, dvE dvN dvU, psiE psiN psiU, eg (3), ea (3), dcb, dcd]   (17,)

``dcb`` (m) and ``dcd`` (m/s) are the clock bias and drift errors, estimate minus truth,
with the two-state model (Brown & Hwang 9.3)

    dcb' = dcd + w_f,   dcd' = w_g,   PSDs S_f = c^2 h0/2, S_g = 2 pi^2 c^2 h-2     (TC.1)

Receiver clock: when ``context.gnss.clock_modelled`` is False (seed 003's case, the clock
compensated), the states stay (option ``clock="auto"``) with a tiny prior (1 mm, 0.1 mm/s)
and no process noise, so they absorb nothing and cost one 17 x 17 instead of a 15 x 15
covariance; ``clock="none"`` drops them (15 states).

Atmosphere: when ``context.gnss.atmosphere_modelled`` is True (an uncorrected
single-frequency receiver; option ``atmosphere="auto"``), two more states follow:

    x = [..., dI, dT]   (19,; 17 with clock="none")

the errors (estimate minus truth) of the zenith ionospheric delay ``I_z`` and of the
sea-level zenith tropospheric delay ``T_z``. The filter starts from the a-priori zenith
delays of the context (standard-model values a receiver applies, never the simulator's)
with their 1-sigma as prior, and models the residual from the a-priori value as a
first-order Gauss-Markov process with stationary sigma equal to that prior sigma:

    d' = -d / tau + w,   Phi = exp(-t / tau),   Qd = sigma^2 (1 - exp(-2 t / tau))    (TC.5)

(options ``ionosphere_tau_s`` = 1800 s, ``troposphere_tau_s`` = 3600 s; ``math.inf``
makes them random constants). The time constants are a modelling choice, not published
figures: a vertical ionospheric delay changes on the scale of half an hour to hours
(diurnal cycle), the troposphere more slowly; the simulator's delays are constant in an
episode, and the Gauss-Markov only keeps the filter from locking onto a stale value.
The predicted pseudorange gets the slant delays (the pseudorange rate none: the
simulator, like most receivers' Doppler models, leaves the atmospheric rates of
< 1 cm/s out)::

    rho_i += I_z F(E_i) + T_z exp(-h / H_T) m(E_i)                                  (TC.6)
    F(E) = 1 / sqrt(1 - (R cos E / (R + h_I))^2)        thin shell (Misra & Enge ch. 5)
    m(E) = 1.001 / sqrt(0.002001 + sin^2 E)             RTCA DO-229D A.4.2.4

with ``E_i`` the elevation above the geodetic horizon of the estimated position, R the
Earth model's equatorial radius, ``h_I`` and ``H_T`` the context's shell and scale
heights. Partial derivatives (columns of the pseudorange rows)::

    d rho_i / d I_z = F(E_i),   d rho_i / d T_z = exp(-h / H_T) m(E_i)
    d rho_i / d p_n += (I_z dF/ds + T_z exp(-h/H_T) dm/ds) ds_i/dp_n
                       - [0, 0, T_z exp(-h/H_T) m(E_i) / H_T]                        (TC.7)
    dF/ds = -k^2 s F^3 (k = R / (R + h_I)),   dm/ds = -s m^3 / 1.001^2,   s = sin E
    ds_i/dp_n = -C_en (U - u_i s_i) / |r_sat_i - r_e| + [u_i . E / (R_E + h),
                u_i . N / (R_N + h), 0]

(U, N, E the ECEF unit vectors of the local axes: the first term is the turn of the line
of sight, the second the tilt of the local vertical; both are ~1e-5 m/m and kept for an
exact Jacobian). The functions are written here from the published formulas; the
truth-side :class:`navsim.sensors.gnss.GnssErrorModel` is not read by the filter. When
the context says the atmosphere is absent, or ``atmosphere="none"``, the filter is the
17-state one above, number for number.

Observables of every valid satellite i at a GNSS epoch (seed 003 eqs. (2), (3), with the
same-instant geometry of :mod:`navsim.sensors.gnss`)::

    rho_i    = |r_sat_i - r_e| + cb                                        (TC.2)
    rhodot_i = u_i . (v_sat_i - v_e) + cd,   u_i = (r_sat_i - r_e) / |.|   (TC.3)

with ``r_e`` the ECEF position of the INS and ``v_e = C_en^T v_n``. Jacobians with
respect to the estimated position (metres along ENU), velocity and clock::

    d rho_i / d p_n    = -C_en u_i              d rho_i / d cb = 1
    d rhodot_i / d v_n = -C_en u_i              d rhodot_i / d cd = 1
    d rhodot_i / d p_n = -C_en (rel_i - u_i (u_i . rel_i)) / rho_i
                         - u_i . [dC_en^T/dN, dC_en^T/dE, 0] v_n               (TC.4)

(``rel_i = v_sat_i - v_e``; the last term is the turn of the ENU axes with position,
~v/R). The filter's innovation is ``y = z - h(INS)`` and, the error being estimate minus
truth, its measurement matrix is ``H = -dh/dx``.

Antenna lever arm (``context.gnss.lever_arm_b_m`` = l in body axes; option
``lever_arm``): the observables are the antenna's, so (TC.2)-(TC.3) are evaluated at

    r_a = r_e + C_en^T C l,   v_a = C_en^T (v_n + C (omega x l) - omega_ie x C l)   (TC.8)

(C the INS attitude, omega the bias-compensated body rate, its mean over the epoch's
navigation step) and, with ``L`` of :func:`navsim.estimators._inserror.lever_arm_terms`
(LA.3), the Jacobian by the chain rule through the antenna's position and velocity:

    J[:, 6:15] = J_p L_pos + J_v L_vel   (attitude and bias columns)               (TC.9)

(J_p, J_v: the position and velocity columns of (TC.4) at the antenna, J_p without the
turn of the ENU axes: an attitude error moves the antenna, not the INS). This adds the
attitude columns (the antenna moves with the attitude error, ``-[C l x] psi``; its
velocity by ``-[C (omega x l) x] psi + [omega_ie x][C l x] psi``) and the gyro-bias
columns (``-C [l x] eg``). The atmospheric delays are evaluated at the antenna too
(height ``h + (C l)_U``; their attitude partials likewise without the tilt of the local
vertical). The UKF evaluates (TC.8) exactly at each hypothesis (attitude
``exp(-[psi x]) C``, rate ``omega - eg``). With a zero lever arm (or ``lever_arm="none"``)
the code path is the one without these terms, number for number.

EKF
    Joseph-form update (:func:`navsim.estimators._inserror.joseph_update`), symmetrised,
    eigenvalue-floored by the engine's guard.
UKF (error state, own sigma points)
    The error dynamics are linear, and the unscented transform of a linear map is exact,
    so the time update is the same Phi P Phi^T + Qd as the EKF's (computing it through
    35 sigma points would only cost time). The measurement update pushes the scaled
    sigma points (alpha, beta, kappa; defaults 1, 2, 0: spread sqrt(n) sigma, no
    negative weight) of the error state through the exact nonlinear (TC.2)-(TC.3)
    evaluated at ``INS minus error`` (latitude, longitude, height, ENU axes and all),
    then ``K = Pxz Pzz^-1``, ``P = P - K Pzz K^T`` (symmetrised, guarded; the Joseph
    form needs an H, which the UKF does not have). The square root is a Cholesky factor
    of the states with non-zero variance (the bias states of an IMU without bias are
    exactly zero); when it fails, jitter (1e-12, 1e-9, 1e-6 of the largest variance) is
    added, and as a last resort an eigen-decomposition with clipped eigenvalues is used.
    The count is in ``Estimate.extra["cholesky_fallbacks"]``.

Covariance between epochs: the engine propagates P once per covariance interval
(``covariance_period_s``, default 1 s, restarted at each update) by the series transition
and evaluates it at every step from the interval start (so the reported covariance is
never stale, and ``step`` and ``step_batch`` agree). The clock error model (TC.1) and the
INS error model do not act on each other, so F and Qc are block diagonal: the engine's
15 x 15 block is propagated as for any INS, and the clock block and the cross-covariance
ride beside it with ``P_nc(tau) = Phi_15(tau) P_nc Phi_c(tau)^T`` (the 17 x 17 matrix is
assembled only at updates); the atmospheric states join the clock in that auxiliary
block (TC.5 acts on neither the INS nor the clock). The strapdown body terms are computed once per batch and the
INS runs over all the steps between epochs in one sequential pass in ``step_batch``.

Barometric height aiding (``context.baro``; option ``baro="auto"``, EKF only): one more
state after the others, the error db (estimate minus truth) of the altimeter bias b, a
first-order Gauss-Markov process with the nominal sigma and correlation time
(:class:`~navsim.types.NominalBaro`; Phi = exp(-t/tau), Qd = sigma^2 (1 - exp(-2t/tau)),
its estimate decaying with Phi between updates). Every ``baro_period_s`` (default 1 s,
whole navigation steps at global step multiples) the pressure altitude z gives::

    y = h_ins - z + b_est = dU + db - v,   H = [e_U | e_b],   R = sigma_n^2 + q^2 / 12   (TC.10)

``baro="none"``, no barometer in the context, or the UKF: the filter without it, number
for number.

Divergence: ``extra["diverged"]`` is set when the engine had to repair P (non-finite,
negative variance), an update failed, or NIS/dof exceeded ``nis_divergence`` at
``divergence_epochs`` consecutive epochs. Nothing raises.

References
----------
.. [1] Sokolov S.V., Vdovichenko S.S. (2012), seed 003, eqs. (2), (3), (6).
.. [2] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., 2013, sections 14.3.3 (tightly coupled measurement model,
       eqs. 14.126-14.129, with the lever arm), 14.2.3 and 9.4.2 (clock states).
.. [3] Brown R.G., Hwang P.Y.C., Introduction to Random Signals and Applied Kalman
       Filtering, 4th ed., 2012, section 9.3 (two-state clock model).
.. [5] Misra P., Enge P., Global Positioning System: Signals, Measurements and
       Performance, 2nd ed., 2006, chapter 5 (thin-shell obliquity factor, 350 km).
.. [6] RTCA DO-229D (2006), Appendix A.4.2.4 (tropospheric model and mapping function,
       sigma_TVE = 0.12 m) and J.2.3 (residual error of the broadcast ionospheric model).
.. [7] Klobuchar J.A. (1987), Ionospheric time-delay algorithm for single-frequency GPS
       users, IEEE Trans. AES 23(3), 325-331 (the broadcast model, its 5 ns constant term).
.. [4] Julier S.J., Uhlmann J.K. (2004), Unscented filtering and nonlinear estimation,
       Proc. IEEE 92(3); Wan E.A., van der Merwe R. (2000), The unscented Kalman filter
       for nonlinear estimation (scaled sigma points, weights).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Generic, TypeVar, cast, overload

import numpy as np
from numpy.typing import ArrayLike

from ..earth import mat_en
from ..errors import ConfigError
from ..option_checks import (
    check_auto_none,
    check_integer,
    check_optional_positive_finite,
    check_positive_finite,
    check_time_constant,
)
from ..rotations import quat_to_mat
from ._inserror import BG, AuxBlocksIns, BodyTerms, ImuNoise, StepTerms, joseph_update, lever_arm_terms
from .base import (
    Context,
    Estimate,
    EstimateBatch,
    GnssObservation,
    Measurement,
    MeasurementBatch,
    NoiseScalable,
    Prior,
    StepRow,
    row_of,
)

if TYPE_CHECKING:  # type hints only
    from ..earth import EarthModel

__all__ = [
    "TightlyCoupledEkf",
    "TightlyCoupledUkf",
    "TightlyCoupledOptions",
    "predict_observables",
    "observation_jacobian",
    "sigma_points",
    "guarded_cholesky",
    "unscented_update",
    "unscented_predict",
    "ionosphere_obliquity",
    "troposphere_mapping",
    "atmosphere_delays",
    "atmosphere_jacobian",
]

CB, CD = 15, 16
T = TypeVar("T")
Num = float | np.ndarray  # a scalar or an array of them (the vectorised functions take both)

TINY_CLOCK_BIAS_M = 1e-3
TINY_CLOCK_DRIFT_MPS = 1e-4
SIGMA_FLOOR_PR_M = 1e-3  # floors of the measurement sigmas (the "ideal" receiver has 0)
SIGMA_FLOOR_RATE_MPS = 1e-4


# ============================================================================ observables
def predict_observables(lat: Num, lon: Num, h: Num, velocity_n: ArrayLike, clock_bias: Num, clock_drift: Num,
                        sat_pos_e: np.ndarray, sat_vel_e: np.ndarray, earth: EarthModel, *,
                        arm_n: ArrayLike | None = None,
                        arm_velocity_n: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Pseudoranges (TC.2) and pseudorange rates (TC.3) of m satellites.

    Parameters
    ----------
    lat, lon, h : float or (N,) arrays
        Receiver position, rad, rad, m.
    velocity_n : (3,) or (N, 3)
        ENU velocity, m/s.
    clock_bias, clock_drift : float or (N,)
        m and m/s.
    sat_pos_e, sat_vel_e : (m, 3)
        Satellite ECEF positions (m) and ECEF-frame velocities (m/s).
    earth : EarthModel
    arm_n, arm_velocity_n : (3,) or (N, 3), optional
        Antenna offset from the INS and its velocity in the ENU axes of the INS position
        (:func:`navsim.estimators._inserror.lever_arm_terms`): the observables are then
        the antenna's (TC.8).

    Returns
    -------
    rho, rate : (..., m)
        Leading shape that of ``lat``.
    """
    r_e = earth.geodetic_to_ecef(lat, lon, h)
    c_en = mat_en(lat, lon)
    if arm_n is not None:  # (TC.8) the antenna's position and velocity
        r_e, velocity_n = _antenna(r_e, c_en, velocity_n, arm_n, arm_velocity_n)
    _, rho, rate = _ranges(r_e, c_en, velocity_n, sat_pos_e, sat_vel_e)
    return rho + np.asarray(clock_bias)[..., None], rate + np.asarray(clock_drift)[..., None]


def _antenna(r_e: np.ndarray, c_en: np.ndarray, velocity_n: ArrayLike, arm_n: ArrayLike,
             arm_velocity_n: ArrayLike | None) -> tuple[np.ndarray, np.ndarray]:
    """Antenna ECEF position and ENU velocity from the INS ones (TC.8)."""
    arm_e = np.einsum("...ji,...j->...i", c_en, np.asarray(arm_n, dtype=float))  # C_en^T arm_n
    return r_e + arm_e, np.asarray(velocity_n, dtype=float) + np.asarray(arm_velocity_n, dtype=float)


def _rotate_back(psi: np.ndarray, vec: np.ndarray) -> np.ndarray:
    """exp(-[psi x]) vec, row-wise for (N, 3) arrays (Rodrigues)."""
    theta2 = np.einsum("ni,ni->n", psi, psi)
    theta = np.sqrt(theta2)
    small = theta < 1e-6
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    c1 = np.cross(psi, vec)
    return vec - a[:, None] * c1 + b[:, None] * np.cross(psi, c1)


def _ranges(r_e: np.ndarray, c_en: np.ndarray, velocity_n: ArrayLike, sat_pos_e: np.ndarray,
            sat_vel_e: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lines of sight (..., m, 3), geometric ranges and range rates (..., m): (TC.2), (TC.3)."""
    v_e = np.einsum("...ji,...j->...i", c_en, np.asarray(velocity_n, dtype=float))  # C_en^T v_n
    los = sat_pos_e - r_e[..., None, :]
    rho = np.sqrt(np.einsum("...mi,...mi->...m", los, los))
    rel = sat_vel_e - v_e[..., None, :]
    rate = np.einsum("...mi,...mi->...m", los, rel) / rho
    return los, rho, rate


def observation_jacobian(lat: float, lon: float, h: float, velocity_n: ArrayLike, sat_pos_e: np.ndarray,
                         sat_vel_e: np.ndarray, earth: EarthModel, n_states: int = 17, *,
                         lever: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """d[rho; rate]/dx (2m, n_states) at the estimate: (TC.4), x = estimate error.

    Columns: position (metres along E, N, U), velocity, then zeros for attitude and
    biases, then clock bias and drift (when ``n_states == 17``).

    ``lever``: ``(arm_n, arm_velocity_n, L)`` of
    :func:`navsim.estimators._inserror.lever_arm_terms`; the observables are then the
    antenna's (TC.8) and the attitude and gyro-bias columns are (TC.9).
    """
    r_n, r_e_rad = (float(x) for x in earth.radii(lat))
    r_e = earth.geodetic_to_ecef(lat, lon, h)
    c_en = mat_en(lat, lon)
    v_n = np.asarray(velocity_n, dtype=float)
    if lever is not None:  # (TC.8) line of sight and relative velocity of the antenna
        r_e, v_n = _antenna(r_e, c_en, v_n, lever[0], lever[1])
    v_e = c_en.T @ v_n
    los = sat_pos_e - r_e
    rho = np.sqrt(np.einsum("mi,mi->m", los, los))
    u = los / rho[:, None]
    rel = sat_vel_e - v_e
    u_n = u @ c_en.T  # rows C_en u_i
    m = len(rho)
    J = np.zeros((2 * m, n_states))
    J[:m, 0:3] = -u_n
    J[m:, 3:6] = -u_n
    g_e = -(rel - u * np.einsum("mi,mi->m", u, rel)[:, None]) / rho[:, None]
    J[m:, 0:3] = g_e @ c_en.T
    if lever is not None:  # (TC.9): the antenna alone moves (line of sight), not the ENU axes
        J_antenna = J[:, 0:6].copy()
    # turn of the ENU axes: v_e = v_E E + v_N N + v_U U with rows E, N, U of C_en
    sl, cl = math.sin(lat), math.cos(lat)
    so, co = math.sin(lon), math.cos(lon)
    east, north, up = c_en
    dv_dlat = -v_n[1] * up + v_n[2] * north
    dv_dlon = v_n[0] * np.array([-co, -so, 0.0]) + v_n[1] * np.array([sl * so, -sl * co, 0.0]) \
        + v_n[2] * np.array([-cl * so, cl * co, 0.0])
    J[m:, 1] += -(u @ dv_dlat) / (r_n + h)
    J[m:, 0] += -(u @ dv_dlon) / ((r_e_rad + h) * cl)
    if lever is not None:  # (TC.9) chain rule through the antenna position and velocity
        L = lever[2]
        J[:, 6:15] = J_antenna[:, 0:3] @ L[0:3, 6:15] + J_antenna[:, 3:6] @ L[3:6, 6:15]
    if n_states > CD:
        J[:m, CB] = 1.0
        J[m:, CD] = 1.0
    return J


# ============================================================================ atmosphere
def ionosphere_obliquity(elevation: Num, shell_height_m: float = 350_000.0,
                         earth_radius_m: float = 6_378_137.0) -> np.ndarray:
    """Thin-shell ionospheric obliquity factor F(E) = 1 / sqrt(1 - (R cos E / (R + h_I))^2) (TC.6).

    Parameters
    ----------
    elevation : float or array, rad. shell_height_m : h_I, m. earth_radius_m : R, m.

    Returns
    -------
    F : same shape as ``elevation`` (1 at the zenith).
    """
    k = earth_radius_m / (earth_radius_m + shell_height_m)
    c = np.cos(np.asarray(elevation, dtype=float))
    return 1.0 / np.sqrt(1.0 - (k * c) ** 2)


def troposphere_mapping(elevation: Num) -> np.ndarray:
    """RTCA DO-229D tropospheric mapping m(E) = 1.001 / sqrt(0.002001 + sin^2 E) (TC.6).

    ``elevation`` in rad; m(90 deg) = 1.001/sqrt(1.002001) = 1 to 1e-9.
    """
    s = np.sin(np.asarray(elevation, dtype=float))
    return 1.001 / np.sqrt(0.002001 + s * s)


def _sin_elevation(los: np.ndarray, rho: np.ndarray, c_en: np.ndarray) -> np.ndarray:
    """sin E = u . up (geodetic vertical, row U of C_en), (..., m)."""
    return np.einsum("...mi,...i->...m", los, c_en[..., 2, :]) / rho


def slant_maps(s: np.ndarray, k: float, h: Num, scale_height_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """F, m and the tropospheric height factor exp(-h / H_T) from s = sin E (TC.6): the thin-shell
    ionospheric obliquity with k = a / (a + shell height), the RTCA DO-229D mapping m(E)."""
    F = 1.0 / np.sqrt(1.0 - k * k * (1.0 - s * s))
    m = 1.001 / np.sqrt(0.002001 + s * s)
    return F, m, np.exp(-np.asarray(h, dtype=float) / scale_height_m)


def _slant(s: np.ndarray, h: Num, ionosphere_zenith_m: Num, troposphere_zenith_m: Num, k: float,
           scale_height_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Slant delays (TC.6) from s = sin E; zenith delays scalar or (N,)."""
    F, m, height = slant_maps(s, k, h, scale_height_m)
    iono = np.asarray(ionosphere_zenith_m, dtype=float)[..., None] * F
    tropo = (np.asarray(troposphere_zenith_m, dtype=float) * height)[..., None] * m
    return iono, tropo


def _slant_partials(s: np.ndarray, los: np.ndarray, rho: np.ndarray, c_en: np.ndarray, lat: Num, h: Num,
                    ionosphere_zenith_m: Num, troposphere_zenith_m: Num, earth: EarthModel, k: float,
                    scale_height_m: float, vertical_tilt: bool = True) -> np.ndarray:
    """(m, 5) partials of I + T (TC.7) at one position; see :func:`atmosphere_jacobian`.

    ``vertical_tilt=False`` leaves out the tilt of the local vertical: the partials for
    a displacement of the antenna alone, the ENU axes staying those of the INS (TC.9)."""
    r_n, r_e_rad = (float(x) for x in earth.radii(lat))
    F, m, height = slant_maps(s, k, h, scale_height_m)
    t_h = troposphere_zenith_m * height
    u = los / rho[:, None]
    east, north, up = c_en
    # ds/dp_n: line of sight turning, then the local vertical tilting
    ds = -((up - u * s[:, None]) @ c_en.T) / rho[:, None]
    if vertical_tilt:
        ds[:, 0] += (u @ east) / (r_e_rad + h)
        ds[:, 1] += (u @ north) / (r_n + h)
    d_delay_ds = ionosphere_zenith_m * (-k * k * s * F**3) + t_h * (-s * m**3 / 1.001**2)
    J = np.empty((len(s), 5))
    J[:, 0:3] = d_delay_ds[:, None] * ds
    J[:, 2] -= t_h * m / scale_height_m
    J[:, 3] = F
    J[:, 4] = height * m
    return J


def atmosphere_delays(lat: Num, lon: Num, h: Num, sat_pos_e: np.ndarray, ionosphere_zenith_m: Num,
                      troposphere_zenith_m: Num, earth: EarthModel, *, shell_height_m: float = 350_000.0,
                      scale_height_m: float = 8_000.0) -> tuple[np.ndarray, np.ndarray]:
    """Slant ionospheric and tropospheric code delays (TC.6) of m satellites.

    Parameters
    ----------
    lat, lon, h : float or (N,) arrays
        Receiver geodetic position, rad, rad, m.
    sat_pos_e : (m, 3)
        Satellite ECEF positions, m.
    ionosphere_zenith_m, troposphere_zenith_m : float or (N,)
        Vertical ionospheric delay and sea-level zenith tropospheric delay, m.
    earth : EarthModel (its equatorial radius is the R of the thin shell).
    shell_height_m, scale_height_m : float
        Ionospheric shell height and tropospheric scale height, m.

    Returns
    -------
    iono, tropo : (..., m), m; leading shape that of ``lat``.
    """
    r_e = earth.geodetic_to_ecef(lat, lon, h)
    c_en = mat_en(lat, lon)
    los = sat_pos_e - r_e[..., None, :]
    rho = np.sqrt(np.einsum("...mi,...mi->...m", los, los))
    k = earth.a / (earth.a + shell_height_m)
    return _slant(_sin_elevation(los, rho, c_en), h, ionosphere_zenith_m, troposphere_zenith_m, k, scale_height_m)


def atmosphere_jacobian(lat: float, lon: float, h: float, sat_pos_e: np.ndarray, ionosphere_zenith_m: float,
                        troposphere_zenith_m: float, earth: EarthModel, *, shell_height_m: float = 350_000.0,
                        scale_height_m: float = 8_000.0) -> np.ndarray:
    """Partial derivatives (m, 5) of the total slant delay I + T (TC.7).

    Columns: position (metres along E, N, U, through the elevation and the height),
    then the zenith ionospheric and sea-level zenith tropospheric delays.
    """
    r_e = earth.geodetic_to_ecef(lat, lon, h)
    c_en = mat_en(lat, lon)
    los = sat_pos_e - r_e
    rho = np.sqrt(np.einsum("mi,mi->m", los, los))
    k = earth.a / (earth.a + shell_height_m)
    return _slant_partials(_sin_elevation(los, rho, c_en), los, rho, c_en, lat, h, ionosphere_zenith_m,
                           troposphere_zenith_m, earth, k, scale_height_m)


# ============================================================================ sigma points
def guarded_cholesky(A: np.ndarray) -> tuple[np.ndarray, int]:
    """Lower square root L (L L^T = A) of a covariance-like matrix, and a fallback count.

    The Cholesky factor of ``A`` restricted to the states with non-zero variance (the
    others get zero rows and columns); on failure jitter is added (1e-12, 1e-9, 1e-6 of
    the largest variance) and, last, an eigen-decomposition with clipped eigenvalues is
    used (then L is not triangular, but L L^T is still the clipped A).
    """
    n = len(A)
    active = np.flatnonzero(np.diag(A) > 0.0)
    L = np.zeros((n, n))
    fallbacks = 0
    if active.size:
        B = A[np.ix_(active, active)]
        B = 0.5 * (B + B.T)
        scale = float(np.max(np.diag(B)))
        factor = None
        for jitter in (0.0, 1e-12, 1e-9, 1e-6):
            try:
                factor = np.linalg.cholesky(B + jitter * scale * np.eye(active.size) if jitter else B)
                break
            except np.linalg.LinAlgError:
                fallbacks += 1
        if factor is None:  # eigen-decomposition, negative eigenvalues clipped
            w, v = np.linalg.eigh(B)
            factor = v * np.sqrt(np.clip(w, 0.0, None))
        L[np.ix_(active, active)] = factor
    return L, fallbacks


def sigma_points(mean: np.ndarray, P: np.ndarray, alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Scaled symmetric sigma points (2n+1, n) with weights, and a fallback count.

    The square root is the Cholesky factor of ``(n + lambda) P`` restricted to the states
    with non-zero variance; on failure jitter is added (1e-12, 1e-9, 1e-6 of the largest
    variance) and, last, an eigen-decomposition with clipped eigenvalues is used.

    Returns
    -------
    X : (2n+1, n). Wm, Wc : (2n+1,). fallbacks : int (0 when the plain Cholesky worked).
    """
    n = len(mean)
    lam = alpha * alpha * (n + kappa) - n
    c = n + lam
    L, fallbacks = guarded_cholesky(c * P)
    X = np.empty((2 * n + 1, n))
    X[0] = mean
    X[1:n + 1] = mean + L.T
    X[n + 1:] = mean - L.T
    Wm = np.full(2 * n + 1, 0.5 / c)
    Wc = Wm.copy()
    Wm[0] = lam / c
    Wc[0] = lam / c + (1.0 - alpha * alpha + beta)
    return X, Wm, Wc, fallbacks


def unscented_update(mean: np.ndarray, P: np.ndarray, hx: Callable[[np.ndarray], np.ndarray], z: np.ndarray,
                     R: np.ndarray, alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0
                     ) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Unscented measurement update.

    Parameters
    ----------
    mean : (n,). P : (n, n). hx : callable (N, n) -> (N, m) measurement model.
    z : (m,) measurement. R : (m,) diagonal or (m, m) noise covariance.

    Returns
    -------
    mean_new (n,), P_new (n, n) symmetrised, nis float, fallbacks int.
    """
    X, Wm, Wc, fallbacks = sigma_points(mean, P, alpha, beta, kappa)
    Z = hx(X)
    z_hat = Wm @ Z
    dZ = Z - z_hat
    dX = X - mean
    R = np.asarray(R, dtype=float)
    Pzz = (dZ.T * Wc) @ dZ + (np.diag(R) if R.ndim == 1 else R)
    Pxz = (dX.T * Wc) @ dZ
    cho = np.linalg.cholesky(0.5 * (Pzz + Pzz.T))
    K = np.linalg.solve(cho.T, np.linalg.solve(cho, Pxz.T)).T  # K = Pxz Pzz^-1
    y = z - z_hat
    w = np.linalg.solve(cho, y)
    P_new = P - K @ Pzz @ K.T
    return mean + K @ y, 0.5 * (P_new + P_new.T), float(w @ w), fallbacks


def unscented_predict(mean: np.ndarray, P: np.ndarray, fx: Callable[[np.ndarray], np.ndarray], Q: np.ndarray,
                      alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0
                      ) -> tuple[np.ndarray, np.ndarray, int]:
    """Unscented time update: sigma points through ``fx`` ((N, n) -> (N, n)) plus Q.

    Returns mean (n,), P (n, n), fallbacks. (The tightly coupled UKF does not need it,
    its error dynamics being linear; it is here for completeness and the linear check.)
    """
    X, Wm, Wc, fallbacks = sigma_points(mean, P, alpha, beta, kappa)
    Y = fx(X)
    m = Wm @ Y
    dY = Y - m
    P_new = (dY.T * Wc) @ dY + Q
    return m, 0.5 * (P_new + P_new.T), fallbacks


# ============================================================================ the engine
def _clock_transition(tau: float, psd: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Phi and Qd of the two-state clock (TC.1) over tau (Brown & Hwang 9.3)."""
    s_f, s_g = psd
    phi = np.array([[1.0, tau], [0.0, 1.0]])
    q = np.array([[s_f * tau + s_g * tau**3 / 3.0, s_g * tau**2 / 2.0], [s_g * tau**2 / 2.0, s_g * tau]])
    return phi, q


class _StepMean(Generic[T]):
    """An estimate of :class:`_ClockEngine` that follows the INS steps: read after steps, it
    is first brought to the last one (:meth:`_ClockEngine._propagate_means`); assignment
    stores it (in the instance attribute of the same name with a leading underscore)."""

    def __init__(self, doc: str) -> None:
        self.__doc__ = doc
        self.slot = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.slot = "_" + name

    @overload
    def __get__(self, obj: None, owner: type | None = None) -> _StepMean[T]: ...

    @overload
    def __get__(self, obj: _ClockEngine, owner: type | None = None) -> T: ...

    def __get__(self, obj: _ClockEngine | None, owner: type | None = None) -> T | _StepMean[T]:
        if obj is None:
            return self
        if obj._means_due:
            obj._propagate_means()
        return getattr(obj, self.slot)

    def __set__(self, obj: _ClockEngine, value: T) -> None:
        setattr(obj, self.slot, value)


class _ClockEngine(AuxBlocksIns):
    """The INS error engine plus auxiliary states: receiver clock (2), atmosphere (2) and
    barometric-altimeter bias (1).

    The clock dynamics (TC.1) and the atmospheric Gauss-Markov processes (TC.5) do not
    involve the INS errors and vice versa: the interval bookkeeping of the auxiliary
    block is that of :class:`~navsim.estimators._inserror.AuxBlocksIns`; this class gives
    their transition (coupled 2 x 2 clock block, diagonal atmosphere).

    ``atmosphere`` is None (no atmospheric states) or ``(apriori, sigma, tau)``, each
    (ionosphere, troposphere): a-priori zenith delays (m), their 1-sigma (m) and the
    Gauss-Markov time constants (s, ``inf`` for random constants). ``baro`` is None or
    ``(sigma_m, tau_s)`` of the Gauss-Markov altimeter bias (TC.10), its state last.
    """

    def __init__(self, context: Context, prior: Prior, noise: ImuNoise, *, clock_sigma: tuple[float, float],
                 clock_psd: tuple[float, float], with_clock: bool,
                 atmosphere: tuple[tuple[float, float], tuple[float, float], tuple[float, float]] | None = None,
                 baro: tuple[float, float] | None = None, **kw: Any) -> None:
        self._means_due = False  # the means of _after_steps, computed when read
        self.with_clock = bool(with_clock)
        self.with_atmosphere = atmosphere is not None
        self.with_baro = baro is not None
        self.atm_index = 15 + (2 if self.with_clock else 0)
        self.baro_index = self.atm_index + (2 if self.with_atmosphere else 0)
        self.baro_bias = 0.0  # estimated altimeter bias, m
        self.clock = np.zeros(2)
        self._clock_psd = clock_psd
        variances = [clock_sigma[0] ** 2, clock_sigma[1] ** 2] if self.with_clock else []
        if atmosphere is not None:
            apriori, sigma, tau = (np.asarray(a, dtype=float) for a in atmosphere)
            self.atm_apriori = apriori.copy()
            self.atm = apriori.copy()  # estimated zenith delays [I_z, T_z], m
            self._atm_var = sigma**2
            self._atm_tau = tau
            variances += list(self._atm_var)
        if baro is not None:
            self._baro_var, self._baro_tau = float(baro[0]) ** 2, float(baro[1])
            variances.append(self._baro_var)
        self._init_aux(variances)
        self._mark_update()
        super().__init__(context, prior, noise, **kw)

    def _aux_transition(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """Phi_a and Qd_a of the auxiliary states over tau: (TC.1), (TC.5), (TC.10)."""
        if self.with_baro:
            return self._baro_transition(tau)
        if not self.with_atmosphere:
            return _clock_transition(tau, self._clock_psd)
        decay = np.exp(-tau / self._atm_tau)  # (TC.5), 1 for a random constant
        phi = np.zeros((self.n_aux, self.n_aux))
        q = np.zeros((self.n_aux, self.n_aux))
        a = self.atm_index - 15
        if self.with_clock:
            phi[:2, :2], q[:2, :2] = _clock_transition(tau, self._clock_psd)
        phi[a, a], phi[a + 1, a + 1] = decay
        q[a, a], q[a + 1, a + 1] = self._atm_var * (1.0 - decay * decay)
        return phi, q

    def _baro_transition(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """(TC.1), (TC.5) and the altimeter bias (TC.10) as one block-diagonal transition."""
        phi = np.zeros((self.n_aux, self.n_aux))
        q = np.zeros((self.n_aux, self.n_aux))
        if self.with_clock:
            phi[:2, :2], q[:2, :2] = _clock_transition(tau, self._clock_psd)
        if self.with_atmosphere:
            a = self.atm_index - 15
            decay = np.exp(-tau / self._atm_tau)
            phi[a, a], phi[a + 1, a + 1] = decay
            q[a, a], q[a + 1, a + 1] = self._atm_var * (1.0 - decay * decay)
        b = self.baro_index - 15
        decay_b = math.exp(-tau / self._baro_tau)
        phi[b, b], q[b, b] = decay_b, self._baro_var * -math.expm1(-2.0 * tau / self._baro_tau)
        return phi, q

    def _mark_update(self) -> None:
        """Remember the clock, atmosphere and altimeter-bias estimates at an update (or the reset)."""
        self._since_update = 0
        self._clock_at_update = self.clock.copy()
        if self.with_atmosphere:
            self._atm_at_update = self.atm.copy()
        if self.with_baro:
            self._baro_at_update = self.baro_bias

    def advance_body(self, body: BodyTerms | StepTerms, start: int = 0,
                     stop: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The INS steps, then the clock (TC.1) and atmosphere (TC.5) means.

        The means are propagated from the last update by the total number of steps
        since then (not call by call), so one call over n steps and n one-step calls
        give the same numbers bit for bit on any CPU.
        """
        rows, cov = super().advance_body(body, start, stop)
        self._after_steps(len(rows))
        return rows, cov

    def _after_steps(self, n: int) -> None:
        """n more steps since the update (also called by the compiled one-step path of
        :meth:`ErrorStateIns.advance_row`): the clock, atmosphere and altimeter-bias means
        are brought to them when next read (:meth:`_propagate_means`; they depend on the
        step count only, so the values are those of an evaluation here)."""
        self._since_update += n
        self._means_due = True

    clock = _StepMean[np.ndarray]("Receiver clock estimate [bias (m), drift (m/s)] at the last processed step.")
    atm = _StepMean[np.ndarray]("Estimated zenith delays [I_z, T_z] (m) at the last processed step.")
    baro_bias = _StepMean[float]("Estimated altimeter bias (m) at the last processed step.")

    def _propagate_means(self) -> None:
        """The clock (TC.1), atmosphere (TC.5) and altimeter-bias (TC.10) means after
        ``_since_update`` steps since the update."""
        self._means_due = False
        tau = self._since_update * self.dt
        if self.with_clock:  # (TC.1) mean: bias + drift tau
            c0 = self._clock_at_update
            self.clock = np.array([c0[0] + c0[1] * tau, c0[1]])
        if self.with_atmosphere:  # (TC.5) mean: the residual decays towards the a-priori value
            self.atm = self.atm_apriori + (self._atm_at_update - self.atm_apriori) * np.exp(-tau / self._atm_tau)
        if self.with_baro:  # (TC.10) mean: the bias estimate decays towards zero
            self.baro_bias = self._baro_at_update * math.exp(-tau / self._baro_tau)

    def apply(self, dx: np.ndarray, P_new: np.ndarray) -> None:
        """Closed-loop feedback of an estimated error dx and restart of the interval."""
        self._feed_back(dx)
        P_new = self._guard(P_new)
        if self.n_aux:
            if self.with_clock:
                self.clock = self.clock - dx[CB:CD + 1]  # estimate minus truth: remove it
            if self.with_atmosphere:
                a = self.atm_index
                self.atm = self.atm - dx[a:a + 2]
            if self.with_baro:
                self.baro_bias = self.baro_bias - float(dx[self.baro_index])
            self._mark_update()
            self._restart_after_update(P_new)
        else:
            self._start_interval(P_new[:15, :15].copy())


# ============================================================================ options
@dataclass(frozen=True, slots=True)
class TightlyCoupledOptions:
    """Options of the tightly coupled filters (see :class:`TightlyCoupledEkf`)."""

    clock: str = "auto"
    use_doppler: bool = True
    covariance_period_s: float = 1.0
    noise_scale: float = 1.0
    bias_scale: float = 1.0
    estimate_biases: bool = True
    coning: str | None = None
    sculling: str | None = None
    position: str | None = None
    nis_divergence: float = 50.0
    divergence_epochs: int = 10
    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0
    pseudorange_sigma_m: float | None = None
    doppler_sigma_mps: float | None = None
    atmosphere: str = "auto"
    ionosphere_tau_s: float = 1800.0
    troposphere_tau_s: float = 3600.0
    lever_arm: str = "auto"
    baro: str = "auto"
    baro_period_s: float = 1.0
    gyro_scale_sigma: float = 0.0
    accel_scale_sigma: float = 0.0
    scale_tau_s: float = 5.0

    def __post_init__(self) -> None:
        ImuNoise(gyro_scale_sigma=self.gyro_scale_sigma, accel_scale_sigma=self.accel_scale_sigma,
                 scale_tau_s=self.scale_tau_s)  # checks them
        check_auto_none("tightly.baro", self.baro)
        check_positive_finite("tightly.baro_period_s", self.baro_period_s, "a positive finite number, s")
        check_auto_none("tightly.lever_arm", self.lever_arm)
        check_auto_none("tightly.atmosphere", self.atmosphere)
        for name in ("ionosphere_tau_s", "troposphere_tau_s"):
            check_time_constant(f"tightly.{name}", getattr(self, name))
        for name in ("pseudorange_sigma_m", "doppler_sigma_mps"):
            check_optional_positive_finite(f"tightly.{name}", getattr(self, name), "None or a positive finite sigma")
        check_auto_none("tightly.clock", self.clock)
        for name in ("covariance_period_s", "noise_scale", "bias_scale", "nis_divergence", "alpha"):
            check_positive_finite(f"tightly.{name}", getattr(self, name))
        # a whole float (10.0, from an option file) is kept as the int it stands for
        object.__setattr__(self, "divergence_epochs",
                           check_integer("tightly.divergence_epochs", self.divergence_epochs, 1, "a positive integer"))


# ============================================================================ filters
class _TightlyCoupled(NoiseScalable):
    """Shared machinery: reset, the INS between epochs, outputs; subclasses update."""

    NOISE_PROCESS = ('engine.Qc',)
    NOISE_MEASUREMENT_SIGMA = ('sigma_pr', 'sigma_rate')
    # where set_noise_scale finds Q and R after reset (navsim.estimators.base.NoiseScalable)

    kind = "ekf"

    def __init__(self, **options: Any) -> None:
        self.options = TightlyCoupledOptions(**options)
        self.engine: _ClockEngine | None = None

    def reset(self, context: Context, prior: Prior) -> None:
        """Start from the prior (9 x 9 navigation covariance, nominal bias sigmas, clock)."""
        opt = self.options
        self.context = context
        noise = ImuNoise.from_nominal(context.imu, noise_scale=opt.noise_scale, bias_scale=opt.bias_scale)
        if opt.gyro_scale_sigma > 0.0 or opt.accel_scale_sigma > 0.0:  # (RS.1), (RS.2) of _inserror
            noise = dataclasses.replace(noise, gyro_scale_sigma=opt.gyro_scale_sigma,
                                        accel_scale_sigma=opt.accel_scale_sigma, scale_tau_s=opt.scale_tau_s)
        gnss = context.gnss
        if gnss.clock_modelled:
            clock_sigma = (gnss.clock_bias_sigma_m, gnss.clock_drift_sigma_mps)
            clock_psd = (gnss.clock_phase_psd, gnss.clock_freq_psd)
        else:  # compensated clock (seed 003): tiny prior, no process noise
            clock_sigma = (TINY_CLOCK_BIAS_M, TINY_CLOCK_DRIFT_MPS)
            clock_psd = (0.0, 0.0)
        steps = max(1, round(opt.covariance_period_s / context.nav_period_s))
        atmosphere = None
        if opt.atmosphere == "auto" and getattr(gnss, "atmosphere_modelled", False):
            atmosphere = ((gnss.ionosphere_zenith_m, gnss.troposphere_zenith_m),
                          (gnss.ionosphere_zenith_sigma_m, gnss.troposphere_zenith_sigma_m),
                          (opt.ionosphere_tau_s, opt.troposphere_tau_s))
            self._shell_height_m = float(gnss.ionosphere_shell_height_m)
            self._scale_height_m = float(gnss.troposphere_scale_height_m)
        spec = getattr(context, "baro", None)
        # (TC.10): the EKF only (the UKF's sigma points do not carry the altimeter state)
        self._baro = spec if opt.baro == "auto" and self.kind == "ekf" else None
        baro = None
        if self._baro is not None:
            baro = (self._baro.bias_sigma_m, self._baro.bias_tau_s)
            self._baro_steps = max(1, round(opt.baro_period_s / context.nav_period_s))
            self._baro_var = max(self._baro.noise_sigma_m**2 + self._baro.resolution_m**2 / 12.0, 1e-12)
        self.engine = _ClockEngine(context, prior, noise, clock_sigma=clock_sigma, clock_psd=clock_psd,
                                   with_clock=opt.clock == "auto", atmosphere=atmosphere, baro=baro,
                                   interval_steps=steps,
                                   coning=opt.coning, sculling=opt.sculling, position=opt.position,
                                   estimate_biases=opt.estimate_biases)
        self.earth = context.earth
        # measurement sigmas with a floor (an error-free receiver must not make S singular)
        sigma_pr = opt.pseudorange_sigma_m if opt.pseudorange_sigma_m is not None else gnss.pseudorange_sigma_m
        sigma_rate = opt.doppler_sigma_mps if opt.doppler_sigma_mps is not None else gnss.doppler_sigma_mps
        self.sigma_pr = max(float(sigma_pr), SIGMA_FLOOR_PR_M)
        self.sigma_rate = max(float(sigma_rate), SIGMA_FLOOR_RATE_MPS)
        arm = getattr(gnss, "lever_arm_b_m", (0.0, 0.0, 0.0)) if opt.lever_arm == "auto" else (0.0, 0.0, 0.0)
        self.lever_arm_b = np.array(arm, dtype=float)
        self._with_lever = bool(np.any(self.lever_arm_b != 0.0))
        self._omega_ib_b = np.zeros(3)
        self.diverged = False
        self._bad = 0
        self.cholesky_fallbacks = 0
        self.n_used = 0
        self._last_extra: dict | None = {}

    @property
    def last_extra(self) -> dict:
        """The diagnostics of the last step (biases, clock, atmosphere, ...); after a
        :meth:`step_row` they are gathered on reading."""
        extra = self._last_extra
        if extra is None:
            extra = self._last_extra = self._extra()
        return extra

    @last_extra.setter
    def last_extra(self, value: dict) -> None:
        self._last_extra = value

    def _engine(self) -> _ClockEngine:
        """The engine of the episode (made by :meth:`reset`)."""
        eng = self.engine
        if eng is None:
            raise ConfigError(type(self).__name__, "reset(context, prior) before stepping", "no reset")
        return eng

    # ------------------------------------------------------------------ update
    def _measurements(self, obs: GnssObservation) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        use = np.asarray(obs.valid, dtype=bool) & np.isfinite(obs.pseudorange_m) & np.isfinite(obs.pseudorange_rate_mps)
        sat_pos, sat_vel = obs.sat_pos_e[use], obs.sat_vel_e[use]
        m = int(use.sum())
        z = obs.pseudorange_m[use]
        R = np.full(m, self.sigma_pr**2)
        if self.options.use_doppler:
            z = np.concatenate([z, obs.pseudorange_rate_mps[use]])
            R = np.concatenate([R, np.full(m, self.sigma_rate**2)])
        return m, sat_pos, sat_vel, z, R

    def _update(self, obs: GnssObservation) -> tuple[float | None, int]:
        m, sat_pos, sat_vel, z, R = self._measurements(obs)
        self.n_used = m
        if m == 0:
            return None, 0
        P = self._engine().full_covariance()
        nis = self._apply(lambda: self._kalman(P, sat_pos, sat_vel, z, R, m))
        if nis is None:
            return None, 0
        dof = len(z)
        self._bad = self._bad + 1 if nis / dof > self.options.nis_divergence else 0
        if self._bad >= self.options.divergence_epochs:
            self.diverged = True
        return nis, dof

    def _predicted(self, sat_pos: np.ndarray, sat_vel: np.ndarray,
                   lever: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
        eng = self._engine()
        st = eng.state
        cb, cd = (eng.clock if eng.with_clock else (0.0, 0.0))
        if lever is not None:
            return predict_observables(st.lat, st.lon, st.h, st.velocity_n, cb, cd, sat_pos, sat_vel, self.earth,
                                       arm_n=lever[0], arm_velocity_n=lever[1])
        return predict_observables(st.lat, st.lon, st.h, st.velocity_n, cb, cd, sat_pos, sat_vel, self.earth)

    def _lever_terms(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """(arm_n, arm_velocity_n, L) of the current INS state (TC.8), or None."""
        if not self._with_lever:
            return None
        st = self._engine().state
        return lever_arm_terms(quat_to_mat(st.quat_nb), self._omega_ib_b, self.lever_arm_b,
                               self.earth.earth_rate_n(st.lat))

    def _with_atmosphere(self, lat: Num, lon: Num, h: Num, velocity_n: ArrayLike, cb: Num, cd: Num, iono_zenith: Num,
                         tropo_zenith: Num, sat_pos: np.ndarray, sat_vel: np.ndarray, partials: bool = False,
                         arm_n: ArrayLike | None = None, arm_velocity_n: ArrayLike | None = None
                         ) -> tuple[np.ndarray, ...]:
        """(TC.2), (TC.3) plus the slant delays (TC.6) on one geometry (one ECEF position and
        C_en per hypothesis); with ``partials`` (one position) also (TC.7), (m, 5). With
        ``arm_n`` the geometry is the antenna's (TC.8), its height ``h + arm_U``, and the
        partials come with the position partials for the antenna alone (m, 3)."""
        r_e = self.earth.geodetic_to_ecef(lat, lon, h)
        c_en = mat_en(lat, lon)
        if arm_n is not None:  # (TC.8)
            r_e, velocity_n = _antenna(r_e, c_en, velocity_n, arm_n, arm_velocity_n)
            h = h + np.asarray(arm_n, dtype=float)[..., 2]
        los, rho, rate = _ranges(r_e, c_en, velocity_n, sat_pos, sat_vel)
        s = _sin_elevation(los, rho, c_en)
        k = self.earth.a / (self.earth.a + self._shell_height_m)
        iono, tropo = _slant(s, h, iono_zenith, tropo_zenith, k, self._scale_height_m)
        rho_pr = rho + np.asarray(cb)[..., None] + iono + tropo
        rate = rate + np.asarray(cd)[..., None]
        if not partials:
            return rho_pr, rate
        J = _slant_partials(s, los, rho, c_en, lat, h, iono_zenith, tropo_zenith, self.earth, k, self._scale_height_m)
        if arm_n is None:
            return rho_pr, rate, J
        J_antenna = _slant_partials(s, los, rho, c_en, lat, h, iono_zenith, tropo_zenith, self.earth, k,
                                    self._scale_height_m, vertical_tilt=False)[:, 0:3]
        return rho_pr, rate, J, J_antenna

    def _kalman(self, P: np.ndarray, sat_pos: np.ndarray, sat_vel: np.ndarray, z: np.ndarray, R: np.ndarray,
                m: int) -> tuple[np.ndarray, np.ndarray, float]:  # pragma: no cover - subclasses
        raise NotImplementedError

    # ------------------------------------------------------------------ stepping
    def _extra(self) -> dict:
        eng = self._engine()
        extra = {"gyro_bias": eng.gyro_bias.copy(), "accel_bias": eng.accel_bias.copy(), "n_used": self.n_used,
                 "diverged": bool(self.diverged or eng.diverged), "cholesky_fallbacks": self.cholesky_fallbacks}
        if eng.with_clock:
            extra["clock_bias_m"], extra["clock_drift_mps"] = float(eng.clock[0]), float(eng.clock[1])
        if eng.with_atmosphere:
            extra["ionosphere_zenith_m"], extra["troposphere_zenith_m"] = float(eng.atm[0]), float(eng.atm[1])
        if eng.with_baro:
            extra["baro_bias_m"] = float(eng.baro_bias)
        return extra

    def _baro_update(self, altitude_m: float) -> tuple[float | None, int]:
        """(TC.10) at the current step: ``y = h_ins - z + b_est = dU + db - v``, ``H = [e_U | e_b]``."""
        eng = self._engine()
        if not math.isfinite(altitude_m):
            return None, 0
        P = eng.full_covariance()
        H = np.zeros((1, eng.n_states))
        H[0, 2], H[0, eng.baro_index] = 1.0, 1.0
        y = np.array([eng.state.h - altitude_m + eng.baro_bias])
        nis = self._apply(lambda: joseph_update(P, H, np.array([[self._baro_var]]), y))
        return (None, 0) if nis is None else (float(nis), 1)

    def _apply(self, update: Callable[[], tuple[np.ndarray, np.ndarray, float]]) -> float | None:
        """Make ``update() -> (dx, P_new, nis)`` and feed it back (:meth:`_ClockEngine.apply`);
        None, with the divergence flag set, when it fails or is not finite."""
        try:
            dx, P_new, nis = update()
        except np.linalg.LinAlgError:
            self.diverged = True
            return None
        if not (np.all(np.isfinite(dx)) and np.all(np.isfinite(P_new))):
            self.diverged = True
            return None
        self._engine().apply(dx, P_new)
        return nis

    def step_row(self, measurement: Measurement) -> StepRow:
        """:meth:`step` as ``(row (9,), covariance (9, 9), nis, nis_dof)`` (the
        :class:`~navsim.estimators.base.RowStepping` protocol): the same numbers; a step
        without an update builds no :class:`Estimate` and leaves :attr:`last_extra` to be
        gathered on reading."""
        m = measurement
        eng = self.engine
        if eng is not None and (
                self._baro is None or getattr(m, "baro_alt_m", None) is None or (m.step + 1) % self._baro_steps != 0):
            if m.gnss is None:
                row, c = eng.advance_row(m.dtheta_sub, m.dv_sub, m.dtheta_r, m.dv_r)
                self._last_extra = None
                return row, c, None, None
            if not self._with_lever:
                out = self._epoch_row(m)
                self._last_extra = None
                return out
        return row_of(self.step(m))

    def step(self, measurement: Measurement) -> Estimate:
        """One navigation step (an update when the step carries a GNSS epoch): the batch path
        on a batch of one at epochs, the engine's one-step INS path in between (the same
        operations, see :meth:`ErrorStateIns.advance_body`)."""
        m = measurement
        baro = getattr(m, "baro_alt_m", None)
        if m.gnss is None and self.engine is not None and (
                self._baro is None or baro is None or (m.step + 1) % self._baro_steps != 0):
            row, c = self.engine.advance_row(m.dtheta_sub, m.dv_sub, m.dtheta_r, m.dv_r)
            self.last_extra = self._extra()
            lat, lon, h, ve, vn, vu, heading, pitch, roll = row.tolist()
            return Estimate(m.t, lat, lon, h, np.array((ve, vn, vu)), heading, pitch, roll, covariance=c,
                            extra=self.last_extra)
        if m.gnss is not None and self.engine is not None and not self._with_lever and (
                self._baro is None or baro is None or (m.step + 1) % self._baro_steps != 0):
            return self._epoch_step(m)
        out = self.step_batch(MeasurementBatch.of(m))
        row = out.solution[0]
        nis = None if np.isnan(out.nis[0]) else float(out.nis[0])
        return Estimate(m.t, row[0], row[1], row[2], row[3:6].copy(), row[6], row[7], row[8],
                        covariance=None if out.covariance is None else out.covariance[0], nis=nis,
                        nis_dof=int(out.nis_dof[0]) if nis is not None else None, extra=self.last_extra)

    def _epoch_row(self, m: Measurement) -> StepRow:
        """The :data:`StepRow` of a GNSS epoch without barometer update or lever arm: the
        operations of :meth:`step_batch` on a batch of one (the INS step, the update), with
        the INS step on the engine's one-step path (:meth:`ErrorStateIns.advance_step`, the
        same numbers) and no batch built."""
        eng = self._engine()
        rows, c = eng.advance_step(m.dtheta_sub, m.dv_sub, m.dtheta_r, m.dv_r)
        value, d = self._update(cast(GnssObservation, m.gnss))  # an epoch
        nis = nis_dof = None
        if value is not None:
            row = eng.current_row()
            cov = eng.covariance[:9, :9].copy()
            if not math.isnan(value):
                nis, nis_dof = float(value), int(d)
        else:
            row = rows[0]
            cov = c[0]
        return row, cov, nis, nis_dof

    def _epoch_step(self, m: Measurement) -> Estimate:
        """:meth:`step` at a GNSS epoch without barometer update or lever arm: :meth:`_epoch_row`
        as an :class:`Estimate`."""
        row, cov, nis, nis_dof = self._epoch_row(m)
        self.last_extra = self._extra()
        lat, lon, h, ve, vn, vu, heading, pitch, roll = row.tolist()
        return Estimate(m.t, lat, lon, h, np.array((ve, vn, vu)), heading, pitch, roll, covariance=cov, nis=nis,
                        nis_dof=nis_dof, extra=self.last_extra)

    def step_batch(self, batch: MeasurementBatch) -> EstimateBatch:
        """n steps: one INS integration per stretch between epochs, updates at epochs."""
        if self.engine is None:
            raise ConfigError(type(self).__name__, "reset(context, prior) before stepping", "no reset")
        n = len(batch)
        sol = np.empty((n, 9))
        cov = np.empty((n, 9, 9))
        nis = np.full(n, np.nan)
        dof = np.zeros(n, dtype=int)
        cuts = [j for j, _ in batch.gnss]
        obs_at = dict(batch.gnss)
        baro_due: set[int] = set()
        baro_alt = getattr(batch, "baro_alt_m", None)
        if self._baro is not None and baro_alt is not None:  # (TC.10) update steps
            baro_due = set(np.flatnonzero((np.asarray(batch.step) + 1) % self._baro_steps == 0).tolist())
            cuts = sorted(set(cuts) | baro_due)
        start = 0
        body = self.engine.prepare(batch.dtheta_sub, batch.dv_sub, batch.dtheta_r, batch.dv_r)  # once per batch
        for end in cuts + ([n - 1] if not cuts or cuts[-1] != n - 1 else []):
            if end < start:
                continue
            rows, c = self.engine.advance_body(body, start, end + 1)
            sol[start:end + 1], cov[start:end + 1] = rows, c
            obs = obs_at.get(end)
            if obs is not None:
                if self._with_lever:  # mean compensated body rate over the epoch's step (TC.8)
                    self._omega_ib_b = body.dtheta1[end] / self.engine.dt - self.engine.gyro_bias
                value, d = self._update(obs)
                if value is not None:
                    nis[end], dof[end] = value, d
                    sol[end] = self.engine.current_row()
                    cov[end] = self.engine.covariance[:9, :9]
            if end in baro_due and baro_alt is not None:
                value, d = self._baro_update(float(baro_alt[end]))
                if value is not None:
                    nis[end], dof[end] = (nis[end] + value, dof[end] + d) if dof[end] else (value, d)
                    sol[end] = self.engine.current_row()
                    cov[end] = self.engine.covariance[:9, :9]
            start = end + 1
        self.last_extra = self._extra()
        return EstimateBatch(sol, cov, nis, dof)


class TightlyCoupledEkf(_TightlyCoupled):
    """Error-state EKF on pseudoranges and pseudorange rates (15 to 19 states).

    Parameters (keywords, all optional)
    -----------------------------------
    clock : {"auto", "none"}
        "auto": clock bias/drift states (tiny prior when the context says the clock is
        compensated); "none": 15 states.
    use_doppler : bool
        Use the pseudorange rates too (default True).
    covariance_period_s : float
        Covariance interval of the engine, s (default 1).
    noise_scale, bias_scale : float
        Factors on the nominal IMU noise densities and bias sigmas.
    estimate_biases : bool
        Feed back the bias estimates (default True).
    coning, sculling, position : str or None
        Strapdown methods (None: the most accurate the data allow).
    nis_divergence, divergence_epochs : float, int
        Divergence flag settings.
    pseudorange_sigma_m, doppler_sigma_mps : float, optional
        Measurement sigmas assumed instead of the context's nominal ones (tuning, e.g.
        for unmodelled atmospheric delays). Floors: 1 mm and 0.1 mm/s.
    atmosphere : {"auto", "none"}
        "auto": when the context says the atmosphere is modelled, apply its a-priori
        slant delays and estimate the residual zenith ionospheric and tropospheric delays
        (two more states, (TC.5)-(TC.7)); "none": ignore the atmosphere.
    ionosphere_tau_s, troposphere_tau_s : float
        Gauss-Markov time constants of the residual zenith delays, s (defaults 1800 and
        3600; ``math.inf``: random constants).
    lever_arm : {"auto", "none"}
        "auto": the observables are the antenna's, at ``context.gnss.lever_arm_b_m``
        from the IMU (TC.8)-(TC.9); "none": the antenna is taken to be at the IMU
        (uncompensated).
    baro : {"auto", "none"}
        "auto": with a barometer in the context, the height update (TC.10) with an
        altimeter-bias state (EKF only); "none": without it.
    baro_period_s : float
        Interval of the barometer updates, s (default 1).
    gyro_scale_sigma, accel_scale_sigma, scale_tau_s : float
        Unmodelled gyro and accelerometer scale-factor/misalignment: 1-sigma of each element
        of the matrices (dimensionless, default 0: off) and the correlation time (s,
        default 5), covered as rate- and acceleration-proportional attitude and velocity
        noise (:mod:`navsim.estimators._inserror`, (RS.1), (RS.2)).

    See the module docstring for the model and equations.
    """

    kind = "ekf"
    # (P, H, R, innovation) -> (dx, P_new, nis); navsim.estimators.filterpy_based replaces it
    kalman_update = staticmethod(joseph_update)

    def _kalman(self, P: np.ndarray, sat_pos: np.ndarray, sat_vel: np.ndarray, z: np.ndarray, R: np.ndarray,
                m: int) -> tuple[np.ndarray, np.ndarray, float]:
        h, J = self.observation_model(sat_pos, sat_vel)
        if J.shape[1] < P.shape[0]:  # the altimeter-bias column (TC.10): no GNSS partial
            J = np.concatenate([J, np.zeros((J.shape[0], P.shape[0] - J.shape[1]))], axis=1)
        # y = z - h(INS) = -J x + v: H = -J          (003 eqs. (2), (3) linearised)
        return self.kalman_update(P, -J, np.diag(R), z - h)

    def observation_model(self, sat_pos: np.ndarray, sat_vel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted observables h (2m,; m without Doppler) and J = dh/dx at the estimate.

        (TC.2)-(TC.4), with the atmosphere (TC.6)-(TC.7) and the lever arm (TC.8)-(TC.9)
        when they are on; ``sat_pos``, ``sat_vel`` (m, 3) of the channels used.
        """
        m = len(sat_pos)
        eng = self._engine()
        st = eng.state
        lever = self._lever_terms()
        J = observation_jacobian(st.lat, st.lon, st.h, st.velocity_n, sat_pos, sat_vel, self.earth,
                                 eng.atm_index, lever=lever)
        if not eng.with_atmosphere:
            rho, rate = self._predicted(sat_pos, sat_vel, lever)
        else:  # (TC.6) and (TC.7): position partials and the two zenith-delay columns
            cb, cd = (eng.clock if eng.with_clock else (0.0, 0.0))
            arm = (None, None) if lever is None else lever[:2]
            out = self._with_atmosphere(st.lat, st.lon, st.h, st.velocity_n, cb, cd, eng.atm[0], eng.atm[1],
                                        sat_pos, sat_vel, partials=True, arm_n=arm[0], arm_velocity_n=arm[1])
            rho, rate, J_atm = out[:3]
            J = np.concatenate([J, np.zeros((2 * m, 2))], axis=1)
            J[:m, 0:3] += J_atm[:, 0:3]
            if lever is not None:  # the delays move with the antenna: (TC.9) for their partials
                J[:m, 6:9] += out[3] @ lever[2][0:3, 6:9]
            J[:m, eng.atm_index:] = J_atm[:, 3:]
        if self.options.use_doppler:
            return np.concatenate([rho, rate]), J
        return rho, J[:m]


class TightlyCoupledUkf(_TightlyCoupled):
    """Error-state UKF (own sigma points) on pseudoranges and pseudorange rates.

    Same parameters as :class:`TightlyCoupledEkf`, plus ``alpha``, ``beta``, ``kappa``
    of the scaled unscented transform (defaults 1, 2, 0). The time update is the EKF's
    (exact for the linear error dynamics); the measurement update is unscented through
    the nonlinear observables at ``INS minus error``; Cholesky failures fall back to
    jitter and then an eigen-decomposition (counted in ``extra["cholesky_fallbacks"]``).
    """

    kind = "ukf"
    # (mean, P, hx, z, R, alpha, beta, kappa) -> (dx, P_new, nis, fallbacks);
    # navsim.estimators.filterpy_based replaces it
    unscented_update = staticmethod(unscented_update)

    def _kalman(self, P: np.ndarray, sat_pos: np.ndarray, sat_vel: np.ndarray, z: np.ndarray, R: np.ndarray,
                m: int) -> tuple[np.ndarray, np.ndarray, float]:
        eng = self._engine()
        st = eng.state
        earth = self.earth
        r_n, r_e = (float(x) for x in earth.radii(st.lat))
        clock = eng.clock if eng.with_clock else np.zeros(2)
        doppler = self.options.use_doppler
        cos_lat = math.cos(st.lat)
        lever = self._with_lever
        if lever:  # (TC.8) at each hypothesis: attitude exp(-[psi x]) C, rate omega - eg
            C = quat_to_mat(st.quat_nb)
            arm_est = C @ self.lever_arm_b
            w, l = self._omega_ib_b, self.lever_arm_b

        def hx(X: np.ndarray) -> np.ndarray:
            # the truth hypothesis of each sigma point: INS minus the error
            lat = st.lat - X[:, 1] / (r_n + st.h)
            lon = st.lon - X[:, 0] / ((r_e + st.h) * cos_lat)
            h = st.h - X[:, 2]
            v = st.velocity_n[None, :] - X[:, 3:6]
            if eng.with_clock:
                cb, cd = clock[0] - X[:, CB], clock[1] - X[:, CD]
            else:
                cb = cd = np.zeros(len(X))
            arm_n = arm_vel = None
            if lever:
                psi = X[:, 6:9]
                arm_n = _rotate_back(psi, np.broadcast_to(arm_est, psi.shape))
                w_true = w[None, :] - X[:, BG]
                turn = np.cross(w_true, l[None, :]) @ C.T  # C (omega x l), rotated back below
                w_ie = earth.earth_rate_n(lat)
                arm_vel = _rotate_back(psi, turn) - np.cross(w_ie, arm_n)
            if eng.with_atmosphere:  # (TC.6) at each hypothesis' position and zenith delays
                a = eng.atm_index
                rho, rate = self._with_atmosphere(lat, lon, h, v, cb, cd, eng.atm[0] - X[:, a],
                                                  eng.atm[1] - X[:, a + 1], sat_pos, sat_vel,
                                                  arm_n=arm_n, arm_velocity_n=arm_vel)
            else:
                rho, rate = predict_observables(lat, lon, h, v, cb, cd, sat_pos, sat_vel, earth, arm_n=arm_n,
                                                arm_velocity_n=arm_vel)
            return np.concatenate([rho, rate], axis=1) if doppler else rho

        opt = self.options
        dx, P_new, nis, fallbacks = self.unscented_update(np.zeros(len(P)), P, hx, z, R, opt.alpha, opt.beta,
                                                          opt.kappa)
        self.cholesky_fallbacks += fallbacks
        return dx, P_new, nis
