"""The covariance of seed 003's continuous filter (14): the Riccati equation, its layout, the gain.

Between GNSS epochs (14) is the Kalman-Bucy filter with correlated process and
measurement noise (W_a drives V_Y and is in Z_ax)::

    Y' = F(Y) + K (Z_ax - H_a(Y)),   K = (R h + s) / sigma^2,   h = dH_a/dY^T
    R' = A R + R A^T + Q - (R h + s)(R h + s)^T / sigma^2                    (14)

with ``A = dF/dY``, ``Q = F1 D_xi F1^T`` (D_d rad^2/s on the kinematics, D_a m^2/s^3 on
V_Y, the clock and bias PSDs), ``s = F1 D_A H_w^T`` (only its V_Y entry, ``D_a k / u_b,x``)
and ``sigma^2 = H_w D_a H_w^T = D_a (1 + k^2) / u_b,x^2``. Without the observer
(``observer=False``) ``h = 0, s = 0``: ``R' = A R + R A^T + Q`` and K = 0.

The right-hand side is written as the quadratic form ``R' = [R; I]^T H [R; I]`` with
``H = [[-g g^T, Abar^T], [Abar, Qbar]]``, ``g = h / sigma``, ``Abar = A - s h^T /
sigma^2``, ``Qbar = Q - s s^T / sigma^2`` (2n x 2n): the constant entries (clock,
Gauss-Markov time constants and PSDs) are written once at reset, the state-dependent ones
per covariance interval through one flat index array; RK4 with H frozen over the
interval (:func:`~navsim.estimators.paper_ekf.numerics.riccati_rk4_h`), the rate
``|dH_a/dY K|`` bounding the interval (option ``stiffness_limit``).
``_coefficients`` assembles the dense A, h, Q, s, sigma^2 from the same one-pass
coefficients and the layout's constants (for the checks: the direct form
:func:`~navsim.estimators.paper_ekf.numerics.riccati_rk4`, finite differences).

References: [003] eq. (14); [3] Brown R.G., Hwang P.Y.C., Introduction to Random Signals
and Applied Kalman Filtering, 4th ed., 2012, sec. 8.2.
"""

from __future__ import annotations

import operator
from typing import Any, Sequence

import numpy as np

from .mechanization import Mechanization
from .numerics import check_rows, riccati_rk4_h

__all__ = ["Covariance"]


