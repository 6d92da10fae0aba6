"""IMU presets and the nominal specification a filter is told.

:data:`PRESET_NAMES`: "ideal", "paper-2012" (seed 003's white accelerometer intensity),
"consumer-mems", "tactical", "navigation" (sources in :mod:`navsim.sensors.imu`, references
[2]-[4]); :func:`nominal_noise` and :func:`nominal_imu` give the noise densities and bias
figures that a filter assumes (IEEE Std 952-1997 / 1293-1998 terms).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
from numpy.typing import NDArray

from ...errors import ConfigError
from .error_model import ImuErrorModel, SensorErrors

if TYPE_CHECKING:
    from ...types import NominalImu

# Unit conversions used by the presets (SI inside).
_DEG = math.pi / 180.0
_DEG_PER_HOUR = _DEG / 3600.0  # deg/h -> rad/s
_DEG_PER_SQRT_HOUR = _DEG / 60.0  # deg/sqrt(h) -> rad/sqrt(s)
_PER_SQRT_HOUR = 1.0 / 60.0  # m/s/sqrt(h) -> m/s/sqrt(s)
_MICRO_G = 9.80665e-6  # micro-g -> m/s^2
_MGAL = 1.0e-5  # milligal -> m/s^2
_PPM = 1.0e-6
_DEG_PER_HOUR_PER_G = _DEG_PER_HOUR / 9.80665  # deg/h/g -> rad/s per m/s^2


def is_error_free(model: ImuErrorModel) -> bool:
    """True if the model adds no error at all (its output equals the true increments).

    The simulator then skips :func:`apply_imu_errors` and draws nothing from the IMU
    stream; no other stream is affected, so this changes no other number.
    """
    for sensor in (model.gyro, model.accel):
        for name in ("bias", "turn_on_bias_sigma", "bias_instability_sigma", "white_noise_density",
                     "rate_random_walk", "scale_factor", "misalignment"):
            if np.any(getattr(sensor, name)):
                return False
        if sensor.quantization_lsb or sensor.vibration:
            return False
    return not np.any(model.g_sensitivity)


PRESET_NAMES = ("ideal", "paper-2012", "consumer-mems", "tactical", "navigation")

# Quantization levels of the Groves demos are given for the rate-type output (m/s^2,
# rad/s) at the demos' 100 Hz IMU rate; the increment LSB is that level times 0.01 s.
_GROVES_DT = 0.01


def _axes(value: float) -> NDArray[np.float64]:
    """One value on the three axes (what :class:`SensorErrors` makes of a scalar)."""
    return np.full(3, value)


def _split_m(matrix_ppm: Sequence[Sequence[float]]) -> tuple[NDArray, NDArray]:
    """Groves' combined scale-factor / cross-coupling matrix -> (scale, misalignment)."""
    m = np.array(matrix_ppm, dtype=float) * _PPM
    return np.diag(m).copy(), m - np.diag(np.diag(m))


