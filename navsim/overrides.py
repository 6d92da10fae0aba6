"""Scenario overrides from the command line, shared by every command (navsim, navsim fmu).

``--set KEY=VALUE`` items become a nested override dict: the dotted key is the path of a
scenario field, the value a TOML value (a bare word is taken as a string), e.g.
``--set timing.duration_s=10 --set imu.preset=tactical`` ->
``{"timing": {"duration_s": 10.0}, "imu": {"preset": "tactical"}}``.
"""

from __future__ import annotations

import sys
from typing import Any

from .errors import NavsimError

__all__ = ["parse_overrides", "scenario_from_args"]


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``--set timing.duration_s=10`` -> {"timing": {"duration_s": 10.0}} (TOML values)."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        import tomli as tomllib

    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep:
            raise NavsimError(f"--set expects KEY=VALUE, got {item!r}")
        try:
            parsed = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            parsed = value  # a bare string
        node = out
        parts = key.split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = parsed
    return out


def scenario_from_args(args: Any) -> Any:
    """The scenario ``args.scenario`` (name or TOML path) with the ``args.set`` overrides."""
    from .scenario import load_scenario

    scenario = load_scenario(args.scenario)
    if getattr(args, "set", None):
        scenario = scenario.with_overrides(parse_overrides(args.set))
    return scenario
