"""The recursive error state (:class:`ImuState`: biases, Gauss-Markov and rate-random-walk
states, quantizer carries; chunk-invariant generation) and the sensor output (:class:`ImuOutput`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence, TypeVar

import numpy as np
from numpy.typing import NDArray

from ...errors import ConfigError
from .._common import frozen_array
from .error_model import ImuErrorModel, level_lsb
from .integrals import MAX_ORDER, check_h, check_int

_State = TypeVar("_State", bound="_ImuStateFields")

ARRAY_SHAPES: dict[str, tuple[int, ...]] = {
    "turn_on_bias": (2, 3),
    "bias_gauss_markov": (2, 3),
    "bias_random_walk": (2, 3),
    "quant_accumulator": (2, MAX_ORDER + 1, 3),
    "quant_count": (2, MAX_ORDER + 1, 3),
}
"""The array fields of one IMU's error state and their shapes (:class:`ImuState`; a
:class:`BatchImuState` has the same fields with a leading member axis)."""


@dataclass(frozen=True, slots=True, eq=False)
class _ImuStateFields:
    """The fields :class:`ImuState` and :class:`BatchImuState` share (one source for both)."""

    sample_index: int
    turn_on_bias: NDArray[np.float64]
    bias_gauss_markov: NDArray[np.float64]
    bias_random_walk: NDArray[np.float64]
    quant_accumulator: NDArray[np.float64]
    quant_count: NDArray[np.float64]

    def _arrays(self) -> tuple[NDArray[np.float64], ...]:
        """The array fields in the order of :data:`ARRAY_SHAPES`."""
        return tuple(getattr(self, name) for name in ARRAY_SHAPES)

    @classmethod
    def _unchecked(cls: type[_State], sample_index: int, arrays: Sequence[NDArray]) -> _State:
        """An instance holding ``arrays`` as they are (the caller guarantees shapes and
        read-only flags), without ``__post_init__``'s checks and copies."""
        state = object.__new__(cls)
        for name, value in zip(ARRAY_SHAPES, arrays, strict=True):
            object.__setattr__(state, name, value)
        object.__setattr__(state, "sample_index", sample_index)
        return state


