"""navsim.envs: the Gymnasium face of navsim.

Importing this package registers one navigation env id per bundled scenario file and
the two learning tasks (Gymnasium's ``register``; calling :func:`register_envs` again is
harmless):

==============================  =====================  =========================================
id                              scenario               env
==============================  =====================  =========================================
``navsim/PaperRail-v0``         ``paper-2012``         :class:`NavigationEnv`
``navsim/MountainRailway-v0``   ``mountain-railway``   :class:`NavigationEnv`
``navsim/UrbanRoad-v0``         ``urban-road``         :class:`NavigationEnv`
``navsim/AdaptiveFilter-v0``    ``paper-2012``         :class:`AdaptiveFilterEnv`
``navsim/TrainDriving-v0``      ``mountain-railway``   :class:`DrivingEnv`
==============================  =====================  =========================================

A scenario file added later gets ``navsim/<CamelCaseName>-v0``. The navigation ids have a
native vector implementation (:class:`NavigationVectorEnv`):
``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``.

``gym.make(id, **kwargs)`` takes scenario overrides as nested dicts
(``timing={"duration_s": 60}``); the resolved scenario (name, config hash, TOML) is in
the reset info.

Registration (Gymnasium 1.x has no plugin discovery: an id exists once a module called
``gymnasium.register``): ``import navsim.envs`` registers; so does ``import navsim`` in
either order with ``import gymnasium`` (:mod:`navsim._gymhook`); without importing navsim
at all, ``gym.make("navsim.envs:navsim/PaperRail-v0")`` imports and registers in one call.

The core (``navsim``) never imports Gymnasium; this package is the only one that does.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # type hints only
    from typing import Any

try:
    import gymnasium  # noqa: F401
except ImportError:  # the core installs without the Gymnasium face's extra
    from navsim.errors import DependencyNotInstalled

    raise DependencyNotInstalled("gymnasium", "gym") from None

from .agent import EstimateAction, EstimatorAgent, evaluate
from .navigation import NavigationEnv
from .registration import SCENARIO_IDS, env_ids, register_envs, scenario_of

__all__ = ["register_envs", "env_ids", "scenario_of", "NavigationEnv", "NavigationVectorEnv", "AdaptiveFilterEnv",
           "DrivingEnv", "EstimatorAgent", "EstimateAction", "evaluate", "SCENARIO_IDS"]

def __getattr__(name: str) -> Any:
    if name == "NavigationVectorEnv":
        from .vector import NavigationVectorEnv

        return NavigationVectorEnv
    if name == "AdaptiveFilterEnv":
        from .adaptive import AdaptiveFilterEnv

        return AdaptiveFilterEnv
    if name == "DrivingEnv":
        from .driving import DrivingEnv

        return DrivingEnv
    raise AttributeError(f"module 'navsim.envs' has no attribute {name!r}")


register_envs()
