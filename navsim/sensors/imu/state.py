"""The recursive error state (:class:`ImuState`: biases, Gauss-Markov and rate-random-walk
states, quantizer carries; chunk-invariant generation) and the sensor output (:class:`ImuOutput`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from ...errors import ConfigError
from .._common import frozen_array
from .error_model import ImuErrorModel, level_lsb
from .integrals import MAX_ORDER, check_h, check_int


@dataclass(frozen=True, slots=True, eq=False)
class ImuState:
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

    sample_index: int
    turn_on_bias: NDArray[np.float64]
    bias_gauss_markov: NDArray[np.float64]
    bias_random_walk: NDArray[np.float64]
    quant_accumulator: NDArray[np.float64]
    quant_count: NDArray[np.float64]

    def __post_init__(self) -> None:
        index = check_int("state.sample_index", self.sample_index, 0)
        object.__setattr__(self, "sample_index", index)
        shapes = {
            "turn_on_bias": (2, 3),
            "bias_gauss_markov": (2, 3),
            "bias_random_walk": (2, 3),
            "quant_accumulator": (2, MAX_ORDER + 1, 3),
            "quant_count": (2, MAX_ORDER + 1, 3),
        }
        for name, shape in shapes.items():
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

    @classmethod
    def _batch(cls, sample_index: int, turn_on: Sequence[NDArray], gauss_markov: NDArray, random_walk: NDArray,
               accumulator: NDArray, count: NDArray) -> list[ImuState]:
        """The states of B members after a batched call: each (B, ...) array is copied once
        to a read-only array and member j gets read-only views of row j (the shapes are
        those of the batch arrays by construction, so the per-member checks are skipped).
        ``turn_on`` holds the members' own (already read-only) turn-on biases."""
        rows = []
        for a in (gauss_markov, random_walk, accumulator, count):
            a = np.array(a, dtype=float, copy=True)
            a.setflags(write=False)
            rows.append(a)
        index = int(sample_index)
        out = []
        for j, t in enumerate(turn_on):
            state = object.__new__(cls)
            for name, value in zip(("turn_on_bias", "bias_gauss_markov", "bias_random_walk", "quant_accumulator",
                                    "quant_count"), (t, rows[0][j], rows[1][j], rows[2][j], rows[3][j])):
                object.__setattr__(state, name, value)
            object.__setattr__(state, "sample_index", index)
            out.append(state)
        return out

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
        return all(
            np.array_equal(getattr(self, n), getattr(other, n))
            for n in ("turn_on_bias", "bias_gauss_markov", "bias_random_walk",
                      "quant_accumulator", "quant_count")
        )

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, slots=True, eq=False)
class BatchImuState:
    """The :class:`ImuState` of B lockstep members as (B, ...) arrays (the batched error
    model's working form: no per-member objects between calls).

    ``turn_on_bias``, ``bias_gauss_markov``, ``bias_random_walk``: (B, 2, 3);
    ``quant_accumulator``, ``quant_count``: (B, 2, MAX_ORDER + 1, 3); one ``sample_index``.
    Row j is member j's :class:`ImuState` (:meth:`member`). The arrays are read-only.
    """

    sample_index: int
    turn_on_bias: NDArray[np.float64]
    bias_gauss_markov: NDArray[np.float64]
    bias_random_walk: NDArray[np.float64]
    quant_accumulator: NDArray[np.float64]
    quant_count: NDArray[np.float64]

    @property
    def size(self) -> int:
        """Number of members B."""
        return int(self.turn_on_bias.shape[0])

    @classmethod
    def of(cls, states: Sequence[ImuState]) -> BatchImuState:
        """Stack B states (at one ``sample_index``; the caller checks it)."""
        arrays = []
        for name in ("turn_on_bias", "bias_gauss_markov", "bias_random_walk", "quant_accumulator", "quant_count"):
            a = np.stack([getattr(s, name) for s in states])
            a.setflags(write=False)
            arrays.append(a)
        return cls(int(states[0].sample_index), *arrays)

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
        return cls(int(sample_index), *arrays)

    def member(self, j: int) -> ImuState:
        """Member j's :class:`ImuState` (read-only views of row j)."""
        state = object.__new__(ImuState)
        for name in ("turn_on_bias", "bias_gauss_markov", "bias_random_walk", "quant_accumulator", "quant_count"):
            object.__setattr__(state, name, getattr(self, name)[j])
        object.__setattr__(state, "sample_index", self.sample_index)
        return state

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
