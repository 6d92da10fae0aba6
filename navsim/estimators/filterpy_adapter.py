"""A user's own filterpy filter as a navsim estimator: :func:`from_filterpy`.

``from_filterpy(kf, fx, hx, ...)`` wraps a filterpy ``KalmanFilter``,
``ExtendedKalmanFilter`` or ``UnscentedKalmanFilter`` [1] (configured by the user: dimensions,
F/Q/H, sigma points, noise) into an object with navsim's estimator interface
(:mod:`navsim.estimators.base`): ``reset(context, prior)`` and ``step(measurement) ->
Estimate``. The filter's own ``predict`` and ``update`` do all the arithmetic; the adapter
only feeds them and reads ``x``, ``P``, ``y`` and ``SI`` back.

What the filter receives
    At ``reset`` a fresh deep copy of ``kf`` (episodes never share state) gets its initial
    state from the prior (``init``, below) and ``configure(kf, context)`` is called if given
    (e.g. to build F and Q for the navigation period ``context.nav_period_s``). At every
    navigation step (``measurement.dt`` s, 0.01 s in the bundled scenarios) one ``predict``:

    * ``KalmanFilter``: ``kf.predict()`` with the filter's F, Q (``fx`` unused);
    * ``ExtendedKalmanFilter``: ``kf.predict()``; with ``fx`` the mean is ``fx(x, dt)``
      instead of ``F x`` and, with ``fx_jacobian``, ``kf.F = fx_jacobian(x, dt)`` first;
    * ``UnscentedKalmanFilter``: ``kf.predict(dt=dt, fx=fx)`` (``fx(x, dt)``; None: the
      filter's own).

    At a GNSS epoch the measurement ``z, R = measure(measurement)``; ``None`` (too few
    satellites, an outage) skips the update. The update is ``kf.update(z, R=R)`` (KF,
    H = the filter's), ``kf.update(z, HJacobian=hx_jacobian, Hx=hx, R=R)`` (EKF) or
    ``kf.update(z, R=R, hx=hx)`` (UKF).

Measurements (``measure``)
    ``"fix"`` (default): the receiver's single-epoch least-squares position and velocity
    fixes (:mod:`navsim.receiver`, the raw pseudoranges and rates of the valid channels,
    at least 4), in metres and m/s along the East, North, Up axes of a local tangent plane
    at the prior position (the origin fixed at ``reset``), ``z = [E, N, U, vE, vN, vU]``,
    ``R = blockdiag(sigma_rho^2 C (H^T H)^-1 C^T, sigma_rhodot^2 C (H_v^T H_v)^-1 C^T)``
    (C the ECEF-to-ENU rotation at the origin, sigmas the context's nominal ones, floors
    1 mm and 0.1 mm/s); ``"position"``: the position fix alone (3,). A callable
    ``measure(measurement, adapter) -> (z, R) | None`` gives any other (e.g. raw
    pseudoranges for the user's own hx; ``adapter.to_enu(r_e)`` and ``adapter.origin_e``
    help).

    Default ``hx``/``hx_jacobian`` (when None): ``x[:k]`` and ``[I_k 0]`` with k = len(z);
    for a KalmanFilter whose H is still filterpy's zeros, H = ``[I_k 0]``.

What it must return (``output``)
    Default: the state starts with the tangent-plane position and velocity, ``x[:6] =
    [E, N, U, vE, vN, vU]`` (m, m/s), and ``P[:6, :6]`` is their covariance. The estimate
    is the geodetic position of ``origin + C^T x[:3]``, the velocity and covariance rotated
    from the tangent plane to the local ENU axes at that position (a rotation by the angle
    between the two verticals, ~ distance / R), attitude NaN (not estimated; its covariance
    rows NaN, which the metrics skip). ``output(x, P) -> (p_enu (3,), v_enu (3,),
    cov (6, 6))`` maps any other state layout to those tangent-plane quantities. NIS: ``y^T
    SI y`` of the update (filterpy's innovation and inverse innovation covariance), with
    ``len(z)`` degrees of freedom.

Initial state (``init``)
    Default: ``x = 0`` except ``x[3:6]`` = the prior's ENU velocity (the origin is the
    prior's position), ``P`` = the filter's P with ``P[:6, :6]`` = the prior's
    position/velocity covariance. ``init(kf, context, prior)`` sets ``kf.x``, ``kf.P``
    itself (the tangent-plane origin is still the prior position).

The adapter has no batch path: every face (``run_episode``, the envs, the estimator FMU)
calls ``step`` once per navigation step, so all give the same numbers.

Example (``examples/filterpy_cv.py``; ``navsim bench paper-2012 --estimators
examples/filterpy_cv.py:make``)::

    from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter
    from navsim.estimators.filterpy_adapter import from_filterpy

    def make(accel_psd=0.1):
        ukf = UnscentedKalmanFilter(6, 6, 0.01, hx=None, fx=None, points=MerweScaledSigmaPoints(6, 0.5, 2, -3))
        ...  # Q for white acceleration
        return from_filterpy(ukf, fx=lambda x, dt: cv_transition(dt) @ x, hx=lambda x: x[:6])

References
----------
.. [1] Labbe R., filterpy, ``filterpy.kalman`` (KalmanFilter, ExtendedKalmanFilter,
       UnscentedKalmanFilter), https://github.com/rlabbe/filterpy; "Kalman and Bayesian
       Filters in Python", ch. 8, 10, 11.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Union

import numpy as np
from numpy.typing import ArrayLike

from ..earth import mat_en
from ..errors import ConfigError
from ..receiver import least_squares_fix, velocity_fix
from .base import Context, Estimate, Measurement, Prior

if TYPE_CHECKING:  # filterpy is untyped: these are Any to the checker
    from filterpy.kalman import ExtendedKalmanFilter, KalmanFilter, UnscentedKalmanFilter

__all__ = ["from_filterpy", "FilterpyEstimator"]

Filter = Union["KalmanFilter", "ExtendedKalmanFilter", "UnscentedKalmanFilter"]
"""A configured filterpy filter (the three kinds :func:`from_filterpy` takes)."""
Transition = Callable[[np.ndarray, float], np.ndarray]
"""``fx(x, dt) -> x`` (or ``-> F`` for ``fx_jacobian``)."""
MeasurementFunction = Callable[[np.ndarray], np.ndarray]
"""``hx(x) -> z`` (or ``-> H`` for ``hx_jacobian``)."""
Measure = Callable[[Measurement, "FilterpyEstimator"], "tuple[ArrayLike, ArrayLike] | None"]
"""``measure(measurement, adapter) -> (z, R)`` or None (no update)."""
Output = Callable[[np.ndarray, np.ndarray], tuple[ArrayLike, ArrayLike, ArrayLike]]
"""``output(x, P) -> (p_enu, v_enu, cov6)``."""
Init = Callable[[Filter, Context, Prior], None]
"""``init(kf, context, prior)``: set ``kf.x`` and ``kf.P``."""
Configure = Callable[[Filter, Context], None]
"""``configure(kf, context)``: e.g. F, Q for ``context.nav_period_s``."""

SIGMA_FLOOR_PR_M = 1e-3
SIGMA_FLOOR_RATE_MPS = 1e-4


def _kind(kf: Filter) -> str:
    from filterpy.kalman import ExtendedKalmanFilter, KalmanFilter, UnscentedKalmanFilter

    if isinstance(kf, UnscentedKalmanFilter):
        return "ukf"
    if isinstance(kf, ExtendedKalmanFilter):
        return "ekf"
    if isinstance(kf, KalmanFilter):
        return "kf"
    raise ConfigError("from_filterpy kf", "a filterpy KalmanFilter, ExtendedKalmanFilter or UnscentedKalmanFilter",
                      type(kf).__name__)


def from_filterpy(kf: Filter, fx: Transition | None = None, hx: MeasurementFunction | None = None, *,
                  fx_jacobian: Transition | None = None, hx_jacobian: MeasurementFunction | None = None,
                  measure: str | Measure = "fix", output: Output | None = None,
                  init: Init | None = None, configure: Configure | None = None,
                  min_satellites: int = 4) -> FilterpyEstimator:
    """Turn a configured filterpy filter plus ``fx``/``hx`` into a navsim estimator.

    Parameters
    ----------
    kf : filterpy ``KalmanFilter``, ``ExtendedKalmanFilter`` or ``UnscentedKalmanFilter``
        Deep-copied at every ``reset``.
    fx : callable ``(x, dt) -> x``, optional
        State transition (EKF: the mean; UKF: each sigma point). KalmanFilter: unused.
    hx : callable ``x -> z``, optional
        Measurement function (EKF, UKF); default ``x[:len(z)]``.
    fx_jacobian : callable ``(x, dt) -> F``, optional
        EKF only: F set before each predict (otherwise the filter's F).
    hx_jacobian : callable ``x -> H``, optional
        EKF only (``HJacobian``); default ``[I 0]``.
    measure : ``"fix"``, ``"position"`` or callable ``(measurement, adapter) -> (z, R) | None``
        What an update receives (module docstring).
    output : callable ``(x, P) -> (p_enu, v_enu, cov6)``, optional
        From the state to the tangent-plane position, velocity and their covariance.
    init : callable ``(kf, context, prior) -> None``, optional
        Sets ``kf.x`` and ``kf.P`` from the prior.
    configure : callable ``(kf, context) -> None``, optional
        Called at each reset after ``init`` (e.g. F, Q for ``context.nav_period_s``).
    min_satellites : int
        Fewest valid channels for a fix (``measure`` "fix"/"position").
    """
    return FilterpyEstimator(kf, fx, hx, fx_jacobian=fx_jacobian, hx_jacobian=hx_jacobian, measure=measure,
                             output=output, init=init, configure=configure, min_satellites=min_satellites)


class FilterpyEstimator:
    """A filterpy filter behind navsim's estimator interface (built by :func:`from_filterpy`)."""

    def __init__(self, kf: Filter, fx: Transition | None = None, hx: MeasurementFunction | None = None, *,
                 fx_jacobian: Transition | None = None, hx_jacobian: MeasurementFunction | None = None,
                 measure: str | Measure = "fix", output: Output | None = None, init: Init | None = None,
                 configure: Configure | None = None, min_satellites: int = 4) -> None:
        self.kind = _kind(kf)
        if not (callable(measure) or measure in ("fix", "position")):
            raise ConfigError("from_filterpy measure", "'fix', 'position' or a callable", measure)
        if int(min_satellites) != min_satellites or min_satellites < 4:
            raise ConfigError("from_filterpy min_satellites", "an integer >= 4", min_satellites)
        if self.kind != "ekf" and (fx_jacobian is not None or hx_jacobian is not None):
            raise ConfigError("from_filterpy", "fx_jacobian/hx_jacobian only with an ExtendedKalmanFilter",
                              self.kind)
        self._template = copy.deepcopy(kf)
        self.fx, self.hx, self.fx_jacobian, self.hx_jacobian = fx, hx, fx_jacobian, hx_jacobian
        self.measure, self.output, self.init, self.configure = measure, output, init, configure
        self.min_satellites = int(min_satellites)
        self.kf: Filter | None = None

    # ------------------------------------------------------------------ frames
    def to_enu(self, r_e: np.ndarray) -> np.ndarray:
        """ECEF position (m) to the tangent-plane ENU coordinates at the origin (m)."""
        return self._c0 @ (np.asarray(r_e, dtype=float) - self.origin_e)

    def _from_enu(self, p: np.ndarray) -> np.ndarray:
        return self.origin_e + self._c0.T @ np.asarray(p, dtype=float)

    # ------------------------------------------------------------------ interface
    def reset(self, context: Context, prior: Prior) -> None:
        """A fresh copy of the filter, its initial state from the prior (``init``), then ``configure``."""
        self.context = context
        self.earth = context.earth
        self.origin_e = np.asarray(self.earth.geodetic_to_ecef(prior.lat, prior.lon, prior.h), dtype=float)
        self._c0 = mat_en(prior.lat, prior.lon)  # ECEF -> ENU at the origin
        self.sigma_pr = max(float(context.gnss.pseudorange_sigma_m), SIGMA_FLOOR_PR_M)
        self.sigma_rate = max(float(context.gnss.doppler_sigma_mps), SIGMA_FLOOR_RATE_MPS)
        kf = self.kf = copy.deepcopy(self._template)
        if self.init is not None:
            self.init(kf, context, prior)
        else:
            n = len(np.ravel(kf.x))
            if n < 6:
                raise ConfigError("from_filterpy kf", "at least 6 states [E, N, U, vE, vN, vU] (or an init callable)",
                                  n)
            x = np.zeros(n)
            x[3:6] = np.asarray(prior.velocity_n, dtype=float)
            P = np.array(kf.P, dtype=float)
            cov = np.asarray(prior.covariance, dtype=float) if prior.covariance is not None else None
            if cov is not None and np.all(np.isfinite(cov[:6, :6])):
                P[:6, :] = 0.0
                P[:, :6] = 0.0
                P[:6, :6] = cov[:6, :6]
            kf.x = x.reshape(np.shape(kf.x)) if self.kind == "kf" else x
            kf.P = P
        if self.configure is not None:
            self.configure(kf, context)
        self.last_extra: dict = {}

    def _fix(self, m: Measurement) -> tuple[np.ndarray, np.ndarray] | None:
        g = m.gnss
        if g is None or np.count_nonzero(g.valid) < self.min_satellites:
            return None
        guess = self._from_enu(self._state()[0])
        fix = least_squares_fix(g.sat_pos_e, g.pseudorange_m, g.valid, self.earth, initial=guess)
        if not bool(fix.ok):
            return None
        c = self._c0
        p = self.to_enu(fix.position_e)
        R_p = self.sigma_pr**2 * (c @ fix.covariance[:3, :3] @ c.T)
        if self.measure == "position":
            return p, R_p
        vfix = velocity_fix(g.sat_pos_e, g.sat_vel_e, g.pseudorange_rate_mps, g.valid, fix.position_e)
        if not bool(vfix.ok):
            return None
        R = np.zeros((6, 6))
        R[:3, :3] = R_p
        R[3:, 3:] = self.sigma_rate**2 * (c @ vfix.covariance[:3, :3] @ c.T)
        return np.concatenate([p, c @ vfix.velocity_e]), R

    def _state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(p_enu, v_enu, cov6) of the filter's state (``output`` or the first six states)."""
        kf = self.kf
        assert kf is not None, "reset() first"
        x = np.ravel(kf.x)
        if self.output is not None:
            p, v, cov = self.output(x, np.asarray(kf.P))
            return np.asarray(p, dtype=float), np.asarray(v, dtype=float), np.asarray(cov, dtype=float)
        return x[:3].astype(float), x[3:6].astype(float), np.array(kf.P, dtype=float)[:6, :6]

    def _predict(self, dt: float) -> None:
        kf = self.kf
        assert kf is not None, "reset() first"
        if self.kind == "kf":
            kf.predict()
        elif self.kind == "ekf":
            if self.fx_jacobian is not None:
                kf.F = np.asarray(self.fx_jacobian(kf.x, dt), dtype=float)
            if self.fx is not None:
                fx = self.fx

                def predict_x(u: object = 0) -> None:
                    kf.x = np.asarray(fx(kf.x, dt), dtype=float)

                kf.predict_x = predict_x
            kf.predict()
        else:
            kf.predict(dt=dt, fx=self.fx)

    def _update(self, z: np.ndarray, R: np.ndarray) -> float:
        kf = self.kf
        assert kf is not None, "reset() first"
        k, n = len(z), len(np.ravel(kf.x))
        select = np.eye(k, n)
        if self.kind == "kf":
            if not np.any(kf.H):
                kf.H = select
            kf.update(z.reshape(-1, 1) if np.ndim(kf.x) == 2 else z, R=R)
        elif self.kind == "ekf":
            hx = self.hx if self.hx is not None else (lambda x: np.ravel(x)[:k])
            jac = self.hx_jacobian if self.hx_jacobian is not None else (lambda x: select)
            kf.update(z, HJacobian=jac, Hx=hx, R=R)
        else:
            kf.update(z, R=R, hx=self.hx if self.hx is not None else (lambda x: x[:k]))
        y = np.ravel(kf.y)
        return float(y @ np.asarray(kf.SI) @ y)

    def step(self, measurement: Measurement) -> Estimate:
        """One ``predict`` over the step, an ``update`` at a GNSS epoch with a measurement."""
        if self.kf is None:
            raise ConfigError("FilterpyEstimator", "reset(context, prior) before stepping", "no reset")
        m = measurement
        self._predict(float(m.dt))
        nis: float | None = None
        dof: int | None = None
        if m.gnss is not None:
            got = self.measure(m, self) if callable(self.measure) else self._fix(m)
            if got is not None:
                z, R = np.asarray(got[0], dtype=float), np.asarray(got[1], dtype=float)
                nis, dof = self._update(z, R), len(z)
        p, v, cov6 = self._state()
        r_e = self._from_enu(p)
        lat, lon, h = (float(a) for a in self.earth.ecef_to_geodetic(r_e))
        rot = mat_en(lat, lon) @ self._c0.T  # tangent plane at the origin -> ENU here
        big = np.zeros((6, 6))
        big[:3, :3] = big[3:, 3:] = rot
        cov = np.full((9, 9), np.nan)
        cov[:6, :6] = big @ cov6 @ big.T
        cov[:6, :6] = 0.5 * (cov[:6, :6] + cov[:6, :6].T)
        self.last_extra = {"filterpy": self.kind}
        return Estimate(m.t, lat, lon, h, rot @ v, math.nan, math.nan, math.nan, covariance=cov, nis=nis,
                        nis_dof=dof, extra=self.last_extra)
