"""The wheel odometer in the navigation env: observation key, space, checker, agent."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import navsim.envs as ne  # noqa: E402
from gymnasium.utils.env_checker import check_env  # noqa: E402

from navsim import estimators  # noqa: E402
from navsim.episode import run_episode  # noqa: E402
from navsim.metrics import score_episode  # noqa: E402
from navsim.scenario import load_scenario  # noqa: E402
from navsim.simulator import Simulator  # noqa: E402

ODO = {"odometer": {"enabled": True, "preset": "rail-tachometer"}}
OVER = {"timing": {"duration_s": 3.0}, "outages": {"windows_s": [[1.0, 2.5]]}}
CPU_FIELDS = {"step_time_us", "cpu_total_s", "realtime_factor"}


def test_check_env_with_odometer_without_warnings():
    env = gym.make("navsim/MountainRailway-v0", **OVER, **ODO)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)
    assert [str(w.message) for w in caught] == []
    env.close()


def test_observation_key_only_with_odometer_and_equal_to_the_simulator():
    plain = gym.make("navsim/MountainRailway-v0", **OVER)
    obs, _ = plain.reset(seed=0)
    assert set(obs) == set(ne.spaces.OBS_KEYS)
    env = gym.make("navsim/MountainRailway-v0", chunk_steps=70, **OVER, **ODO)
    space = env.observation_space
    assert "odometer_ds" in space.spaces and np.all(np.isfinite(space["odometer_ds"].high))
    obs, info = env.reset(seed=4)
    seen = [obs["odometer_ds"][0]]
    while True:
        obs, _, _, truncated, info = env.step(env.action_space.sample() * 0)
        assert space.contains(obs)
        if truncated:
            break
        seen.append(obs["odometer_ds"][0])
    sim = Simulator(load_scenario("mountain-railway").with_overrides({**OVER, **ODO}))
    sim.reset(4)
    want = np.concatenate([c.odometer.ds_m for c in sim.chunks(1000)])
    assert np.array_equal(np.array(seen), want)
    assert obs["odometer_ds"].shape == (1,) and obs["odometer_ds"][0] == 0.0  # terminal observation


@pytest.mark.parametrize("name", ["along-track", "lc-ekf"])
def test_estimator_agent_passes_the_odometer_on(name):
    """Through the env the estimator gets the odometer: the score equals run_episode's
    on the odometer scenario and differs from the estimator told to ignore it."""
    score = ne.evaluate(name, "navsim/MountainRailway-v0", seeds=[5], **OVER, **ODO)[0].to_flat_dict()
    scenario = load_scenario("mountain-railway").with_overrides({**OVER, **ODO})
    ref = score_episode(run_episode(scenario, estimators.make(name), seed=5, name=name, use_batch=False)).to_flat_dict()
    assert {k: v for k, v in score.items() if k not in CPU_FIELDS} == {k: v for k, v in ref.items() if k not in CPU_FIELDS}
    blind = score_episode(run_episode(scenario, estimators.make(name, odometer="none"), seed=5, name=name,
                                      use_batch=False)).to_flat_dict()
    assert blind["horizontal_rmse_m"] != score["horizontal_rmse_m"]
