"""Stable-Baselines3's env checker (optional: the ``rl`` extra; skipped without it)."""

from __future__ import annotations

import warnings

import numpy as np

import pytest

gym = pytest.importorskip("gymnasium")
sb3_checker = pytest.importorskip(
    "stable_baselines3.common.env_checker",
    reason="stable-baselines3 is in the test extra only on Python 3.11 (torch's CPU build); elsewhere: the rl extra")

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


def _same(a: dict, b: dict) -> bool:
    return set(a) == set(b) and all(np.array_equal(a[k], b[k]) for k in a)


def test_sb3_adapter_equals_the_native_vector_env_through_an_episode_end():
    from navsim.envs.sb3 import GymnasiumVecEnv

    kw = {"timing": {"duration_s": 0.05}}  # 5 steps
    native = gym.make_vec("navsim/PaperRail-v0", num_envs=3, vectorization_mode="vector_entry_point", **kw)
    adapter = GymnasiumVecEnv(gym.make_vec("navsim/PaperRail-v0", num_envs=3, vectorization_mode="vector_entry_point",
                                           **kw))
    assert adapter.seed(7) == [7, 8, 9]
    obs_a = adapter.reset()
    obs_n, info_n = native.reset(seed=7)
    assert _same(obs_a, obs_n) and [i["seed"] for i in adapter.reset_infos] == [7, 8, 9]
    rng = np.random.default_rng(0)
    for k in range(5):
        actions = rng.uniform(-1, 1, (3, 9)).astype(np.float32)
        obs_a, rew_a, done_a, infos = adapter.step(actions)
        obs_n, rew_n, term_n, trunc_n, info_n = native.step(actions)
        assert np.array_equal(rew_a, rew_n.astype(np.float32))
        assert np.array_equal(done_a, term_n | trunc_n) and done_a.all() == (k == 4)
    # SB3's convention at the end: the last observation in the info, the next episode's first one returned
    for j in range(3):
        assert _same(infos[j]["terminal_observation"], {key: v[j] for key, v in obs_n.items()})
        assert infos[j]["TimeLimit.truncated"] is True
        assert infos[j]["episode_score"].steps == 5
    assert np.all(obs_a["t"] == 0.01) and obs_a["t"].shape == (3, 1)
    assert adapter.observation_space == native.single_observation_space
    adapter.close()
    native.close()


def test_ppo_trains_on_the_native_vector_env_through_the_adapter():
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor

    from navsim.envs.sb3 import make_sb3_vec_env

    venv = VecMonitor(make_sb3_vec_env("navsim/PaperRail-v0", num_envs=4, seed=0, score=False,
                                       timing={"duration_s": 1.0}))  # 100-step episodes
    model = PPO("MultiInputPolicy", venv, n_steps=128, batch_size=256, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=2048)
    assert model.num_timesteps == 2048
    episodes = list(model.ep_info_buffer)
    assert len(episodes) == 4 * 5 and all(ep["l"] == 100 for ep in episodes)  # 2048 steps = 4 envs x 5 episodes of 100
    assert all(np.isfinite(ep["r"]) and ep["r"] < 0 for ep in episodes)  # minus position errors
    venv.close()


def test_make_sb3_vec_env_for_the_task_ids_uses_single_envs():
    from stable_baselines3.common.vec_env import DummyVecEnv

    from navsim.envs.sb3 import GymnasiumVecEnv, make_sb3_vec_env

    venv = make_sb3_vec_env("navsim/AdaptiveFilter-v0", num_envs=2, seed=1, **SHORT)
    assert isinstance(venv, DummyVecEnv) and not isinstance(venv, GymnasiumVecEnv)
    venv.reset()
    venv.close()
