"""Small helpers shared by the sensor models."""

from __future__ import annotations

import collections
import math
import operator
import threading
from typing import Any, Sequence, TypeVar

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from ..errors import ConfigError

__all__ = ["frozen_array", "RecentBatches", "lockstep_members", "positive_step"]

_State = TypeVar("_State")


def frozen_array(value: ArrayLike, dtype: DTypeLike = float) -> np.ndarray:
    """A read-only copy of ``value`` (state and configuration arrays are immutable)."""
    arr = np.array(value, dtype=dtype, copy=True)
    arr.setflags(write=False)
    return arr


class RecentBatches:
    """The state objects made by the last few batched calls of a sensor model, each with
    the read-only arrays they were made from.

    A batched call (B receivers in lockstep) returns one immutable state object per
    receiver, and its next call gets them back as a list; :meth:`recall` gives the arrays
    of a batch when that list holds the very objects it made, all of them, in their order,
    so the call reads them instead of an attribute of each object (with B = 1024 that was
    most of the GNSS and outage models' time per chunk). The objects and arrays are kept
    for the ``size`` most recent batches (their ids cannot be reused while they are kept).
    """

    def __init__(self, size: int = 8) -> None:
        self._size = int(size)
        self._entries: collections.OrderedDict[int, tuple[tuple[Any, ...], Any]] = collections.OrderedDict()
        self._lock = threading.Lock()  # batches of several simulators may run on threads

    def remember(self, states: Sequence[Any], arrays: Any) -> None:
        """Keep ``arrays`` (read-only, the states' values) with the objects of ``states``."""
        if not states:
            return
        made = tuple(states)  # the caller's list may change later; the objects may not
        with self._lock:
            self._entries[id(made[0])] = (made, arrays)
            self._entries.move_to_end(id(made[0]))
            while len(self._entries) > self._size:
                self._entries.popitem(last=False)

    def recall(self, states: Sequence[Any]) -> Any:
        """The arrays kept with exactly these objects (the same ones, in the same order),
        else None."""
        if not states:
            return None
        with self._lock:
            entry = self._entries.get(id(states[0]))
        if entry is None:
            return None
        made, arrays = entry
        if len(made) != len(states) or not all(map(operator.is_, made, states)):
            return None
        return arrays


def positive_step(dt: float) -> float:
    """``dt`` as a float, checked positive and finite (the step of a batched sensor call, s)."""
    dt = float(dt)
    if not (dt > 0.0 and math.isfinite(dt)):
        raise ConfigError("dt", "a positive finite step, s", dt)
    return dt


def lockstep_members(states: Sequence[_State], rngs: Sequence[np.random.Generator], index: str,
                     kind: type | None = None) -> tuple[list[_State], list[np.random.Generator], Any]:
    """The members of a batched sensor call, checked: at least one state, one generator per
    state, each state a ``kind`` (when given), all at the same value of their attribute
    ``index`` (lockstep). Returns the states and generators as lists and that value."""
    states, rngs = list(states), list(rngs)
    if not states or len(rngs) != len(states):
        raise ConfigError("rngs", f"one generator per state ({len(states)}, at least one)", len(rngs))
    if kind is not None:
        for state in states:
            if not isinstance(state, kind):
                raise ConfigError("state", f"an {kind.__name__}", type(state).__name__)
    value = getattr(states[0], index)
    if any(getattr(s, index) != value for s in states):
        raise ConfigError("states", f"states at the same {index} (lockstep)", sorted({getattr(s, index) for s in states}))
    return states, rngs, value
