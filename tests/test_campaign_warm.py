"""The fork server's warm-up (navsim.campaign.warm): its episode runs and loads what a first episode loads."""

from __future__ import annotations

import sys

import pytest

from navsim import jit
from navsim.campaign import executors


def test_warm_up_is_preloaded_by_the_fork_server():
    assert "navsim.campaign.warm" in executors._FORKSERVER_PRELOAD


@pytest.mark.skipif(not jit.available(), reason="numba not installed (extra 'fast')")
def test_warm_up_episode_loads_the_compiled_kernels():
    from navsim import truthgen_kernel
    from navsim.campaign import warm
    from navsim.sensors.imu import kernel as imu_kernel
    from navsim.strapdown import compiled as ins_kernel

    assert warm.warm()  # the episode ran (a failure would only cost the workers their warm start)
    assert "numba" in sys.modules and "scipy.signal" in sys.modules
    assert truthgen_kernel._compiled and imu_kernel._compiled and ins_kernel._compiled
