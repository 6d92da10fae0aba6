"""Sculling algorithms of seed 000 against closed forms, their derivations and the paper."""

from __future__ import annotations

import numpy as np
import pytest

from navsim.errors import ConfigError
from navsim.paper import seed000
from navsim.strapdown import SCULLING, required_inputs
from navsim.strapdown.motion_models import Motion, Signal, polynomial_motion

RNG_SEED = 20020202
NAMES = ["first-order", "two-sample", "smoothing", "invariant-4.4", "invariant-4.5", "invariant-4.6", "invariant-4.7"]


def _inputs(name, motion, t0, dt):
    return seed000._sculling_inputs(name, motion, t0, dt)


def _harmonic(rng, freqs):
    amps = rng.standard_normal((len(freqs), 3)) + 1j * rng.standard_normal((len(freqs), 3))
    return Signal(poly=rng.standard_normal((1, 3)), freqs=np.asarray(freqs), amps=amps)


def _poly(rng, degree):
    return Signal(poly=rng.standard_normal((degree + 1, 3)))


#: (name, omega model, accel model) for which the algorithm must be exact;
#: "h" = arbitrary harmonic signal (the invariance claims of (4.1), (4.2))
EXACT_CASES = [
    ("first-order", 0, 0),
    ("two-sample", 1, 1),
    ("smoothing", 1, 1),
    ("invariant-4.4", 1, "h"),
    ("invariant-4.5", 0, "h"),
    ("invariant-4.6", "h", 1),
    ("invariant-4.7", "h", 0),
]


@pytest.mark.parametrize(("name", "w_model", "a_model"), EXACT_CASES)
def test_exact_for_model_and_invariant_to_the_other_factor(name, w_model, a_model):
    rng = np.random.default_rng(RNG_SEED)
    omega = _harmonic(rng, [3.0, 11.0]) if w_model == "h" else _poly(rng, w_model)
    accel = _harmonic(rng, [5.0, 40.0]) if a_model == "h" else _poly(rng, a_model)
    motion = Motion(omega=omega, accel=accel)
    dt, t0 = 0.3, np.array([0.0, 0.77])
    got = SCULLING[name](*_inputs(name, motion, t0, dt), dt)
    np.testing.assert_allclose(got, motion.exact_velocity_bracket(t0, dt), atol=1e-13)
    # one degree more in the modelled factor breaks exactness
    if w_model != "h":
        richer = Motion(omega=_poly(rng, w_model + 1), accel=accel)
    else:
        richer = Motion(omega=omega, accel=_poly(rng, a_model + 1))
    err = SCULLING[name](*_inputs(name, richer, t0, dt), dt) - richer.exact_velocity_bracket(t0, dt)
    assert np.abs(err).max() > 1e-6


def test_printed_coefficient_of_23_is_wrong():
    # omega = A, a = B t: exact (1.8) = A x B T^3/3; printed 1/3 misses it, 2/3 hits it
    a_vec, b_vec, dt = np.array([0.1, 0.2, 0.3]), np.array([1.0, -2.0, 0.5]), 0.2
    motion = polynomial_motion(a_vec[None], np.stack([np.zeros(3), b_vec]))
    t0 = np.array([0.0])
    th, dv = motion.sub_increments(t0, dt, 2)
    exact = motion.exact_sculling(t0, dt)[0]
    np.testing.assert_allclose(exact, np.cross(a_vec, b_vec) * dt**3 / 3, rtol=1e-13)
    t1, t2, v1, v2 = th[0, 0], th[0, 1], dv[0, 0], dv[0, 1]
    base = 0.5 * np.cross(t1 + t2, v1 + v2)
    printed = base + (1 / 3) * (np.cross(t1, v2) - np.cross(t2, v1))
    corrected = SCULLING["two-sample"](th, dv) - (v1 + v2)
    np.testing.assert_allclose(corrected[0], exact, rtol=1e-12)
    assert np.linalg.norm(printed - exact) > 0.1 * np.linalg.norm(exact)


