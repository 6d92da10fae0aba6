"""What runs inside navsim's FMUs: a translation of FMI calls into the core's calls.

This module imports neither pythonfmu nor fmpy: the FMI 2 and FMI 3 slave classes
(:mod:`navsim.fmu.fmi2`, :mod:`navsim.fmu.fmi3`) are thin shells that forward every FMI
call to a :class:`PlantRuntime` or :class:`EstimatorRuntime`. The runtimes own a
:class:`ValueStore` (the FMU's variables by value reference, laid out from the shared
table :mod:`navsim.fmu.variables`) and a core :class:`~navsim.simulator.Simulator` or
estimator. No physics lives here.

Plant time base
    The FMU's clock counts simulator ticks. ``do_step(t, h)`` requires ``t`` to be the
    FMU's current time and ``h`` a whole number (>= 1) of ticks (relative tolerance
    1e-9); otherwise it refuses the step with a logged message and an error status. The
    navigation steps whose end falls in ``(t, t + h]`` are served (``Simulator.step``,
    the same numbers as any chunking); the ``imu.dtheta_r*``/``imu.dv_r*`` outputs are
    the multiple-integral increments over those steps (composed exactly with
    :func:`navsim.sensors.imu.compose_multiple_integrals` when there are several, zero
    when the step ended inside a navigation step); ``imu.dtheta_sub``/``imu.dv_sub``,
    truth and ``time.t_s`` are those of the last step served; ``gnss.*`` holds the latest
    epoch of the interval (``gnss.new_epoch`` says whether there was one). With a
    communication step of one navigation step every output is exactly the core's value.
External motion
    With ``motion.use_inputs`` the scenario's profile becomes ``"external"`` and, at
    each ``do_step(t, h)``, the inputs ``motion.s_m``, ``motion.speed_mps``,
    ``motion.accel_mps2`` are the along-track state at ``t + h`` (default; a master
    that steps the motion source before the plant, Gauss-Seidel), or, with
    ``motion.inputs_at_step_start``, the state at ``t`` carried to ``t + h`` at constant
    acceleration. The input values at ``exitInitializationMode`` are the initial state
    (``motion.start_s_m``, ``motion.speed_mps`` and the initial acceleration). The sample is pushed into the core's
    :class:`~navsim.motion.ExternalMotion` (quintic Hermite between samples), exactly as
    :meth:`Simulator.push_motion` does when ``h`` is one navigation step.
Estimator: co-simulation semantics under any master
    The estimator FMU's inputs carry the plant's output names (285 connections by name
    for paper-2012, FMI 2), the plant's step counter ``time.step`` and ``time.t_s``
    included. It accepts a communication step ``h`` of a whole number of ticks, either
    within one navigation step ``dt`` or spanning ``k`` whole navigation steps, and keeps
    its own time. At ``doStep(t, h)`` let ``c`` be the ``time.step`` input, ``p`` the
    plant steps already processed (output ``nav.step``), ``n0``/``n1`` the navigation
    steps ended at ``t``/``t + h`` and ``k = n1 - n0`` the span of the step (fixed by the
    first communication step that ends a navigation step; 1 for ``h <= dt``). It
    processes the plant's data when ``c = p + k`` and holds its outputs when ``c = p``,
    provided ``n0 <= c <= n1``: a Gauss-Seidel master stepping the plant first gives
    ``c = n1`` (no lag); a Jacobi master, or a Gauss-Seidel one stepping the estimator
    first, gives ``c = n0`` (the estimate is one communication step, ``k`` navigation
    steps, behind the FMU's time). The first communication step that spans the end of a
    navigation step shows which of the two the master is; from then on ``c`` must be
    ``n1`` (plant-first) or ``n0`` (lagged). Every other case is refused with an error
    status and a log line, state unchanged: ``c < p`` (repeated data: a plant reset or
    replayed values), ``c`` beyond ``p + k`` or between ``p`` and ``p + k`` (skipped data:
    a lost transfer, or a plant stepped with another ``h``), a step whose span differs
    from the first one's (``h`` changed, or ``h`` of 1.5 navigation steps), ``c`` behind
    the master's order (stale data: a missed transfer, a master that changed its order,
    ``time.step`` not connected), ``c`` ahead of it, and a ``time.t_s`` input that is not
    ``c`` navigation steps. Outputs: ``nav.t_s`` is the time the solution refers to (the
    end of plant step ``c``; the prior, at 0, before the first step), ``nav.lag_steps =
    n1 - p`` the lag in navigation steps (0, or ``k`` under a lagged master). The
    estimator is reset with the ``prior.*`` inputs when the first plant data arrive (so
    the prior has been transferred whatever the master's order) and the prior
    covariance of the embedded scenario's ``[initial]`` section.
Estimator: a communication step of k navigation steps (``h = k dt``, k > 1)
    The plant then composes the k steps' multiple integrals exactly
    (:func:`navsim.sensors.imu.compose_multiple_integrals`, seed 000 eq. 1.14 over the
    interval ``k dt``), and the strapdown algorithms of seed 000 take an interval of any
    length from its multiple integrals. The estimator therefore runs with a navigation
    step of ``k dt``: it is reset with the context of the scenario whose
    ``nav_period_s`` (and, for the one sample it receives per interval,
    ``imu_period_s``) is ``k dt`` and ``samples_per_step = 1``, and each interval is one
    :class:`~navsim.types.Measurement` with ``dt = k dt``, the composed ``dtheta_r`` /
    ``dv_r``, and as its single sub-sample the interval's first-order increments
    (``dtheta_r[0]``, ``dv_r[0]``: the sums of the interval's samples; the plant
    transfers the samples of its last navigation step only). The numbers are those of
    ``run_episode`` on the scenario with ``[timing] nav_period_s = k dt`` for every
    estimator whose strapdown reads the multiple integrals, as the bundled ones do with
    their automatic method choice (same IMU samples and GNSS epochs; the composition of
    the simulator and of the plant is the same contraction, element by element): bit for
    bit in ``tests/fmu/test_masters.py``. Such a scenario's odometer would draw its
    errors per step of ``k dt``, the plant's ``odometer.ds_m`` is the exact sum over the
    k steps of ``dt``, so with an odometer only the IMU/GNSS part of that statement holds.
    GNSS epochs: ``k`` must divide the navigation steps of a GNSS period (and of the
    episode), so every epoch falls at the end of an interval and is processed there, at
    its own time; any other ``k`` is refused at the first step with an error status and a
    log line (an epoch inside an interval would otherwise be applied at the interval's
    end, and the plant keeps only the latest epoch of an interval), as is an epoch
    whose ``gnss.t_s`` is not the interval's end. An estimator that cannot take the
    longer step (a configuration that needs IMU sub-samples, or a covariance period
    that is not a whole number of such steps) refuses at its reset, at the first plant
    data: an error status and a log line naming the estimator and its reason.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, NoReturn, cast

import numpy as np

from navsim.errors import ConfigError, NavsimError
from navsim.estimators.base import row_stepping
from navsim.signals import MEASUREMENT_SIGNALS, STEP_SIGNALS, signal
from navsim.types import GnssObservation, Measurement

from .variables import Dimensions, Var, estimator_variables, plant_variables

if TYPE_CHECKING:
    from navsim.motion import ExternalMotion
    from navsim.scenario import Scenario
    from navsim.signals import Signal

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "FmuError",
    "SCENARIO_FILE",
    "META_FILE",
    "ValueStore",
    "PlantRuntime",
    "EstimatorRuntime",
    "plant_defaults",
    "effective_scenario",
]

SCENARIO_FILE = "navsim_scenario.toml"
META_FILE = "navsim_fmu.json"
REL_TOL = 1e-9


class FmuError(NavsimError):
    """A call into a navsim FMU cannot be honoured (the message goes to the FMI log)."""


def _version() -> str:
    import navsim

    return navsim.__version__


# =========================================================================== store
_copyto, _abs, _sqrt = np.copyto, np.abs, np.sqrt  # bound once: the estimator's per-step writes
_DTYPES = {"real": np.float64, "int": np.int64, "bool": np.bool_}
_CACHE_MAX = 64  # distinct value-reference lists kept resolved (a host asks the same few each step)


class ValueStore:
    """The FMU's variable values, array-backed: one preallocated NumPy array per FMI type.

    Every variable's elements occupy one slice of the array of its type (``real``:
    float64, ``int``: int64, ``bool``: bool; strings in a list), in table order. FMI 2
    (``fmi=2``): every element of an array :class:`Var` is one scalar variable, so a
    variable of size n has n consecutive value references. FMI 3 (``fmi=3``): value
    reference 0 is the independent variable ``time`` (element 0 of the real array); each
    :class:`Var` has one value reference and arrays are read and set whole.

    Host side: :meth:`get` / :meth:`set` resolve a list of value references once (type and
    causality checked, then a slice or an index array into the typed array, cached by the
    list) and read or assign it with one NumPy operation. Runtime side: :meth:`slot` gives
    a variable's ``(array, slice)``, so the runtime writes a whole signal, or several
    consecutive ones, with one slice assignment of a preallocated float array
    (:meth:`segments`); :meth:`read` / :meth:`write` by name are for the cold paths.
    """

    def __init__(self, table: list[Var], fmi: int) -> None:
        if fmi not in (2, 3):
            raise ConfigError("fmi", "2 or 3", fmi)
        self.fmi = fmi
        self.table = table
        self.by_name = {v.name: v for v in table}
        count = {"real": 1 if fmi == 3 else 0, "int": 0, "bool": 0, "string": 0}
        self._elements: dict[str, tuple[str, int, int]] = {}  # name -> (type, first element, size)
        for var in table:
            self._elements[var.name] = (var.type, count[var.type], var.size)
            count[var.type] += var.size
        self.arrays: dict[str, np.ndarray] = {t: np.zeros(count[t], dtype=d) for t, d in _DTYPES.items()}
        self.strings: list[str] = [""] * count["string"]
        self.real, self.int, self.bool = self.arrays["real"], self.arrays["int"], self.arrays["bool"]
        # value reference -> (type, first element, size, Var or None for FMI 3's time)
        refs: list[tuple[str, int, int, Var | None]] = [("real", 0, 1, None)] if fmi == 3 else []
        self.first_vr: dict[str, int] = {}
        for var in table:
            kind, first, n = self._elements[var.name]
            self.first_vr[var.name] = len(refs)
            if fmi == 2:
                refs.extend((kind, first + j, 1, var) for j in range(n))
            else:
                refs.append((kind, first, n, var))
            default = _zero(var.type) if var.start is None else var.start
            if kind == "string":
                self.strings[first:first + n] = [str(default)] * n
            else:
                self.arrays[kind][first:first + n] = default
        self._refs = refs
        self._n = len(refs)
        self._resolved: dict[tuple, Any] = {}

    def __len__(self) -> int:
        return self._n

    # -- host side (FMI get/set) ------------------------------------------------------
    def _resolve(self, vrs: Any, type_: str, allowed: tuple[str, ...] | None) -> Any:
        """Elements of the value references ``vrs`` of type ``type_`` (a slice when they
        are consecutive, else an index array; FmuError on a wrong reference, type or, for
        a set, causality not in ``allowed``), cached by ``(vrs, type_, allowed)``."""
        key = (tuple(vrs), type_, allowed)
        hit = self._resolved.get(key)
        if hit is not None:
            return hit
        elements: list[int] = []
        refs, n = self._refs, self._n
        for vr in key[0]:
            if not 0 <= vr < n or refs[vr][0] != type_:
                raise FmuError(f"value reference {vr}: expected a {type_} variable of this FMU")
            _, first, size, var = refs[vr]
            if allowed is not None and (var is None or var.causality not in allowed):
                name = "time" if var is None else var.name
                raise FmuError(f"{name} (value reference {vr}) cannot be set now (causality "
                               f"{'independent' if var is None else var.causality})")
            elements.extend(range(first, first + size))
        if elements and elements == list(range(elements[0], elements[0] + len(elements))):
            where: Any = slice(elements[0], elements[0] + len(elements))
        else:
            where = np.array(elements, dtype=np.intp)
        if len(self._resolved) >= _CACHE_MAX:
            self._resolved.clear()
        self._resolved[key] = (where, len(elements))
        return where, len(elements)

    def get(self, vrs: Any, type_: str) -> list:
        """The values of the value references ``vrs`` (flat, in order) as Python scalars."""
        where, n = self._resolve(vrs, type_, None)
        if type_ == "string":
            strings = self.strings
            return strings[where] if type(where) is slice else [strings[i] for i in where]
        return self.arrays[type_][where].tolist()

    def set(self, vrs: Any, new_values: Any, type_: str, allowed: tuple[str, ...]) -> None:
        """Set the value references ``vrs`` from ``new_values`` (flat, in order; FmuError on
        a wrong reference or type, a variable that cannot be set now, too few values)."""
        where, n = self._resolve(vrs, type_, allowed)
        values = new_values if type(new_values) is list else list(new_values)  # the shims pass lists
        if len(values) < n:
            raise FmuError(f"value references {list(vrs)}: expected {n} values, got {len(values)}")
        if type_ == "string":
            for i, value in zip(range(where.start, where.stop) if type(where) is slice else where.tolist(), values):
                self.strings[i] = value
            return
        self.arrays[type_][where] = values if len(values) == n else values[:n]

    def set_time(self, t: float) -> None:
        """FMI 3's independent variable (value reference 0)."""
        self.real[0] = t

    # -- runtime side ------------------------------------------------------------------
    def slot(self, name: str) -> tuple[np.ndarray, slice]:
        """``(array, slice)`` of a (non-string) variable's elements in its typed array."""
        kind, first, n = self._elements[name]
        return self.arrays[kind], slice(first, first + n)

    def segments(self, names: list[str]) -> list[tuple[np.ndarray, slice, slice]]:
        """The variables ``names`` (in this order: the columns of a row) as few
        ``(array, store slice, row slice)`` assignments: consecutive elements of one typed
        array are merged, so writing a row is one slice assignment per run of them."""
        out: list[tuple[np.ndarray, slice, slice]] = []
        col = 0
        for name in names:
            kind, first, n = self._elements[name]
            arr = self.arrays[kind]
            if out and out[-1][0] is arr and out[-1][1].stop == first:
                prev = out[-1]
                out[-1] = (arr, slice(prev[1].start, first + n), slice(prev[2].start, col + n))
            else:
                out.append((arr, slice(first, first + n), slice(col, col + n)))
            col += n
        return out

    def write(self, name: str, value: Any) -> None:
        """Set a variable (scalar, array or nested list) from the runtime."""
        kind, first, n = self._elements[name]
        if kind == "string":
            self.strings[first] = str(value)
        elif n == 1 and not self.by_name[name].shape:
            self.arrays[kind][first] = value
        else:
            self.arrays[kind][first:first + n] = np.ravel(value)

    def read(self, name: str) -> Any:
        """The current value of a variable: a Python scalar or a NumPy array (a copy) of its shape."""
        kind, first, n = self._elements[name]
        if kind == "string":
            return self.strings[first]
        shape = self.by_name[name].shape
        if not shape:
            return self.arrays[kind][first].item()
        return self.arrays[kind][first:first + n].reshape(shape).copy()




