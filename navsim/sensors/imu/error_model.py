"""The configuration of the truth-side IMU error model: :class:`VibrationHarmonic`,
:class:`SensorErrors` (scale factor, misalignment, constant, turn-on, Gauss-Markov and
rate-random-walk biases, white noise, vibration, quantization of one sensor triad) and
:class:`ImuErrorModel` (gyro, accelerometer and the gyro g-sensitivity). The effect of each
term on the r-fold integrals is tabulated in :mod:`navsim.sensors.imu`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np
from numpy.typing import NDArray

from ...errors import ConfigError
from .integrals import check_int


def _vector3(name: str, value: Any, *, nonneg: bool = False, positive: bool = False) -> NDArray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(name, "a number or a 3-vector", value) from None
    if arr.ndim == 0:
        arr = np.full(3, float(arr))
    if arr.shape != (3,):
        raise ConfigError(name, "a number or a 3-vector", value)
    if positive:
        if not np.all((arr > 0.0) & (arr < math.inf)):
            raise ConfigError(name, "positive finite values", value)
    elif not np.all(np.isfinite(arr)):
        raise ConfigError(name, "finite values", value)
    if nonneg and np.any(arr < 0.0):
        raise ConfigError(name, "non-negative values", value)
    arr.setflags(write=False)
    return arr


def _matrix3(name: str, value: Any, *, zero_diagonal: bool = False) -> NDArray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(name, "a 3x3 matrix", value) from None
    if arr.ndim == 0 and arr == 0.0:
        arr = np.zeros((3, 3))
    if arr.shape != (3, 3) or not np.all(np.isfinite(arr)):
        raise ConfigError(name, "a finite 3x3 matrix", value)
    if zero_diagonal and np.any(np.diag(arr) != 0.0):
        raise ConfigError(name, "a zero diagonal (scale factors go in scale_factor)", value)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, slots=True, eq=False)
class VibrationHarmonic:
    """One harmonic ``amplitude * sin(2 pi frequency_hz t + phase_rad)`` added to a sensor.

    Two such harmonics on orthogonal gyro and accelerometer axes, 90 deg apart, give the
    pseudo-sculling error (6.1) of seed 000; on two orthogonal gyros, pseudo-coning (6.2).

    Parameters
    ----------
    amplitude : array_like, shape (3,)
        Per-axis amplitude, rad/s (gyro) or m/s^2 (accelerometer).
    frequency_hz : float
        Hz, >= 0.
    phase_rad : float
        rad.
    """

    amplitude: NDArray[np.float64]
    frequency_hz: float
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "amplitude", _vector3("vibration.amplitude", self.amplitude))
        freq = float(self.frequency_hz)
        if not (0.0 <= freq < math.inf):
            raise ConfigError(
                "vibration.frequency_hz", "a finite frequency >= 0", self.frequency_hz
            )
        phase = float(self.phase_rad)
        if not math.isfinite(phase):
            raise ConfigError("vibration.phase_rad", "a finite phase", self.phase_rad)
        object.__setattr__(self, "frequency_hz", freq)
        object.__setattr__(self, "phase_rad", phase)

    @classmethod
    def on_axis(
        cls, axis: int, amplitude: float, frequency_hz: float, phase_rad: float = 0.0
    ) -> VibrationHarmonic:
        """A harmonic on one body axis (0 = x right, 1 = y forward, 2 = z up)."""
        axis = check_int("vibration.axis", axis, 0, 2)
        vec = np.zeros(3)
        vec[axis] = float(amplitude)
        return cls(vec, frequency_hz, phase_rad)

    def to_dict(self) -> dict[str, Any]:
        return {
            "amplitude": self.amplitude.tolist(),
            "frequency_hz": self.frequency_hz,
            "phase_rad": self.phase_rad,
        }

    def __eq__(self, other: object) -> bool:
        return isinstance(other, VibrationHarmonic) and self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]


def _as_harmonic(value: Any) -> VibrationHarmonic:
    if isinstance(value, VibrationHarmonic):
        return value
    if isinstance(value, Mapping):
        return VibrationHarmonic(**value)
    try:
        items = tuple(value)
    except TypeError:
        raise ConfigError(
            "vibration", "VibrationHarmonic or (amplitude, f_hz, phase)", value
        ) from None
    if len(items) not in (2, 3):
        raise ConfigError("vibration", "VibrationHarmonic or (amplitude, f_hz, phase)", value)
    return VibrationHarmonic(*items)


@dataclass(frozen=True, slots=True, eq=False)
class SensorErrors:
    """Errors of one sensor triad (gyro or accelerometer); every field is per axis.

    Units below are for the gyro / the accelerometer. Scalars are broadcast to 3 axes.

    Parameters
    ----------
    bias : array_like, shape (3,)
        Constant (deterministic) bias, rad/s / m/s^2.
    turn_on_bias_sigma : array_like, shape (3,)
        Sigma of a random constant bias drawn once by :meth:`ImuState.initial`.
    bias_instability_sigma : array_like, shape (3,)
        Stationary sigma of the first-order Gauss-Markov bias, rad/s / m/s^2.
    bias_correlation_time_s : array_like, shape (3,)
        Its correlation time, s (> 0).
    white_noise_density : array_like, shape (3,)
        Root PSD of the white noise on the rate: angle random walk in rad/sqrt(s)
        (= (rad/s)/sqrt(Hz)) / velocity random walk in m/s/sqrt(s). PSD = square.
    rate_random_walk : array_like, shape (3,)
        Root PSD of the white noise driving a random-walk bias, rad/s/sqrt(s) /
        m/s^2/sqrt(s).
    scale_factor : array_like, shape (3,)
        Scale-factor errors (unitless; 1e-6 = 1 ppm).
    misalignment : array_like, shape (3, 3)
        Small-angle misalignment / non-orthogonality matrix with zero diagonal: the output
        is ``(I + diag(scale_factor) + misalignment) @ true``.
    quantization_lsb : float
        LSB of the first-order increment output, rad / m/s (0 = off).
    vibration : sequence of VibrationHarmonic
        Harmonics added to the sensed quantity (seed 000 section 6).
    """

    bias: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    turn_on_bias_sigma: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    bias_instability_sigma: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    bias_correlation_time_s: NDArray[np.float64] = 3600.0  # type: ignore[assignment]
    white_noise_density: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    rate_random_walk: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    scale_factor: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    misalignment: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    quantization_lsb: float = 0.0
    vibration: tuple[VibrationHarmonic, ...] = ()

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "bias", _vector3("bias", self.bias))
        for name in ("turn_on_bias_sigma", "bias_instability_sigma", "white_noise_density",
                     "rate_random_walk"):
            set_(self, name, _vector3(name, getattr(self, name), nonneg=True))
        set_(self, "bias_correlation_time_s",
             _vector3("bias_correlation_time_s", self.bias_correlation_time_s, positive=True))
        set_(self, "scale_factor", _vector3("scale_factor", self.scale_factor))
        set_(self, "misalignment", _matrix3("misalignment", self.misalignment, zero_diagonal=True))
        try:
            lsb = float(self.quantization_lsb)
        except (TypeError, ValueError):
            raise ConfigError("quantization_lsb", "a number >= 0", self.quantization_lsb) from None
        if not (0.0 <= lsb < math.inf):
            raise ConfigError("quantization_lsb", "a finite number >= 0", self.quantization_lsb)
        set_(self, "quantization_lsb", lsb)
        if isinstance(self.vibration, (VibrationHarmonic, Mapping)):
            raise ConfigError("vibration", "a sequence of harmonics", self.vibration)
        set_(self, "vibration", tuple(_as_harmonic(v) for v in self.vibration))

    @property
    def white_noise_psd(self) -> NDArray[np.float64]:
        """PSD of the white noise, (rad/s)^2/Hz / (m/s^2)^2/Hz, shape (3,)."""
        return self.white_noise_density**2

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and floats (TOML-ready); inverse of ``SensorErrors(**d)``."""
        return {
            "bias": self.bias.tolist(),
            "turn_on_bias_sigma": self.turn_on_bias_sigma.tolist(),
            "bias_instability_sigma": self.bias_instability_sigma.tolist(),
            "bias_correlation_time_s": self.bias_correlation_time_s.tolist(),
            "white_noise_density": self.white_noise_density.tolist(),
            "rate_random_walk": self.rate_random_walk.tolist(),
            "scale_factor": self.scale_factor.tolist(),
            "misalignment": self.misalignment.tolist(),
            "quantization_lsb": self.quantization_lsb,
            "vibration": [v.to_dict() for v in self.vibration],
        }

    def __eq__(self, other: object) -> bool:
        return isinstance(other, SensorErrors) and self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, slots=True, eq=False)
