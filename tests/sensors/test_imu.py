"""Tests of navsim.sensors.imu: multiple integrals and the truth-side IMU error model."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from navsim.errors import ConfigError
from navsim.sensors import imu
from navsim.sensors.imu import (
    ImuErrorModel,
    ImuState,
    SensorErrors,
    VibrationHarmonic,
    apply_imu_errors,
    compose_multiple_integrals,
    harmonic_multiple_integrals,
    imu_preset,
    multiple_integral_rule,
)

# ------------------------------------------------------------------ helpers


def exact_poly_integrals(coeffs, t0: Fraction, h: Fraction, order: int) -> list[Fraction]:
    """Exact r-fold integrals (1.14) of sum_p c_p t^p over [t0, t0 + h], in rationals.

    g(t0 + s h) = sum_k d_k s^k and int_0^1 (1-s)^(r-1)/(r-1)! s^k ds = k!/(k+r)!.
    """
    deg = len(coeffs) - 1
    d = [Fraction(0)] * (deg + 1)
    for p, c in enumerate(coeffs):
        for k in range(p + 1):
            d[k] += c * math.comb(p, k) * t0 ** (p - k) * h**k
    return [
        h**r * sum(dk * Fraction(math.factorial(k), math.factorial(k + r)) for k, dk in enumerate(d))
        for r in range(1, order + 1)
    ]


def poly_eval(coeffs, t):
    return sum(float(c) * t**p for p, c in enumerate(coeffs))


def smooth_truth(n: int, h: float, order: int, t0: float = 0.0):
    """True multiple integrals of a smooth test motion (harmonics), to machine precision."""
    t_start = t0 + h * np.arange(n)
    dtheta = np.zeros((n, order, 3))
    dv = np.zeros((n, order, 3))
    omega = np.zeros((n, 3))
    f = np.zeros((n, 3))
    specs = [(0.3, 0.7, 0.1), (0.2, 1.1, 1.0), (0.1, 0.4, 2.0)]
    for axis, (a, freq, ph) in enumerate(specs):
        dtheta[:, :, axis] = harmonic_multiple_integrals(a, freq, ph, t_start, h, order)
        omega[:, axis] = a * np.sin(2 * np.pi * freq * (t_start + h) + ph)
        dv[:, :, axis] = harmonic_multiple_integrals(2 * a, freq * 1.3, ph + 0.5, t_start, h, order)
        f[:, axis] = 2 * a * np.sin(2 * np.pi * freq * 1.3 * (t_start + h) + ph + 0.5)
    # gravity-like constant on z: constant c has r-fold integral c h^r / r!
    hr = np.array([h**r / math.factorial(r) for r in range(1, order + 1)])
    dv[:, :, 2] += 9.8 * hr
    f[:, 2] += 9.8
    return t_start, dtheta, dv, omega, f


def run(model, n, h=0.01, order=4, seed=1, state=None, t0=0.0, truth=None):
    rng = np.random.default_rng(seed)
    if state is None:
        state = ImuState.initial(model, rng)
    truth = truth if truth is not None else smooth_truth(n, h, order, t0)
    out, new_state = apply_imu_errors(*truth[:1], h, *truth[1:], model, state, rng)
    return out, new_state, rng


# ------------------------------------------------------------------ multiple integrals


@pytest.mark.parametrize("n_nodes", [1, 2, 3, 4, 5])
def test_rule_exact_for_polynomials_of_degree_2n_minus_r(n_nodes):
    order = 4
    nodes, weights = multiple_integral_rule(n_nodes, order)
    assert nodes.shape == (n_nodes,) and weights.shape == (order, n_nodes)
    assert np.all((nodes > 0) & (nodes < 1))
    rng = np.random.default_rng(n_nodes)
    t0, h = Fraction(7, 10), Fraction(1, 50)
    for r in range(1, order + 1):
        degree = 2 * n_nodes - r
        if degree < 0:
            continue
        coeffs = [Fraction(int(v), 7) for v in rng.integers(-20, 21, degree + 1)]
        exact = float(exact_poly_integrals(coeffs, t0, h, order)[r - 1])
        g = poly_eval(coeffs, float(t0) + nodes * float(h))
        approx = float(h) ** r * np.dot(weights[r - 1], g)
        assert abs(approx - exact) <= 1e-12 * abs(exact), (r, approx, exact)


def test_rule_not_exact_one_degree_higher():
    """The degree bound 2 n - r is sharp: a monomial one degree higher is not integrated."""
    nodes, weights = multiple_integral_rule(3, 2)
    t0, h = Fraction(0), Fraction(1)
    coeffs = [Fraction(0)] * 5 + [Fraction(1)]  # t^5, degree 2*3 - 2 + 1
    exact = float(exact_poly_integrals(coeffs, t0, h, 2)[1])
    approx = np.dot(weights[1], nodes**5)
    assert abs(approx - exact) > 1e-6 * abs(exact)


def test_rule_matches_paper_linear_model():
    """Seed 000 after (3.4): for omega = A + B tau, dTheta^2 = A T^2/2 + B T^3/6."""
    nodes, weights = multiple_integral_rule(2, 3)
    A, B, T = 0.3, -1.7, 0.05
    values = (A + B * nodes * T)[None, :, None] * np.ones((1, 1, 3))
    got = imu.apply_multiple_integral_rule(values, T, weights)[0, :, 0]
    expect = [A * T + B * T**2 / 2, A * T**2 / 2 + B * T**3 / 6, A * T**3 / 6 + B * T**4 / 24]
    np.testing.assert_allclose(got, expect, rtol=1e-14)


@pytest.mark.parametrize("freq_hz, n_nodes", [(0.37, 6), (3.0, 7), (12.5, 8)])
def test_rule_on_harmonic_rate(freq_hz, n_nodes):
    """The rule is machine-precise on harmonic rates once (omega h)^(2n-R+1)/(2n-R+1)! << eps."""
    h, order = 0.01, 4
    nodes, weights = multiple_integral_rule(n_nodes, order)
    t0 = 10.0 + h * np.arange(50)
    values = np.sin(2 * np.pi * freq_hz * (t0[:, None] + nodes[None] * h) + 0.4)
    values = values[:, :, None] * np.ones(3)
    got = imu.apply_multiple_integral_rule(values, h, weights)[:, :, 0]
    expect = harmonic_multiple_integrals(1.0, freq_hz, 0.4, t0, h, order)
    scale = np.max(np.abs(expect), axis=0)
    assert np.max(np.abs(got - expect) / scale) < 1e-12


def test_rule_error_follows_degree_bound():
    """With 4 nodes the r = 4 error on a harmonic is ~ (omega h)^5 (degree bound 2n - r = 4)."""
    h, order = 0.01, 4
    nodes, weights = multiple_integral_rule(4, order)
    errors = []
    for freq_hz in (1.0, 2.0):
        t0 = np.linspace(0.0, 1.0 / freq_hz, 201)  # one period: the envelope of the error
        values = np.sin(2 * np.pi * freq_hz * (t0[:, None] + nodes * h))[:, :, None] * np.ones(3)
        got = imu.apply_multiple_integral_rule(values, h, weights)[:, 3, 0]
        expect = harmonic_multiple_integrals(1.0, freq_hz, 0.0, t0, h, order)[:, 3]
        errors.append(np.max(np.abs(got - expect)))
    assert 24 < errors[1] / errors[0] < 42  # doubling omega: error envelope x 2^5 = 32


def test_harmonic_low_orders_closed_form():
    """Direct closed forms for r = 1, 2 (integration by parts), over both code branches."""
    A, phase = 1.7, 0.3
    t0 = np.array([0.0, 0.123, 5.0])
    for omega_h in [0.5, 2.0, 3.5, 10.0, 80.0]:  # |i omega h| <= 3 series, > 3 recurrence
        h = 0.01
        w = omega_h / h
        got = harmonic_multiple_integrals(A, w / (2 * np.pi), phase, t0, h, 2)
        a, b = w * t0 + phase, w * (t0 + h) + phase
        i1 = A * (np.cos(a) - np.cos(b)) / w
        i2 = A * (h * np.cos(a) / w - (np.sin(b) - np.sin(a)) / w**2)
        np.testing.assert_allclose(got[:, 0], i1, rtol=1e-12, atol=1e-15 * A * h)
        np.testing.assert_allclose(got[:, 1], i2, rtol=1e-11, atol=1e-15 * A * h**2)


def test_harmonic_against_high_order_quadrature_all_orders():
    """All orders up to MAX_ORDER, omega h from 1e-3 to 60, against a 60-node rule.

    Small t0: the float64 phase omega t carries an absolute error ~ eps omega t that no
    formula can remove (2.7e-12 relative at omega t ~ 1650 rad), so it is kept small here.
    """
    order = imu.MAX_ORDER
    nodes, weights = multiple_integral_rule(60, order)
    h = 0.02
    t0 = np.array([0.0, 0.013])
    for omega_h in [1e-3, 0.3, 2.9, 3.1, 7.0, 25.0, 60.0]:
        f = omega_h / h / (2 * np.pi)
        got = harmonic_multiple_integrals(0.9, f, -0.2, t0, h, order)
        vals = 0.9 * np.sin(2 * np.pi * f * (t0[:, None] + nodes * h) - 0.2)
        ref = np.einsum("rj,nj->nr", weights * (h ** np.arange(1, order + 1))[:, None], vals)
        scale = np.max(np.abs(ref), axis=0)
        # above omega h ~ 10 the *reference* sum cancels (I_1 ~ 2/(omega h) of its terms)
        # and loses ~2 digits: 1.1e-12 measured at omega h = 25, while the closed form
        # agrees with the elementary r = 1, 2 formulas to 3e-15 there
        tol = 1e-12 if omega_h < 10 else 2e-11
        assert np.max(np.abs(got - ref) / scale) < tol, omega_h


def test_harmonic_zero_frequency_is_constant():
    got = harmonic_multiple_integrals(2.0, 0.0, 0.5, np.array([3.0]), 0.1, 5)
    expect = 2.0 * np.sin(0.5) * np.array([0.1**r / math.factorial(r) for r in range(1, 6)])
    np.testing.assert_allclose(got[0], expect, rtol=1e-15)


@pytest.mark.parametrize("m", [1, 2, 5])
def test_compose_equals_direct_integrals(m):
    h, order, n = 0.01, 5, 3
    step0 = 0.4 + m * h * np.arange(n)
    t_sub = (step0[:, None] + h * np.arange(m)[None]).ravel()
    sub = np.stack(
        [harmonic_multiple_integrals(a, f, p, t_sub, h, order) for a, f, p in
         [(1.0, 2.0, 0.1), (0.5, 17.0, 1.0), (2.0, 0.2, -0.4)]],
        axis=-1,
    ).reshape(n, m, order, 3)
    got = compose_multiple_integrals(sub, h)
    direct = np.stack(
        [harmonic_multiple_integrals(a, f, p, step0, m * h, order) for a, f, p in
         [(1.0, 2.0, 0.1), (0.5, 17.0, 1.0), (2.0, 0.2, -0.4)]],
        axis=-1,
    )
    scale = np.max(np.abs(direct), axis=(0, 2))[None, :, None]
    assert np.max(np.abs(got - direct) / scale) < 1e-12


def test_compose_polynomial_exact():
    """Composition of per-sample rule integrals equals the exact step integrals."""
    h, m, order = Fraction(1, 100), 4, 4
    coeffs = [Fraction(3, 2), Fraction(-2), Fraction(5, 3), Fraction(1, 4), Fraction(-1, 5)]
    t0 = Fraction(3, 10)
    sub = np.array([[float(v) for v in exact_poly_integrals(coeffs, t0 + j * h, h, order)]
                    for j in range(m)])
    sub = np.repeat(sub[None, :, :, None], 3, axis=3)
    got = compose_multiple_integrals(sub, float(h))[0, :, 0]
    exact = np.array([float(v) for v in exact_poly_integrals(coeffs, t0, m * h, order)])
    np.testing.assert_allclose(got, exact, rtol=1e-13)


# ------------------------------------------------------------------ deterministic errors


def test_bias_scale_misalignment_g_sensitivity_exact():
    misal = np.array([[0.0, 1e-3, -2e-3], [5e-4, 0.0, 1e-3], [-1e-3, 2e-3, 0.0]])
    G = np.array([[1e-5, 2e-5, -1e-5], [0.0, 3e-5, 1e-5], [2e-5, 0.0, -4e-5]])
    model = ImuErrorModel(
        gyro=SensorErrors(bias=[1e-3, -2e-3, 3e-3], scale_factor=[1e-3, -5e-4, 2e-3], misalignment=misal),
        accel=SensorErrors(bias=[0.05, -0.02, 0.01], scale_factor=[-1e-3, 2e-3, 5e-4],
                           misalignment=misal.T),
        g_sensitivity=G,
    )
    h, order = 0.01, 4
    truth = smooth_truth(200, h, order, t0=2.0)
    out, _, _ = run(model, 200, h, order, truth=truth)
    _, dtheta, dv, omega, f = truth
    hr = np.array([h**r / math.factorial(r) for r in range(1, order + 1)])
    Tg = np.eye(3) + np.diag(model.gyro.scale_factor) + misal
    Ta = np.eye(3) + np.diag(model.accel.scale_factor) + misal.T
    exp_dtheta = dtheta @ Tg.T + dv @ G.T + hr[:, None] * model.gyro.bias
    exp_dv = dv @ Ta.T + hr[:, None] * model.accel.bias
    np.testing.assert_allclose(out.dtheta_r, exp_dtheta, rtol=1e-13, atol=1e-18)
    np.testing.assert_allclose(out.dv_r, exp_dv, rtol=1e-13, atol=1e-18)
    np.testing.assert_allclose(out.rate_b, omega @ Tg.T + f @ G.T + model.gyro.bias, rtol=1e-13)
    np.testing.assert_allclose(out.accel_b, f @ Ta.T + model.accel.bias, rtol=1e-13)


def test_ideal_preset_is_identity():
    out, state, _ = run(imu_preset("ideal"), 100)
    truth = smooth_truth(100, 0.01, 4)
    np.testing.assert_array_equal(out.dtheta_r, truth[1])
    np.testing.assert_array_equal(out.dv_r, truth[2])
    np.testing.assert_array_equal(out.rate_b, truth[3])
    np.testing.assert_array_equal(out.accel_b, truth[4])
    assert state.sample_index == 100


def test_vibration_harmonics_against_quadrature():
    """Vibration increments against an independent 12-node rule of the sine."""
    harm = VibrationHarmonic.on_axis(1, 0.02, 37.0, 0.3)
    model = ImuErrorModel(accel=SensorErrors(vibration=[harm, ([0.0, 0.0, 0.1], 120.0, 1.0)]))
    h, order, n = 0.005, 3, 40
    zeros = (np.arange(n) * h, np.zeros((n, order, 3)), np.zeros((n, order, 3)),
             np.zeros((n, 3)), np.zeros((n, 3)))
    out, _, _ = run(model, n, h, order, truth=zeros)
    nodes, weights = multiple_integral_rule(12, order)
    t = zeros[0][:, None] + nodes * h
    ref_y = np.einsum("rj,nj->nr", weights * (h ** np.arange(1, order + 1))[:, None],
                      0.02 * np.sin(2 * np.pi * 37.0 * t + 0.3))
    ref_z = np.einsum("rj,nj->nr", weights * (h ** np.arange(1, order + 1))[:, None],
                      0.1 * np.sin(2 * np.pi * 120.0 * t + 1.0))
    np.testing.assert_allclose(out.dv_r[:, :, 1], ref_y, rtol=1e-11, atol=1e-16)
    np.testing.assert_allclose(out.dv_r[:, :, 2], ref_z, rtol=1e-11, atol=1e-16)
    np.testing.assert_array_equal(out.dv_r[:, :, 0], 0.0)
    np.testing.assert_allclose(out.accel_b[:, 1], 0.02 * np.sin(2 * np.pi * 37.0 * (zeros[0] + h) + 0.3))


# ------------------------------------------------------------------ random errors


def zero_truth(n, h, order):
    return (np.arange(n) * h, np.zeros((n, order, 3)), np.zeros((n, order, 3)),
            np.zeros((n, 3)), np.zeros((n, 3)))


def test_white_noise_covariance_formula_by_fine_simulation():
    """Independent check of q h^(i+j-1)/((i+j-1)(i-1)!(j-1)!): piecewise-constant noise."""
    q, h, order, m, trials = 2.0, 0.5, 3, 200, 20000
    rng = np.random.default_rng(7)
    edges = np.linspace(0.0, h, m + 1)
    kern = np.stack([((h - edges[:-1]) ** r - (h - edges[1:]) ** r) / math.factorial(r)
                     for r in range(1, order + 1)])  # exact r-fold integral of unit pulses
    w = rng.standard_normal((trials, m)) * math.sqrt(q / (h / m))
    samples = w @ kern.T
    cov = np.cov(samples, rowvar=False)
    expect = imu.white_noise_integral_covariance(q, h, order)
    se = np.sqrt((np.outer(np.diag(expect), np.diag(expect)) + expect**2) / trials)
    assert np.all(np.abs(cov - expect) < 5 * se + 1e-3 * np.abs(expect))


def test_white_noise_multiple_integrals_sample_covariance():
    arw, vrw = 3e-3, 2e-2
    model = ImuErrorModel(gyro=SensorErrors(white_noise_density=arw),
                          accel=SensorErrors(white_noise_density=vrw))
    h, order, n = 0.01, 4, 40000
    out, _, _ = run(model, n, h, order, truth=zero_truth(n, h, order))
    for data, dens in ((out.dtheta_r, arw), (out.dv_r, vrw)):
        samples = np.concatenate([data[:, :, a] for a in range(3)])  # 3 axes pooled
        N = samples.shape[0]
        cov = samples.T @ samples / N  # zero mean known
        expect = imu.white_noise_integral_covariance(dens**2, h, order)
        se = np.sqrt((np.outer(np.diag(expect), np.diag(expect)) + expect**2) / N)
        assert np.all(np.abs(cov - expect) < 5 * se), (cov / expect)
        # whitened draws: identity covariance
        white = np.linalg.solve(np.linalg.cholesky(expect), samples.T).T
        c = white.T @ white / N
        assert np.all(np.abs(c - np.eye(order)) < 5 * np.sqrt((1 + np.eye(order)) / N))
    # rate output: band-limited white noise, sigma = sqrt(PSD / h)
    for data, dens in ((out.rate_b, arw), (out.accel_b, vrw)):
        sigma = np.sqrt(np.mean(data**2))
        assert abs(sigma / (dens / math.sqrt(h)) - 1.0) < 5 / math.sqrt(2 * data.size)
    np.testing.assert_allclose(out.rate_b, out.dtheta_r[:, 0] / h, rtol=1e-14)


def test_gauss_markov_stationary_variance_and_correlation():
    sigma, tau, h, n = 2e-3, 0.2, 0.01, 100000
    model = ImuErrorModel(gyro=SensorErrors(bias_instability_sigma=sigma, bias_correlation_time_s=tau))
    out, state, _ = run(model, n, h, 2, truth=zero_truth(n, h, 2))
    b = out.dtheta_r[:, 0] / h  # bias held constant in each sample
    np.testing.assert_allclose(out.dtheta_r[:, 1], b * h**2 / 2, rtol=1e-14)
    np.testing.assert_allclose(out.rate_b, b, rtol=1e-14)
    phi = math.exp(-h / tau)
    var = np.mean(b**2)
    se_var = sigma**2 * math.sqrt(2 * (1 + phi**2) / (1 - phi**2) / (3 * n))
    assert abs(var - sigma**2) < 5 * se_var
    lag1 = np.mean(b[1:] * b[:-1]) / var
    assert abs(lag1 - phi) < 5 * math.sqrt((1 - phi**2) / (3 * n)) + 5 * se_var / sigma**2
    assert np.all(out.accel_b == 0.0)
    # the state holds the bias of the next sample: b_n = phi b_{n-1} + ...
    assert state.bias_gauss_markov.shape == (2, 3)


def test_rate_random_walk_increments():
    N, h, n = 1e-4, 0.01, 20000
    model = ImuErrorModel(accel=SensorErrors(rate_random_walk=N))
    out, state, _ = run(model, n, h, 1, truth=zero_truth(n, h, 1))
    b = out.accel_b
    steps = np.diff(b, axis=0)
    sd = np.sqrt(np.mean(steps**2))
    assert abs(sd / (N * math.sqrt(h)) - 1) < 5 / math.sqrt(2 * steps.size)
    np.testing.assert_allclose(out.dv_r[:, 0], b * h, rtol=1e-14)
    assert np.all(out.rate_b == 0.0)
    np.testing.assert_array_equal(state.bias_random_walk[0], 0.0)


def test_turn_on_bias_statistics():
    model = ImuErrorModel(gyro=SensorErrors(turn_on_bias_sigma=[1e-4, 2e-4, 3e-4]),
                          accel=SensorErrors(turn_on_bias_sigma=0.01))
    draws = np.array([ImuState.initial(model, np.random.default_rng(s)).turn_on_bias
                      for s in range(3000)])
    sd = np.sqrt(np.mean(draws**2, axis=0))
    expect = np.array([[1e-4, 2e-4, 3e-4], [0.01, 0.01, 0.01]])
    assert np.all(np.abs(sd / expect - 1) < 5 / math.sqrt(2 * 3000))
    # the turn-on bias is applied as a constant
    state = ImuState.initial(model, np.random.default_rng(3))
    out, _, _ = run(model, 5, 0.01, 2, state=state, truth=zero_truth(5, 0.01, 2))
    np.testing.assert_allclose(out.rate_b, np.tile(state.turn_on_bias[0], (5, 1)), rtol=1e-15)


def test_quantization_residual_carry_tracks_sums():
    h, order, n = 0.01, 3, 5000  # crosses several renormalisation blocks
    base = imu_preset("consumer-mems")
    unq = ImuErrorModel(
        gyro=SensorErrors(**{**base.gyro.to_dict(), "quantization_lsb": 0.0}),
        accel=SensorErrors(**{**base.accel.to_dict(), "quantization_lsb": 0.0}),
        g_sensitivity=base.g_sensitivity,
    )
    out_q, state_q, _ = run(base, n, h, order, seed=5)
    out_u, _, _ = run(unq, n, h, order, seed=5)
    lsb = {
        "gyro": base.gyro.quantization_lsb * np.concatenate((h ** np.arange(order), [1 / h])),
        "accel": base.accel.quantization_lsb * np.concatenate((h ** np.arange(order), [1 / h])),
    }
    residual = state_q.quantization_residual(base, h, order)
    for k, (q_r, q_rate, u_r, u_rate) in enumerate((
        (out_q.dtheta_r, out_q.rate_b, out_u.dtheta_r, out_u.rate_b),
        (out_q.dv_r, out_q.accel_b, out_u.dv_r, out_u.accel_b),
    )):
        levels = lsb["gyro" if k == 0 else "accel"]
        q = np.concatenate((q_r, q_rate[:, None]), axis=1)
        u = np.concatenate((u_r, u_rate[:, None]), axis=1)
        counts = q / levels[None, :, None]
        assert np.max(np.abs(counts - np.rint(counts))) < 1e-6  # whole LSBs
        err = np.cumsum(u, axis=0) - np.cumsum(q, axis=0)
        bound = 0.5 * levels[None, :, None] * (1 + 1e-6)
        assert np.all(np.abs(err) <= bound)  # within half an LSB, at every sample
        assert np.max(np.abs(q - u) / levels[None, :, None]) > 0.4  # quantization is active
        np.testing.assert_allclose(residual[k], err[-1], atol=1e-9 * levels.max())


@pytest.mark.parametrize("order", [1, 4])
def test_chunk_invariance(order):
    model = imu_preset("consumer-mems")
    model = ImuErrorModel(
        gyro=SensorErrors(**{**model.gyro.to_dict(), "rate_random_walk": 1e-5,
                             "turn_on_bias_sigma": 1e-3,
                             "vibration": [([1e-3, 0, 2e-3], 45.0, 0.2)]}),
        accel=SensorErrors(**{**model.accel.to_dict(),
                              "vibration": [VibrationHarmonic.on_axis(0, 0.05, 45.0, 1.77)]}),
        g_sensitivity=model.g_sensitivity,
    )
    h, n = 0.01, 3000
    truth = smooth_truth(n, h, order, t0=100.0)
    full, full_state, rng_full = run(model, n, h, order, seed=11, truth=truth)
    rng = np.random.default_rng(11)
    state = ImuState.initial(model, rng)
    parts = []
    for a, b in [(0, 1), (1, 1), (1, 1023), (1023, 1100), (1100, 2048), (2048, 3000)]:
        piece = tuple(x[a:b] for x in truth)
        out, state = apply_imu_errors(piece[0], h, *piece[1:], model, state, rng)
        parts.append(out)
    for name in ("dtheta_r", "dv_r", "rate_b", "accel_b"):
        np.testing.assert_array_equal(np.concatenate([getattr(p, name) for p in parts]),
                                      getattr(full, name))
    assert state == full_state
    assert rng.standard_normal() == rng_full.standard_normal()


def test_stream_independence():
    h, order, n = 0.01, 3, 2000
    gyro_white = dict(white_noise_density=1e-3)
    gyro_gm = dict(bias_instability_sigma=1e-3, bias_correlation_time_s=5.0)
    accel = SensorErrors(white_noise_density=1e-2, rate_random_walk=1e-3, bias_instability_sigma=0.01)
    runs = {}
    for label, g in {"both": {**gyro_white, **gyro_gm}, "white": gyro_white, "gm": gyro_gm,
                     "none": {}}.items():
        for acc_label, acc in (("acc", accel), ("noacc", SensorErrors())):
            model = ImuErrorModel(gyro=SensorErrors(**g), accel=acc)
            out, _, rng = run(model, n, h, order, seed=3, truth=zero_truth(n, h, order))
            runs[label, acc_label] = (out, rng.standard_normal())
    # the accelerometer settings change no gyro number, bit for bit
    for label in ("both", "white", "gm", "none"):
        np.testing.assert_array_equal(runs[label, "acc"][0].dtheta_r, runs[label, "noacc"][0].dtheta_r)
        np.testing.assert_array_equal(runs[label, "acc"][0].rate_b, runs[label, "noacc"][0].rate_b)
    # switching the white noise off leaves the Gauss-Markov part unchanged, and vice versa
    both, white, gm = (runs[k, "acc"][0].dtheta_r for k in ("both", "white", "gm"))
    np.testing.assert_allclose(both - white, gm, rtol=1e-12, atol=1e-20)
    np.testing.assert_allclose(both - gm, white, rtol=1e-9, atol=1e-20)
    assert np.std(gm) > 0 and np.std(white) > 0
    # and the generator advances identically whatever is switched on
    assert len({v[1] for v in runs.values()}) == 1


def test_empty_call_draws_nothing():
    model = imu_preset("tactical")
    rng = np.random.default_rng(0)
    state = ImuState.initial(model, rng)
    before = rng.bit_generator.state
    out, new = apply_imu_errors(np.zeros(0), 0.01, np.zeros((0, 2, 3)), np.zeros((0, 2, 3)),
                                np.zeros((0, 3)), np.zeros((0, 3)), model, state, rng)
    assert out.dtheta_r.shape == (0, 2, 3) and new == state
    assert rng.bit_generator.state == before


# ------------------------------------------------------------------ configuration


def test_presets_round_trip_and_figures():
    for name in imu.PRESET_NAMES:
        model = imu_preset(name)
        assert model.name == name
        assert ImuErrorModel.from_dict(model.to_dict()) == model
    paper = imu_preset("paper-2012")
    np.testing.assert_allclose(paper.accel.white_noise_psd, 1e-10)  # (1e-5 m/s^2)^2 as a PSD
    nav = imu_preset("navigation")
    np.testing.assert_allclose(nav.gyro.white_noise_density, 0.003 * np.pi / 180 / 60)
    np.testing.assert_allclose(nav.accel.bias_instability_sigma, 15e-5)
    cons = imu_preset("consumer-mems")
    np.testing.assert_allclose(cons.accel.scale_factor, [0.05, -0.06, 0.02])
    assert np.all(np.diag(cons.gyro.misalignment) == 0)
    with pytest.raises(ConfigError, match="imu.preset"):
        imu_preset("nope")


def test_nominal_noise_is_the_specification():
    model = imu_preset("tactical")
    nom = nominal_noise = imu.nominal_noise(model)
    np.testing.assert_allclose(nominal_noise["gyro_arw"], 0.1 * np.pi / 180 / 60)
    assert np.ptp(nom["accel_bias_sigma"]) == 0.0  # per-axis truth not revealed
    rms = math.sqrt(np.mean(model.accel.bias**2))
    np.testing.assert_allclose(nom["accel_bias_sigma"], rms)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(misalignment=np.eye(3) * 1e-3), "misalignment"),
        (dict(bias=[1.0, 2.0]), "bias"),
        (dict(bias_instability_sigma=-1.0), "bias_instability_sigma"),
        (dict(bias_correlation_time_s=0.0), "bias_correlation_time_s"),
        (dict(quantization_lsb=-1e-3), "quantization_lsb"),
        (dict(vibration=[([1.0, 0.0, 0.0], -3.0, 0.0)]), "vibration.frequency_hz"),
    ],
)
def test_bad_configuration_names_field(kwargs, field):
    with pytest.raises(ConfigError) as info:
        SensorErrors(**kwargs)
    assert info.value.field == field


def test_bad_inputs_rejected():
    model = imu_preset("ideal")
    state = ImuState.initial(model, np.random.default_rng(0))
    rng = np.random.default_rng(0)
    with pytest.raises(ConfigError) as info:
        apply_imu_errors(np.zeros(2), 0.01, np.zeros((2, 2, 3)), np.zeros((2, 3, 3)),
                         np.zeros((2, 3)), np.zeros((2, 3)), model, state, rng)
    assert info.value.field == "dv_r"
    with pytest.raises(ConfigError):
        apply_imu_errors(np.zeros(2), -0.01, np.zeros((2, 2, 3)), np.zeros((2, 2, 3)),
                         np.zeros((2, 3)), np.zeros((2, 3)), model, state, rng)
    with pytest.raises(ConfigError):
        multiple_integral_rule(0, 2)
    with pytest.raises(ConfigError):
        multiple_integral_rule(3, imu.MAX_ORDER + 1)
