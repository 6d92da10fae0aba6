"""FMI 3.0 co-simulation slaves (pythonfmu3) that forward every call to a runtime.

As :mod:`navsim.fmu.fmi2`, with FMI 3 arrays for the per-channel GNSS signals and the
3-vectors. ``do_step`` returns ``fmi3Error`` with an error-category log message for a
bad communication step (the instance stays usable); a bad parameter value gives
``fmi3Error`` from ``fmi3ExitInitializationMode`` with the message, through the C guard
as in FMI 2 (without the guard it raises, which pythonfmu3's C layer reports as
``fmi3Fatal``).
"""

from __future__ import annotations

from typing import Any, ClassVar, NoReturn

from pythonfmu3 import Fmi3Slave
from pythonfmu3.enums import Fmi3Status
from pythonfmu3.fmi3slave import Fmi3StepResult

from .runtime import EstimatorRuntime, FmuError, PlantRuntime, SlaveValues, guard_embedded_exit
from .runtime import mark_failed as _mark_failed
from .runtime import refuse_through_guard as _refuse

guard_embedded_exit()  # a non-Python host: see navsim.fmu.runtime

__all__ = ["PlantSlave", "EstimatorSlave"]

_LEVEL = {"info": Fmi3Status.ok, "warning": Fmi3Status.warning, "error": Fmi3Status.error}
_OK = Fmi3StepResult()  # an immutable NamedTuple: one instance serves every accepted step


class _Slave(SlaveValues, Fmi3Slave):
    runtime_class: ClassVar[type[PlantRuntime] | type[EstimatorRuntime]]  # set by the two subclasses below

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._failed = False
        self.rt = self.runtime_class(self.resources, 3, self._log)
        self.time = 0.0
        self._time = self.rt.store.real  # element 0: FMI 3's independent variable, set after every step

    def _log(self, message: str, level: str = "info") -> None:
        self.log(message, _LEVEL[level])

    def _fail(self, message: str) -> NoReturn:
        self.log(message, Fmi3Status.error)
        _mark_failed(self)
        raise FmuError(message)

    def setup_experiment(self, start_time: float, *_: Any) -> None:
        self.rt.start_time = float(start_time)  # refused at exitInitializationMode unless 0

    def exit_initialization_mode(self) -> None:
        if self._failed:
            return
        try:
            self.rt.exit_initialization_mode()
        except FmuError as exc:
            if _refuse(self.rt, str(exc)):  # the C guard logs it, answers an error status; the instance stays usable
                return
            self._fail(str(exc))

    def do_step(self, current_time: float, step_size: float) -> Fmi3StepResult:
        if self._failed:
            self.log("doStep refused: the instance failed earlier (see the log); free it", Fmi3Status.error)
            return Fmi3StepResult(status=Fmi3Status.error)
        try:
            self.rt.do_step(current_time, step_size)
        except FmuError as exc:
            self.log(f"doStep refused: {exc}", Fmi3Status.error)
            return Fmi3StepResult(status=Fmi3Status.error)
        except Exception as exc:  # a bug must not take the host down: report, refuse the step
            self.log(f"doStep failed: {type(exc).__name__}: {exc}", Fmi3Status.error)
            return Fmi3StepResult(status=Fmi3Status.error)
        self.time = self._time[0] = current_time + step_size  # value reference 0 (ValueStore.set_time)
        return _OK

    def get_float64(self, vrs: list[int]) -> list[Any]:
        return self._get(vrs, "real")

    def get_int32(self, vrs: list[int]) -> list[Any]:
        return self._get(vrs, "int")

    def set_float64(self, vrs: list[int], values: list[Any]) -> None:
        self._set(vrs, values, "real")

    def set_int32(self, vrs: list[int], values: list[Any]) -> None:
        self._set(vrs, values, "int")


class PlantSlave(_Slave):
    """The plant FMU (FMI 3): :class:`~navsim.fmu.runtime.PlantRuntime`."""

    runtime_class = PlantRuntime


class EstimatorSlave(_Slave):
    """The estimator FMU (FMI 3): :class:`~navsim.fmu.runtime.EstimatorRuntime`."""

    runtime_class = EstimatorRuntime
