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


# ----------------------------------------------------------- elementary functions
# NumPy evaluates its float64 transcendental ufuncs with its own SIMD code on some CPUs
# (AVX-512: arctan2, arcsin, arccos, exp, log, tan, sinh, cosh, ...), with the C library's
# functions elsewhere; Python's ``math``/``cmath`` and numba's compiled code call the C
# library. Two paths that run the same operations but take such a function from different
# sides (an estimator's one-step path in ``math`` or numba, its batch in NumPy) then agree
# only to the accuracy of the two implementations: each is within 1 ulp of the exact
# value (glibc's documented bounds for these functions; NumPy's AVX-512 code targets
# 1 ulp as well), so their results differ by at most 2 ulps of the result, plus what an
# ulp of the input becomes through the function. Where NumPy's results are the C
# library's (probed below on a fixed sample), the same comparisons are bit for bit.
_PROBED = ("arctan2", "arcsin", "arccos", "arctan", "exp", "log", "tan", "sinh", "cosh")


def numpy_matches_libm() -> bool:
    """Whether NumPy's float64 ``arctan2, arcsin, arccos, arctan, exp, log, tan, sinh,
    cosh`` give the C library's (``math``'s) results on a fixed sample of 4096 values."""
    global _MATCH
    if _MATCH is None:
        rng = np.random.default_rng(20261202)
        x = rng.uniform(-3.0, 3.0, 4096)
        y = rng.uniform(-3.0, 3.0, 4096)
        u = x / 3.0
        p = np.abs(x) + 1e-3
        pairs = [(np.arctan2(x, y), [math.atan2(a, b) for a, b in zip(x.tolist(), y.tolist())]),
                 (np.arcsin(u), [math.asin(a) for a in u.tolist()]),
                 (np.arccos(u), [math.acos(a) for a in u.tolist()]),
                 (np.arctan(x), [math.atan(a) for a in x.tolist()]),
                 (np.exp(x), [math.exp(a) for a in x.tolist()]),
                 (np.log(p), [math.log(a) for a in p.tolist()]),
                 (np.tan(u), [math.tan(a) for a in u.tolist()]),
                 (np.sinh(x), [math.sinh(a) for a in x.tolist()]),
                 (np.cosh(x), [math.cosh(a) for a in x.tolist()])]
        _MATCH = all(np.array_equal(a, np.array(b)) for a, b in pairs)
    return _MATCH


_MATCH: bool | None = None


def assert_same_but_elementary(actual, desired, scale, ulps: float = 4.0, what: str = "") -> None:
    """Bit for bit where NumPy's transcendental functions are the C library's
    (:func:`numpy_matches_libm`); otherwise ``|actual - desired| <= ulps * eps * scale``,
    with ``scale`` the magnitude of the quantity the differing function produced (pi for an
    angle from ``arctan2``/``arcsin``; 1 for a direction-cosine entry); NaN where NaN.
    The caller states which function differs and why the difference does not propagate."""
    a = np.asarray(actual, dtype=float)
    b = np.asarray(desired, dtype=float)
    if numpy_matches_libm():
        np.testing.assert_array_equal(a, b, err_msg=what)
        return
    assert a.shape == b.shape, (a.shape, b.shape, what)
    assert np.array_equal(np.isnan(a), np.isnan(b)), f"NaN pattern differs {what}"
    bound = ulps * EPS * np.asarray(scale, dtype=float)
    d = np.abs(a - b)
    ok = np.isnan(b) | (d <= bound)
    if not np.all(ok):
        raise AssertionError(f"{what}: {np.count_nonzero(~ok)} values differ beyond {ulps:g} ulps of the scale; "
                             f"largest difference {np.nanmax(d):.3g}")


def assert_same_field(actual, desired, field: str) -> None:
    """An episode-record field from two paths of an estimator that share every state and
    update computation: bit for bit, except the attitude angles ``est_hpr``, which the
    one-step path extracts with the C library's ``atan2``/``asin`` (``math``, numba) and the
    batch path with NumPy's: to :func:`assert_same_but_elementary` with scale pi (each angle
    is one function of the same attitude and feeds no state)."""
    if field == "est_hpr":
        assert_same_but_elementary(actual, desired, math.pi, what=field)
    else:
        assert_same_arithmetic(actual, desired, field)


def assert_same_solution(actual, desired, what: str = "") -> None:
    """(n, 9) solutions ``[lat, lon, h, vE, vN, vU, heading, pitch, roll]`` of two such
    paths: position and velocity bit for bit, the angles as in :func:`assert_same_field`."""
    a = np.asarray(actual, dtype=float)
    b = np.asarray(desired, dtype=float)
    assert a.shape == b.shape and a.shape[-1] == 9, (a.shape, b.shape)
    assert_same_arithmetic(a[..., :6], b[..., :6], f"{what} position, velocity")
    assert_same_but_elementary(a[..., 6:], b[..., 6:], math.pi, what=f"{what} heading, pitch, roll")
