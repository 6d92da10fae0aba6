"""Strapdown algorithms of seeds 000 and 001 and the INS mechanisation.

This package's registries are the contract between the algorithm modules and the INS:

``CONING[name](dtheta_sub, dtheta_r, dt=None) -> Phi (n, 3)``
    Rotation vector over one navigation step, Phi = DeltaTheta + deltaTheta_c (1.11)
    of seed 000. See :mod:`navsim.strapdown.coning`.
``SCULLING[name](dtheta_sub, dv_sub, dtheta_r, dv_r, dt=None) -> (n, 3)``
    DeltaV + deltaV_s, the bracket of (1.6) in body axes at t_k (the inertial velocity
    increment is ``mat_ib_k @ result``). See :mod:`navsim.strapdown.sculling`.
``POSITION[name](velocity_i_k, mat_ib_k, dtheta_sub, dv_sub, dtheta_r, dv_r, dt) -> (n, 3)``
    Displacement S_i(k+1) - S_i(k) in the inertial frame (§5 of seed 000). See
    :mod:`navsim.strapdown.position`.
``required_inputs(kind, name) -> set[str]``
    What a method reads, as tokens ``"dtheta_sub:m"``, ``"dv_sub:m"`` (m sub-sample
    increments per step), ``"dtheta_r:R"``, ``"dv_r:R"`` (multiple integrals up to order
    R), ``"dt"`` (the step must be passed) and ``"velocity"``/``"attitude"`` (position).

Array conventions: ``dtheta_sub``/``dv_sub`` (n, m, 3) hold m first-order increments in
time order; ``dtheta_r``/``dv_r`` (n, R, 3) hold ``[:, r-1]`` = the r-fold integral (1.14)
over the step, ``int (t_k+1 - tau)**(r-1)/(r-1)! omega(tau) dtau`` (likewise for the
specific force). Arguments a method does not read may be ``None``. ``dt`` is the
navigation step DeltaT in seconds.

References
----------
.. [000] Litmanovich Yu.A., Izv. RAN, 2002 (seed 000).
.. [001] Kononenko 2007 (seed 001): quaternion algorithms (:mod:`.quaternion`).
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
