"""The one table of navsim's exchanged variables: names, units, descriptions, start values.

The sensor variables of both FMUs (the plant's outputs, the estimator's inputs: IMU
increments and multiple integrals, GNSS channels, every optional sensor's outputs, and
``time.t_s``) and the solution, prior and truth variables are generated from the signal
table :data:`navsim.signals.SIGNALS` (name, unit, shape, type, description of each
signal declared once; a signal with ``components`` becomes one variable per component,
``nav.lat_rad``, ``truth.velocity_n``), so a signal declared there appears in both FMUs,
and one of an optional sensor only where the scenario has that sensor. This module adds
only what is FMI-specific: the variable causality, variability and start values, the
FMU-only variables beside the signals (info, parameters, motion inputs, the step
counters, ``gnss.t_s`` / ``receiver_outage`` / ``n_valid`` / ``prn``, the solution's
standard deviations), and the FMI unit definitions. It imports neither gymnasium nor
pythonfmu.

A :class:`Var` is one signal, scalar or array (``shape``). The FMI 3 FMUs export arrays
as FMI 3 arrays; the FMI 2 FMUs, which have scalars only, export each element as a
scalar named with 1-based structured indices, ``gnss.pseudorange_m[3]`` or
``gnss.sat_pos_e[3,2]`` (:func:`scalar_names`). Gymnasium spaces use ``shape``, ``low``
and ``high`` (finite bounds; ``None`` = use a generous default).

Groups (``Var.group``)
    ``parameter``  set before initialisation (seed, sensor grades, noise, outages)
    ``motion``     inputs: external along-track motion (arc length, speed, acceleration)
    ``imu``        IMU increments and multiple integrals of the last navigation step(s)
    ``gnss``       per-channel GNSS arrays with a validity mask and a new-epoch flag
    (sensor)       an optional sensor's outputs, group = its name (only with that sensor)
    ``time``       time stamps and counters
    ``truth``      the true state (plant only; never an estimator input)
    ``prior``      the estimator's initial estimate drawn by the simulator
    ``solution``   the navigation solution and its uncertainty (estimator outputs,
                   the Gymnasium action)
    ``info``       navsim version and configuration hash

Use :func:`plant_variables`, :func:`estimator_variables` for the FMU tables and
:func:`observation_variables`, :func:`action_variables` for the Gymnasium spaces; all
take the scenario's dimensions (:class:`Dimensions`).

Units are the FMI unit names used in the FMUs' ``UnitDefinitions`` (:data:`UNITS`
gives their SI base-unit exponents).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Mapping

from navsim.signals import SIGNALS, Signal, optional_sensors, signal

if TYPE_CHECKING:  # type hints only
    from navsim.scenario import Scenario
    from navsim.simulator import Simulator

__all__ = [
    "Var",
    "Dimensions",
    "UNITS",
    "plant_variables",
    "estimator_variables",
    "observation_variables",
    "action_variables",
    "scalar_names",
    "size",
]

# unit name -> SI base-unit exponents (FMI UnitDefinitions / BaseUnit attributes)
UNITS: dict[str, dict[str, int]] = {
    "s": {"s": 1},
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "m.s": {"m": 1, "s": 1},
    "m.s2": {"m": 1, "s": 2},
    "m2": {"m": 2},
    "m2/s2": {"m": 2, "s": -2},
    "rad": {"rad": 1},
    "rad/s": {"rad": 1, "s": -1},
    "rad.s": {"rad": 1, "s": 1},
    "rad.s2": {"rad": 1, "s": 2},
    "rad.s3": {"rad": 1, "s": 3},
    "N": {"kg": 1, "m": 1, "s": -2},
}


StartValue = float | int | bool | str | None
"""A variable's start value (scalar, broadcast over its shape), ``None`` for calculated outputs."""


