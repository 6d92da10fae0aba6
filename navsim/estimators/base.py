"""The estimator interface: what an estimator may know, what it receives, what it returns.

An estimator is any object with two methods (no navsim base class needed); it may add a
batch fast path ``step_batch`` (see :class:`MeasurementBatch`)::

    class MyEstimator:
        def reset(self, context: Context, prior: Prior) -> None: ...
        def step(self, measurement: Measurement) -> Estimate: ...

``reset`` hands over what the estimator may know: the track model (the map), the
Earth model, the time base and the *nominal* sensor specification (never the
simulator's actual error draws), and the prior (initial estimate and covariance drawn
by the simulator from the scenario's initial uncertainty). ``step`` is called once per
navigation step with the IMU data of that step and, at GNSS epochs, the GNSS channels;
it returns the navigation solution at the end of the step. Truth is never passed in.
When the scenario has a wheel odometer, the context carries its nominal specification
(:class:`NominalOdometer`) and every measurement the distance it counted over the step
(``odometer_ds_m``); both are None otherwise.

Frames and units follow the package conventions (:mod:`navsim`): geodetic latitude,
longitude (rad) and height (m); ENU velocity (m/s); heading, pitch, roll (rad) of the
body (x right, y forward, z up) relative to ENU.

The covariance of an :class:`Estimate` is 9 x 9 over the error vector
``[dE, dN, dU (m), dvE, dvN, dvU (m/s), psi_E, psi_N, psi_U (rad)]`` where
``psi`` is the small rotation of the estimated attitude relative to the true one about
the ENU axes (``mat_nb_est = (I + [psi x]) mat_nb_true``). Estimators that do not
estimate some components (e.g. GNSS only: no attitude) put ``nan`` on those diagonal
entries; metrics then skip them.

Step-wise fast path (optional, :class:`RowStepping`): ``step_row(measurement) -> (row,
covariance, nis, nis_dof)`` does what ``step`` does and returns the solution as a (9,) row
(:meth:`NavSolution.as_action`) with its covariance and NIS, without the
:class:`Estimate` and its ``extra`` diagnostics; :class:`navsim.envs.EstimatorAgent` and the
estimator FMU use it when the estimator's ``step`` and ``step_row`` come from the same
class. lc-ekf, tc-ekf, tc-ukf, along-track, paper-ekf, gnss-ls and gnss-cv implement it.

The values themselves (context, measurements, solutions) live in :mod:`navsim.types`
and are re-exported here; ``Prior`` and ``Estimate`` are two names of
:class:`navsim.types.NavSolution`.
"""

from __future__ import annotations

import functools
import math
from typing import Any, Callable, ClassVar, Protocol, runtime_checkable

import numpy as np

from ..types import (
    STATE_LABELS,
    Context,
    Estimate,
    EstimateBatch,
    GnssObservation,
    Measurement,
    MeasurementBatch,
    NavSolution,
    NominalGnss,
    NominalImu,
    NominalOdometer,
    Prior,
)

__all__ = [
    "NominalImu",
    "NominalGnss",
    "NominalOdometer",
    "Context",
    "GnssObservation",
    "Measurement",
    "NavSolution",
    "Prior",
    "Estimate",
    "Estimator",
    "RowStepping",
    "StepRow",
    "row_of",
    "row_stepping",
    "NoiseScalable",
    "NoiseScaling",
    "MeasurementBatch",
    "EstimateBatch",
    "STATE_LABELS",
]


@runtime_checkable
class Estimator(Protocol):
    """What navsim requires of an estimator (structural: no subclassing needed)."""

    def reset(self, context: Context, prior: Prior) -> None:
        """Start an episode from the prior (:class:`navsim.types.NavSolution`)."""
        ...

    def step(self, measurement: Measurement) -> Estimate:
        """Process one navigation step and return the solution at its end."""
        ...


StepRow = tuple[np.ndarray, "np.ndarray | None", "float | None", "int | None"]
"""``(row, covariance, nis, nis_dof)`` of one step: ``row`` (9,) as
:meth:`NavSolution.as_action`, ``covariance`` (9, 9) or None, the NIS of an update made in
the step and its degrees of freedom (None when no update happened)."""


@runtime_checkable
class RowStepping(Protocol):
    """The step-wise fast path (optional; the five INS/track filters and the two GNSS-only
    estimators have it).

    ``step_row(measurement)`` processes one navigation step exactly as ``step`` does (the
    same numbers, the same state afterwards) and returns the solution as a
    :data:`StepRow` instead of an :class:`Estimate`: no per-step diagnostics (``extra``)
    are built. ``row`` and ``covariance`` belong to the caller (arrays made for this call).
    The measurement may be any object with the attributes of :class:`Measurement`; a step
    without a GNSS epoch does not keep a reference to it. Used by
    :class:`navsim.envs.EstimatorAgent` and the estimator FMU.
    """

    def step_row(self, measurement: Measurement) -> StepRow:
        """Process one navigation step; ``(row (9,), covariance (9, 9) or None, nis, nis_dof)``."""
        ...


