"""INS only: free-inertial dead reckoning from the prior, with its error covariance.

The estimator integrates the IMU data with :func:`navsim.strapdown.ins.integrate` (the
most accurate coning/sculling/position algorithms the measurement carries, unless named)
from the prior and never uses GNSS. Its covariance is the 15-state INS error model of
:mod:`navsim.estimators._inserror` (position, velocity, attitude, gyro and accelerometer
bias) propagated from the prior covariance with the nominal IMU noise, so the NEES of the
reported solution is meaningful: the covariance grows as the error model says
(Schuler-bounded horizontal drift, the vertical channel's instability on WGS-84, the bias
contributions).

The biases are not estimated (nothing observes them); their uncertainty only shapes the
covariance.

References
----------
.. [1] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., 2013, sections 5.4 (mechanisation) and 14.2 (error propagation).
.. [2] Savage P.G., Strapdown Analytics, 2nd ed., 2007, ch. 12.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..option_checks import check_positive_finite
from ._inserror import ErrorStateIns, ImuNoise
from .base import Context, Estimate, EstimateBatch, Measurement, MeasurementBatch, NoiseScalable, Prior

__all__ = ["InsOnly"]


class InsOnly(NoiseScalable):
    """Dead reckoning with the strapdown INS and the propagated error covariance.

    Parameters
    ----------
    covariance_period_s : float
        Length of a covariance interval (rounded to whole navigation steps, at least one):
        F is rebuilt and P advanced by the series transition once per interval; the
        reported covariance inside an interval is the series evaluated at each step.
    noise_scale, bias_scale : float
        Factors on the nominal white-noise densities and bias sigmas.
    coning, sculling, position : str or None
        Strapdown method names (``navsim.strapdown`` registries); None = best available.
    """

    NOISE_PROCESS = ('engine.Qc',)
    # where set_noise_scale finds Q and R after reset (navsim.estimators.base.NoiseScalable)

    def __init__(self, covariance_period_s: float = 1.0, noise_scale: float = 1.0, bias_scale: float = 1.0,
                 coning: str | None = None, sculling: str | None = None, position: str | None = None) -> None:
        check_positive_finite("covariance_period_s", covariance_period_s, "a positive finite time, s")
        self.covariance_period_s = float(covariance_period_s)
        self.noise_scale = noise_scale
        self.bias_scale = bias_scale
        self.methods = dict(coning=coning, sculling=sculling, position=position)
        self.engine: ErrorStateIns | None = None

    def reset(self, context: Context, prior: Prior) -> None:
        """Start from the prior state and covariance."""
        noise = ImuNoise.from_nominal(context.imu, noise_scale=self.noise_scale, bias_scale=self.bias_scale)
        steps = max(1, round(self.covariance_period_s / context.nav_period_s))
        self.engine = ErrorStateIns(context, prior, noise, interval_steps=steps, estimate_biases=False,
                                    **self.methods)

    def step(self, measurement: Measurement) -> Estimate:
        """Integrate one navigation step."""
        m = measurement
        out = self.step_batch(MeasurementBatch.of(m))
        assert self.engine is not None and out.covariance is not None  # step_batch checked the reset
        row = out.solution[0]
        return Estimate(m.t, row[0], row[1], row[2], row[3:6].copy(), row[6], row[7], row[8],
                        covariance=out.covariance[0], extra={"diverged": self.engine.diverged})

    def step_batch(self, batch: MeasurementBatch) -> EstimateBatch:
        """Integrate n steps at once (one strapdown call)."""
        if self.engine is None:
            raise ConfigError("InsOnly", "reset(context, prior) before stepping", "no reset")
        rows, cov = self.engine.advance(batch.dtheta_sub, batch.dv_sub, batch.dtheta_r, batch.dv_r)
        n = len(rows)
        return EstimateBatch(rows, cov, np.full(n, np.nan), np.zeros(n, dtype=int))
