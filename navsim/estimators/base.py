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

The values themselves (context, measurements, solutions) live in :mod:`navsim.types`
and are re-exported here; ``Prior`` and ``Estimate`` are two names of
:class:`navsim.types.NavSolution`.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

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


# An estimator may also offer ``step_batch(batch: MeasurementBatch) -> EstimateBatch``,
# a fast path that must give the same numbers as calling ``step`` on each measurement
# in turn (to floating-point rounding); navsim's episode runner uses it when present.
