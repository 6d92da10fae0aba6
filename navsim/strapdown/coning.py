"""Coning compensation: the rotation vector over one navigation step (seed 000, §§2-4).

Every public algorithm returns the rotation vector (1.11)

    Phi(k, k+1) = DeltaTheta(k, k+1) + deltaTheta_c(k, k+1),
    deltaTheta_c = 1/2 int_{t_k}^{t_k+1} DeltaTheta(t_k, t) x omega(t) dt      (1.12)

from one of two kinds of gyro output over the step ``dt`` = DeltaT:

``dtheta_sub``, shape (n, m, 3), rad
    *Traditional* input: m first-order increments over m equal sub-intervals of the step
    (DeltaTheta_1 ... DeltaTheta_m in time order).
``dtheta_r``, shape (n, R, 3), rad*s**(r-1)
    Increments of *multiple integrals* (1.14): ``dtheta_r[:, r-1]`` is the r-fold
    integral of omega over the step, ``int (t_k+1 - tau)**(r-1)/(r-1)! omega(tau) dtau``.
    Only the first orders an algorithm needs are read; R may be larger.

Every function has the same signature ``f(dtheta_sub, dtheta_r, dt=None) -> (n, 3)``
(the registry contract of :mod:`navsim.strapdown`); the argument a method does not use may
be ``None``. ``dt`` (s) is required by the multiple-integral methods.

Algorithms
----------
========================== ============ ===========================================
name                       input        formula
========================== ============ ===========================================
one-sample                 sub or r=1   Phi = DeltaTheta (no correction)
two-sample                 sub, m=2     2/3 DTheta1 x DTheta2 (linear omega; [9])
three-sample               sub, m=3     (2.10), X = 33/80, Y = 57/80 (quadratic)
three-sample-optimized     sub, m=3     (2.10), X = 9/20, Y = 27/40 (Miller [9])
smoothing-linear           r = 1..2     (3.5) in (2.9) truncated: -(1/T) DT1 x DT2
smoothing                  r = 1..3     (3.7) (quadratic model, (3.4) in (2.9))
invariant-constant         r = 1..2     (4.3) with omega = DT1/T: DT2 x DT1 / (2T)
invariant-linear           r = 1..3     (4.3), two terms, omega_k+1 from (3.5)
invariant                  r = 1..4     (4.8) (three terms of (4.3), (3.4))
========================== ============ ===========================================

"smoothing-linear", "invariant-constant" and "invariant-linear" are not printed in the
paper; they follow from its general formulas exactly as the printed ones do, and the
paper's remark that coning and sculling algorithms of the same model order share their
coefficients ((3.6) -> smoothing-linear, (4.5) -> invariant-constant, (4.4) ->
invariant-linear, each halved because of the 1/2 in (1.12)).

Corrections of the printed text (checked numerically in tests/strapdown/test_coning.py)
-------------------------------------------------------------------------------------
* (4.3) as printed lacks the factor 1/2 of (1.12): the series
  ``DT2 x omega_k+1 - DT3 x omega'_k+1 + DT4 x omega''_k+1 - ...`` equals
  ``int DeltaTheta x omega dt`` = 2 deltaTheta_c. (4.8) does include the 1/2.
* (4.8): the last term is printed with ``30/DeltaT**2``; dimensional analysis
  (DeltaTheta^4 is in rad*s**3) and the derivation from (4.3) and (3.4) give
  ``30/DeltaT**3``. The bracket it multiplies is C_hat T^3/60, zero for linear omega, so
  the typo shows only for a quadratic rate: with ``/DeltaT**2`` the algorithm is not
  exact for quadratic omega(t) and its result depends on the unit of time; with
  ``/DeltaT**3`` it is exact for every quadratic omega(t), as a quadratic-model algorithm
  must be, and reproduces (4.13) and (4.14).

References
----------
.. [000] Litmanovich Yu.A., "Determination of the parameters of angular and translational
   motion of a rigid body from inertial information in the form of increments of
   multiple integrals of the measured quantities", Izv. RAN, 2002 (seed 000),
   eqs. (1.11)-(1.14), (2.8)-(2.13), (3.4), (3.7), (4.3), (4.8).
.. [9] Miller R.B., "A new strapdown attitude algorithm", J. Guidance, Control and
   Dynamics 6(4), 1983, 287-291 (two- and three-sample coning coefficients).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from .checks import check_dt as _dt
from .checks import check_multi as _multi
from .checks import check_sub as _sub

__all__ = [
    "one_sample",
    "two_sample",
    "three_sample",
    "three_sample_optimized",
    "smoothing_linear",
    "smoothing",
    "invariant_constant",
    "invariant_linear",
    "invariant",
    "CONING_ALGORITHMS",
    "CONING_INPUTS",
]

ConingFn = Callable[..., np.ndarray]


# ----------------------------------------------------------------------------- input checks
# ------------------------------------------------------------------------------ traditional
def one_sample(dtheta_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None, dt: float | None = None) -> np.ndarray:
    """Phi = DeltaTheta: no coning correction ((1.11) with deltaTheta_c = 0).

    Uses the sum of ``dtheta_sub`` if given, else ``dtheta_r[:, 0]``.
    """
    if dtheta_sub is not None:
        return np.asarray(dtheta_sub, dtype=float).sum(axis=1)
    return _multi(dtheta_r, 1, "one-sample")[:, 0].copy()


def two_sample(dtheta_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None, dt: float | None = None) -> np.ndarray:
    """Two-sample algorithm (linear omega model): deltaTheta_c = 2/3 DT1 x DT2.

    The coning twin of the sculling algorithm (2.3) (same coefficient, halved by the 1/2
    of (1.12)); Miller [9]. Input ``dtheta_sub`` (n, 2, 3).
    """
    d = _sub(dtheta_sub, 2, "two-sample")
    d1, d2 = d[:, 0], d[:, 1]
    return d1 + d2 + (2.0 / 3.0) * np.cross(d1, d2)


def _three_sample_xy(dtheta_sub: ArrayLike | None, x: float, y: float, name: str) -> np.ndarray:
    d = _sub(dtheta_sub, 3, name)
    d1, d2, d3 = d[:, 0], d[:, 1], d[:, 2]
    # (2.10) deltaTheta_c = X (DT1 x DT3) + Y DT2 x (DT3 - DT1)
    correction = x * np.cross(d1, d3) + y * np.cross(d2, d3 - d1)
    return d1 + d2 + d3 + correction


def three_sample(dtheta_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None, dt: float | None = None) -> np.ndarray:
    """Three-sample algorithm (2.10) for the quadratic omega model, X = 33/80, Y = 57/80.

    Local error (2.11) DeltaT**5/6480 (A x D); coning drift (2.12).
    Input ``dtheta_sub`` (n, 3, 3).
    """
    return _three_sample_xy(dtheta_sub, 33.0 / 80.0, 57.0 / 80.0, "three-sample")


def three_sample_optimized(dtheta_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None,
                           dt: float | None = None) -> np.ndarray:
    """Three-sample algorithm (2.10) with Miller's coning-optimized X = 9/20, Y = 27/40.

    Coning drift (2.13); general local error DeltaT**4/120 (A x C) (printed after (2.13)).
    Input ``dtheta_sub`` (n, 3, 3).
    """
    return _three_sample_xy(dtheta_sub, 9.0 / 20.0, 27.0 / 40.0, "three-sample-optimized")


# ------------------------------------------------------------------------------- smoothing
def smoothing_linear(dtheta_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None,
                     dt: float | None = None) -> np.ndarray:
    """Smoothing algorithm for the linear omega model (coning twin of (3.6)).

    deltaTheta_c = -(1/T) DT1 x DT2, i.e. (3.5) substituted into the first term of (2.9).
    Input ``dtheta_r`` with R >= 2.
    """
    d = _multi(dtheta_r, 2, "smoothing-linear")
    t = _dt(dt, "smoothing-linear")
    d1, d2 = d[:, 0], d[:, 1]
    return d1 - np.cross(d1, d2) / t


def smoothing(dtheta_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None, dt: float | None = None) -> np.ndarray:
    """Smoothing algorithm (3.7) for the quadratic omega model.

    deltaTheta_c = 6/T^2 (DT1 x DT3) - 3/T DT2 x (4/T^2 DT3 - DT1).
    Local error (3.9) DeltaT**7/100800 (C x D); coning drift (3.11).
    Input ``dtheta_r`` with R >= 3.
    """
    d = _multi(dtheta_r, 3, "smoothing")
    t = _dt(dt, "smoothing")
    d1, d2, d3 = d[:, 0], d[:, 1], d[:, 2]
    # (3.7) smoothing coning correction
    correction = (6.0 / t**2) * np.cross(d1, d3) - (3.0 / t) * np.cross(d2, (4.0 / t**2) * d3 - d1)
    return d1 + correction


# ------------------------------------------------------------------------------- invariant
def invariant_constant(dtheta_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None,
                       dt: float | None = None) -> np.ndarray:
    """Invariant algorithm, constant omega model: (4.3) one term, omega_k+1 = DT1/T.

    deltaTheta_c = DT2 x DT1 / (2T) (coning twin of (4.5)/(4.7)). Input ``dtheta_r``, R >= 2.
    """
    d = _multi(dtheta_r, 2, "invariant-constant")
    t = _dt(dt, "invariant-constant")
    d1, d2 = d[:, 0], d[:, 1]
    return d1 + np.cross(d2, d1) / (2.0 * t)


def invariant_linear(dtheta_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None,
                     dt: float | None = None) -> np.ndarray:
    """Invariant algorithm, linear omega model: (4.3) two terms with (3.5) at t_k+1.

    omega_k+1 = 4/T DT1 - 6/T^2 DT2, omega'_k+1 = 6/T^2 DT1 - 12/T^3 DT2,
    deltaTheta_c = 1/2 (DT2 x omega_k+1 - DT3 x omega'_k+1) (coning twin of (4.4)).
    Input ``dtheta_r`` with R >= 3.
    """
    d = _multi(dtheta_r, 3, "invariant-linear")
    t = _dt(dt, "invariant-linear")
    d1, d2, d3 = d[:, 0], d[:, 1], d[:, 2]
    rate_end = (4.0 / t) * d1 - (6.0 / t**2) * d2
    rate_dot_end = (6.0 / t**2) * d1 - (12.0 / t**3) * d2
    return d1 + 0.5 * (np.cross(d2, rate_end) - np.cross(d3, rate_dot_end))


def invariant(dtheta_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None, dt: float | None = None) -> np.ndarray:
    """Invariant algorithm (4.8) for the quadratic omega model (printed typo corrected).

    deltaTheta_c = 18/T^2 (DT1 x DT3) - 3/(2T) DT2 x (44/T^2 DT3 - 3 DT1)
                   - 30/T^3 (DT1 - 6/T DT2 + 12/T^2 DT3) x DT4.
    The paper prints 30/T^2 in the last term; 30/T^3 is the dimensionally consistent
    value that follows from (4.3) and (3.4) (see the module docstring).
    Local error (4.13) DeltaT**7/201600 (C x D); coning drift (4.14).
    Input ``dtheta_r`` with R >= 4.
    """
    d = _multi(dtheta_r, 4, "invariant")
    t = _dt(dt, "invariant")
    d1, d2, d3, d4 = d[:, 0], d[:, 1], d[:, 2], d[:, 3]
    # (4.8) invariant coning correction; last coefficient 30/T^3 (printed 30/T^2, a typo)
    correction = (
        (18.0 / t**2) * np.cross(d1, d3)
        - (1.5 / t) * np.cross(d2, (44.0 / t**2) * d3 - 3.0 * d1)
        - (30.0 / t**3) * np.cross(d1 - (6.0 / t) * d2 + (12.0 / t**2) * d3, d4)
    )
    return d1 + correction


CONING_ALGORITHMS: dict[str, ConingFn] = {
    "one-sample": one_sample,
    "two-sample": two_sample,
    "three-sample": three_sample,
    "three-sample-optimized": three_sample_optimized,
    "smoothing-linear": smoothing_linear,
    "smoothing": smoothing,
    "invariant-constant": invariant_constant,
    "invariant-linear": invariant_linear,
    "invariant": invariant,
}

#: Inputs per algorithm: ("sub", m) sub-samples or ("r", R) multiple-integral orders.
CONING_INPUTS: dict[str, tuple[str, int]] = {
    "one-sample": ("r", 1),
    "two-sample": ("sub", 2),
    "three-sample": ("sub", 3),
    "three-sample-optimized": ("sub", 3),
    "smoothing-linear": ("r", 2),
    "smoothing": ("r", 3),
    "invariant-constant": ("r", 2),
    "invariant-linear": ("r", 3),
    "invariant": ("r", 4),
}
