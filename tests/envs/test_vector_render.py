"""Native vector env against single envs; sync/async modes; rendering and RecordVideo."""

from __future__ import annotations

import weakref

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import navsim.envs  # noqa: E402, F401  (registers the ids)
from navsim.envs.render import HEIGHT, WIDTH  # noqa: E402
from navsim.envs.spaces import solution_to_action  # noqa: E402
from navsim.envs.vector import NavigationVectorEnv  # noqa: E402
from navsim.errors import ConfigError  # noqa: E402

OVER = {"timing": {"duration_s": 3.0}, "outages": {"windows_s": [[1.0, 2.0]]}}


def _prior_actions(info) -> np.ndarray:
    return np.array([solution_to_action([p.lat, p.lon, p.h, *p.velocity_n, p.heading, p.pitch, p.roll])
                     for p in info["prior"]])


def _same(a: dict, b: dict) -> bool:
    return set(a) == set(b) and all(np.array_equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize("extra", [{}, {"odometer": {"enabled": True, "preset": "rail-tachometer"}}],
                         ids=["imu-gnss", "odometer"])
def test_native_vector_equals_single_envs_over_two_episodes(extra):
    """Sub-env j is the single env with seed + j, through an autoreset (NEXT_STEP);
    with a wheel odometer the observations carry ``odometer_ds`` too."""
    n = 3
    over = {**OVER, **extra}
    venv = gym.make_vec("navsim/MountainRailway-v0", num_envs=n, vectorization_mode="vector_entry_point",
                        chunk_steps=130, reward_weights=(1.0, 0.5, 2.0), **over)
    assert isinstance(venv.unwrapped, NavigationVectorEnv)
    singles = [gym.make("navsim/MountainRailway-v0", reward_weights=(1.0, 0.5, 2.0), **over) for _ in range(n)]
    obs_v, info_v = venv.reset(seed=20)
    assert ("odometer_ds" in obs_v) == bool(extra)
    outs = [env.reset(seed=20 + j) for j, env in enumerate(singles)]
    assert venv.observation_space.contains(obs_v)
    for j in range(n):
        assert _same({k: v[j] for k, v in obs_v.items()}, outs[j][0])
    rng = np.random.default_rng(1)
    actions = _prior_actions(info_v)
    steps = singles[0].unwrapped.n_steps
    scores_seen = 0
    for k in range(2 * steps + 2):
        actions = actions + 1e-8 * rng.standard_normal(actions.shape)
        obs_v, rew_v, term_v, trunc_v, info_v = venv.step(actions)
        for j, env in enumerate(singles):
            if k % (steps + 1) == steps:  # NEXT_STEP autoreset: the step after the end resets
                obs_s, info_s = env.reset()
                rew_s, trunc_s = 0.0, False
                assert info_v["seed"][j] == info_s["seed"]
            else:
                obs_s, rew_s, _, trunc_s, info_s = env.step(actions[j])
            assert _same({key: v[j] for key, v in obs_v.items()}, obs_s)
            assert rew_v[j] == rew_s and trunc_v[j] == trunc_s
            assert info_v["receiver_outage"][j] == info_s["receiver_outage"]
            if trunc_s:
                assert info_v["episode_score"][j].to_flat_dict() == info_s["episode_score"].to_flat_dict()
                scores_seen += 1
    assert scores_seen == 2 * n
    # one truth generator for all members (the truth is generated once per chunk)
    members = venv.unwrapped.batch.members
    assert len(members) == n and all(sim.truthgen is members[0].truthgen for sim in members)
    venv.close()
    venv.close()


def test_sync_and_async_modes():
    for mode in ("sync", "async"):
        venv = gym.make_vec("navsim/PaperRail-v0", num_envs=2, vectorization_mode=mode, timing={"duration_s": 0.5})
        obs, info = venv.reset(seed=3)
        native = gym.make_vec("navsim/PaperRail-v0", num_envs=2, vectorization_mode="vector_entry_point",
                              timing={"duration_s": 0.5})
        obs_n, _ = native.reset(seed=3)
        assert _same(obs, obs_n)
        for _ in range(10):
            obs, *_ = venv.step(np.zeros((2, 9)))
            obs_n, *_ = native.step(np.zeros((2, 9)))
        assert _same(obs, obs_n)
        venv.close()
        native.close()


def test_vector_env_refuses_partial_resets_and_external_motion():
    venv = NavigationVectorEnv(2, "paper-2012", timing={"duration_s": 0.5})
    with pytest.raises(ConfigError, match="reset_mask"):
        venv.reset(seed=0, options={"reset_mask": np.array([True, False])})
    with pytest.raises(ConfigError, match="external"):
        NavigationVectorEnv(2, "paper-2012", timing={"duration_s": 0.5}, motion={"profile": "external"})


def test_rgb_array_frames_show_track_truth_estimate_and_outage():
    over = {"timing": {"duration_s": 40.0}, "outages": {"windows_s": [[10.0, 25.0]]}}
    env = gym.make("navsim/PaperRail-v0", render_mode="rgb_array", truth_in_info=True, **over)
    obs, info = env.reset(seed=0)
    first = env.render()
    assert first.shape == (HEIGHT, WIDTH, 3) and first.dtype == np.uint8
    for _ in range(3000):  # 30 s; estimate 30 m north of the truth
        truth = info["truth"].copy()
        truth[0] += 30.0 / 6.37e6
        obs, r, term, trunc, info = env.step(solution_to_action(truth))
    frame = env.render()
    colours = {tuple(c) for c in frame.reshape(-1, 3)}
    assert {(0, 150, 0), (220, 0, 0), (255, 150, 0), (170, 170, 170)} <= colours  # truth, estimate, outage, track
    assert not np.array_equal(frame, first)
    env.close()
    env.close()


def test_human_mode_runs_headless(monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    env = gym.make("navsim/PaperRail-v0", render_mode="human", timing={"duration_s": 0.05})
    env.reset(seed=0)
    for _ in range(5):
        assert env.step(np.zeros(9))[0] is not None
    assert env.render() is None
    env.close()
    env.close()


def test_record_video(tmp_path):
    pytest.importorskip("moviepy")
    from gymnasium.wrappers import RecordVideo

    env = gym.make("navsim/PaperRail-v0", render_mode="rgb_array", timing={"duration_s": 0.3})
    env = RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda e: True, disable_logger=True)
    env.reset(seed=0)
    done = False
    while not done:
        *_, term, trunc, _ = env.step(np.zeros(9))
        done = term or trunc
    env.close()
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000


def test_large_score_record_warns_and_tapes_share_the_truth():
    """300 envs x 100 000 steps x 72 B > 2 GB: a warning; score=False: none."""
    import warnings

    with pytest.warns(UserWarning, match="score=False"):
        NavigationVectorEnv(300, "paper-2012")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        NavigationVectorEnv(300, "paper-2012", score=False)
    venv = NavigationVectorEnv(3, "paper-2012", timing={"duration_s": 0.5})
    venv.reset(seed=0)
    first, second = venv.tapes[0], venv.tapes[1]
    assert second.lat is first.lat and np.all(np.isfinite(first.lat[:10]))
    venv.close()


def test_reused_chunk_buffers_keep_held_observations_and_the_numbers():
    """score=False: the chunks' IMU buffers are reused once nothing references them (the
    pool of SimulatorBatch), yet an observation the caller still holds keeps its values and
    every member's observations stay those of its single env, chunk after chunk."""
    n, chunk = 2, 40
    venv = gym.make_vec("navsim/PaperRail-v0", num_envs=n, vectorization_mode="vector_entry_point",
                        chunk_steps=chunk, score=False, timing={"duration_s": 3.0})
    singles = [gym.make("navsim/PaperRail-v0", score=False, timing={"duration_s": 3.0}) for _ in range(n)]
    venv.reset(seed=5)
    for j, env in enumerate(singles):
        env.reset(seed=5 + j)
    action = np.zeros((n, 9))
    held, held_copy = None, None
    seen: list = []  # weak references to every buffer set's first array met (identity, not id())
    for k in range(6 * chunk):
        obs, *_ = venv.step(action)
        for j, env in enumerate(singles):
            assert _same({key: v[j] for key, v in obs.items()}, env.step(action[j])[0])
        if k == chunk + 3:  # an observation of the second chunk, kept through the later ones
            held = obs
            held_copy = {key: v.copy() for key, v in obs.items()}
        for bufs in venv.unwrapped.batch._pool:
            if not any(ref() is bufs[0] for ref in seen):
                seen.append(weakref.ref(bufs[0]))
    assert _same(held, held_copy)
    # 7 chunks (the reset's and 6 more) from 3 buffer sets: the two the pool alternates
    # between and one more while the held observation kept one busy
    assert len(venv.unwrapped.batch._pool) <= 2 and len(seen) == 3
    venv.close()
