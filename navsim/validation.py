"""One validation pass over a scenario, before any work starts.

Each section of a :class:`~navsim.scenario.Scenario` checks its own values when it is
built (types, signs, whole-multiple rates). This pass checks what needs several sections
at once, the settings that are well-formed but physically meaningless or beyond the
machine, and is called by :class:`~navsim.simulator.Simulator` (so by every entry point:
the CLI, :func:`~navsim.episode.run_episode`, the Gymnasium envs, the FMUs, campaign
tasks) and by campaign loading before any episode runs.

Refused (:class:`~navsim.errors.ConfigError`, naming the field, the expectation, the value):

* a body oscillation at or above the IMU's Nyquist frequency ``1 / (2 imu_period_s)``:
  the sampled increments alias it to another frequency (Shannon);
* an outage window starting before the episode (``t < 0`` does not exist);
* a navigation step whose IMU samples need more memory than the machine has available
  (estimate: :data:`BYTES_PER_IMU_SAMPLE_NODE` per sample and quadrature node).

A window after the episode end is accepted without a word: shortening a scenario
(``--set timing.duration_s=60``) is the usual way to run the start of an episode.

:func:`check_seed` and :func:`check_steps` guard the run-time arguments (seed >= 0, a
positive whole number of steps per chunk, and a chunk that fits in memory).
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING, SupportsIndex

from .errors import ConfigError

if TYPE_CHECKING:  # type hints only
    from .scenario import Scenario

__all__ = ["validate_scenario", "check_seed", "check_steps", "available_memory_bytes", "BYTES_PER_IMU_SAMPLE_NODE"]

BYTES_PER_IMU_SAMPLE_NODE = 400
"""Working memory of the truth generator per IMU sample and quadrature node, bytes (an
upper estimate: position, velocity, attitude and their rates at each node, the multiple
integrals and the sensor-error arrays of the sample, in float64 with temporaries)."""


def available_memory_bytes() -> int | None:
    """MemAvailable of /proc/meminfo (Linux), else the free physical pages, else None."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def _step_bytes(scenario: Scenario) -> int:
    timing = scenario.timing
    return timing.samples_per_step * scenario.imu.quadrature_nodes * BYTES_PER_IMU_SAMPLE_NODE


def validate_scenario(scenario: Scenario) -> None:
    """Check the cross-section and physical sense of a scenario (see the module notes)."""
    timing = scenario.timing
    nyquist = 0.5 / timing.imu_period_s
    for i, osc in enumerate(scenario.motion.oscillations):
        f = osc.frequency_hz
        if not (isinstance(f, (int, float)) and math.isfinite(f) and f > 0.0):
            raise ConfigError(f"motion.oscillations[{i}].frequency_hz", "a positive finite frequency, Hz", f)
        if f >= nyquist:
            raise ConfigError(f"motion.oscillations[{i}].frequency_hz",
                              f"a frequency below the IMU Nyquist frequency 1/(2 imu_period_s) = {nyquist:g} Hz "
                              "(higher ones alias in the sampled increments)", f)
    for i, (start, end) in enumerate(scenario.outages.windows_s):
        if start < 0.0:
            raise ConfigError(f"outages.windows_s[{i}]",
                              f"a window inside the episode [0, {timing.duration_s:g}] s (t < 0 does not exist)",
                              [start, end])
    step = _step_bytes(scenario)
    avail = available_memory_bytes()
    if avail is not None and step > avail:
        raise ConfigError("timing.imu_period_s",
                          f"an IMU period giving navigation steps that fit in memory (one step of "
                          f"{timing.samples_per_step} samples needs ~{step / 2**30:.3g} GiB, "
                          f"{avail / 2**30:.3g} GiB available)", timing.imu_period_s)


def check_seed(seed: SupportsIndex | None, field: str = "seed") -> int | None:
    """A seed is None (fresh entropy) or an integer >= 0 (numpy's SeedSequence)."""
    if seed is None:
        return None
    if isinstance(seed, bool) or not isinstance(seed, int) and not (hasattr(seed, "__index__")):
        raise ConfigError(field, "an integer >= 0 (or None for fresh entropy)", seed)
    if int(seed) < 0:
        raise ConfigError(field, "an integer >= 0 (or None for fresh entropy)", seed)
    return int(seed)


def check_steps(n_steps: SupportsIndex, scenario: Scenario, field: str = "chunk") -> int:
    """A positive whole number of navigation steps whose IMU samples fit in memory."""
    if isinstance(n_steps, bool) or not hasattr(n_steps, "__index__") or int(n_steps) < 1:
        raise ConfigError(field, "a positive whole number of navigation steps", n_steps)
    n = int(n_steps)
    need = min(n, scenario.timing.steps) * _step_bytes(scenario)
    avail = available_memory_bytes()
    if avail is not None and need > avail:
        raise ConfigError(field, f"a number of steps whose IMU samples fit in memory (~{need / 2**30:.3g} GiB "
                                 f"needed, {avail / 2**30:.3g} GiB available; use fewer steps per chunk)", n)
    return n
