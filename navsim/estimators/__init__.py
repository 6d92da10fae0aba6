"""Estimators: the plug-in interface and the bundled estimators.

Any object with ``reset(context, prior)`` and ``step(measurement) -> Estimate`` is an
estimator (see :mod:`navsim.estimators.base`); :func:`make` builds the bundled ones by
name, and any other by its import path ``package.module:Factory`` (or
``path/to/file.py:Factory``), which every command and spec that takes an estimator name
accepts too. :func:`describe` lists them with their options and, for those whose optional
dependency is missing, the install hint. Estimator modules import numpy/scipy (filterpy only in the baselines) and never
the simulator: they see measurements, the map and the nominal sensor specification.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import os
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any, Callable

from ..errors import ConfigError
from .base import Context, Estimate, Estimator, GnssObservation, Measurement, NominalGnss, NominalImu

__all__ = ["make", "available", "register", "check", "describe", "is_import_path", "EstimatorInfo",
           "Context", "Estimate", "Estimator", "GnssObservation", "Measurement", "NominalGnss", "NominalImu"]

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
    "lc-ekf-filterpy": "navsim.estimators.filterpy_based:FilterpyLcEkf",
    "tc-ekf-filterpy": "navsim.estimators.filterpy_based:FilterpyTcEkf",
    "tc-ukf-filterpy": "navsim.estimators.filterpy_based:FilterpyTcUkf",
}

# name -> (importable module it needs, the install hint shown when it is missing)
_REQUIRES: dict[str, tuple[str, str]] = {
    "gnss-cv": ("filterpy", "pip install 'navsim-track[filters]'"),
    "lc-ekf-filterpy": ("filterpy", "pip install 'navsim-track[filters]'"),
    "tc-ekf-filterpy": ("filterpy", "pip install 'navsim-track[filters]'"),
    "tc-ukf-filterpy": ("filterpy", "pip install 'navsim-track[filters]'"),
}

# "package.module:Factory" or "path/to/file.py:Factory"
_IMPORT_PATH = re.compile(r"^(?P<module>[A-Za-z_][\w.]*|[^:]+\.py):(?P<attr>[A-Za-z_]\w*)$")


@dataclass(frozen=True)
class EstimatorInfo:
    """What ``navsim estimators`` lists for one estimator.

    name : the registry name or the import path. target : ``module:Factory``.
    available : whether it can be built here. missing : why not (the missing module and
    the install hint), empty when available. options : the factory's keyword options with
    their defaults (``inspect.signature``), empty when unavailable. summary : the first
    line of the factory's docstring.
    """

    name: str
    target: str
    available: bool
    missing: str
    options: dict[str, object]
    summary: str


def register(name: str, target: str, requires: tuple[str, str] | None = None) -> None:
    """Register a third-party estimator factory as ``"package.module:Factory"``.

    ``requires`` = ``(module, install hint)`` names an optional dependency: without it the
    estimator is listed as unavailable with the hint instead of failing when built.
    """
    if not _IMPORT_PATH.match(target):
        raise ConfigError("target", "an import path package.module:Factory", target)
    _REGISTRY[name] = target
    if requires is not None:
        _REQUIRES[name] = requires


def is_import_path(name: str) -> bool:
    """True for ``package.module:Factory`` / ``file.py:Factory`` (not a registry name)."""
    return name not in _REGISTRY and _IMPORT_PATH.match(name) is not None


def _missing(name: str) -> str:
    need = _REQUIRES.get(name)
    if need is not None and importlib.util.find_spec(need[0]) is None:
        return f"needs {need[0]} ({need[1]})"
    return ""


def available() -> list[str]:
    """Names of the registered estimators that can be built here (dependencies installed)."""
    names = []
    for name, target in _REGISTRY.items():
        module = target.split(":")[0]
        if importlib.util.find_spec(module) is not None and not _missing(name):
            names.append(name)
    return names


def _import_module(module_name: str, given: str) -> ModuleType:
    """Import ``module_name`` (a dotted name, or a ``.py`` file resolved against the
    current directory); the current directory is searched too, as a user running
    ``navsim`` from a project folder expects."""
    if module_name.endswith(".py"):
        path = Path(module_name).expanduser()
        if not path.is_file():
            raise ConfigError("estimator", "an existing Python file before ':' (relative to the current directory)",
                              given)
        mod_name = "navsim_user_" + re.sub(r"\W", "_", str(path.resolve().with_suffix("")))
        if mod_name in sys.modules:
            return sys.modules[mod_name]
        spec = importlib.util.spec_from_file_location(mod_name, path)
        if spec is None or spec.loader is None:  # not for a .py file; the checker cannot know
            raise ConfigError("estimator", "a Python file Python can load", given)
        module = importlib.util.module_from_spec(spec)
        sys.modules[mod_name] = module
        try:
            spec.loader.exec_module(module)
        except Exception:
            del sys.modules[mod_name]
            raise
        return module
    cwd = os.getcwd()
    if cwd not in sys.path and "" not in sys.path:
        sys.path.append(cwd)
    return importlib.import_module(module_name)


def _factory(name: str) -> Callable[..., Any]:
    """The factory behind a registry name or an import path, or a ConfigError."""
    target = _REGISTRY.get(name)
    if target is None:
        if not _IMPORT_PATH.match(name):
            raise ConfigError("estimator", f"one of {', '.join(sorted(_REGISTRY))} or an import path "
                              "package.module:Factory", name)
        target = name
    missing = _missing(name)
    if missing:
        raise ConfigError("estimator", f"an installed estimator ({name} {missing})", name)
    module_name, attr = target.rsplit(":", 1)
    try:
        module = _import_module(module_name, name)
    except ModuleNotFoundError as exc:
        raise ConfigError("estimator", f"an importable module ({exc.name} is not installed or not on the path)",
                          name) from None
    factory = getattr(module, attr, None)
    if factory is None or not callable(factory):
        raise ConfigError("estimator", f"a callable {attr} in module {module_name}", name)
    return factory


def check(name: str) -> None:
    """Raise a :class:`~navsim.errors.ConfigError` unless ``name`` can be built here."""
    _factory(name)


def make(name: str, **options: Any) -> Estimator:
    """Build an estimator by registry name or import path (``package.module:Factory``,
    ``path/to/file.py:Factory``) with keyword options."""
    factory = _factory(name)
    try:
        return factory(**options)
    except TypeError as exc:
        raise ConfigError(f"estimator {name} options", "keyword options the estimator accepts",
                          f"{options} ({exc})") from None


def describe(names: list[str] | None = None) -> list[EstimatorInfo]:
    """:class:`EstimatorInfo` for the registered estimators (or the given names/paths)."""
    out = []
    for name in names or list(_REGISTRY):
        target = _REGISTRY.get(name, name)
        try:
            factory = _factory(name)
        except ConfigError as exc:
            out.append(EstimatorInfo(name, target, False, _missing(name) or exc.expected, {}, ""))
            continue
        try:
            params = inspect.signature(factory).parameters.values()
            opts = {p.name: (p.default if p.default is not inspect.Parameter.empty else "(required)")
                    for p in params if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)}
        except (TypeError, ValueError):
            opts = {}
        doc = (inspect.getdoc(factory) or "").strip().splitlines()
        out.append(EstimatorInfo(name, target, True, "", opts, doc[0] if doc else ""))
    return out
