"""Running FMUs from Python over fmpy: an instance wrapper and navsim's co-simulation master.

:class:`FmuInstance` wraps one fmpy co-simulation instance (FMI 2 or FMI 3) with
name-based, type-grouped access to its variables and a log that keeps every message.
:func:`cosimulate` connects a navsim plant FMU and estimator FMU by variable name and
runs one episode under a fixed-step master of the chosen order (Gauss-Seidel plant
first, the default; Gauss-Seidel estimator first; Jacobi), returning a
:class:`navsim.episode.EpisodeRecord` built only from FMU outputs, each estimate beside
the truth of the step it refers to (``nav.t_s``), which
:func:`navsim.metrics.score_episode` scores as ``navsim run`` does.

Examples
--------
Not run by the doctests (it compiles the FMUs' C guard and writes them to the current folder;
``tests/fmu`` runs the same calls):

>>> from navsim.fmu import build_fmu, cosimulate          # doctest: +SKIP
>>> build_fmu("paper-2012", "plant", 2, "plant.fmu")      # doctest: +SKIP
>>> build_fmu("paper-2012", "estimator", 2, "est.fmu", estimator="lc-ekf")  # doctest: +SKIP
>>> record = cosimulate("plant.fmu", "est.fmu", seed=0)   # doctest: +SKIP
"""

from __future__ import annotations

import re
import shutil
import time
from pathlib import Path
from types import ModuleType, TracebackType
from typing import TYPE_CHECKING, Any, Callable, Iterable, NoReturn

import numpy as np

from navsim.errors import DependencyNotInstalled, NavsimError
from navsim.types import IntArray

if TYPE_CHECKING:
    from navsim.episode import EpisodeRecord
    from navsim.scenario import Scenario

__all__ = ["Connection", "FmuInstance", "FmuCallError", "cosimulate", "plant_scenario", "MASTERS"]


class FmuCallError(NavsimError):
    """An FMI call returned an error status (the FMU's log messages are in the text)."""


def _fmpy() -> ModuleType:
    try:
        import fmpy  # noqa: F401
    except ImportError:
        raise DependencyNotInstalled("fmpy", "fmu") from None
    return fmpy


_FMI2_TYPES = {"Real": "real", "Integer": "int", "Boolean": "bool", "String": "string", "Enumeration": "int"}
_FMI3_TYPES = {"Float64": "real", "Int32": "int", "Boolean": "bool", "String": "string"}


class _Fmi2Logs:
    """The FMI 2 logger of every :class:`FmuInstance` in the process: one C callback, never freed.

    An FMI 2 logger is variadic (printf-style), which ctypes cannot receive, so fmpy's
    native ``addLoggerProxy`` puts a C function in the callbacks that formats the message
    and calls the Python logger stored in ONE static variable of fmpy's logging library,
    overwritten by every later ``addLoggerProxy`` call (each instance, each
    ``fmpy.simulate_fmu``). With one Python callback per instance, every instance's
    messages went to the newest instance's log, and once that instance (or a finished
    ``simulate_fmu``) was garbage-collected, the next message of any live instance called
    a freed ctypes thunk: a SIGSEGV there or a corrupted heap found later (at exit:
    "corrupted double-linked list", exit code 139). Here a single module-level thunk is
    the only Python logger ever given to the proxy, it is never freed, and it finds the
    instance's log by the ``componentEnvironment`` the FMU passes back (a key, not a
    pointer); :meth:`claim_proxy`, called before each FMI call, points the proxy back at
    it in case other fmpy code in the process repointed it.
    """

    def __init__(self) -> None:
        self._logs: dict[int, list[tuple[int, str]]] = {}
        self._next = 1
        self._thunk: Any = None  # fmpy's ctypes objects (untyped), made by _setup
        self._probe: Any = None
        self._add_proxy: Callable[[], object] | None = None

    def _setup(self) -> None:
        from ctypes import byref

        from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
        from fmpy.logging import addLoggerProxy

        def dispatch(env: int | None, instance_name: bytes, status: int, category: bytes, message: bytes | str) -> None:
            log = self._logs.get(env or 0)
            if log is not None:
                log.append((int(status), message.decode("utf-8", "replace") if isinstance(message, bytes)
                            else str(message)))

        self._thunk = fmi2CallbackLoggerTYPE(dispatch)
        self._probe = fmi2CallbackFunctions()
        self._add_proxy = lambda: addLoggerProxy(byref(self._probe))

    def register(self, log: list[tuple[int, str]]) -> int:
        if self._thunk is None:
            self._setup()
        key, self._next = self._next, self._next + 1
        self._logs[key] = log
        return key

    def forget(self, key: int) -> None:
        self._logs.pop(key, None)

    def attach(self, callbacks: Any) -> None:
        """Give ``callbacks`` the proxy (formatting) in front of the shared thunk."""
        callbacks.logger = self._thunk
        self.claim_proxy()
        callbacks.logger = self._probe.logger  # fmpy's formatting proxy

    def claim_proxy(self) -> None:
        """Point fmpy's proxy at the shared thunk (a no-op call but for one C call)."""
        self._probe.logger = self._thunk
        assert self._add_proxy is not None, "register() sets up the proxy first"
        self._add_proxy()


