"""render() and close() of the three envs (written once, envs.render.EnvRendering)."""

from __future__ import annotations

import pytest

gym = pytest.importorskip("gymnasium")
import navsim.envs  # noqa: E402,F401  (registers the ids)
from navsim.envs.render import HEIGHT, WIDTH, EnvRendering  # noqa: E402


@pytest.mark.parametrize("env_id", ["navsim/PaperRail-v0", "navsim/AdaptiveFilter-v0", "navsim/TrainDriving-v0"])
def test_render_gives_a_frame_and_close_releases_the_renderer(env_id):
    env = gym.make(env_id, render_mode="rgb_array", timing={"duration_s": 20.0})
    inner = env.unwrapped
    assert isinstance(inner, EnvRendering)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    frame = env.render()
    assert frame.shape == (HEIGHT, WIDTH, 3) and frame.dtype.name == "uint8" and frame.any()
    assert inner._renderer is not None
    env.close()
    assert inner._renderer is None
    env.close()  # harmless twice