def imu_preset(name: str) -> ImuErrorModel:
    """A named IMU error model.

    ``"ideal"``
        No error at all.
    ``"paper-2012"``
        Seed 003's worked example: white noise only. The accelerometer "intensity
        (1e-5 m/s^2)^2" is read as a PSD, i.e. VRW = 1e-5 m/s/sqrt(s) (= 6e-4
        m/s/sqrt(h), about 1 micro-g/sqrt(Hz)). The gyro noise is not printed; we take a
        navigation-grade ARW of 0.002 deg/sqrt(h) (the aviation-grade value of the Groves
        (2013) demos, also the HG9900-class "high-accuracy" grade of gnss-ins-sim).
    ``"consumer-mems"``
        ICM-20602 class: ARW 0.2 deg/sqrt(h), VRW 0.2 m/s/sqrt(h), Gauss-Markov bias
        sigma 200 deg/h and 1000 mGal with 1 h correlation time (KF-GINS
        awesome-gins-datasets tuned values); constant biases, scale factor /
        cross-coupling, g-sensitivity and quantization (0.1 m/s^2, 2e-3 rad/s at 100 Hz)
        of the Groves consumer-grade demo.
    ``"tactical"``
        ADIS16465 class: ARW 0.1 deg/sqrt(h), VRW 0.1 m/s/sqrt(h), Gauss-Markov bias
        sigma 25 deg/h and 200 mGal, 1 h (awesome-gins-datasets); constant biases (900
        micro-g, 9 deg/h), scale factor / cross-coupling, g-sensitivity and quantization
        (1e-2 m/s^2, 2e-4 rad/s at 100 Hz) of the Groves tactical-grade demo.
    ``"navigation"``
        Leador-A15 figures quoted in the KF-GINS paper: ARW 0.003 deg/sqrt(h), VRW 0.03
        m/s/sqrt(h), Gauss-Markov bias instability 0.027 deg/h and 15 mGal with 4 h
        correlation time; constant biases (30 micro-g, 0.0009 deg/h), scale factor /
        cross-coupling and quantization (5e-5 m/s^2, 1e-6 rad/s at 100 Hz) of the Groves
        aviation-grade demo (which has no g-sensitivity).

    Parameters
    ----------
    name : str
        One of :data:`PRESET_NAMES`.

    Returns
    -------
    ImuErrorModel
    """
    if name == "ideal":
        return ImuErrorModel(name="ideal")
    if name == "paper-2012":
        return ImuErrorModel(
            gyro=SensorErrors(white_noise_density=_axes(0.002 * _DEG_PER_SQRT_HOUR)),
            accel=SensorErrors(white_noise_density=_axes(1.0e-5)),  # (1e-5 m/s^2)^2 read as PSD
            name="paper-2012",
        )
    if name == "consumer-mems":
        sa, ma = _split_m([[50000, -15000, 10000], [-7500, -60000, 12500], [-12500, 5000, 20000]])
        sg, mg = _split_m([[40000, -14000, 12500], [0, -30000, -7500], [0, 0, -17500]])
        return ImuErrorModel(
            gyro=SensorErrors(
                bias=np.array([-180.0, 260.0, -160.0]) * _DEG_PER_HOUR,
                bias_instability_sigma=_axes(200.0 * _DEG_PER_HOUR),
                bias_correlation_time_s=_axes(3600.0),
                white_noise_density=_axes(0.2 * _DEG_PER_SQRT_HOUR),
                scale_factor=sg,
                misalignment=mg,
                quantization_lsb=2.0e-3 * _GROVES_DT,
            ),
            accel=SensorErrors(
                bias=np.array([9000.0, -13000.0, 8000.0]) * _MICRO_G,
                bias_instability_sigma=_axes(1000.0 * _MGAL),
                bias_correlation_time_s=_axes(3600.0),
                white_noise_density=_axes(0.2 * _PER_SQRT_HOUR),
                scale_factor=sa,
                misalignment=ma,
                quantization_lsb=1.0e-1 * _GROVES_DT,
            ),
            g_sensitivity=np.array(
                [[90.0, -110.0, -60.0], [-50.0, 190.0, -160.0], [30.0, 110.0, -130.0]]
            )
            * _DEG_PER_HOUR_PER_G,
            name="consumer-mems",
        )
    if name == "tactical":
        sa, ma = _split_m([[500, -300, 200], [-150, -600, 250], [-250, 100, 450]])
        sg, mg = _split_m([[400, -300, 250], [0, -300, -150], [0, 0, -350]])
        return ImuErrorModel(
            gyro=SensorErrors(
                bias=np.array([-9.0, 13.0, -8.0]) * _DEG_PER_HOUR,
                bias_instability_sigma=_axes(25.0 * _DEG_PER_HOUR),
                bias_correlation_time_s=_axes(3600.0),
                white_noise_density=_axes(0.1 * _DEG_PER_SQRT_HOUR),
                scale_factor=sg,
                misalignment=mg,
                quantization_lsb=2.0e-4 * _GROVES_DT,
            ),
            accel=SensorErrors(
                bias=np.array([900.0, -1300.0, 800.0]) * _MICRO_G,
                bias_instability_sigma=_axes(200.0 * _MGAL),
                bias_correlation_time_s=_axes(3600.0),
                white_noise_density=_axes(0.1 * _PER_SQRT_HOUR),
                scale_factor=sa,
                misalignment=ma,
                quantization_lsb=1.0e-2 * _GROVES_DT,
            ),
            g_sensitivity=np.array([[0.9, -1.1, -0.6], [-0.5, 1.9, -1.6], [0.3, 1.1, -1.3]])
            * _DEG_PER_HOUR_PER_G,
            name="tactical",
        )
    if name == "navigation":
        sa, ma = _split_m([[100, -120, 80], [-60, -120, 100], [-100, 40, 90]])
        sg, mg = _split_m([[8, -120, 100], [0, -6, -60], [0, 0, -7]])
        return ImuErrorModel(
            gyro=SensorErrors(
                bias=np.array([-0.0009, 0.0013, -0.0008]) * _DEG_PER_HOUR,
                bias_instability_sigma=_axes(0.027 * _DEG_PER_HOUR),
                bias_correlation_time_s=_axes(4.0 * 3600.0),
                white_noise_density=_axes(0.003 * _DEG_PER_SQRT_HOUR),
                scale_factor=sg,
                misalignment=mg,
                quantization_lsb=1.0e-6 * _GROVES_DT,
            ),
            accel=SensorErrors(
                bias=np.array([30.0, -45.0, 26.0]) * _MICRO_G,
                bias_instability_sigma=_axes(15.0 * _MGAL),
                bias_correlation_time_s=_axes(4.0 * 3600.0),
                white_noise_density=_axes(0.03 * _PER_SQRT_HOUR),
                scale_factor=sa,
                misalignment=ma,
                quantization_lsb=5.0e-5 * _GROVES_DT,
            ),
            name="navigation",
        )
    raise ConfigError("imu.preset", f"one of {', '.join(PRESET_NAMES)}", name)


