"""A user's own filterpy filter run by navsim: a constant-velocity GNSS filter.

The filter is plain filterpy (``KalmanFilter``, ``ExtendedKalmanFilter`` or
``UnscentedKalmanFilter``, option ``kind``) on the state ``x = [E, N, U, vE, vN, vU]`` (m,
m/s, a local tangent plane at the start) with the white-acceleration model (Bar-Shalom et
al. 2001, section 6.2.2), per axis over a step dt::

    F = [[1, dt], [0, 1]],   Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]   (q = accel_psd, m^2/s^3)

:func:`navsim.estimators.filterpy_adapter.from_filterpy` turns it into a navsim estimator:
navsim hands it the receiver's least-squares position and velocity fixes at each GNSS epoch
(``z = x[:6]`` plus noise, R from the fix geometry) and reads back ``x`` and ``P``.
The model and h are linear, so the three kinds are the same filter (the unscented
transform of a linear map is exact): their numbers agree to rounding.

    navsim bench paper-2012 --estimators examples/filterpy_cv.py:make --seeds 0:3
    navsim run paper-2012 --estimator examples.filterpy_cv:make --option kind=ekf
"""

from __future__ import annotations

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter, KalmanFilter, MerweScaledSigmaPoints, UnscentedKalmanFilter

from navsim.estimators.filterpy_adapter import from_filterpy


def cv_model(dt: float, accel_psd: float) -> tuple[np.ndarray, np.ndarray]:
    """F and Q of the white-acceleration model over dt (6 states, three axes)."""
    i3 = np.eye(3)
    F = np.block([[i3, dt * i3], [np.zeros((3, 3)), i3]])
    Q = accel_psd * np.block([[dt**3 / 3 * i3, dt**2 / 2 * i3], [dt**2 / 2 * i3, dt * i3]])
    return F, Q


def make(kind: str = "ukf", accel_psd: float = 0.1):
    """Constant-velocity filterpy filter on GNSS fixes (kind: kf, ekf or ukf)."""
    state = {}

    def configure(kf, context):  # F and Q for this scenario's navigation period
        F, Q = cv_model(context.nav_period_s, accel_psd)
        state["F"] = F
        kf.Q = Q
        if kind != "ukf":
            kf.F = F

    if kind == "kf":
        return from_filterpy(KalmanFilter(dim_x=6, dim_z=6), configure=configure)
    if kind == "ekf":
        return from_filterpy(ExtendedKalmanFilter(dim_x=6, dim_z=6), configure=configure,
                             hx=lambda x: x[:6], hx_jacobian=lambda x: np.eye(6))
    if kind == "ukf":
        points = MerweScaledSigmaPoints(6, alpha=1.0, beta=2.0, kappa=0.0)
        ukf = UnscentedKalmanFilter(dim_x=6, dim_z=6, dt=0.01, hx=None, fx=None, points=points)
        return from_filterpy(ukf, fx=lambda x, dt: state["F"] @ x, hx=lambda x: x[:6], configure=configure)
    raise ValueError(f"kind: expected kf, ekf or ukf, got {kind!r}")