def test_smoothing_36_is_22_with_coefficients_35():
    rng = np.random.default_rng(RNG_SEED + 1)
    t = 0.41
    scale = np.array([t, t**2])[None, :, None]
    th, dv = rng.standard_normal((4, 2, 3)) * scale, rng.standard_normal((4, 2, 3)) * scale
    got = SCULLING["smoothing"](None, None, th, dv, t) - dv[:, 0]
    for k in range(4):
        # (3.5): A = 6/T^2 (D2 - D1 T/3), B = 12/T^3 (D1 T/2 - D2)
        aw, bw = 6 / t**2 * (th[k, 1] - th[k, 0] * t / 3), 12 / t**3 * (th[k, 0] * t / 2 - th[k, 1])
        aa, ba = 6 / t**2 * (dv[k, 1] - dv[k, 0] * t / 3), 12 / t**3 * (dv[k, 0] * t / 2 - dv[k, 1])
        expected = (np.cross(aw, aa) * t**2 / 2 + np.cross(aw, ba) * t**3 / 3 + np.cross(bw, aa) * t**3 / 6
                    + np.cross(bw, ba) * t**4 / 8)  # (2.2)
        np.testing.assert_allclose(got[k], expected, rtol=1e-10, atol=1e-14)


@pytest.mark.parametrize(("ref", "name", "order", "paper"), seed000.SCULLING_PAPER)
def test_sculling_error_matches_paper(ref, name, order, paper):
    err = seed000.sculling_error(name)
    slope, coef = seed000.fit_leading(seed000._X_VALUES, err, order)
    assert slope == pytest.approx(order, abs=0.05)
    assert abs(coef) == pytest.approx(paper, rel=0.01)


@pytest.mark.parametrize(
    ("ref", "name", "ratio"),
    [("(2.5)", "two-sample", 1.0), ("(3.8)", "smoothing", 1.0),
     # (4.9), (4.10) are printed with T^5/1440; measured T^5/720 (and (4.10) with the
     # opposite sign); 1/720 is what the paper's own (4.11) requires
     ("(4.9)", "invariant-4.4", 2.0), ("(4.10)", "invariant-4.6", -2.0)],
)
def test_local_error_against_printed_expressions(ref, name, ratio):
    fit = seed000.local_error_fit(ref, "sculling", name, 5)
    assert fit["slope"] == pytest.approx(5.0, abs=0.1)
    assert fit["ratio"] == pytest.approx(ratio, abs=0.01)


def test_invariant_49_coefficient_from_411():
    # mean of C_w x B_a over sculling phases is -theta0 a0 W^4/2; a local error
    # c T^5 (C_w x B_a) then gives dW = c T^4 theta0 a0 W^4/2 = c (theta0 a0/2)(W T)^4,
    # so (4.11)'s 1/720 requires c = 1/720, not the printed 1/1440 of (4.9)
    theta0, a0, w = 0.01, 1.0, 2.0
    phases = np.arange(8) / 8 * 2 * np.pi
    c_w = -theta0 * w**3 * np.cos(phases)  # second derivative of theta0 W cos(W t)
    b_a = a0 * w * np.cos(phases)  # first derivative of a0 sin(W t)
    assert np.mean(c_w * b_a) == pytest.approx(-theta0 * a0 * w**4 / 2)
    _, coef = seed000.fit_leading(seed000._X_VALUES, seed000.sculling_error("invariant-4.4"), 4)
    assert abs(coef) == pytest.approx(1 / 720, rel=0.01)


def test_required_inputs_and_errors():
    assert required_inputs("sculling", "two-sample") == {"dtheta_sub:2", "dv_sub:2"}
    assert required_inputs("sculling", "invariant-4.4") == {"dtheta_r:2", "dv_r:3", "dt"}
    assert required_inputs("sculling", "invariant-4.6") == {"dtheta_r:3", "dv_r:2", "dt"}
    assert required_inputs("sculling", "first-order") == {"dtheta_r:1", "dv_r:1"}
    for alias, name in (("accel-invariant-linear", "invariant-4.4"), ("rate-invariant-constant", "invariant-4.7")):
        assert SCULLING[alias] is SCULLING[name]
        assert required_inputs("sculling", alias) == required_inputs("sculling", name)
    with pytest.raises(ConfigError, match="dv_r"):
        SCULLING["invariant-4.4"](None, None, np.zeros((1, 2, 3)), np.zeros((1, 2, 3)), 0.1)
    with pytest.raises(ConfigError, match="dt"):
        SCULLING["smoothing"](None, None, np.zeros((1, 2, 3)), np.zeros((1, 2, 3)))


def test_first_order_sub_and_r_inputs_agree():
    rng = np.random.default_rng(RNG_SEED + 2)
    motion = Motion(omega=_harmonic(rng, [2.0]), accel=_harmonic(rng, [3.0]))
    t0 = np.array([0.1, 0.2])
    th_s, dv_s = motion.sub_increments(t0, 0.05, 4)
    th_r, dv_r = motion.increments(t0, 0.05, 1)
    np.testing.assert_allclose(SCULLING["first-order"](th_s, dv_s), SCULLING["first-order"](None, None, th_r, dv_r),
                               rtol=1e-12)
