"""Observation and action spaces of the navigation environments, with finite bounds.

The observation is the sensor data of one navigation step ``[t - dt, t]`` as a
:class:`gymnasium.spaces.Dict` (every entry float64 unless stated):

==========================  =============  =====================================================
key                         shape          meaning
==========================  =============  =====================================================
``t``                       (1,)           step end time, s
``dtheta_r``                (3R,)          r-fold integrals of the angular rate over the step
                                           (seed 000 eq. 1.14), rad s^(r-1); [0:3] = dTheta
``dv_r``                    (3R,)          the same of the specific force, m/s s^(r-1)
``dtheta_sub``              (3m,)          first-order gyro increments of the m IMU samples, rad
``dv_sub``                  (3m,)          first-order accelerometer increments, m/s
``gnss_new_epoch``          (1,) int8      1 when a GNSS epoch falls at this step end
``gnss_valid``              (k,) int8      channel validity mask (0 between epochs)
``pseudorange_m``           (k,)           pseudorange per channel, m (0 between epochs)
``pseudorange_rate_mps``    (k,)           Doppler as pseudorange rate, m/s
``sat_pos_e``               (3k,)          satellite ECEF position, m
``sat_vel_e``               (3k,)          satellite ECEF velocity, m/s
``odometer_ds``             (1,)           wheel-odometer distance over the step, m (only
                                           when the scenario has ``[odometer] enabled``)
==========================  =============  =====================================================

Vectors are flattened row by row (``obs["dtheta_r"].reshape(R, 3)`` gives the (R, 3)
array of :class:`navsim.estimators.base.Measurement`): every entry is 1-D, as RL
libraries prefer. k is the number of satellites of the scenario's constellation (channel j is always the
same PRN, ``info["gnss_prn"][j]``). Between epochs the GNSS entries are zero with
``gnss_valid == 0``; at an epoch, invalid channels hold finite but meaningless values.

Bounds are physical limits far outside anything a bundled scenario produces, so the
env never clips: an angular rate of :data:`MAX_RATE_RAD_S`, a specific force of
:data:`MAX_FORCE_MPS2`, satellite distances of :data:`MAX_RANGE_M`. The r-fold
integral of a quantity bounded by B over a span dt is bounded by ``B dt^r / r!``.

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

import numpy as np
from gymnasium import spaces

__all__ = ["ACTION_SCALE", "solution_to_action", "action_to_solution", "MAX_RATE_RAD_S", "MAX_FORCE_MPS2", "MAX_RANGE_M", "MAX_RANGE_RATE_MPS", "MAX_SAT_SPEED_MPS",
           "MAX_WHEEL_SPEED_MPS", "ACTION_LABELS", "observation_space", "action_space", "OBS_KEYS", "ODOMETER_KEY"]

MAX_RATE_RAD_S = 50.0
"""Bound of the angular rate, rad/s (above the range of consumer MEMS gyros, about 35 rad/s)."""
MAX_FORCE_MPS2 = 500.0
"""Bound of the specific force, m/s^2 (about 50 g)."""
MAX_RANGE_M = 1.0e8
"""Bound of pseudoranges and satellite ECEF coordinates, m (GNSS orbits: about 2.7e7 m)."""
MAX_RANGE_RATE_MPS = 1.0e5
"""Bound of pseudorange rates, m/s (satellite speeds about 4e3 m/s plus the clock drift)."""
MAX_SAT_SPEED_MPS = 1.0e4
"""Bound of satellite ECEF velocity components, m/s."""
MAX_WHEEL_SPEED_MPS = 500.0
"""Bound of the wheel speed, m/s: the odometer distance of a step is within +-500 dt m
(above any rail or road vehicle, with room for scale-factor and slip errors)."""

ACTION_LABELS = ("lat", "lon", "h", "vE", "vN", "vU", "heading", "pitch", "roll")

OBS_KEYS = ("t", "dtheta_r", "dv_r", "dtheta_sub", "dv_sub", "gnss_new_epoch", "gnss_valid",
            "pseudorange_m", "pseudorange_rate_mps", "sat_pos_e", "sat_vel_e")
"""Keys of every observation; :data:`ODOMETER_KEY` is added with an odometer."""
ODOMETER_KEY = "odometer_ds"


def _integral_bounds(bound: float, span: float, orders: int) -> np.ndarray:
    """(orders, 3) bounds ``B span^r / r!`` of the r-fold integrals, r = 1..orders."""
    r = np.arange(1, orders + 1)
    col = bound * span**r / np.array([math.factorial(int(k)) for k in r], dtype=float)
    return np.repeat(col[:, None], 3, axis=1)


def _box(high: np.ndarray) -> spaces.Box:
    high = np.asarray(high, dtype=np.float64)
    return spaces.Box(low=-high, high=high, dtype=np.float64)


def observation_space(timing, orders: int, n_sats: int, odometer: bool = False) -> spaces.Dict:
    """The Dict observation space of a scenario's time base (see the module table).

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
    dt, h, m = timing.nav_period_s, timing.imu_period_s, timing.samples_per_step
    entries = {
        "t": spaces.Box(0.0, float(timing.duration_s), shape=(1,), dtype=np.float64),
        "dtheta_r": _box(_integral_bounds(MAX_RATE_RAD_S, dt, orders).ravel()),
        "dv_r": _box(_integral_bounds(MAX_FORCE_MPS2, dt, orders).ravel()),
        "dtheta_sub": _box(np.full(3 * m, MAX_RATE_RAD_S * h)),
        "dv_sub": _box(np.full(3 * m, MAX_FORCE_MPS2 * h)),
        "gnss_new_epoch": spaces.MultiBinary(1),
        "gnss_valid": spaces.MultiBinary(n_sats),
        "pseudorange_m": _box(np.full(n_sats, MAX_RANGE_M)),
        "pseudorange_rate_mps": _box(np.full(n_sats, MAX_RANGE_RATE_MPS)),
        "sat_pos_e": _box(np.full(3 * n_sats, MAX_RANGE_M)),
        "sat_vel_e": _box(np.full(3 * n_sats, MAX_SAT_SPEED_MPS)),
    }
    if odometer:
        entries[ODOMETER_KEY] = _box(np.full(1, MAX_WHEEL_SPEED_MPS * dt))
    return spaces.Dict(entries)


ACTION_SCALE = np.array([2.0, 4.0, 2.0**17, 2.0**10, 2.0**10, 2.0**10, 8.0, 2.0, 4.0])
"""Units of the normalised action: ``solution = action * ACTION_SCALE`` (rad, rad, m, m/s,
m/s, m/s, rad, rad, rad). Powers of two, so the scaling is exact in floating point and
scores equal those of the unscaled solution bit for bit. The ranges they give: latitude
+-pi/2 (inside +-2), longitude +-pi (+-4), height +-131 km, velocity +-1024 m/s,
heading +-8 rad (estimators report [0, 2 pi) or (-pi, pi]), pitch +-2, roll +-4."""


def solution_to_action(solution) -> np.ndarray:
    """Normalised action of a solution ``[lat, lon, h, vE, vN, vU, heading, pitch, roll]``."""
    return np.asarray(solution, dtype=float) / ACTION_SCALE


def action_to_solution(action) -> np.ndarray:
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