@dataclass(frozen=True, slots=True, eq=False)
class ImuState(_ImuStateFields):
    """Everything recursive in the IMU error model. Index 0 = gyro, 1 = accelerometer.

    Parameters
    ----------
    sample_index : int
        Number of samples generated so far (the global index of the next sample).
    turn_on_bias : ndarray, shape (2, 3)
        Random constant biases drawn at turn-on, rad/s and m/s^2.
    bias_gauss_markov : ndarray, shape (2, 3)
        Gauss-Markov bias during the next sample.
    bias_random_walk : ndarray, shape (2, 3)
        Rate-random-walk bias during the next sample.
    quant_accumulator : ndarray, shape (2, MAX_ORDER + 1, 3)
        Quantizer accumulators (rows 0..R-1 the integral orders, row ``MAX_ORDER`` the
        rate output), in output units.
    quant_count : ndarray, shape (2, MAX_ORDER + 1, 3)
        LSB counts emitted within the current renormalisation block; the residual carry is
        ``quant_accumulator - lsb_level * quant_count`` (see :meth:`quantization_residual`).
    """

    def __post_init__(self) -> None:
        index = check_int("state.sample_index", self.sample_index, 0)
        object.__setattr__(self, "sample_index", index)
        for name, shape in ARRAY_SHAPES.items():
            arr = frozen_array(getattr(self, name))
            if arr.shape != shape:
                raise ConfigError(f"state.{name}", f"shape {shape}", arr.shape)
            object.__setattr__(self, name, arr)

    @classmethod
    def initial(cls, model: ImuErrorModel, rng: np.random.Generator) -> ImuState:
        """Turn-on state: draws one ``(2, 2, 3)`` block of standard normals.

        ``z[s, 0]`` gives the turn-on biases (``turn_on_bias_sigma * z``) and ``z[s, 1]``
        the Gauss-Markov biases from their stationary distribution
        (``bias_instability_sigma * z``); the random-walk biases start at zero.
        """
        z = rng.standard_normal((2, 2, 3))
        sensors = (model.gyro, model.accel)
        turn_on = np.stack([s.turn_on_bias_sigma for s in sensors]) * z[:, 0]
        gauss_markov = np.stack([s.bias_instability_sigma for s in sensors]) * z[:, 1]
        zeros_q = np.zeros((2, MAX_ORDER + 1, 3))
        return cls(0, turn_on, gauss_markov, np.zeros((2, 3)), zeros_q, zeros_q)

    def quantization_residual(
        self, model: ImuErrorModel, h: float, order: int
    ) -> NDArray[np.float64]:
        """Residual carry (unquantized minus quantized running sum), shape (2, R + 1, 3).

        Rows 0..R-1 are the integral orders, row R the rate output; zero where the
        sensor has no quantization.
        """
        lsb = level_lsb(model, check_h(h), check_int("order", order, 1, MAX_ORDER))
        rows = list(range(order)) + [MAX_ORDER]
        acc = self.quant_accumulator[:, rows]
        count = self.quant_count[:, rows]
        return acc - lsb[:, :, None] * count

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ImuState) or other.sample_index != self.sample_index:
            return False
        return all(np.array_equal(a, b) for a, b in zip(self._arrays(), other._arrays()))

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, slots=True, eq=False)
class BatchImuState(_ImuStateFields):
    """The :class:`ImuState` of B lockstep members as (B, ...) arrays (the batched error
    model's working form: no per-member objects between calls).

    The fields of :class:`ImuState` (:data:`ARRAY_SHAPES`), each with a leading member
    axis: ``turn_on_bias``, ``bias_gauss_markov``, ``bias_random_walk``: (B, 2, 3);
    ``quant_accumulator``, ``quant_count``: (B, 2, MAX_ORDER + 1, 3); one ``sample_index``.
    Row j is member j's :class:`ImuState` (:meth:`member`). The arrays are read-only.
    """

    @property
    def size(self) -> int:
        """Number of members B."""
        return int(self.turn_on_bias.shape[0])

    @classmethod
    def of(cls, states: Sequence[ImuState]) -> BatchImuState:
        """Stack B >= 1 :class:`ImuState` at one ``sample_index`` (lockstep; checked)."""
        if not states:
            raise ConfigError("states", "at least one ImuState", "none")
        for state in states:
            if not isinstance(state, ImuState):
                raise ConfigError("state", "an ImuState", type(state).__name__)
        index = states[0].sample_index
        if any(s.sample_index != index for s in states):
            raise ConfigError("states", "states at the same sample_index (lockstep)",
                              sorted({s.sample_index for s in states}))
        arrays = []
        for rows in zip(*(s._arrays() for s in states)):
            a = np.stack(rows)
            a.setflags(write=False)
            arrays.append(a)
        return cls._unchecked(int(index), arrays)

    @classmethod
    def _owned(cls, sample_index: int, turn_on: NDArray, gauss_markov: NDArray, random_walk: NDArray,
               accumulator: NDArray, count: NDArray) -> BatchImuState:
        """From arrays of the right shapes: each copied once (unless it is the read-only
        ``turn_on`` of a batch state already) and made read-only."""
        arrays = []
        for a in (turn_on, gauss_markov, random_walk, accumulator, count):
            if a.flags.writeable or a.base is not None and a is not turn_on:
                a = np.array(a, dtype=float, copy=True)
                a.setflags(write=False)
            arrays.append(a)
        return cls._unchecked(int(sample_index), arrays)

    def member(self, j: int) -> ImuState:
        """Member j's :class:`ImuState` (read-only views of row j)."""
        return ImuState._unchecked(self.sample_index, [a[j] for a in self._arrays()])

    def members(self) -> list[ImuState]:
        """Every member's :class:`ImuState`."""
        return [self.member(j) for j in range(self.size)]


@dataclass(frozen=True, slots=True, eq=False)
class ImuOutput:
    """IMU measurements with errors for ``n`` samples.

    Attributes
    ----------
    dtheta_r : ndarray, shape (n, R, 3)
        Multiple integrals of the angular rate (1.14), rad s^(r-1).
    dv_r : ndarray, shape (n, R, 3)
        Multiple integrals of the specific force, m/s * s^(r-1).
    rate_b : ndarray, shape (n, 3)
        Angular-rate output at the sample instants ``t_start + h``, rad/s.
    accel_b : ndarray, shape (n, 3)
        Specific-force output at the sample instants, m/s^2.
    """

    dtheta_r: NDArray[np.float64]
    dv_r: NDArray[np.float64]
    rate_b: NDArray[np.float64]
    accel_b: NDArray[np.float64]
