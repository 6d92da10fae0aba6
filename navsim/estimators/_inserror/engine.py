"""The propagation engine :class:`ErrorStateIns` (INS mechanisation on bias-compensated
increments, the covariance propagated once per covariance interval, closed-loop updates),
its auxiliary-state forms :class:`AuxBlocksIns`, :class:`AuxStateIns`, the odometer's
:func:`body_velocity_terms` and :func:`nis_threshold`. The model and the covariance
intervals: :mod:`navsim.estimators._inserror`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Callable, Generic, TypeVar, overload

import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import chi2

from ...errors import ConfigError
from ...rotations import quat_to_mat
from ...strapdown import compiled as _compiled
from ...strapdown import ins as _ins
from ...strapdown import onestep as _one
from ...strapdown.ins import InsState
from .model import (
    ATT,
    BA,
    BG,
    N_STATES,
    NAV,
    VEL,
    ImuNoise,
    TransitionSeries,
    correct_state,
    cross3,
    error_dynamics,
    joseph_update,
    noise_density,
    skew3,
    solution_rows,
    state_from_prior,
)
from .terms import BodyTerms, StepTerms, body_terms

if TYPE_CHECKING:  # type hints only
    from ...types import Context, Prior

T = TypeVar("T")
Arr = np.ndarray | None  # an optional input array (sub-sample increments, a batch's fields)


class _InWork(Generic[T]):
    """An attribute of :class:`ErrorStateIns` kept in its work array ``_w[start:stop]``
    (:func:`navsim.strapdown.compiled.work_array`), where the compiled one-step path reads
    it and adds to it: assignment copies the value in, reading gives ``read`` of the slice
    (a view, or the Python floats of the float path). One place for every path, so a deep
    copy of the engine copies it with the array."""

    def __init__(self, start: int, stop: int, read: Callable[[np.ndarray], T], doc: str) -> None:
        self.index = slice(start, stop)
        self.read = read
        self.__doc__ = doc

    @overload
    def __get__(self, obj: None, owner: type | None = None) -> _InWork[T]: ...

    @overload
    def __get__(self, obj: ErrorStateIns, owner: type | None = None) -> T: ...

    def __get__(self, obj: ErrorStateIns | None, owner: type | None = None) -> T | _InWork[T]:
        if obj is None:
            return self
        return self.read(obj._w[self.index])

    def __set__(self, obj: ErrorStateIns, value: ArrayLike) -> None:
        obj._w[self.index] = value


class ErrorStateIns:
    """INS mechanisation plus a 15-state error covariance with closed-loop feedback.

    Parameters
    ----------
    context : navsim.estimators.base.Context
        Earth model and time base (``nav_period_s``).
    prior : navsim.simulator.Prior
        Initial state; its 9 x 9 covariance starts the navigation block of P, the bias
        block starts at ``diag(sigma^2)`` of ``noise``.
    noise : ImuNoise
    interval_steps : int
        Navigation steps per covariance interval (see the module notes).
    coning, sculling, position : str or None
        Strapdown methods (None: the most accurate the data allow).
    estimate_biases : bool
        False keeps the bias estimates at zero (the bias states still shape P).

    Attributes
    ----------
    state : InsState
        The corrected INS state at the last processed step.
    gyro_bias, accel_bias : ndarray (3,)
        Current bias estimates (body axes), rad/s and m/s^2.
    steps : int
        Navigation steps processed since the reset.
    diverged : bool
        Set when the covariance lost symmetry/positive definiteness or became non-finite
        (it is then repaired: symmetrised, eigenvalues floored), or the state became
        non-finite.
    """

    # The Kalman arithmetic of a measurement update, (P, H, R, innovation) -> (dx, P_new,
    # nis); replaceable per instance (navsim.estimators.filterpy_based hands it to filterpy).
    kalman_update = staticmethod(joseph_update)

    def __init__(self, context: Context, prior: Prior, noise: ImuNoise, *, interval_steps: int = 100,
                 coning: str | None = None, sculling: str | None = None, position: str | None = None,
                 estimate_biases: bool = True) -> None:
        if int(interval_steps) != interval_steps or interval_steps < 1:
            raise ConfigError("interval_steps", "a positive integer number of navigation steps", interval_steps)
        self.earth = context.earth
        self.dt = float(context.nav_period_s)
        # the work array of the compiled one-step path (navsim.strapdown.compiled.step_row):
        # constants, biases, state, the specific-force sum of the interval (kept here on
        # every path) and the input layout found fit
        self._w = _compiled.work_array(self.earth, self.dt)
        self._in_w = False  # the state lives in the work array (the compiled path's last step)
        self._row_kernel: Callable[..., int] | None = None  # the compiled step_row once a layout is found fit
        self._dummy = np.zeros((1, 3))  # the sub-sample arguments of a step without them
        self.noise = noise
        self.interval_steps = int(interval_steps)
        self.methods = dict(coning=coning, sculling=sculling, position=position)
        self._resolved: dict[tuple, Any] = {}  # input shapes -> resolved (coning, sculling, position)
        self._compiled_key: tuple | None = None  # the input shapes advance_row found fit for the compiled step
        self._state: InsState | None = None
        self._flat: tuple | None = None  # the state as Python floats (see _floats), when built
        self._pending: np.ndarray | None = None  # the covariance starting the next interval, when due
        self._poly: np.ndarray | None = None
        self._nav_block: np.ndarray | None = None
        self.estimate_biases = bool(estimate_biases)
        self.Qc = noise_density(noise)
        self.state = state_from_prior(prior)
        self.gyro_bias = np.zeros(3)
        self.accel_bias = np.zeros(3)
        P = np.zeros((N_STATES, N_STATES))
        P[NAV, NAV] = np.asarray(prior.covariance, dtype=float)
        P[BG, BG] = np.eye(3) * noise.gyro_bias_sigma**2
        P[BA, BA] = np.eye(3) * noise.accel_bias_sigma**2
        self.steps = 0
        self.diverged = False
        g = self.earth.gravity_n(self.state.lat, self.state.h)
        self._f_n = -np.asarray(g, dtype=float)  # at rest until measured
        self._f_sum = np.zeros(3)
        # a subclass's hook of the one-step path, called only when it has one
        self._after_hook = type(self)._after_steps is not ErrorStateIns._after_steps
        self._start_interval(P)

    # -- the INS state ----------------------------------------------------------------
    @property
    def state(self) -> InsState:
        """The corrected INS state at the last processed step."""
        if self._state is None:  # built on demand after steps of the one-step path
            lat, lon, h, velocity, quat, compensation = self._floats()
            self._state = InsState(lat, lon, h, np.array(velocity), np.array(quat), compensation)
        return self._state

    @state.setter
    def state(self, value: InsState) -> None:
        self._state = value
        self._flat = None
        self._in_w = False

    gyro_bias = _InWork[np.ndarray](_compiled.W_GYRO, _compiled.W_ACCEL, np.ndarray.view,
                                    "Gyro bias estimate (3,), rad/s, body axes.")
    accel_bias = _InWork[np.ndarray](_compiled.W_ACCEL, _compiled.W_STATE, np.ndarray.view,
                                     "Accelerometer bias estimate (3,), m/s^2, body axes.")
    _f_sum = _InWork[list](_compiled.W_FSUM, _compiled.W_LAYOUT, np.ndarray.tolist,
                           "Sum of the specific-force increments (ENU, m/s) of the current interval, as floats.")

    def _floats(self) -> tuple:
        """The state as Python floats: (lat, lon, h, velocity (3,), quat (4,), compensation)."""
        if self._flat is None:
            st = self._state
            if st is None:  # the compiled one-step path holds the state in its work array
                v = self._w[_compiled.W_STATE:_compiled.W_FSUM].tolist()
                self._flat = (v[0], v[1], v[2], v[6:9], v[9:13], (v[3], v[4], v[5]))
            else:
                self._flat = (st.lat, st.lon, st.h, st.velocity_n.tolist(), st.quat_nb.tolist(), st.compensation)
        return self._flat

    # -- covariance intervals ----------------------------------------------------------
    def _start_interval(self, P: np.ndarray) -> None:
        """Begin a covariance interval at the current step with covariance P."""
        steps = getattr(self, "_j", 0)  # steps of the interval that ends here (the sum's terms)
        if steps:  # mean specific force of the interval that ends here
            self._f_n = np.asarray(self._f_sum) / (steps * self.dt)
        self._f_sum = np.zeros(3)
        self._P0 = P
        self._pending = None
        span = steps * self.dt  # length of the interval that ends here, s
        self._j = 0  # steps into the interval
        st = self.state
        C = quat_to_mat(st.quat_nb)
        F = error_dynamics(st.lat, st.h, st.velocity_n, C, self._f_n, self.earth, self.noise)
        Qc = self.Qc
        if self.noise.gyro_scale_sigma > 0.0 or self.noise.accel_scale_sigma > 0.0:
            # (RS.1), (RS.2) with the mean rate and acceleration of the interval that ends here
            c0 = getattr(self, "_mat_nb0", None)
            if c0 is not None and span > 0.0:
                cos_angle = min(1.0, max(-1.0, 0.5 * (float(np.trace(c0.T @ C)) - 1.0)))
                self._rate = math.acos(cos_angle) / span
            Qc = Qc.copy()
            Qc[6:9, 6:9] += np.eye(3) * (self.noise.gyro_scale_sigma * getattr(self, "_rate", 0.0)) ** 2 \
                * self.noise.scale_tau_s
            accel = self._f_n + np.asarray(self.earth.gravity_n(st.lat, st.h), dtype=float)  # kinematic part
            Qc[3:6, 3:6] += np.eye(3) * (self.noise.accel_scale_sigma**2 * float(accel @ accel)
                                         * self.noise.scale_tau_s)
            self._mat_nb0 = C
        self._series = TransitionSeries.build(F, Qc)
        self._poly = None  # navigation-block polynomial of P(tau), built on first use
        self._nav_block = None  # P9 at every step of the interval, for the one-step path

    def _full_covariance(self, j: int) -> np.ndarray:
        """P(tau = j dt) of the current interval (15, 15), symmetrised and guarded."""
        tau = np.array([j * self.dt])
        phi = self._series.phi(tau)[0]
        P = phi @ self._P0 @ phi.T + self._series.qd(tau)[0]  # P = F P F^T + Q
        return self._guard(0.5 * (P + P.T))

    def _guard(self, P: np.ndarray) -> np.ndarray:
        d = np.diag(P)
        if np.all(np.isfinite(P)) and np.all(d >= 0.0):
            return P
        self.diverged = True
        if not np.all(np.isfinite(P)):
            return np.diag(np.where(np.isfinite(d) & (d > 0), d, 1e6))
        w, v = np.linalg.eigh(P)
        return (v * np.maximum(w, 1e-12 * max(float(w.max()), 1e-300))) @ v.T

    @property
    def dynamics(self) -> np.ndarray:
        """F (15, 15) of the current covariance interval (frozen at its start)."""
        return self._series.F

    @property
    def covariance(self) -> np.ndarray:
        """The full 15 x 15 covariance at the last processed step."""
        if self._pending is not None:
            return self._pending
        return self._P0 if self._j == 0 else self._full_covariance(self._j)

    # -- propagation -------------------------------------------------------------------
    def prepare(self, dtheta_sub: Arr = None, dv_sub: Arr = None, dtheta_r: Arr = None,
                dv_r: Arr = None) -> BodyTerms | StepTerms:
        """Raw (uncompensated) body-frame strapdown terms of n steps, for :meth:`advance_body`.

        One step with multiple integrals gives :class:`StepTerms` when the resolved methods
        have a float form (:mod:`navsim.strapdown.onestep`): the same numbers at a
        fraction of the array forms' fixed cost.
        """
        if dtheta_r is not None and dv_r is not None and len(dtheta_r) == 1:
            return self.prepare_step(None if dtheta_sub is None else dtheta_sub[0],
                                     None if dv_sub is None else dv_sub[0], dtheta_r[0], dv_r[0])
        return body_terms(dtheta_sub, dv_sub, dtheta_r, dv_r, self.dt, **self.methods)

    def prepare_step(self, dtheta_sub: Arr, dv_sub: Arr, dtheta_r: np.ndarray, dv_r: np.ndarray
                     ) -> BodyTerms | StepTerms:
        """:meth:`prepare` of one step from its (m, 3) / (R, 3) arrays (a
        :class:`~navsim.estimators.base.Measurement`'s fields)."""
        key = (None if dtheta_sub is None else dtheta_sub.shape, None if dv_sub is None else dv_sub.shape,
               dtheta_r.shape, dv_r.shape)
        methods = self._resolved.get(key)
        if methods is None:
            arrays = [None if a is None else np.asarray(a)[None] for a in (dtheta_sub, dv_sub, dtheta_r, dv_r)]
            methods = self._resolved[key] = _ins.resolve_methods(self.methods["coning"], self.methods["sculling"],
                                                                 self.methods["position"], *arrays)
        terms = _one.one_step_terms(methods, dtheta_r.tolist(), dv_r.tolist(),
                                    None if dtheta_sub is None else dtheta_sub.tolist(),
                                    None if dv_sub is None else dv_sub.tolist(), self.dt)
        if terms is None:
            sub, dv_s = (None if a is None else np.asarray(a)[None] for a in (dtheta_sub, dv_sub))
            return body_terms(sub, dv_s, np.asarray(dtheta_r)[None], np.asarray(dv_r)[None], self.dt, **self.methods)
        return StepTerms(*terms[:3], None, *terms[3:], self.dt)

    def advance_step(self, dtheta_sub: Arr, dv_sub: Arr, dtheta_r: np.ndarray, dv_r: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        """``advance_body(prepare_step(...))`` of one step from a
        :class:`~navsim.estimators.base.Measurement`'s arrays: rows (1, 9), covariance (1, 9, 9)
        (:meth:`advance_row` with a leading step axis)."""
        row, cov = self.advance_row(dtheta_sub, dv_sub, dtheta_r, dv_r)
        return row[None], cov[None]

    def advance_row(self, dtheta_sub: Arr, dv_sub: Arr, dtheta_r: np.ndarray, dv_r: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
        """One navigation step from a :class:`~navsim.estimators.base.Measurement`'s arrays:
        the solution row (9,) and the navigation block (9, 9) of P at its end, both the
        caller's (fresh arrays).

        With numba and the methods of :data:`navsim.strapdown.onestep.ONE_STEP_METHODS`
        (the default with multiple integrals of order >= 4) the whole step (strapdown terms,
        bias removal, the INS step, the solution row, the specific-force sum and the copy
        of the covariance block) is one compiled call,
        :func:`navsim.strapdown.compiled.step_row` (around
        :func:`~navsim.strapdown.compiled.one_step`) on the engine's work array, which
        holds the constants, the biases, the state and the specific-force sum: the
        operations of the float path in the same order, so the same numbers. The first
        step of an input layout (the shapes of the four arrays) and every step of a layout
        without that form take the float path (:meth:`advance_body` of
        :meth:`prepare_step`).
        """
        kern = self._row_kernel
        if kern is not None:  # a layout was found fit: step_row checks that this step has it
            if self._pending is not None:
                self._start_interval(self._pending)
            w = self._w
            if not self._in_w:
                lat, lon, h, velocity, quat, compensation = self._floats()
                w[_compiled.W_STATE:_compiled.W_FSUM] = (lat, lon, h, *compensation, *velocity, *quat)
                self._in_w = True
            blocks = self._nav_block
            if blocks is None:
                blocks = self._nav_blocks()
            row = np.empty(9)
            cov = np.empty((9, 9))
            if dtheta_sub is not None and dv_sub is not None:
                status = kern(w, dtheta_r, dv_r, dtheta_sub, dv_sub, True, blocks, self._j, row, cov)
            elif dtheta_sub is None and dv_sub is None:
                status = kern(w, dtheta_r, dv_r, self._dummy, self._dummy, False, blocks, self._j, row, cov)
            else:
                status = 1
            if status != 1:
                # the state now lives in the work array: the floats and the InsState are built when read
                self._flat = None
                self._state = None
                if status == 2:  # position and velocity not finite (or a finite sum that overflowed)
                    self._floats()
                    self._in_w = False
                    self.state  # noqa: B018  (validates: the error of the array path)
                j = self._j = self._j + 1
                if j == self.interval_steps:
                    self._pending = self._full_covariance(j)
                self.steps += 1
                if self._after_hook:
                    self._after_steps(1)
                return row, cov
        key = (None if dtheta_sub is None else dtheta_sub.shape, None if dv_sub is None else dv_sub.shape,
               dtheta_r.shape, dv_r.shape)
        methods = self._resolved.get(key)
        if (methods is None or (dtheta_sub is None) != (dv_sub is None)
                or tuple(methods) not in _one.ONE_STEP_METHODS or key[2][0] < 4 or key[3][0] < 4
                or len(key[2]) != 2 or len(key[3]) != 2 or key[2][1] != 3 or key[3][1] != 3
                or (dtheta_sub is not None and dv_sub is not None and (dtheta_sub.ndim != 2 or dv_sub.ndim != 2))
                or not _compiled.available()):
            rows, cov = self.advance_body(self.prepare_step(dtheta_sub, dv_sub, dtheta_r, dv_r))
            return rows[0], cov[0]
        # the choice of path, made once per input layout: the compiled step from now on
        self._compiled_key = key
        _compiled.set_layout(self._w, key[2][0], key[3][0], None if key[0] is None else key[0][0],
                             None if key[1] is None else key[1][0])
        self._row_kernel = _compiled.row_kernel()
        return self.advance_row(dtheta_sub, dv_sub, dtheta_r, dv_r)

    def _after_steps(self, n: int) -> None:
        """Hook of subclasses whose own means follow the INS steps (called by the compiled
        one-step path; their ``advance_body`` calls it too)."""

    def advance(self, dtheta_sub: Arr = None, dv_sub: Arr = None, dtheta_r: Arr = None,
                dv_r: Arr = None) -> tuple[np.ndarray, np.ndarray]:
        """Process n navigation steps of IMU data (arrays as in :class:`MeasurementBatch`).

        Returns
        -------
        solution : ndarray (n, 9)
            ``[lat, lon, h, vE, vN, vU, heading, pitch, roll]`` at each step end.
        covariance : ndarray (n, 9, 9)
            Navigation block of P at each step end.
        """
        return self.advance_body(self.prepare(dtheta_sub, dv_sub, dtheta_r, dv_r))

    def advance_body(self, body: BodyTerms | StepTerms, start: int = 0,
                     stop: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`advance` over steps ``start:stop`` of precomputed :class:`BodyTerms`
        (compute them once per batch with :meth:`prepare`; the current bias estimates are
        applied here). A :class:`StepTerms` (one step) takes the float path of
        :meth:`_advance_step`, with the same operations."""
        if isinstance(body, StepTerms):
            if start != 0 or stop not in (None, 1):
                raise ConfigError("advance_body", "steps 0:1 of a one-step StepTerms", (start, stop))
            return self._advance_step(body)
        if self._pending is not None:
            self._start_interval(self._pending)
        quat_b, dv_b, ds_b, dv_first = body.compensated(self.gyro_bias, self.accel_bias, start, stop)
        # the loop, explicitly: keeps stepping and batch bit-for-bit equal (compiled when
        # numba is installed: the same loop bit for bit, navsim.strapdown.compiled)
        sol = _ins.integrate_body_terms(self.state, quat_b, dv_b, ds_b, body.rule, self.dt, self.earth,
                                        method="compiled" if _compiled.available() else "sequential")
        n = len(sol) - 1
        rows = solution_rows(sol.lat[1:], sol.lon[1:], sol.h[1:], sol.velocity_n[1:], sol.quat_nb[1:])
        # specific force in ENU per step, C(k+1) dV_k / dt (for F of the next interval)
        q = sol.quat_nb[1:]
        t2 = 2.0 * cross3(q[:, 1:], dv_first)  # C dv = dv + q0 t + q_v x t, t = 2 q_v x dv
        f_dv = dv_first + q[:, :1] * t2 + cross3(q[:, 1:], t2)
        cov = np.empty((n, 9, 9))
        i = 0
        while i < n:
            take = min(self.interval_steps - self._j, n - i)
            tau = (self._j + 1 + np.arange(take)) * self.dt
            if self._poly is None:
                self._poly = self._series.nav_polynomial(self._P0)
            powers = tau[:, None] ** np.arange(9)  # P9(tau) = sum_p tau^p coef_p
            cov[i:i + take] = (powers @ self._poly).reshape(take, 9, 9)
            self._f_sum = self._f_sum + f_dv[i:i + take].sum(axis=0)
            self._j += take
            i += take
            if self._j == self.interval_steps:
                # the interval ends: its end covariance starts the next one (state there);
                # at the end of the data the start waits for the next call (an update
                # may come first and restart the interval anyway)
                P_end = self._full_covariance(self._j)
                if i < n:
                    self.state = sol.state(i)
                    self._start_interval(P_end)
                else:
                    self._pending = P_end
        self.state = sol.final
        self.steps += n
        if not (math.isfinite(self.state.lat) and np.all(np.isfinite(self.state.velocity_n))):
            self.diverged = True
        return rows, cov

    def _advance_step(self, body: StepTerms) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`advance_body` of one step on Python floats: every operation of the array
        path for a batch of one, in the same order (so the same numbers), without its
        per-call array set-up; the :class:`InsState` is built only when read."""
        if self._pending is not None:
            self._start_interval(self._pending)
        quat_b, dv_b, ds_b, dv_first = body.compensated(self.gyro_bias.tolist(), self.accel_bias.tolist())
        lat, lon, h, velocity, quat, compensation = self._floats()
        pos, vel, quats, compensation = _ins.sequential_rows(
            lat, lon, h, velocity, quat, compensation, (quat_b,), (dv_b,), None if ds_b is None else (ds_b,),
            body.rule, self.dt, self.earth)
        (lat, lon, h), velocity, quat = pos[1], vel[1], quats[1]
        self._flat = (lat, lon, h, velocity, quat, compensation)
        self._state = None
        self._in_w = False
        ve, vn, vu = velocity
        if not (math.isfinite(lat) and math.isfinite(lon) and math.isfinite(h) and math.isfinite(ve)
                and math.isfinite(vn) and math.isfinite(vu)):
            self.state  # noqa: B018  (validates: the error of the array path)
        q0, q1, q2, q3 = quat
        c01 = 2.0 * (q1 * q2 - q0 * q3)
        c11 = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
        c20 = 2.0 * (q1 * q3 - q0 * q2)
        c21 = 2.0 * (q2 * q3 + q0 * q1)
        c22 = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
        rows = np.array([[lat, lon, h, ve, vn, vu, math.atan2(c01, c11), math.asin(min(max(c21, -1.0), 1.0)),
                          math.atan2(-c20, c22)]])
        # specific force in ENU, C(k+1) dV_k / dt (see advance_body)
        d0, d1, d2 = dv_first
        u0, u1, u2 = 2.0 * (q2 * d2 - q3 * d1), 2.0 * (q3 * d0 - q1 * d2), 2.0 * (q1 * d1 - q2 * d0)
        fs = self._f_sum
        self._f_sum = [fs[0] + (d0 + q0 * u0 + (q2 * u2 - q3 * u1)), fs[1] + (d1 + q0 * u1 + (q3 * u0 - q1 * u2)),
                       fs[2] + (d2 + q0 * u2 + (q1 * u1 - q2 * u0))]
        return rows, self._step_covariance()

    def _step_covariance(self) -> np.ndarray:
        """The navigation block (1, 9, 9) of P after one more step of the interval (one-step paths)."""
        return self._step_covariance_row()[None]

    def _nav_blocks(self) -> np.ndarray:
        """The navigation block of P at every step of the interval (interval_steps, 9, 9), made once."""
        # P9(tau) = (tau^p)_p @ coefficients at every step of the interval in one product,
        # as advance_body does for the steps of a batch
        if self._poly is None:
            self._poly = self._series.nav_polynomial(self._P0)
        tau = (1 + np.arange(self.interval_steps)) * self.dt
        self._nav_block = ((tau[:, None] ** np.arange(9)) @ self._poly).reshape(-1, 9, 9)
        return self._nav_block

    def _step_covariance_row(self) -> np.ndarray:
        """The navigation block (9, 9) of P after one more step of the interval (one-step paths)."""
        blocks = self._nav_block
        if blocks is None:
            blocks = self._nav_blocks()
        cov = blocks[self._j].copy()
        self._j += 1
        if self._j == self.interval_steps:
            self._pending = self._full_covariance(self._j)
        self.steps += 1
        return cov

    # -- measurement update --------------------------------------------------------------
    def _feed_back(self, dx: np.ndarray) -> None:
        """Closed-loop feedback of the 15 INS error states of dx (in place: the bias
        entries are zeroed when biases are not estimated)."""
        if not self.estimate_biases:
            dx[BG] = 0.0
            dx[BA] = 0.0
        self.state = correct_state(self.state, dx[NAV], self.earth)
        self.gyro_bias = self.gyro_bias + dx[BG]
        self.accel_bias = self.accel_bias + dx[BA]

    def update(self, H: np.ndarray, R: np.ndarray, innovation: np.ndarray) -> tuple[float, np.ndarray]:
        """Closed-loop Kalman update at the current step.

        Parameters
        ----------
        H : (m, 15). R : (m, m). innovation : (m,) measurement minus its prediction from
        the current (corrected) INS state, i.e. ``y = H x + v`` for the error state x.

        Returns
        -------
        nis : float
        dx : (15,) the estimated error that was fed back.

        The covariance interval restarts here with the updated covariance and the
        corrected state.
        """
        P = self.covariance
        try:
            dx, P_new, nis = self.kalman_update(P, H, R, innovation)
        except np.linalg.LinAlgError:
            self.diverged = True
            self._start_interval(P)
            return math.nan, np.zeros(N_STATES)
        if not np.all(np.isfinite(dx)):
            self.diverged = True
            self._start_interval(P)
            return math.nan, np.zeros(N_STATES)
        self._feed_back(dx)
        self._start_interval(self._guard(P_new))
        return nis, dx

    def current_row(self) -> np.ndarray:
        """The solution row (9,) of the current state."""
        st = self.state
        return solution_rows(np.array([st.lat]), np.array([st.lon]), np.array([st.h]),
                             st.velocity_n[None], st.quat_nb[None])[0]


def body_velocity_terms(mat_nb: ArrayLike, velocity_n: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame velocity ``v_b = C^T v_n`` and its partials over the error state.

    From ``C_est = (I + [psi x]) C`` and ``v_est = v + dv``::

        v_b(est) - v_b(true) = C^T dv + C^T [v_n x] psi                          (OD.6)

    (first order; ``-[psi x] v = [v x] psi``). Used by the wheel-odometer forward-speed
    update and the non-holonomic constraint (zero lateral and vertical body velocity of
    a vehicle on its wheels); tests/estimators/test_odometer_aiding.py checks it against
    finite differences through :func:`correct_state`.

    Returns
    -------
    velocity_b : (3,) m/s.  J : (3, 15) rows x (right), y (forward), z (up).
    """
    C = np.asarray(mat_nb, dtype=float)
    v = np.asarray(velocity_n, dtype=float)
    J = np.zeros((3, N_STATES))
    J[:, VEL] = C.T
    J[:, ATT] = C.T @ skew3(v)  # (OD.6)
    return C.T @ v, J


class AuxBlocksIns(ErrorStateIns):
    """:class:`ErrorStateIns` plus ``n_aux`` auxiliary error states that neither drive nor
    are driven by the INS errors (receiver clock, atmospheric delays, odometer scale
    factor, the slowly varying error of a GNSS fix).

    F and Qc are then block diagonal and over a covariance interval ``Phi = diag(Phi_15,
    Phi_a)``: the engine keeps propagating its 15 x 15 block untouched, and this class
    carries the auxiliary block and the cross-covariance from the interval start,
    ``P_na(tau) = Phi_15(tau) P_na Phi_a(tau)^T`` and ``P_aa(tau) = Phi_a P_aa Phi_a^T +
    Qd_a``, with the engine's own ``Phi_15`` (nothing of its series is duplicated). The
    full matrix is assembled at updates only. Subclasses give ``_aux_transition(tau) ->
    (Phi_a, Qd_a)`` (full n_aux-square matrices) and may carry their estimates over an
    interval in ``_carry_means``.
    """

    def _init_aux(self, variances: np.ndarray | list[float]) -> None:
        """Set up ``n_aux`` states with the given initial variances (before ``super().__init__``)."""
        self.n_aux = len(variances)
        self.n_states = N_STATES + self.n_aux
        self.P_na: np.ndarray = np.zeros((N_STATES, self.n_aux))
        self.P_aa: np.ndarray = np.diag(variances) if self.n_aux else np.zeros((0, 0))
        self._fresh = True  # the next interval start carries no auxiliary propagation

    def _aux_transition(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def _aux_blocks(self) -> tuple[np.ndarray, np.ndarray]:
        """P_na and P_aa at the current step of the interval."""
        tau = self._j * self.dt
        if tau == 0.0:
            return self.P_na, self.P_aa
        phi = self._series.phi(np.array([tau]))[0]
        phi_a, q_a = self._aux_transition(tau)
        return phi @ self.P_na @ phi_a.T, phi_a @ self.P_aa @ phi_a.T + q_a

    def _carry_means(self) -> None:
        """Carry the auxiliary estimates to the current step (default: they are constant)."""

    def _start_interval(self, P: np.ndarray) -> None:
        if self.n_aux and not self._fresh:
            # the engine restarts an interval on its own: carry the auxiliary blocks to here
            self._carry_means()
            self.P_na, self.P_aa = self._aux_blocks()
        self._fresh = False
        super()._start_interval(P)

    def _restart_after_update(self, P_new: np.ndarray) -> None:
        """Keep the updated auxiliary blocks and restart the interval from P_new."""
        self.P_na, self.P_aa = P_new[:N_STATES, N_STATES:].copy(), P_new[N_STATES:, N_STATES:].copy()
        self._fresh = True
        self._start_interval(P_new[:N_STATES, :N_STATES].copy())

    def full_covariance(self) -> np.ndarray:
        """The (15 + n_aux)-square covariance at the current step."""
        P = self.covariance
        if not self.n_aux:
            return P
        P_na, P_aa = self._aux_blocks()
        full = np.empty((self.n_states, self.n_states))
        full[:N_STATES, :N_STATES] = P
        full[:N_STATES, N_STATES:] = P_na
        full[N_STATES:, :N_STATES] = P_na.T
        full[N_STATES:, N_STATES:] = P_aa
        return full


class AuxStateIns(AuxBlocksIns):
    """:class:`ErrorStateIns` plus ``n_aux`` auxiliary error states (random walks or
    first-order Gauss-Markov processes).

    The auxiliary states (e.g. the wheel-odometer scale factor, the slowly varying error
    of a GNSS fix) are independent of each other; the interval bookkeeping is that of
    :class:`AuxBlocksIns`. Every :meth:`update` is made on the full state; a 15-column H
    is padded with zeros.

    Per auxiliary state i with correlation time ``T_i`` and driving PSD ``q_i``
    (``x_i' = -x_i / T_i + w_i``)::

        phi_i(tau) = exp(-tau / T_i),   Qd_i(tau) = q_i T_i / 2 (1 - exp(-2 tau / T_i))   (AX.1)

    (the exact discretisation; stationary variance ``q_i T_i / 2``, so ``q_i = 2 sigma_i^2
    / T_i``), and for ``T_i = inf`` (the default) the random walk ``phi_i = 1``, ``Qd_i =
    q_i tau``. The estimate of a Gauss-Markov state decays with the same ``phi_i``
    between updates (the conditional mean of the process; :meth:`aux_now`). Without
    ``aux_tau_s`` (or with every ``T_i`` infinite) the code is the random-walk engine of
    before, number for number.

    Parameters
    ----------
    aux_variance : (n_aux,) initial variances. aux_psd : (n_aux,) driving PSDs (per
    second). aux_tau_s : (n_aux,) correlation times, s (``inf``: random walk), or None
    (all random walks). Other parameters as :class:`ErrorStateIns`.

    Attributes
    ----------
    aux : ndarray (n_aux,)
        The estimates of the auxiliary quantities at the start of the current covariance
        interval (:meth:`aux_now` at the current step); the error state is ``aux - truth``
        and the feedback subtracts the estimated error.
    """

    def __init__(self, context: Context, prior: Prior, noise: ImuNoise, *, aux_variance: ArrayLike,
                 aux_psd: ArrayLike, aux_tau_s: ArrayLike | None = None, **kw: Any) -> None:
        var = np.asarray(aux_variance, dtype=float).reshape(-1)
        self.aux_psd = np.asarray(aux_psd, dtype=float).reshape(-1)
        if len(self.aux_psd) != len(var):
            raise ConfigError("aux_psd", f"{len(var)} driving PSDs", len(self.aux_psd))
        tau = np.full(len(var), math.inf) if aux_tau_s is None else np.asarray(aux_tau_s, dtype=float).reshape(-1)
        if len(tau) != len(var) or not np.all(tau > 0.0):
            raise ConfigError("aux_tau_s", f"{len(var)} positive correlation times, s (inf: random walk)",
                              aux_tau_s)
        self.aux_tau_s = tau
        self._markov = bool(np.any(np.isfinite(tau)))
        self.aux = np.zeros(len(var))
        self._init_aux(var)
        super().__init__(context, prior, noise, **kw)

    def _aux_decay(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """(phi_i, Qd_i) per auxiliary state over tau seconds (AX.1)."""
        T = self.aux_tau_s
        finite = np.isfinite(T)
        Tf = np.where(finite, T, 1.0)
        phi = np.where(finite, np.exp(-tau / Tf), 1.0)
        qd = np.where(finite, 0.5 * self.aux_psd * Tf * -np.expm1(-2.0 * tau / Tf), self.aux_psd * tau)
        return phi, qd

    def _aux_transition(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """Diagonal (Phi_a, Qd_a) over tau seconds (AX.1)."""
        phi, qd = self._aux_decay(tau)
        return np.diag(phi), np.diag(qd)

    def aux_now(self) -> np.ndarray:
        """The auxiliary estimates at the current step (Gauss-Markov ones decayed)."""
        if not self._markov or self._j == 0:
            return self.aux.copy()
        return self.aux * self._aux_decay(self._j * self.dt)[0]

    def _carry_means(self) -> None:
        if self._markov:
            self.aux = self.aux_now()

    def update(self, H: np.ndarray, R: np.ndarray, innovation: np.ndarray) -> tuple[float, np.ndarray]:
        """Closed-loop update on the full state (H (m, 15) or (m, 15 + n_aux))."""
        H = np.asarray(H, dtype=float)
        if H.shape[1] == N_STATES:
            H = np.concatenate([H, np.zeros((H.shape[0], self.n_aux))], axis=1)
        P = self.full_covariance()
        try:
            dx, P_new, nis = self.kalman_update(P, H, R, innovation)
        except np.linalg.LinAlgError:
            self.diverged = True
            return math.nan, np.zeros(self.n_states)
        if not np.all(np.isfinite(dx)):
            self.diverged = True
            return math.nan, np.zeros(self.n_states)
        self._feed_back(dx)
        self.aux = (self.aux_now() if self._markov else self.aux) - dx[N_STATES:]
        self._restart_after_update(self._guard(P_new))
        return nis, dx


def nis_threshold(dof: int, probability: float = 1e-6) -> float:
    """Chi-square quantile exceeded with ``probability`` (innovation-test helper)."""
    return float(chi2.isf(probability, dof))