def nominal_noise(model: ImuErrorModel) -> dict[str, Any]:
    """Nominal noise figures an estimator may be told (the specification, not the draws).

    The constant bias enters as a sigma: its RMS over the three axes (so the per-axis
    truth values are not revealed), combined with the turn-on sigma.

    Returns
    -------
    dict
        ``gyro_arw`` (rad/sqrt(s)), ``accel_vrw`` (m/s/sqrt(s)), ``gyro_noise_psd``,
        ``accel_noise_psd``, ``{gyro,accel}_bias_sigma`` (constant + turn-on),
        ``{gyro,accel}_bias_instability_sigma`` and ``..._bias_correlation_time_s``
        (Gauss-Markov), ``{gyro,accel}_rate_random_walk``, ``{gyro,accel}_scale_factor_sigma``
        (RMS over axes), ``{gyro,accel}_quantization_lsb``; arrays of shape (3,) except
        the LSBs. Units as in :class:`SensorErrors`.
    """
    result: dict[str, Any] = {
        "gyro_arw": model.gyro.white_noise_density.copy(),
        "accel_vrw": model.accel.white_noise_density.copy(),
        "gyro_noise_psd": model.gyro.white_noise_psd,
        "accel_noise_psd": model.accel.white_noise_psd,
    }
    for label, sensor in (("gyro", model.gyro), ("accel", model.accel)):
        rms_bias = math.sqrt(float(np.mean(sensor.bias**2)))
        result[f"{label}_bias_sigma"] = np.sqrt(sensor.turn_on_bias_sigma**2 + rms_bias**2)
        result[f"{label}_bias_instability_sigma"] = sensor.bias_instability_sigma.copy()
        result[f"{label}_bias_correlation_time_s"] = sensor.bias_correlation_time_s.copy()
        result[f"{label}_rate_random_walk"] = sensor.rate_random_walk.copy()
        rms_scale = math.sqrt(float(np.mean(sensor.scale_factor**2)))
        result[f"{label}_scale_factor_sigma"] = np.full(3, rms_scale)
        result[f"{label}_quantization_lsb"] = sensor.quantization_lsb
    return result


def nominal_imu(model: ImuErrorModel) -> NominalImu:
    """The IMU datasheet an estimator is told (:class:`navsim.types.NominalImu`).

    From :func:`nominal_noise`: RMS over the axes of the white-noise densities and rate
    random walks; bias sigma = hypot(RMS of the constant + turn-on sigma, RMS of the
    Gauss-Markov instability sigma); correlation time = the shortest of the axes.
    """
    from ...types import NominalImu

    nominal = nominal_noise(model)

    def rms(x: Any) -> float:
        return float(np.sqrt(np.mean(np.square(x))))

    return NominalImu(
        gyro_arw=rms(nominal["gyro_arw"]), accel_vrw=rms(nominal["accel_vrw"]),
        gyro_bias_sigma=float(np.hypot(rms(nominal["gyro_bias_sigma"]), rms(nominal["gyro_bias_instability_sigma"]))),
        accel_bias_sigma=float(np.hypot(rms(nominal["accel_bias_sigma"]), rms(nominal["accel_bias_instability_sigma"]))),
        gyro_bias_tau_s=float(np.min(nominal["gyro_bias_correlation_time_s"])),
        accel_bias_tau_s=float(np.min(nominal["accel_bias_correlation_time_s"])),
        gyro_rrw=rms(nominal["gyro_rate_random_walk"]), accel_rrw=rms(nominal["accel_rate_random_walk"]),
    )
