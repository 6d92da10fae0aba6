"""The native vector env's compiled rewards (:func:`navsim.envs.vector.rewards_into`):
the single env's operations member by member, bit for bit; the NumPy path beside it."""

from __future__ import annotations

import math

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import navsim.envs  # noqa: E402, F401  (registers the ids)
from navsim.envs import vector  # noqa: E402

from navsim.jit import available  # noqa: E402
from navsim.naverror import local_level_error_scalar, wrap_angle, wrap_angle_scalar  # noqa: E402

needs_numba = pytest.mark.skipif(not available(), reason="numba (extra fast) not installed")

SPECIAL = [0.0, -0.0, math.pi, -math.pi, 2 * math.pi, 3 * math.pi, math.pi / 2, -math.pi / 2, 5e-324, -5e-324,
           1e-300, 1e300, -1e300, math.nan, math.inf, -math.inf]
ROW = np.array([0.7, 0.3, 120.0, 1.0, 2.0, -0.1, 0.5, 0.01, -0.02, 6.37e6, 6.39e6, math.cos(0.7), 10.0])


def _actions(n: int, seed: int = 0) -> np.ndarray:
    """Solutions at every scale (1e-8 .. 1e8 about the truth), the special values first."""
    rng = np.random.default_rng(seed)
    a = ROW[:9] + rng.normal(size=(n, 9)) * rng.choice([1e-8, 1e-3, 1.0, 3.0, 10.0, 1e3, 1e8], size=(n, 9))
    a.flat[: 9 * len(SPECIAL)] = np.repeat(SPECIAL, 9)
    a[len(SPECIAL):2 * len(SPECIAL)] = np.array(SPECIAL)[:, None]  # a special value in every column
    return a


def _single_env_reward(a: list, sc: np.ndarray, row: list, weights: tuple, cap: float) -> float:
    """NavigationEnv.step's reward (envs/navigation.py), Python floats."""
    de, dn, du = local_level_error_scalar(a[0] * sc[0], a[1] * sc[1], a[2] * sc[2], row[0], row[1], row[2], row[9],
                                          row[10], row[11])
    w_pos, w_vel, w_att = weights
    e = w_pos * math.sqrt(de * de + dn * dn + du * du)
    if w_vel:
        d = [a[j] * sc[j] - row[j] for j in (3, 4, 5)]
        e = e + w_vel * math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    if w_att:
        d = [wrap_angle_scalar(a[j] * sc[j] - row[j]) for j in (6, 7, 8)]
        e = e + w_att * math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    return -e if e < cap else -cap


@needs_numba
@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # the scalar reference overflows on 1e300
@pytest.mark.parametrize("weights", [(1.0, 0.0, 0.0), (1.0, 0.5, 2.0), (0.0, 0.0, 3.0)])
def test_compiled_rewards_are_the_single_envs_bit_for_bit(weights):
    """Every member's reward from the compiled loop is the single env's (the same
    operations on Python floats, the C library's sin/cos/atan2 as cmath's), including
    nan/inf solutions (-cap), -0, multiples of pi and the overflow to inf."""
    kernel = vector._rewards_kernel()
    assert kernel is not None
    a = _actions(4000)
    sc = np.random.default_rng(1).uniform(0.5, 2.0, size=9)
    out = np.empty(len(a))
    kernel(a, sc, ROW, *weights, 1e4, out)
    row = ROW.tolist()
    expected = np.array([_single_env_reward(aj, sc, row, weights, 1e4) for aj in a.tolist()])
    assert np.array_equal(out.view(np.int64), expected.view(np.int64))


@needs_numba
@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_compiled_wrap_is_wrap_angle_scalar_bit_for_bit():
    """The compiled principal angle equals ``phase(exp(1j x))`` of cmath on every input;
    NumPy's ``wrap_angle`` may differ from both in the last bit (its arctangent)."""
    vector._rewards_kernel()  # compiles _wrap too
    rng = np.random.default_rng(2)
    x = np.concatenate([SPECIAL, rng.normal(size=20000) * rng.choice([1e-300, 1e-8, 1.0, 4.0, 1e5, 1e15], size=20000)])
    compiled = np.array([vector._wrap(v) for v in x.tolist()])
    scalar = np.array([wrap_angle_scalar(v) for v in x.tolist()])
    assert np.array_equal(compiled.view(np.int64), scalar.view(np.int64))
    numpy_path = wrap_angle(x)
    finite = np.isfinite(x)
    # within one rounding of a result in (-pi, pi]: |difference| <= ulp(pi) = 2^-51 (derived
    # from the magnitude of the result; the two arctangents are each within an ulp of it)
    assert np.all(np.abs(numpy_path[finite] - scalar[finite]) <= 2.0**-51)
    assert np.array_equal(np.isnan(numpy_path), np.isnan(scalar))


@needs_numba
def test_env_rewards_compiled_and_numpy_paths(monkeypatch):
    """The env with the compiled rewards and with the NumPy path, same actions: equal to
    a few roundings (the NumPy arctangent's last bit, scaled by the position factor
    (R_E + h) cos(lat) and the square root: relative 1e-15 of the error), and the
    compiled rewards are the single env's formula bit for bit."""
    envs = {}
    for use in (True, False):
        monkeypatch.setattr(vector, "USE_KERNEL", use)
        env = vector.NavigationVectorEnv(40, "paper-2012", score=False, chunk_steps=7, reward_weights=(1.0, 0.5, 2.0),
                                         timing={"duration_s": 0.3})
        env.reset(seed=5)
        envs[use] = env
    rng = np.random.default_rng(3)
    for _ in range(12):
        a = np.asarray(envs[True]._truth[envs[True]._i, :9]) / envs[True].action_scale
        a = a + rng.normal(size=(40, 9)) * rng.choice([1e-9, 1e-5, 1.0], size=(40, 9))
        row = envs[True]._truth[envs[True]._i].tolist()
        monkeypatch.setattr(vector, "USE_KERNEL", True)
        r_kernel = envs[True].step(a)[1]
        monkeypatch.setattr(vector, "USE_KERNEL", False)
        r_numpy = envs[False].step(a)[1]
        expected = [_single_env_reward(aj, envs[True].action_scale, row, (1.0, 0.5, 2.0), 1e4) for aj in a.tolist()]
        assert np.array_equal(r_kernel, np.array(expected))
        np.testing.assert_allclose(r_numpy, r_kernel, rtol=1e-15, atol=0.0)
    for env in envs.values():
        env.close()
