"""Wheel odometer (tachometer): pulse counts of a wheel encoder, truth side.

Per navigation step ``k`` of length ``dt`` the odometer delivers the distance the wheel
rolled, as a whole number of encoder pulses. With ``ds_k`` the true along-track
arc-length increment of the step (:class:`navsim.motion.TrueState` ``s``) and ``a_k`` the
true along-track acceleration at the step end::

    d_k   = ds_k (1 + e_sf,k + slip_k) + q sqrt(dt) z_k                       (OD.1)
    e_sf,k = c + g_k                                                          (OD.2)
    g_k+1 = exp(-dt/tau) g_k + sigma_g sqrt(1 - exp(-2 dt/tau)) w_k           (OD.3)
    slip_k = +slip_fraction   if a_k >  a_thr    (traction: the wheel spins ahead)
             -slide_fraction  if a_k < -a_thr    (braking: the wheel slides behind)
             0                otherwise                                       (OD.4)
    D_k   = D_k-1 + d_k,   N_k = floor(D_k / p),   pulses_k = N_k - N_k-1     (OD.5)
    output: pulses_k and ds_m,k = p pulses_k

* ``c``: turn-on scale-factor error, drawn once per episode with sigma
  ``scale_factor_sigma`` (wheel-diameter uncertainty after calibration);
* ``g``: a slow first-order Gauss-Markov scale-factor term (wear, tyre pressure and
  temperature, adhesion conditions), stationary sigma ``scale_factor_gm_sigma`` and
  correlation time ``scale_factor_gm_tau_s``; exact discretisation (OD.3), the value of
  step k held over the step;
* ``q``: white distance noise density, m/sqrt(s) (the distance error of a span T
  accumulates as ``q sqrt(T)`` whatever the step; ``q / sqrt(dt)`` is the speed noise of
  one step);
* slip/slide (OD.4): a macroscopic over-read during traction and under-read during
  braking when the demanded acceleration exceeds the adhesion a wheel can transmit
  without sliding, given as fractions of the true distance above a threshold on the
  along-track acceleration (|a| > a_thr, strict);
* quantisation (OD.5): the encoder counts whole pulses of length
  ``p = wheel_circumference_m / pulses_per_revolution``; the residual carry (the part of
  a pulse not yet counted) lives in the state, so the running sum of the output stays
  within one pulse below the running sum of ``d``: ``0 <= sum d - sum ds_m < p``. With
  ``pulses_per_revolution = 0`` there is no quantiser: ``ds_m = d`` and ``pulses`` is 0.

The running sums of (OD.5) are kept as an accumulator and an emitted count that are
renormalised (``D -= p N``, ``N = 0``) at fixed *global* step indices, every
:data:`QUANTIZATION_BLOCK` steps, so that the result does not depend on the chunking
(the IMU quantiser of :mod:`navsim.sensors.imu` does the same).

Randomness: :meth:`OdometerState.initial` draws one block of 2 standard normals (the
turn-on scale factor and the stationary start of ``g``); every call of
:func:`simulate_odometer` / :func:`simulate_odometer_batch` draws one block
``rng.standard_normal((n, 2))`` per member, rows the steps in time order, columns
``[z (OD.1), w (OD.3)]``, whatever is switched on. Every recursive quantity (``g``,
the quantiser's accumulator and count, the step index) is in the frozen
:class:`OdometerState`, so n1 then n2 steps give exactly the numbers of n1 + n2.

Presets (:meth:`OdometerModel.preset`)
--------------------------------------
``"ideal"``: ``ds_m = ds`` exactly (no error, no quantiser).

``"rail-tachometer"``: a wheel of 0.92 m nominal tread diameter (circumference
2.890 m; 0.92 m is a common diameter of new passenger-coach wheels, worn down to about
0.84 m over their life, so the diameter must be entered and calibrated, Malvezzi et al.
2011 [2]) with a 200-pulse-per-revolution pulse generator (14.5 mm per pulse;
illustrative: rail pulse generators of tens to a few hundred pulses per revolution are
common). Residual turn-on scale factor 0.3 % (a diameter known to about 3 mm after
calibration; illustrative within the 0.1-1 % the brief and [2] discuss), Gauss-Markov
0.1 % with 600 s correlation (adhesion and wear drift; illustrative), noise
1e-3 m/sqrt(s) (illustrative). Slip 1 % in traction and slide 1 % in braking above
0.45 m/s^2 (illustrative: creep of the order of 1 % at high adhesion demand, [2]; the
bundled mountain railway accelerates at up to 0.5 and brakes at up to 0.6 m/s^2, so the
plateaus of its ramps slip). For scale: the ETCS odometry requirement allows
+-(5 m + 5 % of the distance) [3].

``"car-wheel-speed"``: an ABS wheel-speed sensor with a 48-tooth tone ring on a tyre of
1.95 m rolling circumference (40.6 mm per pulse; illustrative, typical passenger-car
values), turn-on scale factor 0.5 % and Gauss-Markov 0.2 % over 300 s (tyre pressure,
load, temperature and wear change the rolling radius by fractions of a per cent [1];
illustrative), noise 2e-3 m/sqrt(s), slip/slide 2 % above 2 m/s^2 (illustrative).

References
----------
.. [1] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., Artech House, 2013, section 6.3 (odometry: wheel-speed and
       pulse-count sensors, scale-factor errors from tyre and wheel radius, quantisation,
       wheel slip and skid) and 16.2 (rail navigation).
.. [2] Malvezzi M., Allotta B., Rinchi M., Pugi L., Ridolfi A., Vettori G., Odometric
       estimation for automatic train protection and control systems, Vehicle System
       Dynamics 49(5), 2011: wheel-diameter uncertainty, slip in traction and slide in
       braking as the dominant tachometer errors. The numbers of the presets above are
       illustrative, not taken from a table of this paper.
.. [3] ERA/UNISIG SUBSET-041, ETCS performance requirements for interoperability:
       odometer accuracy +-(5 m + 5 % of the distance travelled).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ConfigError
from ._common import lockstep_members, positive_step
from .imu import first_order_recursion

if TYPE_CHECKING:
    from ..types import NominalOdometer

__all__ = [
    "QUANTIZATION_BLOCK",
    "PRESET_NAMES",
    "OdometerModel",
    "OdometerState",
    "OdometerOutput",
    "simulate_odometer",
    "simulate_odometer_batch",
    "slip_factor",
]

QUANTIZATION_BLOCK = 1024
"""The quantiser's accumulator is renormalised every this many steps (global index)."""

