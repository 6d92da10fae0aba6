"""Stable-Baselines3's env checker (optional: the ``rl`` extra; skipped without it)."""

from __future__ import annotations

import warnings

import numpy as np

import pytest

gym = pytest.importorskip("gymnasium")
sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")

import navsim.envs as ne  # noqa: E402

SHORT = {"timing": {"duration_s": 3.0}}
DRIVING = {"motion": {"stations": [{"s_m": 400.0, "dwell_s": 3.0}, {"s_m": 900.0, "dwell_s": 5.0}]}}
# the one recommendation deliberately not followed: a float32 action would quantise latitude to ~0.5 m
FLOAT64_ACTION = "Your action space has dtype float64"


@pytest.mark.parametrize("env_id", [*sorted(ne.env_ids()), "navsim/AdaptiveFilter-v0", "navsim/TrainDriving-v0"])
def test_sb3_check_env(env_id):
    env = gym.make(env_id, **(DRIVING if env_id == "navsim/TrainDriving-v0" else SHORT))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_checker.check_env(env.unwrapped, warn=True)
    messages = [str(w.message) for w in caught]
    expected = [] if env_id in ("navsim/AdaptiveFilter-v0", "navsim/TrainDriving-v0") else [FLOAT64_ACTION]
    assert [m for m in messages if not any(m.startswith(e) for e in expected)] == []


@pytest.mark.parametrize("env_id", [*sorted(ne.env_ids()), "navsim/AdaptiveFilter-v0", "navsim/TrainDriving-v0"])
def test_make_vec_env_with_its_defaults(env_id):
    """SB3's make_vec_env asks gym.make for render_mode="rgb_array" (its default): every id accepts it."""
    from stable_baselines3.common.env_util import make_vec_env

    venv = make_vec_env(env_id, n_envs=2, seed=0,
                        env_kwargs=DRIVING if env_id == "navsim/TrainDriving-v0" else SHORT)
    assert venv.render_mode == "rgb_array"
    obs = venv.reset()
    for _ in range(3):
        obs, rewards, dones, infos = venv.step(np.stack([venv.action_space.sample() for _ in range(2)]))
    assert rewards.shape == (2,) and np.all(np.isfinite(rewards))
    frames = venv.get_images()
    assert len(frames) == 2 and frames[0].shape[2] == 3
    venv.close()
