"""Baselines whose Kalman arithmetic is filterpy's: the loosely and tightly coupled EKFs, the tightly coupled UKF.

``lc-ekf-filterpy`` and ``tc-ekf-filterpy`` are :class:`~navsim.estimators.loosely.
LooselyCoupledEkf` and :class:`~navsim.estimators.tightly.TightlyCoupledEkf` with every
measurement update done by filterpy's ``ExtendedKalmanFilter.update`` [1]: navsim supplies
the strapdown INS, the error-state model and its propagation, the measurement model h and
its Jacobian H; filterpy computes S = H P H^T + R, K = P H^T S^-1, x = K y and the Joseph
form P = (I - K H) P (I - K H)^T + K R K^T. The error state is closed-loop (x = 0 before
each update, fed back after it), so ``Hx`` is zero and ``z`` is the innovation. The
numbers equal navsim's own engines up to rounding: filterpy inverts S where navsim solves
with its Cholesky factor (``tests/estimators/test_filterpy_based.py`` bounds the difference).

``tc-ukf-filterpy`` is :class:`~navsim.estimators.tightly.TightlyCoupledUkf` with every
measurement update done by filterpy's ``UnscentedKalmanFilter`` [1] and its
``MerweScaledSigmaPoints``: filterpy draws the 2n+1 scaled sigma points of the error state
(mean 0, covariance P; alpha, beta, kappa the filter's options), passes each one through
navsim's measurement function h (the exact pseudoranges and rates (TC.2)-(TC.3), with the
atmosphere and the lever arm, at ``INS minus error``), forms the unscented transform
z_hat = sum Wm_i Z_i, S = sum Wc_i (Z_i - z_hat)(Z_i - z_hat)^T + R, the cross covariance
Pxz, K = Pxz S^-1 (``inv``), x = K (z - z_hat) and P = P - K S K^T. Merwe's scheme is the
scaled symmetric set of Julier (2002) / van der Merwe (2004), the one navsim's
:func:`~navsim.estimators.tightly.sigma_points` uses with the same weights
(lambda = alpha^2 (n + kappa) - n, Wm_0 = lambda / (n + lambda), Wc_0 = Wm_0 + 1 - alpha^2
+ beta, the others 1 / (2 (n + lambda))) and the same columns of the lower Cholesky factor
(filterpy's rows of the upper one): with filterpy's own square root (``scipy.linalg.
cholesky``) the two filters differ by rounding only. The square root falls back to navsim's
guarded factor (:func:`~navsim.estimators.tightly.guarded_cholesky`: the states with
non-zero variance, then jitter, then clipped eigenvalues) only when filterpy's Cholesky
fails (e.g. an IMU without biases leaves the bias states at exactly zero variance); those
cases are counted in ``Estimate.extra["cholesky_fallbacks"]``. The time update is navsim's
(the error dynamics are linear, as in tc-ukf), so the sigma points of each update are drawn
from the propagated P directly (``sigmas_f``), not through ``predict`` with an identity fx.

Options: those of the wrapped estimator. Needs filterpy (``pip install
'navsim-track[filters]'``).

References
----------
.. [1] Labbe R., filterpy, ``filterpy.kalman.ExtendedKalmanFilter``,
       https://github.com/rlabbe/filterpy (documentation: "Kalman and Bayesian Filters in
       Python", ch. 11).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable

import numpy as np

from .base import Context, Prior
from .loosely import LooselyCoupledEkf
from .tightly import TightlyCoupledEkf, TightlyCoupledUkf, guarded_cholesky

if TYPE_CHECKING:  # filterpy is untyped: these are Any to the checker
    from filterpy.kalman import ExtendedKalmanFilter, UnscentedKalmanFilter

__all__ = ["FilterpyUpdate", "FilterpyUnscentedUpdate", "FilterpyLcEkf", "FilterpyTcEkf", "FilterpyTcUkf"]


class FilterpyUpdate:
    """``(P, H, R, innovation) -> (dx, P_new, nis)`` through filterpy's
    ``ExtendedKalmanFilter.update`` (one filter object per state/measurement size)."""

    def __init__(self) -> None:
        from filterpy.kalman import ExtendedKalmanFilter

        self._cls = ExtendedKalmanFilter
        self._filters: dict[tuple[int, int], ExtendedKalmanFilter] = {}

    def __call__(self, P: np.ndarray, H: np.ndarray, R: np.ndarray, innovation: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                 float]:
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

    def reset(self, context: Context, prior: Prior) -> None:
        super().reset(context, prior)
        assert self.engine is not None  # made by reset
        self.engine.kalman_update = FilterpyUpdate()


class FilterpyTcEkf(TightlyCoupledEkf):
    """tc-ekf with filterpy's ExtendedKalmanFilter doing the measurement updates."""

    def reset(self, context: Context, prior: Prior) -> None:
        super().reset(context, prior)
        self.kalman_update = FilterpyUpdate()


