"""Numerical building blocks of the seed-003 filter: the polynomial input model and the Riccati RK4.

* :func:`input_polynomial_matrix`: the polynomial of degree R-1 whose r-fold integrals are
  the step's increments (seed 000 eq. (1.14), Cauchy's formula for repeated integrals).
* :func:`riccati_rk4`, :func:`riccati_rk4_h`: one RK4 step of the Riccati equation of the
  continuous filter (14) of seed 003 with frozen coefficients, in the direct form
  ``R' = A R + R A^T + Q - (R h + S)(R h + S)^T / sigma^2`` and as ``R' = [R; I]^T H [R; I]``
  (equal to rounding).
* :func:`check_rows`, :func:`check_covariance`: the divergence checks (non-finite values or a
  negative variance raise FloatingPointError).
* :data:`CSTEP`: the complex-step size of the phi-derivatives (Martins et al. 2003).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

__all__ = ["CSTEP", "cross", "input_polynomial_matrix", "riccati_rk4", "riccati_rk4_h", "check_rows",
           "check_covariance"]

CSTEP = 1e-20  # complex-step size, rad


def input_polynomial_matrix(orders: int) -> np.ndarray:
    """M^-1 for the polynomial input model: ``c = M^-1 [I_r / dt^r]``, shape (R, R).

    A signal ``g(t0 + s dt) = sum_j c_j s^j`` (j < R) has the r-fold integrals (seed 000
    eq. (1.14), Cauchy's formula) ``I_r = dt^r sum_j c_j j! / (j + r)!``; M holds those
    factors, so the inversion recovers the unique degree R-1 polynomial with the given
    increments (exact for signals that are such polynomials).
    """
    R = int(orders)
    m = np.array([[math.factorial(j) / math.factorial(j + r) for j in range(R)] for r in range(1, R + 1)])
    return np.linalg.inv(m)


def cross(u: Sequence[float], v: Sequence[float]) -> tuple[float, float, float]:
    return (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])


def riccati_rk4(P: np.ndarray, A: np.ndarray, hneg: np.ndarray, Q: np.ndarray, s: np.ndarray, sig2: float,
                tau: float) -> np.ndarray:
    """RK4 of R' = A R + R A^T + Q - (R h + S)(R h + S)^T / sigma^2 (14), frozen coefficients.

    Written with few numpy calls (each costs microseconds on 5 x 5 matrices).
    """
    h = -hneg
    inv = 1.0 / sig2
    multiply_outer = np.multiply.outer

    def rhs(R: np.ndarray) -> np.ndarray:
        AR = A @ R
        AR += AR.T
        AR += Q
        M = R @ h
        M += s
        AR -= multiply_outer(M, M * inv)
        return AR

    k1 = rhs(P)
    k2 = rhs(P + (0.5 * tau) * k1)
    k3 = rhs(P + (0.5 * tau) * k2)
    k4 = rhs(P + tau * k3)
    k2 += k3
    k2 *= 2.0
    k2 += k1
    k2 += k4
    k2 *= tau / 6.0
    k2 += P
    k2 += k2.T
    k2 *= 0.5
    return k2


def riccati_rk4_h(P: np.ndarray, H: np.ndarray, tau: float, work: tuple[np.ndarray, ...]) -> np.ndarray:
    """RK4 of (14)'s Riccati equation written as R' = [R; I]^T H [R; I] (frozen H).

    The same step as :func:`riccati_rk4` (equal to rounding) in fewer and cheaper numpy
    calls (each costs about a microsecond on these small matrices, more than its
    arithmetic): two ``np.dot`` per stage into work arrays, H pre-scaled by tau/2 so that a
    stage returns m_j = tau/2 k_j. ``work = (Z, top, Zt, HZ, m1, m2, m3, m4)`` from
    :meth:`PaperEkf._riccati_layout`: Z (2n, n) with the identity in its lower half and the
    stage's R written into its upper half ``top``, Zt its transpose (views made once).
    Returns a new array.
    """
    Z, top, Zt, HZ, m1, m2, m3, m4 = work
    dot, add = np.dot, np.add
    Hh = H * (0.5 * tau)
    np.copyto(top, P)
    dot(Hh, Z, HZ)
    dot(Zt, HZ, m1)
    add(P, m1, top)
    dot(Hh, Z, HZ)
    dot(Zt, HZ, m2)
    add(P, m2, top)
    dot(Hh, Z, HZ)
    dot(Zt, HZ, m3)
    add(m3, m3, top)
    add(top, P, top)
    dot(Hh, Z, HZ)
    dot(Zt, HZ, m4)
    add(m2, m3, m2)
    add(m2, m2, m2)
    add(m2, m1, m2)
    add(m2, m4, m2)  # tau/2 (k1 + 2 k2 + 2 k3 + k4)
    out = add(m2, m2.T)
    np.multiply(out, 1.0 / 6.0, out)
    add(out, P, out)  # P + tau/6 (...), symmetrised
    return out


def check_rows(rows: Sequence[Sequence[float]]) -> None:
    """:func:`check_covariance` on P.tolist() (the rows are needed for the gain anyway)."""
    if not (math.isfinite(sum(map(sum, rows))) and min([r[i] for i, r in enumerate(rows)]) >= 0.0):
        raise FloatingPointError("non-finite or indefinite covariance")


def check_covariance(P: np.ndarray) -> None:
    """Raise FloatingPointError when P is non-finite or has a negative diagonal."""
    d = P.diagonal()
    if not (math.isfinite(float(P.sum())) and float(d.min()) >= 0.0):
        raise FloatingPointError("non-finite or indefinite covariance")