_FMI2_LOGS = _Fmi2Logs()
_KEPT: list[tuple[Any, Any, Any]] = []  # instances that returned Fatal, never freed (FmuInstance.free)


class FmuInstance:
    """One co-simulation instance of an FMU under fmpy (FMI 2.0 or 3.0).

    Parameters
    ----------
    path : the ``.fmu`` file (or an extracted folder).
    name : instance name.
    debug_logging : pass ``loggingOn`` to the FMU (pythonfmu 0.7 forwards log messages,
        errors included, only when it is on).

    Attributes
    ----------
    fmi : 2 or 3. variables : name -> fmpy ModelVariable. log : list of (status, message).
    """

    def __init__(self, path: str | Path, name: str = "instance", debug_logging: bool = True):
        _fmpy()
        from fmpy import extract, read_model_description

        self.path = Path(path)
        self.md = read_model_description(str(path))
        self.fmi = int(self.md.fmiVersion[0])
        self._own_dir = not self.path.is_dir()
        self.unzipdir = extract(str(path)) if self._own_dir else str(path)
        self.variables = {v.name: v for v in self.md.modelVariables}
        self.log: list[tuple[int, str]] = []
        self.name = name
        self._freed = False
        self._fatal = False  # a call returned Fatal: free() then keeps the instance (see free)
        self._instantiate(debug_logging)

    # -- life cycle ------------------------------------------------------------------------
    def _instantiate(self, debug_logging: bool) -> None:
        identifier = self.md.coSimulation.modelIdentifier
        if self.fmi == 2:
            from fmpy.fmi1 import calloc, free
            from fmpy.fmi2 import FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions

            self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipdir, modelIdentifier=identifier,
                                 instanceName=self.name)
            # one process-wide logger; this instance's messages are told apart by its
            # componentEnvironment key (see _Fmi2Logs)
            self._log_key = _FMI2_LOGS.register(self.log)
            callbacks = fmi2CallbackFunctions()
            callbacks.componentEnvironment = self._log_key
            callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            _FMI2_LOGS.attach(callbacks)
            self._callbacks = callbacks
            try:
                self.fmu.instantiate(callbacks=callbacks, loggingOn=debug_logging)
            except Exception:
                raise FmuCallError(f"{self.name}: instantiate failed: {'; '.join(m for _, m in self.log)}") from None
        else:
            from fmpy.fmi3 import FMU3Slave

            self.fmu = FMU3Slave(guid=self.md.instantiationToken, unzipDirectory=self.unzipdir,
                                 modelIdentifier=identifier, instanceName=self.name)
            log = self.log  # FMI 3 loggers are not variadic: one callback per instance, no shared proxy

            def keep(env: object, status: int, category: bytes, message: bytes | str) -> None:
                log.append((int(status), message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)))

            self._logger = keep
            try:
                self.fmu.instantiate(loggingOn=debug_logging, logMessage=self._logger)
            except Exception:
                raise FmuCallError(f"{self.name}: instantiate failed: {'; '.join(m for _, m in self.log)}") from None

    def _call(self, what: str, fn: Callable[..., Any], *args: Any) -> Any:
        seen = len(self.log)
        if self.fmi == 2:
            _FMI2_LOGS.claim_proxy()
        try:
            return fn(*args)
        except Exception as exc:
            self._failed_call(what, seen, exc)

    def _failed_call(self, what: str, seen: int, exc: Exception) -> NoReturn:
        """Raise FmuCallError for a call that raised ``exc`` (its status and the log lines after ``seen``)."""
        status = getattr(exc, "status", None)
        labels: dict[Any, str] = {2: "discard", 3: "error", 4: "fatal"}
        label = labels.get(status, type(exc).__name__)
        if status == 4:
            self._fatal = True
        messages = "; ".join(m for _, m in self.log[seen:]) or str(exc)
        raise FmuCallError(f"{self.name}: {what} failed ({label}): {messages}") from exc

    def initialize(self, parameters: dict[str, Any] | None = None, start_time: float = 0.0,
                   stop_time: float | None = None) -> None:
        """Set parameters and pass through initialisation mode."""
        if self.fmi == 2:
            self._call("setupExperiment", self.fmu.setupExperiment, None, start_time, stop_time)
            self._call("enterInitializationMode", self.fmu.enterInitializationMode)
        else:
            self._call("enterInitializationMode", self.fmu.enterInitializationMode, None, start_time, stop_time)
        if parameters:
            self.set(parameters)
        self._call("exitInitializationMode", self.fmu.exitInitializationMode)

    def do_step(self, t: float, h: float) -> None:
        """``doStep(t, h)`` (FmuCallError on a non-OK status); :meth:`_call` with the call's
        description formatted only when it fails (a master calls this every step)."""
        seen = len(self.log)
        if self.fmi == 2:
            _FMI2_LOGS.claim_proxy()
        try:
            self.fmu.doStep(t, h)
        except Exception as exc:
            self._failed_call(f"doStep(t={t!r}, h={h!r})", seen, exc)

    def terminate(self) -> None:
        self._call("terminate", self.fmu.terminate)

    def reset(self) -> None:
        self._call("reset", self.fmu.reset)

    def free(self) -> None:
        """Free the instance and unload the library (idempotent).

        After a Fatal status the instance is not freed and the library stays loaded (FMI
        2.0 section 2.1.3: after ``fmi2Fatal`` no function of the FMU may be called).
        pythonfmu's shims release their Python references when they report Fatal and
        again when the instance is freed, so freeing a failed instance of an FMU without
        navsim's C guard corrupted the heap (see :mod:`navsim.fmu.guard`).
        """
        if self._freed:
            return
        self._freed = True
        if self._fatal:  # kept for the process's life, with the callbacks the FMU was given
            _KEPT.append((self.fmu, getattr(self, "_callbacks", None), getattr(self, "_logger", None)))
            if self.fmi == 2:
                _FMI2_LOGS.forget(self._log_key)
            if self._own_dir:  # a loaded library's file may go (Linux keeps the mapping)
                shutil.rmtree(self.unzipdir, ignore_errors=True)
            return
        if self.fmi == 2:
            _FMI2_LOGS.claim_proxy()
        self.fmu.freeInstance()
        if self.fmi == 2:
            _FMI2_LOGS.forget(self._log_key)
        if self._own_dir:
            shutil.rmtree(self.unzipdir, ignore_errors=True)

    def __enter__(self) -> FmuInstance:
        return self

    def __exit__(self, *exc: type[BaseException] | BaseException | TracebackType | None) -> None:
        self.free()

    # -- values ------------------------------------------------------------------------------
    def type_of(self, name: str) -> str:
        v = self.variables[name]
        return (_FMI2_TYPES if self.fmi == 2 else _FMI3_TYPES)[v.type]

    def size_of(self, name: str) -> int:
        v = self.variables[name]
        return int(np.prod(v.shape)) if getattr(v, "shape", None) else 1

    def _getter(self, type_: str) -> Callable[..., Any]:
        f = self.fmu
        if self.fmi == 2:
            return {"real": f.getReal, "int": f.getInteger, "bool": f.getBoolean, "string": f.getString}[type_]
        return {"real": f.getFloat64, "int": f.getInt32, "bool": f.getBoolean, "string": f.getString}[type_]

    def _setter(self, type_: str) -> Callable[..., Any]:
        f = self.fmu
        if self.fmi == 2:
            return {"real": f.setReal, "int": f.setInteger, "bool": f.setBoolean, "string": f.setString}[type_]
        return {"real": f.setFloat64, "int": f.setInt32, "bool": f.setBoolean, "string": f.setString}[type_]

    def get_raw(self, type_: str, vrs: list[int], n_values: int) -> list[Any]:
        getter = self._getter(type_)
        if self.fmi == 3 and type_ != "string":
            return list(self._call("get", getter, vrs, n_values))
        return list(self._call("get", getter, vrs))

    def set_raw(self, type_: str, vrs: list[int], values: list[Any]) -> None:
        if type_ == "string":
            values = [v.decode() if isinstance(v, bytes) else str(v) for v in values]
        self._call("set", self._setter(type_), vrs, values)

    def get(self, names: Iterable[str]) -> dict[str, Any]:
        """Values by name (arrays as numpy arrays of the variable's shape)."""
        out: dict[str, Any] = {}
        for name in names:
            v = self.variables[name]
            type_ = self.type_of(name)
            n = self.size_of(name)
            raw = self.get_raw(type_, [v.valueReference], n)
            if type_ == "string":
                raw = [r.decode() if isinstance(r, bytes) else r for r in raw]
            out[name] = np.asarray(raw).reshape(v.shape) if getattr(v, "shape", None) else raw[0]
        return out

    def set(self, values: dict[str, Any]) -> None:
        """Set variables by name (arrays flattened row-major)."""
        for name, value in values.items():
            v = self.variables[name]
            flat = np.asarray(value).ravel().tolist() if np.ndim(value) else [value]
            self.set_raw(self.type_of(name), [v.valueReference], flat)


