"""True multiple integrals of seed 000, eq. (1.14): Gauss-Legendre rules for all orders at once
(:func:`multiple_integral_rule`), their composition over a step (:func:`compose_multiple_integrals`),
the closed form of a harmonic (:func:`harmonic_multiple_integrals`) and the covariance of the R
integrals of white noise, ``q h^(i+j-1) / ((i+j-1) (i-1)! (j-1)!)``
(:func:`white_noise_integral_covariance`). See :mod:`navsim.sensors.imu`.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import cholesky, hilbert

from ...errors import ConfigError

MAX_ORDER = 8
"""Largest number R of multiple-integral orders the error model handles."""

_SERIES_RADIUS = 3.0  # |i omega h| below which the phi functions use their power series


def check_int(name: str, value: Any, low: int, high: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ConfigError(name, "an integer", value)
    if value < low or (high is not None and value > high):
        expect = f"an integer >= {low}" if high is None else f"an integer in [{low}, {high}]"
        raise ConfigError(name, expect, value)
    return int(value)


def check_h(h: Any) -> float:
    try:
        value = float(h)
    except (TypeError, ValueError):
        raise ConfigError("h", "a positive sample length in s", h) from None
    if not (0.0 < value < math.inf):
        raise ConfigError("h", "a positive finite sample length in s", h)
    return value


def multiple_integral_rule(
    n_nodes: int = 4, order: int = 4
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gauss-Legendre rule for the r-fold integrals (1.14) over one sample.

    By Cauchy's formula the r-fold integral of ``g`` over ``[t_k, t_k + h]`` is
    ``h^r int_0^1 (1 - s)^(r-1) / (r-1)! g(t_k + s h) ds``; the rule applies the
    Gauss-Legendre nodes of ``[0, 1]`` to that integrand, so::

        I_r ~= h^r * sum_j weights[r-1, j] * g(t_k + nodes[j] * h)

    which is exact when ``g`` is a polynomial of degree ``<= 2 n_nodes - r``. The error
    on a harmonic of angular frequency ``omega`` scales as ``(omega h)^(2 n_nodes - r + 1)``;
    measured worst relative errors for R = 4 (order 1 .. 4):

    ==========  ===================  ===================  ===================
    omega h     n_nodes = 4          n_nodes = 5          n_nodes = 6
    ==========  ===================  ===================  ===================
    0.063       7e-16 .. 7.5e-13     ~1e-15               ~1e-15
    0.2         2e-15 .. 2.4e-10     6e-16 .. 1.5e-14     ~1e-15
    0.8         1e-10 .. 2.5e-7      4e-14 .. 2.4e-10     1e-15 .. 1.4e-13
    ==========  ===================  ===================  ===================

    so for machine precision on the higher orders use ``n_nodes >= R + 2`` (6 for R = 4)
    when the motion has content up to ``omega h ~ 0.2``.

    Parameters
    ----------
    n_nodes : int
        Number of nodes per sample (>= 1).
    order : int
        Number R of integral orders (1 <= R <= ``MAX_ORDER``).

    Returns
    -------
    nodes : ndarray, shape (n_nodes,)
        Fractions ``tau_j`` of the sample, in (0, 1), increasing.
    weights : ndarray, shape (order, n_nodes)
        ``weights[r-1, j] = w_j (1 - tau_j)^(r-1) / (r-1)!``.
    """
    n_nodes = check_int("n_nodes", n_nodes, 1)
    order = check_int("order", order, 1, MAX_ORDER)
    x, w = np.polynomial.legendre.leggauss(n_nodes)
    nodes = 0.5 * (x + 1.0)
    w01 = 0.5 * w
    r_minus_1 = np.arange(order)
    inv_fact = 1.0 / np.array([math.factorial(k) for k in r_minus_1], dtype=float)
    # (1.14) via Cauchy: kernel (1 - s)^(r-1) / (r-1)!
    weights = w01[None, :] * (1.0 - nodes)[None, :] ** r_minus_1[:, None] * inv_fact[:, None]
    return nodes, weights


def apply_multiple_integral_rule(
    values: ArrayLike, h: float, weights: ArrayLike
) -> NDArray[np.float64]:
    """Multiple integrals from the values of ``g`` at the nodes of each sample.

    Parameters
    ----------
    values : array_like, shape (n, n_nodes, 3)
        ``g(t_k + nodes[j] h)`` for each sample ``k`` (units of g).
    h : float
        Sample length, s.
    weights : array_like, shape (R, n_nodes)
        From :func:`multiple_integral_rule`.

    Returns
    -------
    ndarray, shape (n, R, 3)
        ``I_r`` in units of g times s^r.
    """
    h = check_h(h)
    values = np.asarray(values, dtype=float)
    weights = np.asarray(weights, dtype=float)
    if values.ndim != 3 or weights.ndim != 2 or values.shape[1] != weights.shape[1]:
        raise ConfigError(
            "values", f"shape (n, {weights.shape[-1]}, 3) matching weights", values.shape
        )
    h_pow = h ** np.arange(1, weights.shape[0] + 1)
    return np.einsum("rj,nja->nra", weights * h_pow[:, None], values)


