"""Coning algorithms of seed 000 against closed forms, their derivations and the paper."""

from __future__ import annotations

import numpy as np
import pytest

from navsim.errors import ConfigError
from navsim.paper import seed000
from navsim.strapdown import CONING, required_inputs
from navsim.strapdown.coning import CONING_INPUTS
from navsim.strapdown.motion_models import polynomial_motion

RNG_SEED = 20020101
#: highest degree of omega(t) for which each algorithm is exact
EXACT_DEGREE = {
    "one-sample": 0,
    "two-sample": 1,
    "three-sample": 2,
    "three-sample-optimized": 1,
    "smoothing-linear": 1,
    "smoothing": 2,
    "invariant-constant": 0,
    "invariant-linear": 1,
    "invariant": 2,
}


def _inputs(name, motion, t0, dt):
    source, count = CONING_INPUTS[name]
    if source == "sub":
        return motion.omega.sub_increments(t0, dt, count), None
    return None, motion.omega.multiple_integrals(t0, dt, count)


@pytest.mark.parametrize("name", sorted(CONING))
def test_exact_for_model_degree_and_not_above(name):
    rng = np.random.default_rng(RNG_SEED)
    degree = EXACT_DEGREE[name]
    dt, t0 = 0.4, np.array([0.0])
    taylor = rng.standard_normal((degree + 2, 3))
    exact_motion = polynomial_motion(taylor[: degree + 1])
    got = CONING[name](*_inputs(name, exact_motion, t0, dt), dt)
    np.testing.assert_allclose(got, exact_motion.exact_rotation_vector(t0, dt), atol=1e-14)
    richer = polynomial_motion(taylor)
    err = CONING[name](*_inputs(name, richer, t0, dt), dt) - richer.exact_rotation_vector(t0, dt)
    assert np.abs(err).max() > 1e-11  # round-off is ~1e-16


def _coefficients_from_multiple_integrals(d1, d2, d3, t):
    """Solve the paper's 3x3 system (after (3.4)) for A, B, C of omega = A + B t + C t^2/2."""
    system = np.array([[t, t**2 / 2, t**3 / 6], [t**2 / 2, t**3 / 6, t**4 / 24], [t**3 / 6, t**4 / 24, t**5 / 120]])
    return np.linalg.solve(system, np.stack([d1, d2, d3]))


def test_smoothing_37_is_29_with_coefficients_34():
    # (3.7) must equal (2.9) evaluated with the least-squares coefficients (3.4)
    rng = np.random.default_rng(RNG_SEED)
    t = 0.37
    d = rng.standard_normal((5, 3, 3)) * np.array([t, t**2, t**3])[None, :, None]
    got = CONING["smoothing"](None, d, t) - d[:, 0]
    for k in range(5):
        a, b, c = _coefficients_from_multiple_integrals(*d[k], t)
        expected = np.cross(a, b) * t**3 / 12 + np.cross(a, c) * t**4 / 24 + np.cross(b, c) * t**5 / 120  # (2.9)
        np.testing.assert_allclose(got[k], expected, rtol=1e-10, atol=1e-14)


def test_invariant_48_is_half_of_43_with_coefficients_34():
    # (4.8) = 1/2 [DT2 x w(T) - DT3 x w'(T) + DT4 x w''(T)] with (3.4) moved to t_k+1
    rng = np.random.default_rng(RNG_SEED + 1)
    t = 0.29
    d = rng.standard_normal((5, 4, 3)) * np.array([t, t**2, t**3, t**4])[None, :, None]
    got = CONING["invariant"](None, d, t) - d[:, 0]
    for k in range(5):
        a, b, c = _coefficients_from_multiple_integrals(*d[k, :3], t)
        w, w_dot, w_ddot = a + b * t + c * t**2 / 2, b + c * t, c
        series = np.cross(d[k, 1], w) - np.cross(d[k, 2], w_dot) + np.cross(d[k, 3], w_ddot)  # (4.3)
        np.testing.assert_allclose(got[k], 0.5 * series, rtol=1e-10, atol=1e-14)


def _invariant_as_printed(d, t):
    d1, d2, d3, d4 = d[:, 0], d[:, 1], d[:, 2], d[:, 3]
    return d1 + (18 / t**2) * np.cross(d1, d3) - (1.5 / t) * np.cross(d2, 44 / t**2 * d3 - 3 * d1) - (
        30 / t**2  # as printed
    ) * np.cross(d1 - 6 / t * d2 + 12 / t**2 * d3, d4)