PRESET_NAMES = ("ideal", "rail-tachometer", "car-wheel-speed")


@dataclass(frozen=True, slots=True)
class OdometerModel:
    """Truth-side error model of a wheel odometer (see the module docstring).

    Attributes
    ----------
    wheel_circumference_m : float
        Nominal rolling circumference of the wheel, m (> 0).
    pulses_per_revolution : int
        Encoder pulses per wheel revolution; 0 = no quantiser (continuous output).
    scale_factor_sigma : float
        1-sigma of the turn-on scale-factor error c of (OD.2), dimensionless.
    scale_factor_gm_sigma : float
        Stationary 1-sigma of the Gauss-Markov scale-factor term g (OD.3).
    scale_factor_gm_tau_s : float
        Its correlation time, s (> 0).
    noise_density_m_per_sqrt_s : float
        White distance-noise density q of (OD.1), m/sqrt(s).
    slip_fraction, slide_fraction : float
        Over-read in traction and under-read in braking (OD.4), fractions of the true
        distance, in [0, 1).
    slip_accel_threshold_mps2 : float
        Along-track acceleration magnitude above which (OD.4) applies, m/s^2 (> 0;
        ``inf`` never).
    """

    wheel_circumference_m: float = 2.890
    pulses_per_revolution: int = 0
    scale_factor_sigma: float = 0.0
    scale_factor_gm_sigma: float = 0.0
    scale_factor_gm_tau_s: float = 600.0
    noise_density_m_per_sqrt_s: float = 0.0
    slip_fraction: float = 0.0
    slide_fraction: float = 0.0
    slip_accel_threshold_mps2: float = math.inf

    def __post_init__(self) -> None:
        def number(name: str) -> float:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ConfigError(f"odometer.{name}", "a number", value)
            return float(value)

        c = number("wheel_circumference_m")
        if not (c > 0.0 and math.isfinite(c)):
            raise ConfigError("odometer.wheel_circumference_m", "a positive finite circumference, m", c)
        ppr = self.pulses_per_revolution
        if isinstance(ppr, bool) or not isinstance(ppr, (int, np.integer)) or ppr < 0:
            raise ConfigError("odometer.pulses_per_revolution", "an integer >= 0 (0: no quantiser)", ppr)
        for name in ("scale_factor_sigma", "scale_factor_gm_sigma", "noise_density_m_per_sqrt_s"):
            value = number(name)
            if not (value >= 0.0 and math.isfinite(value)):
                raise ConfigError(f"odometer.{name}", "a non-negative finite number", value)
        tau = number("scale_factor_gm_tau_s")
        if not tau > 0.0:
            raise ConfigError("odometer.scale_factor_gm_tau_s", "a positive time, s (inf: random constant)", tau)
        for name in ("slip_fraction", "slide_fraction"):
            value = number(name)
            if not 0.0 <= value < 1.0:
                raise ConfigError(f"odometer.{name}", "a fraction in [0, 1)", value)
        thr = number("slip_accel_threshold_mps2")
        if not thr > 0.0:
            raise ConfigError("odometer.slip_accel_threshold_mps2", "a positive acceleration, m/s^2 (inf: never)", thr)
        for name in ("wheel_circumference_m", "scale_factor_sigma", "scale_factor_gm_sigma", "scale_factor_gm_tau_s",
                     "noise_density_m_per_sqrt_s", "slip_fraction", "slide_fraction", "slip_accel_threshold_mps2"):
            object.__setattr__(self, name, float(getattr(self, name)))
        object.__setattr__(self, "pulses_per_revolution", int(ppr))

    @property
    def pulse_length_m(self) -> float:
        """Distance per pulse p, m (0 without a quantiser)."""
        if self.pulses_per_revolution == 0:
            return 0.0
        return self.wheel_circumference_m / self.pulses_per_revolution

    @property
    def has_slip(self) -> bool:
        return (self.slip_fraction > 0.0 or self.slide_fraction > 0.0) and math.isfinite(self.slip_accel_threshold_mps2)

    def nominal(self) -> NominalOdometer:
        """The datasheet an estimator is told (:class:`navsim.types.NominalOdometer`), never
        the drawn errors: the larger of the slip and slide fractions, the slip threshold
        (inf without slip)."""
        from ..types import NominalOdometer

        return NominalOdometer(
            pulse_length_m=self.pulse_length_m, scale_factor_sigma=self.scale_factor_sigma,
            scale_factor_gm_sigma=self.scale_factor_gm_sigma, scale_factor_tau_s=self.scale_factor_gm_tau_s,
            noise_density_m_per_sqrt_s=self.noise_density_m_per_sqrt_s,
            slip_fraction=max(self.slip_fraction, self.slide_fraction),
            slip_accel_threshold_mps2=self.slip_accel_threshold_mps2 if self.has_slip else float("inf"),
        )

    @classmethod
    def preset(cls, name: str) -> OdometerModel:
        """A named model: ``"ideal"``, ``"rail-tachometer"``, ``"car-wheel-speed"``
        (values and sources in the module docstring)."""
        if name == "ideal":
            return cls()
        if name == "rail-tachometer":
            return cls(wheel_circumference_m=math.pi * 0.92, pulses_per_revolution=200, scale_factor_sigma=3e-3,
                       scale_factor_gm_sigma=1e-3, scale_factor_gm_tau_s=600.0, noise_density_m_per_sqrt_s=1e-3,
                       slip_fraction=0.01, slide_fraction=0.01, slip_accel_threshold_mps2=0.45)
        if name == "car-wheel-speed":
            return cls(wheel_circumference_m=1.95, pulses_per_revolution=48, scale_factor_sigma=5e-3,
                       scale_factor_gm_sigma=2e-3, scale_factor_gm_tau_s=300.0, noise_density_m_per_sqrt_s=2e-3,
                       slip_fraction=0.02, slide_fraction=0.02, slip_accel_threshold_mps2=2.0)
        raise ConfigError("odometer.preset", f"one of {PRESET_NAMES}", name)


