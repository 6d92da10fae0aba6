"""Equality between two code paths at the precision the arithmetic guarantees.

Two rules (the project's standard):

* **bit for bit** (:func:`assert_same_arithmetic`) where both paths run the same
  floating-point operations in the same order (the step and batch paths of an estimator
  share every state and update computation); any difference is then a bug, whatever the
  CPU or BLAS kernel;
* otherwise a **tolerance derived from the magnitudes** (:func:`assert_covariance_close`,
  :func:`sum_bound`), the reason written beside it.

The between-epoch covariance of the INS error engine (``ErrorStateIns.advance_body``) is
``P9(tau) = sum_p tau^p c_p`` (p = 0..8), evaluated as one ``(n, 9) @ (9, 81)`` product per
call: n rows in the batch path, one row per call in the step path. OpenBLAS picks
different kernels for those shapes and, by CPU, fused multiply-adds (Haswell) or not
(Sandybridge), so the two paths agree only to the rounding of a 9-term sum: per entry
``|dP| <= 2 gamma_9 sum_p |tau^p c_p|`` (Higham, Accuracy and Stability of Numerical
Algorithms, 2nd ed., eq. 3.5; gamma_n = n u / (1 - n u), u = eps / 2, each path's error
counted once). Over one covariance interval the terms are dominated by the entry's
Cauchy-Schwarz scale ``sqrt(P_ii P_jj)`` (c_0 is the interval-start covariance, the series
converges within the interval), which is the scale used here.
"""

from __future__ import annotations

import math

import numpy as np

EPS = float(np.finfo(float).eps)
UNIT_ROUNDOFF = EPS / 2.0


def gamma(n: int) -> float:
    """gamma_n = n u / (1 - n u): the relative error bound of an n-term sum or product."""
    nu = n * UNIT_ROUNDOFF
    return nu / (1.0 - nu)


def sum_bound(n_terms: int, magnitude) -> np.ndarray:
    """Difference bound of two evaluations of the same n-term sum in different orders
    (with or without FMA): ``2 gamma_n * magnitude`` (magnitude: sum of |terms|)."""
    return 2.0 * gamma(n_terms) * np.asarray(magnitude, dtype=float)


def assert_same_arithmetic(actual, desired, what: str = "") -> None:
    """Bit-for-bit equality (NaN where NaN): both paths run the same operations in order."""
    np.testing.assert_array_equal(np.asarray(actual), np.asarray(desired), err_msg=what)


def assert_covariance_close(actual, desired, n_terms: int = 9, what: str = "") -> None:
    """Covariance stacks (..., k, k) equal to the rounding of an ``n_terms``-term sum per
    entry, scaled by ``sqrt(P_ii P_jj)`` (see the module notes); NaN where NaN."""
    a = np.asarray(actual, dtype=float)
    b = np.asarray(desired, dtype=float)
    assert a.shape == b.shape, (a.shape, b.shape)
    assert np.array_equal(np.isnan(a), np.isnan(b)), f"NaN pattern differs {what}"
    d = np.sqrt(np.abs(np.diagonal(b, axis1=-2, axis2=-1)))
    scale = d[..., :, None] * d[..., None, :]
    bound = sum_bound(n_terms, scale)
    ok = np.isnan(b) | (np.abs(a - b) <= bound)
    if not np.all(ok):
        excess = np.nanmax(np.abs(a - b) / np.where(bound > 0, bound, math.inf))
        raise AssertionError(f"covariances differ beyond {n_terms}-term rounding {what}: "
                             f"{np.count_nonzero(~ok)} entries, worst {excess:.3g} x the bound")
