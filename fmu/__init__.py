"""navsim's FMU face: navsim as FMUs for other tools, other tools' FMUs inside navsim.

Export (FMI 2.0 through pythonfmu, FMI 3.0 through pythonfmu3; ``navsim fmu build``)
    :func:`build_fmu` writes a *plant* FMU (the core simulator: truth, IMU increments
    and multiple integrals, GNSS channels; optional external-motion inputs) or an
    *estimator* FMU (a registered estimator: sensor inputs, navigation solution and its
    uncertainty as outputs). Variable names, units, descriptions and start values come
    from :mod:`navsim.fmu.variables`, the table shared with the Gymnasium spaces. What
    runs inside is :mod:`navsim.fmu.runtime` (a translation of FMI calls into core
    calls, no physics). :data:`navsim.fmu.build.HOST_REQUIREMENTS` says what a host
    needs.
Run (fmpy)
    :class:`~navsim.fmu.master.FmuInstance` and :func:`cosimulate` (plant + estimator
    FMUs under a Gauss-Seidel or Jacobi master, an :class:`~navsim.episode.EpisodeRecord`
    to score). The estimator FMU reads the plant's step counter, so any fixed-step master
    gives run_episode's numbers, lagged one step under Jacobi (see
    :mod:`navsim.fmu.runtime`).
Import
    :class:`~navsim.fmu.motion.FmuMotionSource` steps an external co-simulation FMU (for
    example a train-dynamics model) and feeds its arc length, speed and acceleration to
    the simulator; :class:`~navsim.fmu.motion.FmuDrivenSimulator` is a Simulator driven
    by it (usable by ``run_episode``, the CLI and the Gymnasium env).

The core (``navsim/``) never imports pythonfmu or fmpy; this package imports them
lazily, so ``import navsim.fmu`` works without the ``fmu`` extra.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .variables import Dimensions, Var, action_variables, estimator_variables, observation_variables, plant_variables

if TYPE_CHECKING:  # type hints only
    from typing import Any

__all__ = [
    "Var", "Dimensions", "plant_variables", "estimator_variables", "observation_variables", "action_variables",
    "build_fmu", "cosimulate", "FmuInstance", "FmuMotionSource", "MotionMapping", "FmuDrivenSimulator",
]

_LAZY = {
    "build_fmu": ("build", "build_fmu"),
    "cosimulate": ("master", "cosimulate"),
    "FmuInstance": ("master", "FmuInstance"),
    "FmuMotionSource": ("motion", "FmuMotionSource"),
    "MotionMapping": ("motion", "MotionMapping"),
    "FmuDrivenSimulator": ("motion", "FmuDrivenSimulator"),
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(f".{module}", __name__), attr)
    raise AttributeError(f"module 'navsim.fmu' has no attribute {name!r}")
