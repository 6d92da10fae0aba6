"""Small helpers shared by the sensor models."""

from __future__ import annotations

import numpy as np

__all__ = ["frozen_array"]


def frozen_array(value, dtype=float) -> np.ndarray:
    """A read-only copy of ``value`` (state and configuration arrays are immutable)."""
    arr = np.array(value, dtype=dtype, copy=True)
    arr.setflags(write=False)
    return arr