def _zero(type_: str) -> Any:
    return {"real": 0.0, "int": 0, "bool": False, "string": ""}[type_]


# =========================================================================== scenario
def load_embedded(resources: str | Path) -> tuple[Scenario, dict[str, Any]]:
    """The scenario and build metadata written into an FMU's resources folder."""
    from navsim.scenario import Scenario

    folder = Path(resources)
    try:
        data = tomllib.loads((folder / SCENARIO_FILE).read_text(encoding="utf-8"))
        meta = json.loads((folder / META_FILE).read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise FmuError(f"the FMU's resources lack {exc.filename}: rebuild it with `navsim fmu build`") from None
    return Scenario.from_dict(data, source=SCENARIO_FILE, base_dir=str(folder)), meta


def plant_defaults(scenario: Scenario) -> dict[str, Any]:
    """Start values of the plant FMU's parameters and inputs for ``scenario``."""
    m = scenario.motion
    return {
        "seed": 0,
        "imu.preset": scenario.imu.preset,
        "imu.gyro_noise_density": -1.0,
        "imu.accel_noise_density": -1.0,
        "gnss.preset": scenario.gnss.preset,
        "gnss.pseudorange_sigma_m": -1.0,
        "gnss.doppler_sigma_mps": -1.0,
        "outages.windows_s": json.dumps([list(w) for w in scenario.outages.windows_s]),
        "scenario.overrides": "",
        "motion.use_inputs": m.profile == "external",
        "motion.inputs_at_step_start": False,
        "motion.s_m": float(m.start_s_m),
        "motion.speed_mps": float(m.speed_mps),
        "motion.accel_mps2": 0.0,
    }


def _toml_value(field: str, text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(field, "a TOML value", f"{text} ({exc})") from None


def effective_scenario(base: Scenario, params: dict[str, Any]) -> Scenario:
    """The scenario after the plant FMU's parameter values (ConfigError on a bad one)."""
    over: dict = {}
    if params["imu.preset"] != base.imu.preset:
        over.setdefault("imu", {})["preset"] = params["imu.preset"]
    for key, sensor in (("imu.gyro_noise_density", "gyro"), ("imu.accel_noise_density", "accel")):
        value = float(params[key])
        if value != -1.0:
            if not (value >= 0.0 and math.isfinite(value)):
                raise ConfigError(key, "a noise density >= 0 (or -1 to keep the preset's)", value)
            over.setdefault("imu", {})[sensor] = {**getattr(base.imu, sensor), "white_noise_density": [value] * 3}
    if params["gnss.preset"] != base.gnss.preset:
        over.setdefault("gnss", {})["preset"] = params["gnss.preset"]
    gnss_over = dict(base.gnss.overrides)
    for key, name in (("gnss.pseudorange_sigma_m", "pseudorange_sigma_m"), ("gnss.doppler_sigma_mps", "doppler_sigma_mps")):
        value = float(params[key])
        if value != -1.0:
            if not (value >= 0.0 and math.isfinite(value)):
                raise ConfigError(key, "a sigma >= 0 (or -1 to keep the preset's)", value)
            gnss_over[name] = value
    if gnss_over != dict(base.gnss.overrides):
        over.setdefault("gnss", {})["overrides"] = gnss_over
    windows = _toml_value("outages.windows_s", params["outages.windows_s"] or "[]")
    if windows != [list(w) for w in base.outages.windows_s]:
        over["outages"] = {"windows_s": windows}
    if params["motion.use_inputs"]:  # the inputs at initialisation are the initial state
        over.setdefault("motion", {}).update(profile="external", start_s_m=float(params["motion.s_m"]),
                                             speed_mps=float(params["motion.speed_mps"]))
    elif base.motion.profile == "external":
        raise ConfigError("motion.use_inputs", "true for a scenario whose motion profile is 'external'", False)
    scenario = base.with_overrides(over) if over else base
    text = params["scenario.overrides"].strip()
    if text:
        try:
            extra = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError("scenario.overrides", "TOML key = value lines", f"{text} ({exc})") from None
        scenario = scenario.with_overrides(extra)
    return scenario


# =========================================================================== plant
Log = Callable[..., None]
"""The slave's log callback: ``log(message, level="info")`` with level "info", "warning" or "error"."""


class _RuntimeBase:
    kind = ""
    # set by the subclass's __init__ (store) and at exitInitializationMode (the rest)
    store: ValueStore
    timing: Any  # navsim.scenario.Timing
    tick: int
    end_tick: int
    nav_ticks: int
    start_time: float  # set by setupExperiment (FMI 2) / enterInitializationMode (FMI 3), if called

    def __init__(self, resources: str, fmi: int, log: Log | None = None) -> None:
        self.resources = resources
        self.fmi = fmi
        self.log = log or (lambda message, level="info": None)
        self.base_scenario, self.meta = load_embedded(resources)
        if self.meta.get("kind") != self.kind:
            raise FmuError(f"resources describe a {self.meta.get('kind')!r} FMU, this slave is a {self.kind!r} one")
        if self.meta.get("build_version") != _version():
            self.log(f"navsim {_version()} runs an FMU built with navsim {self.meta.get('build_version')}",
                     "warning")
        self.initialised = False
        self.terminated = False
        self._h_checked: tuple[float, float] = (math.nan, math.nan)  # (h, tick) of the last accepted step
        self._h_ticks = 0

    def _info(self, scenario: Scenario) -> None:
        self.store.write("navsim.version", _version())
        self.store.write("navsim.build_version", str(self.meta.get("build_version", "")))
        self.store.write("navsim.config_hash", scenario.config_hash())
        self.store.write("navsim.scenario", scenario.name)

    def check_initialisation(self) -> None:
        """The checks of ``exitInitializationMode`` common to both FMUs (FmuError: refused).

        The C guard (:mod:`navsim.fmu.guard`) refuses these cases before Python sees
        them, with an error status; an FMU built without it gets them here (a Fatal
        status, pythonfmu's answer to any exception)."""
        if self.initialised:
            raise FmuError("exitInitializationMode called again: the episode is running; call reset to start again")
        if getattr(self, "start_time", 0.0) != 0.0:
            raise FmuError(f"start time {self.start_time!r} s refused: a navsim episode starts at t = 0 (the FMU's "
                           "time counts ticks from the episode start)")

    def params(self) -> dict[str, Any]:
        return {v.name: self.store.read(v.name) for v in self.store.table if v.causality in ("parameter", "input")}

    # FMI set: parameters only before initialisation is over, inputs at any time
    def settable(self) -> tuple[str, ...]:
        return ("input",) if self.initialised else ("parameter", "input")

    def terminate(self) -> None:
        self.terminated = True


    def _step_ticks(self, t: float, h: float) -> int:
        """The number of simulator ticks of the communication step (t, h), or FmuError with
        the reason: called before initialisation or after terminate, a communication point
        that is not the FMU's time, a step that is not a whole number (>= 1) of ticks, or one
        that goes past the episode's end."""
        if not self.initialised:
            raise FmuError("doStep before initialisation: call enterInitializationMode/exitInitializationMode first")
        if self.terminated:
            raise FmuError("doStep after terminate: reset or instantiate the FMU again")
        tick_s = self.timing.tick_s
        now = self.tick * tick_s
        if not abs(t - now) <= REL_TOL * max(1.0, abs(now)) + 1e-12:
            raise FmuError(f"communication point t = {t!r} s does not match the FMU's time {now!r} s "
                           "(steps must follow each other without gaps)")
        if h == self._h_checked[0] and tick_s == self._h_checked[1]:  # as the last step: the same ticks
            n = self._h_ticks
        else:
            ratio = h / tick_s if math.isfinite(h) else math.nan
            n = round(ratio) if math.isfinite(ratio) else 0
            if n < 1 or abs(ratio - n) > REL_TOL * max(1.0, ratio):
                raise FmuError(f"communication step h = {h!r} s is not a whole number (>= 1) of simulator ticks "
                               f"(tick = {tick_s!r} s; e.g. the navigation step {self.timing.nav_period_s!r} s)")
            self._h_checked, self._h_ticks = (h, tick_s), n
        if self.tick + n > self.end_tick:
            raise FmuError(f"communication step to t = {t + h!r} s goes beyond the episode's end "
                           f"({self.timing.duration_s!r} s)")
        return n


class PlantRuntime(_RuntimeBase):
    """The plant FMU: the core :class:`~navsim.simulator.Simulator` behind FMI calls.

    Hot path (a communication step of one navigation step): when a new chunk of the
    simulator arrives, its per-step outputs are laid out once as rows, in the value
    layout of the store (``time.t_s``, the IMU block, every per-step signal of
    :data:`navsim.signals.STEP_SIGNALS`, the truth components; the step counters; the
    GNSS epochs' values), so a doStep writes a few preallocated rows with one slice
    assignment per run of consecutive variables (:meth:`ValueStore.segments`).
    """

    kind = "plant"

    def __init__(self, resources: str, fmi: int, log: Any = None) -> None:
        from navsim.simulator import Simulator

        super().__init__(resources, fmi, log)
        self.sim = Simulator(self.base_scenario)
        self.dims = Dimensions.of(self.sim)
        self.store = ValueStore(plant_variables(self.dims, plant_defaults(self.base_scenario)), fmi)
        orders = range(1, self.dims.orders + 1)
        self._imu_names = ([f"imu.dtheta_r{r}" for r in orders] + [f"imu.dv_r{r}" for r in orders]
                           + ["imu.dtheta_sub", "imu.dv_sub"])
        self._step_signals = [s for s in STEP_SIGNALS if s.present(self.dims)]
        truth = signal("truth")
        self._truth = [(f"{truth.fmu_name}.{c.name}", c.source) for c in truth.components]
        real = {v.name for v in self.store.table if v.type == "real"}
        steps = [s.fmu_name for s in self._step_signals]
        # the per-step rows: reals (time, IMU, per-step signals, truth), then the rest
        self._real_names = (["time.t_s", *self._imu_names] + [n for n in steps if n in real]
                            + [name for name, _ in self._truth])
        self._other_names = ["time.step", "time.steps_in_interval"] + [n for n in steps if n not in real]
        self._real_rows = self.store.segments(self._real_names)
        self._other_rows = self.store.segments(self._other_names)
        # the same elements as one index each (a row is then one fancy assignment)
        self._real_at = _elements(self._real_rows)
        self._other_at = _elements(self._other_rows)
        if any(arr is not self.store.int for arr, _, _ in self._other_rows):
            raise FmuError("a per-step signal of the table is neither float64 nor int64: the plant serves those two")
        sizes = {v.name: v.size for v in self.store.table}
        self._column = {name: int(col) for names in (self._real_names, self._other_names)  # a name's first column
                        for name, col in zip(names, np.cumsum([0] + [sizes[n] for n in names])[:-1])}
        self._gnss_real = self.store.segments(["gnss.t_s", "gnss.pseudorange_m", "gnss.pseudorange_rate_mps",
                                               "gnss.sat_pos_e", "gnss.sat_vel_e"])
        self._gnss_bool = self.store.segments(["gnss.receiver_outage", "gnss.valid"])
        self._gnss_int = self.store.segments(["gnss.n_valid"])
        self._new_epoch = self.store.slot("gnss.new_epoch")
        self._new_epoch_at = self._new_epoch[1].start  # its one element (an index: cheaper than the slice)
        self._chunk: Any = None  # the chunk whose rows are laid out
        self._info(self.base_scenario)

    # -- initialisation ---------------------------------------------------------------
    def exit_initialization_mode(self) -> None:
        from navsim.simulator import Simulator

        self.check_initialisation()
        params = self.params()
        try:
            seed = int(params["seed"])
            if seed < 0:
                raise ConfigError("seed", "an integer >= 0", seed)
            scenario = effective_scenario(self.base_scenario, params)
            sim = self.sim if scenario == self.base_scenario else Simulator(scenario)
        except NavsimError as exc:
            raise FmuError(f"bad parameter value: {exc}") from None
        dims = Dimensions.of(sim)
        if dims != self.dims:
            raise FmuError(f"bad parameter value: the parameters change the FMU's dimensions from {self.dims} "
                           f"to {dims}; build another FMU for that scenario")
        self.sim, self.scenario, self.seed = sim, scenario, seed
        self.timing = scenario.timing
        self.external = scenario.motion.profile == "external"
        self.inputs_at_start = bool(params["motion.inputs_at_step_start"])
        self.nav_ticks = self.timing.nav_ticks
        self.end_tick = self.timing.steps * self.nav_ticks
        self.tick = 0
        self._chunk = None
        start = sim.reset(seed)
        a0 = float(params["motion.accel_mps2"])
        if self.external and a0 != 0.0:  # Simulator.reset starts external motion at zero acceleration
            m = scenario.motion
            cast("ExternalMotion", sim.profile).reset(0.0, m.start_s_m, m.speed_mps, a0)
            start = type(start)(truth=sim.truth_at([0.0]), prior=start.prior)
        self._info(scenario)
        self.store.write("gnss.prn", np.asarray(sim.constellation.prn))
        prior = signal("prior")  # its components are the solution layout (signal table)
        row = start.prior.as_action()
        for arr, where, cols in self.store.segments([f"{prior.fmu_name}.{c.name}" for c in prior.components]):
            arr[where] = row[cols]
        for (arr, where, cols) in self.store.segments([name for name, _ in self._truth]):
            arr[where] = _truth_row(start.truth, self._truth, 0)[cols]
        self.initialised = True
        self.log(f"navsim {_version()} plant: scenario {scenario.name!r} (config {scenario.config_hash()}), "
                 f"seed {seed}, tick {self.timing.tick_s} s, navigation step {self.timing.nav_period_s} s")

    # -- stepping -----------------------------------------------------------------------
    def check_step(self, t: float, h: float) -> int:
        """The number of ticks of a communication step, or FmuError with the reason."""
        return self._step_ticks(t, h)

    def do_step(self, t: float, h: float) -> None:
        """Advance one communication step (FmuError: refused, state unchanged)."""
        n = self.check_step(t, h)
        new_tick = self.tick + n
        k = new_tick // self.nav_ticks - self.tick // self.nav_ticks
        if self.external:
            self._push_motion(new_tick, h)
        step = self.sim.step
        if k == 1:
            chunk, i = step()
            self.tick = new_tick
            if chunk is not self._chunk:
                self._lay_out(chunk)
            real, other = self._rows
            store = self.store
            store.real[self._real_at] = real[i]
            store.int[self._other_at] = other[i]
            epoch = self._epoch_of[i]
            if epoch is None:
                store.bool[self._new_epoch_at] = False
            else:
                self._write_epoch(epoch)
        elif k:
            self._write_steps([step() for _ in range(k)])
            self.tick = new_tick
        else:
            self.tick = new_tick
            self._write_idle()

    def _lay_out(self, chunk: Any) -> None:
        """The rows of a new chunk (class docstring): reals (n, ...) and the others (n, ...)
        in the column order of :attr:`_real_names` / :attr:`_other_names`, and its epochs."""
        n = len(chunk)
        imu = chunk.imu
        real = [chunk.t[:, None], imu.dtheta_r.reshape(n, -1), imu.dv_r.reshape(n, -1),
                imu.dtheta_sample[:, :, 0].reshape(n, -1), imu.dv_sample[:, :, 0].reshape(n, -1)]
        other = [(chunk.step0 + 1 + np.arange(n))[:, None], np.ones((n, 1), dtype=np.int64)]
        for sig in self._step_signals:
            (real if sig.dtype == "float64" else other).append(_read(sig, chunk).reshape(n, -1))
        real.append(_truth_rows(chunk.truth, self._truth))
        self._rows = (np.concatenate(real, axis=1), np.concatenate(other, axis=1))
        epoch_of: list = [None] * n
        g = chunk.gnss
        if g is not None and len(chunk.gnss_step):
            e = len(chunk.gnss_step)
            g_real = np.concatenate([g.t[:, None], g.pseudorange_m, g.pseudorange_rate_mps,
                                     g.sat_pos_e.reshape(e, -1), g.sat_vel_e.reshape(e, -1)], axis=1)
            g_bool = np.concatenate([np.asarray(chunk.receiver_outage, dtype=bool)[:, None], g.valid], axis=1)
            g_int = g.valid.sum(axis=1, dtype=np.int64)[:, None]
            for j, at in enumerate(chunk.gnss_step.tolist()):
                epoch_of[at] = (g_real[j], g_bool[j], g_int[j])
        self._epoch_of = epoch_of
        self._chunk = chunk

    def _write_epoch(self, epoch: Any) -> None:
        """``gnss.new_epoch`` and, at an epoch, the epoch's values (held until the next one)."""
        arr, sl = self._new_epoch
        arr[sl] = epoch is not None
        if epoch is not None:
            for (rows, row) in ((self._gnss_real, epoch[0]), (self._gnss_bool, epoch[1]), (self._gnss_int, epoch[2])):
                for arr, where, cols in rows:
                    arr[where] = row[cols]

    def _push_motion(self, new_tick: int, h: float) -> None:
        s = float(self.store.read("motion.s_m"))
        v = float(self.store.read("motion.speed_mps"))
        a = float(self.store.read("motion.accel_mps2"))
        if self.inputs_at_start:  # the state at t carried to t + h at constant acceleration
            s, v = s + v * h + 0.5 * a * h * h, v + a * h
        if new_tick % self.nav_ticks == 0:  # the time Simulator.push_motion uses for a step end
            t_push = (new_tick // self.nav_ticks) * self.timing.nav_period_s
        else:
            t_push = new_tick * self.timing.tick_s
        try:
            self.sim.push_motion(s, v, a, t=t_push)
        except ConfigError as exc:
            raise FmuError(f"motion inputs: {exc}") from None

    def _write_idle(self) -> None:
        """A communication step that ended inside a navigation step: no step served, the
        multiple-integral increments and every per-step signal zero, no new epoch."""
        self.store.write("time.steps_in_interval", 0)
        for name in self._imu_names[:2 * self.dims.orders]:
            self.store.write(name, np.zeros(3))
        for sig in self._step_signals:
            self.store.write(sig.fmu_name, 0)
        self._write_epoch(None)

    def _write_steps(self, served: list) -> None:
        """k > 1 navigation steps in one communication step: the IMU increments composed
        exactly, per-step signals summed ("sum") or the last one ("last"), the rest of the
        last step; the latest epoch of the interval."""
        from navsim.sensors.imu import compose_multiple_integrals

        chunk, i = served[-1]
        if chunk is not self._chunk:
            self._lay_out(chunk)
        real, other = self._rows[0][i].copy(), self._rows[1][i].copy()
        dt = self.timing.nav_period_s
        dtheta = compose_multiple_integrals(np.stack([c.imu.dtheta_r[j] for c, j in served])[None], dt)[0]
        dv = compose_multiple_integrals(np.stack([c.imu.dv_r[j] for c, j in served])[None], dt)[0]
        a = 3 * self.dims.orders
        col = self._column
        c0 = col[self._imu_names[0]]
        real[c0:c0 + 2 * a] = np.concatenate((dtheta.ravel(), dv.ravel()))
        other[col["time.steps_in_interval"]] = len(served)
        for sig in self._step_signals:
            if sig.compose != "sum":  # "last": the reading at the end of the interval
                continue
            values = [_read(sig, c)[j] for c, j in served]
            if sig.dtype == "float64":  # distances of consecutive steps add exactly
                real[col[sig.fmu_name]] = math.fsum(float(x) for x in values)
            else:
                other[col[sig.fmu_name]] = sum(int(x) for x in values)
        for arr, where, cols in self._real_rows:
            arr[where] = real[cols]
        for arr, where, cols in self._other_rows:
            arr[where] = other[cols]
        epoch = None
        for c, j in served:
            if c is not self._chunk:
                self._lay_out(c)
            if self._epoch_of[j] is not None:
                epoch = self._epoch_of[j]
        if self._chunk is not chunk:
            self._lay_out(chunk)
        self._write_epoch(epoch)


def _read(sig: Signal, chunk: Any) -> np.ndarray:
    """A present per-step signal's array of a chunk (FmuError if the chunk lacks it)."""
    values = sig.read(chunk)
    if values is None:
        raise FmuError(f"the simulator's chunk lacks the per-step signal {sig.fmu_name!r} of the FMU's table")
    return values


def _elements(segments: list[tuple[np.ndarray, slice, slice]]) -> Any:
    """The store elements of row segments of one typed array, in row order: the slice
    itself for one run, else an index array."""
    if len(segments) == 1:
        return segments[0][1]
    return np.concatenate([np.arange(where.start, where.stop) for _, where, _ in segments])


def _truth_rows(truth: Any, components: list[tuple[str, str]]) -> np.ndarray:
    """(n, 15) truth rows of a chunk's true state in the truth signal's component order."""
    n = len(truth.s)
    return np.concatenate([np.asarray(getattr(truth, src.split(".", 1)[1])).reshape(n, -1) for _, src in components],
                          axis=1)


def _truth_row(truth: Any, components: list[tuple[str, str]], i: int) -> np.ndarray:
    return _truth_rows(truth, components)[i]


# =========================================================================== estimator
class EstimatorRuntime(_RuntimeBase):
    """The estimator FMU: a registered estimator behind FMI calls (never sees truth)."""

    kind = "estimator"

    def __init__(self, resources: str, fmi: int, log: Log | None = None) -> None:
        from navsim.earth import earth_model
        from navsim.simulator import build_gnss

        super().__init__(resources, fmi, log)
        # no simulator: the context comes from make_context(scenario) at initialisation, the
        # channel order from the scenario's constellation
        self.prn = np.asarray(build_gnss(self.base_scenario, earth_model(self.base_scenario.earth))[0].prn)
        self.dims = Dimensions.of_scenario(self.base_scenario, len(self.prn))
        defaults = {"estimator.name": self.meta.get("estimator", ""),
                    "estimator.options": self.meta.get("estimator_options", "")}
        store = self.store = ValueStore(estimator_variables(self.dims, defaults), fmi)
        orders = range(1, self.dims.orders + 1)
        self._imu = _one_span(store, [f"imu.dtheta_r{r}" for r in orders] + [f"imu.dv_r{r}" for r in orders]
                              + ["imu.dtheta_sub", "imu.dv_sub"])
        self._gnss = _one_span(store, ["gnss.t_s", "gnss.pseudorange_m", "gnss.pseudorange_rate_mps", "gnss.sat_pos_e",
                                       "gnss.sat_vel_e"])
        self._valid = store.slot("gnss.valid")[1]
        self._at = {name: store.slot(name)[1].start for name in ("time.step", "time.t_s", "gnss.new_epoch")}
        self._epoch_at = self._at["gnss.new_epoch"]
        self._at_step, self._at_t = self._at["time.step"], self._at["time.t_s"]
        self._reals, self._ints, self._bools = store.real, store.int, store.bool
        self._fast: tuple[float, int, float, float] | None = None  # see do_step
        self._writer: Any = None  # _write_solution compiled (set at the first plant data)
        self._step_row: Any = None  # the estimator's row_stepping (set at the first plant data)
        self._meas_signals = [(s.measurement, store.slot(s.fmu_name)[1].start, s.dtype == "float64")
                              for s in MEASUREMENT_SIGNALS if s.present(self.dims)]
        solution, prior = signal("solution"), signal("prior")
        self._prior_names = [(c.name, f"{prior.fmu_name}.{c.name}") for c in prior.components]
        # the solution block: reals [t_s, solution (9), sigmas (9), covariance (81), nis], ints [step, lag, nis_dof]
        self._sol_real = _one_span(store, ["nav.t_s", *(f"{solution.fmu_name}.{c.name}" for c in solution.components),
                                           "nav.sigma_position_n", "nav.sigma_velocity_n", "nav.sigma_attitude_n",
                                           "nav.covariance", "nav.nis"]).start
        self._sol_int = _one_span(store, ["nav.step", "nav.lag_steps", "nav.nis_dof"]).start
        o, real = self._sol_real, store.real  # views of the solution block's parts (the store is never reallocated)
        self._out_row, self._out_sigma = real[o + 1:o + 10], real[o + 10:o + 19]
        self._out_cov, self._out_diag = real[o + 19:o + 100].reshape(9, 9), real[o + 19:o + 100:10]
        self._out_int = store.int[self._sol_int:self._sol_int + 3]
        self._info(self.base_scenario)

    def exit_initialization_mode(self) -> None:
        from navsim import estimators
        from navsim.episode import make_context

        self.check_initialisation()
        params = self.params()
        try:
            options = tomllib.loads(params["estimator.options"]) if params["estimator.options"].strip() else {}
        except tomllib.TOMLDecodeError as exc:
            raise FmuError(f"bad parameter value: estimator.options: expected TOML key = value pairs, got "
                           f"{params['estimator.options']!r} ({exc})") from None
        try:
            name = params["estimator.name"]
            if name.startswith("user_estimator/"):  # a user's file embedded by navsim fmu build
                name = str(Path(self.resources) / name)
            self.estimator = estimators.make(name, **options)
        except NavsimError as exc:
            raise FmuError(f"bad parameter value: {exc}") from None
        self.context = make_context(self.base_scenario)
        self.prior_covariance = self.base_scenario.initial.covariance()
        self.timing = self.base_scenario.timing
        self.nav_ticks = self.timing.nav_ticks
        self.end_tick = self.timing.steps * self.nav_ticks
        self.tick = 0  # the estimator FMU's time in simulator ticks
        self.processed = 0  # plant steps processed (nav.step)
        self.lagged: bool | None = None  # None until the master's order is seen; then True (Jacobi) or False
        self.span: int | None = None  # navigation steps per communication step, fixed by the first that ends one
        self.started = False
        self._fast = None
        self.initialised = True
        self.log(f"navsim {_version()} estimator {params['estimator.name']!r} on scenario "
                 f"{self.base_scenario.name!r} (config {self.base_scenario.config_hash()})")

    # -- stepping -----------------------------------------------------------------------
    def check_step(self, t: float, h: float) -> tuple[int, int | None]:
        """``(ticks, c)`` of a communication step: its length in ticks and the plant's step
        counter to process now (``None``: no new plant data); FmuError with the reason
        when the step or the plant's counter breaks the rules of the module docstring."""
        n = self._step_ticks(t, h)
        dt = self.timing.nav_period_s
        store, at = self.store, self._at
        c = int(store.int[at["time.step"]])
        done = self.processed
        n0, n1 = self.tick // self.nav_ticks, (self.tick + n) // self.nav_ticks
        span = self.span if self.span is not None else (n1 - n0 if n1 > n0 else None)
        if n1 > n0 and span is not None and n1 - n0 != span:
            raise FmuError(f"communication step h = {h!r} s spans {n1 - n0} navigation step(s) where the earlier "
                           f"steps spanned {span}: the estimator takes every interval as one navigation update "
                           f"of a fixed length; keep h constant, a whole number of navigation steps ({dt!r} s) "
                           "or a fraction of one")
        if span is not None and span > 1 and self.span is None:
            self._check_span(span, h)
        k = span or 1
        if c < done:
            raise FmuError(f"repeated data: the plant's time.step input went back from {done} to {c} (a plant "
                           "reset or restarted without the estimator, or old values replayed); the estimator "
                           "takes each plant step once and in order")
        if c > done + k or done < c < done + k:
            raise FmuError(f"skipped data: the plant's time.step input jumped from {done} to {c}, where this "
                           f"estimator's communication step (h = {h!r} s) takes {k} navigation step(s) at a time: "
                           "a lost transfer, or a plant stepped with another communication step than the "
                           "estimator; step both FMUs with the same h")
        lagged = self.lagged
        if lagged is None and n1 > n0:  # the first step across a step end shows the master's order
            lagged = c == n0 and c < n1
        want = n1 if not lagged else n0
        if c != want:
            order = ("a plant-first (Gauss-Seidel) master" if lagged is False else
                     "a Jacobi or estimator-first master" if lagged else "any master")
            if c < want:
                raise FmuError(f"stale data: the plant's time.step input is {c} at t = {t!r} s, where {order} "
                               f"gives {want}: a transfer of the plant's outputs was missed, the master changed "
                               "its order, or time.step is not connected (is time.step connected?)")
            raise FmuError(f"the plant's time.step input {c} is ahead of the estimator (t = {t!r} s, h = {h!r} "
                           f"s; {order} gives {want}): plant and estimator must start and step together")
        t_in = float(store.real[at["time.t_s"]])
        if c and not abs(t_in - c * dt) <= REL_TOL * max(1.0, c * dt) + 1e-12:
            raise FmuError(f"the plant's time.t_s input {t_in!r} s is not the end of its step {c} with this "
                           f"estimator's navigation step {dt!r} s: plant and estimator of different scenarios?")
        if c == done + k and k > 1 and store.bool[at["gnss.new_epoch"]]:
            t_epoch = float(store.real[self._gnss.start])
            if not abs(t_epoch - c * dt) <= REL_TOL * max(1.0, c * dt) + 1e-12:
                raise FmuError(f"the GNSS epoch at {t_epoch!r} s fell inside the composed interval "
                               f"({(c - k) * dt!r}, {c * dt!r}] s: the estimator would apply it at the interval's "
                               "end; choose a communication step that divides the GNSS period")
        self._lagged_next, self._span_next = lagged, span
        return n, (c if c == done + k and c > done else None)

    def _check_span(self, k: int, h: float) -> None:
        """The first interval of k > 1 navigation steps: refused (FmuError) when GNSS epochs
        would fall inside intervals or the episode is not a whole number of them."""
        timing = self.timing
        if timing.steps_per_epoch % k:
            raise FmuError(f"communication step h = {h!r} s spans {k} navigation steps, which do not divide the "
                           f"GNSS period {timing.gnss_period_s!r} s ({timing.steps_per_epoch} steps): epochs would "
                           "fall inside the composed intervals, where the plant keeps only the latest and the "
                           "estimator would apply it at the wrong time; choose h dividing the GNSS period")
        if timing.steps % k:
            raise FmuError(f"communication step h = {h!r} s spans {k} navigation steps, which do not divide the "
                           f"episode ({timing.steps} steps): the last interval would be shorter; choose h "
                           "dividing the episode length")

    def _reset_estimator(self, k: int) -> None:
        """Reset the estimator with the prior at the first plant data: navigation step k dt."""
        context = self.context
        if k > 1:  # one navigation update per composed interval of k steps (module docstring)
            dt = k * self.timing.nav_period_s
            context = dataclasses.replace(context, nav_period_s=dt, imu_period_s=dt, samples_per_step=1)
        try:
            self.estimator.reset(context, self._prior())
        except NavsimError as exc:
            raise FmuError(f"estimator {self.meta.get('estimator', '')!r} cannot run with a navigation step of "
                           f"{k} x {self.timing.nav_period_s!r} s (the master's communication step): {exc}") from None

    def do_step(self, t: float, h: float) -> None:
        """Advance one communication step (FmuError: refused, state unchanged).

        Steady state (the master's order known, one navigation step per communication
        step, ``h`` as at the last accepted step): the checks of :meth:`check_step` for
        the one case that passes them (``c = p + 1`` and ``n0 + 1 = n1``, ``c`` as the
        master's order gives, ``t`` the FMU's time, ``time.t_s`` the end of step ``c``)
        are made on Python scalars read once; any other case takes :meth:`check_step`,
        which accepts it or refuses it with its reason."""
        fast = self._fast
        if fast is not None and h == fast[0] and not self.terminated:
            tick, n, nav_ticks = self.tick, fast[1], self.nav_ticks
            n0, n1 = tick // nav_ticks, (tick + n) // nav_ticks
            c = self._ints.item(self._at_step)
            now = tick * fast[2]
            t_c = c * fast[3]
            if (n1 == n0 + 1 and c == self.processed + 1 and c == (n0 if self.lagged else n1)
                    and tick + n <= self.end_tick and abs(t - now) <= REL_TOL * max(1.0, abs(now)) + 1e-12
                    and abs(self._reals.item(self._at_t) - t_c) <= REL_TOL * max(1.0, t_c) + 1e-12):
                self._process(c, 1, t_c, tick + n)
                self.tick = tick + n
                return
        n, c = self.check_step(t, h)
        if c is not None:
            k = self._span_next or 1
            if not self.started:  # the prior came with (or before) the plant's first step
                self._reset_estimator(k)
                self._step_row = row_stepping(self.estimator)
                self._writer = _solution_writer() if self._step_row is not None else None
                self._view = _StoreView(self, k)
                self.started = True
            self._process(c, k, c * self.timing.nav_period_s, self.tick + n)
        elif not self.started:
            self._write_estimate(self._prior(), 0.0, self.tick + n)
        else:
            self.store.write("nav.lag_steps", (self.tick + n) // self.nav_ticks - self.processed)
        self.lagged, self.span = self._lagged_next, self._span_next
        self.tick += n
        # the steady state of the fast path above: (h, its ticks, tick, navigation step)
        self._fast = ((h, n, self.timing.tick_s, self.timing.nav_period_s)
                      if self.started and self.lagged is not None and self.span == 1 else None)

    def _process(self, c: int, k: int, t_s: float, tick: int) -> None:
        """Step the estimator with plant steps ``c - k .. c - 1`` and write its solution (at
        time ``t_s``, FMU time ``tick``); FmuError (state unchanged) if the estimator refuses."""
        step_row = self._step_row
        try:
            if step_row is None:
                est = self.estimator.step(self._measurement(c, k))
            elif self._bools.item(self._epoch_at):  # an epoch: a Measurement (the estimator may keep it)
                row, cov, nis, dof = step_row(self._measurement(c, k))
            else:
                row, cov, nis, dof = step_row(self._view.fill(c, k))
        except NavsimError as exc:  # e.g. a strapdown method that needs IMU sub-samples
            raise FmuError(f"estimator {self.meta.get('estimator', '')!r} refused the data of plant step {c} "
                           f"(navigation step {k} x {self.timing.nav_period_s!r} s): {exc}") from None
        self.processed = c
        if step_row is None:
            self._write_estimate(est, t_s, tick)
        else:
            self._write_row(row, cov, nis, dof, t_s, tick)

    def _prior(self) -> Any:
        from navsim.types import Prior

        read = self.store.read
        v = {name: read(fmu) for name, fmu in self._prior_names}  # the solution layout (signal table)
        return Prior(t=0.0, lat=float(v["lat_rad"]), lon=float(v["lon_rad"]), h=float(v["h_m"]),
                     velocity_n=v["velocity_n"], heading=float(v["heading_rad"]), pitch=float(v["pitch_rad"]),
                     roll=float(v["roll_rad"]), covariance=self.prior_covariance.copy())

    def _measurement(self, c: int, k: int) -> Measurement:
        """The Measurement of plant steps ``c - k .. c - 1`` (one navigation step when k = 1):
        views of one copy of the store's IMU block (and, at an epoch, of its GNSS block), so
        an estimator may keep them."""
        store = self.store
        real = store.real
        orders, m = self.dims.orders, self.dims.samples_per_step
        gnss = None
        if store.bool[self._at["gnss.new_epoch"]]:
            g = real[self._gnss].copy()  # [t_s, pseudorange (K), rate (K), sat_pos (K, 3), sat_vel (K, 3)]
            n = self.dims.channels
            gnss = GnssObservation(t=float(g[0]), prn=self.prn, sat_pos_e=g[1 + 2 * n:1 + 5 * n].reshape(n, 3),
                                   sat_vel_e=g[1 + 5 * n:].reshape(n, 3), pseudorange_m=g[1:1 + n],
                                   pseudorange_rate_mps=g[1 + n:1 + 2 * n], valid=store.bool[self._valid].copy())
        dt = self.timing.nav_period_s
        rows = real[self._imu].reshape(-1, 3)  # [dtheta_r (R), dv_r (R), dtheta_sub (m), dv_sub (m)] rows
        rows = rows.copy()
        if k == 1:
            dtheta_sub, dv_sub = rows[2 * orders:2 * orders + m], rows[2 * orders + m:]
        else:  # the interval as one sample: its first-order increments (the sums of its samples)
            dtheta_sub, dv_sub = rows[:1], rows[orders:orders + 1]
        if self._meas_signals:
            extras = {field: float(real[i]) if is_real else int(store.int[i]) for field, i, is_real in self._meas_signals}
            return Measurement(step=c // k - 1, t=c * dt, dt=k * dt, dtheta_r=rows[:orders],
                               dv_r=rows[orders:2 * orders], dtheta_sub=dtheta_sub, dv_sub=dv_sub, gnss=gnss, **extras)
        return Measurement(c // k - 1, c * dt, k * dt, rows[:orders], rows[orders:2 * orders], dtheta_sub, dv_sub, gnss)

    def _write_row(self, row: np.ndarray, cov: np.ndarray | None, nis: float | None, dof: int | None, t_s: float,
                   tick: int) -> None:
        """:meth:`_write_estimate` from a :data:`~navsim.estimators.base.StepRow`: ``row``
        (9,) is the solution block's [lat, lon, h, velocity_n (3), heading, pitch, roll]."""
        processed = self.processed
        writer = self._writer
        if writer is not None and cov is not None:
            try:
                writer(self._reals, self._sol_real, t_s, row, cov, math.nan if nis is None else nis, self._out_int,
                       processed, tick // self.nav_ticks - processed, 0 if nis is None else int(dof or 0))
                return
            except TypeError:  # not the compiled layout (float64, C order): the NumPy path from now on
                self._writer = None
        real, o = self._reals, self._sol_real
        real[o] = t_s
        _copyto(self._out_row, row)
        if cov is None:
            real[o + 10:o + 100] = math.nan
        else:  # standard deviations from the diagonal of the row-major 9 x 9
            _copyto(self._out_cov, cov)
            sigma = self._out_sigma
            _abs(self._out_diag, sigma)
            _sqrt(sigma, sigma)
        ints = self._out_int
        ints[0] = processed
        ints[1] = tick // self.nav_ticks - processed
        if nis is None:
            real[o + 100] = math.nan
            ints[2] = 0
        else:
            real[o + 100] = nis
            ints[2] = int(dof or 0)

    def _write_estimate(self, est: Any, t_s: float, tick: int) -> None:
        """Write the solution, its time, step and lag at FMU time ``tick`` straight into the
        store's consecutive solution block: reals [t_s, solution (9), sigmas (9), covariance
        (81), nis], ints [step, lag, nis_dof] (one slice assignment per part)."""
        real, o = self.store.real, self._sol_real
        v = est.velocity_n
        real[o:o + 10] = (t_s, est.lat, est.lon, est.h, v[0], v[1], v[2], est.heading, est.pitch, est.roll)
        cov = est.covariance
        if cov is None:
            real[o + 10:o + 100] = math.nan
        else:  # standard deviations from the diagonal, every 10th element of the row-major 9 x 9
            flat = real[o + 19:o + 100]
            flat[:] = np.ravel(cov)
            np.sqrt(np.abs(flat[::10]), out=real[o + 10:o + 19])
        nis = getattr(est, "nis", None)
        real[o + 100] = math.nan if nis is None else nis
        self.store.int[self._sol_int:self._sol_int + 3] = (
            self.processed, tick // self.nav_ticks - self.processed,
            (int(est.nis_dof or 0) if nis is not None else 0))


def _write_solution(real: np.ndarray, o: int, t_s: float, row: np.ndarray, cov: np.ndarray, nis: float,
                    ints: np.ndarray, processed: int, lag: int, dof: int) -> None:
    """:meth:`EstimatorRuntime._write_row`'s NumPy path in one call, element by element:
    the solution block ``real[o:o + 101]`` = [t_s, row (9), sqrt(|diag cov|) (9), cov (81,
    row-major), nis], ``ints[:3]`` = [step, lag, nis_dof]. Copies, ``abs`` and the correctly
    rounded ``sqrt`` are the operations of that path: the same bits. Compiled by numba
    (:func:`_solution_writer`)."""
    real[o] = t_s
    for i in range(9):
        real[o + 1 + i] = row[i]
        real[o + 10 + i] = math.sqrt(abs(cov[i, i]))
        for j in range(9):
            real[o + 19 + 9 * i + j] = cov[i, j]
    real[o + 100] = nis
    ints[0] = processed
    ints[1] = lag
    ints[2] = dof


_WRITER: list = []


def _solution_writer() -> Any:
    """:func:`_write_solution` compiled by numba for float64 C-ordered rows and covariances
    (what the bundled estimators' ``step_row`` returns; another layout raises TypeError and
    the caller takes the NumPy path), or None without numba (extra ``fast``)."""
    if not _WRITER:
        from navsim.jit import available

        if available():
            import numba

            sig = "void(float64[::1], int64, float64, float64[::1], float64[:, ::1], float64, int64[::1], int64, int64, int64)"
            _WRITER.append(numba.njit(sig, cache=True, nogil=True)(_write_solution))
        else:
            _WRITER.append(None)
    return _WRITER[0]


class _StoreView:
    """The fields of :class:`~navsim.types.Measurement` for a navigation step without a
    GNSS epoch, refilled for every such step from the estimator FMU's value store (what
    :meth:`EstimatorRuntime._measurement` builds, without building a value): the IMU block
    is copied once per step (the host overwrites the store in place) and the increments
    are views of that copy; ``gnss`` is None; the optional sensors' fields are read from
    their inputs (None for a sensor the scenario lacks). Handed to the estimator's
    ``step_row`` (:class:`~navsim.estimators.base.RowStepping`), which keeps no reference
    to it."""

    def __init__(self, rt: EstimatorRuntime, k: int) -> None:
        orders, m = rt.dims.orders, rt.dims.samples_per_step
        self._real, self._int, self._imu = rt.store.real, rt.store.int, rt._imu
        self._k = k
        self._nav = rt.timing.nav_period_s
        self.dt = k * self._nav
        self.gnss = None
        for sig in MEASUREMENT_SIGNALS:
            setattr(self, sig.measurement, None)
        self._optional = tuple(rt._meas_signals)
        # [dtheta_r (R), dv_r (R), dtheta_sub (m), dv_sub (m)] rows; a composed interval (k > 1)
        # is one sample: its first-order increments
        self._cuts = (slice(0, orders), slice(orders, 2 * orders),
                      slice(2 * orders, 2 * orders + m) if k == 1 else slice(0, 1),
                      slice(2 * orders + m, 2 * orders + 2 * m) if k == 1 else slice(orders, orders + 1))
        self._rows = self._real[self._imu].reshape(-1, 3)  # a view: the store is never reallocated

    def fill(self, c: int, k: int) -> _StoreView:
        """The fields of plant steps ``c - k .. c - 1`` (see the class docstring)."""
        rows = self._rows.copy()
        a, b, d, e = self._cuts
        self.step = c // k - 1
        self.t = c * self._nav
        self.dtheta_r, self.dv_r, self.dtheta_sub, self.dv_sub = rows[a], rows[b], rows[d], rows[e]
        if self._optional:
            real, ints = self._real, self._int
            for field, i, is_real in self._optional:
                setattr(self, field, real.item(i) if is_real else ints.item(i))
        return self


def _one_span(store: ValueStore, names: list[str]) -> slice:
    """The slice of consecutive variables ``names`` in one typed array of ``store``."""
    segments = store.segments(names)
    if len(segments) != 1:
        raise FmuError(f"variables {names} are not consecutive in the FMU's value table")
    return segments[0][1]


# Exit of a non-Python host. pythonfmu's shim starts Python itself when the host has none
# and calls Py_Finalize when the shim library is unloaded or the process exits. In that
# final pass the garbage collector clears scipy's _uarray module (imported through scipy)
# after the module has freed its own exception type, so a dictionary still holding that
# type is freed afterwards: a use after free that corrupts the heap (SIGSEGV, exit code
# 139, in a C host and in the ECOS tool; valgrind shows the free in _uarray's
# globals_free). Freezing the collector in an atexit handler (which runs at the start of
# Py_Finalize) leaves those objects to the process's exit instead. Only an interpreter
# embedded by a non-Python host (empty ``sys.orig_argv``) registers it.
_EXIT_GUARD: list = []


def guard_embedded_exit() -> bool:
    """Register the exit protection above once in an embedded interpreter; True if registered."""
    if _EXIT_GUARD or getattr(sys, "orig_argv", None) != []:
        return False
    import atexit
    import gc

    atexit.register(gc.freeze)
    _EXIT_GUARD.append(True)
    return True


# Failure protocol. pythonfmu's C++ shim (0.7 and pythonfmu3 0.3.4) turns a Python
# exception into a Fatal status and, in doing so, releases its references to the slave
# class, the slave instance and its log queue (cleanPyObject) without forgetting them, and
# its destructor (freeInstance) releases them a second time. One extra reference per
# object is kept here when an instance fails (a small, bounded leak per failed instance),
# which balances the first release; the second is avoided by never handing a failed
# instance to the shim's freeInstance (navsim's C guard, navsim.fmu.guard, and
# FmuInstance.free keep it instead). A failed instance never raises again: later calls
# log, return zeros or refuse the step.
_FAILED: list = []


_GUARD_LIBS: dict = {}


def refuse_through_guard(rt: _RuntimeBase, message: str) -> bool:
    """Ask the FMU's C guard (:mod:`navsim.fmu.guard`) to answer the current
    ``exitInitializationMode`` with an error status and ``message`` as its log line;
    False when the FMU has no guard (then the caller raises: pythonfmu's Fatal status)."""
    if not rt.meta.get("guard"):
        return False
    import ctypes

    folder = Path(rt.resources).parent / "binaries"
    libs = [p for p in sorted(folder.glob("*/*")) if p.suffix in (".so", ".dylib", ".dll")
            and not p.stem.endswith("_pythonfmu")]
    for path in libs:
        key = str(path)
        try:
            if key not in _GUARD_LIBS:
                _GUARD_LIBS[key] = ctypes.CDLL(key)  # the library the host loaded: the same handle
        except OSError:  # another platform's binary
            continue
        hook = getattr(_GUARD_LIBS[key], "navsim_guard_refuse", None)
        if hook is not None:
            hook.argtypes, hook.restype = [ctypes.c_char_p], None
            hook(message.encode("utf-8", "replace"))
            return True
    return False


def mark_failed(slave: Any) -> None:
    """Mark a slave (FMI 2 or 3) failed under the protocol above (idempotent)."""
    if not slave._failed:
        slave._failed = True
        _FAILED.append((slave, type(slave), slave.log_queue))
        rt = getattr(slave, "rt", None)
        if rt is not None:  # drop the simulator / estimator of a dead instance
            rt.sim = rt.estimator = None


class SlaveValues:
    """Value access shared by the FMI 2 and FMI 3 slave classes (a mixin).

    A failed instance (see the failure protocol in ``fmi2.py``) answers reads with zeros
    and ignores writes; otherwise :class:`FmuError` from the store marks it failed.
    Subclasses provide ``rt`` (a runtime), ``_failed`` and ``_fail(message)``.
    """

    rt: PlantRuntime | EstimatorRuntime
    _failed: bool

    def _fail(self, message: str) -> NoReturn:  # pragma: no cover - the slave classes define it
        raise FmuError(message)

    def _zeros(self, vrs: list[int], type_: str) -> list[Any]:
        zero = {"real": 0.0, "int": 0, "bool": False, "string": ""}[type_]
        try:
            return [zero] * len(self.rt.store.get(vrs, type_))
        except Exception:
            return [zero] * len(vrs)

    def _get(self, vrs: list[int], type_: str) -> list[Any]:
        if self._failed:
            return self._zeros(vrs, type_)
        try:
            return self.rt.store.get(vrs, type_)
        except FmuError as exc:
            self._fail(str(exc))

    def _set(self, vrs: list[int], values: list[Any], type_: str) -> None:
        if self._failed:
            return
        try:
            self.rt.store.set(vrs, values, type_, self.rt.settable())
        except FmuError as exc:
            self._fail(str(exc))

    def terminate(self) -> None:
        if not self._failed:
            self.rt.terminate()

    # the accessors whose names FMI 2 and FMI 3 share (the others are in fmi2.py / fmi3.py)
    def get_boolean(self, vrs: list[int]) -> list[Any]:
        return self._get(vrs, "bool")

    def get_string(self, vrs: list[int]) -> list[Any]:
        return self._get(vrs, "string")

    def set_boolean(self, vrs: list[int], values: list[Any]) -> None:
        self._set(vrs, [bool(v) for v in values], "bool")

    def set_string(self, vrs: list[int], values: list[Any]) -> None:
        self._set(vrs, values, "string")
