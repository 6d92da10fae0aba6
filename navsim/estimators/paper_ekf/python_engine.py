"""The reference propagation engine of seed 003's filter: (14) step by step in plain Python and NumPy.

Per navigation step dt (s), from the step's r-fold integrals dtheta_r (rad s^(r-1)), dv_r
(m s^(r-2)):

* Inputs: omega(s), f(s) at s = 0, 1/2, 1 of the step (option ``input_model``: the
  polynomial of degree R-1 whose r-fold integrals are the increments, seed 000 eq. (1.14),
  or the step means dtheta_1/dt, dv_1/dt), and the step-mean f for (16).
* At the start of each covariance interval (``cov_step_s``, at most up to the next epoch):
  the coefficients of (14) at the current state, the gain ``K = (R h + s) / sigma^2`` and
  one RK4 step of the Riccati equation over the interval (H frozen); the interval is
  shortened where ``rate x interval > stiffness_limit`` (rate = ``|dH_a/dY K|``), and a step
  whose ``rate x dt`` exceeds the limit is split into adaptive sub-steps of
  ``stiffness_limit / rate`` (start-up stiffness), each with fresh coefficients and gain.
* RK4 of the state equation ``Y' = F(Y) + K (Z_ax - H_a(Y))`` over the step with the gain
  held; the clock (``b' = d``) and Gauss-Markov bias states (``x' = -x / tau``) by their
  exact transitions plus the gain times the integrated innovation.
* At a GNSS epoch the update (16); the output covariance of a step inside an interval is
  interpolated linearly between the interval's ends.

A step that fails (non-finite values, a negative variance, a singular update) marks the
filter diverged; its outputs and all later ones are NaN. ``_reference_step`` is the one
form of a step: the engine's batch loop and the compiled engine's hand-backs
(:mod:`~navsim.estimators.paper_ekf.compiled_engine`) both call it.

References: [003] eq. (14); seed 000 (Litmanovich 2002) eq. (1.14).
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from .outputs import Outputs

__all__ = ["PythonEngine"]


class PythonEngine(Outputs):
    """The reference engine: inputs, the step of (14), sub-steps, the batch loop (a layer of :class:`PaperEkf`)."""

    def _run(self, t_end: np.ndarray, inp: np.ndarray, dtheta_r: np.ndarray, dv_r: np.ndarray, epochs: dict[int, Any],
             steps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The reference engine over a batch: :meth:`_reference_step` for each step.

        Returns the states (n, ns), covariances (n, ns, ns), NIS (n,) and their degrees of
        freedom (n,); NaN from a failed step on (the filter is then diverged)."""
        n = len(t_end)
        ns = self.n_states
        out_y = np.full((n, ns), np.nan)
        out_p = np.full((n, ns, ns), np.nan)
        nis = np.full(n, np.nan)
        dof = np.zeros(n, dtype=int)
        rows = np.asarray(inp, dtype=float).tolist()
        times = np.asarray(t_end, dtype=float).tolist()
        step_list = np.asarray(steps).tolist()
        reference_step = self._reference_step
        for i in range(n):
            if self._diverged:
                break
            reference_step(i, rows[i], times[i], step_list[i], dtheta_r, dv_r, epochs.get(i), True, out_y, out_p,
                           nis, dof)
        return out_y, out_p, nis, dof

    def _prepare(self, dtheta_r: np.ndarray, dv_r: np.ndarray) -> np.ndarray:
        """Stage inputs (n, 21): omega and f at s = 0, 1/2, 1 and the step-mean f."""
        dtheta_r = np.asarray(dtheta_r, dtype=float)
        dv_r = np.asarray(dv_r, dtype=float)
        R = self._minv.shape[0]
        cols = []
        scaled_w = [dtheta_r[:, r, :] / self._dt_pow[r] for r in range(R)]
        scaled_f = [dv_r[:, r, :] / self._dt_pow[r] for r in range(R)]
        for s in range(3):
            for scaled in (scaled_w, scaled_f):
                acc = self._lvec[s, 0] * scaled[0]
                for r in range(1, R):
                    acc = acc + self._lvec[s, r] * scaled[r]
                cols.append(acc)
        cols.append(scaled_f[0])
        # order: w0 f0 w1 f1 w2 f2 fmean -> (n, 21)
        return np.concatenate(cols, axis=1)

    def _coef(self, dtheta_r: np.ndarray, dv_r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Polynomial coefficients (R, 3) of omega(s) and f(s) of one step (sub-steps)."""
        R = self._minv.shape[0]
        sw = np.array([dtheta_r[r] / self._dt_pow[r] for r in range(R)])
        sf = np.array([dv_r[r] / self._dt_pow[r] for r in range(R)])
        return self._minv @ sw, self._minv @ sf

    def _reference_step(self, i: int, row: list[float], t: float, step: int, dtheta_r: np.ndarray, dv_r: np.ndarray,
                        obs: Any, propagate: bool, out_y: np.ndarray, out_p: np.ndarray, nis: np.ndarray,
                        dof: np.ndarray) -> None:
        """One step of :meth:`_run`'s loop (propagation unless done, epoch update, outputs)."""
        try:
            if propagate:
                self._one_step(row, t, step, dtheta_r, dv_r, i)
            if obs is not None:
                self._cov_left = 0
                res = self._epoch_update(obs, row[18:21], t, dtheta_r[i][0] / self._dt if self._lever else None)
                if res is not None:
                    nis[i], dof[i] = res
            y = self._Y
            if not math.isfinite(sum(y)):
                raise FloatingPointError("non-finite state")
            out_y[i] = y
            if self._cov_left > 0 and self._cov_len > 1:
                p0 = self._P_start
                out_p[i] = p0 + (self._cov_pos / self._cov_len) * (self._P - p0)
            else:
                out_p[i] = self._P
        except (ArithmeticError, ValueError, np.linalg.LinAlgError):
            self._diverged = True
            out_y[i] = np.nan
            out_p[i] = np.nan

    def _one_step(self, row: list[float], t1: float, step: int, dtheta_r: np.ndarray, dv_r: np.ndarray, i: int) -> None:
        dt = self._dt
        t0 = t1 - dt
        if self._cov_left <= 0:
            limit = self.config.stiffness_limit
            coeffs = self._cov_coefficients(row[0:3], row[3:6], t0)
            first, H, K, rate = coeffs
            to_epoch = self._spe - (step % self._spe)
            L = min(self._n_c, to_epoch)
            if rate * dt > limit:
                self._substeps(t0, dtheta_r[i], dv_r[i], coeffs)
                self._cov_left = 0
                self._cov_len = 1
                return
            if rate * L * dt > limit:
                L = max(1, int(limit / (rate * dt)))
            self._P_start = self._P
            self._P, self._P_rows = self._riccati(self._P, H, L * dt)
            self._K = K
            self._cov_left = L
            self._cov_len = L
            self._cov_pos = 0
        else:
            first = None
        self._state_rk4(row, t0, dt, first)
        self._cov_left -= 1
        self._cov_pos += 1

    def _substeps(self, t0: float, dtheta_r: np.ndarray, dv_r: np.ndarray, coeffs: tuple[Any, ...] | None) -> None:
        """Adaptive sub-steps inside one navigation step (start-up stiffness)."""
        dt = self._dt
        limit = self.config.stiffness_limit
        cw, cf = self._coef(dtheta_r, dv_r)
        R = cw.shape[0]

        def at(c: np.ndarray, s: float) -> list[float]:
            powers = np.array([s ** j for j in range(R)])
            return (powers @ c).tolist()

        s_done = 0.0
        while s_done < 1.0 - 1e-12:
            if coeffs is None:
                coeffs = self._cov_coefficients(at(cw, s_done), at(cf, s_done), t0 + s_done * dt)
            first, H, K, rate = coeffs
            coeffs = None
            tau = min((1.0 - s_done) * dt, limit / max(rate, 1e-300))
            s_mid = s_done + 0.5 * tau / dt
            s_end = s_done + tau / dt
            row = at(cw, s_done) + at(cf, s_done) + at(cw, s_mid) + at(cf, s_mid) + at(cw, s_end) + at(cf, s_end)
            self._P, self._P_rows = self._riccati(self._P, H, tau)
            self._K = K
            self._state_rk4(row, t0 + s_done * dt, tau, first)
            s_done = s_end
            self.substeps += 1

    def _state_rk4(self, row: Sequence[float], t0: float, tau: float, first: tuple[Any, ...] | None = None) -> None:
        """RK4 of (14) over tau with the gain K held: Y' = F(Y) + K (Z_ax - H_a(Y))."""
        Y = self._Y
        K = self._K
        stage = self._stage
        a, b, g, phi, V = Y[0], Y[1], Y[2], Y[3], Y[4]
        w1x, w1y, w1z, f1x, f1y, f1z, w2x, w2y, w2z, f2x, f2y, f2z, w3x, w3y, w3z, f3x, f3y, f3z = row[:18]
        if self._biases:
            ia, ig = self._i_ba, self._i_bg
            bax, bay, baz, bgx, bgy, bgz = Y[ia], Y[ia + 1], Y[ia + 2], Y[ig], Y[ig + 1], Y[ig + 2]
            w1x, w1y, w1z, w2x, w2y, w2z, w3x, w3y, w3z = (
                w1x - bgx, w1y - bgy, w1z - bgz, w2x - bgx, w2y - bgy, w2z - bgz, w3x - bgx, w3y - bgy, w3z - bgz)
            f1x, f1y, f1z, f2x, f2y, f2z, f3x, f3y, f3z = (
                f1x - bax, f1y - bay, f1z - baz, f2x - bax, f2y - bay, f2z - baz, f3x - bax, f3y - bay, f3z - baz)
        k0, k1, k2, k3, k4 = K[0], K[1], K[2], K[3], K[4]
        h2 = 0.5 * tau
        tm = t0 + h2
        te = t0 + tau
        d1 = stage(a, b, g, phi, V, t0, w1x, w1y, w1z, f1x, f1y, f1z) if first is None else first
        i1 = d1[5]
        d2 = stage(a + h2 * (d1[0] + k0 * i1), b + h2 * (d1[1] + k1 * i1), g + h2 * (d1[2] + k2 * i1),
                   phi + h2 * (d1[3] + k3 * i1), V + h2 * (d1[4] + k4 * i1), tm, w2x, w2y, w2z, f2x, f2y, f2z)
        i2 = d2[5]
        d3 = stage(a + h2 * (d2[0] + k0 * i2), b + h2 * (d2[1] + k1 * i2), g + h2 * (d2[2] + k2 * i2),
                   phi + h2 * (d2[3] + k3 * i2), V + h2 * (d2[4] + k4 * i2), tm, w2x, w2y, w2z, f2x, f2y, f2z)
        i3 = d3[5]
        d4 = stage(a + tau * (d3[0] + k0 * i3), b + tau * (d3[1] + k1 * i3), g + tau * (d3[2] + k2 * i3),
                   phi + tau * (d3[3] + k3 * i3), V + tau * (d3[4] + k4 * i3), te, w3x, w3y, w3z, f3x, f3y, f3z)
        i4 = d4[5]
        c = tau / 6.0
        ibar = c * (i1 + 2.0 * (i2 + i3) + i4)
        Y[0] = a + c * (d1[0] + 2.0 * (d2[0] + d3[0]) + d4[0]) + k0 * ibar
        Y[1] = b + c * (d1[1] + 2.0 * (d2[1] + d3[1]) + d4[1]) + k1 * ibar
        Y[2] = g + c * (d1[2] + 2.0 * (d2[2] + d3[2]) + d4[2]) + k2 * ibar
        Y[3] = phi + c * (d1[3] + 2.0 * (d2[3] + d3[3]) + d4[3]) + k3 * ibar
        Y[4] = V + c * (d1[4] + 2.0 * (d2[4] + d3[4]) + d4[4]) + k4 * ibar
        if self.n_states > 5:  # linear extra states: exact transition + gain x integrated innovation
            if self._clock:
                i = self._i_clk
                Y[i] = Y[i] + tau * Y[i + 1] + K[i] * ibar
                Y[i + 1] = Y[i + 1] + K[i + 1] * ibar
            if self._biases:
                imu = self.context.imu
                fa = math.exp(-tau / imu.accel_bias_tau_s)
                fg = math.exp(-tau / imu.gyro_bias_tau_s)
                for j in range(3):
                    Y[ia + j] = fa * Y[ia + j] + K[ia + j] * ibar
                    Y[ig + j] = fg * Y[ig + j] + K[ig + j] * ibar
