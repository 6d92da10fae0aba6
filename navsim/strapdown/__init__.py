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

from .registry import CONING, POSITION, SCULLING, required_inputs

__all__ = ["CONING", "SCULLING", "POSITION", "required_inputs"]