@dataclass(frozen=True, slots=True, eq=False)
class OdometerState:
    """Everything recursive in the odometer model.

    Attributes
    ----------
    step_index : int
        Steps generated so far (global index of the next step).
    scale_factor_turn_on : float
        The turn-on scale-factor error c of (OD.2).
    scale_factor_gm : float
        The Gauss-Markov term g during the next step (OD.3).
    accumulator_m : float
        Running sum of d since the last renormalisation, m (OD.5).
    count : float
        Pulses emitted since the last renormalisation (a whole number); the residual carry
        is ``accumulator_m - p count`` in [0, p).
    """

    step_index: int
    scale_factor_turn_on: float
    scale_factor_gm: float
    accumulator_m: float = 0.0
    count: float = 0.0

    def __post_init__(self) -> None:
        if isinstance(self.step_index, bool) or int(self.step_index) != self.step_index or self.step_index < 0:
            raise ConfigError("state.step_index", "an integer >= 0", self.step_index)
        object.__setattr__(self, "step_index", int(self.step_index))
        for name in ("scale_factor_turn_on", "scale_factor_gm", "accumulator_m", "count"):
            object.__setattr__(self, name, float(getattr(self, name)))

    @classmethod
    def initial(cls, model: OdometerModel, rng: np.random.Generator) -> OdometerState:
        """Turn-on state; draws one block of 2 standard normals: ``z[0]`` the turn-on
        scale factor (``scale_factor_sigma z[0]``), ``z[1]`` the Gauss-Markov term from
        its stationary distribution (``scale_factor_gm_sigma z[1]``)."""
        z = rng.standard_normal(2)
        return cls(0, model.scale_factor_sigma * float(z[0]), model.scale_factor_gm_sigma * float(z[1]))

    def residual_m(self, model: OdometerModel) -> float:
        """Distance rolled but not yet counted, m (0 without a quantiser)."""
        return self.accumulator_m - model.pulse_length_m * self.count if model.pulses_per_revolution else 0.0

    def __eq__(self, other: object) -> bool:
        return isinstance(other, OdometerState) and all(
            getattr(self, n) == getattr(other, n) for n in OdometerState.__slots__)

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, slots=True, eq=False)
class OdometerOutput:
    """Odometer output of n steps (a leading member axis B in the batched form).

    Attributes
    ----------
    ds_m : (n,) or (B, n)
        Distance per step as counted, m: ``p pulses`` with a quantiser, else ``d``.
    pulses : (n,) or (B, n) int64
        Pulses counted in each step (0 without a quantiser).
    scale_factor : (n,) or (B, n)
        The scale-factor error ``c + g_k`` applied in each step (diagnostic).
    """

    ds_m: NDArray[np.float64]
    pulses: NDArray[np.int64]
    scale_factor: NDArray[np.float64]


