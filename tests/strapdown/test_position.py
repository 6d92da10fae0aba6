"""Position algorithms of seed 000 §5: the exact form (5.2) and the partial increments."""

from __future__ import annotations

import numpy as np
import pytest

from navsim.errors import ConfigError
from navsim.paper import seed000
from navsim.strapdown import POSITION, required_inputs
from navsim.strapdown.motion_models import Motion, Signal
from navsim.strapdown.position import (
    partial_increment_constant,
    partial_increment_invariant,
    partial_increment_smoothing,
)

RNG_SEED = 20020505


def _harmonic(rng, freqs):
    amps = rng.standard_normal((len(freqs), 3)) + 1j * rng.standard_normal((len(freqs), 3))
    return Signal(poly=rng.standard_normal((1, 3)), freqs=np.asarray(freqs), amps=amps)


@pytest.mark.parametrize(
    ("partial", "w_degree", "a_model"),
    [(partial_increment_constant, 0, 0), (partial_increment_smoothing, 1, 1), (partial_increment_invariant, 1, "h")],
)
def test_partial_increment_exact_for_its_model(partial, w_degree, a_model):
    rng = np.random.default_rng(RNG_SEED)
    accel = _harmonic(rng, [4.0, 31.0]) if a_model == "h" else Signal(poly=rng.standard_normal((a_model + 1, 3)))
    motion = Motion(omega=Signal(poly=rng.standard_normal((w_degree + 1, 3))), accel=accel)
    t0, dt = np.array([0.0, 0.6]), 0.35
    th, dv = motion.increments(t0, dt, 4)
    np.testing.assert_allclose(partial(th, dv, dt), motion.exact_partial_displacement(t0, dt), atol=1e-13)


def test_smoothing_partial_increment_equals_its_polynomial_derivation():
    # dS_s = A_w x A_a T^3/6 + A_w x B_a T^4/12 + B_w x A_a T^4/24 + B_w x B_a T^5/40, (3.5)
    rng = np.random.default_rng(RNG_SEED + 1)
    t = 0.3
    scale = np.array([t, t**2])[None, :, None]
    th, dv = rng.standard_normal((3, 2, 3)) * scale, rng.standard_normal((3, 2, 3)) * scale
    got = partial_increment_smoothing(th, dv, t)
    for k in range(3):
        aw, bw = 6 / t**2 * (th[k, 1] - th[k, 0] * t / 3), 12 / t**3 * (th[k, 0] * t / 2 - th[k, 1])
        aa, ba = 6 / t**2 * (dv[k, 1] - dv[k, 0] * t / 3), 12 / t**3 * (dv[k, 0] * t / 2 - dv[k, 1])
        expected = (np.cross(aw, aa) * t**3 / 6 + np.cross(aw, ba) * t**4 / 12 + np.cross(bw, aa) * t**4 / 24
                    + np.cross(bw, ba) * t**5 / 40)
        np.testing.assert_allclose(got[k], expected, rtol=1e-10, atol=1e-15)


@pytest.mark.parametrize(("name", "order"), [("exact", 4), ("exact-smoothing", 5), ("exact-invariant", 5)])
def test_partial_increment_local_error_order(name, order):
    steps = seed000._STEPS
    errors = seed000.local_errors("position", name, steps)
    slope = np.polyfit(np.log(steps[-3:]), np.log(np.linalg.norm(errors[-3:], axis=1)), 1)[0]
    assert slope == pytest.approx(order, abs=0.15)


def test_exact_form_is_step_independent_for_linear_vibration():
    steps = np.array([0.002, 0.02, 0.1])
    errs = seed000.position_errors(seed000.position_motion(False), steps)
    for name in ("exact", "exact-smoothing", "exact-invariant"):
        assert np.all(errs[name] < 1e-12)
    # (5.1): the error grows in proportion to the step (0.5 m/s^2 * T * 2 s / 2 dominates)
    assert errs["rectangle"][-1] / errs["rectangle"][0] == pytest.approx(50.0, rel=0.05)
    assert errs["rectangle"][0] > 1e-4


def test_exact_form_with_rotation_beats_rectangle():
    steps = np.array([0.01, 0.1])
    errs = seed000.position_errors(seed000.position_motion(True), steps)
    for name in ("exact-smoothing", "exact-invariant"):
        assert np.all(errs[name] < 1e-3 * errs["rectangle"])
    assert errs["exact-invariant"][-1] < errs["exact"][-1]


def test_shapes_inputs_and_errors():
    rng = np.random.default_rng(RNG_SEED + 2)
    n = 4
    velocity, mat = rng.standard_normal((n, 3)), np.broadcast_to(np.eye(3), (n, 3, 3))
    th, dv = rng.standard_normal((n, 4, 3)), rng.standard_normal((n, 4, 3))
    for name, fn in POSITION.items():
        out = fn(velocity, mat, None, None, th, dv, 0.01)
        assert out.shape == (n, 3)
    np.testing.assert_allclose(POSITION["rectangle"](velocity, mat, None, None, th, dv, 0.01), velocity * 0.01)
    assert required_inputs("position", "exact-invariant") == {"dtheta_r:2", "dv_r:4", "velocity", "attitude", "dt"}
    assert required_inputs("position", "rectangle") == {"velocity", "dt"}
    with pytest.raises(ConfigError, match="mat_ib_k"):
        POSITION["exact"](velocity, np.eye(3), None, None, th, dv, 0.01)
    with pytest.raises(ConfigError, match="dv_r"):
        POSITION["exact-invariant"](velocity, mat, None, None, th, dv[:, :3], 0.01)
