"""Register the navsim env ids with Gymnasium whichever of the two is imported first.

Gymnasium 1.x has no plugin discovery (its ``gymnasium.envs`` entry points were dropped
in 1.0): an id is known once some imported module called ``gymnasium.register``. The core
must not import Gymnasium, so ``import navsim`` does one of two things:

* Gymnasium already imported: register the ids now (:func:`navsim.envs.register_envs`);
* otherwise: put a one-shot finder on ``sys.meta_path`` that, when ``gymnasium`` is
  imported later, lets the import run to completion and then registers the ids.

Either way ``import navsim`` followed by ``gym.make("navsim/PaperRail-v0")`` works in both
import orders, and ``import navsim`` alone never imports Gymnasium. A failing registration
(e.g. a broken optional install) warns instead of breaking the Gymnasium import.
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import sys
import warnings
from importlib.machinery import ModuleSpec
from types import ModuleType
from typing import Sequence

__all__ = ["install"]


def _register() -> None:
    envs = sys.modules.get("navsim.envs")
    if envs is not None and not hasattr(envs, "register_envs"):
        return  # navsim.envs is being imported (and imported Gymnasium): it registers at its end
    try:
        from navsim.envs import register_envs
    except ImportError as exc:  # pragma: no cover - a broken optional install
        warnings.warn(f"navsim: Gymnasium ids not registered ({exc})", RuntimeWarning, stacklevel=2)
        return
    register_envs()


class _AfterGymnasium(importlib.abc.MetaPathFinder):
    """One-shot finder: wraps the ``gymnasium`` loader so that the ids are registered after it ran."""

    def find_spec(self, name: str, path: Sequence[str] | None = None, target: ModuleType | None = None) -> ModuleSpec | None:
        if name != "gymnasium":
            return None
        _remove()
        spec = importlib.util.find_spec(name)  # the regular finders (this one is gone)
        if spec is None or spec.loader is None or not hasattr(spec.loader, "exec_module"):
            return spec
        exec_module = spec.loader.exec_module

        def exec_then_register(module: ModuleType) -> None:
            exec_module(module)
            _register()

        spec.loader.exec_module = exec_then_register  # type: ignore[method-assign]  # this spec's loader instance only
        return spec


def _remove() -> None:
    sys.meta_path[:] = [f for f in sys.meta_path if not isinstance(f, _AfterGymnasium)]


def install() -> None:
    """Register now if Gymnasium is imported, else once it is (idempotent)."""
    if "gymnasium" in sys.modules:
        _register()
    elif not any(isinstance(f, _AfterGymnasium) for f in sys.meta_path):
        sys.meta_path.insert(0, _AfterGymnasium())
