"""Registration of the navsim env ids with Gymnasium (re-exported by :mod:`navsim.envs`).

One navigation env id per bundled scenario file (``navsim/PaperRail-v0``,
``navsim/MountainRailway-v0``, ...; the native vector env as its vector entry point) and
the tasks ``navsim/AdaptiveFilter-v0`` and ``navsim/TrainDriving-v0``.
"""

from __future__ import annotations

from navsim.scenario import list_scenarios

__all__ = ["SCENARIO_IDS", "env_ids", "scenario_of", "register_envs"]

SCENARIO_IDS = {"paper-2012": "navsim/PaperRail-v0"}
"""Scenario names whose env id is not the CamelCase of the name."""

_TASKS = {
    "navsim/AdaptiveFilter-v0": "navsim.envs.adaptive:AdaptiveFilterEnv",
    "navsim/TrainDriving-v0": "navsim.envs.driving:DrivingEnv",
}


def _camel(name: str) -> str:
    return "".join(part[:1].upper() + part[1:] for part in name.replace("_", "-").split("-") if part)


def env_ids() -> dict[str, str]:
    """Navigation env id -> scenario name, for every bundled scenario file."""
    return {SCENARIO_IDS.get(name, f"navsim/{_camel(name)}-v0"): name for name in list_scenarios()}


def scenario_of(env_id: str) -> str:
    """The scenario name behind a navigation env id."""
    return env_ids()[env_id]


def register_envs() -> None:
    """Register the navsim ids with Gymnasium (idempotent)."""
    from gymnasium.envs.registration import register, registry

    for env_id, scenario in env_ids().items():
        if env_id not in registry:
            register(id=env_id, entry_point="navsim.envs.navigation:NavigationEnv",
                     vector_entry_point="navsim.envs.vector:NavigationVectorEnv",
                     kwargs={"scenario": scenario}, disable_env_checker=False)
    for env_id, entry in _TASKS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry)