@dataclass(frozen=True, slots=True)
class Var:
    """One exchanged signal.

    Attributes
    ----------
    name : str
        Structured name (``group.quantity_unit``), unique within a table.
    type : str
        ``"real"``, ``"int"``, ``"bool"`` or ``"string"``.
    causality : str
        FMI causality: ``"parameter"``, ``"calculatedParameter"``, ``"input"`` or
        ``"output"``.
    variability : str
        FMI variability: ``"fixed"``, ``"tunable"``, ``"discrete"``, ``"continuous"``.
    unit : str
        A key of :data:`UNITS`, or ``""`` (dimensionless, counts, flags, text).
    description : str
        One line: what it is, its frame, when it changes.
    start : float, int, bool, str or None
        Start value (scalar; broadcast over ``shape``) for parameters and inputs,
        ``None`` for calculated outputs.
    shape : tuple of int
        ``()`` for a scalar.
    group : str
        See the module docstring.
    low, high : float or None
        Finite bounds for Gymnasium spaces (``None``: the face picks a default).
    """

    name: str
    type: str
    causality: str
    variability: str
    unit: str
    description: str
    start: StartValue = None
    shape: tuple[int, ...] = ()
    group: str = ""
    low: float | None = None
    high: float | None = None

    def __post_init__(self) -> None:
        if self.type not in ("real", "int", "bool", "string"):
            raise ValueError(f"Var.type: expected real/int/bool/string, got {self.type!r}")
        if self.unit and self.unit not in UNITS:
            raise ValueError(f"Var.unit: expected one of {sorted(UNITS)}, got {self.unit!r}")

    @property
    def size(self) -> int:
        """Number of scalar elements."""
        return size(self.shape)


@dataclass(frozen=True, slots=True)
class Dimensions:
    """The scenario's dimensions that size the tables.

    channels : GNSS channels (one per satellite of the constellation).
    orders : multiple-integral orders R of the IMU output.
    samples_per_step : IMU samples m per navigation step.
    sensors : the optional sensors the scenario has (names of
        :data:`navsim.signals.OPTIONAL_SENSORS`, each ``[name] enabled``); a signal with
        ``optional = name`` is a variable only then.
    """

    channels: int
    orders: int
    samples_per_step: int
    sensors: frozenset[str] = frozenset()

    @classmethod
    def of_scenario(cls, scenario: Scenario, channels: int) -> "Dimensions":
        """The dimensions of a :class:`navsim.scenario.Scenario` whose constellation has
        ``channels`` satellites (no simulator built)."""
        return cls(channels=int(channels), orders=int(scenario.imu.orders),
                   samples_per_step=int(scenario.timing.samples_per_step), sensors=optional_sensors(scenario))

    @classmethod
    def of(cls, simulator: Simulator) -> "Dimensions":
        """The dimensions of a built :class:`navsim.simulator.Simulator`."""
        return cls.of_scenario(simulator.scenario, len(simulator.constellation.prn))


def size(shape: tuple[int, ...]) -> int:
    n = 1
    for d in shape:
        n *= d
    return n


def scalar_names(var: Var) -> list[str]:
    """FMI 2 scalar names of ``var`` in row-major order (1-based structured indices)."""
    if not var.shape:
        return [var.name]
    names = [""]
    for d in var.shape:
        names = [f"{p},{i}" if p else str(i) for p in names for i in range(1, d + 1)]
    return [f"{var.name}[{p}]" for p in names]


# --------------------------------------------------------------------------- groups
def _info_vars() -> list[Var]:
    return [
        Var("navsim.version", "string", "calculatedParameter", "fixed", "",
            "Version of the navsim package that runs this FMU (set at initialisation)", group="info"),
        Var("navsim.build_version", "string", "calculatedParameter", "fixed", "",
            "Version of navsim that built this FMU", group="info"),
        Var("navsim.config_hash", "string", "calculatedParameter", "fixed", "",
            "SHA-256 (16 hex digits) of the effective scenario after parameter overrides", group="info"),
        Var("navsim.scenario", "string", "calculatedParameter", "fixed", "",
            "Name of the embedded scenario", group="info"),
    ]