class FilterpyUnscentedUpdate:
    """``(mean, P, hx, z, R, alpha, beta, kappa) -> (dx, P_new, nis, fallbacks)`` through
    filterpy's ``UnscentedKalmanFilter.update`` with ``MerweScaledSigmaPoints`` (one filter
    object per state/measurement size and sigma-point parameters).

    ``hx`` maps sigma points (N, n) to predicted measurements (N, m); filterpy calls it
    once per sigma point, as its update does. ``R`` is the (m,) diagonal or (m, m).
    """

    def __init__(self) -> None:
        from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

        self._ukf, self._points = UnscentedKalmanFilter, MerweScaledSigmaPoints
        self._filters: dict[tuple[int, int, float, float, float], UnscentedKalmanFilter] = {}
        self._fallbacks = 0

    def _sqrt(self, A: np.ndarray) -> np.ndarray:
        """filterpy's default square root (upper Cholesky factor); navsim's guarded factor,
        transposed to filterpy's row convention, only where it fails."""
        import scipy.linalg

        try:
            return scipy.linalg.cholesky(A)
        except np.linalg.LinAlgError:
            L, count = guarded_cholesky(A)
            self._fallbacks += 1 + count
            return L.T

    def __call__(self, mean: np.ndarray, P: np.ndarray, hx: Callable[[np.ndarray], np.ndarray], z: np.ndarray, R: np.ndarray,
                 alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0) -> tuple[np.ndarray, np.ndarray, float, int]:
        n, m = len(mean), len(z)
        key = (n, m, float(alpha), float(beta), float(kappa))
        kf = self._filters.get(key)
        if kf is None:
            points = self._points(n, alpha=alpha, beta=beta, kappa=kappa, sqrt_method=self._sqrt)
            kf = self._filters[key] = self._ukf(dim_x=n, dim_z=m, dt=1.0, hx=None, fx=None, points=points)
        self._fallbacks = 0
        kf.x = np.array(mean, dtype=float)
        kf.P = np.array(P, dtype=float)
        kf.sigmas_f = kf.points_fn.sigma_points(kf.x, kf.P)  # the prior's sigma points (time update done)
        R = np.asarray(R, dtype=float)
        kf.update(np.asarray(z, dtype=float), R=np.diag(R) if R.ndim == 1 else R, hx=lambda x: hx(x[None, :])[0])
        nis = float(kf.y @ kf.SI @ kf.y)
        return np.array(kf.x, dtype=float), 0.5 * (kf.P + kf.P.T), nis, self._fallbacks


class FilterpyTcUkf(TightlyCoupledUkf):
    """tc-ukf with filterpy's UnscentedKalmanFilter (Merwe sigma points) doing the measurement updates."""

    def reset(self, context: Context, prior: Prior) -> None:
        super().reset(context, prior)
        self.unscented_update = FilterpyUnscentedUpdate()