class _Plan:
    """Bulk transfer of a fixed list of variables: one get/set per type.

    :meth:`unpack` gives arrays under their array name for both FMI versions (FMI 2
    scalars ``x[i,j]`` are gathered back into ``x``, in row-major order).
    """

    def __init__(self, inst: FmuInstance, names: list[str]):
        self.inst = inst
        self.groups: dict[str, tuple[list[int], int]] = {}
        fields: dict[str, dict[str, list]] = {}
        for name in names:
            type_ = inst.type_of(name)
            vrs, count = self.groups.get(type_, ([], 0))
            n = inst.size_of(name)
            vrs.append(inst.variables[name].valueReference)
            self.groups[type_] = (vrs, count + n)
            m = re.fullmatch(r"(.+)\[([\d,]+)\]", name) if inst.fmi == 2 else None
            shape = tuple(getattr(inst.variables[name], "shape", None) or ())
            entry = fields.setdefault(type_, {})
            if m:
                base, index = m.group(1), tuple(int(i) for i in m.group(2).split(","))
                entry.setdefault(base, []).append((index, count))
            else:
                entry[name] = [(shape, count, n)]
        self.layout: dict[str, list[tuple[str, int | slice | IntArray, tuple[int, ...]]]] = {}
        for type_, entry in fields.items():
            items: list[tuple[str, int | slice | IntArray, tuple[int, ...]]] = []
            for base, parts in entry.items():
                if len(parts) == 1 and len(parts[0]) == 3:
                    shape, offset, n = parts[0]
                    items.append((base, slice(offset, offset + n) if shape else offset, shape))
                else:
                    shape = tuple(max(ix[d] for ix, _ in parts) for d in range(len(parts[0][0])))
                    order = sorted(parts)
                    items.append((base, np.array([pos for _, pos in order]), shape))
            self.layout[type_] = items

    def fetch(self) -> dict[str, list[Any]]:
        return {t: self.inst.get_raw(t, vrs, n) for t, (vrs, n) in self.groups.items()}

    def unpack(self, raw: dict[str, list[Any]]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for t, items in self.layout.items():
            values = raw[t]
            arr = None
            for name, where, shape in items:
                if isinstance(where, int):
                    out[name] = values[where]
                elif isinstance(where, slice):
                    out[name] = np.asarray(values[where]).reshape(shape)
                else:
                    if arr is None:
                        arr = np.asarray(values)
                    out[name] = arr[where].reshape(shape)
        return out

class Connection:
    """The pair's connections: every estimator input fed by the plant output of the same
    name, moved with one bulk get and one bulk set per variable type (FmuCallError when an
    input has no plant output of its name)."""

    def __init__(self, plant: FmuInstance, est: FmuInstance):
        inputs = [n for n, v in est.variables.items() if v.causality == "input"]
        missing = [n for n in inputs if n not in plant.variables or plant.variables[n].causality != "output"]
        if missing:
            raise FmuCallError(f"estimator inputs without a plant output of the same name: {missing[:5]}")
        self.est = est
        self.src, self.dst = _Plan(plant, inputs), _Plan(est, inputs)

    def push(self) -> dict[str, list[Any]]:
        """Copy the plant's current outputs to the estimator's inputs; the raw values by type."""
        raw = self.src.fetch()
        for t, (vrs, _) in self.dst.groups.items():
            self.est.set_raw(t, vrs, raw[t])
        return raw



def plant_scenario(plant: FmuInstance, parameters: dict[str, Any] | None = None) -> Scenario:
    """The effective scenario of a navsim plant FMU instance with ``parameters``."""
    from .runtime import effective_scenario, load_embedded, plant_defaults

    base, _ = load_embedded(Path(plant.unzipdir) / "resources")
    params = {**plant_defaults(base), **(parameters or {})}
    return effective_scenario(base, params)


MASTERS = ("plant-first", "estimator-first", "jacobi")


def cosimulate(plant_fmu: str | Path, estimator_fmu: str | Path, seed: int = 0, *,
               plant_parameters: dict[str, Any] | None = None, estimator_parameters: dict[str, Any] | None = None,
               steps: int | None = None, name: str = "", progress: Callable[[int], object] | None = None,
               master: str = "plant-first") -> EpisodeRecord:
    """Run one episode of a navsim plant FMU and estimator FMU connected by name.

    ``master`` picks the order of each communication step of one navigation step (every
    estimator input is fed by the plant output of the same name):

    ``"plant-first"`` (Gauss-Seidel, the default)
        the plant steps, its outputs go to the estimator, then the estimator steps: the
        estimate of step k is ready at the end of step k (the numbers of ``run_episode``).
    ``"estimator-first"`` (Gauss-Seidel, the other order) and ``"jacobi"``
        both FMUs step on the values exchanged at the start of the step (Jacobi: both
        step, then all outputs are exchanged): the estimator processes plant step k one
        communication step later (``nav.lag_steps`` = 1), and the episode's last plant
        step is never processed.

    The returned :class:`~navsim.episode.EpisodeRecord` holds, for each plant step the
    estimator processed (``nav.step``), the plant's truth of that step and the estimate
    that refers to it (``nav.t_s``), so every master gives the same record up to the
    lagged master's missing last step; GNSS availability and the prior come from the
    plant's outputs. ``step_time_s`` is the CPU time of the estimator FMU's ``doStep``
    (FMI overhead included).
    """
    from navsim.earth import earth_model
    from navsim.episode import EpisodeRecorder
    from navsim.errors import ConfigError
    from navsim.types import NavSolution, Prior

    if master not in MASTERS:
        raise ConfigError("master", f"one of {MASTERS}", master)
    plant = FmuInstance(plant_fmu, "plant")
    est = FmuInstance(estimator_fmu, "estimator")
    try:
        params = {"seed": int(seed), **(plant_parameters or {})}
        scenario = plant_scenario(plant, params)
        plant.initialize(params)
        est.initialize(estimator_parameters or {})
        link = Connection(plant, est)
        truth_names = [n for n, v in plant.variables.items() if n.startswith(("truth.", "time."))]
        truth_plan = _Plan(plant, truth_names)
        nav_names = [n for n, v in est.variables.items() if n.startswith("nav.")]
        nav_plan = _Plan(est, nav_names)

        def push() -> dict[str, Any]:
            return link.src.unpack(link.push())

        timing = scenario.timing
        n = timing.steps if steps is None else min(int(steps), timing.steps)
        dt = timing.nav_period_s
        sensors = push()  # prior and start values
        prior = Prior(t=0.0, lat=float(sensors["prior.lat_rad"]), lon=float(sensors["prior.lon_rad"]),
                      h=float(sensors["prior.h_m"]), velocity_n=np.asarray(sensors["prior.velocity_n"], float),
                      heading=float(sensors["prior.heading_rad"]), pitch=float(sensors["prior.pitch_rad"]),
                      roll=float(sensors["prior.roll_rad"]), covariance=scenario.initial.covariance())
        rows_truth: list[dict[str, Any]] = []
        rows_nav: list[dict[str, Any]] = []
        cpu: list[float] = []
        epochs: list[tuple[int, float, int, bool]] = []  # (plant step, t, n_valid, receiver outage)
        clock = time.process_time

        def step_estimator(t: float) -> None:
            c0 = clock()
            est.do_step(t, dt)
            nav = nav_plan.unpack(nav_plan.fetch())
            spent = clock() - c0
            if nav["nav.step"] == len(rows_nav) + 1:
                rows_nav.append(nav)
                cpu.append(spent)

        def step_plant(t: float) -> None:
            plant.do_step(t, dt)
            rows_truth.append(truth_plan.unpack(truth_plan.fetch()))

        for k in range(n):
            t = k * dt
            if master == "plant-first":
                step_plant(t)
                sensors = push()
                step_estimator(t)
            else:  # estimator-first and Jacobi: both step on the values exchanged at t
                step_estimator(t)
                step_plant(t)
                sensors = push()
            if sensors["gnss.new_epoch"]:
                epochs.append((k, float(sensors["gnss.t_s"]), int(sensors["gnss.n_valid"]),
                               bool(sensors["gnss.receiver_outage"])))
            if progress is not None:
                progress(1)
        hash_out = plant.get(["navsim.config_hash"])["navsim.config_hash"]
        if hash_out != scenario.config_hash():
            raise FmuCallError(f"the plant reports config {hash_out}, the master rebuilt {scenario.config_hash()}")
        plant.terminate()
        est.terminate()
    finally:
        plant.free()
        est.free()

    m = len(rows_nav)  # plant steps processed: n, or n - 1 under a lagged master
    recorder = EpisodeRecorder(m)
    for i, (r, tr) in enumerate(zip(rows_nav, rows_truth)):  # each estimate refers to the plant step it processed
        if r["nav.t_s"] != (i + 1) * dt or tr["time.step"] != i + 1:
            raise FmuCallError(f"estimate {i}: nav.t_s = {r['nav.t_s']!r} s, plant step {tr['time.step']}")
        recorder.add_truth(i, tr["truth.s_m"], tr["truth.lat_rad"], tr["truth.lon_rad"], tr["truth.h_m"],
                           np.asarray(tr["truth.velocity_n"], dtype=float),
                           [tr["truth.heading_rad"], tr["truth.pitch_rad"], tr["truth.roll_rad"]])
        cov = np.asarray(r["nav.covariance"], dtype=float).reshape(9, 9)
        nis = float(r["nav.nis"])
        recorder.add_estimate(i, NavSolution(
            t=r["nav.t_s"], lat=r["nav.lat_rad"], lon=r["nav.lon_rad"], h=r["nav.h_m"],
            velocity_n=np.asarray(r["nav.velocity_n"], dtype=float), heading=r["nav.heading_rad"],
            pitch=r["nav.pitch_rad"], roll=r["nav.roll_rad"], covariance=None if np.all(np.isnan(cov)) else cov,
            nis=None if np.isnan(nis) else nis, nis_dof=int(r["nav.nis_dof"])), cpu[i])
    epochs = [e for e in epochs if e[0] < m]
    recorder.add_epochs([e[1] for e in epochs], [e[2] for e in epochs], [e[3] for e in epochs])
    return recorder.record(scenario, seed, name or "fmu", earth_model(scenario.earth), prior)
