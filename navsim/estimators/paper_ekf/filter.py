"""The seed-003 estimator :class:`PaperEkf`: options, reset, and the estimator interface.

:class:`PaperEkf` is the reduced-state track-model filter of seed 003 (Sokolov &
Vdovichenko 2012): the state (8), the continuous filter (14) with the accelerometer
observer (13) between GNSS epochs, the discrete update (16) with the pseudoranges and
Dopplers (9) at the epochs. This module is its facade: the options
(:mod:`~navsim.estimators.paper_ekf.config`), :meth:`PaperEkf.reset` (the model's
constants from the context, the state from the prior), and ``step``, ``step_row``
(:class:`~navsim.estimators.base.RowStepping`) and ``step_batch``. The class is built from
one layer per part of the filter, each in its module:

* :mod:`~navsim.estimators.paper_ekf.state`: the constants, the state (8), the prior's projection;
* :mod:`~navsim.estimators.paper_ekf.mechanization`: (7)-(8) and the observer (13);
* :mod:`~navsim.estimators.paper_ekf.covariance`: the Riccati equation and the gain of (14);
* :mod:`~navsim.estimators.paper_ekf.gnss`: the measurement model (9) and the update (16);
* :mod:`~navsim.estimators.paper_ekf.outputs`: the navigation solution and its covariance;
* :mod:`~navsim.estimators.paper_ekf.python_engine`: the reference engine (option ``engine="python"``);
* :mod:`~navsim.estimators.paper_ekf.compiled_engine`: the compiled engine's buffers and
  step-wise paths (:mod:`~navsim.estimators.paper_ekf.kernel`, ``engine="compiled"``).

The model, the corrections of the printed formulas, the modes and the numerical choices
are described in :mod:`navsim.estimators.paper_ekf`.

References: [003] Sokolov S.V., Vdovichenko S.S., Nauchnoe Priborostroenie 2012, eqs. (7)-(16).
"""

from __future__ import annotations

import cmath
import math
from typing import Iterable

import numpy as np

from ...earth import SPHERICAL, EarthModel
from ...errors import ConfigError
from ..base import Context, Estimate, EstimateBatch, Measurement, MeasurementBatch, NoiseScalable, Prior, StepRow, row_of
from . import kernel as _kernel
from .compiled_engine import CompiledEngine
from .config import PaperEkfConfig
from .kernel import STATUS_DONE
from .numerics import input_polynomial_matrix
from .state import paper_state
from .track_functions import TrackFunctions

__all__ = ["PaperEkf", "paper_state"]