_FMI_TYPES = {"float64": "real", "int8": "bool", "int64": "int"}
_NO_DIMS = Dimensions(0, 0, 0)  # for the signals of fixed shape (solution, prior, truth)


def _zero(type_: str) -> float | int | bool | str:
    zeros: dict[str, float | int | bool | str] = {"real": 0.0, "int": 0, "bool": False, "string": ""}
    return zeros[type_]
_TIME_NOTE = {"plant": " served (holds between steps)",
              "estimator": ": the plant's time.t_s, end time of the plant's latest navigation step"}


def _signal_shape(sig: Signal, dims: Dimensions) -> tuple[int, ...]:
    """The FMU shape of a signal: its dimensions with R, m, k resolved; (1,) is a scalar."""
    sizes = {"R": dims.orders, "m": dims.samples_per_step, "k": dims.channels}
    shape = tuple(sizes[d] if isinstance(d, str) else d for d in sig.shape)
    return () if shape == (1,) else shape


def _signal_vars(sig: Signal, dims: Dimensions, causality: str, description: str = "") -> list[Var]:
    """The FMU variables of one signal of :data:`navsim.signals.SIGNALS`: its FMU name,
    type, unit, shape and description. Multiple-integral signals (``order_units``) become
    one (3,) variable per order r, named ``{fmu_name}{r}`` with the unit of that order.
    FMI specifics: inputs start at zero (outputs have no start value); IMU inputs are
    ``continuous``, everything else ``discrete``."""
    type_ = _FMI_TYPES[sig.dtype]
    start = _zero(type_) if causality == "input" else None
    variability = "continuous" if causality == "input" and sig.group == "imu" else "discrete"
    text = description or sig.description
    if sig.order_units:
        return [Var(f"{sig.fmu_name}{r}", type_, causality, variability, sig.order_units[r - 1],
                    f"Order r = {r} of {sig.name}: {text}", start, (3,), sig.group) for r in range(1, dims.orders + 1)]
    if sig.components:
        return [Var(f"{sig.fmu_name}.{c.name}", type_, causality, variability, c.unit, c.description, start,
                    (c.size,) if c.size > 1 else (), sig.group, c.low, c.high) for c in sig.components]
    return [Var(sig.fmu_name, type_, causality, variability, sig.unit, text, start, _signal_shape(sig, dims),
                sig.group)]


def _gnss_extras(dims: Dimensions, causality: str) -> list[Var]:
    """FMU-only GNSS variables beside the observation's: the epoch's time, the receiver
    outage flag, the count of valid channels and the channel order."""
    start = causality == "input"
    n = dims.channels

    def v(name: str, type_: str, unit: str, text: str, shape: tuple[int, ...] = (), low: float | None = None,
          high: float | None = None) -> Var:
        return Var(name, type_, causality, "discrete", unit, text, _zero(type_) if start else None, shape, "gnss",
                   low, high)

    return [
        v("gnss.t_s", "real", "s", "Time of the latest GNSS epoch"),
        v("gnss.receiver_outage", "bool", "", "True when the whole receiver was in an outage at the latest epoch"),
        v("gnss.n_valid", "int", "", "Valid channels at the latest epoch", low=0, high=n),
        v("gnss.prn", "int", "", "Satellite number of each channel", (n,), low=0, high=255),
    ]


# FMI specifics appended after a signal of the table (by signal name)
_EXTRAS = {"gnss_new_epoch": _gnss_extras}


_NOT_SENSOR = ("time", "solution", "prior", "truth")


