"""The glue between :class:`PaperEkf` and its compiled engine (:mod:`~navsim.estimators.paper_ekf.kernel`).

At reset the constants, the Riccati layout, the polynomial input weights, the work array
and the filter state are copied into the two buffers of :func:`kernel.pack
<navsim.estimators.paper_ekf.kernel.pack>` (one float64, one int64); the filter keeps
views of them, so the batch driver :func:`kernel.advance
<navsim.estimators.paper_ekf.kernel.advance>` and the step-wise :func:`kernel.step_packed
<navsim.estimators.paper_ekf.kernel.step_packed>` work on the same memory. The state lives
in the buffers while the compiled code runs and is handed to the reference engine's
attributes (``_k_release``) before any step the kernel hands back: start-up sub-steps,
failures and the epoch updates (16), which run
:meth:`~navsim.estimators.paper_ekf.python_engine.PythonEngine._reference_step`.

The step-wise paths: a step without an epoch is one call of the compiled
``step_packed`` (inputs, (14), outputs); a step ending at an epoch is the compiled
propagation then the reference update (16) and the compiled outputs, the numbers of a
one-step batch. The options are those of :mod:`navsim.estimators.paper_ekf.config`
(``engine``).

References: [003] eqs. (14), (16).
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from ..base import Estimate, Measurement, StepRow
from . import kernel as _kernel
from .kernel import STATUS_DONE
from .python_engine import PythonEngine

__all__ = ["CompiledEngine"]


class CompiledEngine(PythonEngine):
    """The compiled engine's buffers, hand-overs and step-wise paths (a layer of :class:`PaperEkf`)."""

    _kpack: tuple | None
    _noise_qd: float
    _noise_qa: float
    _kargs: tuple | None
    _kstate: tuple | None
    _kstep_one: Callable[..., int] | None
    _krow: tuple | None  # (compiled step_packed, fbuf, ibuf) while the state is in the buffers
    _kwork: np.ndarray
    last_states: np.ndarray
    last_state_cov: np.ndarray

    @property
    def engine(self) -> str:
        """The propagation engine in use after :meth:`reset`: "compiled" or "python"."""
        return "compiled" if getattr(self, "_kargs", None) is not None else "python"

    def _propagate(self, t_end: np.ndarray, inp: np.ndarray, dtheta_r: np.ndarray, dv_r: np.ndarray,
                   epochs: dict[int, Any], steps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        if self._kargs is None:
            return self._run(t_end, inp, dtheta_r, dv_r, epochs, steps)
        return self._run_compiled(t_end, inp, dtheta_r, dv_r, epochs, steps)

    def _kernel_args(self) -> tuple:
        """Constants of :func:`navsim.estimators.paper_ekf.kernel.advance_py` (set-up)."""
        k = _kernel
        imu = self.context.imu
        c = np.zeros(10)
        c[k.C_OM], c[k.C_A], c[k.C_E2], c[k.C_CENT] = self._omega, self._a, self._e2, self._cent
        c[k.C_QD], c[k.C_QA], c[k.C_DT], c[k.C_LIMIT] = self._qd, self._qa, self._dt, self.config.stiffness_limit
        if self._biases:
            c[k.C_TAU_A], c[k.C_TAU_G] = imu.accel_bias_tau_s, imu.gyro_bias_tau_s
        tf = self.track_functions
        ic = np.zeros(13, dtype=np.int64)
        ic[k.I_OBSERVER] = self._observer
        ic[k.I_SPHERE], ic[k.I_PRINTED], ic[k.I_BIASES], ic[k.I_CLOCK] = (
            self._sphere, self._printed_kin, self._biases, self._clock)
        ic[k.I_IA] = self._i_ba
        ic[k.I_IG] = self._i_bg
        ic[k.I_ICLK] = self._i_clk
        ic[k.I_SPE], ic[k.I_NC], ic[k.I_SINGLE], ic[k.I_ORDER], ic[k.I_HALL] = (
            self._spe, self._n_c, tf.single, tf.order, self._h_all)
        bar_idx = np.array([i for i, _ in self._bar_fix], dtype=np.int64)
        bar_col = np.array([j for _, j in self._bar_fix], dtype=np.int64)
        # every array of the engine is a view of two buffers (kernel.pack): the step-wise path
        # hands the compiled step_packed 9 arguments instead of step_core's 22
        fbuf, ibuf, views = _kernel.pack(
            c, ic, np.asarray(tf._breaks_arr, dtype=float), np.asarray(tf._lam_arr, dtype=float),
            np.asarray(tf._h_arr, dtype=float), self._H, self._h_flat_idx.astype(np.int64),
            np.array(self._h_sup, dtype=np.int64), bar_idx, bar_col, np.asarray(self._lvec, dtype=float),
            np.asarray(self._dt_pow, dtype=float), _kernel.work_size(self.n_states), self.n_states)
        self._H = views[5]  # the reference engine's H (_h_matrix) is the engine's, as before
        self._kwork = views[12]
        self._kpack = (fbuf, ibuf, views[13], views[14])
        return views[:10]

    # D_d and D_a may change after reset (set_noise_scale, navsim.estimators.base.NoiseScalable):
    # the compiled engine's copies in its constants follow every assignment
    @property
    def _qd(self) -> float:
        return self._noise_qd

    @_qd.setter
    def _qd(self, value: float) -> None:
        self._noise_qd = value
        kargs = getattr(self, "_kargs", None)
        if kargs is not None:
            kargs[0][_kernel.C_QD] = value

    @property
    def _qa(self) -> float:
        return self._noise_qa

    @_qa.setter
    def _qa(self, value: float) -> None:
        self._noise_qa = value
        kargs = getattr(self, "_kargs", None)
        if kargs is not None:
            kargs[0][_kernel.C_QA] = value

    def _k_arrays(self) -> tuple[np.ndarray, ...]:
        """The compiled engine's state: (flat [Y, K, P, P_start], cov counters, Y, K, P, P_start
        views), loaded from the reference engine's attributes when those hold the state."""
        st = self._kstate
        if st is None:
            ns = self.n_states
            pk = self._kpack
            flat = np.empty(2 * ns + 2 * ns * ns) if pk is None else pk[2]
            Y, K = flat[:ns], flat[ns:2 * ns]
            P = flat[2 * ns:2 * ns + ns * ns].reshape(ns, ns)
            P_start = flat[2 * ns + ns * ns:].reshape(ns, ns)
            Y[:] = self._Y
            K[:] = self._K
            P[:] = self._P
            P_start[:] = self._P_start
            cov = np.empty(3, dtype=np.int64) if pk is None else pk[3]
            cov[:] = (self._cov_left, self._cov_len, self._cov_pos)
            st = self._kstate = (flat, cov, Y, K, P, P_start)
            if pk is not None:  # what the step-wise paths call: fetched once per hand-over, not per step
                step = self._kstep_one
                if step is None:  # the compiled dispatcher itself (no wrapper call per step)
                    step = self._kstep_one = _kernel.step_packed_dispatcher()
                self._krow = (step, pk[0], pk[1])
        return st

    def _k_release(self) -> None:
        """Hand the state back to the reference engine's attributes (before its code runs)."""
        st = self._kstate
        if st is not None:
            _, cov, Y, K, P, P_start = st
            self._Y = Y.tolist()
            self._K = K.tolist()
            self._P = P.copy()
            self._P_rows = self._P.tolist()
            self._P_start = P_start.copy()
            self._cov_left, self._cov_len, self._cov_pos = (int(x) for x in cov)
            self._kstate = None
            self._krow = None

    def _run_compiled(self, t_end: np.ndarray, inp: np.ndarray, dtheta_r: np.ndarray, dv_r: np.ndarray,
                      epochs: dict[int, Any], steps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_run` with the runs of steps between epochs advanced by the compiled engine.

        The steps it hands back (start-up sub-steps, failures, epoch updates) are done here
        by the reference code; the filter state is passed both ways at each hand-over."""
        n = len(t_end)
        ns = self.n_states
        out_y = np.full((n, ns), np.nan)
        out_p = np.full((n, ns, ns), np.nan)
        nis = np.full(n, np.nan)
        dof = np.zeros(n, dtype=int)
        is_epoch = np.zeros(n, dtype=bool)
        is_epoch[list(epochs)] = True
        t_end = np.ascontiguousarray(t_end, dtype=float)
        inp = np.ascontiguousarray(inp, dtype=float)
        steps = np.ascontiguousarray(steps, dtype=np.int64)
        advance = _kernel.advance
        kargs = self._kargs
        assert kargs is not None  # the compiled engine is in use
        i = 0
        while i < n and not self._diverged:
            _, cov, Y, K, P, P_start = self._k_arrays()
            i, status = advance(i, inp, t_end, steps, is_epoch, Y, P, P_start, K, cov, *kargs, out_y, out_p,
                                self._kwork)
            if status == _kernel.STATUS_DONE:
                break
            self._k_release()
            self._reference_step(i, inp[i].tolist(), float(t_end[i]), int(steps[i]), dtheta_r, dv_r,
                                 epochs.get(i), status != _kernel.STATUS_EPOCH, out_y, out_p, nis, dof)
            i += 1
        return out_y, out_p, nis, dof

    def _outputs(self, y: np.ndarray, p: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`outputs`, by the compiled engine when it is in use (the same expressions)."""
        if self._kargs is None:
            return self.outputs(y, p, t)
        n = len(y)
        sol = np.empty((n, 9))
        cov = np.empty((n, 9, 9))
        c, ic, breaks, lam_c, h_c = self._kargs[:5]
        _kernel.outputs_compiled(np.ascontiguousarray(y), np.ascontiguousarray(p), np.ascontiguousarray(t, dtype=float),
                                 c, ic, breaks, lam_c, h_c, sol, cov)
        return sol, cov

    def _row_compiled(self, measurement: Measurement) -> tuple[np.ndarray, np.ndarray] | None:
        """The step-wise path of the compiled engine for a step without an epoch: (solution
        row (9,), covariance (9, 9)); None when the step needs the general path (sub-steps,
        a failure), the state then unchanged."""
        krow = self._krow
        if krow is None:  # the state into the packed buffers (views of kernel.pack)
            self._k_arrays()
            krow = self._krow
            assert krow is not None  # set by _k_arrays with the compiled engine's buffers
        step, fbuf, ibuf = krow
        sol = np.empty(9)
        cov9 = np.empty((9, 9))
        status = step(np.ascontiguousarray(measurement.dtheta_r, dtype=float),
                      np.ascontiguousarray(measurement.dv_r, dtype=float), float(measurement.t),
                      int(measurement.step), False, fbuf, ibuf, sol, cov9)
        if status != STATUS_DONE:
            return None
        return sol, cov9

    def _row_epoch(self, measurement: Measurement) -> StepRow | None:
        """The step-wise path of the compiled engine for a step that ends at a GNSS epoch: the
        propagation by the compiled :func:`~navsim.estimators.paper_ekf.kernel.step_core`, then
        the update (16) and the outputs by the code of :meth:`_run_compiled` for a one-step
        batch (:meth:`_reference_step`, :meth:`_outputs`), so the numbers of
        :meth:`_step_general`, without its array preparation and :class:`Estimate`. None when
        the step needs the general path (sub-steps, a failure), the state then unchanged."""
        krow = self._krow
        if krow is None:
            self._k_arrays()
            krow = self._krow
            assert krow is not None  # set by _k_arrays with the compiled engine's buffers
        step, fbuf, ibuf = krow
        dtheta_r = np.ascontiguousarray(measurement.dtheta_r, dtype=float)
        dv_r = np.ascontiguousarray(measurement.dv_r, dtype=float)
        t = float(measurement.t)
        status = step(dtheta_r, dv_r, t, int(measurement.step),
                      True, fbuf, ibuf, np.empty(9), np.empty((9, 9)))
        if status != _kernel.STATUS_EPOCH:
            return None
        ns = self.n_states
        o = _kernel.input_offset(ns)
        row = self._kwork[o:o + 21].tolist()
        self._k_release()
        out_y = np.full((1, ns), np.nan)
        out_p = np.full((1, ns, ns), np.nan)
        nis = np.full(1, np.nan)
        dof = np.zeros(1, dtype=int)
        self._reference_step(0, row, t, int(measurement.step), dtheta_r[None], dv_r[None], measurement.gnss, False,
                             out_y, out_p, nis, dof)
        sol, cov = self._outputs(out_y, out_p, np.array([t]))
        return (sol[0], cov[0], None if math.isnan(nis[0]) else float(nis[0]),
                None if dof[0] == 0 else int(dof[0]))

    def _step_compiled(self, measurement: Measurement) -> Estimate | None:
        """:meth:`_row_compiled` as an :class:`Estimate` (None: the general path)."""
        done = self._row_compiled(measurement)
        if done is None:
            return None
        sol, cov9 = done
        st = self._kstate
        assert st is not None  # the compiled step left the state in the buffers
        y = st[2].copy()
        extra = {"state": y, "state_cov": st[4].copy(), "diverged": False}
        if self.n_states > 5:
            extra.update(self._extra_states(y))
        lat, lon, h, _, _, _, heading, pitch, roll = sol.tolist()  # the floats of float(sol[i]), in one call
        return Estimate(t=float(measurement.t), lat=lat, lon=lon, h=h, velocity_n=sol[3:6], heading=heading,
                        pitch=pitch, roll=roll, covariance=cov9, nis=None, nis_dof=None, extra=extra)