def test_printed_48_coefficient_is_a_typo():
    rng = np.random.default_rng(RNG_SEED + 2)
    dt, t0 = 0.3, np.array([0.0])
    motion = polynomial_motion(rng.standard_normal((3, 3)))  # quadratic omega
    d = motion.omega.multiple_integrals(t0, dt, 4)
    exact = motion.exact_rotation_vector(t0, dt)
    np.testing.assert_allclose(CONING["invariant"](None, d, dt), exact, atol=1e-14)
    assert np.abs(_invariant_as_printed(d, dt) - exact).max() > 1e-6


@pytest.mark.parametrize(
    ("ref", "name", "order", "paper"),
    [row for row in seed000.CONING_PAPER if row[3] is not None],
)
def test_coning_drift_matches_paper(ref, name, order, paper):
    drift = seed000.coning_drift(name)
    slope, coef = seed000.fit_leading(seed000._X_VALUES, drift, order)
    assert slope == pytest.approx(order, abs=0.05)
    assert abs(coef) == pytest.approx(paper, rel=0.01)


def test_unprinted_drift_coefficients():
    # one-sample eps = (a^2 W/2)(WT)^2/6 and Miller's two-sample (a^2 W/2)(WT)^4/480
    for name, order, expected in (("one-sample", 2, 1 / 6), ("two-sample", 4, 1 / 480)):
        _, coef = seed000.fit_leading(seed000._X_VALUES, seed000.coning_drift(name), order)
        assert abs(coef) == pytest.approx(expected, rel=0.01)


@pytest.mark.parametrize(("ref", "name"), [("(2.11)", "three-sample"), ("(3.9)", "smoothing"), ("(4.13)", "invariant")])
def test_local_error_orders_and_coefficients(ref, name):
    order = 7 if ref != "(2.11)" else 5
    steps = seed000._STEPS_HIGH if order == 7 else seed000._STEPS
    motion = seed000.general_motion()
    errors = seed000.local_errors("coning", name, steps, motion)
    slope = np.polyfit(np.log(steps[-3:]), np.log(np.linalg.norm(errors[-3:], axis=1)), 1)[0]
    assert slope == pytest.approx(order, abs=0.1)
    printed = seed000._printed_local_error(ref, motion, np.array([0.37]), steps[-1])[0]
    ratio = errors[-1] @ printed / (printed @ printed)
    # printed as exact - computed, so the measured (computed - exact) ratio is -1
    assert ratio == pytest.approx(-1.0, abs=0.03)


def test_optimized_general_error_is_fifth_order_not_printed_fourth():
    # the printed Delta = T^4/120 (A x C) after (2.13) would give slope 4
    motion = seed000.general_motion()
    errors = seed000.local_errors("coning", "three-sample-optimized", seed000._STEPS, motion)
    slope = np.polyfit(np.log(seed000._STEPS[-3:]), np.log(np.linalg.norm(errors[-3:], axis=1)), 1)[0]
    assert slope == pytest.approx(5.0, abs=0.1)
    # leading term -T^5/6480 (A x D + B x C) for a cubic omega
    rng = np.random.default_rng(RNG_SEED + 3)
    taylor = rng.standard_normal((4, 3))
    cubic = polynomial_motion(taylor)
    t0 = np.array([0.0])
    for dt in (1e-2, 5e-3):
        err = CONING["three-sample-optimized"](cubic.omega.sub_increments(t0, dt, 3), None) - cubic.exact_rotation_vector(t0, dt)
        lead = -dt**5 / 6480 * (np.cross(taylor[0], taylor[3]) + np.cross(taylor[1], taylor[2]))
        np.testing.assert_allclose(err[0], lead, rtol=0.02 * dt / 5e-3, atol=1e-19)


def test_required_inputs_and_errors():
    assert required_inputs("coning", "three-sample") == {"dtheta_sub:3"}
    assert required_inputs("coning", "invariant") == {"dtheta_r:4", "dt"}
    assert required_inputs("coning", "one-sample") == {"dtheta_r:1"}
    with pytest.raises(ConfigError):
        required_inputs("coning", "four-sample")
    with pytest.raises(ConfigError):
        required_inputs("attitude", "one-sample")
    with pytest.raises(ConfigError, match="dt"):
        CONING["smoothing"](None, np.zeros((1, 3, 3)))
    with pytest.raises(ConfigError, match="dtheta_r"):
        CONING["invariant"](None, np.zeros((1, 3, 3)), 0.1)
    with pytest.raises(ConfigError, match="dtheta_sub"):
        CONING["three-sample"](np.zeros((1, 2, 3)), None)


def test_vectorised_rows_are_independent():
    rng = np.random.default_rng(RNG_SEED + 4)
    d = rng.standard_normal((6, 4, 3)) * 1e-3
    for name in ("smoothing", "invariant", "invariant-linear"):
        batch = CONING[name](None, d, 0.01)
        single = np.concatenate([CONING[name](None, d[k : k + 1], 0.01) for k in range(6)])
        np.testing.assert_array_equal(batch, single)
