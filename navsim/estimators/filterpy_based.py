"""Baselines whose Kalman arithmetic is filterpy's: the loosely and tightly coupled EKFs.

``lc-ekf-filterpy`` and ``tc-ekf-filterpy`` are :class:`~navsim.estimators.loosely.
LooselyCoupledEkf` and :class:`~navsim.estimators.tightly.TightlyCoupledEkf` with every
measurement update done by filterpy's ``ExtendedKalmanFilter.update`` [1]: navsim supplies
the strapdown INS, the error-state model and its propagation, the measurement model h and
its Jacobian H; filterpy computes S = H P H^T + R, K = P H^T S^-1, x = K y and the Joseph
form P = (I - K H) P (I - K H)^T + K R K^T. The error state is closed-loop (x = 0 before
each update, fed back after it), so ``Hx`` is zero and ``z`` is the innovation. The
numbers equal navsim's own engines up to rounding: filterpy inverts S where navsim solves
with its Cholesky factor (``tests/estimators/test_filterpy_based.py`` bounds the difference).

Options: those of the wrapped estimator. Needs filterpy (``pip install
'navsim-track[filters]'``).

References
----------
.. [1] Labbe R., filterpy, ``filterpy.kalman.ExtendedKalmanFilter``,
       https://github.com/rlabbe/filterpy (documentation: "Kalman and Bayesian Filters in
       Python", ch. 11).
"""

from __future__ import annotations

import numpy as np

from .loosely import LooselyCoupledEkf
from .tightly import TightlyCoupledEkf

__all__ = ["FilterpyUpdate", "FilterpyLcEkf", "FilterpyTcEkf"]


class FilterpyUpdate:
    """``(P, H, R, innovation) -> (dx, P_new, nis)`` through filterpy's
    ``ExtendedKalmanFilter.update`` (one filter object per state/measurement size)."""

    def __init__(self) -> None:
        from filterpy.kalman import ExtendedKalmanFilter

        self._cls = ExtendedKalmanFilter
        self._filters: dict[tuple[int, int], object] = {}

    def __call__(self, P: np.ndarray, H: np.ndarray, R: np.ndarray, innovation: np.ndarray):
        n, m = P.shape[0], H.shape[0]
        kf = self._filters.get((n, m))
        if kf is None:
            kf = self._filters[(n, m)] = self._cls(dim_x=n, dim_z=m)
        kf.x = np.zeros(n)
        kf.P = np.array(P, dtype=float)
        zero = np.zeros(m)
        kf.update(np.asarray(innovation, dtype=float), HJacobian=lambda x: H, Hx=lambda x: zero, R=R)
        nis = float(kf.y @ kf.SI @ kf.y)
        return np.array(kf.x, dtype=float), 0.5 * (kf.P + kf.P.T), nis


class FilterpyLcEkf(LooselyCoupledEkf):
    """lc-ekf with filterpy's ExtendedKalmanFilter doing the measurement updates."""

    def reset(self, context, prior) -> None:
        super().reset(context, prior)
        self.engine.kalman_update = FilterpyUpdate()


class FilterpyTcEkf(TightlyCoupledEkf):
    """tc-ekf with filterpy's ExtendedKalmanFilter doing the measurement updates."""

    def reset(self, context, prior) -> None:
        super().reset(context, prior)
        self.kalman_update = FilterpyUpdate()