def slip_factor(accel: ArrayLike, model: OdometerModel) -> NDArray[np.float64]:
    """The slip term of (OD.4) for along-track accelerations ``accel`` (m/s^2)."""
    a = np.asarray(accel, dtype=float)
    thr = model.slip_accel_threshold_mps2
    return np.where(a > thr, model.slip_fraction, np.where(a < -thr, -model.slide_fraction, 0.0))


def _renormalise_quantize(d: NDArray, p: float, acc: NDArray, count: NDArray, start_index: int) -> tuple[NDArray, NDArray,
                          NDArray]:
    """(OD.5) for B members at once: d (B, n); returns pulses (B, n), acc, count (B,)."""
    n = d.shape[1]
    out = np.empty(d.shape)
    i = 0
    while i < n:
        g = start_index + i
        stop = min(n, i + QUANTIZATION_BLOCK - g % QUANTIZATION_BLOCK)
        # np.cumsum is a sequential accumulation: the same sums whatever the chunking
        sums = np.cumsum(np.concatenate((acc[:, None], d[:, i:stop]), axis=1), axis=1)[:, 1:]
        counts = np.floor(sums / p)
        out[:, i:stop] = np.diff(np.concatenate((count[:, None], counts), axis=1), axis=1)
        acc, count = sums[:, -1], counts[:, -1]
        if (start_index + stop) % QUANTIZATION_BLOCK == 0:
            acc = acc - p * count
            count = np.zeros_like(count)
        i = stop
    return out, acc, count


