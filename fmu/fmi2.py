"""FMI 2.0 co-simulation slaves (pythonfmu) that forward every call to a runtime.

The classes here only translate: value references and types to the
:class:`~navsim.fmu.runtime.ValueStore`, ``do_step`` to the runtime, errors to FMI
statuses with a log message. pythonfmu's C layer maps a ``False`` return of ``do_step``
to ``fmi2Discard`` and any Python exception to ``fmi2Fatal`` (after which the instance
can only be freed); navsim therefore refuses a bad communication step with
``fmi2Discard`` and an error-category log message (the instance stays usable: retry with a
valid step), and a bad parameter value with ``fmi2Error`` from
``fmi2ExitInitializationMode`` and an error-category message naming the parameter, the
expectation and the value (through the C guard, :func:`~navsim.fmu.runtime.refuse_through_guard`;
the instance stays in initialisation mode: set a valid value and exit again, or reset;
an FMU built without the guard answers ``fmi2Fatal`` with the same message).

Generated FMUs contain a one-line slave script that subclasses :class:`PlantSlave` or
:class:`EstimatorSlave` under the name pythonfmu's loader looks for.
"""

from __future__ import annotations

from typing import Any, ClassVar, NoReturn

from pythonfmu import Fmi2Slave
from pythonfmu.enums import Fmi2Status

from .runtime import EstimatorRuntime, FmuError, PlantRuntime, SlaveValues, guard_embedded_exit
from .runtime import mark_failed as _mark_failed
from .runtime import refuse_through_guard as _refuse

guard_embedded_exit()  # a non-Python host: see navsim.fmu.runtime

__all__ = ["PlantSlave", "EstimatorSlave", "pin_module_dict"]

_PINNED: list[dict[str, Any]] = []


def pin_module_dict(namespace: dict[str, Any]) -> None:
    """Keep one reference to the slave script's module dict per execution of the script.

    pythonfmu 0.7's loader (``findClass`` in its C++ shim) re-executes the slave script
    with the module's ``__dict__`` as globals at every ``fmi2Instantiate`` and then calls
    ``Py_DECREF`` on that borrowed reference, so each instantiation drops one reference
    it never owned; after a few instantiations in one process the dict is freed and the
    next one fails with "module has no attribute 'NavsimPlant'". The generated script
    calls this at module level, which balances the count (8 bytes per instantiation).
    """
    _PINNED.append(namespace)


_LEVEL = {"info": Fmi2Status.ok, "warning": Fmi2Status.warning, "error": Fmi2Status.error}


class _Slave(SlaveValues, Fmi2Slave):
    runtime_class: ClassVar[type[PlantRuntime] | type[EstimatorRuntime]]  # set by the two subclasses below

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._failed = False
        self.rt = self.runtime_class(self.resources, 2, self._log)

    def _log(self, message: str, level: str = "info") -> None:
        self.log(message, _LEVEL[level])

    def _fail(self, message: str) -> NoReturn:
        self.log(message, Fmi2Status.error)
        _mark_failed(self)
        raise FmuError(message)

    # -- life cycle ------------------------------------------------------------------------
    def setup_experiment(self, start_time: float, *_: Any) -> None:  # stop time and tolerance: unused
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

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._failed:
            self.log("doStep refused: the instance failed earlier (see the log); free it", Fmi2Status.error)
            return False
        try:
            self.rt.do_step(current_time, step_size)
        except FmuError as exc:
            self.log(f"doStep refused: {exc}", Fmi2Status.error)
            return False
        except Exception as exc:  # a bug must not take the host down: report, refuse the step
            self.log(f"doStep failed: {type(exc).__name__}: {exc}", Fmi2Status.error)
            return False
        return True

    def get_real(self, vrs: list[int]) -> list[Any]:
        return self._get(vrs, "real")

    def get_integer(self, vrs: list[int]) -> list[Any]:
        return self._get(vrs, "int")

    def set_real(self, vrs: list[int], values: list[Any]) -> None:
        self._set(vrs, values, "real")

    def set_integer(self, vrs: list[int], values: list[Any]) -> None:
        self._set(vrs, values, "int")


class PlantSlave(_Slave):
    """The plant FMU (FMI 2): :class:`~navsim.fmu.runtime.PlantRuntime`."""

    runtime_class = PlantRuntime


class EstimatorSlave(_Slave):
    """The estimator FMU (FMI 2): :class:`~navsim.fmu.runtime.EstimatorRuntime`."""

    runtime_class = EstimatorRuntime
