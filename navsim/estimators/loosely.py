"""Loosely coupled INS/GNSS: a 15-state closed-loop error-state EKF aided by GNSS fixes.

The INS (:func:`navsim.strapdown.ins.integrate`, most accurate methods the data allow)
runs on bias-compensated IMU data; a 15-state error-state Kalman filter (position,
velocity, attitude, gyro bias, accelerometer bias; :mod:`navsim.estimators._inserror`)
estimates its errors and feeds them back after every update (closed loop), so the error
state is zero between updates and only the covariance is propagated.

Measurements, at every GNSS epoch with at least ``min_satellites`` valid channels:

* position: the single-epoch least-squares fix :func:`navsim.receiver.least_squares_fix`
  (position and receiver clock bias, so a receiver clock error is absorbed whether or not
  ``context.gnss.clock_modelled``), as ``y = mat_en (r_ins_e - r_fix_e) = dr + v``;
  ``R = sigma_rho^2 mat_en (H^T H)^-1_pos mat_en^T`` from the fix geometry and the nominal
  pseudorange sigma;
* velocity (``use_velocity``): :func:`navsim.receiver.velocity_fix` from the Doppler
  pseudorange rates (velocity and clock drift), ``y = v_ins_n - mat_en v_fix_e``,
  ``R = sigma_dot^2 mat_en (H^T H)^-1_vel mat_en^T``.

With ``fix_error="white"``, or when the context has no atmosphere, both are white and
uncorrelated with each other: consistent on white-noise GNSS (the "paper-2012" preset).

Fix error of a standalone receiver (``fix_error="auto"`` with ``context.gnss.atmosphere_modelled``)
---------------------------------------------------------------------------------------
An uncorrected single-frequency receiver's fix carries the atmospheric delays, common to
all satellites up to the elevation mapping; the clock absorbs their mean and the excess
delay of the low satellites lifts the fix. Like a receiver, the filter first removes the
a-priori zenith delays of the context (thin-shell obliquity, DO-229 mapping at the
elevations of a first fix; the fix is repeated)                                   (LC.6)
and models what is left as white noise (the nominal sigma, R as above) plus three ENU
first-order Gauss-Markov states b (:class:`AuxStateIns` with ``aux_tau_s``)::

    y_pos = mat_en (r_ins - r_fix) (+ C l) + b_est = dr + db - w,  H = [I 0 ... | I]   (LC.8)

A zenith delay error dZ moves an LS fix (position + clock) by ``k dZ`` per axis; k was
measured with the fixes themselves over 24 h of the GPS constellation with a 10 deg mask
(:data:`FIX_ZENITH_FACTORS`, recomputed by the tests): vertical 1.95 (ionosphere) and
3.55 (troposphere), horizontal <= 0.13 and <= 0.51. With the independent a-priori
sigmas sI, sT of the context                                                       (LC.7)
``sigma_U = hypot(2.0 sI, 3.6 sT)``, ``sigma_E = sigma_N = hypot(0.15 sI, 0.55 sT)``: for
the standalone preset's context (sI 4.5 m, sT 0.12 m) 9.0 m and 0.68 m. The vertical
error keeps 99 % of its autocorrelation after 1 h (only the satellite set changes it);
the horizontal one decorrelates in 0.7-1.3 ks: correlation times 7200 s and 1200 s
(``fix_error_tau_s``). The Doppler velocity fix stays white; multipath (30 s Gauss-Markov
in the simulator) is not a separate state: the nominal white sigma includes its horizon
value (hypot(1, 3) m), conservative for all but the lowest satellites.

Antenna lever arm (``context.gnss.lever_arm_b_m`` = l, body axes; option ``lever_arm``):
the fixes refer to the antenna, so the predicted measurements are those of the antenna
(:func:`navsim.estimators._inserror.lever_arm_terms`)::

    y_pos = mat_en (r_ins_e - r_fix_e) + C l                                (LC.1)
    y_vel = v_ins + C (omega x l) - omega_ie x C l - mat_en v_fix_e         (LC.2)

with C the INS attitude and omega the bias-compensated body rate of the epoch's
navigation step (its mean over the step: ``dtheta / dt - b_g``). The rows of H are those
of ``L`` (LA.3): identity on position/velocity plus the attitude columns ``-[C l x]``
(position) and ``-[C (omega x l) x] + [omega_ie x][C l x]`` (velocity) and the gyro-bias
columns ``-C [l x]`` (velocity). With a zero lever arm (or ``lever_arm="none"``) the
code is the one without these terms, number for number.

Wheel odometer and non-holonomic constraint (``context.odometer``; option ``odometer``)
---------------------------------------------------------------------------------
With an odometer the error state gains the odometer scale-factor error ``dk`` (estimate
minus truth; :class:`~navsim.estimators._inserror.AuxStateIns`: a random walk of PSD
``2 sigma_g^2 / tau_g`` from the initial variance ``sigma_c^2 + sigma_g^2`` of the nominal
turn-on and Gauss-Markov parts). Every ``odometer_period_s`` (whole navigation steps at
global step multiples; default 1 s) the distance D counted over the interval T and the
mean body velocity of the INS over the same steps, ``vb = mean_k C_k^T v_k``, give::

    y_fwd = (1 + k) vb_y - D / T,      H_fwd = (1 + k) J_y + vb_y e_k           (LC.3)
    y_x   = vb_x,  y_z = vb_z,         H_x = J_x,  H_z = J_z                    (LC.4)

(:func:`~navsim.estimators._inserror.body_velocity_terms` (OD.6): ``J = [0, C^T,
C^T [v x], 0, 0]`` at the update step). (LC.3) is the forward speed the wheel measured;
(LC.4) the non-holonomic constraint: a vehicle on its wheels (on rails) does not move
sideways or vertically in its body frame (Groves 2013, section 16.2.3), ``R_nhc =
nhc_sigma_mps^2`` per axis (default 0.05 m/s: body oscillations tilt the forward axis).
``R_fwd = (q^2 T + p^2 / 6 (+ (slip D)^2 while the INS forward speed changed by more than
0.9 a_slip T)) / T^2`` with q the nominal noise density and p the pulse length (the
quantisation error of a span is a difference of two carries uniform on [0, p)). The
odometer is taken to sit at the IMU. D / T and vb are means over the interval, so their
error is that of its middle: the rows of J are taken through ``x(t - T/2) = (I - F T/2)
x(t)`` (LC.5), F the error dynamics of the engine's current covariance interval (with a
0.2 deg tilt the velocity error changes by ~0.03 m/s within 1 s, five times the forward
sigma of the rail tachometer, so the end-of-interval error is not good enough). A GNSS
update inside an odometer interval removes its correction from the INS velocities
already summed.

Barometric height aiding (``context.baro``; option ``baro``)
-----------------------------------------------------------
With a barometric altimeter the error state gains the error ``db`` of the estimated
altimeter bias b (a first-order Gauss-Markov state, :class:`AuxStateIns` (AX.1), with
the nominal stationary sigma and correlation time of :class:`~navsim.types.NominalBaro`).
Every ``baro_period_s`` (whole navigation steps at global step multiples; default 1 s)
the pressure altitude z of the step end gives::

    y = h_ins - z + b_est = dU + db - v,      H = [e_U | e_b]                (LC.9)

``R = sigma_n^2 + q^2 / 12`` (white noise and rounding of one reading; the altimeter
reads the height of the IMU). ``baro="none"``, or no barometer in the context, is the
filter without these terms, number for number.

Process noise: :meth:`ImuNoise.from_nominal` (ARW, VRW, Gauss-Markov biases with the
nominal sigma and correlation time, rate random walk). Update in Joseph form, covariance
symmetrised and guarded; a divergence becomes ``extra["diverged"]`` (and the attribute
``diverged``): a non-finite or non-positive covariance, a non-finite state, or
``divergence_epochs`` consecutive updates whose NIS exceeds the chi-square quantile of
tail probability ``divergence_probability``.

Speed (``step_batch``): one strapdown call per GNSS interval, the LS fixes of all epochs
of the batch in one vectorised call, and the covariance advanced once per covariance
interval (:class:`~navsim.estimators._inserror.ErrorStateIns`). ``step`` runs the same
code on one step, so both give the same numbers.

References
----------
.. [1] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., 2013, sections 14.1-14.2 (INS/GNSS integration architectures,
       closed-loop correction), 14.2.3 (lever arm) and 14.2.6 (loosely coupled
       measurement model).
.. [2] Bar-Shalom Y., Li X.R., Kirubarajan T., Estimation with Applications to Tracking
       and Navigation, 2001, section 5.4 (NIS consistency test).
.. [3] Groves (2013) [1], sections 6.3 (odometers) and 16.2.3 (odometer and
       non-holonomic-constraint aiding of an INS).
.. [4] Groves (2013) [1], sections 9.3.2 (ionosphere and troposphere models), 14.3.1
       (loosely coupled: time-correlated position errors of the GNSS solution, modelled
       as Gauss-Markov states or by inflating R); RTCA DO-229D (2006) A.4.2.4.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Callable, Sequence, cast

import numpy as np
from numpy.typing import ArrayLike

from ..earth import mat_en
from ..errors import ConfigError
from ..option_checks import (
    check_auto_none,
    check_choice,
    check_integer,
    check_optional_positive_finite,
    check_positive_finite,
    check_probability,
    check_time_constant,
)
from ..receiver import epoch_kernels, least_squares_fix, velocity_fix
from ..rotations import mat_nb_from_hpr, quat_to_mat
from ._inserror import (
    N_STATES,
    NAV,
    AuxStateIns,
    ErrorStateIns,
    ImuNoise,
    body_velocity_terms,
    lever_arm_terms,
    nis_threshold,
)
from .base import (
    Context,
    Estimate,
    EstimateBatch,
    Measurement,
    MeasurementBatch,
    NoiseScalable,
    Prior,
    StepRow,
    row_of,
)
from .tightly import atmosphere_delays

if TYPE_CHECKING:  # type hints only
    from ..earth import EarthModel
    from ..types import GnssObservation, NominalGnss, NominalOdometer

__all__ = ["LooselyCoupledEkf", "gnss_fixes", "FIX_ZENITH_FACTORS", "fix_error_model"]

# Error of a least-squares fix (position + clock) per metre of a common-mode zenith delay
# mapped to the satellites, (horizontal per axis, vertical), RMS over 24 h of the bundled
# GPS constellation with a 10 deg mask at the sites of mountain-railway (47 deg N) and
# paper-2012, measured with the fixes themselves (tests/estimators/test_loosely.py
# recomputes them): ionosphere (thin-shell obliquity) 0.07 E / 0.13 N / 1.95 U,
# troposphere (DO-229 mapping) 0.27-0.28 E / 0.46-0.51 N / 3.55 U; rounded up. The vertical
# error is positive (the fix goes up: the clock absorbs the common part, the excess delay of
# the low satellites pushes the fix away from them).
FIX_ZENITH_FACTORS = {"ionosphere": (0.15, 2.0), "troposphere": (0.55, 3.6)}


def gnss_fixes(observations: Sequence[GnssObservation], min_satellites: int = 4, initial_e: ArrayLike | None = None,
               atmosphere: tuple[float, float, float, float] | None = None,
               earth: EarthModel | None = None) -> tuple[np.ndarray, ...]:
    """Position and velocity fixes of a list of :class:`GnssObservation` (vectorised).

    ``initial_e`` (3,): a starting point of the Gauss-Newton iteration for every epoch
    (e.g. the prior position: fewer iterations than from the Earth's centre).
    ``atmosphere``: None (raw pseudoranges), or ``(ionosphere_zenith_m,
    troposphere_zenith_m, shell_height_m, scale_height_m)``, the a-priori zenith delays a
    standalone receiver removes before its fix (:class:`NominalGnss`): a first fix gives
    the elevations, the delays (thin-shell obliquity and DO-229 mapping,
    :func:`navsim.estimators.tightly.atmosphere_delays`) are subtracted from the
    pseudoranges and the fix is repeated from the first one (``earth`` required).

    Returns
    -------
    ok : (k,) bool, at least ``min_satellites`` valid channels and both fixes converged
    position_e : (k, 3) m. cov_pos : (k, 3, 3) unit-variance position covariance (H^T H)^-1.
    velocity_e : (k, 3) m/s. cov_vel : (k, 3, 3) unit-variance velocity covariance.
    n_valid : (k,) int.
    """
    k = len(observations)
    if k == 0:
        z = np.zeros((0, 3))
        return np.zeros(0, bool), z, np.zeros((0, 3, 3)), z, np.zeros((0, 3, 3)), np.zeros(0, int)
    if k == 1 and atmosphere is None:
        kernels = epoch_kernels()
        if kernels is not None:  # a step-wise estimator's epoch: the compiled fixes without their wrappers
            return _one_epoch_fixes(kernels, observations[0], min_satellites, initial_e)
    if k == 1:  # views, the values np.stack would copy
        (o,) = observations
        sat_pos, sat_vel = np.asarray(o.sat_pos_e)[None], np.asarray(o.sat_vel_e)[None]
        rho, rate = np.asarray(o.pseudorange_m)[None], np.asarray(o.pseudorange_rate_mps)[None]
        valid = np.asarray(o.valid, bool)[None]
    else:
        sat_pos = np.stack([o.sat_pos_e for o in observations])
        sat_vel = np.stack([o.sat_vel_e for o in observations])
        rho = np.stack([o.pseudorange_m for o in observations])
        rate = np.stack([o.pseudorange_rate_mps for o in observations])
        valid = np.stack([np.asarray(o.valid, bool) for o in observations])
    n_valid = valid.sum(axis=1)
    fix = least_squares_fix(sat_pos, rho, valid, initial=initial_e)
    if atmosphere is not None:  # (LC.6) the receiver's a-priori correction
        if earth is None:
            raise ConfigError("gnss_fixes earth", "the Earth model with an atmosphere correction", None)
        iono_z, tropo_z, shell_m, scale_m = atmosphere
        start = fix.position_e if initial_e is None else np.where(fix.ok[:, None], fix.position_e, initial_e)
        lat, lon, h = earth.ecef_to_geodetic(start)
        iono, tropo = atmosphere_delays(lat, lon, h, sat_pos, iono_z, tropo_z, earth, shell_height_m=shell_m,
                                        scale_height_m=scale_m)
        fix = least_squares_fix(sat_pos, rho - iono - tropo, valid, initial=start)
    vfix = velocity_fix(sat_pos, sat_vel, rate, valid, np.where(fix.ok[:, None], fix.position_e, 0.0))
    ok = fix.ok & vfix.ok & (n_valid >= min_satellites)
    return ok, fix.position_e, fix.covariance[:, :3, :3], vfix.velocity_e, vfix.covariance[:, :3, :3], n_valid


# the iteration limits gnss_fixes uses: least_squares_fix's defaults (read there, not repeated)
_LS_MAX_ITER: int = (least_squares_fix.__kwdefaults__ or {})["max_iter"]
_LS_TOL_M: float = (least_squares_fix.__kwdefaults__ or {})["tol_m"]


def _one_epoch_fixes(kernels: tuple[Callable[..., None], Callable[..., None]], o: GnssObservation,
                     min_satellites: int, initial_e: ArrayLike | None) -> tuple[np.ndarray, ...]:
    """:func:`gnss_fixes` of one epoch without the a-priori atmosphere, by the compiled
    kernels (:func:`navsim.receiver.epoch_kernels`) called directly: the inputs, starting
    state and kernel calls of :func:`~navsim.receiver.least_squares_fix` and
    :func:`~navsim.receiver.velocity_fix` (``method="compiled"``) for one epoch, so the
    same numbers, without their per-call array checks and result objects."""
    fix_epochs, velocity_epochs = kernels
    sat = np.ascontiguousarray(np.asarray(o.sat_pos_e, dtype=float)[None])
    m = sat.shape[1]
    if sat.shape[2] != 3:
        raise ConfigError("sat_pos_e", "shape (k, m, 3) or (m, 3)", sat.shape)
    valid = np.ascontiguousarray(np.asarray(o.valid, dtype=bool).reshape(1, m))
    state = np.zeros((1, 4))
    if initial_e is not None:
        init = np.asarray(initial_e, dtype=float)
        state[:, :init.shape[-1]] = init
    out, cov_pos = np.empty((1, 4)), np.empty((1, 4, 4))
    used, ok = np.empty(1, dtype=np.int64), np.empty(1, dtype=bool)
    fix_epochs(sat, np.ascontiguousarray(np.asarray(o.pseudorange_m, dtype=float).reshape(1, m)), valid, state,
               _LS_MAX_ITER, _LS_TOL_M, out, cov_pos, used, ok)
    position = np.zeros((1, 3))
    if ok[0]:  # the fix where it is ok, else zero (velocity_fix's np.where)
        position[0] = out[0, :3]
    vel_out, cov_vel = np.empty((1, 4)), np.empty((1, 4, 4))
    v_used, v_ok = np.empty(1, dtype=np.int64), np.empty(1, dtype=bool)
    velocity_epochs(sat, np.ascontiguousarray(np.asarray(o.sat_vel_e, dtype=float).reshape(sat.shape)),
                    np.ascontiguousarray(np.asarray(o.pseudorange_rate_mps, dtype=float).reshape(1, m)), valid,
                    position, vel_out, cov_vel, v_used, v_ok)
    n_valid = valid.sum(axis=1)
    return (ok & v_ok & (n_valid >= min_satellites), out[:, :3], cov_pos[:, :3, :3], vel_out[:, :3],
            cov_vel[:, :3, :3], n_valid)


def fix_error_model(gnss: NominalGnss, height_m: float = 0.0,
                    tau_s: tuple[float, float] = (1200.0, 7200.0)) -> tuple[np.ndarray, np.ndarray]:
    """Stationary sigma (3,) and correlation time (3,) of the ENU Gauss-Markov fix error.

    The residual zenith delays of a standalone receiver after its a-priori correction
    (1-sigma ``ionosphere_zenith_sigma_m`` and ``troposphere_zenith_sigma_m`` scaled by
    ``exp(-h / H)`` to the receiver height) are independent and common to all
    satellites, so the fix error they cause is ``k_I dI + k_T dT`` per axis with the
    geometry factors :data:`FIX_ZENITH_FACTORS` (LC.7)::

        sigma_h = hypot(k_hI sigma_I, k_hT sigma_T),  sigma_u = hypot(k_uI sigma_I, k_uT sigma_T)

    Correlation times ``tau_s = (horizontal, vertical)``: the horizontal error follows the
    satellite geometry (measured 1/e time of its autocorrelation 0.7-1.3 ks, about zero at
    30 min, tests/estimators/test_loosely.py); the vertical error keeps its sign and 90 %
    of its size for hours (autocorrelation of the raw error 0.99 at 1 h; the 2 h default
    leaves the filter some room for the geometry change of a new satellite).

    Parameters
    ----------
    gnss : NominalGnss. height_m : receiver height, m. tau_s : (2,) s.

    Returns
    -------
    sigma_m : (3,) E, N, U, m. tau_s : (3,) s.
    """
    k_hi, k_ui = FIX_ZENITH_FACTORS["ionosphere"]
    k_ht, k_ut = FIX_ZENITH_FACTORS["troposphere"]
    s_i = float(gnss.ionosphere_zenith_sigma_m)
    s_t = float(gnss.troposphere_zenith_sigma_m) * math.exp(-height_m / gnss.troposphere_scale_height_m)
    sigma_h, sigma_u = math.hypot(k_hi * s_i, k_ht * s_t), math.hypot(k_ui * s_i, k_ut * s_t)  # (LC.7)
    return np.array([sigma_h, sigma_h, sigma_u]), np.array([tau_s[0], tau_s[0], tau_s[1]], dtype=float)


class LooselyCoupledEkf(NoiseScalable):
    """15-state closed-loop error-state EKF aided by GNSS position/velocity fixes.

    Parameters
    ----------
    use_velocity : bool
        Also use the Doppler velocity fix (default True).
    min_satellites : int
        Fewest valid channels for an update (>= 4).
    noise_scale, bias_scale : float
        Factors on the nominal IMU white-noise densities and bias sigmas (Q tuning).
    measurement_scale : float
        Factor on the GNSS sigmas (R tuning).
    gyro_scale_sigma, accel_scale_sigma, scale_tau_s : float
        Unmodelled gyro and accelerometer scale-factor/misalignment: 1-sigma of each element
        of the matrices (dimensionless, default 0: off) and the correlation time (s,
        default 5), covered as rate- and acceleration-proportional attitude and velocity
        noise (:mod:`navsim.estimators._inserror`, (RS.1), (RS.2)).
    covariance_period_s : float or None
        Longest covariance interval (default: the GNSS period, at most 1 s).
    divergence_probability : float
        Tail probability of the NIS test used for the divergence flag.
    divergence_epochs : int
        Consecutive failed NIS tests that raise the flag.
    coning, sculling, position : str or None
        Strapdown method names; None = the most accurate the data allow.
    lever_arm : {"auto", "none"}
        "auto": compensate the antenna lever arm of ``context.gnss.lever_arm_b_m``
        (LC.1)-(LC.2); "none": take the antenna to be at the IMU (uncompensated).
    odometer : {"auto", "none"}
        "auto": with an odometer in the context, the forward-speed update (LC.3) and the
        non-holonomic constraint (LC.4) with a scale-factor state; "none": today's
        filter, number for number.
    odometer_period_s : float
        Interval of the odometer updates, s (rounded to whole navigation steps).
    nhc : bool
        Apply the non-holonomic constraint with the odometer updates (default True).
    nhc_sigma_mps : float
        Its 1-sigma per axis, m/s.
    fix_error : {"auto", "white"}
        "auto": with ``context.gnss.atmosphere_modelled`` (an uncorrected single-frequency
        receiver), the fixes are made from pseudoranges corrected with the a-priori zenith
        delays (LC.6) and their residual error is three ENU Gauss-Markov states (LC.7-8);
        "white" (and "auto" without atmosphere): the fixes as white measurements, the
        filter of before, number for number.
    fix_error_tau_s : (2,) float
        Correlation times of the horizontal and vertical fix-error states, s.
    baro : {"auto", "none"}
        "auto": with a barometer in the context, the height update (LC.9) with a
        Gauss-Markov altimeter-bias state; "none": the filter without it, number for number.
    baro_period_s : float
        Interval of the barometer updates, s (rounded to whole navigation steps).

    Attributes
    ----------
    engine : ErrorStateIns (after reset). diverged : bool. last_update : dict.
    """

    NOISE_PROCESS = ('engine.Qc',)
    NOISE_MEASUREMENT_SIGMA = ('sigma_pos', 'sigma_vel')
    # where set_noise_scale finds Q and R after reset (navsim.estimators.base.NoiseScalable)

    def __init__(self, use_velocity: bool = True, min_satellites: int = 4, noise_scale: float = 1.0,
                 bias_scale: float = 1.0, measurement_scale: float = 1.0, covariance_period_s: float | None = None,
                 divergence_probability: float = 1e-6, divergence_epochs: int = 10, coning: str | None = None,
                 sculling: str | None = None, position: str | None = None, lever_arm: str = "auto",
                 odometer: str = "auto", odometer_period_s: float = 1.0, nhc: bool = True,
                 nhc_sigma_mps: float = 0.05, fix_error: str = "auto",
                 fix_error_tau_s: tuple[float, float] = (1200.0, 7200.0), baro: str = "auto",
                 baro_period_s: float = 1.0, gyro_scale_sigma: float = 0.0, accel_scale_sigma: float = 0.0,
                 scale_tau_s: float = 5.0) -> None:
        self.baro = check_auto_none("baro", baro)
        self.baro_period_s = check_positive_finite("baro_period_s", baro_period_s)
        self._scale = dict(gyro_scale_sigma=float(gyro_scale_sigma), accel_scale_sigma=float(accel_scale_sigma),
                           scale_tau_s=float(scale_tau_s))
        ImuNoise(**self._scale)  # checks them
        self.fix_error = check_choice("fix_error", fix_error, ("auto", "white"))
        expected = "two positive correlation times, s (horizontal, vertical)"
        try:
            tau = tuple(fix_error_tau_s)
        except TypeError:
            raise ConfigError("fix_error_tau_s", expected, fix_error_tau_s) from None
        if len(tau) != 2:
            raise ConfigError("fix_error_tau_s", expected, fix_error_tau_s)
        self.fix_error_tau_s = (check_time_constant("fix_error_tau_s", tau[0], expected),
                                check_time_constant("fix_error_tau_s", tau[1], expected))
        check_integer("min_satellites", min_satellites, 4)
        check_positive_finite("measurement_scale", measurement_scale, "a positive finite factor")
        check_optional_positive_finite("covariance_period_s", covariance_period_s,
                                       "a positive finite time, s, or None")
        check_probability("divergence_probability", divergence_probability)
        check_integer("divergence_epochs", divergence_epochs, 1, "a positive integer")
        self.lever_arm = check_auto_none("lever_arm", lever_arm)
        check_auto_none("odometer", odometer)
        check_positive_finite("odometer_period_s", odometer_period_s)
        check_positive_finite("nhc_sigma_mps", nhc_sigma_mps)
        self.odometer = odometer
        self.odometer_period_s = float(odometer_period_s)
        self.nhc = bool(nhc)
        self.nhc_sigma_mps = float(nhc_sigma_mps)
        self.use_velocity = bool(use_velocity)
        self.min_satellites = int(min_satellites)
        self.noise_scale, self.bias_scale = noise_scale, bias_scale
        self.measurement_scale = float(measurement_scale)
        self.covariance_period_s = covariance_period_s
        self.divergence_probability = float(divergence_probability)
        self.divergence_epochs = int(divergence_epochs)
        self.methods = dict(coning=coning, sculling=sculling, position=position)
        self.engine: ErrorStateIns | None = None
        self._no_aiding = False  # set by reset: neither odometer nor barometer updates
        self.diverged = False
        self.last_update: dict = {}

    # ------------------------------------------------------------------------ interface
    def reset(self, context: Context, prior: Prior) -> None:
        """Start an episode from the prior (INS state and 9 x 9 covariance)."""
        noise = ImuNoise.from_nominal(context.imu, noise_scale=self.noise_scale, bias_scale=self.bias_scale)
        if self._scale["gyro_scale_sigma"] > 0.0 or self._scale["accel_scale_sigma"] > 0.0:  # (RS.1), (RS.2)
            noise = dataclasses.replace(noise, **self._scale)
        period = self.covariance_period_s or min(context.gnss_period_s, 1.0)
        steps = max(1, round(period / context.nav_period_s))
        spec = getattr(context, "odometer", None)
        self._odo = spec if self.odometer == "auto" else None
        gn = context.gnss
        self._atmosphere: tuple[float, float, float, float] | None = None
        self._fix_index: int | None = None  # first auxiliary index of the fix-error states
        if self.fix_error == "auto" and getattr(gn, "atmosphere_modelled", False):
            sigma, tau_fix = fix_error_model(gn, float(prior.h), self.fix_error_tau_s)
            if sigma[2] > 0.0:
                self._atmosphere = (gn.ionosphere_zenith_m, gn.troposphere_zenith_m, gn.ionosphere_shell_height_m,
                                    gn.troposphere_scale_height_m)
        aux_var: list[float] = []
        aux_psd: list[float] = []
        aux_tau: list[float] = []
        odo = self._odo
        if odo is not None:  # the odometer scale-factor error (a random walk)
            tau = float(odo.scale_factor_tau_s)
            psd = 2.0 * odo.scale_factor_gm_sigma**2 / tau if math.isfinite(tau) else 0.0
            aux_var.append(odo.scale_factor_sigma**2 + odo.scale_factor_gm_sigma**2)
            aux_psd.append(psd)
            aux_tau.append(math.inf)
        if self._atmosphere is not None:  # (LC.8) three Gauss-Markov fix-error states
            self._fix_index = len(aux_var)
            aux_var.extend(sigma**2)
            aux_psd.extend(2.0 * sigma**2 / tau_fix)
            aux_tau.extend(tau_fix)
        baro_spec = getattr(context, "baro", None)
        baro = self._baro = baro_spec if self.baro == "auto" else None
        self._baro_index: int | None = None
        if baro is not None:  # (LC.9) the Gauss-Markov altimeter bias
            self._baro_index = len(aux_var)
            aux_var.append(baro.bias_sigma_m**2)
            aux_psd.append(2.0 * baro.bias_sigma_m**2 / baro.bias_tau_s)
            aux_tau.append(baro.bias_tau_s)
            self._baro_steps = max(1, round(self.baro_period_s / context.nav_period_s))
            self._baro_var = max(baro.noise_sigma_m**2 + baro.resolution_m**2 / 12.0, 1e-12)
            self.baro_nis = math.nan
        methods = self.methods
        if not aux_var:
            self.engine = ErrorStateIns(context, prior, noise, interval_steps=steps, coning=methods["coning"],
                                        sculling=methods["sculling"], position=methods["position"])
        else:
            self.engine = AuxStateIns(context, prior, noise, interval_steps=steps, coning=methods["coning"],
                                      sculling=methods["sculling"], position=methods["position"],
                                      aux_variance=aux_var, aux_psd=aux_psd,
                                      aux_tau_s=aux_tau if self._atmosphere is not None or self._baro is not None
                                      else None)
        if self._odo is not None:
            self._odo_steps = max(1, round(self.odometer_period_s / context.nav_period_s))
            self._odo_sum, self._odo_n, self._odo_missing = 0.0, 0, False
            self._odo_vb = np.zeros(3)
            self._odo_v0: float | None = None  # INS forward speed at the last odometer update
            self.odometer_nis = math.nan
        self.sigma_pos = self.measurement_scale * context.gnss.pseudorange_sigma_m
        self.sigma_vel = self.measurement_scale * context.gnss.doppler_sigma_mps
        dof = 6 if self.use_velocity else 3
        self._nis_limit = nis_threshold(dof, self.divergence_probability)
        self._failed = 0
        self.diverged = False
        self.last_update = {}
        self._initial_e = context.earth.geodetic_to_ecef(prior.lat, prior.lon, prior.h)
        arm = getattr(context.gnss, "lever_arm_b_m", (0.0, 0.0, 0.0)) if self.lever_arm == "auto" else (0.0, 0.0, 0.0)
        self.lever_arm_b = np.array(arm, dtype=float)
        self._with_lever = bool(np.any(self.lever_arm_b != 0.0))
        self._no_aiding = self._odo is None and self._baro is None

    def _engine(self) -> ErrorStateIns:
        """The engine of the episode (made by :meth:`reset`)."""
        eng = self.engine
        if eng is None:
            raise ConfigError("LooselyCoupledEkf", "reset(context, prior) before stepping", "no reset")
        return eng

    def _aux_engine(self) -> AuxStateIns:
        """The engine when the options in use gave it auxiliary states (odometer scale,
        fix errors, barometer bias: :meth:`reset` made an :class:`AuxStateIns`)."""
        return cast(AuxStateIns, self._engine())

    def _ins_only_step(self, m: Measurement) -> bool:
        """True when step ``m`` makes no update (no GNSS epoch, no odometer or barometer update due)."""
        return m.gnss is None and (self._odo is None or (m.step + 1) % self._odo_steps != 0) and (
            self._baro is None or getattr(m, "baro_alt_m", None) is None or (m.step + 1) % self._baro_steps != 0)

    def _ins_step(self, m: Measurement, eng: ErrorStateIns) -> tuple[np.ndarray, np.ndarray]:
        """A step without an update on the engine's one-step path: row (9,), covariance (9, 9)."""
        row, cov = eng.advance_row(m.dtheta_sub, m.dv_sub, m.dtheta_r, m.dv_r)
        if self._odo is not None:
            odo = getattr(m, "odometer_ds_m", None)
            self._odometer_accumulate(row[None], None if odo is None else (odo,), 0, 1)
        if eng.diverged:
            self.diverged = True
        return row, cov

    def _ins_extra(self, eng: ErrorStateIns) -> dict:
        """The ``extra`` of an :class:`Estimate`: divergence flag, bias estimates and the
        auxiliary states of the options in use (fix errors, odometer scale, baro bias)."""
        extra = {"diverged": self.diverged, "gyro_bias": eng.gyro_bias.copy(), "accel_bias": eng.accel_bias.copy()}
        if self._fix_index is not None:
            extra["fix_error_enu"] = self._aux_engine().aux_now()[self._fix_index:self._fix_index + 3]
        if self._odo is not None:
            extra["odometer_scale"] = float(self._aux_engine().aux[0])
            extra["odometer_nis"] = self.odometer_nis
        if self._baro_index is not None:
            extra["baro_bias_m"] = float(self._aux_engine().aux_now()[self._baro_index])
        return extra

    def step_row(self, measurement: Measurement) -> StepRow:
        """:meth:`step` as ``(row (9,), covariance (9, 9), nis, nis_dof)`` (the
        :class:`~navsim.estimators.base.RowStepping` protocol): the same numbers, and no
        :class:`Estimate` built for a step without an update."""
        eng = self.engine
        m = measurement
        if eng is not None and m.gnss is None:
            if self._no_aiding:  # no odometer, no barometer: every step without an epoch is INS only
                row, cov = eng.advance_row(m.dtheta_sub, m.dv_sub, m.dtheta_r, m.dv_r)
                if eng.diverged:
                    self.diverged = True
                return row, cov, None, None
            if self._ins_only_step(m):
                row, cov = self._ins_step(m, eng)
                return row, cov, None, None
        elif eng is not None and self._epoch_only(m):
            return self._epoch_row(m)
        return row_of(self.step(m))

    def step(self, measurement: Measurement) -> Estimate:
        """One navigation step: the batch path on a batch of one at update steps (GNSS epoch,
        end of an odometer interval), the engine's one-step INS path in between (the same
        operations, see :meth:`ErrorStateIns.advance_body`)."""
        m = measurement
        eng = self.engine
        if eng is None:
            raise ConfigError("LooselyCoupledEkf", "reset(context, prior) before stepping", "no reset")
        if self._ins_only_step(m):
            row, cov = self._ins_step(m, eng)
            lat, lon, h, ve, vn, vu, heading, pitch, roll = row.tolist()
            return Estimate(m.t, lat, lon, h, np.array((ve, vn, vu)), heading, pitch, roll, covariance=cov,
                            extra=self._ins_extra(eng))
        if self._epoch_only(m):
            return self._epoch_step(m)
        out = self.step_batch(MeasurementBatch.of(m))
        row = out.solution[0]
        extra = self._ins_extra(eng)
        if self._baro is not None:
            extra["baro_nis"] = self.baro_nis
        if m.gnss is not None:
            extra["n_valid"] = self.last_update.get("n_valid", 0)
        nis = None if math.isnan(out.nis[0]) else float(out.nis[0])
        return Estimate(m.t, row[0], row[1], row[2], row[3:6].copy(), row[6], row[7], row[8],
                        covariance=None if out.covariance is None else out.covariance[0], nis=nis,
                        nis_dof=int(out.nis_dof[0]) if nis is not None else None, extra=extra)

    def _epoch_only(self, m: Measurement) -> bool:
        """True when step ``m`` is a GNSS epoch whose only update is the GNSS one, without a
        lever arm (the path of :meth:`_epoch_row`)."""
        return m.gnss is not None and self._odo is None and not self._with_lever and (
            self._baro is None or getattr(m, "baro_alt_m", None) is None or (m.step + 1) % self._baro_steps != 0)

    def _epoch_row(self, m: Measurement) -> StepRow:
        """The :data:`StepRow` of a step of :meth:`_epoch_only`: the operations of
        :meth:`step_batch` on a batch of one (the fix of the epoch, the INS step, the
        update), with the INS step on the engine's one-step path
        (:meth:`ErrorStateIns.advance_step`, the same numbers) and no batch built."""
        eng = self._engine()
        gnss = cast("GnssObservation", m.gnss)  # an epoch (_epoch_only)
        ok, pos_e, cov_pos, vel_e, cov_vel, n_valid = gnss_fixes((gnss,), self.min_satellites, self._initial_e,
                                                                 self._atmosphere, eng.earth)
        rows, cov = eng.advance_step(m.dtheta_sub, m.dv_sub, m.dtheta_r, m.dv_r)
        nis = nis_dof = None
        if ok[0]:
            value, dof = self._update(pos_e[0], cov_pos[0], vel_e[0], cov_vel[0])
            self.last_update = {"index": 0, "n_valid": int(n_valid[0]), "nis": value}
            row = eng.current_row()
            covariance = eng.covariance[NAV, NAV].copy()
            if not math.isnan(value):
                nis, nis_dof = float(value), int(dof)
        else:
            row = rows[0]
            covariance = cov[0]
        self.diverged = self.diverged or eng.diverged
        return row, covariance, nis, nis_dof

    def _epoch_step(self, m: Measurement) -> Estimate:
        """:meth:`step` at a step of :meth:`_epoch_only`: :meth:`_epoch_row` as an :class:`Estimate`."""
        row, covariance, nis, nis_dof = self._epoch_row(m)
        extra = self._ins_extra(self._engine())  # no odometer on this path
        if self._baro is not None:
            extra["baro_nis"] = self.baro_nis
        extra["n_valid"] = self.last_update.get("n_valid", 0)
        lat, lon, h, ve, vn, vu, heading, pitch, roll = row.tolist()
        return Estimate(m.t, lat, lon, h, np.array((ve, vn, vu)), heading, pitch, roll, covariance=covariance,
                        nis=nis, nis_dof=nis_dof, extra=extra)

    def step_batch(self, batch: MeasurementBatch) -> EstimateBatch:
        """n steps at once: one strapdown call per GNSS interval, vectorised fixes."""
        eng = self.engine
        if eng is None:
            raise ConfigError("LooselyCoupledEkf", "reset(context, prior) before stepping", "no reset")
        n = len(batch)
        solution = np.empty((n, 9))
        covariance = np.empty((n, 9, 9))
        nis = np.full(n, np.nan)
        nis_dof = np.zeros(n, dtype=int)
        epochs = list(batch.gnss)
        ok, pos_e, cov_pos, vel_e, cov_vel, n_valid = gnss_fixes([o for _, o in epochs], self.min_satellites,
                                                                 self._initial_e, self._atmosphere, eng.earth)
        body = eng.prepare(batch.dtheta_sub, batch.dv_sub, batch.dtheta_r, batch.dv_r)
        # update steps: the epochs with a fix (missing data is a value: an epoch without
        # one is just INS) and, with an odometer, the ends of the odometer intervals
        events: dict[int, int | None] = {index: e for e, (index, _) in enumerate(epochs) if ok[e]}
        odo_due: set[int] = set()
        if self._odo is not None:
            steps = np.asarray(batch.step)
            odo_due = set(np.flatnonzero((steps + 1) % self._odo_steps == 0).tolist())
            odo_ds = getattr(batch, "odometer_ds_m", None)
            events.update({i: None for i in odo_due if i not in events})
        baro_due: set[int] = set()
        baro_alt = getattr(batch, "baro_alt_m", None)
        if self._baro is not None and baro_alt is not None:
            baro_due = set(np.flatnonzero((np.asarray(batch.step) + 1) % self._baro_steps == 0).tolist())
            events.update({i: None for i in baro_due if i not in events})
        start = 0
        for index in sorted(events):
            e = events[index]
            stop = index + 1
            if stop > start:
                rows, cov = eng.advance_body(body, start, stop)
                solution[start:stop], covariance[start:stop] = rows, cov
                if self._odo is not None:
                    self._odometer_accumulate(rows, odo_ds, start, stop)
            if e is not None:
                # mean compensated body rate over the epoch's step (for the lever-arm velocity)
                omega_ib_b = body.dtheta1[index] / eng.dt - eng.gyro_bias if self._with_lever else None
                value, dof = self._update(pos_e[e], cov_pos[e], vel_e[e], cov_vel[e], omega_ib_b)
                self.last_update = {"index": index, "n_valid": int(n_valid[e]), "nis": value}
                nis[index], nis_dof[index] = value, dof
            if index in odo_due:
                value, dof = self._odometer_update()
                if dof:
                    if nis_dof[index]:  # sequential updates in one step: the NIS add up
                        nis[index], nis_dof[index] = nis[index] + value, nis_dof[index] + dof
                    else:
                        nis[index], nis_dof[index] = value, dof
            if index in baro_due and baro_alt is not None:
                value, dof = self._baro_update(float(baro_alt[index]))
                if dof:
                    if nis_dof[index]:
                        nis[index], nis_dof[index] = nis[index] + value, nis_dof[index] + dof
                    else:
                        nis[index], nis_dof[index] = value, dof
            solution[index] = eng.current_row()
            covariance[index] = eng.covariance[NAV, NAV]
            start = stop
        if start < n:
            rows, cov = eng.advance_body(body, start)
            solution[start:], covariance[start:] = rows, cov
            if self._odo is not None:
                self._odometer_accumulate(rows, odo_ds, start, n)
        self.diverged = self.diverged or eng.diverged
        return EstimateBatch(solution, covariance, nis, nis_dof)

    # ------------------------------------------------------------------------ update
    def _update(self, pos_e: np.ndarray, cov_pos: np.ndarray, vel_e: np.ndarray, cov_vel: np.ndarray,
                omega_ib_b: np.ndarray | None = None) -> tuple[float, int]:
        eng = self._engine()
        st = eng.state
        earth = eng.earth
        m_en = mat_en(st.lat, st.lon)
        r_ins = earth.geodetic_to_ecef(st.lat, st.lon, st.h)
        y_pos = m_en @ (r_ins - pos_e)  # y = r_ins - r_fix = dr + v
        if self._with_lever:  # (LC.1), (LC.2): the fix is the antenna's
            omega = cast(np.ndarray, omega_ib_b)  # step_batch passes the epoch step's rate with a lever arm
            arm_n, arm_vel_n, L = lever_arm_terms(quat_to_mat(st.quat_nb), omega, self.lever_arm_b,
                                                  earth.earth_rate_n(st.lat))
            y_pos = y_pos + arm_n
        R_pos = self.sigma_pos**2 * (m_en @ cov_pos @ m_en.T)
        if self.use_velocity:
            y_vel = st.velocity_n - m_en @ vel_e  # y = v_ins - v_fix = dv + v
            R_vel = self.sigma_vel**2 * (m_en @ cov_vel @ m_en.T)
            H: np.ndarray = np.zeros((6, N_STATES))
            H[:6, :6] = np.eye(6)
            if self._with_lever:
                y_vel = y_vel + arm_vel_n
                H = L
            R = np.zeros((6, 6))
            R[:3, :3], R[3:, 3:] = R_pos, R_vel
            y = np.concatenate([y_pos, y_vel])
        else:
            H = np.zeros((3, N_STATES))
            H[:, :3] = np.eye(3)
            if self._with_lever:
                H = L[:3]
            R, y = R_pos, y_pos
        if self._fix_index is not None:  # (LC.8) y = dr + db - w with the fix error b
            i = N_STATES + self._fix_index
            aux = self._aux_engine()
            y[:3] += aux.aux_now()[self._fix_index:self._fix_index + 3]
            H = np.concatenate([H, np.zeros((len(y), aux.n_states - N_STATES))], axis=1)
            H[0, i], H[1, i + 1], H[2, i + 2] = 1.0, 1.0, 1.0
        value, dx = eng.update(H, 0.5 * (R + R.T), y)
        self._odometer_correct(dx)
        if not math.isfinite(value) or value > self._nis_limit:
            self._failed += 1
        else:
            self._failed = 0
        if self._failed >= self.divergence_epochs:
            self.diverged = True
        return value, len(y)

    def _odometer_correct(self, dx: np.ndarray) -> None:
        """The INS rows already summed for the odometer carry the error an update just
        removed: remove it from them too (first order, as if constant over the interval)."""
        if self._odo is not None and self._odo_n:
            st = self._engine().state
            self._odo_vb = self._odo_vb - self._odo_n * (
                body_velocity_terms(quat_to_mat(st.quat_nb), st.velocity_n)[1] @ dx[:N_STATES])

    def _baro_update(self, altitude_m: float) -> tuple[float, int]:
        """(LC.9) at the current step with the pressure altitude ``altitude_m``; (nis, dof)."""
        eng = self._aux_engine()
        i = cast(int, self._baro_index)  # made by reset with the barometer
        if not math.isfinite(altitude_m):
            self.baro_nis = math.nan
            return math.nan, 0
        H = np.zeros((1, eng.n_states))
        H[0, 2], H[0, N_STATES + i] = 1.0, 1.0
        y = np.array([eng.state.h - altitude_m + eng.aux_now()[i]])
        value, dx = eng.update(H, np.array([[self._baro_var]]), y)
        self._odometer_correct(dx)
        self.baro_nis = value
        return value, 1

    # ------------------------------------------------------------------------ odometer
    def _odometer_accumulate(self, rows: np.ndarray, odo_ds: Sequence[float] | np.ndarray | None, start: int,
                             stop: int) -> None:
        """Add the INS body velocities C_k^T v_k and the odometer distances of steps start:stop."""
        mats = mat_nb_from_hpr(rows[:, 6], rows[:, 7], rows[:, 8])
        self._odo_vb = self._odo_vb + np.einsum("kji,kj->i", mats, rows[:, 3:6])
        self._odo_n += stop - start
        if odo_ds is None:
            self._odo_missing = True
        else:
            self._odo_sum += float(np.sum(odo_ds[start:stop]))

    def _odometer_update(self) -> tuple[float, int]:
        """(LC.3)-(LC.4) at the current step; returns (nis, dof) (dof 0: no update)."""
        eng = self._aux_engine()
        spec = cast("NominalOdometer", self._odo)  # an odometer update: reset found one
        count, missing = self._odo_n, self._odo_missing
        vb_mean = self._odo_vb / max(count, 1)
        D = self._odo_sum
        self._odo_sum, self._odo_n, self._odo_missing = 0.0, 0, False
        self._odo_vb = np.zeros(3)
        st = eng.state
        C = quat_to_mat(st.quat_nb)
        vb_now, J = body_velocity_terms(C, st.velocity_n)
        v0, self._odo_v0 = self._odo_v0, float(vb_now[1])
        if count == 0 or missing:
            self.odometer_nis = math.nan
            return math.nan, 0
        T = count * eng.dt
        k = float(eng.aux[0])
        var_fwd = spec.noise_density_m_per_sqrt_s**2 * T + spec.pulse_length_m**2 / 6.0
        if spec.slip_fraction > 0.0 and v0 is not None \
                and abs(float(vb_now[1]) - v0) > 0.9 * spec.slip_accel_threshold_mps2 * T:
            var_fwd += (spec.slip_fraction * D) ** 2
        rows = [1, 0, 2] if self.nhc else [1]
        # the measured quantities are means over the interval, whose error is that of its
        # middle: x(t - T/2) = (I - F T/2) x(t) to first order                    (LC.5)
        J = J - (0.5 * T) * (J @ eng.dynamics)
        H = np.zeros((len(rows), eng.n_states))
        H[:, :N_STATES] = J[rows]
        H[0, :N_STATES] *= 1.0 + k  # (LC.3)
        H[0, N_STATES] = vb_mean[1]
        y = np.empty(len(rows))
        y[0] = (1.0 + k) * vb_mean[1] - D / T
        R = np.zeros((len(rows), len(rows)))
        R[0, 0] = max(var_fwd, 1e-12) / (T * T)
        if self.nhc:  # (LC.4)
            y[1], y[2] = vb_mean[0], vb_mean[2]
            R[1, 1] = R[2, 2] = self.nhc_sigma_mps**2
        value, _ = eng.update(H, R, y)
        self._odo_v0 = float(body_velocity_terms(quat_to_mat(eng.state.quat_nb), eng.state.velocity_n)[0][1])
        self.odometer_nis = value
        return value, len(y)

    @property
    def bias_estimates(self) -> tuple[np.ndarray, np.ndarray]:
        """(gyro_bias rad/s, accel_bias m/s^2) in body axes."""
        eng = self._engine()
        return eng.gyro_bias.copy(), eng.accel_bias.copy()

