"""GNSS only: single-epoch least-squares fixes, and a constant-velocity Kalman filter on them.

:class:`GnssLeastSquares`
    At each epoch with at least ``min_satellites`` valid channels: the position / clock
    fix :func:`navsim.receiver.least_squares_fix` and the velocity / clock-drift fix
    :func:`navsim.receiver.velocity_fix` (the receiver clock is estimated every
    epoch, so it needs no model). Between epochs (and through outages) the last fix is
    **extrapolated with the last velocity fix** (``extrapolate=True``, the default;
    ``False`` holds it). Covariance: ``sigma_rho^2 (H^T H)^-1`` and
    ``sigma_dot^2 (H^T H)^-1`` rotated to ENU, the position part growing as
    ``P_pos + tau^2 P_vel + q tau^3 / 3`` while extrapolating (q: ``accel_psd``). Before the first fix the prior is
    extrapolated the same way with the prior covariance.
:class:`GnssConstantVelocity`
    A 6-state constant-velocity Kalman filter (filterpy ``KalmanFilter``) in ECEF,
    ``[r_e, v_e]`` with white-acceleration process noise of PSD ``accel_psd`` per axis,
    updated at each epoch with the LS position and velocity fixes (R from the fix
    geometry and the nominal sigmas). Between epochs the estimate is the filter's
    prediction to the step time (closed form, the same as filterpy's predict over that
    span).

Step-wise (``step``, and ``step_row``: :class:`~navsim.estimators.base.RowStepping`), a
step without a GNSS epoch costs no batch: between usable fixes the estimate is a function
of the step time alone, so the rows of the next ``gnss_period_s / nav_period_s`` steps are
predicted in one call of the batch's own prediction, at the times ``(step + 1 + j) dt`` the
simulator gives its steps, and a step whose time is the next one predicted takes its row
(any other time is predicted alone; a fix or a changed option starts over). The
prediction is elementwise over the steps, so the rows are those of ``step_batch`` bit for
bit.

Neither estimates attitude: heading, pitch and roll are ``nan`` and so are the attitude
rows and columns of the 9 x 9 covariance (metrics skip them). The course over ground
``atan2(vE, vN)`` is a heading only for a vehicle without sideslip; it is not reported.

References
----------
.. [1] Misra P., Enge P., Global Positioning System: Signals, Measurements and
       Performance, 2nd ed., 2006, ch. 6 (least-squares position, DOP).
.. [2] Bar-Shalom Y., Li X.R., Kirubarajan T., Estimation with Applications to Tracking
       and Navigation, 2001, section 6.2.2 (continuous white-noise acceleration model).
.. [3] Labbe R., filterpy (KalmanFilter), https://github.com/rlabbe/filterpy.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..earth import mat_en
from ..errors import ConfigError
from ..option_checks import check_integer, check_nonnegative_finite, check_positive_finite
from .base import Context, Estimate, EstimateBatch, Measurement, MeasurementBatch, NoiseScalable, Prior, StepRow, row_of
from .loosely import gnss_fixes

if TYPE_CHECKING:
    from filterpy.kalman import KalmanFilter  # untyped: taken as Any

Predict = Callable[[np.ndarray, np.ndarray, np.ndarray], None]
"""``predict(t, solution, covariance)``: fill the rows of times t (views), no state change."""
TakeFix = Callable[[float, int, int, tuple[np.ndarray, ...], np.ndarray, np.ndarray], None]
"""``take_fix(t, index, e, fixes, nis, nis_dof)``: update the state with fix e at step index."""

__all__ = ["GnssLeastSquares", "GnssConstantVelocity"]

_NAN_ATT = np.full(3, np.nan)


def _check_min_satellites(value: float) -> int:
    return check_integer("min_satellites", value, 4)


def _covariance9(p_pos_n: np.ndarray, p_vel_n: np.ndarray, p_cross_n: np.ndarray | None = None) -> np.ndarray:
    cov = np.full((9, 9), np.nan)
    cov[:3, :3], cov[3:6, 3:6] = p_pos_n, p_vel_n
    if p_cross_n is None:
        cov[:3, 3:6] = cov[3:6, :3] = 0.0
    else:
        cov[:3, 3:6], cov[3:6, :3] = p_cross_n, p_cross_n.T
    return cov


def _estimate(t: float, row: np.ndarray, cov: np.ndarray, nis: float, dof: int, extra: dict) -> Estimate:
    has = not math.isnan(nis)
    return Estimate(t, row[0], row[1], row[2], row[3:6].copy(), row[6], row[7], row[8], covariance=cov,
                    nis=float(nis) if has else None, nis_dof=int(dof) if has else None, extra=extra)


class _RowsAhead:
    """The rows of the steps between usable fixes, predicted ahead (the step-wise path of
    both estimators, see the module docstring). ``key``: the time of the last fix (a new
    fix changes it) and the options the prediction reads; a changed key starts over."""

    __slots__ = ("span", "key", "t", "solution", "covariance", "next")

    def __init__(self, span: int) -> None:
        self.span = span
        self.key: tuple | None = None
        self.t: np.ndarray = np.empty(0)
        self.solution: np.ndarray = np.empty((0, 9))
        self.covariance: np.ndarray = np.empty((0, 9, 9))
        self.next = 0

    def row(self, m: Measurement, key: tuple, predict: Predict) -> tuple[np.ndarray, np.ndarray]:
        """``(row (9,), covariance (9, 9))`` of step ``m`` (copies: the caller's)."""
        i = self.next
        if self.key != key or i >= len(self.t) or self.t[i] != m.t:
            t = (np.arange(self.span) + (int(m.step) + 1)) * m.dt  # the simulator's (steps + 1) * dt
            if t[0] != m.t:  # times of another source: this step alone
                t = np.array([float(m.t)])
            self.t, self.key, i = t, key, 0
            self.solution, self.covariance = np.empty((len(t), 9)), np.empty((len(t), 9, 9))
            predict(t, self.solution, self.covariance)
        self.next = i + 1
        return self.solution[i].copy(), self.covariance[i].copy()


def _span(context: Context) -> int:
    """Steps per GNSS period: how many rows :class:`_RowsAhead` predicts in one call."""
    return max(1, min(10_000, round(context.gnss_period_s / context.nav_period_s)))


def _over_fixes(batch: MeasurementBatch, min_satellites: int, initial_e: np.ndarray, predict: Predict,
                take_fix: TakeFix) -> EstimateBatch:
    """The batch loop both GNSS-only estimators share.

    The fixes of all epochs come from one vectorised :func:`gnss_fixes` call. Steps
    between usable fixes are filled by ``predict(t, solution, covariance)`` (no state
    change); at each usable fix ``take_fix(t, index, e, fixes, nis, nis_dof)`` changes
    the state, then the fix's own step is filled by ``predict``.
    """
    n = len(batch)
    solution = np.empty((n, 9))
    covariance = np.empty((n, 9, 9))
    nis = np.full(n, np.nan)
    nis_dof = np.zeros(n, dtype=int)
    epochs = list(batch.gnss)
    fixes = gnss_fixes([o for _, o in epochs], min_satellites, initial_e)
    t = np.asarray(batch.t, dtype=float)
    start = 0
    marks = [(index, e) for e, (index, _) in enumerate(epochs) if fixes[0][e]] + [(n, -1)]
    for index, e in marks:
        stop = min(index, n)
        if stop > start:
            predict(t[start:stop], solution[start:stop], covariance[start:stop])
        if e < 0:
            break
        take_fix(float(t[index]), index, e, fixes, nis, nis_dof)
        predict(t[index:index + 1], solution[index:index + 1], covariance[index:index + 1])
        start = index + 1
    return EstimateBatch(solution, covariance, nis, nis_dof)


class _GnssOnly(NoiseScalable):
    """``step`` and ``step_row`` of both GNSS-only estimators: a step without an epoch
    from the rows predicted ahead (:class:`_RowsAhead`), any other through ``step_batch``
    on a batch of one. A subclass sets ``_ahead``, ``_n_valid`` and ``_t`` (the time of the
    last fix, of the prior before the first) in ``reset``, ``_t`` at each fix, and defines
    ``step_batch``, ``_predict`` (the batch's prediction, a :data:`Predict`) and ``_options``
    (the options ``_predict`` reads)."""

    _ahead: _RowsAhead | None = None  # set by reset
    _n_valid: int
    _t: float

    def step_batch(self, batch: MeasurementBatch) -> EstimateBatch:
        raise NotImplementedError

    def _predict(self, t: np.ndarray, solution: np.ndarray, covariance: np.ndarray) -> None:
        raise NotImplementedError

    def _options(self) -> tuple:
        raise NotImplementedError

    def step(self, measurement: Measurement) -> Estimate:
        """One navigation step (without an epoch: a row predicted ahead, see the module)."""
        if measurement.gnss is None and self._ahead is not None:
            row, cov = self._ahead.row(measurement, (self._t, *self._options()), self._predict)
            return _estimate(measurement.t, row, cov, math.nan, 0, {"n_valid": self._n_valid})
        out = self.step_batch(MeasurementBatch.of(measurement))
        assert out.covariance is not None  # _over_fixes fills it
        return _estimate(measurement.t, out.solution[0], out.covariance[0], out.nis[0], out.nis_dof[0],
                         {"n_valid": self._n_valid})

    def step_row(self, measurement: Measurement) -> StepRow:
        """:meth:`step` as ``(row (9,), covariance (9, 9), nis, nis_dof)`` (the
        :class:`~navsim.estimators.base.RowStepping` protocol): the same numbers."""
        if measurement.gnss is None and self._ahead is not None:
            row, cov = self._ahead.row(measurement, (self._t, *self._options()), self._predict)
            return row, cov, None, None
        return row_of(self.step(measurement))


class GnssLeastSquares(_GnssOnly):
    """Per-epoch LS fix, extrapolated (or held) between epochs.

    Parameters
    ----------
    extrapolate : bool
        True: position extrapolated with the last velocity fix between epochs;
        False: the last fix is held (its covariance is not grown).
    min_satellites : int
        Fewest valid channels for a fix (>= 4).
    measurement_scale : float
        Factor on the nominal pseudorange and Doppler sigmas.
    accel_psd : float
        White-acceleration PSD per axis, m^2/s^3, that the extrapolated covariance
        grows with (the vehicle's unmodelled acceleration: curves, speed changes);
        0 gives the pure constant-velocity covariance, which is overconfident through
        long outages on a curved track.
    """

    NOISE_MEASUREMENT_SIGMA = ('sigma_pos', 'sigma_vel')
    # where set_noise_scale finds Q and R after reset (navsim.estimators.base.NoiseScalable)

    def __init__(self, extrapolate: bool = True, min_satellites: int = 4, measurement_scale: float = 1.0,
                 accel_psd: float = 0.01) -> None:
        self.extrapolate = bool(extrapolate)
        self.accel_psd = check_nonnegative_finite("accel_psd", accel_psd, "a non-negative finite PSD, m^2/s^3")
        self.min_satellites = _check_min_satellites(min_satellites)
        check_positive_finite("measurement_scale", measurement_scale, "a positive finite factor")
        self.measurement_scale = float(measurement_scale)
        self.context: Context | None = None

    def reset(self, context: Context, prior: Prior) -> None:
        """Start from the prior position, velocity and covariance."""
        self.context = context
        self.earth = context.earth
        self.sigma_pos = self.measurement_scale * context.gnss.pseudorange_sigma_m
        self.sigma_vel = self.measurement_scale * context.gnss.doppler_sigma_mps
        self._initial_e = self.earth.geodetic_to_ecef(prior.lat, prior.lon, prior.h)
        cov = np.asarray(prior.covariance, dtype=float)
        # the last fix: time, ECEF position and velocity, ENU covariances (at the fix)
        self._t = float(prior.t)
        self._pos_e = self._initial_e.copy()
        m = mat_en(prior.lat, prior.lon)
        self._vel_e = m.T @ np.asarray(prior.velocity_n, dtype=float)
        self._p_pos, self._p_vel = cov[:3, :3].copy(), cov[3:6, 3:6].copy()
        self._n_valid = 0
        self._ahead = _RowsAhead(_span(context))

    def _options(self) -> tuple:
        return (self.extrapolate, self.accel_psd)

    def step_batch(self, batch: MeasurementBatch) -> EstimateBatch:
        """n steps at once (fixes of all epochs in one vectorised call)."""
        if self.context is None:
            raise ConfigError("GnssLeastSquares", "reset(context, prior) before stepping", "no reset")
        return _over_fixes(batch, self.min_satellites, self._initial_e, self._predict, self._take_fix)

    def _take_fix(self, t: float, index: int, e: int, fixes: tuple, nis: np.ndarray, nis_dof: np.ndarray) -> None:
        _, pos_e, cov_pos, vel_e, cov_vel, n_valid = fixes
        self._pos_e, self._vel_e, self._t = pos_e[e], vel_e[e], t
        self._n_valid = int(n_valid[e])
        lat, lon, h = (float(x) for x in self.earth.ecef_to_geodetic(self._pos_e))
        m = mat_en(lat, lon)
        self._p_pos = self.sigma_pos**2 * (m @ cov_pos[e] @ m.T)
        self._p_vel = self.sigma_vel**2 * (m @ cov_vel[e] @ m.T)

    def _predict(self, t: np.ndarray, solution: np.ndarray, covariance: np.ndarray) -> None:
        tau = (t - self._t) if self.extrapolate else np.zeros_like(t)
        pos_e = self._pos_e + tau[:, None] * self._vel_e
        lat, lon, h = self.earth.ecef_to_geodetic(pos_e)
        m = mat_en(lat, lon)  # (k, 3, 3)
        solution[:, 0], solution[:, 1], solution[:, 2] = lat, lon, h
        solution[:, 3:6] = m @ self._vel_e
        solution[:, 6:] = np.nan
        covariance[:] = _covariance9(self._p_pos, self._p_vel)
        # P_pos(tau) = P_pos + tau^2 P_vel + q tau^3 / 3, cov(pos, vel) = tau P_vel + q tau^2 / 2,
        # P_vel(tau) = P_vel + q tau  (white acceleration of PSD q per axis)
        eye, q, tt = np.eye(3), self.accel_psd, tau[:, None, None]
        covariance[:, :3, :3] += tt**2 * self._p_vel + (q * tt**3 / 3.0) * eye
        covariance[:, :3, 3:6] = covariance[:, 3:6, :3] = tt * self._p_vel + (q * tt**2 / 2.0) * eye
        covariance[:, 3:6, 3:6] += (q * tt) * eye


class GnssConstantVelocity(_GnssOnly):
    """Constant-velocity Kalman filter (filterpy) on the LS position and velocity fixes.

    Parameters
    ----------
    accel_psd : float
        White-acceleration PSD per ECEF axis, m^2/s^3 (the vehicle's unmodelled
        acceleration; 0.1 suits a train or car at steady speed).
    use_velocity : bool
        Also update with the Doppler velocity fix.
    min_satellites : int
        Fewest valid channels for an update.
    measurement_scale : float
        Factor on the nominal GNSS sigmas.
    """

    NOISE_PROCESS = ('accel_psd',)
    NOISE_MEASUREMENT_SIGMA = ('sigma_pos', 'sigma_vel')
    # where set_noise_scale finds Q and R after reset (navsim.estimators.base.NoiseScalable)

    def __init__(self, accel_psd: float = 0.1, use_velocity: bool = True, min_satellites: int = 4,
                 measurement_scale: float = 1.0) -> None:
        check_nonnegative_finite("accel_psd", accel_psd, "a non-negative finite PSD, m^2/s^3")
        check_positive_finite("measurement_scale", measurement_scale, "a positive finite factor")
        self.accel_psd = float(accel_psd)
        self.use_velocity = bool(use_velocity)
        self.min_satellites = _check_min_satellites(min_satellites)
        self.measurement_scale = float(measurement_scale)
        self.kf: KalmanFilter | None = None

    def reset(self, context: Context, prior: Prior) -> None:
        """Initialise the filter from the prior (ENU covariance rotated to ECEF)."""
        from filterpy.kalman import KalmanFilter

        self.earth = context.earth
        self.sigma_pos = self.measurement_scale * context.gnss.pseudorange_sigma_m
        self.sigma_vel = self.measurement_scale * context.gnss.doppler_sigma_mps
        m = mat_en(prior.lat, prior.lon)
        big = np.zeros((6, 6))
        big[:3, :3] = big[3:, 3:] = m.T
        kf = KalmanFilter(dim_x=6, dim_z=6 if self.use_velocity else 3)
        pos_e = self.earth.geodetic_to_ecef(prior.lat, prior.lon, prior.h)
        kf.x = np.concatenate([pos_e, m.T @ np.asarray(prior.velocity_n, dtype=float)])
        kf.P = big @ np.asarray(prior.covariance, dtype=float)[:6, :6] @ big.T
        kf.H = np.eye(6)[: kf.dim_z]
        self.kf = kf
        self._initial_e = pos_e
        self._t = float(prior.t)
        self._n_valid = 0
        self._ahead = _RowsAhead(_span(context))

    def _fq(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        # x' = F x: r += v tau; Q of white acceleration q: [[t^3/3, t^2/2], [t^2/2, t]] q
        F = np.eye(6)
        F[:3, 3:] = tau * np.eye(3)
        q = self.accel_psd
        Q = np.zeros((6, 6))
        Q[:3, :3] = q * tau**3 / 3.0 * np.eye(3)
        Q[:3, 3:] = Q[3:, :3] = q * tau**2 / 2.0 * np.eye(3)
        Q[3:, 3:] = q * tau * np.eye(3)
        return F, Q

    def _options(self) -> tuple:
        return (self.accel_psd,)

    def step_batch(self, batch: MeasurementBatch) -> EstimateBatch:
        """n steps at once: filterpy predict/update at epochs, closed-form prediction between."""
        if self.kf is None:
            raise ConfigError("GnssConstantVelocity", "reset(context, prior) before stepping", "no reset")
        return _over_fixes(batch, self.min_satellites, self._initial_e, self._predict, self._take_fix)

    def _take_fix(self, t: float, index: int, e: int, fixes: tuple, nis: np.ndarray, nis_dof: np.ndarray) -> None:
        _, pos_e, cov_pos, vel_e, cov_vel, n_valid = fixes
        kf = self.kf
        assert kf is not None  # step_batch checked the reset
        # predict to the epoch: x = F x, P = F P F^T + Q
        kf.F, kf.Q = self._fq(t - self._t)
        kf.predict()
        self._t = t
        # update: z = [r_fix, v_fix], R from the fix geometry
        z = np.concatenate([pos_e[e], vel_e[e]])[: kf.dim_z]
        R_full = np.zeros((6, 6))
        R_full[:3, :3] = self.sigma_pos**2 * cov_pos[e]
        R_full[3:, 3:] = self.sigma_vel**2 * cov_vel[e]
        R = R_full[: kf.dim_z, : kf.dim_z]
        kf.update(z, R=0.5 * (R + R.T))
        kf.P = 0.5 * (kf.P + kf.P.T)
        y = np.asarray(kf.y, dtype=float).reshape(-1)
        nis[index] = float(y @ np.linalg.solve(kf.S, y))
        nis_dof[index] = kf.dim_z
        self._n_valid = int(n_valid[e])

    def _predict(self, t: np.ndarray, solution: np.ndarray, covariance: np.ndarray) -> None:
        """The prediction of the current filter state to times t (no state change)."""
        kf = self.kf
        assert kf is not None  # step_batch checked the reset
        x = np.asarray(kf.x, dtype=float).reshape(-1)
        P = kf.P
        tau = t - self._t
        pos_e = x[:3] + tau[:, None] * x[3:]
        lat, lon, h = self.earth.ecef_to_geodetic(pos_e)
        m = mat_en(lat, lon)  # (k, 3, 3)
        solution[:, 0], solution[:, 1], solution[:, 2] = lat, lon, h
        solution[:, 3:6] = m @ x[3:]
        solution[:, 6:] = np.nan
        T = tau[:, None, None]
        q = self.accel_psd
        # P(tau) = F P F^T + Q blocks with F = [[I, tau I], [0, I]]
        p_rr = P[:3, :3] + T * (P[:3, 3:] + P[3:, :3]) + T**2 * P[3:, 3:] + q * T**3 / 3.0 * np.eye(3)
        p_rv = P[:3, 3:] + T * P[3:, 3:] + q * T**2 / 2.0 * np.eye(3)
        p_vv = P[3:, 3:] + q * T * np.eye(3)
        mt = np.swapaxes(m, -1, -2)
        covariance[:] = np.nan
        covariance[:, :3, :3] = m @ p_rr @ mt
        covariance[:, 3:6, 3:6] = m @ p_vv @ mt
        covariance[:, :3, 3:6] = m @ p_rv @ mt
        covariance[:, 3:6, :3] = np.swapaxes(covariance[:, :3, 3:6], -1, -2)
