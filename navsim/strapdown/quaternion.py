"""Quaternion attitude algorithms of seed 001 (Kononenko 2007) and their reference.

The attitude quaternion ``Lambda = [l0, l1, l2, l3]`` (Rodrigues-Hamilton parameters,
scalar first) of a body relative to an inertial frame obeys the kinematic equation

    Lambda' = 1/2 Phi(omega) Lambda = 1/2 Lambda o [0, omega]           (001 eqs. 2-4)

with ``omega`` the body rate in body axes; in navsim's notation ``Lambda = q_ib`` (or
``q_nb`` for a non-rotating n) and ``v_i = Lambda o v_b o conj(Lambda)``. Gyros deliver the
angle increments ``theta(n+1) = int_{nh}^{(n+1)h} omega dt``.

Algorithms
----------
:func:`matrizant_integrate`
    The matrizant power-series algorithm (8)-(9): on the double step ``H = 2h`` the
    matrizant ``F = f0 E4 + Phi(f)`` is expanded to fourth order from the two increments
    ``Theta_0``, ``Theta_1`` of the step, then ``P(t0 + H) = P(t0) o [f0, f]``.
:func:`reversible_integrate`
    The "reversible" Gauss-Seidel algorithm (11): Euler steps of (2) in which each
    component uses the components already updated on this step, the order of evaluation
    (1, 2, 3 on odd steps, 3, 2, 1 on even steps) alternating, and the scalar part
    restored from the unit norm.
:func:`rk4_integrate`
    The classical Runge-Kutta integration of (2) used by the paper as the "ideal"
    reference (step 1 ms).
:func:`error_angles`
    The error quaternion ``Delta = conj(Lambda) o P`` (13)-(14) and the small-angle
    heading, pitch and roll errors ``2 Delta_0 Delta_3``, ``2 Delta_0 Delta_2``,
    ``2 Delta_0 Delta_1``.

Corrections to the printed formulas
-----------------------------------
Derived from (2) and checked numerically. Evidence: maximum attitude error (rad) over
20 s of three-axis motion (rates 0.174, 0.174, 0.3 rad/s at 0.8, 1, 0.6 Hz) against RK4
at 0.5 ms, for h = 10, 5, 2.5 ms (``tests/strapdown/test_quaternion.py``):

=================  ==============================  ===========  ============
variant            errors at h = 10, 5, 2.5 ms     per halving  global order
=================  ==============================  ===========  ============
corrected          1.6e-9, 9.7e-11, 6.1e-12        16           h^4
printed-sign       2.4e-5, 5.9e-6, 1.5e-6          4            h^2
printed-f0         2.2e-6, 5.5e-7, 1.4e-7          4            h^2
printed-index      1.5e-3, 7.5e-4, 3.7e-4          2            h
printed (all)      1.5e-3, 7.5e-4, 3.7e-4          2            h
reversible (11)    8.7e-5, 4.3e-5, 2.2e-5          2            h
=================  ==============================  ===========  ============

1. **Sign of the coning term in f2 (8)** (``printed-sign``). The vector part of the
   matrizant is ``f = (1/2 - |Theta_0 + Theta_1|^2 / 48) (Theta_0 + Theta_1)
   + (1/3) Theta_0 x Theta_1``: the quaternion of the two-sample rotation vector
   ``Theta_0 + Theta_1 + (2/3) Theta_0 x Theta_1``. The printed y component of the cross
   product, ``theta_x0 theta_z1 - theta_x1 theta_z0``, has the wrong sign; it must be
   ``theta_z0 theta_x1 - theta_x0 theta_z1``.
2. **Index in Theta_0** (``printed-index``). ``Theta_0 = [theta_x0, theta_y0, theta_z1]``
   must read ``theta_z0``: Theta_0 is the increment over the first half of the double step.
3. **The scalar part f0** (``printed-f0``). The printed ``f0 = 1 - ||f_1||^2/2 -
   ||f_1||^4/8`` is the expansion of ``sqrt(1 - f.f)`` (the constraint (7)), so
   ``||f_1||^2`` there must be ``f.f``, the squared norm of the vector part just computed,
   about a quarter of the ``||f_1||^2 = |Theta_0 + Theta_1|^2`` defined under (8) and
   used (correctly) in the vector part. Taken literally, f0 is ``1 - phi^2/2`` instead of
   ``cos(phi/2) = 1 - phi^2/8 + ...``: the quaternion loses norm by ``3 phi^2/8`` per
   double step (2.2 % in the 200 s of the paper's test) and, even renormalised, the
   rotation angle is wrong at third order per step.

The paper's own test has ``C_z = 0``: theta_z vanishes and typos 1 and 2 are invisible.

The "reversible" algorithm is **first order**, not fifth as claimed: each step misses the
second-order term ``-|theta|^2 mu / 8`` of the exact update (with ``mu0`` taken from the
norm, the scalar-part coupling is an explicit Euler step; the alternation of the order
cancels only the Gauss-Seidel cross terms). In the paper's own test it produces a slow
linear drift of pitch and roll whose size matches the printed Table 1
(:mod:`navsim.paper.seed001`), while the correct matrizant algorithm is about five orders
of magnitude more accurate there.

References
----------
.. [1] Kononenko V.A. (2007), seed 001: eqs. (2)-(4) kinematics, (8)-(9) matrizant
       algorithm, (11) reversible algorithm, (12) test rates, (13)-(14) errors, Table 1.
.. [2] Panov A.P., Mathematical foundations of the theory of inertial navigation,
       Kiev, 1995 (the matrizant algorithm, ref. [7] of seed 001).
.. [3] Savage P.G., Strapdown Analytics, 2nd ed., 2007, ch. 7 (two-sample coning).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ConfigError

__all__ = [
    "omega_matrix",
    "matrizant_quaternion",
    "matrizant_integrate",
    "reversible_integrate",
    "rk4_integrate",
    "error_quaternion",
    "error_angles",
    "quat_cumulative_product",
]

_MATRIZANT_VARIANTS = ("corrected", "printed", "printed-sign", "printed-index", "printed-f0")


def omega_matrix(omega: ArrayLike) -> np.ndarray:
    """The 4x4 skew matrix Phi(omega) of 001 eq. (4), shape (..., 4, 4).

    ``Phi(omega) @ q`` equals the Hamilton product ``q o [0, omega]``.
    """
    w = np.asarray(omega, dtype=float)
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    zero = np.zeros_like(x)
    # (4) row by row as printed
    return np.stack(
        [
            np.stack([zero, -x, -y, -z], -1),
            np.stack([x, zero, z, -y], -1),
            np.stack([y, -z, zero, x], -1),
            np.stack([z, y, -x, zero], -1),
        ],
        axis=-2,
    )


def quat_cumulative_product(quat0: ArrayLike, dquat: ArrayLike, normalize: bool = False) -> np.ndarray:
    """Right-multiply a quaternion by a sequence of increments: ``q_{k+1} = q_k o dq_k``.

    Parameters
    ----------
    quat0 : array_like, shape (4,)
        Initial quaternion.
    dquat : array_like, shape (n, 4)
        Increment quaternions (need not be unit).
    normalize : bool
        Rescale to unit norm after every product.

    Returns
    -------
    ndarray, shape (n + 1, 4)
    """
    dq = np.asarray(dquat, dtype=float).tolist()
    a0, a1, a2, a3 = (float(x) for x in np.asarray(quat0, dtype=float))
    out = [(a0, a1, a2, a3)]
    append = out.append
    for b0, b1, b2, b3 in dq:
        a0, a1, a2, a3 = (
            a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
        )
        if normalize:
            s = (a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3) ** -0.5
            a0, a1, a2, a3 = a0 * s, a1 * s, a2 * s, a3 * s
        append((a0, a1, a2, a3))
    return np.array(out)


def matrizant_quaternion(theta0: ArrayLike, theta1: ArrayLike, variant: str = "corrected") -> np.ndarray:
    """The matrizant quaternion ``[f0, f]`` of one double step H = 2h, 001 eq. (8).

    Parameters
    ----------
    theta0, theta1 : array_like, shape (..., 3)
        Gyro increments (rad) over the first and the second half of the double step.
    variant : str
        ``"corrected"`` (default): the formulas derived from (2) (module notes).
        ``"printed"``: (8) literally, with all three typos. ``"printed-sign"``,
        ``"printed-index"``, ``"printed-f0"``: one typo each (the f2 sign, theta_z1 in
        Theta_0, the literal f0), for the evidence of each.

    Returns
    -------
    ndarray, shape (..., 4)
        ``[f0, f1, f2, f3]``, to fourth order in the increments.
    """
    if variant not in _MATRIZANT_VARIANTS:
        raise ConfigError("variant", f"one of {_MATRIZANT_VARIANTS}", variant)
    typo_sign = variant in ("printed", "printed-sign")
    typo_index = variant in ("printed", "printed-index")
    typo_f0 = variant in ("printed", "printed-f0")
    t0 = np.asarray(theta0, dtype=float)
    t1 = np.asarray(theta1, dtype=float)
    if typo_index:
        # Theta_0 = [theta_x0, theta_y0, theta_z1] as printed under (8)
        t0 = np.concatenate([t0[..., :2], t1[..., 2:]], axis=-1)
    total = t0 + t1
    total2 = np.sum(total * total, axis=-1)  # ||f_1||^2 defined under (8)
    x0, y0, z0 = t0[..., 0], t0[..., 1], t0[..., 2]
    x1, y1, z1 = t1[..., 0], t1[..., 1], t1[..., 2]
    # corrected: the y component of Theta_0 x Theta_1 is z0 x1 - x0 z1 (printed: x0 z1 - x1 z0)
    cross_y = x0 * z1 - x1 * z0 if typo_sign else z0 * x1 - x0 * z1
    cross = np.stack([y0 * z1 - y1 * z0, cross_y, x0 * y1 - x1 * y0], -1)
    f = (0.5 - total2 / 48.0)[..., None] * total + cross / 3.0  # (8) vector part
    if typo_f0:
        f0 = 1.0 - 0.5 * total2 - 0.125 * total2**2  # (8) f0, literal
    else:
        f2 = np.sum(f * f, axis=-1)
        f0 = 1.0 - 0.5 * f2 - 0.125 * f2**2  # (8) f0 = sqrt(1 - f.f) to 4th order, (7)
    return np.concatenate([f0[..., None], f], axis=-1)


def matrizant_integrate(quat0: ArrayLike, dtheta: ArrayLike, variant: str = "corrected") -> np.ndarray:
    """Integrate (2) with the matrizant algorithm (8)-(9) on double steps.

    Parameters
    ----------
    quat0 : array_like, shape (4,)
        Initial quaternion P(t_0).
    dtheta : array_like, shape (2 N, 3)
        Gyro increments over consecutive steps h (rad); pairs form the double steps.
    variant : {"corrected", "printed"}
        See :func:`matrizant_quaternion`.

    Returns
    -------
    ndarray, shape (N + 1, 4)
        P at t_0, t_0 + 2h, ..., t_0 + 2Nh. Not renormalised (the algorithm has no
        norm correction), so the norm shows the algorithm's consistency.
    """
    dtheta = np.asarray(dtheta, dtype=float)
    if dtheta.ndim != 2 or dtheta.shape[1] != 3 or dtheta.shape[0] % 2:
        raise ConfigError("dtheta", "an array of shape (2N, 3)", dtheta.shape)
    f = matrizant_quaternion(dtheta[0::2], dtheta[1::2], variant)
    # (9) P(t0 + H) = P(t0) o [f0, f]
    return quat_cumulative_product(quat0, f)


def reversible_integrate(quat0: ArrayLike, dtheta: ArrayLike, first_step_odd: bool = True) -> np.ndarray:
    """Integrate (2) with the reversible Gauss-Seidel algorithm (11).

    Parameters
    ----------
    quat0 : array_like, shape (4,)
        Initial quaternion M(t_0), unit norm, scalar part >= 0.
    dtheta : array_like, shape (n, 3)
        Angle per step (rad). The paper writes ``h omega(t0 + h)`` (the rate sampled at
        the end of the step); the gyro increment ``int omega dt`` over the step is the
        natural input of a strapdown system and is what navsim feeds by default.
    first_step_odd : bool
        Whether the first step uses the "odd" order (mu1, mu2, mu3, mu0) of (11).

    Returns
    -------
    ndarray, shape (n + 1, 4)

    Notes
    -----
    The scalar part is restored as ``sqrt(1 - |mu|^2)`` (11), which assumes
    ``mu0 >= 0``: rotations beyond 180 deg from the initial attitude are not
    representable. The algorithm is first order (see the module notes).
    """
    theta = np.asarray(dtheta, dtype=float)
    if theta.ndim != 2 or theta.shape[1] != 3:
        raise ConfigError("dtheta", "an array of shape (n, 3)", theta.shape)
    m0, m1, m2, m3 = (float(x) for x in np.asarray(quat0, dtype=float))
    out = [(m0, m1, m2, m3)]
    odd = first_step_odd
    for x, y, z in (0.5 * theta).tolist():
        if odd:  # (11) odd step: mu1, mu2, mu3, then mu0
            m1 = m1 + (x * m0 + z * m2 - y * m3)
            m2 = m2 + (x * m3 + y * m0 - z * m1)
            m3 = m3 + (y * m1 + z * m0 - x * m2)
        else:  # (11) even step: mu3, mu2, mu1, then mu0
            m3 = m3 + (y * m1 + z * m0 - x * m2)
            m2 = m2 + (x * m3 + y * m0 - z * m1)
            m1 = m1 + (x * m0 + z * m2 - y * m3)
        m0 = max(0.0, 1.0 - m1 * m1 - m2 * m2 - m3 * m3) ** 0.5  # (11) norm correction
        out.append((m0, m1, m2, m3))
        odd = not odd
    return np.array(out)


def rk4_integrate(
    rate_fn: Callable[[np.ndarray], np.ndarray], quat0: ArrayLike, t0: float, step: float, n_steps: int
) -> np.ndarray:
    """Classical Runge-Kutta (RK4) integration of 001 eq. (3), the paper's reference.

    Because (3) is linear, one RK4 step is the 4x4 matrix
    ``M = E + s/6 (K1 + 2 K2 + 2 K3 + K4)`` with ``K1 = A(t)``,
    ``K2 = A(t + s/2) (E + s/2 K1)``, ``K3 = A(t + s/2) (E + s/2 K2)``,
    ``K4 = A(t + s) (E + s K3)``, ``A = Phi(omega)/2``; the matrices of all steps are
    formed at once and only the products are sequential.

    Parameters
    ----------
    rate_fn : callable
        ``rate_fn(t) -> omega``: body rate (rad/s), t of shape (k,) -> shape (k, 3).
    quat0 : array_like, shape (4,)
    t0, step : float
        Start time and step (s).
    n_steps : int

    Returns
    -------
    ndarray, shape (n_steps + 1, 4)
        The quaternion at ``t0 + k step``; global error O(step^4).
    """
    t = t0 + step * np.arange(n_steps)
    a1 = 0.5 * omega_matrix(rate_fn(t))
    a2 = 0.5 * omega_matrix(rate_fn(t + 0.5 * step))
    a4 = 0.5 * omega_matrix(rate_fn(t + step))
    eye = np.eye(4)
    k1 = a1
    k2 = a2 @ (eye + 0.5 * step * k1)
    k3 = a2 @ (eye + 0.5 * step * k2)
    k4 = a4 @ (eye + step * k3)
    step_mats = eye + step / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    out = np.empty((n_steps + 1, 4))
    out[0] = np.asarray(quat0, dtype=float)
    q = out[0]
    for k in range(n_steps):
        q = step_mats[k] @ q
        out[k + 1] = q
    return out


def error_quaternion(quat_ref: ArrayLike, quat: ArrayLike) -> np.ndarray:
    """``Delta = conj(Lambda) o P`` of 001 eq. (13)-(14), shape (..., 4)."""
    lam = np.asarray(quat_ref, dtype=float)
    p = np.asarray(quat, dtype=float)
    l0, lv = lam[..., :1], lam[..., 1:]
    p0, pv = p[..., :1], p[..., 1:]
    d0 = l0 * p0 + np.sum(lv * pv, axis=-1, keepdims=True)  # (14)
    dv = l0 * pv - p0 * lv - np.cross(lv, pv)  # (14)
    return np.concatenate([d0, dv], axis=-1)


def error_angles(quat_ref: ArrayLike, quat: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Small-angle heading, pitch and roll errors (rad) of 001, after (14).

    ``d_psi = 2 D0 D3`` (about z, vertical), ``d_theta = 2 D0 D2`` (about y,
    transverse), ``d_gamma = 2 D0 D1`` (about x, longitudinal), with ``D`` the error
    quaternion :func:`error_quaternion`. The paper's body axes are x longitudinal,
    y transverse, z vertical.
    """
    d = error_quaternion(quat_ref, quat)
    return 2.0 * d[..., 0] * d[..., 3], 2.0 * d[..., 0] * d[..., 2], 2.0 * d[..., 0] * d[..., 1]
