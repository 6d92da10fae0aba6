"""Gymnasium actions (issue 16): shape and dtype are checked in step() before any state
changes, with a clear error; a non-finite action scores the documented reward cap."""

from __future__ import annotations

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import navsim.envs  # noqa: E402,F401  (registers the ids)
from navsim.errors import ConfigError  # noqa: E402


def _env():
    env = gym.make("navsim/PaperRail-v0", timing={"duration_s": 3.0}).unwrapped
    obs, info = env.reset(seed=0)
    return env, info


@pytest.mark.parametrize("bad", [np.zeros(3), np.zeros(20), np.zeros((3, 3)), np.array(["a"] * 9), "nine", None,
                                 np.zeros(9, dtype=complex)])
def test_wrong_shape_or_dtype_is_refused_before_any_state_change(bad):
    env, info = _env()
    k = env._k
    with pytest.raises(ConfigError, match="action"):
        env.step(bad)
    assert env._k == k  # nothing moved: the episode goes on with a good action
    good = np.asarray(info["prior"].as_action() if hasattr(info.get("prior"), "as_action") else env.action_space.sample(),
                      dtype=float)
    env.step(good)
    assert env._k == k + 1


@pytest.mark.parametrize("value", [np.inf, -np.inf, np.nan])
def test_non_finite_action_scores_the_reward_cap(value):
    env, _ = _env()
    action = np.full(9, value)
    _, reward, *_ = env.step(action)
    assert reward == -env.reward_cap