class PaperEkf(CompiledEngine, NoiseScalable):
    """Seed 003's reduced-state track-model filter (14)/(16); see the module docstring.

    Parameters
    ----------
    mode : {"faithful", "extended"}
        faithful: the paper's model (spherical Earth, 5 states, no clock); extended: clock,
        WGS-84 and bias states where the context needs them.
    as_printed : bool or iterable of {"kinematics", "centrifugal"}
        faithful mode only: keep the printed kinematic matrix and/or centrifugal sign.
    cov_step_s : float, optional
        Riccati RK4 step (a divisor of the GNSS period), default the navigation step.
    input_model : {"polynomial", "mean"}, optional
        omega(t), f(t) inside a step from all multiple integrals, or dtheta/dt, dv/dt.
        Default: polynomial in faithful mode, mean in extended mode.
    accel_in_update : bool, optional
        Stack Z_ax into the epoch update (16). Default: faithful yes, extended no.
    bias_states : {"auto", "on", "off"}
        Gauss-Markov accelerometer and gyro bias states (extended mode; "auto": when the
        nominal IMU has bias sigmas).
    node_step_m : float
        Node spacing of the lambda(phi) interpolation of non-polynomial tracks, m.
    stiffness_limit : float
        Largest gain-rate x interval per RK4 step (start-up stiffness, see module).
    lever_arm : {"auto", "none"}
        "auto": compensate the antenna lever arm of ``context.gnss.lever_arm_b_m`` (a navsim
        extension, in both modes, active only when that arm is non-zero; see the module
        docstring); "none": predict the observables at the track point (003's eq. (2)).
    observer : bool
        True (default): the accelerometer observer (13) runs between epochs (14) and Z_ax
        is stacked into (16) as configured; False: the same track-model filter on GNSS
        alone (no (13): zero gain between epochs, ``R' = A R + R A^T + Q``), the ablation
        of the paper's central claim.
    engine : {"auto", "python", "compiled"}
        Propagation engine between GNSS epochs: "python" the reference (plain Python and
        NumPy), "compiled" :mod:`navsim.estimators.paper_ekf.kernel` (numba, optional extra
        ``fast``; the same equations, equal to rounding), "auto" the compiled one when
        numba is installed.

    Notes
    -----
    ``Estimate.extra`` holds ``state`` (the state vector), ``state_cov``, ``diverged``
    and, when present, ``clock_bias_m``, ``clock_drift_mps``, ``accel_bias``,
    ``gyro_bias``. After :meth:`step_batch`, ``last_states`` / ``last_state_cov`` hold
    the batch's state vectors (n, ns) and covariances (n, ns, ns).
    """

    NOISE_PROCESS = ("_qd", "_qa")
    NOISE_MEASUREMENT_VARIANCE = ("_r_code", "_r_dopp")
    step_row_fields = ("dtheta_r", "dv_r")  # the IMU fields step_row reads between epochs (navsim.envs.EstimatorAgent)
    # where set_noise_scale finds Q and R after reset (navsim.estimators.base.NoiseScalable)

    def __init__(self, mode: str = "faithful", as_printed: bool | Iterable[str] = False,
                 cov_step_s: float | None = None, input_model: str | None = None,
                 accel_in_update: bool | None = None, bias_states: str = "auto",
                 node_step_m: float = 10.0, stiffness_limit: float = 0.5, lever_arm: str = "auto",
                 observer: bool = True, engine: str = "auto") -> None:
        self.config = PaperEkfConfig(mode, as_printed,  # type: ignore[arg-type]  # __post_init__ makes the frozenset
                                     cov_step_s, input_model, accel_in_update,
                                     bias_states, node_step_m, stiffness_limit, lever_arm, observer, engine)
        self._ready = False
        self._krow = None  # set while the compiled engine holds the state (CompiledEngine._k_arrays)

    def reset(self, context: Context, prior: Prior) -> None:
        """Start an episode: model constants from the context, state from the prior."""
        cfg = self.config
        self.context = context
        earth: EarthModel = context.earth
        faithful = cfg.mode == "faithful"
        # --- Earth used by the filter
        if faithful or earth.f == 0.0:
            sph = earth if earth.f == 0.0 else SPHERICAL
            self._sphere, self._a, self._e2 = True, float(sph.a), 0.0
            self._omega = float(sph.rate)
        else:
            self._sphere, self._a, self._e2 = False, float(earth.a), float(earth.e2)
            self._omega = float(earth.rate)
        self._filter_earth = EarthModel("filter", self._a, 0.0 if self._sphere else earth.f, self._omega, earth.gm)
        printed = cfg.as_printed
        self._printed_kin = "kinematics" in printed
        # (7): printed +Omega^2 (r+h) cos sin; physics (plumb line) -; WGS-84 normal gravity: 0
        self._cent = (1.0 if "centrifugal" in printed else -1.0) if self._sphere else 0.0
        self.track_functions = TrackFunctions(context.track, cfg.node_step_m)
        # --- noise
        imu, gnss = context.imu, context.gnss
        self._qd = float(imu.gyro_arw) ** 2  # D_d, rad^2/s
        self._qa = float(imu.accel_vrw) ** 2  # D_a, m^2/s^3
        if self._qa <= 0.0:
            self._qa = (1e-6) ** 2  # an ideal accelerometer would make (14) singular
        self._r_code = max(float(gnss.pseudorange_sigma_m), 1e-3) ** 2
        self._r_dopp = max(float(gnss.doppler_sigma_mps), 1e-4) ** 2
        # --- antenna lever arm (navsim extension; zero arm: the paper's track-point model)
        arm = getattr(gnss, "lever_arm_b_m", (0.0, 0.0, 0.0)) if cfg.lever_arm == "auto" else (0.0, 0.0, 0.0)
        self.lever_arm_b = np.array(arm, dtype=float)
        self._lever = bool(np.any(self.lever_arm_b != 0.0))
        # --- extra states
        self._clock = (not faithful) and bool(gnss.clock_modelled)
        if faithful or cfg.bias_states == "off":
            biases = False
        elif cfg.bias_states == "on":
            biases = True
        else:
            biases = imu.accel_bias_sigma > 0.0 or imu.gyro_bias_sigma > 0.0
        self._biases = biases
        self._accel_in_update = faithful if cfg.accel_in_update is None else bool(cfg.accel_in_update)
        self._observer = bool(cfg.observer)
        if not self._observer:  # no (13): Z_ax is not an observation anywhere
            self._accel_in_update = False
        n = 5
        self._i_clk = n if self._clock else -1
        n += 2 if self._clock else 0
        self._i_ba = n if biases else -1
        n += 3 if biases else 0
        self._i_bg = n if biases else -1
        n += 3 if biases else 0
        self.n_states = n
        # --- time base
        dt = float(context.nav_period_s)
        self._dt = dt
        spe = context.gnss_period_s / dt
        self._spe = max(int(round(spe)), 1)
        cov_step = dt if cfg.cov_step_s is None else float(cfg.cov_step_s)
        n_c = cov_step / dt
        if abs(n_c - round(n_c)) > 1e-9 or round(n_c) < 1 or self._spe % int(round(n_c)) != 0:
            raise ConfigError("cov_step_s", f"a whole multiple of the navigation step {dt} s dividing the GNSS "
                              f"period {context.gnss_period_s} s", cfg.cov_step_s)
        self._n_c = int(round(n_c))
        R = int(context.orders)
        input_model = cfg.input_model or ("polynomial" if faithful else "mean")
        if input_model == "mean" or R == 1:
            minv = np.zeros((R, R))
            minv[0, 0] = 1.0
        else:
            minv = input_polynomial_matrix(R)
        self._minv = minv
        s_pts = np.array([0.0, 0.5, 1.0])
        self._lvec = (s_pts[:, None] ** np.arange(R)[None, :]) @ minv  # (3, R)
        self._dt_pow = np.array([dt ** (r + 1) for r in range(R)])
        # --- stage functions
        scalars = self.track_functions.scalar_function()
        self._stage = self._make_stage(math.sin, math.cos, math.sqrt, scalars)
        self._stage_c = self._make_stage(cmath.sin, cmath.cos, cmath.sqrt, scalars)
        self._fused = self._make_fused()
        self._riccati_layout()
        self._kpack: tuple | None = None  # the compiled engine's packed buffers (kernel.pack), made by _kernel_args
        self._kargs = self._kernel_args() if cfg.engine != "python" and _kernel.available() else None
        self._kstate = None  # the compiled engine's state arrays while they hold the state
        self._kstep_one = None  # kernel.step_packed's compiled dispatcher, fetched on first use
        self._krow = None
        # --- initial state
        y0, p0 = self._state_from_prior(prior)
        self._Y = y0
        self._P = p0
        self._P_rows = p0.tolist()
        self._K = [0.0] * n
        self._cov_left = 0
        self._P_start = p0.copy()
        self._cov_len = 1
        self._cov_pos = 0
        self._diverged = False
        self._t_prev = float(prior.t)
        self.substeps = 0
        self._ready = True

    def _require(self) -> None:
        if not self._ready:
            raise RuntimeError("call PaperEkf.reset(context, prior) first")

    def step(self, measurement: Measurement) -> Estimate:
        """One navigation step: (14) over the step, (16) if an epoch ends it."""
        self._require()
        if self._kargs is not None and measurement.gnss is None and not self._diverged:
            est = self._step_compiled(measurement)
            if est is not None:
                return est
        return self._step_general(measurement)

    def step_row(self, measurement: Measurement) -> StepRow:
        """:meth:`step` as ``(row (9,), covariance (9, 9), nis, nis_dof)`` (the
        :class:`~navsim.estimators.base.RowStepping` protocol): the same numbers; a step of
        the compiled path builds no :class:`Estimate` and no ``extra``.

        A step without an epoch while the compiled engine holds the state is one call of the
        compiled :func:`~navsim.estimators.paper_ekf.kernel.step_packed` on the buffers made
        at the hand-over (``_krow``); a step it hands back (sub-steps, a failure; the state
        then unchanged) and every other step take the general paths."""
        krow = self._krow
        if krow is not None and measurement.gnss is None:
            step, fbuf, ibuf = krow
            sol = np.empty(9)
            cov9 = np.empty((9, 9))
            if step(np.ascontiguousarray(measurement.dtheta_r, dtype=float),
                    np.ascontiguousarray(measurement.dv_r, dtype=float), float(measurement.t), int(measurement.step),
                    False, fbuf, ibuf, sol, cov9) == STATUS_DONE:
                return sol, cov9, None, None
            return row_of(self._step_general(measurement))
        self._require()
        if self._kargs is not None and not self._diverged:
            if measurement.gnss is None:
                done = self._row_compiled(measurement)
                if done is not None:
                    return done[0], done[1], None, None
            else:
                at_epoch = self._row_epoch(measurement)
                if at_epoch is not None:
                    return at_epoch
        return row_of(self._step_general(measurement))

    def _step_general(self, measurement: Measurement) -> Estimate:
        """:meth:`step` by (14) and (16) on arrays (every step the compiled path does not take)."""
        inp = self._prepare(measurement.dtheta_r[None], measurement.dv_r[None])
        epochs = {} if measurement.gnss is None else {0: measurement.gnss}
        t = np.array([measurement.t])
        y, p, nis, dof = self._propagate(t, inp, measurement.dtheta_r[None], measurement.dv_r[None], epochs,
                                         np.array([measurement.step]))
        sol, cov = self._outputs(y, p, t)
        extra = {"state": y[0].copy(), "state_cov": p[0].copy(), "diverged": self._diverged}
        extra.update(self._extra_states(y[0]))
        s = sol[0]
        return Estimate(t=float(measurement.t), lat=float(s[0]), lon=float(s[1]), h=float(s[2]),
                        velocity_n=s[3:6].copy(), heading=float(s[6]), pitch=float(s[7]), roll=float(s[8]),
                        covariance=cov[0], nis=None if math.isnan(nis[0]) else float(nis[0]),
                        nis_dof=None if dof[0] == 0 else int(dof[0]), extra=extra)

    def step_batch(self, batch: MeasurementBatch) -> EstimateBatch:
        """Many steps at once; the same numbers as repeated :meth:`step`."""
        self._require()
        inp = self._prepare(batch.dtheta_r, batch.dv_r)
        epochs = {int(j): obs for j, obs in batch.gnss}
        t = np.asarray(batch.t, dtype=float)
        y, p, nis, dof = self._propagate(t, inp, batch.dtheta_r, batch.dv_r, epochs, np.asarray(batch.step))
        sol, cov = self._outputs(y, p, t)
        self.last_states, self.last_state_cov = y, p
        return EstimateBatch(solution=sol, covariance=cov, nis=nis, nis_dof=dof)

    @property
    def diverged(self) -> bool:
        return self._diverged
