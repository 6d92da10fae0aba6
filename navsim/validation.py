"""One validation pass over a scenario, before any work starts.

Each section of a :class:`~navsim.scenario.Scenario` checks its own values when it is
built (types, signs, whole-multiple rates). This pass checks what needs several sections
at once, the settings that are well-formed but physically meaningless or beyond the
machine, and is called by :class:`~navsim.simulator.Simulator` (so by every entry point:
the CLI, :func:`~navsim.episode.run_episode`, the Gymnasium envs, the FMUs, campaign
tasks) and by campaign loading before any episode runs.

Refused (:class:`~navsim.errors.ConfigError`, naming the field, the expectation, the value):

* an override of the IMU or GNSS error model (``[imu.gyro]``, ``[imu.accel]``,
  ``gnss.overrides``) that names no field of the model or that the model refuses
  (:mod:`navsim.sensors.models`: the same build the simulator uses);
* a body oscillation at or above the IMU's Nyquist frequency ``1 / (2 imu_period_s)``:
  the sampled increments alias it to another frequency (Shannon);
* an outage window starting before the episode (``t < 0`` does not exist);
* an IMU period whose truth-generator block matrices need more memory than the machine
  has (:func:`truth_block_bytes`: a block of ``round(1 s / imu_period_s)`` samples fitted
  with 32 Chebyshev nodes, the matrices of :func:`navsim.truthgen._run_matrices`);
* a navigation step whose IMU samples need more memory than the machine has
  (estimate: :data:`BYTES_PER_IMU_SAMPLE_NODE` per sample and quadrature node).

"What the machine has" is its physical memory (:func:`machine_memory_bytes`:
``os.sysconf('SC_PHYS_PAGES') * os.sysconf('SC_PAGE_SIZE')``, else ``MemTotal`` of
/proc/meminfo; no check where neither exists): a fixed figure, so the same scenario is
refused or accepted whatever else runs at the time. Both estimates are made from the
scenario's numbers before anything is allocated.

:func:`check_episode_memory` refuses an episode whose record (truth and estimates of
every step, kept by :class:`~navsim.episode.EpisodeRecorder` for scoring: ``navsim run``,
``bench``, campaigns, the Gymnasium envs, the FMU master) would not fit
(:data:`EPISODE_BYTES_PER_STEP` per navigation step); streaming faces (``navsim
simulate``, the plant FMU) keep no record and are not limited by the episode length.

A window after the episode end is accepted without a word: shortening a scenario
(``--set timing.duration_s=60``) is the usual way to run the start of an episode.

:func:`check_seed` and :func:`check_steps` guard the run-time arguments (seed >= 0, a
positive whole number of steps per chunk, and a chunk that fits in memory).

The option checks shared by the estimators' option classes (``check_choice``,
``check_positive_finite``, ...) live in :mod:`navsim.option_checks`, which imports nothing
of the truth side (the estimators use them), and are re-exported here.
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING, SupportsIndex

from .errors import ConfigError
from .option_checks import (
    check_auto_none,
    check_choice,
    check_integer,
    check_nonnegative_finite,
    check_optional_positive_finite,
    check_positive_finite,
    check_probability,
    check_time_constant,
)
from .sensors.models import build_gnss_error_model, build_imu_model

if TYPE_CHECKING:  # type hints only
    from .scenario import Scenario

__all__ = ["validate_scenario", "check_seed", "check_steps", "check_episode_memory", "machine_memory_bytes",
           "truth_block_bytes", "BYTES_PER_IMU_SAMPLE_NODE", "EPISODE_BYTES_PER_STEP", "check_choice",
           "check_auto_none", "check_positive_finite", "check_optional_positive_finite", "check_time_constant",
           "check_integer", "check_probability", "check_nonnegative_finite"]

BYTES_PER_IMU_SAMPLE_NODE = 400
"""Working memory of the truth generator per IMU sample and quadrature node, bytes (an
upper estimate: position, velocity, attitude and their rates at each node, the multiple
integrals and the sensor-error arrays of the sample, in float64 with temporaries)."""


EPISODE_BYTES_PER_STEP = 4096
"""Memory of an episode's record and scoring per navigation step, bytes (an upper
estimate: twice the peak growth per step measured for lc-ekf and tc-ukf episodes: truth,
estimates, covariances and the metrics' temporaries)."""


