"""The registries of the strapdown methods: coning, sculling and position algorithms by name.

Re-exported by :mod:`navsim.strapdown`; :mod:`navsim.strapdown.ins` picks its methods
here (so no module of the package imports the package itself).
"""

from __future__ import annotations

from collections.abc import Callable

from ..errors import ConfigError
from .coning import CONING_ALGORITHMS, CONING_INPUTS
from .position import POSITION_INPUTS, POSITION_METHODS
from .sculling import SCULLING_ALGORITHMS, SCULLING_INPUTS

__all__ = ["CONING", "SCULLING", "POSITION", "required_inputs"]

#: name -> f(dtheta_sub, dtheta_r, dt=None) -> Phi (n, 3)
CONING: dict[str, Callable] = dict(CONING_ALGORITHMS)
#: name -> f(dtheta_sub, dv_sub, dtheta_r, dv_r, dt=None) -> DeltaV + deltaV_s (n, 3)
SCULLING: dict[str, Callable] = dict(SCULLING_ALGORITHMS)
#: name -> f(velocity_i_k, mat_ib_k, dtheta_sub, dv_sub, dtheta_r, dv_r, dt) -> (n, 3)
POSITION: dict[str, Callable] = dict(POSITION_METHODS)

_KINDS = {"coning": CONING, "sculling": SCULLING, "position": POSITION}


def required_inputs(kind: str, name: str) -> set[str]:
    """Inputs a registered method reads.

    Parameters
    ----------
    kind : {"coning", "sculling", "position"}
    name : str
        A key of the matching registry.

    Returns
    -------
    set of str
        Tokens ``"dtheta_sub:m"``, ``"dv_sub:m"``, ``"dtheta_r:R"``, ``"dv_r:R"``,
        ``"dt"``, ``"velocity"``, ``"attitude"``. For example
        ``required_inputs("coning", "three-sample") == {"dtheta_sub:3"}`` and
        ``required_inputs("sculling", "invariant-4.4") ==
        {"dtheta_r:2", "dv_r:3", "dt"}``.
        "one-sample"/"first-order" accept sub-samples too (they use their sum), but
        need only the r = 1 integrals, which is what is reported.
    """
    if kind not in _KINDS:
        raise ConfigError("kind", "one of " + ", ".join(sorted(_KINDS)), kind)
    if name not in _KINDS[kind]:
        raise ConfigError("name", f"one of {sorted(_KINDS[kind])}", name)
    tokens: set[str] = set()
    if kind == "coning":
        source, count = CONING_INPUTS[name]
        if source == "sub":
            tokens.add(f"dtheta_sub:{count}")
        else:
            tokens.add(f"dtheta_r:{count}")
            if count > 1:
                tokens.add("dt")
        return tokens
    spec = SCULLING_INPUTS[name] if kind == "sculling" else POSITION_INPUTS[name]
    if "sub" in spec:
        tokens.update({f"dtheta_sub:{spec['sub']}", f"dv_sub:{spec['sub']}"})
    for key in ("dtheta_r", "dv_r"):
        if key in spec:
            tokens.add(f"{key}:{spec[key]}")
    if kind == "position":
        tokens.update({"velocity", "dt"})
        if name != "rectangle":
            tokens.add("attitude")
    elif max(spec.get("dtheta_r", 1), spec.get("dv_r", 1)) > 1:
        tokens.add("dt")
    return tokens
