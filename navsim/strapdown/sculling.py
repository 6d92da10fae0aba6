"""Velocity-increment transformation with sculling compensation (seed 000, §§2-4).

Every public algorithm returns the bracket of (1.6) in body axes at t_k,

    DeltaV(k, k+1) + deltaV_s(k, k+1),
    deltaV_s = int_{t_k}^{t_k+1} DeltaTheta(t_k, t) x a(t) dt                   (1.8)

so that the inertial velocity increment is ``mat_ib(t_k) @ (DeltaV + deltaV_s)`` (1.6).
deltaV_s is the paper's single term: it contains both the "rotation compensation"
1/2 DeltaTheta x DeltaV and the sculling term of the Savage split [5]; nothing is to be
added on top.

Inputs (``None`` where a method does not use them):

``dtheta_sub``, ``dv_sub``, shape (n, m, 3)
    Traditional first-order increments over m equal sub-intervals of the step.
``dtheta_r``, ``dv_r``, shape (n, R, 3)
    Multiple-integral increments (1.14), ``[:, r-1]`` = r-fold integral over the step
    (rad*s**(r-1) and m/s*s**(r-1)). Only the first orders a method needs are read.
``dt``
    The step DeltaT (s); required by the multiple-integral methods.

Signature of every function: ``f(dtheta_sub, dv_sub, dtheta_r, dv_r, dt=None) -> (n, 3)``.

Algorithms
----------
======================= ==================== ===========================================
name (alias)            inputs               what it is
======================= ==================== ===========================================
first-order             sub (any m) or r=1   (2.4) constant omega and a: 1/2 DT x DV
two-sample              sub, m = 2           (2.3) linear omega and a (coefficient 2/3)
smoothing               Theta 1..2, V 1..2   (3.6) linear models from (3.5)
invariant-4.4           Theta 1..2, V 1..3   (4.4) acceleration-invariant, linear omega
(accel-invariant-linear)
invariant-4.5           Theta 1,    V 1..2   (4.5) acceleration-invariant, constant omega
(accel-invariant-constant)
invariant-4.6           Theta 1..3, V 1..2   (4.6) rate-invariant, linear a
(rate-invariant-linear)
invariant-4.7           Theta 1..2, V 1      (4.7) rate-invariant, constant a
(rate-invariant-constant)
======================= ==================== ===========================================

"Acceleration-invariant" ((4.1) truncated) means exact for *any* a(t) when omega(t) is a
polynomial of the model order; "rate-invariant" ((4.2) truncated) the other way round.
The smoothing algorithm for the constant model coincides with (2.4) (paper, after (3.7)).

Correction of the printed text
------------------------------
(2.3) is printed with the coefficient 1/3 in front of
``(DT1 x DV2 - DT2 x DV1)``; substituting (2.1) into (2.2) gives 2/3. Evidence
(tests/strapdown/test_sculling.py): for omega = const, a = B t the exact (1.8) is
``A x B T^3/3``; 1/2 DT x DV gives ``T^3/4`` and ``DT1 x DV2 - DT2 x DV1 = T^3/8``, so the
coefficient must be (1/3 - 1/4) * 8 = 2/3. 2/3 is also the value of Savage [5] and Ignagni
[8], and the one that makes (2.3) the twin of the two-sample coning algorithm
``2/3 DT1 x DT2`` that the paper's "same coefficients" remark requires. With 2/3 the
printed sculling error (2.6) is reproduced; with 1/3 the algorithm is only first order.

References
----------
.. [000] Litmanovich Yu.A., Izv. RAN, 2002 (seed 000), eqs. (1.6)-(1.8), (2.1)-(2.7),
   (3.5), (3.6), (3.8), (3.10), (4.1), (4.2), (4.4)-(4.7), (4.9)-(4.12).
.. [5] Savage P.G., "Strapdown inertial navigation integration algorithm design Part 2:
   velocity and position algorithms", J. Guidance, Control and Dynamics 21(2), 1998.
.. [8] Ignagni M.B., "Duality of optimal strapdown sculling and coning compensation
   algorithms", Navigation 45(2), 1998.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from .checks import check_dt as _dt
from .checks import check_multi as _multi
from .checks import check_sub as _sub

__all__ = [
    "first_order",
    "two_sample",
    "smoothing",
    "accel_invariant_linear",
    "accel_invariant_constant",
    "rate_invariant_linear",
    "rate_invariant_constant",
    "SCULLING_ALGORITHMS",
    "SCULLING_INPUTS",
]

ScullingFn = Callable[..., np.ndarray]


def first_order(dtheta_sub: ArrayLike | None = None, dv_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None,
                dv_r: ArrayLike | None = None, dt: float | None = None) -> np.ndarray:
    """(2.4) constant-model transformation: DeltaV + 1/2 DeltaTheta x DeltaV.

    Uses the sums of the sub-sample increments if given, else the r = 1 integrals.
    """
    if dtheta_sub is not None and dv_sub is not None:
        dtheta = np.asarray(dtheta_sub, dtype=float).sum(axis=1)
        dv = np.asarray(dv_sub, dtype=float).sum(axis=1)
    else:
        dtheta = _multi(dtheta_r, 1, "first-order")[:, 0]
        dv = _multi(dv_r, 1, "first-order", "dv_r")[:, 0]
    # (2.4) deltaV_s = 1/2 DeltaTheta x DeltaV
    return dv + 0.5 * np.cross(dtheta, dv)


def two_sample(dtheta_sub: ArrayLike | None = None, dv_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None,
               dv_r: ArrayLike | None = None, dt: float | None = None) -> np.ndarray:
    """(2.3) two-sample algorithm (linear omega and a), with the corrected coefficient 2/3.

    deltaV_s = 1/2 DT x DV + 2/3 (DT1 x DV2 - DT2 x DV1); the paper prints 1/3 (typo,
    see the module docstring). Local error (2.5), sculling error (2.6).
    """
    th = _sub(dtheta_sub, 2, "two-sample")
    dv = _sub(dv_sub, 2, "two-sample")
    t1, t2 = th[:, 0], th[:, 1]
    v1, v2 = dv[:, 0], dv[:, 1]
    total_t, total_v = t1 + t2, v1 + v2
    # (2.3) two-sample sculling; coefficient 2/3 (printed 1/3)
    correction = 0.5 * np.cross(total_t, total_v) + (2.0 / 3.0) * (np.cross(t1, v2) - np.cross(t2, v1))
    return total_v + correction


def smoothing(dtheta_sub: ArrayLike | None = None, dv_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None,
              dv_r: ArrayLike | None = None, dt: float | None = None) -> np.ndarray:
    """(3.6) smoothing algorithm for linear omega and a models.

    deltaV_s = 1/2 (DT1 x DV1) - 1/T [(DT1 x DV2) - (DT2 x DV1)].
    Local error (3.8), sculling error (3.10).
    """
    th = _multi(dtheta_r, 2, "smoothing")
    dv = _multi(dv_r, 2, "smoothing", "dv_r")
    t = _dt(dt, "smoothing")
    t1, t2 = th[:, 0], th[:, 1]
    v1, v2 = dv[:, 0], dv[:, 1]
    # (3.6) smoothing sculling correction
    correction = 0.5 * np.cross(t1, v1) - (np.cross(t1, v2) - np.cross(t2, v1)) / t
    return v1 + correction


def accel_invariant_linear(dtheta_sub: ArrayLike | None = None, dv_sub: ArrayLike | None = None,
                           dtheta_r: ArrayLike | None = None, dv_r: ArrayLike | None = None,
                           dt: float | None = None) -> np.ndarray:
    """(4.4) acceleration-invariant algorithm for the linear omega model.

    deltaV_s = DT1 x DV1 + 6/T^2 (DT2 - 2T/3 DT1) x DV2 - 12/T^3 (DT2 - T/2 DT1) x DV3.
    Exact for any a(t) when omega(t) is linear. Local error (4.9), sculling error (4.11).
    """
    th = _multi(dtheta_r, 2, "invariant-4.4")
    dv = _multi(dv_r, 3, "invariant-4.4", "dv_r")
    t = _dt(dt, "invariant-4.4")
    t1, t2 = th[:, 0], th[:, 1]
    v1, v2, v3 = dv[:, 0], dv[:, 1], dv[:, 2]
    # (4.4) acceleration-invariant sculling correction
    correction = (
        np.cross(t1, v1)
        + (6.0 / t**2) * np.cross(t2 - (2.0 * t / 3.0) * t1, v2)
        - (12.0 / t**3) * np.cross(t2 - 0.5 * t * t1, v3)
    )
    return v1 + correction


def accel_invariant_constant(dtheta_sub: ArrayLike | None = None, dv_sub: ArrayLike | None = None,
                             dtheta_r: ArrayLike | None = None, dv_r: ArrayLike | None = None,
                             dt: float | None = None) -> np.ndarray:
    """(4.5) acceleration-invariant algorithm for the constant omega model.

    deltaV_s = DT1 x (DV1 - DV2/T). Exact for any a(t) when omega is constant.
    Sculling error (4.12).
    """
    th = _multi(dtheta_r, 1, "invariant-4.5")
    dv = _multi(dv_r, 2, "invariant-4.5", "dv_r")
    t = _dt(dt, "invariant-4.5")
    v1, v2 = dv[:, 0], dv[:, 1]
    # (4.5)
    return v1 + np.cross(th[:, 0], v1 - v2 / t)


def rate_invariant_linear(dtheta_sub: ArrayLike | None = None, dv_sub: ArrayLike | None = None,
                          dtheta_r: ArrayLike | None = None, dv_r: ArrayLike | None = None,
                          dt: float | None = None) -> np.ndarray:
    """(4.6) angular-rate-invariant algorithm for the linear acceleration model.

    deltaV_s = -6/T^2 DT2 x (DV2 - 2T/3 DV1) + 12/T^3 DT3 x (DV2 - T/2 DV1).
    Exact for any omega(t) when a(t) is linear. Local error (4.10), sculling error (4.11).
    """
    th = _multi(dtheta_r, 3, "invariant-4.6")
    dv = _multi(dv_r, 2, "invariant-4.6", "dv_r")
    t = _dt(dt, "invariant-4.6")
    t2, t3 = th[:, 1], th[:, 2]
    v1, v2 = dv[:, 0], dv[:, 1]
    # (4.6) rate-invariant sculling correction
    correction = -(6.0 / t**2) * np.cross(t2, v2 - (2.0 * t / 3.0) * v1) + (12.0 / t**3) * np.cross(
        t3, v2 - 0.5 * t * v1
    )
    return v1 + correction


def rate_invariant_constant(dtheta_sub: ArrayLike | None = None, dv_sub: ArrayLike | None = None,
                            dtheta_r: ArrayLike | None = None, dv_r: ArrayLike | None = None,
                            dt: float | None = None) -> np.ndarray:
    """(4.7) angular-rate-invariant algorithm for the constant acceleration model.

    deltaV_s = (DT2 x DV1)/T. Exact for any omega(t) when a is constant.
    Sculling error (4.12).
    """
    th = _multi(dtheta_r, 2, "invariant-4.7")
    dv = _multi(dv_r, 1, "invariant-4.7", "dv_r")
    t = _dt(dt, "invariant-4.7")
    v1 = dv[:, 0]
    # (4.7)
    return v1 + np.cross(th[:, 1], v1) / t


SCULLING_ALGORITHMS: dict[str, ScullingFn] = {
    "first-order": first_order,
    "two-sample": two_sample,
    "smoothing": smoothing,
    "invariant-4.4": accel_invariant_linear,
    "invariant-4.5": accel_invariant_constant,
    "invariant-4.6": rate_invariant_linear,
    "invariant-4.7": rate_invariant_constant,
    "accel-invariant-linear": accel_invariant_linear,
    "accel-invariant-constant": accel_invariant_constant,
    "rate-invariant-linear": rate_invariant_linear,
    "rate-invariant-constant": rate_invariant_constant,
}

#: Inputs per algorithm: {"sub": m} or {"dtheta_r": R_theta, "dv_r": R_v}.
SCULLING_INPUTS: dict[str, dict[str, int]] = {
    "first-order": {"dtheta_r": 1, "dv_r": 1},
    "two-sample": {"sub": 2},
    "smoothing": {"dtheta_r": 2, "dv_r": 2},
    "invariant-4.4": {"dtheta_r": 2, "dv_r": 3},
    "invariant-4.5": {"dtheta_r": 1, "dv_r": 2},
    "invariant-4.6": {"dtheta_r": 3, "dv_r": 2},
    "invariant-4.7": {"dtheta_r": 2, "dv_r": 1},
}
for _alias, _name in (
    ("accel-invariant-linear", "invariant-4.4"),
    ("accel-invariant-constant", "invariant-4.5"),
    ("rate-invariant-linear", "invariant-4.6"),
    ("rate-invariant-constant", "invariant-4.7"),
):
    SCULLING_INPUTS[_alias] = SCULLING_INPUTS[_name]