def _sensor_vars(dims: Dimensions, causality: str) -> list[Var]:
    """Every sensor signal of the table (the observation's, time aside) that the scenario
    has, in table order, with the FMU-only extras: the plant's outputs and the estimator's
    inputs. A sensor signal declared in :data:`navsim.signals.SIGNALS` appears in both FMUs."""
    out: list[Var] = []
    for sig in SIGNALS:
        if sig.group in _NOT_SENSOR or not sig.present(dims):
            continue
        out += _signal_vars(sig, dims, causality)
        extra = _EXTRAS.get(sig.name)
        if extra is not None:
            out += extra(dims, causality)
    return out


def _time_vars(kind: str, dims: Dimensions) -> list[Var]:
    t = signal("t")
    if kind == "estimator":  # the plant's counters, read to take each plant step once and in order
        return [
            *_signal_vars(t, dims, "input", t.description + _TIME_NOTE[kind]),
            Var("time.step", "int", "input", "discrete", "",
                "The plant's time.step: navigation steps the plant has served; the estimator processes the "
                "plant's data once, when this counter is one more than nav.step", 0, (), "time", low=0),
        ]
    return [
        *_signal_vars(t, dims, "output", t.description + _TIME_NOTE[kind]),
        Var("time.step", "int", "output", "discrete", "",
            "Navigation steps served since the start of the episode (the estimator FMU reads it to take "
            "each step once)", group="time", low=0),
        Var("time.steps_in_interval", "int", "output", "discrete", "",
            "Navigation steps completed in the last communication step (0 when the step ended inside a "
            "navigation step; the other outputs then hold the latest step served)", group="time", low=0),
    ]


def _estimate_time_vars() -> list[Var]:
    return [
        Var("nav.t_s", "real", "output", "discrete", "s",
            "Time the nav.* solution refers to: the end of the plant step it has processed (0: the prior). "
            "Under a Jacobi master it is one communication step behind the FMU's time", group="solution"),
        Var("nav.step", "int", "output", "discrete", "",
            "Plant navigation steps processed (the step the nav.* solution refers to)", group="solution", low=0),
        Var("nav.lag_steps", "int", "output", "discrete", "",
            "Navigation steps between the end of the last communication step and nav.t_s (0 under a "
            "plant-first Gauss-Seidel master; under a Jacobi or estimator-first master 1, or k for a "
            "communication step of k navigation steps)", group="solution",
            low=0),
    ]


def _truth_vars() -> list[Var]:
    return _signal_vars(signal("truth"), _NO_DIMS, "output")


def _prior_vars(causality: str) -> list[Var]:
    return _signal_vars(signal("prior"), _NO_DIMS, causality)


def _solution_vars(causality: str = "output") -> list[Var]:
    return _signal_vars(signal("solution"), _NO_DIMS, causality)


def _uncertainty_vars() -> list[Var]:
    """The standard deviations (FMU-only, from the covariance's diagonal), then the
    covariance, NIS and its degrees of freedom of the signal table."""
    def v(name: str, unit: str, text: str) -> Var:
        return Var(f"nav.{name}", "real", "output", "discrete", unit, text, None, (3,), "solution")

    return [
        v("sigma_position_n", "m", "Standard deviation of the position error, ENU (nan if not estimated)"),
        v("sigma_velocity_n", "m/s", "Standard deviation of the velocity error, ENU"),
        v("sigma_attitude_n", "rad", "Standard deviation of the attitude error about ENU axes"),
        *(var for name in ("covariance", "nis", "nis_dof") for var in _signal_vars(signal(name), _NO_DIMS, "output")),
    ]


