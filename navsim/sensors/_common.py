"""Small helpers shared by the sensor models."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

__all__ = ["frozen_array"]


def frozen_array(value: ArrayLike, dtype: DTypeLike = float) -> np.ndarray:
    """A read-only copy of ``value`` (state and configuration arrays are immutable)."""
    arr = np.array(value, dtype=dtype, copy=True)
    arr.setflags(write=False)
    return arr
