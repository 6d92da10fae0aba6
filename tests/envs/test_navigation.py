"""The navigation env: registration, spaces, checker, reward, info, determinism, scores."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import navsim.envs as ne  # noqa: E402
from gymnasium.utils.env_checker import check_env  # noqa: E402
from gymnasium.wrappers import FlattenObservation  # noqa: E402

from navsim import estimators  # noqa: E402
from navsim.episode import run_episode  # noqa: E402
from navsim.errors import ConfigError  # noqa: E402
from navsim.metrics import score_episode  # noqa: E402
from navsim.scenario import list_scenarios, load_scenario  # noqa: E402
from navsim.envs.spaces import ACTION_SCALE, solution_to_action  # noqa: E402

SHORT = {"timing": {"duration_s": 3.0}}
CPU_FIELDS = {"step_time_us", "cpu_total_s", "realtime_factor"}


def _truth_action(info) -> np.ndarray:
    return solution_to_action(info["truth"])


def test_one_id_per_scenario_file():
    ids = ne.env_ids()
    assert sorted(ids.values()) == sorted(list_scenarios())
    assert ids["navsim/PaperRail-v0"] == "paper-2012"
    assert ids["navsim/MountainRailway-v0"] == "mountain-railway"
    assert ids["navsim/UrbanRoad-v0"] == "urban-road"
    for env_id in (*ids, "navsim/AdaptiveFilter-v0", "navsim/TrainDriving-v0"):
        assert env_id in gym.registry
    ne.register_envs()  # idempotent


@pytest.mark.parametrize("env_id", sorted(ne.env_ids()))
def test_check_env_without_warnings(env_id):
    env = gym.make(env_id, **SHORT)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=False)
    assert [str(w.message) for w in caught] == []
    env.close()


def test_overrides_config_in_info_and_bad_key():
    env = gym.make("navsim/PaperRail-v0", timing={"duration_s": 2.0}, imu={"preset": "tactical"})
    obs, info = env.reset(seed=1)
    expected = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 2.0}, "imu": {"preset": "tactical"}})
    assert info["config_hash"] == expected.config_hash()
    assert "preset = \"tactical\"" in info["scenario_toml"]
    assert env.unwrapped.n_steps == 200
    assert env.spec.kwargs["imu"] == {"preset": "tactical"}
    with pytest.raises(ConfigError, match="timingg"):
        gym.make("navsim/PaperRail-v0", timingg={"duration_s": 2.0})


def test_observation_is_sensor_data_in_space_and_flattens():
    env = gym.make("navsim/PaperRail-v0", truth_in_info=True, **SHORT)
    flat = FlattenObservation(env)
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    assert set(obs) == set(ne.spaces.OBS_KEYS)
    assert not any("truth" in key or key in ("lat", "lon", "s") for key in obs)
    epochs = 0
    for _ in range(150):
        obs, reward, term, trunc, info = env.step(_truth_action(info))
        assert env.observation_space.contains(obs)
        epochs += int(obs["gnss_new_epoch"][0])
        if not obs["gnss_new_epoch"][0]:
            assert not obs["gnss_valid"].any() and not obs["pseudorange_m"].any()
        else:
            assert obs["gnss_valid"].sum() >= 4 and np.all(obs["pseudorange_m"][obs["gnss_valid"] == 1] > 1.9e7)
    assert epochs == 1  # one epoch per 100 steps at 1 Hz / 100 Hz
    fobs, _ = flat.reset(seed=3)
    assert fobs.shape == flat.observation_space.shape and flat.observation_space.contains(fobs)
    # the time of the first observation is the end of the first step
    obs, _ = env.reset(seed=3)
    assert obs["t"][0] == pytest.approx(0.01)


def test_reward_is_minus_position_error():
    env = gym.make("navsim/UrbanRoad-v0", truth_in_info=True, reward_weights=(1.0, 2.0, 0.0), **SHORT).unwrapped
    obs, info = env.reset(seed=0)
    truth = info["truth"]
    # the true solution scores exactly 0 (the scaling is exact)
    _, r0, *_ , info = env.step(_truth_action(info))
    assert r0 == 0.0
    truth = info["truth"]
    # 12 m north, 5 m east, 3 m up, 0.5 m/s east: e = |(5, 12, 3)| + 2 * 0.5
    r_n, r_e = env.sim.earth.radii(truth[0])
    moved = truth.copy()
    moved[0] += 12.0 / (r_n + truth[2])
    moved[1] += 5.0 / ((r_e + truth[2]) * math.cos(truth[0]))
    moved[2] += 3.0
    moved[3] += 0.5
    _, r1, *_ = env.step(solution_to_action(moved))
    assert r1 == pytest.approx(-(math.sqrt(12.0**2 + 5.0**2 + 3.0**2) + 1.0), rel=1e-9)
    _, r2, *_ = env.step(np.full(9, np.nan))
    assert r2 == -env.reward_cap


def test_truth_only_on_request_and_outage_flags():
    over = {"timing": {"duration_s": 6.0}, "outages": {"windows_s": [[2.5, 4.5]]}}
    env = gym.make("navsim/PaperRail-v0", **over)
    obs, info = env.reset(seed=0)
    assert "truth" not in info and {"context", "prior", "gnss_prn", "receiver_outage"} <= set(info)
    flags = []
    for _ in range(600):
        obs, r, term, trunc, info = env.step(np.zeros(9))
        assert "truth" not in info
        flags.append((obs["t"][0], info["receiver_outage"], info["gnss_n_valid"]))
    assert trunc and not term
    t = np.array([f[0] for f in flags[:-1]])
    out = np.array([f[1] for f in flags[:-1]])
    # info of step k holds the latest epoch at or before the step end (t[k] - 0.01)
    t_info = t - 0.01
    in_window = (t_info >= 3.0 - 1e-9) & (t_info < 5.0 - 1e-9)
    assert np.array_equal(out, in_window)


def test_episode_length_truncation_and_step_after_end():
    env = gym.make("navsim/PaperRail-v0", timing={"duration_s": 1.0}).unwrapped
    env.reset(seed=0)
    for k in range(100):
        obs, r, term, trunc, info = env.step(np.zeros(9))
        assert trunc == (k == 99) and not term
    assert obs["t"][0] == 1.0 and env.observation_space.contains(obs)
    assert "episode_score" in info and info["episode_score"].steps == 100
    with pytest.raises(RuntimeError):
        env.step(np.zeros(9))


def test_determinism_rollout_and_close_twice():
    def rollout(seed):
        env = gym.make("navsim/MountainRailway-v0", timing={"duration_s": 2.0})
        env.action_space.seed(7)
        obs, info = env.reset(seed=seed)
        traj = [obs]
        rewards = []
        while True:
            obs, r, term, trunc, info = env.step(env.action_space.sample())
            traj.append(obs)
            rewards.append(r)
            if term or trunc:
                break
        env.close()
        env.close()  # harmless
        return traj, rewards, info["episode_score"].to_flat_dict()

    a, b, c = rollout(11), rollout(11), rollout(12)
    assert a[1] == b[1] and a[2] == b[2]
    assert all(all(np.array_equal(x[k], y[k]) for k in x) for x, y in zip(a[0], b[0]))
    assert not all(np.array_equal(x["dv_r"], y["dv_r"]) for x, y in zip(a[0], c[0]))  # other seed, other noise


def test_reset_without_seed_is_reproducible_from_first_seed():
    env = gym.make("navsim/PaperRail-v0", **SHORT).unwrapped
    env.reset(seed=4)
    env.reset()
    drawn = env.seed_value
    env.reset(seed=4)
    env.reset()
    assert env.seed_value == drawn != 4


@pytest.mark.parametrize("name", estimators.available())
def test_scores_through_env_equal_run_episode(name):
    """The env's episode score is navsim run's for the same estimator, scenario, seed."""
    over = {"timing": {"duration_s": 2.0}, "outages": {"windows_s": [[0.5, 1.5]]}}
    score = ne.evaluate(name, "navsim/PaperRail-v0", seeds=[5], **over)[0]
    scenario = load_scenario("paper-2012").with_overrides(over)
    ref = score_episode(run_episode(scenario, estimators.make(name), seed=5, name=name, use_batch=False))
    got, want = score.to_flat_dict(), ref.to_flat_dict()
    assert {k: v for k, v in got.items() if k not in CPU_FIELDS} == {k: v for k, v in want.items() if k not in CPU_FIELDS}
    assert got["step_time_us"] > 0  # the agent's own CPU time
    assert score.outage_count == 1


def test_scores_match_batch_path_to_rounding():
    over = {"timing": {"duration_s": 3.0}}
    score = ne.evaluate("lc-ekf", "navsim/PaperRail-v0", seeds=[2], **over)[0].to_flat_dict()
    ref = score_episode(run_episode(load_scenario("paper-2012").with_overrides(over), estimators.make("lc-ekf"),
                                    seed=2, name="lc-ekf")).to_flat_dict()
    for key, value in ref.items():
        if key in CPU_FIELDS:
            continue
        if isinstance(value, float):
            assert score[key] == pytest.approx(value, rel=1e-9, abs=1e-12), key
        else:
            assert score[key] == value, key


def test_estimator_agent_on_physical_actions_and_custom_agent():
    env = gym.make("navsim/PaperRail-v0", physical_action=True, **SHORT)
    assert env.action_space.high[2] == 1e5
    score = ne.evaluate("gnss-ls", env, seeds=[0])[0]

    class Prior:  # a trivial agent: always the prior
        name = "prior"

        def reset(self, info):
            p = info["prior"]
            self.a = np.array([p.lat, p.lon, p.h, *p.velocity_n, p.heading, p.pitch, p.roll])

        def act(self, obs):
            return self.a

    still = ne.evaluate(Prior(), env, seeds=[0])[0]
    assert still.estimator == "prior" and score.estimator == "gnss-ls"
    assert still.horizontal_final_m > 50.0 > score.horizontal_final_m  # 20 m/s for 3 s vs GNSS fixes
    assert np.array_equal(ACTION_SCALE, 2.0 ** np.round(np.log2(ACTION_SCALE)))  # powers of two
