"""Adaptive-filtering env: checker, noise hooks of every bundled estimator, reward, score."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import navsim.envs  # noqa: E402,F401
from gymnasium.utils.env_checker import check_env  # noqa: E402

from navsim import estimators  # noqa: E402
from navsim.envs.adaptive import NoiseAdapter  # noqa: E402
from navsim.estimators.base import NoiseScaling, _get_path  # noqa: E402
from navsim.errors import ConfigError  # noqa: E402

OVER = {"timing": {"duration_s": 12.0}, "outages": {"windows_s": [[5.0, 8.0]]}}


def test_check_env_without_warnings():
    env = gym.make("navsim/AdaptiveFilter-v0", timing={"duration_s": 6.0})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    assert [str(w.message) for w in caught] == []


@pytest.mark.parametrize("name", estimators.available())
def test_noise_hooks_scale_the_estimator(name):
    env = gym.make("navsim/AdaptiveFilter-v0", estimator=name, **OVER).unwrapped
    env.reset(seed=2)
    est = env.estimator
    assert isinstance(est, NoiseScaling)
    q, r_var, r_sig = est.NOISE_PROCESS, est.NOISE_MEASUREMENT_VARIANCE, est.NOISE_MEASUREMENT_SIGMA
    assert q or r_var or r_sig
    base = {path: np.copy(_get_path(est, path)) for path in (*q, *r_var, *r_sig)}  # as the reset left them
    env.step(np.array([1.0, -0.5], dtype=np.float32))  # q x 10, r x 10^-0.5
    for path in q:
        assert np.allclose(_get_path(est, path), 10.0 * base[path], rtol=1e-15, atol=0)
    for path in r_var:
        assert _get_path(est, path) == pytest.approx(10**-0.5 * base[path], rel=1e-15)
    for path in r_sig:
        assert _get_path(est, path) == pytest.approx(10**-0.25 * base[path], rel=1e-15)
    env.step(np.array([0.5, 0.5], dtype=np.float32))  # scales do not compound
    for path in q:
        assert np.allclose(_get_path(est, path), 10**0.5 * base[path], rtol=1e-15, atol=0)
    env.step(np.zeros(2, dtype=np.float32))  # back to the untuned filter
    for path in (*q, *r_var, *r_sig):
        assert np.array_equal(_get_path(est, path), base[path])
    env.reset(seed=3)  # a new episode: the base is that of the new reset, not a scaled one
    env.step(np.array([1.0, 1.0], dtype=np.float32))
    for path in q:
        assert np.allclose(_get_path(est, path), 10.0 * base[path], rtol=1e-15, atol=0)


def _episode(action, name="lc-ekf", seed=1, untuned_scale=(1.0, 1.0)):
    env = gym.make("navsim/AdaptiveFilter-v0", estimator=name, untuned_scale=untuned_scale, **OVER)
    obs, info = env.reset(seed=seed)
    total, errors = 0.0, []
    while True:
        obs, r, term, trunc, info = env.step(np.asarray(action, dtype=np.float32))
        assert env.observation_space.contains(obs)
        total += r
        errors.append(info["position_error_m"])
        if term or trunc:
            return total, errors, info


def test_untuned_action_reproduces_the_estimator_and_reward_is_its_error():
    from navsim.episode import run_episode
    from navsim.metrics import error_series
    from navsim.scenario import load_scenario

    total, errors, info = _episode([0.0, 0.0])
    record = run_episode(load_scenario("paper-2012").with_overrides(OVER), estimators.make("lc-ekf"), seed=1)
    e = error_series(record).error[:, :3]
    per_step = np.sqrt(np.sum(e * e, axis=1))
    means = per_step[100:].reshape(-1, 100).mean(axis=1)  # the decisions after the first interval
    assert np.allclose(errors, means, rtol=1e-6)
    assert total == pytest.approx(-means.sum(), rel=1e-6)
    assert info["episode_score"].horizontal_rmse_m == pytest.approx(
        math.sqrt(np.mean(np.sum(e[:, :2] ** 2, axis=1))), rel=1e-9)


def test_default_untuned_filter_is_the_estimator_with_ten_times_r():
    """The default a = 0 is lc-ekf with R x 10: the same numbers as lc-ekf built with its
    measurement sigmas x sqrt(10) (measurement_scale: the same sigmas), and
    a[1] = -1 there is the estimator's own R (products of 10 and 10^-1: to 1 ulp)."""
    from navsim.episode import run_episode
    from navsim.metrics import error_series
    from navsim.scenario import load_scenario

    _, errors, _ = _episode([0.0, 0.0], untuned_scale=(1.0, 10.0))
    record = run_episode(load_scenario("paper-2012").with_overrides(OVER),
                         estimators.make("lc-ekf", measurement_scale=math.sqrt(10.0)), seed=1)
    e = error_series(record).error[:, :3]
    means = np.sqrt(np.sum(e * e, axis=1))[100:].reshape(-1, 100).mean(axis=1)
    assert np.allclose(errors, means, rtol=1e-6)  # the per-interval means of the env's reward (test above)
    nominal = _episode([0.0, 0.0])[1]
    assert not np.allclose(errors, nominal, rtol=1e-3)  # the mis-tuning is visible in the error
    env = gym.make("navsim/AdaptiveFilter-v0", **OVER).unwrapped
    assert env.untuned_scale == (1.0, 10.0)
    env.reset(seed=1)
    est, gnss = env.estimator, env.context.gnss
    assert est.sigma_pos == pytest.approx(math.sqrt(10.0) * gnss.pseudorange_sigma_m, rel=1e-15)
    env.step(np.array([0.0, -1.0], dtype=np.float32))  # R x 10 x 10^-1: the estimator's own sigmas
    assert est.sigma_pos == pytest.approx(gnss.pseudorange_sigma_m, rel=1e-15)
    assert est.sigma_vel == pytest.approx(gnss.doppler_sigma_mps, rel=1e-15)
    with pytest.raises(ConfigError):
        gym.make("navsim/AdaptiveFilter-v0", untuned_scale=(1.0, 0.0), **OVER)


def test_scales_change_the_outcome_and_bad_options():
    base = _episode([0.0, 0.0])[0]
    assert _episode([1.0, 1.0])[0] != base
    with pytest.raises(ConfigError):
        gym.make("navsim/AdaptiveFilter-v0", decision_period_s=0.015)
    with pytest.raises(ConfigError):
        NoiseAdapter(object())


def test_chunked_generation_gives_the_numbers_of_one_pass_per_decision():
    """The env serves decisions from 1000-step chunks; one simulator pass per decision (the
    old path, chunk_steps = one interval) gives the same observations, rewards and score
    bit for bit (the generation is chunk-invariant; the estimator sees the same batches)."""
    over = {"timing": {"duration_s": 25.0}, "outages": {"windows_s": [[8.0, 14.0]]}}
    envs = [gym.make("navsim/AdaptiveFilter-v0", chunk_steps=c, **over) for c in (1000, 100)]
    assert [e.unwrapped.chunk_steps for e in envs] == [1000, 100]
    outs = [e.reset(seed=4) for e in envs]
    assert np.array_equal(outs[0][0], outs[1][0])
    rng = np.random.default_rng(2)
    while True:
        action = rng.uniform(-1, 1, 2).astype(np.float32)
        (o1, r1, _, t1, i1), (o2, r2, _, t2, i2) = (e.step(action) for e in envs)
        assert np.array_equal(o1, o2) and r1 == r2 and t1 == t2
        if t1:
            break
    assert i1["episode_score"].to_flat_dict() == i2["episode_score"].to_flat_dict()
