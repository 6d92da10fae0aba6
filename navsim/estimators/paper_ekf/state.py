"""The state of seed 003's filter: the reduced vector (8), the model's constants, the prior's projection.

The filter state is ``Y = [alpha, beta, gamma, phi, V_Y]`` (003, eq. (8)): the
Euler-Krylov angles of the body relative to the inertial frame (Appendix 1, rad), the
latitude phi (rad) and the north velocity V_Y (m/s), extended in ``mode="extended"`` by
the receiver clock bias and drift (m, m/s) and the accelerometer and gyro bias states
(m/s^2, rad/s). On the known track the other position and velocity components follow::

    lambda = lambda(phi), h = h(phi),   V_X = k V_Y,  V_Z = m V_Y,
    k = lambda'(phi) cos(phi) (R_E + h) / (R_N + h),   m = h'(phi) / (R_N + h)

(003 after (6); R_N = R_E = r on the sphere of faithful mode, the WGS-84 radii of
curvature otherwise).

* :func:`paper_state`: the state (8) of a navigation solution (truth or estimate, for the
  five-state NEES), ``D = mat_nb^T B(phi, lambda + Omega t)`` with ``B = D(-phi, lambda +
  Omega t, 0)`` (Appendix 1).
* :class:`StateModel`: the bottom layer of :class:`~navsim.estimators.paper_ekf.PaperEkf`:
  the attributes that :meth:`PaperEkf.reset <navsim.estimators.paper_ekf.PaperEkf.reset>`
  sets (Earth, track, noise, state layout, time base), the radii and the kinematic matrix
  ``Phi(alpha, gamma)`` (or the printed ``Phi(beta, gamma)``, option ``as_printed``), and
  the projection of the 9 x 9 prior (ENU position, velocity, attitude) on the state:
  Gauss-Newton on the track for phi, weighted least squares along ``[k, 1, m]`` for V_Y,
  the attitude Jacobian for the angles.

References: [003] Sokolov S.V., Vdovichenko S.S., Nauchnoe Priborostroenie 2012, eqs.
(6), (8), Appendix 1; the model and its corrections in :mod:`navsim.estimators.paper_ekf`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ...earth import EarthModel
from ...rotations import euler_krylov_from_matrix, euler_krylov_matrix, mat_nb_from_hpr
from ..base import Context, Prior
from .config import PaperEkfConfig
from .track_functions import TrackFunctions

__all__ = ["StateModel", "paper_state"]


def paper_state(lat: ArrayLike, lon: ArrayLike, velocity_n: ArrayLike, heading: float | np.ndarray,
                pitch: float | np.ndarray, roll: float | np.ndarray, t: ArrayLike, earth_rate: float) -> np.ndarray:
    """The paper's state [alpha, beta, gamma, phi, V_Y] of a navigation solution, (n, 5).

    alpha, beta, gamma from ``D = mat_nb^T B(lat, lon + Omega t)`` (body relative to the
    inertial frame, paper axes); phi = lat; V_Y = north velocity. Vectorised (truth or
    estimates; used for the 5-state NEES).
    """
    lat = np.atleast_1d(np.asarray(lat, dtype=float))
    lon = np.atleast_1d(np.asarray(lon, dtype=float))
    t = np.broadcast_to(np.asarray(t, dtype=float), lat.shape)
    velocity_n = np.asarray(velocity_n, dtype=float).reshape(-1, 3)
    mat_nb = mat_nb_from_hpr(heading, pitch, roll).reshape(-1, 3, 3)
    b = euler_krylov_matrix(-lat, lon + earth_rate * t, 0.0)
    d = np.swapaxes(mat_nb, -1, -2) @ b
    alpha, beta, gamma = euler_krylov_from_matrix(d)
    return np.column_stack([alpha, beta, gamma, lat, velocity_n[:, 1]])


class StateModel:
    """The model's constants and the state conversions (a layer of :class:`PaperEkf`).

    The attributes below are set by ``PaperEkf.reset``; the layers above this one
    (mechanization, covariance, GNSS update, outputs, engines) read them.
    """

    config: PaperEkfConfig
    context: Context
    track_functions: TrackFunctions
    n_states: int  # 5 (+ 2 clock) (+ 3 + 3 biases)
    lever_arm_b: np.ndarray  # antenna lever arm in body axes, m
    substeps: int  # adaptive start-up sub-steps taken so far
    _ready: bool
    # Earth of the filter: sphere (faithful mode or a spherical context Earth) or ellipsoid
    _sphere: bool
    _a: float  # m
    _e2: float
    _omega: float  # rad/s
    _filter_earth: EarthModel
    _printed_kin: bool  # printed Phi(beta, gamma) kept (as_printed)
    _cent: float  # sign of the centrifugal term of (7): +1 printed, -1 physics, 0 WGS-84 normal gravity
    # noise: D_d (rad^2/s), D_a (m^2/s^3), pseudorange and Doppler variances (m^2, m^2/s^2)
    _qd: float
    _qa: float
    _r_code: float
    _r_dopp: float
    _lever: bool
    _clock: bool
    _biases: bool
    _accel_in_update: bool
    _observer: bool
    _i_clk: int  # index of the clock bias state (drift at + 1); -1 without clock states
    _i_ba: int  # first accelerometer bias state; -1 without bias states
    _i_bg: int  # first gyro bias state; -1 without bias states
    # time base
    _dt: float  # navigation step, s
    _spe: int  # navigation steps per GNSS period
    _n_c: int  # navigation steps per covariance interval
    _minv: np.ndarray  # (R, R) polynomial input model
    _lvec: np.ndarray  # (3, R) input weights at s = 0, 1/2, 1
    _dt_pow: np.ndarray  # (R,) dt^r
    # filter state of the reference engine
    _Y: list[float]
    _P: np.ndarray
    _P_rows: list[list[float]]
    _K: list[float]  # the gain held over the covariance interval (zero before the first)
    _P_start: np.ndarray
    _cov_left: int
    _cov_len: int
    _cov_pos: int
    _diverged: bool
    _t_prev: float

    def _state_from_prior(self, prior: Prior) -> tuple[list[float], np.ndarray]:
        tf = self.track_functions
        p9 = np.asarray(prior.covariance, dtype=float)
        phi = float(prior.lat)
        w_pos = np.linalg.inv(p9[:3, :3])
        g_phi = np.zeros(3)
        for _ in range(4):  # Gauss-Newton projection of the prior position on the track
            lam, dlam, _, hh, dh = tf.scalars(phi)
            rn, re = self._radii(phi, hh, dh)[:2]
            cp = math.cos(phi)
            resid = np.array([(prior.lon - lam) * re * cp, (prior.lat - phi) * rn, prior.h - hh])
            jac = np.array([re * cp * dlam, rn, dh])
            info = jac @ w_pos @ jac
            g_phi = (w_pos @ jac) / info
            phi += float(g_phi @ resid)
        lam, dlam, _, hh, dh = tf.scalars(phi)
        rn, re, k, _, m = self._radii(phi, hh, dh, dlam)
        tv = np.array([k, 1.0, m])
        w_vel = np.linalg.inv(p9[3:6, 3:6])
        g_v = (w_vel @ tv) / (tv @ w_vel @ tv)
        v = float(g_v @ np.asarray(prior.velocity_n, dtype=float))
        mat_nb = mat_nb_from_hpr(prior.heading, prior.pitch, prior.roll)
        bmat = euler_krylov_matrix(-phi, lam + self._omega * prior.t, 0.0)
        alpha, beta, gamma = (float(x) for x in euler_krylov_from_matrix(mat_nb.T @ bmat))
        # psi (ENU small angles) -> body rotation mat_bn psi -> angle increments Phi(alpha, gamma)
        j_att = self._kin_matrix(alpha, beta, gamma, printed=False) @ mat_nb.T
        g = np.zeros((5, 9))
        g[0:3, 6:9] = j_att
        g[3, 0:3] = g_phi
        g[4, 3:6] = g_v
        p5 = g @ p9 @ g.T
        n = self.n_states
        p = np.zeros((n, n))
        p[:5, :5] = 0.5 * (p5 + p5.T)
        y = [alpha, beta, gamma, phi, v] + [0.0] * (n - 5)
        ctx = self.context
        if self._clock:
            i = self._i_clk
            p[i, i] = max(ctx.gnss.clock_bias_sigma_m, 1.0) ** 2
            p[i + 1, i + 1] = max(ctx.gnss.clock_drift_sigma_mps, 0.01) ** 2
        if self._biases:
            for i in range(3):
                p[self._i_ba + i, self._i_ba + i] = max(ctx.imu.accel_bias_sigma, 1e-6) ** 2
                p[self._i_bg + i, self._i_bg + i] = max(ctx.imu.gyro_bias_sigma, 1e-9) ** 2
        return y, p

    def _radii(self, phi: float, hh: float, dh: float, dlam: float = 0.0) -> tuple[float, float, float, None, float]:
        """(rho_N, rho_E, k, k unused, m) at phi: rho = R + h, k = V_E / V_N, m = V_U / V_N."""
        if self._sphere:
            rn = re = self._a + hh
        else:
            s = math.sin(phi)
            w = 1.0 - self._e2 * s * s
            r_e = self._a / math.sqrt(w)
            rn, re = r_e * (1.0 - self._e2) / w + hh, r_e + hh
        k = dlam * math.cos(phi) * re / rn
        return rn, re, k, None, dh / rn

    def _kin_matrix(self, a: float, b: float, g: float, printed: bool | None = None) -> np.ndarray:
        """The kinematic matrix of the model: corrected Phi(alpha, gamma) or printed Phi(beta, gamma)."""
        sg, cg = math.sin(g), math.cos(g)
        if self._printed_kin if printed is None else printed:  # (1) as printed
            cb, tb = math.cos(b), math.tan(b)
            return np.array([[sg / cb, cg / cb, 0.0], [cg, -sg, 0.0], [sg * tb, cg * tb, 1.0]])
        ca, ta = math.cos(a), math.tan(a)
        return np.array([[cg, -sg, 0.0], [sg / ca, cg / ca, 0.0], [sg * ta, cg * ta, 1.0]])