def row_of(estimate: Estimate) -> StepRow:
    """The :data:`StepRow` of an :class:`Estimate` (``step_row`` through ``step``)."""
    return estimate.as_action(), estimate.covariance, estimate.nis, estimate.nis_dof


def row_stepping(estimator: Any) -> Callable[[Measurement], StepRow] | None:
    """The estimator's bound ``step_row`` when it is the fast form of its own ``step``
    (both defined by the same class: a subclass that overrides ``step`` alone keeps the
    ``step`` path), else None. What a step-wise driver (the env's agent, the estimator FMU)
    calls per step."""
    fast = getattr(estimator, "step_row", None)
    if not callable(fast):
        return None
    mro = type(estimator).__mro__
    owner_step = next((c for c in mro if "step" in c.__dict__), None)
    owner_row = next((c for c in mro if "step_row" in c.__dict__), None)
    return fast if owner_step is not None and owner_step is owner_row else None


# An estimator may also offer ``step_batch(batch: MeasurementBatch) -> EstimateBatch``,
# a fast path that must give the same numbers as calling ``step`` on each measurement
# in turn (to floating-point rounding); navsim's episode runner uses it when present.


@runtime_checkable
class NoiseScaling(Protocol):
    """The public way for an agent to act on an estimator (every bundled estimator has it).

    ``set_noise_scale(process, measurement)`` multiplies the estimator's process-noise
    intensities (PSDs, variances) by ``process`` and its measurement-noise variances by
    ``measurement`` (standard deviations by ``sqrt(measurement)``), relative to the values
    it set at its last ``reset`` (calls do not compound; ``(1, 1)`` restores them). Used
    by the adaptive-filtering env (:mod:`navsim.envs.adaptive`).
    """

    def set_noise_scale(self, process: float, measurement: float) -> None:
        """Scale Q by ``process`` and R by ``measurement`` (both > 0)."""
        ...


def _get_path(obj: Any, path: str) -> Any:
    for part in path.split("."):
        obj = getattr(obj, part)
    return obj


def _set_path(obj: Any, path: str, value: Any) -> None:
    parts = path.split(".")
    for part in parts[:-1]:
        obj = getattr(obj, part)
    setattr(obj, parts[-1], value)


class NoiseScalable:
    """:class:`NoiseScaling` from declared attributes (a mixin of the bundled estimators).

    A subclass names where its noise lives after ``reset`` (dotted attribute paths):
    ``NOISE_PROCESS`` (intensities scaled by ``process``), ``NOISE_MEASUREMENT_VARIANCE``
    (scaled by ``measurement``), ``NOISE_MEASUREMENT_SIGMA`` (scaled by
    ``sqrt(measurement)``). The values are captured at the first call after each
    ``reset``; the subclass's ``reset`` is wrapped to restore the captured values first
    (some, e.g. an option's PSD, are not set anew by ``reset``) and forget them, so
    scales never compound, within an episode or across episodes.
    """

    NOISE_PROCESS: ClassVar[tuple[str, ...]] = ()
    NOISE_MEASUREMENT_VARIANCE: ClassVar[tuple[str, ...]] = ()
    NOISE_MEASUREMENT_SIGMA: ClassVar[tuple[str, ...]] = ()

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        inner = cls.__dict__.get("reset")
        if inner is not None:
            @functools.wraps(inner)
            def reset(self: Any, *args: Any, **kw: Any) -> Any:
                base = getattr(self, "_noise_base", None)
                if base is not None:  # undo the scaling first: reset may not set every value anew
                    for path, value in base.items():
                        _set_path(self, path, value)
                self._noise_base = None
                return inner(self, *args, **kw)

            cls.reset = reset  # type: ignore[attr-defined]

    def noise_base(self) -> dict[str, Any]:
        """The noise values set by the last ``reset`` (path -> value), captured now if not yet."""
        base = getattr(self, "_noise_base", None)
        if base is None:
            base = {}
            for path in (*self.NOISE_PROCESS, *self.NOISE_MEASUREMENT_VARIANCE, *self.NOISE_MEASUREMENT_SIGMA):
                value = _get_path(self, path)
                base[path] = np.copy(value) if isinstance(value, np.ndarray) else float(value)
            self._noise_base = base
        return base

    def set_noise_scale(self, process: float, measurement: float) -> None:
        """Scale Q by ``process`` and R by ``measurement`` relative to the last reset."""
        process, measurement = float(process), float(measurement)
        if not (process > 0.0 and measurement > 0.0 and math.isfinite(process) and math.isfinite(measurement)):
            raise ValueError(f"set_noise_scale: positive finite factors expected, got {process}, {measurement}")
        base = self.noise_base()
        for path in self.NOISE_PROCESS:
            _set_path(self, path, base[path] * process)
        for path in self.NOISE_MEASUREMENT_VARIANCE:
            _set_path(self, path, base[path] * measurement)
        root = math.sqrt(measurement)
        for path in self.NOISE_MEASUREMENT_SIGMA:
            _set_path(self, path, base[path] * root)