def simulate_odometer_batch(ds_true: ArrayLike, accel: ArrayLike, model: OdometerModel,
                            states: Sequence[OdometerState], rngs: Sequence[np.random.Generator], *,
                            dt: float) -> tuple[OdometerOutput, list[OdometerState]]:
    """The odometer of B members that share the true motion, in one pass.

    Member j gets exactly the numbers of ``simulate_odometer(..., states[j], rngs[j])``
    (that function is this one with B = 1).

    Parameters
    ----------
    ds_true : (n,) array
        True along-track arc-length increment of each step, m.
    accel : (n,) array
        True along-track acceleration at each step (its end), m/s^2, for (OD.4).
    model : OdometerModel
    states : sequence of B OdometerState, at the same ``step_index`` (lockstep).
    rngs : sequence of B numpy.random.Generator
        Generator j draws one ``(n, 2)`` block.
    dt : float
        Step length, s (> 0): the noise (OD.1) and the Gauss-Markov discretisation (OD.3).

    Returns
    -------
    output : OdometerOutput with (B, n) arrays.
    new_states : list of B OdometerState.
    """
    if not isinstance(model, OdometerModel):
        raise ConfigError("model", "an OdometerModel", type(model).__name__)
    dt = positive_step(dt)
    states, rngs, index = lockstep_members(states, rngs, "step_index", OdometerState)
    ds_true = np.asarray(ds_true, dtype=float)
    accel = np.asarray(accel, dtype=float)
    if ds_true.ndim != 1 or accel.shape != ds_true.shape:
        raise ConfigError("accel", f"shape {ds_true.shape} like ds_true (n,)", accel.shape)
    n, members = len(ds_true), len(states)
    if n == 0:
        empty = np.zeros((members, 0))
        return OdometerOutput(empty, np.zeros((members, 0), dtype=np.int64), empty.copy()), states

    z = np.empty((members, n, 2))  # one block per member and call; width fixed
    for j, rng in enumerate(rngs):
        rng.standard_normal(out=z[j])
    # (OD.3) Gauss-Markov scale factor: g_0 from the state, g_1..g_n by the exact recursion
    tau, sigma_g = model.scale_factor_gm_tau_s, model.scale_factor_gm_sigma
    phi = math.exp(-dt / tau)
    drive = (sigma_g * math.sqrt(-math.expm1(-2.0 * dt / tau))) * z[:, :, 1]
    g_start = np.array([s.scale_factor_gm for s in states])
    g_next = first_order_recursion(np.asarray(phi), drive, g_start)  # (B, n): g_1..g_n
    g_used = np.concatenate((g_start[:, None], g_next[:, :-1]), axis=1)
    turn_on = np.array([s.scale_factor_turn_on for s in states])
    scale = turn_on[:, None] + g_used  # (OD.2)
    # (OD.1) with the slip/slide term (OD.4)
    factor = 1.0 + scale
    if model.has_slip:
        factor = factor + slip_factor(accel, model)[None, :]
    d = ds_true[None, :] * factor + (model.noise_density_m_per_sqrt_s * math.sqrt(dt)) * z[:, :, 0]
    acc = np.array([s.accumulator_m for s in states])
    count = np.array([s.count for s in states])
    p = model.pulse_length_m
    if p > 0.0:  # (OD.5)
        pulses, acc, count = _renormalise_quantize(d, p, acc, count, index)
        ds_m = pulses * p
    else:
        pulses, ds_m = np.zeros(d.shape), d
    new_states = [OdometerState(index + n, float(turn_on[j]), float(g_next[j, -1]), float(acc[j]), float(count[j]))
                  for j in range(members)]
    return OdometerOutput(ds_m, pulses.astype(np.int64), scale), new_states


def simulate_odometer(ds_true: ArrayLike, accel: ArrayLike, model: OdometerModel, state: OdometerState,
                      rng: np.random.Generator, *, dt: float) -> tuple[OdometerOutput, OdometerState]:
    """The odometer output of n consecutive steps (the B = 1 case of
    :func:`simulate_odometer_batch`; arrays (n,))."""
    out, states = simulate_odometer_batch(ds_true, accel, model, [state], [rng], dt=dt)
    return OdometerOutput(out.ds_m[0], out.pulses[0], out.scale_factor[0]), states[0]