class ImuErrorModel:
    """Truth-side IMU error model: what the simulator does to the true increments.

    Parameters
    ----------
    gyro : SensorErrors
        Gyro triad errors (rad/s based units).
    accel : SensorErrors
        Accelerometer triad errors (m/s^2 based units).
    g_sensitivity : array_like, shape (3, 3)
        Gyro g-sensitivity, rad/s per m/s^2: adds ``G @ f_b`` to the rate and
        ``G @ dv_r`` to every ``dtheta_r``.
    name : str
        Label (the preset name or "custom").
    """

    gyro: SensorErrors = field(default_factory=SensorErrors)
    accel: SensorErrors = field(default_factory=SensorErrors)
    g_sensitivity: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    name: str = "custom"

    def __post_init__(self) -> None:
        for part in ("gyro", "accel"):
            value = getattr(self, part)
            if isinstance(value, Mapping):
                value = SensorErrors(**value)
            if not isinstance(value, SensorErrors):
                raise ConfigError(part, "SensorErrors or a mapping of its fields", value)
            object.__setattr__(self, part, value)
        object.__setattr__(self, "g_sensitivity", _matrix3("g_sensitivity", self.g_sensitivity))
        object.__setattr__(self, "name", str(self.name))

    def to_dict(self) -> dict[str, Any]:
        """Plain nested dict (TOML-ready); ``ImuErrorModel.from_dict`` inverts it."""
        return {
            "name": self.name,
            "g_sensitivity": self.g_sensitivity.tolist(),
            "gyro": self.gyro.to_dict(),
            "accel": self.accel.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ImuErrorModel:
        """Build from :meth:`to_dict` output (or a scenario-file table)."""
        unknown = set(data) - {"name", "g_sensitivity", "gyro", "accel"}
        if unknown:
            raise ConfigError("imu", "keys among name, g_sensitivity, gyro, accel", sorted(unknown))
        return cls(
            gyro=SensorErrors(**data.get("gyro", {})),
            accel=SensorErrors(**data.get("accel", {})),
            g_sensitivity=data.get("g_sensitivity", 0.0),
            name=data.get("name", "custom"),
        )

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ImuErrorModel) and self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]


def level_lsb(model: ImuErrorModel, h: float, order: int) -> NDArray[np.float64]:
    """LSB of each output level, shape (2, R + 1): ``lsb h^(r-1)`` then ``lsb / h``."""
    base = np.array([model.gyro.quantization_lsb, model.accel.quantization_lsb])
    scale = np.concatenate((h ** np.arange(order), [1.0 / h]))
    return base[:, None] * scale[None, :]
