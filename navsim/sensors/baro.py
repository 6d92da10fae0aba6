"""Barometric altimeter: pressure altitude with a Gauss-Markov bias, white noise and quantisation (truth side).

One reading per navigation step ``k``, at the step end ``t_k`` (the sensor's output
register read by the navigation computer). With ``h_k`` the true height of the IMU
(geodetic height: the geoid undulation and the local deviation of the real atmosphere
from the standard one are left to the bias) the sensor measures the static pressure and
reports it as pressure altitude::

    P(h)  = p0 (1 - L h / T0)^(g0 M / (R* L))                               (BA.1)
    b_k+1 = phi b_k + sigma_b sqrt(1 - phi^2) w_k,   phi = exp(-dt / tau)   (BA.2)
    p_k   = q rint((P(h_k) + b_k + sigma_n z_k) / q)   (q = 0: p_k unrounded) (BA.3)
    a_k   = H(p_k) = T0 / L (1 - (p_k / p0)^(R* L / (g0 M)))                (BA.4)

* (BA.1), (BA.4): the troposphere of the International Standard Atmosphere (ISO
  2533:1975, identical to the U.S. Standard Atmosphere 1976 below 11 km): p0 = 101325
  Pa, T0 = 288.15 K, L = 0.0065 K/m, g0 = 9.80665 m/s^2, M = 0.0289644 kg/mol, R* =
  8.3144598 J/(mol K); H is the exact inverse of P, so an error-free sensor reads the
  true height (to rounding). Near the ground ``dP/dh = -rho(h) g0`` (hydrostatic
  equation, ``rho = p M / (R* T)``), 12.01 Pa/m at sea level (:func:`pressure_gradient`);
* (BA.2): the slowly varying offset (temperature drift of the offset, solder and
  long-term drift; the weather's pressure change over an episode) as a first-order
  Gauss-Markov process of stationary sigma ``bias_sigma_pa`` and correlation time
  ``bias_tau_s``, exact discretisation, started from its stationary distribution
  (``b_0 = sigma_b w_init``): ``E[b_k b_k+j] = sigma_b^2 phi^|j|``;
* (BA.3): white pressure noise of sigma ``noise_sigma_pa`` per reading, then rounding to
  the output resolution ``resolution_pa`` (q): the rounding error of a reading whose
  noise spans several q is uniform on [-q/2, q/2], variance q^2 / 12.

The altitude error is ``a_k - h_k ~ -(b_k + sigma_n z_k + e_q) / (rho(h) g0)``: a
positive pressure bias reads low. :meth:`BaroModel.nominal` converts the sigmas to metres
with the gradient at a reference height (the estimator's datasheet,
:class:`navsim.types.NominalBaro`).

Randomness: :meth:`BaroState.initial` draws one standard normal (``w_init``); every call
of :func:`simulate_baro` / :func:`simulate_baro_batch` draws one block
``rng.standard_normal((n, 2))`` per member, rows the steps in time order, columns ``[z
(BA.3), w (BA.2)]``, whatever is switched on; the bias lives in the frozen
:class:`BaroState`, so n1 then n2 steps give exactly the numbers of n1 + n2. The
simulator spawns the ``baro`` stream last (:data:`navsim.simulator.STREAMS`), so every
other stream is unchanged by it, and draws from it only with ``[baro] enabled = true``.

Presets (:meth:`BaroModel.preset`)
----------------------------------
``"ideal"``: no error, no rounding (``a_k = h_k`` to rounding).

``"bmp280"``: the Bosch Sensortec BMP280 MEMS barometer, data sheet BST-BMP280-DS001-11
(revision 1.14, May 2015) [1], in its "indoor navigation" setting (table 7: normal mode,
ultra-high resolution x16 pressure oversampling, IIR filter coefficient 16, 26.3 Hz
output rate, RMS noise 1.6 cm): ``noise_sigma_pa`` = 0.016 m x 12.01 Pa/m = 0.19 Pa;
``resolution_pa`` = 0.16 Pa (table 4: 20-bit output at x16 oversampling);
``bias_sigma_pa`` = 12 Pa, the data sheet's relative accuracy (+-0.12 hPa, "equiv. to +-1
m", 950-1050 hPa at 25 deg C) taken as the 1-sigma of the slowly varying offset (the
absolute accuracy, +-1 hPa, is a constant offset that a GNSS-aided filter calibrates
like any other part of the bias); ``bias_tau_s`` = 600 s is an assumption, not a data
sheet figure (the data sheet gives no correlation time; 600 s is a thermal time scale
of an enclosure; the temperature coefficient of the offset, 1.5 Pa/K, makes 12 Pa an
8 K change). The IIR filter makes consecutive readings of the real chip correlated over
about 11 samples (table 6); navsim's readings at the navigation rate take the noise as
white.

References
----------
.. [1] Bosch Sensortec, BMP280 Digital Pressure Sensor, data sheet BST-BMP280-DS001-11,
       revision 1.14, 2015: key parameters (relative accuracy, absolute accuracy,
       temperature coefficient of the offset), tables 4 (resolution) and 7 (noise).
.. [2] ISO 2533:1975, Standard Atmosphere; NOAA/NASA/USAF, U.S. Standard Atmosphere,
       1976, eqs. (33a) (pressure in a layer of constant lapse rate) and (42) (density).
.. [3] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., 2013, section 6.2.1 (barometric altimeter: standard-atmosphere
       conversion, errors from the weather and temperature, height aiding of an INS).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ConfigError
from ._common import lockstep_members, positive_step
from .imu import first_order_recursion

if TYPE_CHECKING:
    from ..types import NominalBaro

__all__ = [
    "P0_PA",
    "T0_K",
    "LAPSE_K_PER_M",
    "G0_MPS2",
    "MOLAR_MASS_KG_PER_MOL",
    "GAS_CONSTANT",
    "PRESET_NAMES",
    "pressure_at",
    "pressure_altitude",
    "pressure_gradient",
    "BaroModel",
    "BaroState",
    "BaroOutput",
    "BaroConfig",
    "simulate_baro",
    "simulate_baro_batch",
]

P0_PA = 101_325.0
"""Sea-level standard pressure, Pa (ISA)."""
T0_K = 288.15
"""Sea-level standard temperature, K (ISA)."""
LAPSE_K_PER_M = 0.0065
"""Temperature lapse rate of the ISA troposphere, K/m."""
G0_MPS2 = 9.80665
"""Standard gravity, m/s^2."""
MOLAR_MASS_KG_PER_MOL = 0.0289644
"""Molar mass of dry air, kg/mol (U.S. Standard Atmosphere 1976)."""
GAS_CONSTANT = 8.3144598
"""Universal gas constant R*, J/(mol K)."""

_EXPONENT = G0_MPS2 * MOLAR_MASS_KG_PER_MOL / (GAS_CONSTANT * LAPSE_K_PER_M)  # 5.2559

PRESET_NAMES = ("ideal", "bmp280")


def pressure_at(h: ArrayLike) -> NDArray[np.float64]:
    """Standard-atmosphere static pressure at height ``h`` (m), Pa (BA.1).

    >>> round(float(pressure_at(0.0)), 6)
    101325.0
    >>> round(float(pressure_at(1000.0)), 1)
    89874.8
    """
    h = np.asarray(h, dtype=float)
    return P0_PA * (1.0 - LAPSE_K_PER_M * h / T0_K) ** _EXPONENT


def pressure_altitude(p: ArrayLike) -> NDArray[np.float64]:
    """Pressure altitude of a static pressure ``p`` (Pa), m: the inverse of :func:`pressure_at` (BA.4).

    >>> round(float(pressure_altitude(pressure_at(1234.5))), 9)
    1234.5
    """
    p = np.asarray(p, dtype=float)
    return (T0_K / LAPSE_K_PER_M) * (1.0 - (p / P0_PA) ** (1.0 / _EXPONENT))


def pressure_gradient(h: ArrayLike) -> NDArray[np.float64]:
    """``dP/dh = -rho(h) g0`` (Pa/m) of the standard atmosphere at height ``h`` (m).

    >>> round(float(pressure_gradient(0.0)), 3)
    -12.013
    """
    h = np.asarray(h, dtype=float)
    temperature = T0_K - LAPSE_K_PER_M * h
    density = pressure_at(h) * MOLAR_MASS_KG_PER_MOL / (GAS_CONSTANT * temperature)
    return -density * G0_MPS2


@dataclass(frozen=True, slots=True)
class BaroModel:
    """Truth-side error model of a barometric altimeter (see the module docstring).

    Attributes
    ----------
    noise_sigma_pa : float
        1-sigma of the white pressure noise per reading, Pa (BA.3).
    resolution_pa : float
        Output resolution q, Pa; 0 = no rounding (BA.3).
    bias_sigma_pa : float
        Stationary 1-sigma of the Gauss-Markov pressure bias, Pa (BA.2).
    bias_tau_s : float
        Its correlation time, s (> 0; ``inf``: a random constant).
    """

    noise_sigma_pa: float = 0.0
    resolution_pa: float = 0.0
    bias_sigma_pa: float = 0.0
    bias_tau_s: float = 600.0

    def __post_init__(self) -> None:
        for name in ("noise_sigma_pa", "resolution_pa", "bias_sigma_pa", "bias_tau_s"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ConfigError(f"baro.{name}", "a number", value)
            object.__setattr__(self, name, float(value))
        for name in ("noise_sigma_pa", "resolution_pa", "bias_sigma_pa"):
            value = getattr(self, name)
            if not (value >= 0.0 and math.isfinite(value)):
                raise ConfigError(f"baro.{name}", "a non-negative finite number, Pa", value)
        if not self.bias_tau_s > 0.0:
            raise ConfigError("baro.bias_tau_s", "a positive time, s (inf: random constant)", self.bias_tau_s)

    def nominal(self, height_m: float = 0.0) -> NominalBaro:
        """The datasheet an estimator is told (:class:`navsim.types.NominalBaro`), in metres
        of altitude at ``height_m`` (the pressure sigmas divided by ``|dP/dh|`` there)."""
        from ..types import NominalBaro

        scale = 1.0 / abs(float(pressure_gradient(height_m)))
        return NominalBaro(noise_sigma_m=self.noise_sigma_pa * scale, resolution_m=self.resolution_pa * scale,
                           bias_sigma_m=self.bias_sigma_pa * scale, bias_tau_s=self.bias_tau_s)

    @classmethod
    def preset(cls, name: str) -> BaroModel:
        """A named model: ``"ideal"``, ``"bmp280"`` (values and sources in the module docstring)."""
        if name == "ideal":
            return cls()
        if name == "bmp280":
            return cls(noise_sigma_pa=0.016 * 12.013, resolution_pa=0.16, bias_sigma_pa=12.0, bias_tau_s=600.0)
        raise ConfigError("baro.preset", f"one of {PRESET_NAMES}", name)


@dataclass(frozen=True, slots=True)
class BaroState:
    """Everything recursive in the barometer model: ``step_index`` (global index of the next
    reading) and ``bias_pa``, the bias b of (BA.2) at that reading, Pa."""

    step_index: int
    bias_pa: float

    @classmethod
    def initial(cls, model: BaroModel, rng: np.random.Generator) -> BaroState:
        """Turn-on state: the bias from its stationary distribution (one standard normal)."""
        return cls(0, model.bias_sigma_pa * float(rng.standard_normal()))


@dataclass(frozen=True, slots=True, eq=False)
class BaroOutput:
    """Barometer output of n steps (a leading member axis B in the batched form).

    Attributes
    ----------
    altitude_m : (n,) or (B, n)
        Pressure altitude of each reading, m (BA.4): the measurement.
    pressure_pa : (n,) or (B, n)
        The reading as a pressure, Pa (BA.3), a whole multiple of the resolution.
    bias_pa : (n,) or (B, n)
        The bias b_k of each reading, Pa (diagnostic).
    """

    altitude_m: NDArray[np.float64]
    pressure_pa: NDArray[np.float64]
    bias_pa: NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class BaroConfig:
    """The scenario's ``[baro]`` section: off by default.

    ``preset``: one of :data:`PRESET_NAMES`; ``overrides``: fields of the preset's
    :class:`BaroModel`. Left out of the scenario's dict, TOML and hash while it holds its
    defaults, so scenarios without a barometer are unchanged.
    """

    enabled: bool = False
    preset: str = "bmp280"
    overrides: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.preset not in PRESET_NAMES:
            raise ConfigError("baro.preset", f"one of {PRESET_NAMES}", self.preset)
        self.model()  # validates the overrides

    def model(self) -> BaroModel:
        """The truth-side model: the preset with the overrides applied."""
        from .models import replace_checked  # models imports the IMU and GNSS packages: only when needed

        base = BaroModel.preset(self.preset)
        return replace_checked(base, self.overrides, "baro.overrides") if self.overrides else base


def simulate_baro_batch(h_true: ArrayLike, model: BaroModel, states: Sequence[BaroState],
                        rngs: Sequence[np.random.Generator], *, dt: float) -> tuple[BaroOutput, list[BaroState]]:
    """The barometer of B members that share the true motion, in one pass.

    Member j gets exactly the numbers of ``simulate_baro(..., states[j], rngs[j])``.

    Parameters
    ----------
    h_true : (n,) true heights at the readings, m.
    model : BaroModel.
    states : B BaroState at the same ``step_index`` (lockstep).
    rngs : B generators; each draws one ``(n, 2)`` block.
    dt : the interval between readings, s (> 0), for (BA.2).

    Returns
    -------
    output : BaroOutput with (B, n) arrays. new_states : list of B BaroState.
    """
    if not isinstance(model, BaroModel):
        raise ConfigError("model", "a BaroModel", type(model).__name__)
    dt = positive_step(dt)
    states, rngs, index = lockstep_members(states, rngs, "step_index")
    h_true = np.asarray(h_true, dtype=float)
    if h_true.ndim != 1:
        raise ConfigError("h_true", "a 1-D array of heights, m", h_true.shape)
    n, members = len(h_true), len(states)
    z = np.empty((members, n, 2))  # one block per member and call; width fixed
    for j, rng in enumerate(rngs):
        rng.standard_normal(out=z[j])
    b0 = np.array([s.bias_pa for s in states])
    phi = math.exp(-dt / model.bias_tau_s)
    drive = (model.bias_sigma_pa * math.sqrt(-math.expm1(-2.0 * dt / model.bias_tau_s))) * z[:, :, 1]
    if n:
        b_next = first_order_recursion(np.asarray(phi), drive, b0)  # (BA.2): b_1..b_n
        bias = np.concatenate((b0[:, None], b_next[:, :-1]), axis=1)
        b_end = b_next[:, -1]
    else:
        bias, b_end = np.zeros((members, 0)), b0
    p = pressure_at(h_true)[None, :] + bias + model.noise_sigma_pa * z[:, :, 0]
    q = model.resolution_pa
    if q > 0.0:  # (BA.3)
        p = q * np.rint(p / q)
    out = BaroOutput(pressure_altitude(p), p, bias)
    return out, [BaroState(index + n, float(b_end[j])) for j in range(members)]


def simulate_baro(h_true: ArrayLike, model: BaroModel, state: BaroState, rng: np.random.Generator, *,
                  dt: float) -> tuple[BaroOutput, BaroState]:
    """The readings of n consecutive steps (the B = 1 case of :func:`simulate_baro_batch`).

    >>> import numpy as np
    >>> model = BaroModel.preset("ideal")
    >>> out, _ = simulate_baro([10.0, 20.0], model, BaroState(0, 0.0), np.random.default_rng(0), dt=0.01)
    >>> np.round(out.altitude_m, 9).tolist()
    [10.0, 20.0]
    """
    out, states = simulate_baro_batch(h_true, model, [state], [rng], dt=dt)
    return BaroOutput(out.altitude_m[0], out.pressure_pa[0], out.bias_pa[0]), states[0]