class Covariance(Mechanization):
    """(14)'s Riccati equation as a quadratic form, the gain (a layer of :class:`PaperEkf`)."""

    _a_pos: list[tuple[int, int]]
    _h_sup: list[int]
    _h_all: bool
    _bar_fix: list[tuple[int, int]]
    _h_flat_idx: np.ndarray
    _H: np.ndarray
    _Z: np.ndarray
    _work: tuple[np.ndarray, ...]

    def _coefficients(self, Y: Sequence[float], w: Sequence[float] | np.ndarray, f: Sequence[float] | np.ndarray,
                      t: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, tuple[Any, ...]]:
        """The coefficients of (14) at (Y, inputs) as dense arrays, for the checks.

        Returns (A (n, n), hneg (n,), Q (n, n), s (n,), sig2, first): A = dF/dY, ``hneg`` =
        d(Z_ax - H_a)/dY, Q, the correlation s = F1 D_A H_w^T, sigma^2 = H_w D_a H_w^T and
        ``first`` the stage values (F, Z_ax - H_a) at (Y, inputs, t). Assembled from
        :meth:`_fused` (the one form of the equations) and the constant entries that
        :meth:`_riccati_layout` wrote into H (clock, bias time constants and PSDs).
        """
        n = self.n_states
        first, a_dyn, hneg, q_dyn, s4, sig2 = self._fused(Y, list(w), list(f), t)
        A = self._H[n:, :n].copy()
        for (i, j), x in zip(self._a_pos, a_dyn):
            A[i, j] = x
        Q = self._H[n:, n:].copy()
        for (i, j), x in zip([(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)], q_dyn):
            Q[i, j] = Q[j, i] = x
        Q[4, 4] = q_dyn[6]
        s = np.zeros(n)
        s[4] = s4
        return A, np.array(hneg), Q, s, sig2, first

    def _riccati_layout(self) -> None:
        """Index maps of the Hamiltonian-like matrix H of :func:`riccati_rk4_h` (set-up).

        ``H = [[-g g^T, Abar^T], [Abar, Qbar]]`` (2n x 2n) with ``g = h / sigma``, ``Abar = A -
        s h^T / sigma^2``, ``Qbar = Q - s s^T / sigma^2``: then ``[R; I]^T H [R; I]`` is the
        right-hand side ``A R + R A^T + Q - (R h + s)(R h + s)^T / sigma^2`` of (14)'s Riccati
        equation (s has only its V_Y entry). Constant entries (clock, bias time constants and
        PSDs) are written once; the state-dependent ones are written per coefficient update
        through one flat index array.
        """
        n = self.n_states
        kin_pos = ([(0, 1), (0, 2), (1, 2), (2, 1), (2, 2)] if self._printed_kin
                   else [(0, 2), (1, 0), (1, 2), (2, 0), (2, 2)])
        a_pos = kin_pos + [(3, 3), (3, 4), (4, 0), (4, 1), (4, 2), (4, 3), (4, 4)]
        h_sup = [0, 1, 2, 3, 4]
        H = np.zeros((2 * n, 2 * n))
        if self._biases:
            ia, ig = self._i_ba, self._i_bg
            for j in range(3):
                a_pos += [(0, ig + j), (1, ig + j), (2, ig + j)]
            a_pos += [(4, ia), (4, ia + 1), (4, ia + 2)]
            h_sup += [ia, ia + 1, ia + 2]
            imu = self.context.imu
            for j in range(3):
                for i, tau_s in ((ia + j, imu.accel_bias_tau_s), (ig + j, imu.gyro_bias_tau_s)):
                    H[n + i, i] = H[i, n + i] = -1.0 / tau_s
                H[n + ia + j, n + ia + j] = 2.0 * imu.accel_bias_sigma ** 2 / imu.accel_bias_tau_s + imu.accel_rrw ** 2
                H[n + ig + j, n + ig + j] = 2.0 * imu.gyro_bias_sigma ** 2 / imu.gyro_bias_tau_s + imu.gyro_rrw ** 2
        if self._clock:
            i = self._i_clk
            H[n + i, i + 1] = H[i + 1, n + i] = 1.0
            H[n + i, n + i] = self.context.gnss.clock_phase_psd
            H[n + i + 1, n + i + 1] = self.context.gnss.clock_freq_psd
        self._a_pos = a_pos
        self._h_sup = h_sup
        self._h_all = h_sup == list(range(n))
        # row-4 entries of A that become Abar (index in a_dyn, column)
        self._bar_fix = [(idx, j) for idx, (i, j) in enumerate(a_pos) if i == 4]
        flat = []
        flat += [i * 2 * n + j for i in h_sup for j in h_sup]  # -g g^T
        flat += [(n + i) * 2 * n + j for i, j in a_pos]  # Abar
        flat += [j * 2 * n + n + i for i, j in a_pos]  # Abar^T
        q_pos = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
        flat += [(n + i) * 2 * n + n + j for i, j in q_pos] + [(n + j) * 2 * n + n + i for i, j in q_pos if i != j]
        flat += [(n + 4) * 2 * n + n + 4]
        self._h_flat_idx = np.array(flat)
        self._H = H
        self._Z = np.zeros((2 * n, n))
        self._Z[n:] = np.eye(n)
        m = np.zeros((4, n, n))
        self._work = (self._Z, self._Z[:n], self._Z.T, np.zeros((2 * n, n)), m[0], m[1], m[2], m[3])

    def _h_matrix(self, a_dyn: list[float], hneg: list[float], q_dyn: list[float], s4: float, sig2: float) -> np.ndarray:
        """Fill H (see :meth:`_riccati_layout`) from the coefficients; returns the shared array.
        ``a_dyn`` is modified (it becomes Abar)."""
        inv = 1.0 / sig2
        hs = hneg if self._h_all else [hneg[j] for j in self._h_sup]
        nh = [-x * inv for x in hs]
        si = s4 * inv
        for idx, j in self._bar_fix:
            a_dyn[idx] += si * hneg[j]
        q0, q1, q2, q3, q4, q5, qvv = q_dyn
        self._H.put(self._h_flat_idx, [x * y for x in nh for y in hs] + a_dyn + a_dyn
                    + [q0, q1, q2, q3, q4, q5, q1, q2, q4, qvv - s4 * si])
        return self._H

    def _gain(self, hneg: list[float], s4: float, sig2: float) -> tuple[list[float], float]:
        """K = (R h + s) / sigma^2 (14) from the cached rows of R, and the rate |dH_a/dY K|."""
        inv = 1.0 / sig2
        mul = operator.mul
        dots = [sum(map(mul, r, hneg)) for r in self._P_rows]
        dots[4] -= s4
        K = [-d * inv for d in dots]
        return K, abs(sum(map(mul, hneg, K)))

    def _riccati(self, P: np.ndarray, H: np.ndarray, tau: float) -> tuple[np.ndarray, list[list[float]]]:
        """RK4 of (14)'s Riccati equation with H frozen (:func:`riccati_rk4_h`), checked."""
        P = riccati_rk4_h(P, H, tau, self._work)
        rows = P.tolist()
        check_rows(rows)
        return P, rows

    def _cov_coefficients(self, w: Sequence[float], f: Sequence[float], t: float
                          ) -> tuple[tuple[Any, ...], np.ndarray, list[float], float]:
        """Coefficients at the current state for a covariance interval: (first stage
        values, hneg, H filled, gain K (list), rate |dH_a/dY K|)."""
        first, a_dyn, hneg, q_dyn, s4, sig2 = self._fused(self._Y, w, f, t)
        if not self._observer:  # no (13): h = 0, S = 0 -> H = [[0, A^T], [A, Q]], K = 0
            hneg = [0.0] * len(hneg)
            s4 = 0.0
        H = self._h_matrix(a_dyn, hneg, q_dyn, s4, sig2)
        K, rate = self._gain(hneg, s4, sig2)
        return first, H, K, rate
