"""Closed-form increments of the seed-000 test motions against numerical quadrature."""

from __future__ import annotations

from math import factorial

import numpy as np
import pytest
from scipy.integrate import quad

from navsim.rotations import quat_conjugate, quat_multiply
from navsim.strapdown.motion_models import (
    Signal,
    coning_motion,
    coning_quaternion,
    phi_functions,
    polynomial_motion,
    sculling_motion,
)


def _signal():
    return Signal(
        poly=np.array([[0.2, -0.1, 0.3], [0.05, 0.4, -0.2], [0.3, 0.0, 0.1]]),
        freqs=np.array([0.7, 9.0, 60.0]),
        amps=np.array([[0.5, 0.2j, 0.1], [0.3 * np.exp(1j), 0.0, -0.4], [0.0, 0.05, 0.02j]]),
    )


@pytest.mark.parametrize("dt", [0.01, 0.3, 2.0])
def test_multiple_integrals_against_quad(dt):
    sig = _signal()
    t0 = 1.234
    got = sig.multiple_integrals(np.array([t0]), dt, 4)[0]
    for r in range(1, 5):
        for axis in range(3):
            def integrand(tau, r=r, axis=axis):
                return (t0 + dt - tau) ** (r - 1) / factorial(r - 1) * sig.value(np.array([tau]))[0, axis]

            ref, _ = quad(integrand, t0, t0 + dt, epsabs=0, epsrel=1e-13, limit=200)
            assert got[r - 1, axis] == pytest.approx(ref, rel=1e-10, abs=1e-14 * dt**r)


def test_phi_functions_branches_agree():
    # both branches near |z| = 1 and the defining recurrence phi_{r-1} = 1/(r-1)! + z phi_r
    z = np.array([0.999j, 1.001j, 0.5 + 0.5j, 3j, 20j])
    phi = phi_functions(z, 5)
    for r in range(2, 6):
        np.testing.assert_allclose(phi[:, r - 2], 1.0 / factorial(r - 1) + z * phi[:, r - 1], rtol=1e-13)
    np.testing.assert_allclose(phi[:, 0], (np.exp(z) - 1) / z, rtol=1e-13)


def test_sub_increments_sum_to_first_integral():
    sig = _signal()
    t0 = np.array([0.0, 0.5, 3.0])
    sub = sig.sub_increments(t0, 0.2, 3)
    np.testing.assert_allclose(sub.sum(axis=1), sig.multiple_integrals(t0, 0.2, 1)[:, 0], rtol=1e-13, atol=1e-16)


def test_derivative_against_finite_differences():
    sig = _signal()
    t = np.array([0.77])
    h = 1e-5
    for order in range(3):
        fd = (sig.derivative(t + h, order) - sig.derivative(t - h, order)) / (2 * h)
        np.testing.assert_allclose(sig.derivative(t, order + 1), fd, rtol=1e-6, atol=1e-6)


def test_coning_rate_is_the_body_rate_of_the_coning_attitude():
    alpha, rate = 0.3, 2.0
    motion = coning_motion(alpha, rate)
    t = np.array([0.1, 0.9, 2.5])
    h = 1e-6
    q = coning_quaternion(alpha, rate, t)
    q_dot = (coning_quaternion(alpha, rate, t + h) - coning_quaternion(alpha, rate, t - h)) / (2 * h)
    omega_b = 2.0 * quat_multiply(quat_conjugate(q), q_dot)[:, 1:]  # q_dot = 1/2 q * omega
    np.testing.assert_allclose(motion.omega.value(t), omega_b, atol=1e-8)


def test_exact_coning_integral_closed_form():
    # z component of (1.12) for coning: 1/2 sin^2(a) (W T - sin W T), any t_k
    alpha, rate, dt = 0.2, 3.0, 0.4
    motion = coning_motion(alpha, rate)
    got = motion.exact_coning(np.array([0.0, 1.1]), dt)[:, 2]
    expected = 0.5 * np.sin(alpha) ** 2 * (rate * dt - np.sin(rate * dt))
    np.testing.assert_allclose(got, expected, rtol=1e-13)


def test_exact_sculling_against_nested_quad():
    motion = sculling_motion(0.1, 2.0, 5.0)
    t0, dt = 0.3, 0.7

    def integrand(t):
        angle = motion.omega.integral(np.array([t0]), np.array([t]))[0]
        return np.cross(angle, motion.accel.value(np.array([t]))[0])[2]

    ref, _ = quad(integrand, t0, t0 + dt, epsabs=0, epsrel=1e-13)
    assert motion.exact_sculling(np.array([t0]), dt)[0, 2] == pytest.approx(ref, rel=1e-11)
    # (5.4): the (T - tau) weighted version
    ref_s, _ = quad(lambda t: (t0 + dt - t) * integrand(t), t0, t0 + dt, epsabs=0, epsrel=1e-13)
    assert motion.exact_partial_displacement(np.array([t0]), dt)[0, 2] == pytest.approx(ref_s, rel=1e-11)


def test_polynomial_multiple_integrals_are_beta_integrals():
    # omega = t^p/p! from t_k = 0: r-fold integral over [0, T] = T^(p+r)/(p+r)!
    for p in range(4):
        taylor = np.zeros((p + 1, 3))
        taylor[p] = [1.0, 2.0, 3.0]
        motion = polynomial_motion(taylor)
        got = motion.omega.multiple_integrals(np.array([0.0]), 0.7, 3)[0]
        for r in range(1, 4):
            np.testing.assert_allclose(got[r - 1], taylor[p] * 0.7 ** (p + r) / factorial(p + r), rtol=1e-14)
