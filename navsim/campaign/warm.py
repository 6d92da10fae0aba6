"""Warm-up of the local campaign workers' fork server (imported there, see :mod:`navsim.campaign.executors`).

Local workers are forked from a fork server that imported the episode code once. What an
episode loads lazily on its first run (numba and llvmlite, the compiled kernels of
:mod:`navsim.truthgen_kernel`, :mod:`navsim.sensors.imu.kernel` and
:mod:`navsim.strapdown.compiled` from numba's disk cache, threadpoolctl, scipy.signal)
would otherwise be loaded again by every worker on its first episode, about 0.8 s of CPU
each (measured in ``CHANGELOG.md``, issue 13), so that a pool of two workers paid it twice.
Importing this module runs one 1-s episode of the paper scenario with the loosely coupled
EKF, which loads all of them; the forked workers inherit them.

The warm-up changes no number (it runs in the fork server, whose random streams and state
no episode uses) and never stops a campaign: if it fails, the workers load what they need
themselves, as before.
"""

from __future__ import annotations


def warm() -> bool:
    """Run the warm-up episode; True if it ran, False if it failed (then nothing is warmed)."""
    try:
        import scipy.signal  # noqa: F401  (lazy in the IMU error model's recursions)

        from ..episode import run_episode
        from ..estimators import make
        from ..scenario import load_scenario

        scenario = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 1.0}})
        run_episode(scenario, make("lc-ekf"), seed=0)
    except Exception:  # noqa: BLE001 - an optimisation only: the workers warm themselves
        return False
    return True


WARMED = warm()
"""Whether the warm-up episode ran when this module was imported."""
