"""Estimators: the plug-in interface and the bundled estimators.

Any object with ``reset(context, prior)`` and ``step(measurement) -> Estimate`` is an
estimator (see :mod:`navsim.estimators.base`); :func:`make` builds the bundled ones by
name. Estimator modules import numpy/scipy (filterpy only in the baselines) and never
the simulator: they see measurements, the map and the nominal sensor specification.
"""

from __future__ import annotations

import importlib

from ..errors import ConfigError
from .base import Context, Estimate, Estimator, GnssObservation, Measurement, NominalGnss, NominalImu

__all__ = ["make", "available", "register", "Context", "Estimate", "Estimator", "GnssObservation",
           "Measurement", "NominalGnss", "NominalImu"]

# name -> "module:factory" (imported on first use, so optional dependencies stay optional)
_REGISTRY: dict[str, str] = {
    "paper-ekf": "navsim.estimators.paper_ekf:PaperEkf",
    "ins-only": "navsim.estimators.ins_only:InsOnly",
    "gnss-ls": "navsim.estimators.gnss_only:GnssLeastSquares",
    "gnss-cv": "navsim.estimators.gnss_only:GnssConstantVelocity",
    "lc-ekf": "navsim.estimators.loosely:LooselyCoupledEkf",
    "tc-ekf": "navsim.estimators.tightly:TightlyCoupledEkf",
    "tc-ukf": "navsim.estimators.tightly:TightlyCoupledUkf",
    "along-track": "navsim.estimators.along_track:AlongTrackFilter",
    "full-state-ekf": "navsim.estimators.full_state:FullStateEkf",
}


def register(name: str, target: str) -> None:
    """Register a third-party estimator factory as ``"package.module:Factory"``."""
    _REGISTRY[name] = target


def available() -> list[str]:
    """Names of the registered estimators whose modules can be imported."""
    names = []
    for name, target in _REGISTRY.items():
        module = target.split(":")[0]
        if importlib.util.find_spec(module) is not None:
            names.append(name)
    return names


def make(name: str, **options):
    """Build a registered estimator by name with keyword options."""
    target = _REGISTRY.get(name)
    if target is None:
        raise ConfigError("estimator", f"one of {sorted(_REGISTRY)}", name)
    module_name, factory = target.split(":")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        raise ConfigError("estimator", f"an installed estimator ({exc.name} is missing)", name) from None
    try:
        return getattr(module, factory)(**options)
    except TypeError as exc:
        raise ConfigError(f"estimator {name} options", "keyword options the estimator accepts", f"{options} ({exc})") from None
