"""The strapdown navigation state and solution (plain data shared by the integrators).

:class:`InsState` is the state at one instant (geodetic position, ENU velocity, attitude
quaternion body -> ENU, scalar first, and the compensation of the compensated position
summation); :class:`InsSolution` the rows of a run. Both :mod:`navsim.strapdown.ins`
(which re-exports them) and :mod:`navsim.strapdown.scan` build them, so neither imports
the other for them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

__all__ = ["InsState", "InsSolution"]


@dataclass(frozen=True, slots=True)
class InsState:
    """Navigation state at one instant.

    Parameters
    ----------
    lat, lon : float
        Geodetic latitude and longitude, rad.
    h : float
        Height above the Earth model's surface, m.
    velocity_n : ndarray, shape (3,)
        Ground velocity in ENU components, m/s.
    quat_nb : ndarray, shape (4,)
        Attitude quaternion body -> ENU, scalar first, unit norm.
    compensation : tuple of 3 floats, optional
        Compensated-summation terms of lat, lon, h (rad, rad, m): minus the low-order
        parts lost to rounding, |.| < 1e-16 of the values. Zero for a new state; the
        states returned by :func:`integrate` and :func:`ins_step` carry them so that
        integrating in chunks gives exactly the numbers of one run.
    """

    lat: float
    lon: float
    h: float
    velocity_n: np.ndarray
    quat_nb: np.ndarray
    compensation: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("lat", "lon", "h"):
            value = getattr(self, name)
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise ConfigError(name, "a finite number", value) from None
            if not math.isfinite(number):
                raise ConfigError(name, "a finite number", value)
            object.__setattr__(self, name, number)
        if not abs(self.lat) < 0.5 * math.pi:
            raise ConfigError("lat", "a latitude strictly between -pi/2 and pi/2 rad", self.lat)
        velocity = np.array(self.velocity_n, dtype=float).reshape(-1)
        if velocity.shape != (3,) or not np.all(np.isfinite(velocity)):
            raise ConfigError("velocity_n", "3 finite ENU components, m/s", self.velocity_n)
        quat = np.array(self.quat_nb, dtype=float).reshape(-1)
        if quat.shape != (4,) or not np.all(np.isfinite(quat)):
            raise ConfigError("quat_nb", "4 finite quaternion components", self.quat_nb)
        norm = float(np.linalg.norm(quat))
        if abs(norm - 1.0) > 1e-6:
            raise ConfigError("quat_nb", "a unit quaternion (|q| within 1e-6 of 1)", norm)
        try:
            compensation = tuple(float(x) for x in self.compensation)
        except (TypeError, ValueError):
            raise ConfigError("compensation", "3 finite numbers", self.compensation) from None
        if len(compensation) != 3 or not all(math.isfinite(x) for x in compensation):
            raise ConfigError("compensation", "3 finite numbers", self.compensation)
        object.__setattr__(self, "compensation", compensation)
        velocity.flags.writeable = False
        quat.flags.writeable = False
        object.__setattr__(self, "velocity_n", velocity)
        object.__setattr__(self, "quat_nb", quat)


@dataclass(frozen=True, slots=True)
class InsSolution:
    """The navigation solution at t_0, t_0 + dt, ..., t_0 + n dt.

    Attributes
    ----------
    lat, lon, h : ndarray, shape (n + 1,)
        rad, rad, m.
    velocity_n : ndarray, shape (n + 1, 3)
        ENU, m/s.
    quat_nb : ndarray, shape (n + 1, 4)
        Scalar first, body -> ENU.
    final_compensation : tuple of 3 floats
        :attr:`InsState.compensation` of the last row.
    """

    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    velocity_n: np.ndarray
    quat_nb: np.ndarray
    final_compensation: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __len__(self) -> int:
        return len(self.lat)

    def state(self, index: int) -> InsState:
        """The :class:`InsState` at row ``index`` (negative indices count from the end).

        Only the last row carries its summation compensation (see :attr:`final`).
        """
        last = index in (-1, len(self.lat) - 1)
        return InsState(
            self.lat[index], self.lon[index], self.h[index], self.velocity_n[index], self.quat_nb[index],
            self.final_compensation if last else (0.0, 0.0, 0.0),
        )

    @property
    def final(self) -> InsState:
        """The state at the last row, with its summation compensation."""
        return self.state(-1)
