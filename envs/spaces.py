"""Observation and action spaces of the navigation environments, with finite bounds.

The observation is the sensor data of one navigation step ``[t - dt, t]`` as a
:class:`gymnasium.spaces.Dict`, one entry per observation signal of the core's signal
table (:mod:`navsim.signals`, which gives the table of keys, shapes, units and
bounds): float64 boxes, ``MultiBinary`` for the 0/1 flags ``gnss_new_epoch`` and
``gnss_valid``; ``odometer_ds`` only when the scenario has ``[odometer] enabled``.
Every entry is 1-D (flattened row by row). This module only turns the table into
Gymnasium spaces; the bounds (physical limits, so the env never clips) and the
constants :data:`MAX_RATE_RAD_S` etc. are those of :mod:`navsim.signals`.

The action is the agent's navigation solution at the end of the step it last observed,
``[lat, lon, h, vE, vN, vU, heading, pitch, roll]`` (rad, m, m/s, rad): the layout of
:meth:`navsim.estimators.base.Estimate.as_action`, divided by :data:`ACTION_SCALE`
(powers of two) so that the action box is ``[-1, 1]^9``.

References
----------
.. [1] Litmanovich Yu.A. (2002), seed 000, eq. (1.14): multiple-integral increments.
.. [2] Gymnasium documentation, ``gymnasium.spaces.Dict`` and ``FlattenObservation``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike

from navsim.signals import (
    MAX_FORCE_MPS2,
    MAX_RANGE_M,
    MAX_RANGE_RATE_MPS,
    MAX_RATE_RAD_S,
    MAX_SAT_SPEED_MPS,
    MAX_WHEEL_SPEED_MPS,
    OBS_KEYS,
    ODOMETER_KEY,
    SOLUTION_FIELDS,
    Layout,
    observation_signals,
)

if TYPE_CHECKING:  # type hints only
    from navsim.scenario import TimingConfig

__all__ = ["ACTION_SCALE", "solution_to_action", "action_to_solution", "MAX_RATE_RAD_S", "MAX_FORCE_MPS2",
           "MAX_RANGE_M", "MAX_RANGE_RATE_MPS", "MAX_SAT_SPEED_MPS", "MAX_WHEEL_SPEED_MPS", "ACTION_LABELS",
           "observation_space", "layout_space", "action_space", "OBS_KEYS", "ODOMETER_KEY", "check_action"]

ACTION_LABELS = SOLUTION_FIELDS


def layout_space(layout: Layout) -> spaces.Dict:
    """The Dict observation space of a :class:`navsim.signals.Layout`, from the signal table."""
    entries: dict[str, spaces.Space] = {}
    for sig in observation_signals(layout):
        if sig.binary:
            entries[sig.name] = spaces.MultiBinary(sig.size(layout))
        else:
            low, high = sig.bounds(layout)
            entries[sig.name] = spaces.Box(low=low, high=high, dtype=np.float64)
    return spaces.Dict(entries)


def observation_space(timing: TimingConfig, orders: int, n_sats: int, odometer: bool = False) -> spaces.Dict:
    """The Dict observation space of a scenario's time base (see :mod:`navsim.signals`).

    Parameters
    ----------
    timing : navsim.scenario.TimingConfig
    orders : int
        Multiple-integral orders R.
    n_sats : int
        Channels k (satellites of the constellation).
    odometer : bool
        Add the ``odometer_ds`` entry (the scenario has a wheel odometer).
    """
    return layout_space(Layout(orders=int(orders), samples_per_step=int(timing.samples_per_step),
                               channels=int(n_sats), odometer=bool(odometer),
                               nav_period_s=float(timing.nav_period_s), imu_period_s=float(timing.imu_period_s),
                               duration_s=float(timing.duration_s)))


ACTION_SCALE = np.array([2.0, 4.0, 2.0**17, 2.0**10, 2.0**10, 2.0**10, 8.0, 2.0, 4.0])
"""Units of the normalised action: ``solution = action * ACTION_SCALE`` (rad, rad, m, m/s,
m/s, m/s, rad, rad, rad). Powers of two, so the scaling is exact in floating point and
scores equal those of the unscaled solution bit for bit. The ranges they give: latitude
+-pi/2 (inside +-2), longitude +-pi (+-4), height +-131 km, velocity +-1024 m/s,
heading +-8 rad (estimators report [0, 2 pi) or (-pi, pi]), pitch +-2, roll +-4."""


def solution_to_action(solution: ArrayLike) -> np.ndarray:
    """Normalised action of a solution ``[lat, lon, h, vE, vN, vU, heading, pitch, roll]``."""
    return np.asarray(solution, dtype=float) / ACTION_SCALE


def action_to_solution(action: ArrayLike) -> np.ndarray:
    """The solution of a normalised action (exact inverse of :func:`solution_to_action`)."""
    return np.asarray(action, dtype=float) * ACTION_SCALE


def action_space(physical: bool = False) -> spaces.Box:
    """The navigation-solution action.

    Default: the normalised solution ``solution / ACTION_SCALE`` in ``[-1, 1]^9``
    (Gymnasium's checker and RL libraries expect normalised boxes). ``physical=True``:
    the solution itself with bounds latitude +-pi/2, longitude +-pi, height -1e4..1e5 m,
    velocity +-1e3 m/s, heading +-2 pi, pitch +-pi/2, roll +-pi. Either way the env
    scores the action as it comes and never clips it: the bounds describe the space for
    learners.
    """
    if not physical:
        return spaces.Box(low=-1.0, high=1.0, shape=(9,), dtype=np.float64)
    pi = math.pi
    low = np.array([-pi / 2, -pi, -1e4, -1e3, -1e3, -1e3, -2 * pi, -pi / 2, -pi])
    high = np.array([pi / 2, pi, 1e5, 1e3, 1e3, 1e3, 2 * pi, pi / 2, pi])
    return spaces.Box(low=low, high=high, dtype=np.float64)


def check_action(action: ArrayLike, shape: tuple[int, ...], expected: str, name: str = "action") -> np.ndarray:
    """The action as a float64 array of ``shape``, checked before an env changes any state.

    The one action check of every env (single, vector, the two tasks, the SB3 adapter).
    Accepted: real numbers (integers or floats; bool, complex, strings, objects and None
    are refused) whose array has ``shape``, or ``(1,) + shape`` (a batch of one, from a
    policy's ``predict``; the leading axis is dropped). Anything else raises
    :class:`~navsim.errors.ConfigError` naming ``name``, ``expected`` and what came (its
    type or shape, never its contents). Values are returned as they are, non-finite and
    out-of-bounds ones included: each env documents what it does with those (the
    navigation envs score a non-finite solution at ``-reward_cap``; the tasks refuse it
    or clip out-of-bounds values to the box).
    """
    from navsim.errors import ConfigError

    try:
        arr = np.asarray(action)
    except (TypeError, ValueError):  # ragged sequences
        raise ConfigError(name, expected, f"a value of type {type(action).__name__}") from None
    if arr.dtype.kind not in "iuf":
        raise ConfigError(name, expected, f"a value of type {type(action).__name__} (dtype {arr.dtype})")
    if arr.shape != tuple(shape):
        if arr.shape == (1, *shape):
            arr = arr[0]
        else:
            raise ConfigError(name, expected, f"an array of shape {arr.shape}")
    return np.asarray(arr, dtype=np.float64)