def _plant_parameters(defaults: Mapping[str, StartValue]) -> list[Var]:
    def p(name: str, type_: str, unit: str, text: str, variability: str = "fixed") -> Var:
        return Var(name, type_, "parameter", variability, unit, text, defaults.get(name), (), "parameter")

    return [
        p("seed", "int", "", "Seed of the episode's random streams (Simulator.reset(seed))"),
        p("imu.preset", "string", "", "IMU grade: ideal, paper-2012, consumer-mems, tactical, navigation"),
        p("imu.gyro_noise_density", "real", "", "Gyro white-noise density (angle random walk), rad/sqrt(s); "
          "-1 keeps the preset's value"),
        p("imu.accel_noise_density", "real", "", "Accelerometer white-noise density (velocity random walk), "
          "m/s/sqrt(s); -1 keeps the preset's value"),
        p("gnss.preset", "string", "", "GNSS error preset: paper-2012, standalone, ideal"),
        p("gnss.pseudorange_sigma_m", "real", "m", "Pseudorange white-noise sigma; -1 keeps the preset's value"),
        p("gnss.doppler_sigma_mps", "real", "m/s", "Doppler (pseudorange-rate) noise sigma; -1 keeps the preset's"),
        p("outages.windows_s", "string", "",
          "GNSS outage windows as a TOML array of [start, end] pairs in seconds, e.g. [[400.0, 700.0]]"),
        p("scenario.overrides", "string", "",
          "Further scenario overrides as TOML (e.g. 'imu.orders = 2'); applied last"),
        p("motion.use_inputs", "bool", "",
          "True: the motion.* inputs drive the vehicle (profile 'external'); False: the scenario's profile"),
        p("motion.inputs_at_step_start", "bool", "",
          "False: motion.* inputs at doStep(t, h) are the state at t + h (a Gauss-Seidel master stepping the "
          "motion source first); True: the state at t, extrapolated with constant acceleration to t + h"),
    ]


def _motion_inputs(defaults: Mapping[str, StartValue]) -> list[Var]:
    def v(name: str, unit: str, text: str) -> Var:
        return Var(name, "real", "input", "continuous", unit, text, defaults.get(name, 0.0), (), "motion")

    return [
        v("motion.s_m", "m", "External arc length along the track (used when motion.use_inputs)"),
        v("motion.speed_mps", "m/s", "External speed along the track, ds/dt"),
        v("motion.accel_mps2", "m/s2", "External acceleration along the track, d2s/dt2"),
    ]


# --------------------------------------------------------------------------- tables
def plant_variables(dims: Dimensions, defaults: Mapping[str, StartValue] | None = None) -> list[Var]:
    """The plant FMU's variables, in value-reference order.

    ``defaults`` maps parameter and input names to start values (from the scenario).
    """
    defaults = defaults or {}
    return (_info_vars() + _plant_parameters(defaults) + _motion_inputs(defaults) + _time_vars("plant", dims)
            + _sensor_vars(dims, "output") + _truth_vars() + _prior_vars("output"))


def estimator_variables(dims: Dimensions, defaults: Mapping[str, StartValue] | None = None) -> list[Var]:
    """The estimator FMU's variables: the plant's sensor outputs and prior as inputs, the
    solution and its uncertainty as outputs (same names as the plant's, so connections
    go by name)."""
    defaults = defaults or {}
    params = [
        Var("estimator.name", "string", "parameter", "fixed", "", "Registered estimator (navsim.estimators.make)",
            defaults.get("estimator.name", ""), (), "parameter"),
        Var("estimator.options", "string", "parameter", "fixed", "",
            "Estimator keyword options as a TOML inline table body, e.g. 'gnss_update = \"pseudorange\"'",
            defaults.get("estimator.options", ""), (), "parameter"),
    ]
    return (_info_vars() + params + _sensor_vars(dims, "input") + _prior_vars("input")
            + _time_vars("estimator", dims) + _estimate_time_vars() + _solution_vars() + _uncertainty_vars())


def observation_variables(dims: Dimensions) -> list[Var]:
    """The sensor signals of one navigation step (the Gymnasium observation): IMU and
    GNSS (never truth), with ``time.t_s``."""
    return [v for v in plant_variables(dims) if v.group in ("imu", "gnss") or v.name == "time.t_s"]


def action_variables() -> list[Var]:
    """The navigation solution (the Gymnasium action): the 9 values of
    :meth:`navsim.estimators.base.Estimate.as_action`, in that order."""
    return _solution_vars()
