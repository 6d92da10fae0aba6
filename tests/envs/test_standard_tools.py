"""Every env id with the standard tools: gym.make defaults, rgb_array frames at the real
time rate, frame geometry (scale, time stamp), RecordVideo of the two task envs."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import navsim.envs as ne  # noqa: E402
from gymnasium.utils.env_checker import check_env  # noqa: E402

from navsim.earth import WGS84, mat_en  # noqa: E402
from navsim.envs.render import HEIGHT, WIDTH, TrackRenderer, _text_mask  # noqa: E402

TASKS = ("navsim/AdaptiveFilter-v0", "navsim/TrainDriving-v0")
ALL_IDS = (*sorted(ne.env_ids()), *TASKS)
DRIVING = {"motion": {"stations": [{"s_m": 400.0, "dwell_s": 3.0}, {"s_m": 900.0, "dwell_s": 5.0}]}}
SHORT = {"timing": {"duration_s": 6.0}}


def short(env_id):
    return DRIVING if env_id == "navsim/TrainDriving-v0" else SHORT


def step_seconds(env) -> float:
    u = env.unwrapped
    return u.steps_per_decision * u.scenario.timing.nav_period_s if hasattr(u, "steps_per_decision") \
        else u.scenario.timing.nav_period_s


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_defaults_and_every_render_mode(env_id):
    env = gym.make(env_id)  # the registered defaults, nothing overridden
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    env.step(env.action_space.sample())
    env.close()
    assert set(env.unwrapped.metadata["render_modes"]) == {"rgb_array", "human"}
    env = gym.make(env_id, render_mode="rgb_array", **short(env_id))
    env.reset(seed=1)
    first = env.render()
    for _ in range(3):
        env.step(env.action_space.sample())
    frame = env.render()
    assert frame.shape == first.shape == (HEIGHT, WIDTH, 3) and frame.dtype == np.uint8
    assert not np.array_equal(frame, first)  # time stamp and paths moved on
    # real time rate: one frame per step, render_fps = 1 / (simulated seconds per step)
    assert env.metadata["render_fps"] * step_seconds(env) == pytest.approx(1.0, rel=1e-12)
    env.close()


@pytest.mark.parametrize("env_id", TASKS)
def test_task_envs_pass_the_render_check(env_id):
    env = gym.make(env_id, render_mode="rgb_array", **short(env_id))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=False)
    assert [str(w.message) for w in caught] == []


def test_frame_scale_and_time_stamp():
    env = gym.make("navsim/MountainRailway-v0", render_mode="rgb_array", timing={"duration_s": 2.0})
    env.reset(seed=0)
    for _ in range(123):
        env.step(np.zeros(9))
    frame = env.render()
    r: TrackRenderer = env.unwrapped._renderer
    # the map's scale against the track geometry in the WGS-84 local level of the start (independent of the
    # renderer's display projection, a sphere of 6371 km: they agree to ~1e-2 over a 30 km line)
    track = env.unwrapped.sim.track
    from navsim.track import track_frame

    f = track_frame(track, np.array([0.0, track.length]))
    d_e = WGS84.geodetic_to_ecef(f.lat[1], f.lon[1], f.h[1]) - WGS84.geodetic_to_ecef(f.lat[0], f.lon[0], f.h[0])
    enu = mat_en(f.lat[0], f.lon[0]).T @ d_e
    px = np.array(r._px(*r._en(f.lat, f.lon)))
    dist_px = math.hypot(px[0, 1] - px[0, 0], px[1, 1] - px[1, 0])
    assert dist_px / r.scale == pytest.approx(math.hypot(enu[0], enu[1]), rel=1e-2)
    # the scale bar is scale_bar_m long at that scale, a round number of metres
    x0, y0, x1, y1 = r.map_box
    row = frame[y1 - 11, x0 + 10: x1]
    dark = np.flatnonzero(np.all(row < 60, axis=1))
    assert dark[0] == 0 and (dark[-1] - dark[0]) == pytest.approx(r.scale_bar_m * r.scale, abs=1.0)
    assert r.scale_bar_m / 10 ** math.floor(math.log10(r.scale_bar_m)) in (1.0, 2.0, 5.0)
    # the time stamp: 123 steps of 0.01 s
    mask = _text_mask("t = 1.23 s / 2 s")
    title = frame[5:5 + mask.shape[0], 60:60 + mask.shape[1]].astype(float)
    expected = 255.0 * (1 - mask[..., None]) + 30.0 * mask[..., None]
    assert np.abs(title - expected).max() <= 1.0


@pytest.mark.parametrize("env_id", TASKS)
def test_task_envs_record_video_at_the_real_time_rate(env_id, tmp_path):
    pytest.importorskip("moviepy")
    from gymnasium.wrappers import RecordVideo
    from moviepy import VideoFileClip

    env = gym.make(env_id, render_mode="rgb_array", **short(env_id))
    env = RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda e: True, disable_logger=True)
    env.reset(seed=0)
    steps, done = 0, False
    while not done:
        *_, term, trunc, _ = env.step(env.action_space.sample() * 0 + (0.6 if "Driving" in env_id else 0.0))
        steps += 1
        done = term or trunc or steps >= 40
    env.close()
    (video,) = (tmp_path / "videos").glob("*.mp4")
    with VideoFileClip(str(video)) as clip:
        # one frame at reset and one per step: the video lasts the simulated time plus one frame
        assert clip.fps == pytest.approx(1.0 / step_seconds(env))
        assert clip.duration == pytest.approx((steps + 1) * step_seconds(env), abs=0.05 + step_seconds(env))
