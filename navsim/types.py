"""The values that cross layers: one home for what the core, the estimators and the faces exchange.

Everything here is plain data (frozen dataclasses of floats and NumPy arrays); this
module imports nothing of navsim but the Earth model and the track protocol (for type
hints only), so the simulator, the receiver, the estimators, the Gymnasium env and the
FMUs can all import it without pulling in each other.

* :class:`NominalImu`, :class:`NominalGnss`, :class:`NominalOdometer`, :class:`NominalBaro`: the *nominal*
  (datasheet) sensor specifications an estimator is told, never the simulator's drawn
  errors; :class:`Context` bundles them with the map, the Earth model and the time base.
* :class:`GnssObservation`, :class:`Measurement`, :class:`MeasurementBatch`: the sensor
  data of one navigation step, or of n consecutive steps.
* :class:`NavSolution`: a navigation solution with an optional covariance. The prior an
  estimator is reset with and the estimate it returns are the same value at two times;
  ``Prior`` and ``Estimate`` are kept as names of this one type.
  :class:`EstimateBatch`: the solutions of n steps.
* :data:`STATE_LABELS`: the error vector the 9 x 9 covariances are over.
* :data:`FloatArray`, :data:`IntArray`, :data:`BoolArray`: the annotation aliases of the
  package's NumPy arrays (``numpy.typing.NDArray`` of float64, int64, bool);
  :data:`FloatOrArray`: a float or a float array, for the broadcasting functions.

Frames and units follow the package conventions (:mod:`navsim`): geodetic latitude,
longitude (rad) and height (m); ENU velocity (m/s); heading, pitch, roll (rad) of the
body (x right, y forward, z up) relative to ENU. The covariance is 9 x 9 over
``[dE, dN, dU (m), dvE, dvN, dvU (m/s), psi_E, psi_N, psi_U (rad)]``, ``psi`` being the
small rotation of the estimated attitude relative to the true one about the ENU axes
(``mat_nb_est = (I + [psi x]) mat_nb_true``); ``nan`` on a diagonal entry marks a
component the estimator does not estimate (e.g. GNSS only: no attitude).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:  # type hints only: no import of the track or Earth modules at run time
    from .earth import EarthModel
    from .track import Track

__all__ = [
    "STATE_LABELS",
    "FloatArray",
    "IntArray",
    "BoolArray",
    "FloatOrArray",
    "NominalImu",
    "NominalGnss",
    "NominalOdometer",
    "NominalBaro",
    "Context",
    "GnssObservation",
    "Measurement",
    "MeasurementBatch",
    "NavSolution",
    "Prior",
    "Estimate",
    "EstimateBatch",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]
FloatOrArray = float | NDArray[np.floating[Any]]

STATE_LABELS = ("dE", "dN", "dU", "dvE", "dvN", "dvU", "psiE", "psiN", "psiU")


@dataclass(frozen=True, slots=True)
class NominalImu:
    """The IMU specification an estimator is told (datasheet values, 1-sigma).

    gyro_arw : rad/sqrt(s). accel_vrw : m/s/sqrt(s). gyro_bias_sigma : rad/s and
    accel_bias_sigma : m/s^2 (turn-on plus instability). gyro_bias_tau_s,
    accel_bias_tau_s : correlation times of the bias instability, s. gyro_rrw :
    rad/s/sqrt(s), accel_rrw : m/s^2/sqrt(s).
    """

    gyro_arw: float = 0.0
    accel_vrw: float = 0.0
    gyro_bias_sigma: float = 0.0
    accel_bias_sigma: float = 0.0
    gyro_bias_tau_s: float = 3600.0
    accel_bias_tau_s: float = 3600.0
    gyro_rrw: float = 0.0
    accel_rrw: float = 0.0


@dataclass(frozen=True, slots=True)
class NominalGnss:
    """The GNSS receiver specification an estimator is told (1-sigma).

    pseudorange_sigma_m, doppler_sigma_mps : measurement noise. clock_modelled : True
    when the receiver clock error is present in the measurements (False: the paper's
    case, clock error compensated). clock_bias_sigma_m, clock_drift_sigma_mps : initial
    uncertainty; clock_phase_psd, clock_freq_psd : two-state clock model PSDs
    (m^2/s and m^2/s^3).

    Atmosphere (what a single-frequency receiver knows of it, not the simulator's delays):
    atmosphere_modelled : True when uncorrected ionospheric/tropospheric delays are in the
    pseudoranges (False: the defaults below are unused, nothing changes).
    ionosphere_zenith_m : a-priori vertical ionospheric code delay the receiver applies
    (broadcast-model-like value), mapped to slant with the thin-shell obliquity factor
    at ionosphere_shell_height_m (m above the Earth model's equatorial radius).
    troposphere_zenith_m : a-priori zenith tropospheric delay at sea level from a
    standard model, scaled by exp(-h / troposphere_scale_height_m) and mapped to slant
    with the RTCA DO-229 function. ionosphere_zenith_sigma_m, troposphere_zenith_sigma_m :
    1-sigma uncertainty of those a-priori zenith delays (0: the delay is absent).

    lever_arm_b_m : (3,) tuple, m. Position of the antenna phase centre relative to the
    IMU in body axes (x right, y forward, z up), as surveyed by the installer; the
    measurements refer to the antenna. (0, 0, 0): antenna at the IMU.
    """

    pseudorange_sigma_m: float = 15.0
    doppler_sigma_mps: float = 0.5
    clock_modelled: bool = False
    clock_bias_sigma_m: float = 0.0
    clock_drift_sigma_mps: float = 0.0
    clock_phase_psd: float = 0.0
    clock_freq_psd: float = 0.0
    atmosphere_modelled: bool = False
    ionosphere_zenith_m: float = 0.0
    ionosphere_zenith_sigma_m: float = 0.0
    ionosphere_shell_height_m: float = 350_000.0
    troposphere_zenith_m: float = 0.0
    troposphere_zenith_sigma_m: float = 0.0
    troposphere_scale_height_m: float = 8_000.0
    lever_arm_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True, slots=True)
class NominalOdometer:
    """The wheel-odometer specification an estimator is told (1-sigma, datasheet values).

    pulse_length_m : distance per encoder pulse, m (0: no quantiser); the counted
    distance of a span is within one pulse of the rolled one, so a span's quantisation
    error has variance ``p^2 / 6`` (two independent residuals, uniform on [0, p)).
    scale_factor_sigma : turn-on scale-factor uncertainty (wheel diameter), dimensionless.
    scale_factor_gm_sigma, scale_factor_tau_s : slowly varying scale-factor part (wear,
    adhesion): stationary sigma and correlation time, s. noise_density_m_per_sqrt_s :
    white distance noise, m/sqrt(s). slip_fraction : largest over-/under-read in
    traction/braking above ``slip_accel_threshold_mps2`` (m/s^2; inf: no slip).
    The odometer measures at the IMU's position along the body forward (y) axis.
    """

    pulse_length_m: float = 0.0
    scale_factor_sigma: float = 0.0
    scale_factor_gm_sigma: float = 0.0
    scale_factor_tau_s: float = 600.0
    noise_density_m_per_sqrt_s: float = 0.0
    slip_fraction: float = 0.0
    slip_accel_threshold_mps2: float = float("inf")


@dataclass(frozen=True, slots=True)
class NominalBaro:
    """The barometric-altimeter specification an estimator is told (1-sigma, in metres of
    pressure altitude near the track's height; :mod:`navsim.sensors.baro`).

    noise_sigma_m : white noise of one reading, m. resolution_m : output resolution, m
    (the rounding error of a reading has variance ``resolution_m^2 / 12``).
    bias_sigma_m, bias_tau_s : stationary sigma (m) and correlation time (s) of the
    first-order Gauss-Markov bias of the pressure altitude. The altimeter reads the
    height of the IMU.
    """

    noise_sigma_m: float = 0.0
    resolution_m: float = 0.0
    bias_sigma_m: float = 0.0
    bias_tau_s: float = 600.0


@dataclass(frozen=True)
class Context:
    """Everything an estimator may know before the episode starts.

    Attributes
    ----------
    track : the track model (the map), see :mod:`navsim.track`.
    earth : :class:`navsim.earth.EarthModel` of the scenario.
    nav_period_s, imu_period_s, gnss_period_s : the time base, s.
    samples_per_step : IMU samples per navigation step.
    orders : multiple-integral orders R in each measurement.
    imu : NominalImu. gnss : NominalGnss.
    scenario_name : str. config_hash : str, for logs.
    odometer : NominalOdometer or None (no wheel odometer).
    baro : NominalBaro or None (no barometric altimeter).
    """

    track: Track
    earth: EarthModel
    nav_period_s: float
    imu_period_s: float
    gnss_period_s: float
    samples_per_step: int
    orders: int
    imu: NominalImu
    gnss: NominalGnss
    scenario_name: str = ""
    config_hash: str = ""
    odometer: NominalOdometer | None = None
    baro: NominalBaro | None = None


@dataclass(frozen=True, slots=True)
class GnssObservation:
    """One GNSS epoch: per-channel arrays with a validity mask (m channels).

    Missing data is a value: a satellite below the mask or in an outage has
    ``valid == False`` (its other entries are finite but meaningless).
    """

    t: float
    prn: np.ndarray  # (m,) int
    sat_pos_e: np.ndarray  # (m, 3) ECEF, m
    sat_vel_e: np.ndarray  # (m, 3) ECEF, m/s
    pseudorange_m: np.ndarray  # (m,)
    pseudorange_rate_mps: np.ndarray  # (m,) Doppler as pseudorange rate, 003 eq. (3)
    valid: np.ndarray  # (m,) bool


@dataclass(frozen=True, slots=True)
class Measurement:
    """Sensor data of one navigation step ``[t - dt, t]``.

    dtheta_r, dv_r : (R, 3) multiple-integral increments over the step (seed 000 eq.
    1.14). dtheta_sub, dv_sub : (m, 3) first-order increments of the m IMU samples in the
    step. gnss : the epoch at the step end, or None when no epoch falls there.
    odometer_ds_m : distance counted by the wheel odometer over the step, m (None: no
    odometer). baro_alt_m : pressure altitude read by the barometric altimeter at the
    step end, m (None: no barometer).
    """

    step: int
    t: float
    dt: float
    dtheta_r: np.ndarray
    dv_r: np.ndarray
    dtheta_sub: np.ndarray
    dv_sub: np.ndarray
    gnss: GnssObservation | None = None
    odometer_ds_m: float | None = None
    baro_alt_m: float | None = None


@dataclass(frozen=True, slots=True)
class NavSolution:
    """A navigation solution at time t, with an optional 9 x 9 covariance (see module).

    The same value at two times: the prior an estimator is reset with (``Prior``: drawn
    by the simulator from the scenario's initial uncertainty, covariance diagonal) and
    the estimate it returns after each step (``Estimate``).

    t : s. lat, lon : geodetic, rad. h : m. velocity_n : (3,) ENU, m/s. heading, pitch,
    roll : rad (body x right, y forward, z up, relative to ENU). covariance : (9, 9) over
    :data:`STATE_LABELS` (m, m/s, rad) or None.
    nis, nis_dof : normalised innovation squared of a measurement update made in this
    step, and its degrees of freedom (None when no update happened).
    extra : free-form per-step diagnostics (e.g. bias estimates).
    """

    t: float
    lat: float
    lon: float
    h: float
    velocity_n: np.ndarray
    heading: float
    pitch: float
    roll: float
    covariance: np.ndarray | None = None
    nis: float | None = None
    nis_dof: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def as_action(self) -> np.ndarray:
        """The solution as a flat float array: [lat, lon, h, vE, vN, vU, heading, pitch, roll]."""
        return np.array([self.lat, self.lon, self.h, *self.velocity_n, self.heading, self.pitch, self.roll])


@dataclass(frozen=True, slots=True)
class MeasurementBatch:
    """n consecutive navigation steps at once (for estimators with a batch fast path).

    Arrays are those of :class:`Measurement` with a leading step axis: step, t (n,);
    dtheta_r, dv_r (n, R, 3); dtheta_sub, dv_sub (n, m, 3). ``gnss`` lists the epochs
    as ``(index_in_batch, GnssObservation)`` pairs, in time order. ``odometer_ds_m``
    (n,): the odometer distance of each step, m, or None. ``baro_alt_m`` (n,): the
    barometer's pressure altitude at each step end, m, or None.
    """

    step: np.ndarray
    t: np.ndarray
    dt: float
    dtheta_r: np.ndarray
    dv_r: np.ndarray
    dtheta_sub: np.ndarray
    dv_sub: np.ndarray
    gnss: tuple[tuple[int, GnssObservation], ...]
    odometer_ds_m: np.ndarray | None = None
    baro_alt_m: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.t)

    @classmethod
    def of(cls, m: Measurement) -> MeasurementBatch:
        """The one step ``m`` as a batch of one (``of(m).measurement(0)`` is ``m``'s values);
        ``m`` may be any object with the attributes of :class:`Measurement`."""
        odometer = getattr(m, "odometer_ds_m", None)
        baro = getattr(m, "baro_alt_m", None)
        return cls(np.array([m.step]), np.array([m.t]), m.dt, np.asarray(m.dtheta_r)[None], np.asarray(m.dv_r)[None],
                   np.asarray(m.dtheta_sub)[None], np.asarray(m.dv_sub)[None],
                   ((0, m.gnss),) if m.gnss is not None else (), None if odometer is None else np.array([odometer]),
                   None if baro is None else np.array([baro]))

    def measurement(self, i: int) -> Measurement:
        """The i-th step as a :class:`Measurement`."""
        epoch = next((obs for j, obs in self.gnss if j == i), None)
        odometer = None if self.odometer_ds_m is None else float(self.odometer_ds_m[i])
        baro = None if self.baro_alt_m is None else float(self.baro_alt_m[i])
        return Measurement(int(self.step[i]), float(self.t[i]), self.dt, self.dtheta_r[i], self.dv_r[i],
                           self.dtheta_sub[i], self.dv_sub[i], epoch, odometer, baro)


@dataclass(frozen=True, slots=True)
class EstimateBatch:
    """Solutions of n steps: ``solution`` (n, 9) rows as :meth:`NavSolution.as_action`,
    ``covariance`` (n, 9, 9) or None, ``nis`` (n,) with nan where no update, ``nis_dof`` (n,)."""

    solution: np.ndarray
    covariance: np.ndarray | None
    nis: np.ndarray
    nis_dof: np.ndarray


Prior = NavSolution
"""The solution an estimator is reset with (t = 0, covariance set)."""

Estimate = NavSolution
"""The solution an estimator returns after a step."""