def compose_multiple_integrals(sub: ArrayLike, h: float) -> NDArray[np.float64]:
    """Multiple integrals over a step of ``m`` consecutive samples, from per-sample ones.

    With the step ending at ``T = t_0 + m h`` and sample ``j`` ending at
    ``e_j = t_0 + (j + 1) h``, the binomial expansion of the Cauchy kernel
    ``(T - tau)^(r-1) / (r-1)! = sum_q (e_j - tau)^(q-1)/(q-1)! d_j^(r-q)/(r-q)!`` with
    ``d_j = T - e_j`` gives the exact relation::

        I_r(step) = sum_j sum_{q=1..r} I_q(sample j) d_j^(r-q) / (r-q)!

    Parameters
    ----------
    sub : array_like, shape (n, m, R, 3)
        Per-sample r-fold integrals of ``n`` steps of ``m`` samples each.
    h : float
        Sample length, s.

    Returns
    -------
    ndarray, shape (n, R, 3)
        The r-fold integrals over each step of length ``m h``.
    """
    h = check_h(h)
    sub = np.asarray(sub, dtype=float)
    if sub.ndim != 4 or sub.shape[-1] != 3 or sub.shape[1] < 1:
        raise ConfigError("sub", "shape (n, m, R, 3) with m >= 1", sub.shape)
    m, order = sub.shape[1], sub.shape[2]
    d = (m - 1 - np.arange(m)) * h  # distance from each sample end to the step end
    k = np.arange(order)[:, None] - np.arange(order)[None, :]  # r - q (0-based)
    k_pos = np.maximum(k, 0)
    inv_fact = 1.0 / np.array([math.factorial(int(v)) for v in k_pos.ravel()]).reshape(k.shape)
    coeff = np.where(k >= 0, d[:, None, None] ** k_pos[None] * inv_fact[None], 0.0)
    return np.einsum("jrq,njqa->nra", coeff, sub)


def _phi_functions(z: complex, order: int) -> NDArray[np.complex128]:
    """``J_r(z) = int_0^1 s^(r-1)/(r-1)! exp(-z s) ds`` for r = 1..order.

    Power series for ``|z| <= 3`` (no cancellation: the largest term is ~ the first),
    else the upward recurrence ``J_1 = (1 - e^-z)/z``, ``J_{r+1} = (J_r - e^-z / r!)/z``
    (integration by parts), which is stable for ``|z| > r``-ish and loses at most ~1
    digit at the switch-over for ``order <= 8``.
    """
    out = np.empty(order, dtype=complex)
    if abs(z) <= _SERIES_RADIUS:
        k = np.arange(60)
        pow_term = np.cumprod(np.concatenate(([1.0 + 0j], np.full(59, -z)))) / np.array(
            [math.factorial(int(i)) for i in k], dtype=float
        )  # (-z)^k / k!
        for r in range(1, order + 1):
            out[r - 1] = np.sum(pow_term / (k + r)) / math.factorial(r - 1)
    else:
        ez = np.exp(-z)
        out[0] = (1.0 - ez) / z
        for r in range(1, order):
            out[r] = (out[r - 1] - ez / math.factorial(r)) / z
    return out


def harmonic_multiple_integrals(
    amplitude: float,
    frequency_hz: float,
    phase: float,
    t0: ArrayLike,
    h: float,
    order: int,
) -> NDArray[np.float64]:
    """Closed-form r-fold integrals (1.14) of ``A sin(2 pi f t + phase)`` over samples.

    With ``omega = 2 pi f`` and ``u = t0 + h - tau``::

        I_r = Im[ A exp(i (omega (t0 + h) + phase)) h^r J_r(i omega h) ],
        J_r(z) = int_0^1 s^(r-1) / (r-1)! exp(-z s) ds

    Parameters
    ----------
    amplitude : float
        ``A`` (any unit).
    frequency_hz : float
        ``f``, Hz (0 gives the constant ``A sin(phase)``).
    phase : float
        rad.
    t0 : array_like, shape (n,)
        Sample start times, s.
    h : float
        Sample length, s.
    order : int
        Number R of orders.

    Returns
    -------
    ndarray, shape (n, order)
        ``I_r`` in units of A times s^r.
    """
    h = check_h(h)
    order = check_int("order", order, 1, 64)
    t0 = np.atleast_1d(np.asarray(t0, dtype=float))
    omega = 2.0 * math.pi * float(frequency_hz)
    j_r = _phi_functions(1j * omega * h, order)
    h_pow = h ** np.arange(1, order + 1)
    carrier = np.exp(1j * (omega * (t0 + h) + float(phase)))
    return float(amplitude) * np.imag(carrier[:, None] * (h_pow * j_r)[None, :])


@lru_cache(maxsize=None)
def unit_noise_factor(order: int) -> NDArray[np.float64]:
    """Cholesky factor of ``C_ij = 1 / ((i+j-1) (i-1)! (j-1)!)`` (q = h = 1)."""
    inv_fact = 1.0 / np.array([math.factorial(i) for i in range(order)], dtype=float)
    # C = D H D with H the Hilbert matrix, D = diag(1/(i-1)!): chol(C) = D chol(H)
    factor = inv_fact[:, None] * cholesky(hilbert(order), lower=True)
    factor.setflags(write=False)
    return factor


def white_noise_integral_covariance(psd: float, h: float, order: int) -> NDArray[np.float64]:
    """Covariance of the r-fold integrals (r = 1..R) of white noise over one sample.

    ``Cov(I_i, I_j) = q h^(i+j-1) / ((i+j-1) (i-1)! (j-1)!)``, from
    ``I_r = int_0^h u^(r-1)/(r-1)! w dtau`` and ``E[w(t) w(s)] = q delta(t - s)``.

    Parameters
    ----------
    psd : float
        ``q``, e.g. (rad/s)^2/Hz = ARW^2.
    h : float
        Sample length, s.
    order : int
        R.

    Returns
    -------
    ndarray, shape (R, R)
    """
    h = check_h(h)
    order = check_int("order", order, 1, MAX_ORDER)
    i = np.arange(1, order + 1)
    s = i[:, None] + i[None, :] - 1
    fact = np.array([math.factorial(k) for k in range(order)], dtype=float)
    return psd * h**s / (s * fact[:, None] * fact[None, :])
