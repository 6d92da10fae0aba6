"""Input checks shared by the coning, sculling and position algorithms of seed 000."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ConfigError

__all__ = ["check_sub", "check_multi", "check_dt"]


def check_sub(dtheta_sub: ArrayLike | None, m: int, name: str) -> np.ndarray:
    """The (n, m, 3) sub-sample increments of method ``name`` as floats (ConfigError otherwise)."""
    if dtheta_sub is None:
        raise ConfigError(f"{name}.dtheta_sub", f"array of shape (n, {m}, 3)", None)
    arr = np.asarray(dtheta_sub, dtype=float)
    if arr.ndim != 3 or arr.shape[1] != m or arr.shape[2] != 3:
        raise ConfigError(f"{name}.dtheta_sub", f"array of shape (n, {m}, 3)", arr.shape)
    return arr


def check_multi(dtheta_r: ArrayLike | None, order: int, name: str, field: str = "dtheta_r") -> np.ndarray:
    """The (n, R >= order, 3) multiple integrals of method ``name`` as floats (ConfigError otherwise)."""
    if dtheta_r is None:
        raise ConfigError(f"{name}.{field}", f"array of shape (n, R>={order}, 3)", None)
    arr = np.asarray(dtheta_r, dtype=float)
    if arr.ndim != 3 or arr.shape[1] < order or arr.shape[2] != 3:
        raise ConfigError(f"{name}.{field}", f"array of shape (n, R>={order}, 3)", arr.shape)
    return arr


def check_dt(dt: float | None, name: str) -> float:
    """The navigation step of method ``name``, s (positive and finite; ConfigError otherwise)."""
    if dt is None:
        raise ConfigError(f"{name}.dt", "the navigation step in seconds (> 0)", None)
    value = float(dt)
    if not (value > 0.0 and np.isfinite(value)):
        raise ConfigError(f"{name}.dt", "a positive finite step in seconds", dt)
    return value
