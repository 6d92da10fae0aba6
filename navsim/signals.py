"""The signal table: every quantity that leaves or enters the core, declared once, and its codec.

Each :class:`Signal` is one named quantity with its shape, unit, bounds and description.
The faces read them from :data:`SIGNALS`:

* the Gymnasium face (:mod:`navsim.envs.spaces`) builds its observation space from the
  ``observation`` signals, each a flat 1-D entry of :meth:`Signal.size` elements with the
  bounds of :meth:`Signal.bounds` (``binary`` signals become ``MultiBinary``); the core
  never imports Gymnasium;
* :class:`ObservationCodec` turns a simulator chunk into per-step observations
  (:meth:`~ObservationCodec.encode_chunk`, one vectorised pass per chunk) and an
  observation back into the :class:`~navsim.types.Measurement` an estimator steps on
  (:meth:`~ObservationCodec.decode`, a few microseconds: reshapes of the observation's own
  arrays, no copies); :meth:`~ObservationCodec.encode_measurement` is its inverse;
* the navigation solution is the 9-vector of :data:`SOLUTION_FIELDS` (the action layout,
  :meth:`navsim.types.NavSolution.as_action`) with its 9 x 9 covariance over
  :data:`navsim.types.STATE_LABELS`, NIS and its degrees of freedom;
* truth (plant FMU outputs) is the along-track state, the solution layout and the ECEF
  position (:data:`TRUTH_FIELDS`).

Table (``R`` multiple-integral orders, ``m`` IMU samples per navigation step, ``k``
GNSS channels, one per satellite of the constellation, in ``gnss_prn`` order):

=========================  ===========  ========  ========================================
name                       shape        unit      meaning
=========================  ===========  ========  ========================================
``t``                      (1,)         s         end time of the navigation step
``dtheta_r``               (R, 3)       rad s^(r-1)  r-fold integrals of the angular rate
                                                  over the step (seed 000 eq. 1.14)
``dv_r``                   (R, 3)       m/s s^(r-1)  the same of the specific force
``dtheta_sub``             (m, 3)       rad       first-order gyro increments per sample
``dv_sub``                 (m, 3)       m/s       first-order accelerometer increments
``gnss_new_epoch``         (1,) binary            1 when a GNSS epoch falls at the step end
``gnss_valid``             (k,) binary            channel validity (0 between epochs)
``pseudorange_m``          (k,)         m         pseudorange, seed 003 eq. (2)
``pseudorange_rate_mps``   (k,)         m/s       pseudorange rate (Doppler), eq. (3)
``sat_pos_e``              (k, 3)       m         satellite ECEF position
``sat_vel_e``              (k, 3)       m/s       satellite ECEF velocity
``odometer_ds``            (1,)         m         odometer distance over the step (only
                                                  with ``[odometer] enabled``)
``baro_alt``               (1,)         m         barometric pressure altitude at the step
                                                  end (only with ``[baro] enabled``)
``solution``               (9,)         mixed     lat, lon (rad), h (m), vENU (m/s),
                                                  heading, pitch, roll (rad)
``covariance``             (9, 9)       SI        over STATE_LABELS (m, m/s, rad)
``nis`` / ``nis_dof``      (1,)                   NIS of an update, its dof (nan/0: none)
``prior``                  (9,)         mixed     the initial estimate, the solution layout
``truth``                  (15,)        mixed     s, speed, accel, the solution layout, ECEF
=========================  ===========  ========  ========================================

Observation entries are flattened row by row (``obs["dtheta_r"].reshape(R, 3)`` is the
(R, 3) array of :class:`~navsim.types.Measurement`): every entry is 1-D, as RL libraries
prefer. Between epochs the GNSS entries are zero with ``gnss_valid == 0``; at an epoch,
invalid channels hold finite but meaningless values.

Bounds are physical limits far outside anything a bundled scenario produces, so no face
ever clips: an angular rate of :data:`MAX_RATE_RAD_S`, a specific force of
:data:`MAX_FORCE_MPS2`, satellite distances of :data:`MAX_RANGE_M`. The r-fold integral
of a quantity bounded by B over a span dt is bounded by ``B dt^r / r!``.

For the FMU face (variables of the plant and estimator FMUs and their model
description) each signal gives ``fmu_name`` (structured ``group.quantity`` name),
``unit`` (an FMI unit name of :data:`UNIT_EXPONENTS`; order-dependent signals give
``order_units``, one per order r, and are exported as ``{fmu_name}{r}`` of shape (3,)),
``shape`` (:meth:`Signal.dims`), ``dtype`` and ``causality`` (``output`` of the core:
sensor data, truth; ``input`` of the core: the solution an agent or estimator returns).
The plant FMU's outputs are the sensor signals (every group but time, solution, prior,
truth), the ``truth`` and ``prior`` signals; the estimator FMU takes the sensor and
``prior`` signals as inputs and gives the ``solution`` signals. A signal with
``components`` (solution, prior, truth) is exported as one variable per
:class:`Component` (``nav.lat_rad``, ``truth.velocity_n``).

Optional sensors (:data:`OPTIONAL_SENSORS`): each is declared once with its name (the
scenario section ``[name] enabled``, the :class:`~navsim.types.Context` field, the
chunk attribute) and how its nominal specification is obtained; a signal names its
sensor in ``optional``, the chunk array it is read from in ``source``, the
:class:`~navsim.types.Measurement` field it fills in ``measurement`` and how the plant
FMU combines several navigation steps in ``compose``. From that declaration alone,
:func:`navsim.episode.make_context`, the measurements of :mod:`navsim.episode`, both
FMUs (variables, plant outputs, estimator inputs) and the Gymnasium observation space
carry it.

Adding an output of an existing sensor: declare one :class:`Signal` in :data:`SIGNALS`
(with ``source``, ``measurement`` and ``compose`` for a per-step quantity); the
observation codec's :meth:`ObservationCodec.encode_chunk` and
:meth:`ObservationCodec.decode` still fill the optional sensors' entries by name.

References
----------
.. [1] Litmanovich Yu.A. (2002), seed 000, eq. (1.14): multiple-integral increments.
.. [2] Sokolov S.V., Vdovichenko S.S. (2012), seed 003, eqs. (2), (3): GNSS observables.
.. [3] Modelica Association, FMI 3.0 specification (2022), section 2.4.7 (variables,
       causality, units).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Literal

import numpy as np

from .types import Context, GnssObservation, Measurement

__all__ = [
    "MAX_RATE_RAD_S",
    "MAX_FORCE_MPS2",
    "MAX_RANGE_M",
    "MAX_RANGE_RATE_MPS",
    "MAX_SAT_SPEED_MPS",
    "MAX_WHEEL_SPEED_MPS",
    "MAX_PRESSURE_ALTITUDE_M",
    "UNIT_EXPONENTS",
    "SOLUTION_FIELDS",
    "TRUTH_FIELDS",
    "Signal",
    "Component",
    "OptionalSensor",
    "OPTIONAL_SENSORS",
    "optional_sensors",
    "Layout",
    "SIGNALS",
    "MEASUREMENT_SIGNALS",
    "STEP_SIGNALS",
    "OBS_KEYS",
    "ODOMETER_KEY",
    "BARO_KEY",
    "signal",
    "observation_signals",
    "ObservationCodec",
    "BatchObservations",
]

MAX_RATE_RAD_S = 50.0
"""Bound of the angular rate, rad/s (above the range of consumer MEMS gyros, about 35 rad/s)."""
MAX_FORCE_MPS2 = 500.0
"""Bound of the specific force, m/s^2 (about 50 g)."""
MAX_RANGE_M = 1.0e8
"""Bound of pseudoranges and satellite ECEF coordinates, m (GNSS orbits: about 2.7e7 m)."""
MAX_RANGE_RATE_MPS = 1.0e5
"""Bound of pseudorange rates, m/s (satellite speeds about 4e3 m/s plus the clock drift)."""
MAX_SAT_SPEED_MPS = 1.0e4
"""Bound of satellite ECEF velocity components, m/s."""
MAX_WHEEL_SPEED_MPS = 500.0
"""Bound of the wheel speed, m/s: the odometer distance of a step is within +-500 dt m
(above any rail or road vehicle, with room for scale-factor and slip errors)."""
MAX_PRESSURE_ALTITUDE_M = 2.0e4
"""Bound of the barometric pressure altitude, m (MEMS barometers read 300-1100 hPa, about
-700 to +9200 m in the standard atmosphere)."""

UNIT_EXPONENTS: dict[str, dict[str, int]] = {
    "s": {"s": 1},
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "m.s": {"m": 1, "s": 1},
    "m.s2": {"m": 1, "s": 2},
    "rad": {"rad": 1},
    "rad/s": {"rad": 1, "s": -1},
    "rad.s": {"rad": 1, "s": 1},
    "rad.s2": {"rad": 1, "s": 2},
    "rad.s3": {"rad": 1, "s": 3},
}
"""FMI unit names used by the table -> SI base-unit exponents (FMI ``UnitDefinitions``)."""

SOLUTION_FIELDS = ("lat", "lon", "h", "vE", "vN", "vU", "heading", "pitch", "roll")
"""The navigation-solution vector (rad, rad, m, m/s, m/s, m/s, rad, rad, rad)."""
TRUTH_FIELDS = ("s", "speed", "accel", "lat", "lon", "h", "vE", "vN", "vU", "heading", "pitch", "roll", "xE", "yE",
                "zE")
"""The truth vector: arc length s (m), along-track speed (m/s) and acceleration (m/s^2), the
solution layout, the ECEF position (m)."""

Group = Literal["time", "imu", "gnss", "odometer", "baro", "solution", "truth", "prior"]


@dataclass(frozen=True, slots=True)
class OptionalSensor:
    """A sensor a scenario may leave out, declared once for every face.

    ``name`` is the scenario section (``[name] enabled``), the
    :class:`~navsim.types.Context` field of its nominal specification, the chunk
    attribute of its output (``chunk.<name>``, None without it) and the simulator's
    ``<name>_model``. ``nominal(model, track, scenario)`` is the nominal specification
    the estimator is told (:func:`navsim.episode.make_context`). A :class:`Signal` with
    ``optional = name`` exists only where the sensor is enabled.
    """

    name: str
    nominal: Callable[[Any, Any, Any], Any]

    def enabled(self, scenario: Any) -> bool:
        """Whether ``scenario`` has the sensor (its section's ``enabled``)."""
        return bool(getattr(scenario, self.name).enabled)

    def model(self, scenario: Any) -> Any:
        """The sensor's error model of ``scenario`` (its section's ``model()``), None when disabled."""
        return getattr(scenario, self.name).model() if self.enabled(scenario) else None


def _start_height(track: Any, scenario: Any) -> float:
    """Height of the track at the motion's start, m (where a barometer's nominal spec is taken)."""
    return float(np.ravel(track.geodetic(scenario.motion.start_s_m)[2])[0])


OPTIONAL_SENSORS: tuple[OptionalSensor, ...] = (
    OptionalSensor("odometer", lambda model, track, scenario: model.nominal()),
    OptionalSensor("baro", lambda model, track, scenario: model.nominal(_start_height(track, scenario))),
)
"""The optional sensors, in stream order (:mod:`navsim.simulator`)."""


def optional_sensors(scenario: Any) -> frozenset[str]:
    """Names of the :data:`OPTIONAL_SENSORS` that ``scenario`` has enabled."""
    return frozenset(s.name for s in OPTIONAL_SENSORS if s.enabled(scenario))


@dataclass(frozen=True, slots=True)
class Component:
    """A named part of a vector signal as the FMUs export it (one variable each):
    ``{Signal.fmu_name}.{name}`` of ``size`` elements (1: a scalar), with its own unit,
    description and finite bounds for a face (None: the face picks a default); ``source``
    is the per-step chunk array it is read from (dotted path, as :attr:`Signal.source`),
    or "" (not read from a chunk)."""

    name: str
    unit: str
    description: str
    size: int = 1
    low: float | None = None
    high: float | None = None
    source: str = ""


@dataclass(frozen=True, slots=True)
class Layout:
    """The dimensions and time base that size the signals of one scenario.

    orders : multiple-integral orders R. samples_per_step : IMU samples m per navigation
    step. channels : GNSS channels k. odometer : the scenario has a wheel odometer.
    baro : the scenario has a barometric altimeter. nav_period_s, imu_period_s, duration_s : the time base, s.
    """

    orders: int
    samples_per_step: int
    channels: int
    odometer: bool
    nav_period_s: float
    imu_period_s: float
    duration_s: float
    baro: bool = False

    @classmethod
    def of(cls, scenario: Any, channels: int) -> Layout:
        """The layout of a :class:`navsim.scenario.Scenario` with ``channels`` GNSS channels."""
        timing = scenario.timing
        return cls(orders=int(scenario.imu.orders), samples_per_step=int(timing.samples_per_step),
                   channels=int(channels), odometer=bool(scenario.odometer.enabled),
                   nav_period_s=float(timing.nav_period_s), imu_period_s=float(timing.imu_period_s),
                   duration_s=float(timing.duration_s), baro=bool(scenario.baro.enabled))

    @classmethod
    def of_context(cls, context: Context, channels: int, duration_s: float = math.inf) -> Layout:
        """The layout an estimator knows from its :class:`~navsim.types.Context` (the
        episode length, used only by :meth:`ObservationCodec.terminal`, is not in it)."""
        return cls(orders=int(context.orders), samples_per_step=int(context.samples_per_step),
                   channels=int(channels), odometer=context.odometer is not None,
                   nav_period_s=float(context.nav_period_s), imu_period_s=float(context.imu_period_s),
                   duration_s=float(duration_s), baro=getattr(context, "baro", None) is not None)


def _integral_bounds(bound: float, span: float, orders: int) -> np.ndarray:
    """(orders, 3) bounds ``B span^r / r!`` of the r-fold integrals, r = 1..orders."""
    r = np.arange(1, orders + 1)
    col = bound * span**r / np.array([math.factorial(int(k)) for k in r], dtype=float)
    return np.repeat(col[:, None], 3, axis=1)


@dataclass(frozen=True, slots=True)
class Signal:
    """One quantity that crosses the core's boundary.

    Attributes
    ----------
    name : observation key (and the base of the FMU name).
    group : "time", "imu", "gnss", "odometer" (sensor data), "solution", "truth".
    shape : symbolic shape: ints and the letters R (orders), m (samples per step),
        k (channels); :meth:`dims` resolves it for a :class:`Layout`.
    unit : FMI unit name (a key of :data:`UNIT_EXPONENTS`) or "" (flags, counts, mixed).
    description : one line: what it is, its frame, when it changes.
    fmu_name : structured FMU variable name.
    dtype : "float64", "int8" (binary flags) or "int64" (counts).
    binary : a 0/1 flag vector (Gymnasium ``MultiBinary``).
    causality : "output" (leaves the core) or "input" (enters it: what an agent returns).
    observation : part of the Gymnasium observation.
    order_units : per-order units of an (R, 3) multiple-integral signal (r = 1, 2, ...).
    optional : the :class:`OptionalSensor` (and the layout flag) that must be present for
        the signal to exist, or "" (always there).
    source : dotted path of the per-step chunk array it is read from
        (``"odometer.ds_m"``: ``chunk.odometer.ds_m``, leading axis the steps), or "".
    measurement : the :class:`~navsim.types.Measurement` (and ``MeasurementBatch``)
        field it fills, or "" (it has its own handling).
    compose : how the plant FMU combines the values of the k navigation steps of one
        communication step: "sum" (distances, counts: they add exactly), "last" (a
        reading at the interval's end); "" (its own handling).
    components : the named parts the FMUs export instead of one array variable
        (solution, prior, truth), in element order; () exports the signal whole.
    """

    name: str
    group: Group
    shape: tuple[int | str, ...]
    unit: str
    description: str
    fmu_name: str
    dtype: str = "float64"
    binary: bool = False
    causality: Literal["output", "input"] = "output"
    observation: bool = False
    order_units: tuple[str, ...] = ()
    optional: str = ""
    source: str = ""
    measurement: str = ""
    compose: Literal["", "sum", "last"] = ""
    components: tuple[Component, ...] = ()

    def __post_init__(self) -> None:
        for unit in (self.unit, *self.order_units, *(c.unit for c in self.components)):
            if unit and unit not in UNIT_EXPONENTS:
                raise ValueError(f"Signal {self.name}: unit {unit!r} is not in UNIT_EXPONENTS")

    def dims(self, layout: Layout) -> tuple[int, ...]:
        """The concrete shape for ``layout``."""
        sizes = {"R": layout.orders, "m": layout.samples_per_step, "k": layout.channels}
        return tuple(sizes[d] if isinstance(d, str) else d for d in self.shape)

    def size(self, layout: Layout) -> int:
        """Number of scalar elements (the length of the flat observation entry)."""
        return math.prod(self.dims(layout))

    def present(self, layout: Any) -> bool:
        """Whether the signal exists in a scenario of this layout (a :class:`Layout`, or
        any object with a ``sensors`` set of the optional sensors present)."""
        if not self.optional:
            return True
        sensors = getattr(layout, "sensors", None)
        return self.optional in sensors if sensors is not None else bool(getattr(layout, self.optional))

    def read(self, chunk: Any) -> np.ndarray | None:
        """The per-step array of a chunk at :attr:`source` (None when the sensor is absent)."""
        obj = chunk
        for part in self.source.split("."):
            obj = getattr(obj, part)
            if obj is None:
                return None
        return obj

    def bounds(self, layout: Layout) -> tuple[np.ndarray, np.ndarray]:
        """Flat (size,) arrays ``(low, high)`` of physical limits (module docstring)."""
        n = self.size(layout)
        dt, h = layout.nav_period_s, layout.imu_period_s
        name = self.name
        if self.binary:
            return np.zeros(n), np.ones(n)
        if name == "t":
            return np.zeros(n), np.full(n, layout.duration_s)
        high = {
            "dtheta_r": lambda: _integral_bounds(MAX_RATE_RAD_S, dt, layout.orders).ravel(),
            "dv_r": lambda: _integral_bounds(MAX_FORCE_MPS2, dt, layout.orders).ravel(),
            "dtheta_sub": lambda: np.full(n, MAX_RATE_RAD_S * h),
            "dv_sub": lambda: np.full(n, MAX_FORCE_MPS2 * h),
            "pseudorange_m": lambda: np.full(n, MAX_RANGE_M),
            "pseudorange_rate_mps": lambda: np.full(n, MAX_RANGE_RATE_MPS),
            "sat_pos_e": lambda: np.full(n, MAX_RANGE_M),
            "sat_vel_e": lambda: np.full(n, MAX_SAT_SPEED_MPS),
            "odometer_ds": lambda: np.full(n, MAX_WHEEL_SPEED_MPS * dt),
            "baro_alt": lambda: np.full(n, MAX_PRESSURE_ALTITUDE_M),
        }.get(name)
        if high is None:
            return np.full(n, -np.inf), np.full(n, np.inf)
        hi = np.asarray(high(), dtype=np.float64)
        return -hi, hi


def _sensor(name: str, group: Group, shape: tuple[int | str, ...], unit: str, description: str, fmu_name: str,
            **kw: Any) -> Signal:
    return Signal(name, group, shape, unit, description, fmu_name, observation=True, **kw)


_SOLUTION_BOUNDS: dict[str, tuple[float, float]] = {
    "lat_rad": (-math.pi / 2, math.pi / 2), "lon_rad": (-math.pi, math.pi), "h_m": (-1e4, 1e5),
    "velocity_n": (-1e3, 1e3), "heading_rad": (-7.0, 7.0), "pitch_rad": (-3.2, 3.2), "roll_rad": (-3.2, 3.2)}
"""Finite bounds of the solution's components for a face (angles with room for a wrap)."""


def _solution_components(what: str, bounds: dict[str, tuple[float, float]]) -> tuple[Component, ...]:
    """The FMU parts of a navigation solution (the :data:`SOLUTION_FIELDS` layout)."""
    parts = (("lat_rad", "rad", "geodetic latitude", 1), ("lon_rad", "rad", "longitude", 1),
             ("h_m", "m", "height", 1), ("velocity_n", "m/s", "ENU velocity", 3), ("heading_rad", "rad", "heading", 1),
             ("pitch_rad", "rad", "pitch", 1), ("roll_rad", "rad", "roll", 1))
    return tuple(Component(name, unit, f"{what} {text}", n, *bounds.get(name, (None, None)))
                 for name, unit, text, n in parts)


SIGNALS: tuple[Signal, ...] = (
    _sensor("t", "time", (1,), "s", "End time of the navigation step", "time.t_s"),
    _sensor("dtheta_r", "imu", ("R", 3), "",
            "r-fold integrals of the angular rate over the step, body axes (seed 000 eq. 1.14); row 0 = dTheta",
            "imu.dtheta_r", order_units=("rad", "rad.s", "rad.s2", "rad.s3", "rad.s3", "rad.s3")),
    _sensor("dv_r", "imu", ("R", 3), "",
            "r-fold integrals of the specific force over the step, body axes (seed 000 eq. 1.14); row 0 = dV",
            "imu.dv_r", order_units=("m/s", "m", "m.s", "m.s2", "m.s2", "m.s2")),
    _sensor("dtheta_sub", "imu", ("m", 3), "rad", "First-order gyro increments of the step's IMU samples, body axes",
            "imu.dtheta_sub"),
    _sensor("dv_sub", "imu", ("m", 3), "m/s",
            "First-order accelerometer increments of the step's IMU samples, body axes", "imu.dv_sub"),
    _sensor("gnss_new_epoch", "gnss", (1,), "", "1 when a GNSS epoch falls at the step end", "gnss.new_epoch",
            dtype="int8", binary=True),
    _sensor("gnss_valid", "gnss", ("k",), "",
            "Channel tracked at the epoch (above the mask, not in an outage); 0 between epochs", "gnss.valid",
            dtype="int8", binary=True),
    _sensor("pseudorange_m", "gnss", ("k",), "m", "Pseudorange of each channel, seed 003 eq. (2) (0 between epochs)",
            "gnss.pseudorange_m"),
    _sensor("pseudorange_rate_mps", "gnss", ("k",), "m/s",
            "Pseudorange rate (Doppler) of each channel, seed 003 eq. (3)", "gnss.pseudorange_rate_mps"),
    _sensor("sat_pos_e", "gnss", ("k", 3), "m", "ECEF satellite position of each channel", "gnss.sat_pos_e"),
    _sensor("sat_vel_e", "gnss", ("k", 3), "m/s", "ECEF satellite velocity of each channel", "gnss.sat_vel_e"),
    _sensor("odometer_ds", "odometer", (1,), "m", "Wheel-odometer distance counted over the step", "odometer.ds_m",
            optional="odometer", source="odometer.ds_m", measurement="odometer_ds_m", compose="sum"),
    Signal("odometer_pulses", "odometer", (1,), "", "Wheel-encoder pulses counted over the same steps",
           "odometer.pulses", dtype="int64", optional="odometer", source="odometer.pulses", compose="sum"),
    _sensor("baro_alt", "baro", (1,), "m", "Barometric pressure altitude at the step end (navsim.sensors.baro)",
            "baro.altitude_m", optional="baro", source="baro.altitude_m", measurement="baro_alt_m", compose="last"),
    Signal("solution", "solution", (9,), "",
           "Navigation solution [lat, lon (rad), h (m), vE, vN, vU (m/s), heading, pitch, roll (rad)]", "nav",
           causality="input", components=_solution_components("Estimated", _SOLUTION_BOUNDS)),
    Signal("covariance", "solution", (9, 9), "",
           "Error covariance over [dE dN dU dvE dvN dvU psiE psiN psiU] (SI; nan: not estimated)", "nav.covariance",
           causality="input"),
    Signal("nis", "solution", (1,), "", "Normalised innovation squared of an update in the step (nan: none)",
           "nav.nis", causality="input"),
    Signal("nis_dof", "solution", (1,), "", "Degrees of freedom of nis (0: no update)", "nav.nis_dof",
           dtype="int64", causality="input"),
    Signal("prior", "prior", (9,), "",
           "Initial estimate (truth plus a drawn error), the solution layout, set at initialisation", "prior",
           components=_solution_components("Initial estimate of", {})),
    Signal("truth", "truth", (15,), "",
           "True state [s (m), speed (m/s), accel (m/s2) along the track, lat, lon (rad), h (m), vE, vN, vU (m/s), "
           "heading, pitch, roll (rad), ECEF position (m)]", "truth", components=(
               Component("s_m", "m", "True arc length along the track", source="truth.s"),
               Component("speed_mps", "m/s", "True speed along the track", source="truth.speed"),
               Component("accel_mps2", "m/s2", "True acceleration along the track", source="truth.accel_along"),
               Component("lat_rad", "rad", "True geodetic latitude", source="truth.lat"),
               Component("lon_rad", "rad", "True longitude", source="truth.lon"),
               Component("h_m", "m", "True height above the Earth model", source="truth.h"),
               Component("velocity_n", "m/s", "True ground velocity, ENU", 3, source="truth.velocity_n"),
               Component("heading_rad", "rad", "True heading, clockwise from north", source="truth.heading"),
               Component("pitch_rad", "rad", "True pitch, forward axis up", source="truth.pitch"),
               Component("roll_rad", "rad", "True roll, right side down", source="truth.roll"),
               Component("position_e", "m", "True ECEF position", 3, source="truth.position_e"))),
)
"""Every signal, observation entries first in observation order."""

_BY_NAME = {s.name: s for s in SIGNALS}

MEASUREMENT_SIGNALS = tuple(s for s in SIGNALS if s.measurement)
"""The signals that fill a :class:`~navsim.types.Measurement` field of their own
(``Signal.measurement``) from a chunk array (``Signal.source``): the optional sensors'."""
STEP_SIGNALS = tuple(s for s in SIGNALS if s.source and s.compose)
"""The per-step signals the plant FMU serves generically (``source`` and ``compose``)."""

OBS_KEYS = tuple(s.name for s in SIGNALS if s.observation and not s.optional)
"""Keys of every observation; :data:`ODOMETER_KEY` is added with an odometer, :data:`BARO_KEY`
with a barometer."""
ODOMETER_KEY = "odometer_ds"
BARO_KEY = "baro_alt"


def signal(name: str) -> Signal:
    """The signal called ``name``."""
    return _BY_NAME[name]


def observation_signals(layout: Layout) -> tuple[Signal, ...]:
    """The observation entries of a scenario of this layout, in observation order."""
    return tuple(s for s in SIGNALS if s.observation and s.present(layout))


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


class ObservationCodec:
    """Simulator chunks to observations, and observations to measurements, for one layout.

    ``encode_chunk(chunk)`` gives, per observation key, a read-only (n, size) array with
    one row per navigation step of the chunk (GNSS rows zero between epochs): row ``i``
    of every key is the observation of step ``chunk.step0 + i``. ``decode(obs, step)`` is
    the :class:`~navsim.types.Measurement` of one observation, its arrays views of the
    observation's own (so they are equal to those :func:`navsim.episode.measurements`
    hands out, bit for bit). ``prn`` is the channel order.
    """

    __slots__ = ("layout", "prn", "signals", "keys", "_dt", "_per_step", "_terminal")

    def __init__(self, layout: Layout, prn: np.ndarray) -> None:
        self.layout = layout
        self.prn = np.asarray(prn)
        self.signals = observation_signals(layout)
        self.keys = tuple(s.name for s in self.signals)
        self._dt = float(layout.nav_period_s)
        self._per_step = tuple(s for s in self.signals if s.source and s.measurement)
        terminal = {s.name: np.zeros(s.size(layout), dtype=s.dtype) for s in self.signals}
        terminal["t"][0] = layout.duration_s
        self._terminal = terminal

    @property
    def measurement_signals(self) -> tuple[Signal, ...]:
        """The signals of this layout that fill an optional :class:`~navsim.types.Measurement`
        field (``Signal.measurement``: the optional sensors' per-step readings)."""
        return self._per_step

    def terminal(self) -> dict[str, np.ndarray]:
        """The empty observation at the episode end (t = duration, everything else zero)."""
        return {key: value.copy() for key, value in self._terminal.items()}

    def encode_chunk(self, chunk: Any) -> dict[str, np.ndarray]:
        """Per-step observation rows of a :class:`navsim.simulator.Chunk` (see the class)."""
        n = len(chunk)
        k = self.layout.channels
        imu = chunk.imu
        rows = {
            "t": _frozen(chunk.t[:, None]),
            "dtheta_r": _frozen(imu.dtheta_r.reshape(n, -1)),
            "dv_r": _frozen(imu.dv_r.reshape(n, -1)),
            "dtheta_sub": _frozen(imu.dtheta_sample[:, :, 0, :].reshape(n, -1)),
            "dv_sub": _frozen(imu.dv_sample[:, :, 0, :].reshape(n, -1)),
        }
        new_epoch = np.zeros((n, 1), dtype=np.int8)
        valid = np.zeros((n, k), dtype=np.int8)
        gnss = (np.zeros((n, k)), np.zeros((n, k)), np.zeros((n, k, 3)), np.zeros((n, k, 3)))
        g = chunk.gnss
        if g is not None and len(chunk.gnss_step):
            at = chunk.gnss_step
            new_epoch[at] = 1
            valid[at] = g.valid
            for dst, src in zip(gnss, (g.pseudorange_m, g.pseudorange_rate_mps, g.sat_pos_e, g.sat_vel_e)):
                dst[at] = src
        rows["gnss_new_epoch"] = _frozen(new_epoch)
        rows["gnss_valid"] = _frozen(valid)
        for key, value in zip(("pseudorange_m", "pseudorange_rate_mps", "sat_pos_e", "sat_vel_e"), gnss):
            rows[key] = _frozen(value.reshape(n, -1))
        for sig in self._per_step:  # the optional sensors' entries, from their declared chunk arrays
            values = sig.read(chunk)
            if values is not None:
                rows[sig.name] = _frozen(values.reshape(n, -1))
        return rows

    @staticmethod
    def observation(rows: dict[str, np.ndarray], i: int) -> dict[str, np.ndarray]:
        """The observation of row ``i`` of :meth:`encode_chunk`'s output (views)."""
        return {key: value[i] for key, value in rows.items()}

    def decode(self, obs: dict[str, np.ndarray], step: int) -> Measurement:
        """The :class:`~navsim.types.Measurement` of observation ``obs`` of step ``step``."""
        t = float(obs["t"][0])
        gnss = None
        if obs["gnss_new_epoch"][0]:
            gnss = GnssObservation(t, self.prn, obs["sat_pos_e"].reshape(-1, 3), obs["sat_vel_e"].reshape(-1, 3),
                                   obs["pseudorange_m"], obs["pseudorange_rate_mps"],
                                   np.asarray(obs["gnss_valid"], dtype=bool))
        readings = {}
        for sig in self._per_step:  # the optional sensors' readings, by their declared Measurement field
            value = obs.get(sig.name)
            if value is not None:
                readings[sig.measurement] = float(value[0])
        return Measurement(step, t, self._dt, obs["dtheta_r"].reshape(-1, 3), obs["dv_r"].reshape(-1, 3),
                           obs["dtheta_sub"].reshape(-1, 3), obs["dv_sub"].reshape(-1, 3), gnss, **readings)

    def encode_batch_chunk(self, chunk: Any) -> BatchObservations:
        """The observations of a :class:`navsim.simulator.ChunkBatch` of N lockstep members:
        ``result(i)`` is the dict of (N, size) read-only views of step i (one truth, so
        the time, the epoch flag and the satellite states are shared stride-0 views)."""
        return BatchObservations(self, chunk)

    def encode_measurement(self, m: Measurement) -> dict[str, np.ndarray]:
        """The observation of a :class:`~navsim.types.Measurement` (inverse of :meth:`decode`)."""
        k = self.layout.channels
        obs = {"t": np.array([m.t]), "dtheta_r": np.ravel(m.dtheta_r).astype(float),
               "dv_r": np.ravel(m.dv_r).astype(float), "dtheta_sub": np.ravel(m.dtheta_sub).astype(float),
               "dv_sub": np.ravel(m.dv_sub).astype(float)}
        g = m.gnss
        if g is None:
            obs.update(gnss_new_epoch=np.zeros(1, dtype=np.int8), gnss_valid=np.zeros(k, dtype=np.int8),
                       pseudorange_m=np.zeros(k), pseudorange_rate_mps=np.zeros(k), sat_pos_e=np.zeros(3 * k),
                       sat_vel_e=np.zeros(3 * k))
        else:
            obs.update(gnss_new_epoch=np.ones(1, dtype=np.int8), gnss_valid=np.asarray(g.valid, dtype=np.int8),
                       pseudorange_m=np.asarray(g.pseudorange_m, dtype=float),
                       pseudorange_rate_mps=np.asarray(g.pseudorange_rate_mps, dtype=float),
                       sat_pos_e=np.ravel(g.sat_pos_e).astype(float), sat_vel_e=np.ravel(g.sat_vel_e).astype(float))
        for sig in self._per_step:
            value = getattr(m, sig.measurement)
            obs[sig.name] = np.array([0.0 if value is None else value])
        return obs


def _read_only(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a`` (no copy; strided rows are fine for the observations)."""
    v = a.view()
    v.flags.writeable = False
    return v


class BatchObservations:
    """Per-step observations of N lockstep members (see :meth:`ObservationCodec.encode_batch_chunk`)."""

    __slots__ = ("_epoch_at", "_t", "_new_epoch", "_imu", "_per_step", "_valid", "_pr", "_prr", "_sat_pos",
                 "_sat_vel", "_no_gnss")

    def __init__(self, codec: ObservationCodec, chunk: Any) -> None:
        imu = chunk.imu
        n_env = imu.dtheta_r.shape[0]
        c = len(chunk)
        k = codec.layout.channels
        epoch_at = np.full(c, -1, dtype=np.int64)
        if chunk.gnss is not None and len(chunk.gnss_step):
            epoch_at[chunk.gnss_step] = np.arange(len(chunk.gnss_step))
        self._epoch_at = epoch_at.tolist()
        self._t = np.broadcast_to(chunk.t[:, None, None], (c, n_env, 1))
        self._new_epoch = np.broadcast_to((epoch_at >= 0).astype(np.int8)[:, None, None], (c, n_env, 1))
        self._imu = (("dtheta_r", _read_only(imu.dtheta_r.reshape(n_env, c, -1))),
                     ("dv_r", _read_only(imu.dv_r.reshape(n_env, c, -1))),
                     ("dtheta_sub", _read_only(imu.dtheta_sample[:, :, :, 0, :].reshape(n_env, c, -1))),
                     ("dv_sub", _read_only(imu.dv_sample[:, :, :, 0, :].reshape(n_env, c, -1))))
        # the optional sensors' entries (N, c, size), from their declared chunk arrays
        per_step = []
        for sig in codec.measurement_signals:
            values = sig.read(chunk)
            if values is not None:
                per_step.append((sig.name, _frozen(values.reshape(n_env, c, -1))))
        self._per_step = tuple(per_step)
        self._no_gnss = {"gnss_valid": _frozen(np.zeros((n_env, k), dtype=np.int8)),
                         "pseudorange_m": _frozen(np.zeros((n_env, k))),
                         "pseudorange_rate_mps": _frozen(np.zeros((n_env, k))),
                         "sat_pos_e": _frozen(np.zeros((n_env, 3 * k))), "sat_vel_e": _frozen(np.zeros((n_env, 3 * k)))}
        g = chunk.gnss
        if g is not None and len(chunk.gnss_step):
            e = len(chunk.gnss_step)
            self._valid = _frozen(g.valid.astype(np.int8))  # (N, epochs, k)
            self._pr, self._prr = _frozen(g.pseudorange_m), _frozen(g.pseudorange_rate_mps)
            self._sat_pos = np.broadcast_to(g.sat_pos_e[0].reshape(e, 1, -1), (e, n_env, 3 * k))
            self._sat_vel = np.broadcast_to(g.sat_vel_e[0].reshape(e, 1, -1), (e, n_env, 3 * k))
        else:
            none = _frozen(np.zeros(0))  # never read: no step of the chunk has an epoch
            self._valid = self._pr = self._prr = self._sat_pos = self._sat_vel = none

    def __call__(self, i: int) -> dict[str, np.ndarray]:
        j = self._epoch_at[i]
        if j < 0:
            gnss = self._no_gnss
        else:
            gnss = {"gnss_valid": self._valid[:, j], "pseudorange_m": self._pr[:, j],
                    "pseudorange_rate_mps": self._prr[:, j], "sat_pos_e": self._sat_pos[j],
                    "sat_vel_e": self._sat_vel[j]}
        obs = {"t": self._t[i]}
        for key, rows in self._imu:
            obs[key] = rows[:, i]
        obs["gnss_new_epoch"] = self._new_epoch[i]
        obs.update(gnss)
        for key, rows in self._per_step:
            obs[key] = rows[:, i]
        return obs