def machine_memory_bytes() -> int | None:
    """The machine's physical memory, bytes (``SC_PHYS_PAGES``, else /proc/meminfo
    ``MemTotal``), or None where neither is available."""
    try:
        pages, size = int(os.sysconf("SC_PHYS_PAGES")), int(os.sysconf("SC_PAGE_SIZE"))
        if pages > 0 and size > 0:
            return pages * size
    except (ValueError, OSError, AttributeError):
        pass
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemTotal:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _gib(n: float) -> str:
    return f"{n / 2**30:.3g} GiB"


def _step_bytes(scenario: Scenario) -> int:
    timing = scenario.timing
    return timing.samples_per_step * scenario.imu.quadrature_nodes * BYTES_PER_IMU_SAMPLE_NODE


def truth_block_bytes(scenario: Scenario) -> int:
    """Bytes of the truth generator's block matrices for this scenario's IMU period.

    A block spans ``m = max(1, round(block_s / h))`` samples fitted with ``n`` Chebyshev
    nodes (the defaults of :class:`~navsim.truthgen.TruthGenerator`); the matrices hold
    ``m (q + R + 1) n`` float64 values (the Gauss-Legendre basis of ``q = n // 2 + R + 2``
    points per sample, the ``R`` integral rows and the sample-end row), counted twice
    for the temporaries of their products.
    """
    import inspect

    from .truthgen import TruthGenerator

    params = inspect.signature(TruthGenerator).parameters
    block_s, n = float(params["block_s"].default), int(params["cheb_nodes"].default)
    m = max(1, round(block_s / scenario.timing.imu_period_s))
    R = int(scenario.imu.orders)
    q = n // 2 + R + 2
    return 2 * 8 * m * (q + R + 1) * n


def validate_scenario(scenario: Scenario) -> None:
    """Check the cross-section and physical sense of a scenario (see the module notes)."""
    build_imu_model(scenario)  # the overrides of [imu.gyro], [imu.accel] and gnss.overrides
    build_gnss_error_model(scenario)
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
    avail = machine_memory_bytes()
    if avail is None:
        return
    block = truth_block_bytes(scenario)
    if block > avail:
        raise ConfigError("timing.imu_period_s",
                          f"an IMU period whose truth generation fits in memory (a 1-s block of "
                          f"{max(1, round(1.0 / timing.imu_period_s)):.3g} samples needs ~{_gib(block)}, "
                          f"the machine has {_gib(avail)})", timing.imu_period_s)
    step = _step_bytes(scenario)
    if step > avail:
        raise ConfigError("timing.imu_period_s",
                          f"an IMU period giving navigation steps that fit in memory (one step of "
                          f"{timing.samples_per_step} samples needs ~{_gib(step)}, the machine has {_gib(avail)})",
                          timing.imu_period_s)


def check_episode_memory(n_steps: SupportsIndex) -> None:
    """Refuse an episode record of ``n_steps`` navigation steps that would not fit in the
    machine's memory (:data:`EPISODE_BYTES_PER_STEP` per step); called by
    :class:`~navsim.episode.EpisodeRecorder` before it allocates anything."""
    avail = machine_memory_bytes()
    n = int(n_steps)
    need = n * EPISODE_BYTES_PER_STEP
    if avail is not None and need > avail:
        raise ConfigError("timing.duration_s / timing.nav_period_s",
                          f"an episode whose record fits in memory ({n:.4g} navigation steps need "
                          f"~{_gib(need)}, the machine has {_gib(avail)}; a shorter episode or a longer navigation "
                          "step)", n)


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
    avail = machine_memory_bytes()
    if avail is not None and need > avail:
        raise ConfigError(field, f"a number of steps whose IMU samples fit in memory (~{_gib(need)} "
                                 f"needed, the machine has {_gib(avail)}; use fewer steps per chunk)", n)
    return n
