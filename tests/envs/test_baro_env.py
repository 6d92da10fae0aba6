"""The barometric altimeter in the faces: declared once in navsim.signals, it appears in the
navigation env's observation (space, checker), the vector env and EstimatorAgent's decoding."""

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
from navsim.signals import Layout, ObservationCodec  # noqa: E402
from navsim.simulator import Simulator  # noqa: E402

BARO = {"baro": {"enabled": True}}
OVER = {"timing": {"duration_s": 3.0}, "outages": {"windows_s": [[1.0, 2.5]]}}
CPU_FIELDS = {"step_time_us", "cpu_total_s", "realtime_factor"}


def test_check_env_with_baro_without_warnings():
    env = gym.make("navsim/PaperRail-v0", **OVER, **BARO)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)
    assert [str(w.message) for w in caught] == []
    env.close()


def test_observation_key_only_with_baro_and_equal_to_the_simulator():
    plain = gym.make("navsim/PaperRail-v0", **OVER)
    assert "baro_alt" not in plain.observation_space.spaces
    env = gym.make("navsim/PaperRail-v0", chunk_steps=70, **OVER, **BARO)
    space = env.observation_space
    assert "baro_alt" in space.spaces and np.all(np.isfinite(space["baro_alt"].high))
    obs, _ = env.reset(seed=4)
    seen = [obs["baro_alt"][0]]
    while True:
        obs, _, _, truncated, _ = env.step(env.action_space.sample() * 0)
        assert space.contains(obs)
        if truncated:
            break
        seen.append(obs["baro_alt"][0])
    sim = Simulator(load_scenario("paper-2012").with_overrides({**OVER, **BARO}))
    sim.reset(4)
    want = np.concatenate([c.baro.altitude_m for c in sim.chunks(1000)])
    assert np.array_equal(np.array(seen), want)


def test_codec_round_trip_and_vector_env():
    sc = load_scenario("paper-2012").with_overrides({**OVER, **BARO})
    sim = Simulator(sc)
    sim.reset(2)
    chunk = sim.advance(150)
    codec = ObservationCodec(Layout.of(sc, len(sim.constellation.prn)), sim.constellation.prn)
    rows = codec.encode_chunk(chunk)
    np.testing.assert_array_equal(rows["baro_alt"][:, 0], chunk.baro.altitude_m)
    for i in (0, 99):  # no epoch, epoch at step 99 (1 s)
        obs = codec.observation(rows, i)
        m = codec.decode(obs, chunk.step0 + i)
        assert m.baro_alt_m == chunk.baro.altitude_m[i]
        back = codec.encode_measurement(m)
        assert set(back) == set(obs)
        for key in obs:
            np.testing.assert_array_equal(np.asarray(back[key], dtype=float), np.asarray(obs[key], dtype=float))
    venv = gym.make_vec("navsim/PaperRail-v0", num_envs=2, vectorization_mode="vector_entry_point", **OVER, **BARO)
    obs, _ = venv.reset(seed=[2, 3])
    assert obs["baro_alt"].shape == (2, 1)
    assert obs["baro_alt"][0, 0] == chunk.baro.altitude_m[0]
    venv.close()


@pytest.mark.parametrize("name", ["lc-ekf", "tc-ekf"])
def test_estimator_agent_passes_the_baro_on(name):
    """Through the env the estimator gets the barometer: the score equals run_episode's on
    the barometer scenario and differs from the estimator told to ignore it."""
    score = ne.evaluate(name, "navsim/PaperRail-v0", seeds=[5], **OVER, **BARO)[0].to_flat_dict()
    scenario = load_scenario("paper-2012").with_overrides({**OVER, **BARO})
    ref = score_episode(run_episode(scenario, estimators.make(name), seed=5, name=name, use_batch=False)).to_flat_dict()
    assert {k: v for k, v in score.items() if k not in CPU_FIELDS} == {k: v for k, v in ref.items() if k not in CPU_FIELDS}
    blind = score_episode(run_episode(scenario, estimators.make(name, baro="none"), seed=5, name=name,
                                      use_batch=False)).to_flat_dict()
    assert blind["vertical_rmse_m"] != score["vertical_rmse_m"]
