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


# ------------------------------------------------------------------ every other env
# (id, kwargs, good action, wrong shapes); the checks are the one helper
# navsim.envs.spaces.check_action, so these test each env's wiring of it.
BAD_DTYPES = [np.array(["a"]), "text", None, np.array([1 + 2j]), np.array([True]), [object()]]
TASKS = {
    "adaptive": ("navsim/AdaptiveFilter-v0", {"timing": {"duration_s": 4.0}}, np.zeros(2), [np.zeros(3), np.zeros(1),
                                                                                            np.zeros((2, 2))]),
    "driving": ("navsim/TrainDriving-v0", {"motion": {"stations": [{"s_m": 400.0, "dwell_s": 3.0},
                                                                   {"s_m": 900.0, "dwell_s": 5.0}]}},
                np.full(1, 0.5), [np.zeros(2), np.zeros((3, 1)), np.zeros(0)]),
}


def _task(key):
    env_id, kw, good, _ = TASKS[key]
    env = gym.make(env_id, **kw).unwrapped
    env.reset(seed=3)
    return env, good


@pytest.mark.parametrize("key", sorted(TASKS))
@pytest.mark.parametrize("which", range(3 + len(BAD_DTYPES)))
def test_tasks_refuse_wrong_shape_or_dtype_before_any_state_change(key, which):
    bad = (TASKS[key][3] + BAD_DTYPES)[which]
    env, good = _task(key)
    if which >= 3 and isinstance(bad, np.ndarray) and bad.size == 1 and good.size != 1:
        bad = np.resize(bad, good.shape)  # right shape, wrong dtype
    k = env._k
    with pytest.raises(ConfigError, match="action"):
        env.step(bad)
    assert env._k == k
    # the refused call changed nothing: the next good step equals that of an untouched env
    fresh, _ = _task(key)
    a, b = env.step(good), fresh.step(good)
    assert np.array_equal(a[0], b[0]) and a[1] == b[1]


def test_adaptive_refuses_non_finite_and_clips_out_of_bounds():
    for value in (np.nan, np.inf, -np.inf):
        env, good = _task("adaptive")
        with pytest.raises(ConfigError, match="finite"):
            env.step(np.array([0.0, value]))
        assert env._k == _task("adaptive")[0]._k
    env, _ = _task("adaptive")
    twin, _ = _task("adaptive")
    _, r_out, *_, info = env.step(np.array([5.0, -7.0]))  # outside the box: clipped to (1, -1)
    _, r_in, *_, info_in = twin.step(np.array([1.0, -1.0]))
    q0, r0 = env.untuned_scale
    assert r_out == r_in and info["q_scale"] == pytest.approx(10.0 * q0) and info["r_scale"] == pytest.approx(0.1 * r0)


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf, -5.0])
def test_driving_non_finite_or_below_the_box_is_the_full_brake(value):
    env, _ = _task("driving")
    twin, _ = _task("driving")
    traction, _ = _task("driving")
    for _ in range(4):
        a = env.step(np.array([value]))
        b = twin.step(np.array([-1.0]))
        c = traction.step(np.array([1.0]))
        assert a[1] == b[1] and np.array_equal(a[0], b[0])
    assert not np.array_equal(a[0], c[0])  # not dwelling: the command mattered


def _vec(n=2):
    env = gym.make_vec("navsim/PaperRail-v0", num_envs=n, vectorization_mode="vector_entry_point",
                       timing={"duration_s": 0.05})
    env.reset(seed=5)
    return env


@pytest.mark.parametrize("bad", [np.zeros(9), np.zeros((3, 9)), np.zeros((2, 8)), np.zeros((2, 9), dtype=complex),
                                 np.full((2, 9), "x"), None, [[0.0] * 9, [0.0] * 8]])
def test_vector_env_refuses_wrong_shape_or_dtype_before_any_state_change(bad):
    env = _vec()
    k = env._k
    with pytest.raises(ConfigError, match="actions"):
        env.step(bad)
    assert env._k == k
    _, r, *_ = env.step(np.zeros((2, 9)))
    _, r_fresh, *_ = _vec().step(np.zeros((2, 9)))
    assert np.array_equal(r, r_fresh)


def test_vector_env_non_finite_rows_score_the_reward_cap():
    env = _vec(3)
    actions = np.zeros((3, 9))
    actions[0, 4] = np.nan
    actions[1, :] = np.inf
    _, r, *_ = env.step(actions)
    _, r_ok, *_ = _vec(3).step(np.zeros((3, 9)))
    cap = env.reward_cap
    assert r[0] == -cap and r[1] == -cap and r[2] == r_ok[2]


def test_sb3_adapter_checks_before_stepping():
    pytest.importorskip("stable_baselines3")
    from navsim.envs.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env("navsim/PaperRail-v0", num_envs=2, seed=0, timing={"duration_s": 0.05})
    venv.reset()
    for bad in (np.zeros((3, 9)), np.zeros(9), np.full((2, 9), "x")):
        with pytest.raises(ConfigError, match="actions"):
            venv.step_async(bad)
    _, rewards, dones, _ = venv.step(np.zeros((2, 9), dtype=np.float32))
    assert rewards.shape == (2,) and not dones.any()
    venv.close()
