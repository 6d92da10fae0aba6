"""Along-track filter: the one-dimensional map-matched navigator of rail practice.

A train cannot leave its track, so with the map known (seed 003's premise) the whole
navigation state collapses to the arc length ``s`` along the track and the speed ``v``
along it. :class:`AlongTrackFilter` is a small Kalman filter on

    x = [s (m), v (m/s), b (m/s^2)]            (+ [c_b (m), c_d (m/s)] receiver clock)
                                               (+ [dI, dT] (m) zenith delays, option atmosphere)

with ``b`` the bias of the along-track (body y) accelerometer. It reads only that one
accelerometer: the design is gyro-free.

Model
-----
The body y (forward) axis lies along the unit track tangent ``t_n`` (heading, grade);
roll is the cant, which turns the body about that very axis. The specific force along
it is therefore (:mod:`navsim.motion`: ``f_n = dv_n/dt + (2 w_ie + w_en) x v_n - g_n``)

    f_y = t_n . f_n = s'' - t_n . g_n(s)

because ``t_n . dv_n/dt = s''`` (``|t_n| = 1`` so ``t_n . dt_n/ds = 0``) and the
Coriolis and transport terms are perpendicular to ``v_n = s' t_n``. For the plumb-line
gravity ``g_n = [0, g_N, -g]`` the gravity term is ``t_n . g_n = -g sin(grade) + g_N
t_N`` (``g_N``: the centrifugal part of the spherical model). Hence the exact scalar
dynamics, with no Earth-rate, transport or coning term at all:

    s' = v                                                        (AT.1)
    v' = f_y + g_t(s) - b,    g_t(s) = t_n(s) . g_n(s)            (AT.2)
    b' = -b / tau_a + w_b                                         (AT.3)
    c_b' = c_d + w_f,  c_d' = w_g     (two-state receiver clock)  (AT.4)

Unmodelled body oscillations tilt the y axis off the tangent and leak about
``g x (pitch oscillation)`` into (AT.2); give them as ``accel_psd_extra``.

Unmodelled accelerometer scale factor and misalignment (option ``accel_scale_sigma``,
off by default): the body-y output carries the y row of ``S_a f`` (``S_a`` the
scale-factor / cross-coupling matrix). Its gravity part is constant in body axes while
the vehicle stays level, a bias the bias state absorbs; the kinematic part, the along-track
acceleration ``s''`` times the y scale factor plus the centripetal ``v^2 kappa`` of the
turns times the cross-coupling to the lateral axis, is not. With the elements of
``S_a`` independent of sigma ``sigma_a`` it has the variance ``sigma_a^2 |a|^2`` and is
covered, as in the INS filters' (RS.2) (:mod:`navsim.estimators._inserror`), as white
acceleration noise of PSD

    q_Sa = sigma_a^2 (a_t^2 + (v^2 kappa(s))^2) tau_S                        (AT.13)

added to ``q_v`` for each covariance interval, with ``a_t`` the mean along-track
acceleration of the interval before (its change of the speed estimate over its length),
``kappa = |dt_n/ds|`` the track's curvature from the map at the interval start and
``tau_S`` the correlation time of the error (``scale_tau_s``, about the length of a
turn or of an acceleration phase).

Discretisation per navigation step ``dt`` (exact for the specific-force part: the
increments of the multiple integrals of seed 000 eq. (1.14) on the body y axis are the
exact single and double integrals of ``f_y``):

    a      = g_t(s_k + v_k dt / 2) - b_k                          (AT.5) mid-step grade
    v_k+1  = v_k + dV_y + a dt                                    (AT.6)
    s_k+1  = s_k + v_k dt + dV2_y + a dt^2 / 2                    (AT.7)

``dV_y = dv_r[0, 1]`` and ``dV2_y = dv_r[1, 1]`` (``dV_y dt / 2`` when only first-order
increments come). The covariance uses the Jacobian ``F`` of (AT.1)-(AT.4) frozen at the
start of each propagation interval (``F_vs = dg_t/ds``, ``F_vb = -1``) with
``Phi(tau) = expm(F tau)`` (4th-order series) and the closed-form process noise of a
double integrator driven by white acceleration noise ``q_v`` and a random-walk bias
``q_b`` (see :func:`_process_noise`). It is evaluated at every step from the last
propagation point, so the reported covariance is never stale.

GNSS updates (option ``update``)
--------------------------------
``"pseudorange"`` (default): a direct tightly coupled update, the position being a
function of ``s`` through the map::

    rho_i(s)     = |r_sat_i - r_e(s)| + c_b                      (003 eq. (2))
    rhodot_i     = u_i . (v_sat_i - v t_e(s)) + c_d               (003 eq. (3))
    d rho_i/ds   = -u_i . t_e,           d rhodot_i/dv = -u_i . t_e
    d rhodot_i/ds = du_i/ds . (v_sat_i - v t_e) - v u_i . dt_e/ds,
    du_i/ds      = -(t_e - u_i (u_i . t_e)) / rho_i

(``u_i`` unit line of sight receiver -> satellite, ``t_e`` the ECEF tangent). One
satellite suffices without a clock, two with it: the map makes the problem 1-D.

``"fix"``: the least-squares point fix (:func:`navsim.receiver.least_squares_fix`,
four satellites or more) projected on the track (``s`` minimising the distance to the
fix, Newton on ``t_e . (r_fix - r_e(s)) = 0``), with variance ``t_e^T Sigma_fix t_e``;
and, with ``use_doppler``, the velocity fix projected on the tangent. The clock is
solved by the fix; the filter then has no clock states.

Atmosphere (option ``atmosphere``, default "none")
--------------------------------------------------
An uncorrected single-frequency receiver (``context.gnss.atmosphere_modelled``) has
slant ionospheric and tropospheric delays in every pseudorange. Their common part goes
into the clock bias, but the part that differs between satellites with the elevation
projects onto the track as an arc-length error that lasts as long as the delays do
(minutes to hours): taken as white code noise it is averaged down epoch after epoch and
the filter grows over-confident in ``s``. With ``atmosphere="auto"`` (pseudorange mode
with the clock states) two states follow the clock, the corrections ``dI``, ``dT`` of the
zenith ionospheric and sea-level zenith tropospheric delays to the context's a-priori
values (the standard-model values a receiver applies), with the a-priori sigmas as prior.
The predicted pseudorange gets the slant delays of the tightly coupled filter's (TC.6)
(:mod:`navsim.estimators.tightly`: thin-shell obliquity ``F(E)``, DO-229D mapping ``m(E)``,
height factor ``exp(-h / H_T)``)::

    rho_i += (I_0 + dI) F(E_i) + (T_0 + dT) exp(-h / H_T) m(E_i)                 (AT.14)
    d rho_i / d dI = F(E_i),   d rho_i / d dT = exp(-h / H_T) m(E_i)

with ``E_i`` the elevation at the track point ``s`` (the slant delays' change with ``s``
through the elevation, ~1e-5 m/m, is left out of ``d rho_i / ds``). The corrections are
held constant between updates and walk with the driving PSD ``2 sigma^2 / tau`` of a
Gauss-Markov process of the prior sigma (options ``ionosphere_tau_s`` = 1800 s,
``troposphere_tau_s`` = 3600 s, the tightly coupled filter's): over an episode much
shorter than tau the Gauss-Markov mean hardly decays, and the random walk's variance
exceeds the Gauss-Markov's only after ~tau/2 (conservative). The multipath's 30-s
correlation is not modelled (it stays in the white code sigma).

Antenna lever arm (``context.gnss.lever_arm_b_m`` = l, body axes; option ``lever_arm``)
-------------------------------------------------------------------------------------
The measurements are the antenna's. On its track the body attitude is the track's
(heading, grade, cant; body oscillations are not known to a gyro-free filter), so the
antenna too is a function of s alone::

    r_a(s) = r_e(s) + C_ne(s) C_nb(s) l                                     (AT.8)
    dr_a/ds = t_e + C_ne ((rho_n + w_n) x C_nb l)                           (AT.9)

(``rho_n`` the transport rate per metre, ``earth.transport_rate_n(lat, h, t_n)``,
``w_n`` the track-frame rotation per metre below); the map table holds the offset and
its derivative (cubic Hermite like the rest). Both updates then use the antenna's track:
``r_e -> r_a``, ``t_e -> dr_a/ds``, ``dt_e/ds -> d^2 r_a/ds^2`` in the formulas above
(the antenna velocity is ``v dr_a/ds``), and the "fix" mode projects ``r_fix - C_eb l``
on the track and predicts the velocity fix along ``t_e`` as ``v t_e . dr_a/ds`` (AT.10).
The offset from the body oscillations (3 m x 0.15 deg = 8 mm on mountain-railway) is
left out.

Wheel odometer (``context.odometer``; option ``odometer``)
---------------------------------------------------------
With an odometer the state gains a clone ``s_c`` of the arc length at the last odometer
update (stochastic cloning) and the odometer scale-factor error ``k``::

    x = [s, v, b, (c_b, c_d), s_c, k]
    s_c' = 0,   k' = w_k,  q_k = 2 sigma_g^2 / tau_g                          (AT.11)

``k`` starts with the variance ``sigma_c^2 + sigma_g^2`` of the nominal turn-on and
Gauss-Markov parts and then walks with the Gauss-Markov driving PSD (a random walk: the
Gauss-Markov variance is reached after ~tau/2 and exceeded later, which is conservative;
the turn-on part is a constant). Every ``odometer_period_s`` (global step multiples,
default 1 s) the distance D counted over the interval T updates the state::

    D = (1 + k) (s - s_c) + w,                                               (AT.12)
    H = [1 + k, 0, 0, (0, 0), -(1 + k), s - s_c],
    R = q^2 T + p^2 / 6 (+ (slip D)^2 when |v - v_c| / T > 0.9 a_slip)

(q the nominal noise density, p the pulse length: the quantisation error of a span is the
difference of two carries, uniform on [0, p); v_c the speed at the last update: the
filter's own acceleration estimate decides whether slip is possible), after which
``s_c`` and its covariance rows are reset to those of s. Between odometer updates the
clone is constant, so its rows of Phi are the identity. Without an odometer in the
context, or with ``odometer="none"``, the filter is the one without these states.

Output
------
Position, tangent, heading, grade and cant come from the track at ``s``; velocity is
``v t_n(s)``. The 9 x 9 covariance maps the filter's through the track geometry:
``dp = t_n ds``, ``dv_n = t_n dv + v (dt_n/ds) ds``, ``psi = w_n ds`` with ``w_n`` the
rotation of the track frame (heading, grade, cant) per metre of track in ENU axes, i.e.
``J P J^T`` with a Jacobian ``J`` whose only nonzero columns are those of s and v (computed
from those two columns alone, the same operations in batch and step by step). The
cross-track position and velocity errors and the attitude errors other than through
``ds`` are zero for a vehicle on its track (the map is taken as exact), so the reported
covariance has rank 2 (arc length and speed): it claims a 2-dimensional error subspace,
and :func:`navsim.metrics.nees_summary` scores NEES there, against chi-square(2). Optional
diagonal floors ``position_floor_m``, ``velocity_floor_mps`` (default 0) make it full rank
(NEES then over all six components, where the cross-track floors dominate). The attitude is the track's (heading, grade,
cant): a gyro-free filter cannot know how the body oscillates about it, so by default its
covariance rows are ``nan`` ("not estimated"; metrics then leave attitude out of NEES).
Give ``attitude_floor_rad`` (e.g. the expected body oscillation amplitude) to report the
track-mapped attitude covariance plus that floor instead.

Map table: at ``reset`` the track is sampled every ``table_step_m`` (5 m) metres (finer
where it turns sharply, see :class:`TrackTable`) and evaluated between nodes by cubic
Hermite interpolation on values and analytic s-derivatives (ECEF position with the ECEF
tangent as derivative, geodetic position, ENU tangent, heading, grade, cant, ``g_t``).


References
----------
.. [1] Sokolov S.V., Vdovichenko S.S. (2012), seed 003: the known-track premise and the
       observables (2), (3).
.. [2] Litmanovich Yu.A. (2002), seed 000, eq. (1.14): multiple-integral increments.
.. [3] Brown R.G., Hwang P.Y.C., Introduction to Random Signals and Applied Kalman
       Filtering, 4th ed., 2012: sections 9.3 (clock model) and 4.9 / 9.5 (Joseph form,
       process noise of integrated white noise).
.. [4] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., 2013, section 16.2 (map matching for rail).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..earth import mat_en
from ..errors import ConfigError
from ..rotations import body_rate_from_hpr_rates, mat_nb_from_hpr
from ..types import FloatOrArray
from .base import Context, Estimate, EstimateBatch, Measurement, MeasurementBatch, NoiseScalable, Prior, StepRow
from .tightly import slant_maps

if TYPE_CHECKING:  # type hints only
    from ..track import Track

__all__ = ["AlongTrackFilter", "TrackTable"]

_UPDATES = ("pseudorange", "fix")
_CLOCKS = ("auto", "estimate", "none")
TINY_CLOCK_BIAS_M = 1e-3
TINY_CLOCK_DRIFT_MPS = 1e-4
SIGMA_FLOOR_PR_M = 1e-3  # floors of the measurement sigmas (the "ideal" receiver has 0)
SIGMA_FLOOR_RATE_MPS = 1e-4


# ============================================================================ map table
class TrackTable:
    """The track sampled on a uniform grid of arc length, cubic Hermite in between.

    Parameters
    ----------
    track : navsim.track.Track
    step_m : float
        Node spacing, m (the last interval is made equal by rescaling). Where the track
        turns (heading or grade) by more than ``MAX_TURN`` = 0.05 rad within one interval
        the spacing is reduced for the whole table (not below 0.25 m): a 15-m street
        corner gets ~0.7 m.
    lever_arm_b : array_like (3,), optional
        Antenna relative to the IMU in body axes, m. When given (non-zero), the table
        also holds the antenna's ECEF offset ``C_eb(s) l`` (AT.8) with its s-derivative
        (AT.9), columns :attr:`ANT`.
    """

    def __init__(self, track: Track, step_m: float = 5.0, lever_arm_b: ArrayLike | None = None):
        from ..track import track_frame

        self.length = float(track.length)
        for _ in range(2):
            n = max(2, int(math.ceil(self.length / step_m)) + 1)
            self.step = self.length / (n - 1)
            s = np.linspace(0.0, self.length, n)
            frame = track_frame(track, s)
            # tight curves (streets): at most MAX_TURN rad of heading or grade per interval
            turn = float(np.max(np.hypot(frame.curvature, frame.dpitch_ds))) * self.step
            if turn <= self.MAX_TURN or step_m <= self.MIN_STEP:
                break
            step_m = max(self.MIN_STEP, step_m * self.MAX_TURN / turn)
        pos, d1, _ = track.geodetic(s)
        earth = track.earth
        self.earth = earth
        c_en = mat_en(frame.lat, frame.lon)  # (n, 3, 3) rows E, N, U in ECEF
        r_e = earth.geodetic_to_ecef(frame.lat, frame.lon, frame.h)
        t_e = np.einsum("nij,ni->nj", c_en, frame.tangent_n)  # C_en^T t_n
        heading = np.unwrap(frame.heading)
        g_n = earth.gravity_n(frame.lat, frame.h)
        g_t = np.einsum("ni,ni->n", frame.tangent_n, g_n)  # (AT.2) g_t = t_n . g_n
        dg_t = np.einsum("ni,ni->n", frame.dtangent_n_ds, g_n)
        # track-frame rotation per metre in ENU axes: w_n = C_nb omega_nb_b(d/ds angles)
        mat_nb = mat_nb_from_hpr(heading, frame.pitch, frame.cant)
        w_b = body_rate_from_hpr_rates(heading, frame.pitch, frame.cant, frame.dheading_ds, frame.dpitch_ds,
                                       frame.dcant_ds)
        self.w_n = np.einsum("nij,nj->ni", mat_nb, w_b)
        # Hermite pairs (value, d/ds) stacked column-wise; ECEF relative to the first node
        # (coordinates of 1e4 m instead of 6e6 m keep ~1e-12 relative precision in t_e)
        self.r_ref = r_e[0].copy()
        self.values = np.column_stack([r_e - self.r_ref, pos, frame.tangent_n, heading, frame.pitch, frame.cant, g_t])
        self.derivs = np.column_stack([t_e, d1, frame.dtangent_n_ds, frame.dheading_ds, frame.dpitch_ds,
                                       frame.dcant_ds, dg_t])
        lever = np.zeros(3) if lever_arm_b is None else np.asarray(lever_arm_b, dtype=float)
        self.lever_arm_b = lever
        self.has_antenna = bool(np.any(lever != 0.0))
        if self.has_antenna:
            # (AT.8) antenna offset C_ne C_nb l in ECEF on the track attitude (heading, grade, cant);
            # (AT.9) d/ds = C_ne ((rho_n + w_n) x C_nb l), rho_n the transport rate per metre
            arm_n = mat_nb @ lever
            rho_n = earth.transport_rate_n(frame.lat, frame.h, frame.tangent_n)
            arm_e = np.einsum("nij,ni->nj", c_en, arm_n)
            darm_e = np.einsum("nij,ni->nj", c_en, np.cross(rho_n + self.w_n, arm_n))
            self.values = np.column_stack([self.values, arm_e])
            self.derivs = np.column_stack([self.derivs, darm_e])
        self._g = g_t.tolist()
        self._dg = (dg_t * self.step).tolist()
        self._inv = 1.0 / self.step
        self._n = n

    MAX_TURN = 0.05  # rad per table interval (tangent error ~1e-5 there)
    MIN_STEP = 0.25  # m

    # column blocks of values / derivs
    R_E, GEO, T_N, HEADING, PITCH, CANT, G_T = slice(0, 3), slice(3, 6), slice(6, 9), 9, 10, 11, 12
    ANT = slice(13, 16)  # antenna offset in ECEF (only with a lever arm)

    def _index(self, s: FloatOrArray) -> tuple[np.ndarray, np.ndarray]:
        x = np.clip(np.asarray(s, dtype=float), 0.0, self.length) * self._inv
        i = np.minimum(x.astype(int), self._n - 2)
        return i, x - i

    def evaluate(self, s: FloatOrArray, columns: slice | int | Sequence[int] = slice(None),
                 derivative: int = 0) -> np.ndarray:
        """Hermite interpolant (derivative 0), its first or second s-derivative at s.

        Returns shape ``np.shape(s) + (k,)`` for a slice of columns, ``np.shape(s)`` for
        one integer column.
        """
        i, u = self._index(s)
        y0, y1 = self.values[i][..., columns], self.values[i + 1][..., columns]
        d0, d1 = self.derivs[i][..., columns] * self.step, self.derivs[i + 1][..., columns] * self.step
        if isinstance(columns, slice):
            u = u[..., None]
        uu = u * u
        if derivative == 0:
            h00, h10, h01, h11 = (1 + 2 * u) * (1 - u) ** 2, u * (1 - u) ** 2, uu * (3 - 2 * u), uu * (u - 1)
            return h00 * y0 + h10 * d0 + h01 * y1 + h11 * d1
        if derivative == 1:
            h00, h10, h01, h11 = 6 * uu - 6 * u, 3 * uu - 4 * u + 1, 6 * u - 6 * uu, 3 * uu - 2 * u
            return (h00 * y0 + h10 * d0 + h01 * y1 + h11 * d1) * self._inv
        h00, h10, h01, h11 = 12 * u - 6, 6 * u - 4, 6 - 12 * u, 6 * u - 2
        return (h00 * y0 + h10 * d0 + h01 * y1 + h11 * d1) * self._inv**2

    def position_e(self, s: FloatOrArray) -> np.ndarray:
        """ECEF position of the track at s, (..., 3) m."""
        return self.r_ref + self.evaluate(s, self.R_E)

    def rotation_per_m(self, s: FloatOrArray) -> np.ndarray:
        """Track-frame rotation per metre in ENU axes (linear interpolation), (..., 3) rad/m."""
        i, u = self._index(s)
        u = u[..., None]
        return (1 - u) * self.w_n[i] + u * self.w_n[i + 1]

    def gravity_along(self, s: float) -> float:
        """g_t(s) = t_n . g_n of (AT.2), m/s^2, scalar fast path (same Hermite)."""
        x = min(max(s, 0.0), self.length) * self._inv
        i = min(int(x), self._n - 2)
        u = x - i
        v = 1.0 - u
        g, d = self._g, self._dg
        return ((1 + 2 * u) * v * v * g[i] + u * v * v * d[i]
                + u * u * (3 - 2 * u) * g[i + 1] + u * u * (u - 1) * d[i + 1])

    def project(self, r_e: np.ndarray, s0: float | None = None, iterations: int = 4) -> float:
        """Arc length of the track point nearest to ECEF point r_e (m).

        Global start on the nodes (unless s0 is given), then Newton on
        ``t_e . (r_e - r(s)) = 0`` with the derivative ``-|t_e|^2 + (r_e - r) . dt_e/ds``.
        """
        r_e = np.asarray(r_e, dtype=float)
        if s0 is None:
            d2 = np.sum((self.values[:, self.R_E] + self.r_ref - r_e) ** 2, axis=1)
            s = float(np.argmin(d2)) * self.step
        else:
            s = float(s0)
        for _ in range(iterations):
            diff = r_e - self.position_e(s)
            t_e = self.evaluate(s, self.R_E, 1)
            dt_e = self.evaluate(s, self.R_E, 2)
            gradient = float(t_e @ diff)
            curvature = float(t_e @ t_e) - float(diff @ dt_e)
            s = min(max(s + gradient / max(curvature, 1e-6), 0.0), self.length)
        return s


# ============================================================================ helpers
def _series_expm(a: np.ndarray, order: int = 4) -> np.ndarray:
    """expm(a) by its Taylor series to the given order, batched over leading axes."""
    eye = np.broadcast_to(np.eye(a.shape[-1]), a.shape)
    out = eye + a
    term = a
    for k in range(2, order + 1):
        term = term @ a / k
        out = out + term
    return out


def _process_noise(tau: np.ndarray, q_v: float, q_b: float, s_f: float, s_g: float, n_x: int,
                   q_atm: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """Discrete process noise over intervals tau (k,), shape (k, n_x, n_x).

    [s, v] driven by white acceleration q_v (m^2/s^3): q_v [[t^3/3, t^2/2], [t^2/2, t]];
    a random-walk bias q_b entering v' with -1 adds q_b [[t^5/20, t^4/8, -t^3/6],
    [t^4/8, t^3/3, -t^2/2], [-t^3/6, -t^2/2, t]] (correlation time >> t); clock (AT.4):
    [[S_f t + S_g t^3/3, S_g t^2/2], [S_g t^2/2, S_g t]] (Brown & Hwang 9.3); the
    atmosphere corrections (AT.14), states 5 and 6 when ``n_x == 7``: random walks q_atm t.
    """
    t = np.asarray(tau, dtype=float)
    t2, t3 = t * t, t * t * t
    t4, t5 = t3 * t, t3 * t2
    q = np.zeros(t.shape + (n_x, n_x))
    q[..., 0, 0] = q_v * t3 / 3 + q_b * t5 / 20
    q[..., 0, 1] = q[..., 1, 0] = q_v * t2 / 2 + q_b * t4 / 8
    q[..., 1, 1] = q_v * t + q_b * t3 / 3
    q[..., 0, 2] = q[..., 2, 0] = -q_b * t3 / 6
    q[..., 1, 2] = q[..., 2, 1] = -q_b * t2 / 2
    q[..., 2, 2] = q_b * t
    if n_x >= 5:
        q[..., 3, 3] = s_f * t + s_g * t3 / 3
        q[..., 3, 4] = q[..., 4, 3] = s_g * t2 / 2
        q[..., 4, 4] = s_g * t
    if n_x == 7:
        q[..., 5, 5] = q_atm[0] * t
        q[..., 6, 6] = q_atm[1] * t
    return q


def joseph_update(x: np.ndarray, P: np.ndarray, y: np.ndarray, H: np.ndarray,
                  R: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Kalman update in Joseph form: returns x + K y, (I-KH) P (I-KH)^T + K R K^T, NIS.

    ``R`` is the (m,) diagonal of the measurement noise. Non-finite results come back
    as ``None`` (the caller flags divergence).
    """
    PHt = P @ H.T
    S = H @ PHt + np.diag(R)
    try:
        c = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        return None
    # K = P H^T S^-1 through the Cholesky factor
    w = np.linalg.solve(c, PHt.T)
    K = np.linalg.solve(c.T, w).T
    z = np.linalg.solve(c, y)
    nis = float(z @ z)
    a = np.eye(len(x)) - K @ H
    P_new = a @ P @ a.T + (K * R) @ K.T  # Joseph form
    P_new = 0.5 * (P_new + P_new.T)
    x_new = x + K @ y
    if not (np.all(np.isfinite(x_new)) and np.all(np.isfinite(P_new))):
        return None
    return x_new, P_new, nis


# ============================================================================ the filter
@dataclass(frozen=True, slots=True)
class AlongTrackOptions:
    """Options of :class:`AlongTrackFilter` (validated; see the class docstring)."""

    update: str = "pseudorange"
    use_doppler: bool = True
    clock: str = "auto"
    estimate_bias: bool = True
    accel_psd_extra: float = 0.0
    accel_scale_sigma: float = 0.0
    scale_tau_s: float = 5.0
    cov_period_s: float | None = None
    table_step_m: float = 5.0
    position_floor_m: float = 0.0
    velocity_floor_mps: float = 0.0
    attitude_floor_rad: float | None = None
    nis_divergence: float = 50.0
    divergence_epochs: int = 10
    pseudorange_sigma_m: float | None = None
    doppler_sigma_mps: float | None = None
    lever_arm: str = "auto"
    odometer: str = "auto"
    odometer_period_s: float = 1.0
    atmosphere: str = "none"
    ionosphere_tau_s: float = 1800.0
    troposphere_tau_s: float = 3600.0

    def __post_init__(self) -> None:
        if self.lever_arm not in ("auto", "none"):
            raise ConfigError("along-track.lever_arm", "'auto' or 'none'", self.lever_arm)
        if self.odometer not in ("auto", "none"):
            raise ConfigError("along-track.odometer", "'auto' or 'none'", self.odometer)
        if self.atmosphere not in ("auto", "none"):
            raise ConfigError("along-track.atmosphere", "'auto' or 'none'", self.atmosphere)
        for name in ("ionosphere_tau_s", "troposphere_tau_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and value > 0.0):
                raise ConfigError(f"along-track.{name}", "a positive time, s (inf: a random constant)", value)
        if not (isinstance(self.odometer_period_s, (int, float)) and self.odometer_period_s > 0.0
                and math.isfinite(self.odometer_period_s)):
            raise ConfigError("along-track.odometer_period_s", "a positive finite time, s", self.odometer_period_s)
        for name in ("pseudorange_sigma_m", "doppler_sigma_mps"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and value > 0.0 and math.isfinite(value)):
                raise ConfigError(f"along-track.{name}", "None or a positive finite sigma", value)
        if self.update not in _UPDATES:
            raise ConfigError("along-track.update", f"one of {_UPDATES}", self.update)
        if self.clock not in _CLOCKS:
            raise ConfigError("along-track.clock", f"one of {_CLOCKS}", self.clock)
        for name in ("accel_psd_extra", "accel_scale_sigma", "position_floor_m", "velocity_floor_mps", "attitude_floor_rad"):
            value = getattr(self, name)
            if value is None and name == "attitude_floor_rad":
                continue
            if not (isinstance(value, (int, float)) and value >= 0.0 and math.isfinite(value)):
                raise ConfigError(f"along-track.{name}", "a non-negative finite number", value)
        for name in ("table_step_m", "nis_divergence", "scale_tau_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and value > 0.0 and math.isfinite(value)):
                raise ConfigError(f"along-track.{name}", "a positive finite number", value)
        if self.cov_period_s is not None and not (self.cov_period_s > 0.0 and math.isfinite(self.cov_period_s)):
            raise ConfigError("along-track.cov_period_s", "None or a positive number of seconds", self.cov_period_s)
        if not (isinstance(self.divergence_epochs, int) and self.divergence_epochs >= 1):
            raise ConfigError("along-track.divergence_epochs", "a positive integer", self.divergence_epochs)


class AlongTrackFilter(NoiseScalable):
    """Kalman filter on arc length, speed and along-track accelerometer bias.

    Parameters (keywords, all optional)
    -----------------------------------
    update : {"pseudorange", "fix"}
        Direct pseudorange(-rate) update with the position a function of s (default), or
        the least-squares fix projected on the track.
    use_doppler : bool
        Also use the pseudorange rates (or the velocity fix), default True.
    clock : {"auto", "estimate", "none"}
        Receiver clock bias and drift states in the pseudorange mode. "auto": estimate
        them when ``context.gnss.clock_modelled``, else none (the paper's case: clock
        compensated). "estimate" with an unmodelled clock keeps them with a tiny prior
        (1 mm, 0.1 mm/s) and no process noise. Never used in the "fix" mode.
    estimate_bias : bool
        Keep the accelerometer-bias state (its prior sigma is the nominal
        ``accel_bias_sigma``).
    accel_psd_extra : float
        Extra along-track acceleration PSD, m^2/s^3, for unmodelled effects (body
        oscillations, track errors).
    accel_scale_sigma, scale_tau_s : float
        Sigma of the accelerometer's scale-factor / misalignment elements (default 0:
        off) and the correlation time of their error, s (default 5): the unmodelled
        ``S_a a`` of (AT.13), as acceleration-proportional noise.
    cov_period_s : float, optional
        Longest covariance propagation interval (default: the GNSS period).
    table_step_m : float
        Map-table node spacing, m.
    position_floor_m, velocity_floor_mps : float
        Diagonal floors of the position and velocity blocks of the 9 x 9 covariance (default 0:
        the covariance has rank 2, see Output).
    attitude_floor_rad : float or None
        None (default): attitude covariance nan (not estimated); a number: the
        track-mapped attitude covariance plus this floor (see the module docstring).
    nis_divergence, divergence_epochs : float, int
        ``extra["diverged"]`` turns True when NIS / dof exceeds ``nis_divergence`` at
        that many consecutive epochs, or when the covariance stops being finite.
    pseudorange_sigma_m, doppler_sigma_mps : float, optional
        Measurement sigmas assumed instead of the context's nominal ones (tuning, e.g.
        for unmodelled atmospheric delays). Floors: 1 mm and 0.1 mm/s.
    lever_arm : {"auto", "none"}
        "auto": the observables are the antenna's, at ``context.gnss.lever_arm_b_m`` from
        the IMU on the track attitude (AT.8)-(AT.10); "none": the antenna is taken to be
        at the IMU (uncompensated).
    odometer : {"auto", "none"}
        "auto": use the wheel odometer when the context has one (AT.11)-(AT.12);
        "none": ignore it (the filter without odometer, number for number).
    odometer_period_s : float
        Interval of the odometer updates, s (rounded to whole navigation steps).
    atmosphere : {"none", "auto"}
        "auto": with an uncorrected receiver (``context.gnss.atmosphere_modelled``), in the
        pseudorange mode with clock states, apply the a-priori slant delays and estimate
        the zenith corrections (AT.14); "none" (default): no atmosphere in the model.
    ionosphere_tau_s, troposphere_tau_s : float
        Correlation times of the zenith corrections, s (their random-walk PSD 2 sigma^2 /
        tau; inf: random constants).

    The model, discretisation and measurement equations are in the module docstring.
    """

    NOISE_PROCESS = ('q_v', 'q_b')
    step_row_fields = ("dv_r",)  # the IMU field step_row reads between GNSS epochs (navsim.envs.EstimatorAgent)
    NOISE_MEASUREMENT_SIGMA = ('sigma_pr', 'sigma_rate')
    # where set_noise_scale finds Q and R after reset (navsim.estimators.base.NoiseScalable)

    table: TrackTable  # the map table of the last reset (cached per track)

    def __init__(self, **options: Any) -> None:
        self.options = AlongTrackOptions(**options)
        self._table: TrackTable | None = None
        self._table_key: tuple | None = None

    # ------------------------------------------------------------------ reset
    def reset(self, context: Context, prior: Prior) -> None:
        """Build the map table (cached per track) and the initial state from the prior."""
        opt = self.options
        arm = getattr(context.gnss, "lever_arm_b_m", (0.0, 0.0, 0.0)) if opt.lever_arm == "auto" else (0.0, 0.0, 0.0)
        arm = tuple(float(x) for x in arm)
        key = (id(context.track), opt.table_step_m, arm)
        if self._table is None or self._table_key != key:
            self._table = TrackTable(context.track, opt.table_step_m, lever_arm_b=arm)
            self._table_key = key
        self.context = context
        table = self.table = self._table
        gnss = context.gnss
        if opt.update == "fix" or opt.clock == "none":
            self.clock_states = False
        elif opt.clock == "estimate":
            self.clock_states = True
        else:
            self.clock_states = bool(gnss.clock_modelled)
        self.atmosphere = (opt.atmosphere == "auto" and opt.update == "pseudorange" and self.clock_states
                           and bool(getattr(gnss, "atmosphere_modelled", False)))
        n_core = (5 if self.clock_states else 3) + (2 if self.atmosphere else 0)
        odometer = getattr(context, "odometer", None)
        self.use_odometer = opt.odometer == "auto" and odometer is not None
        n_x = n_core + (2 if self.use_odometer else 0)
        self.n_core, self.n_x = n_core, n_x
        self.i_clone, self.i_scale = n_core, n_core + 1
        imu = context.imu
        self.tau_b = float(imu.accel_bias_tau_s) if imu.accel_bias_tau_s > 0 else math.inf
        self.q_v = float(imu.accel_vrw) ** 2 + opt.accel_psd_extra
        sigma_b = float(imu.accel_bias_sigma) if opt.estimate_bias else 0.0
        self.q_b = (2.0 * sigma_b**2 / self.tau_b if math.isfinite(self.tau_b) else 0.0) + float(imu.accel_rrw) ** 2
        if not opt.estimate_bias:
            self.q_b = 0.0
        if gnss.clock_modelled:
            self.s_f, self.s_g = float(gnss.clock_phase_psd), float(gnss.clock_freq_psd)
            cb_sigma, cd_sigma = float(gnss.clock_bias_sigma_m), float(gnss.clock_drift_sigma_mps)
        else:
            self.s_f = self.s_g = 0.0
            cb_sigma, cd_sigma = TINY_CLOCK_BIAS_M, TINY_CLOCK_DRIFT_MPS
        # initial s: the prior position projected on the track; v along the tangent
        r0 = context.earth.geodetic_to_ecef(prior.lat, prior.lon, prior.h)
        s0 = table.project(r0)
        t_n = table.evaluate(s0, table.T_N)
        t_n = t_n / np.linalg.norm(t_n)
        v0 = float(t_n @ np.asarray(prior.velocity_n, dtype=float))
        cov = np.asarray(prior.covariance, dtype=float)
        x = np.zeros(n_x)
        x[0], x[1] = s0, v0
        P = np.zeros((n_x, n_x))
        P[0, 0] = float(t_n @ cov[:3, :3] @ t_n)
        P[1, 1] = float(t_n @ cov[3:6, 3:6] @ t_n)
        P[2, 2] = sigma_b**2
        if self.clock_states:
            P[3, 3], P[4, 4] = cb_sigma**2, cd_sigma**2
        self.q_atm = (0.0, 0.0)
        if self.atmosphere:  # (AT.14) zenith corrections to the a-priori delays
            sig_i, sig_t = float(gnss.ionosphere_zenith_sigma_m), float(gnss.troposphere_zenith_sigma_m)
            P[5, 5], P[6, 6] = sig_i**2, sig_t**2
            self.q_atm = (2.0 * sig_i**2 / opt.ionosphere_tau_s, 2.0 * sig_t**2 / opt.troposphere_tau_s)
            self.atm_zenith0 = (float(gnss.ionosphere_zenith_m), float(gnss.troposphere_zenith_m))
            self.atm_k = context.earth.a / (context.earth.a + float(gnss.ionosphere_shell_height_m))
            self.atm_scale_height = float(gnss.troposphere_scale_height_m)
        if self.use_odometer and odometer is not None:  # (AT.11) the clone starts as s itself
            ic, ik = self.i_clone, self.i_scale
            x[ic] = s0
            P[ic, ic] = P[0, ic] = P[ic, 0] = P[0, 0]
            P[ik, ik] = odometer.scale_factor_sigma**2 + odometer.scale_factor_gm_sigma**2
            tau_k = float(odometer.scale_factor_tau_s)
            self.q_k = 2.0 * odometer.scale_factor_gm_sigma**2 / tau_k if math.isfinite(tau_k) else 0.0
            self.odo_steps = max(1, int(round(opt.odometer_period_s / context.nav_period_s)))
            self.odo_spec: Any = odometer
            self._odo_sum, self._odo_n, self._odo_missing = 0.0, 0, False
            self._odo_v0 = v0
            self.odo_nis = math.nan
        self.x, self.P = x, P
        # measurement sigmas with a floor (an error-free receiver must not make S singular)
        sigma_pr = opt.pseudorange_sigma_m if opt.pseudorange_sigma_m is not None else gnss.pseudorange_sigma_m
        sigma_rate = opt.doppler_sigma_mps if opt.doppler_sigma_mps is not None else gnss.doppler_sigma_mps
        self.sigma_pr = max(float(sigma_pr), SIGMA_FLOOR_PR_M)
        self.sigma_rate = max(float(sigma_rate), SIGMA_FLOOR_RATE_MPS)
        dt = context.nav_period_s
        period = opt.cov_period_s if opt.cov_period_s is not None else context.gnss_period_s
        self.cov_steps = max(1, int(round(period / dt)))
        self.dt = dt
        self.decay = math.exp(-dt / self.tau_b) if math.isfinite(self.tau_b) else 1.0
        self.k_in, self._v_start = 0, v0  # no interval before the first: (AT.13) starts from a_t = 0
        self._start_interval()
        self.t = float(prior.t)
        self.diverged = False
        self._bad_epochs = 0
        self.n_updates = 0
        self._last_extra: dict | None = {}
        self._row_args: tuple | None = None  # the step path's kernels and arguments (_row_setup), made on first use

    def _start_interval(self) -> None:
        """Freeze F at the start of a covariance propagation interval."""
        F = np.zeros((self.n_x, self.n_x))
        F[0, 1] = 1.0  # (AT.1)
        F[1, 0] = float(self.table.evaluate(self.x[0], self.table.G_T, 1))  # (AT.2) d g_t / ds
        F[1, 2] = -1.0 if self.options.estimate_bias else 0.0
        F[2, 2] = -1.0 / self.tau_b if math.isfinite(self.tau_b) else 0.0  # (AT.3)
        if self.clock_states:
            F[3, 4] = 1.0  # (AT.4)
        self.F = F
        self.q_int = self.q_v  # white acceleration PSD of this interval
        sigma_a = self.options.accel_scale_sigma
        if sigma_a > 0.0:  # (AT.13) with the interval before
            s, v = float(self.x[0]), float(self.x[1])
            span = getattr(self, "k_in", 0) * self.dt
            a_t = (v - self._v_start) / span if span > 0.0 else 0.0
            kappa = float(np.linalg.norm(self.table.evaluate(s, self.table.T_N, 1)))
            a_c = v * v * kappa
            self.q_int = self.q_v + sigma_a * sigma_a * (a_t * a_t + a_c * a_c) * self.options.scale_tau_s
            self._v_start = v
        self.P0 = self.P
        self.k_in = 0  # steps since the interval start
        self._P_block: tuple[int, np.ndarray] | None = None  # (first k, P(k) of the rest of the interval) for step()

    def _covariance_at(self, k: np.ndarray) -> np.ndarray:
        """P(t_0 + k dt) = Phi P0 Phi^T + Q for integer step counts k (array)."""
        tau = np.asarray(k, dtype=float) * self.dt
        phi = _series_expm(self.F * tau[:, None, None])
        q = _process_noise(tau, self.q_int, self.q_b, self.s_f, self.s_g, self.n_core, self.q_atm)
        if self.n_x != self.n_core:  # (AT.11) clone: no noise; scale factor: random walk
            full = np.zeros(tau.shape + (self.n_x, self.n_x))
            full[..., :self.n_core, :self.n_core] = q
            full[..., self.i_scale, self.i_scale] = self.q_k * tau
            q = full
        P = phi @ self.P0 @ np.swapaxes(phi, -1, -2) + q
        return 0.5 * (P + np.swapaxes(P, -1, -2))

    # ------------------------------------------------------------------ mean propagation
    def _propagate_mean(self, dv_y: float, ds2_y: float) -> None:
        x = self.x
        s, v, b = float(x[0]), float(x[1]), float(x[2])
        dt = self.dt
        a = self.table.gravity_along(s + 0.5 * dt * v) - b  # (AT.5) mid-step grade
        x[1] = v + dv_y + a * dt  # (AT.6)
        x[0] = s + v * dt + ds2_y + 0.5 * dt * dt * a  # (AT.7)
        x[2] = b * self.decay  # (AT.3) Gauss-Markov mean
        if self.clock_states:
            x[3] = x[3] + x[4] * dt  # (AT.4)

    @staticmethod
    def _along_increments(dv_r: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Body-y single and double integrals of the specific force, (n,) each."""
        dv_y = dv_r[..., 0, 1]
        ds2_y = dv_r[..., 1, 1] if dv_r.shape[-2] >= 2 else 0.5 * dt * dv_y
        return dv_y, ds2_y

    # ------------------------------------------------------------------ GNSS update
    def _measurement_model(self, s: float, v: float, obs: Any,
                           use: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Predicted pseudoranges/rates and their Jacobian rows over [s, v] (see module)."""
        table = self.table
        r = table.position_e(s)
        t_e = table.evaluate(s, table.R_E, 1)
        dt_e = table.evaluate(s, table.R_E, 2)
        if table.has_antenna:  # (AT.10) the antenna's track: offset (AT.8) and its derivatives
            r = r + table.evaluate(s, table.ANT)
            t_e = t_e + table.evaluate(s, table.ANT, 1)
            dt_e = dt_e + table.evaluate(s, table.ANT, 2)
        los = obs.sat_pos_e[use] - r
        rho = np.sqrt(np.einsum("mi,mi->m", los, los))
        u = los / rho[:, None]
        ut = u @ t_e
        rel = obs.sat_vel_e[use] - v * t_e
        rate = np.einsum("mi,mi->m", u, rel)
        du_ds = -(t_e[None, :] - u * ut[:, None]) / rho[:, None]
        drate_ds = np.einsum("mi,mi->m", du_ds, rel) - v * (u @ dt_e)
        return rho, rate, -ut, drate_ds, -ut

    def _atmosphere_maps(self, s: float, sat_pos_e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(AT.14): F(E_i) and exp(-h / H_T) m(E_i) at the track point s, (m,) each."""
        lat, lon, h = (float(c) for c in self.table.evaluate(s, self.table.GEO))
        up = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
        los = sat_pos_e - self.table.position_e(s)
        sin_e = (los @ up) / np.sqrt(np.einsum("mi,mi->m", los, los))
        obliquity, mapping, height = slant_maps(sin_e, self.atm_k, h, self.atm_scale_height)  # (TC.6)
        return obliquity, height * mapping

    def _update(self, obs: Any) -> tuple[float | None, int]:
        use = np.asarray(obs.valid, dtype=bool) & np.isfinite(obs.pseudorange_m)
        if not use.any():
            return None, 0
        opt = self.options
        x, P = self.x, self.P
        s, v = float(x[0]), float(x[1])
        if opt.update == "pseudorange":
            rho, rate, drho_ds, drate_ds, drate_dv = self._measurement_model(s, v, obs, use)
            m = int(use.sum())
            rows, ys, rs = [], [], []
            H: np.ndarray = np.zeros((m, self.n_x))
            H[:, 0] = drho_ds
            pred = rho.copy()
            if self.clock_states:
                H[:, 3] = 1.0
                pred = pred + x[3]
            if self.atmosphere:  # (AT.14)
                m_iono, m_tropo = self._atmosphere_maps(s, obs.sat_pos_e[use])
                H[:, 5], H[:, 6] = m_iono, m_tropo
                pred = pred + (self.atm_zenith0[0] + x[5]) * m_iono + (self.atm_zenith0[1] + x[6]) * m_tropo
            rows.append(H)
            ys.append(obs.pseudorange_m[use] - pred)  # (003 eq. 2) innovation
            rs.append(np.full(m, self.sigma_pr**2))
            if opt.use_doppler:
                Hd = np.zeros((m, self.n_x))
                Hd[:, 0], Hd[:, 1] = drate_ds, drate_dv
                pred_d = rate.copy()
                if self.clock_states:
                    Hd[:, 4] = 1.0
                    pred_d = pred_d + x[4]
                rows.append(Hd)
                ys.append(obs.pseudorange_rate_mps[use] - pred_d)  # (003 eq. 3)
                rs.append(np.full(m, self.sigma_rate**2))
            H, y, R = np.vstack(rows), np.concatenate(ys), np.concatenate(rs)
        else:
            from ..receiver import least_squares_fix, velocity_fix

            table = self.table
            r_guess = table.position_e(s)
            fix = least_squares_fix(obs.sat_pos_e, obs.pseudorange_m, use, initial=r_guess)
            if not fix.ok:
                return None, 0
            fix_imu = fix.position_e
            if table.has_antenna:  # (AT.10) the fix is the antenna's: back to the track
                fix_imu = fix_imu - table.evaluate(s, table.ANT)
            s_fix = table.project(fix_imu, s0=s)
            t_e = table.evaluate(s_fix, table.R_E, 1)
            t_e = t_e / np.linalg.norm(t_e)
            h_rows = [np.eye(self.n_x)[0]]
            y_list = [s_fix - s]
            r_list = [float(t_e @ fix.covariance[:3, :3] @ t_e) * self.sigma_pr**2]
            if opt.use_doppler:
                vfix = velocity_fix(obs.sat_pos_e, obs.sat_vel_e, obs.pseudorange_rate_mps, use, fix.position_e)
                if vfix.ok:
                    gain = 1.0  # d(t_e . v_antenna)/dv
                    if table.has_antenna:
                        gain = 1.0 + float(t_e @ table.evaluate(s, table.ANT, 1))
                    h_rows.append(np.eye(self.n_x)[1] * gain)
                    y_list.append(float(t_e @ vfix.velocity_e) - gain * v)
                    r_list.append(float(t_e @ vfix.covariance[:3, :3] @ t_e) * self.sigma_rate**2)
            H, y, R = np.array(h_rows), np.array(y_list), np.array(r_list)
        result = joseph_update(x, P, y, H, R)
        if result is None:
            self.diverged = True
            return None, 0
        self.x, self.P, nis = result
        self.n_updates += 1
        dof = len(y)
        self._bad_epochs = self._bad_epochs + 1 if nis / dof > opt.nis_divergence else 0
        if self._bad_epochs >= opt.divergence_epochs:
            self.diverged = True
        return nis, dof

    # ------------------------------------------------------------------ odometer
    def _odometer_due(self, ds: float | None, step: int) -> bool:
        """Accumulate one step's odometer distance; True when an update falls at its end."""
        if ds is None:
            self._odo_missing = True
        else:
            self._odo_sum += ds
        self._odo_n += 1
        return (step + 1) % self.odo_steps == 0

    def _odometer_update(self) -> tuple[float | None, int]:
        """(AT.12) at the current step, then the clone reset. Returns (nis, dof)."""
        x, P = self.x, self.P
        ic, ik = self.i_clone, self.i_scale
        spec = self.odo_spec
        nis = None
        if self._odo_n and not self._odo_missing:
            T = self._odo_n * self.dt
            D = self._odo_sum
            k = float(x[ik])
            span = float(x[0] - x[ic])
            H = np.zeros((1, self.n_x))
            H[0, 0], H[0, ic], H[0, ik] = 1.0 + k, -(1.0 + k), span
            R = spec.noise_density_m_per_sqrt_s**2 * T + spec.pulse_length_m**2 / 6.0
            if spec.slip_fraction > 0.0 and abs(float(x[1]) - self._odo_v0) > 0.9 * spec.slip_accel_threshold_mps2 * T:
                R += (spec.slip_fraction * D) ** 2
            R = max(R, 1e-12)
            result = joseph_update(x, P, np.array([D - (1.0 + k) * span]), H, np.array([R]))
            if result is None:
                self.diverged = True
            else:
                x, P, nis = result
                self.n_updates += 1
        # the clone restarts at s (its covariance rows become those of s)
        x = x.copy()
        x[ic] = x[0]
        P = P.copy()
        P[ic, :] = P[0, :]
        P[:, ic] = P[:, 0]
        P[ic, ic] = P[0, 0]
        self.x, self.P = x, P
        self._odo_sum, self._odo_n, self._odo_missing = 0.0, 0, False
        self._odo_v0 = float(x[1])
        self.odo_nis = math.nan if nis is None else nis
        return nis, (1 if nis is not None else 0)

    @staticmethod
    def _sum_nis(nis: float | None, dof: int, nis_o: float | None, dof_o: int) -> tuple[float | None, int]:
        """NIS of sequential updates in one step: the sum (independent innovations)."""
        if nis_o is None:
            return nis, dof
        if nis is None:
            return nis_o, dof_o
        return nis + nis_o, dof + dof_o

    # ------------------------------------------------------------------ output
    def _outputs(self, s: np.ndarray, v: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Solutions (k, 9) and 9 x 9 covariances (k, 9, 9) from states and covariances."""
        table, opt = self.table, self.options
        vals = table.evaluate(s, slice(3, 12))  # geodetic, tangent, heading, pitch, cant
        dt_n = table.evaluate(s, table.T_N, 1)
        t_n = vals[:, 3:6]
        w_n = table.rotation_per_m(s)
        heading = np.remainder(vals[:, 6] + math.pi, 2.0 * math.pi) - math.pi  # table heading is unwrapped
        sol = np.column_stack([vals[:, 0:3], v[:, None] * t_n, heading, vals[:, 7:9]])
        k = len(s)
        J = np.zeros((k, 9, self.n_x))
        J[:, 0:3, 0] = t_n  # dp = t_n ds
        J[:, 3:6, 0] = v[:, None] * dt_n  # dv_n = t_n dv + v dt_n/ds ds
        J[:, 3:6, 1] = t_n
        J[:, 6:9, 0] = w_n  # psi = w_n ds
        cov = _cov_two_columns(J[:, :, 0], J[:, :, 1], P)  # J P J^T: J has only the columns s, v
        att_floor = 0.0 if opt.attitude_floor_rad is None else opt.attitude_floor_rad**2
        floor = np.repeat([opt.position_floor_m**2, opt.velocity_floor_mps**2, att_floor], 3)
        cov = cov + np.diag(floor)
        if opt.attitude_floor_rad is None:  # attitude not estimated: the map's, not the body's
            cov[:, 6:9, :] = np.nan
            cov[:, :, 6:9] = np.nan
        return sol, cov

    def _interval_covariance(self, k: int, step: int) -> np.ndarray:
        """P at step k of the interval for :meth:`step`: :meth:`_covariance_at` of the steps
        from k to the next covariance boundary computed in one call on first use (the
        same per-step numbers as one call per step), then read one by one."""
        block = self._interval_block(k, step)
        return block[1][k - block[0]]

    def _interval_block(self, k: int, step: int) -> tuple[int, np.ndarray]:
        """``(first k, P(k) of the steps from it to the next covariance boundary)``, computed
        when step k is not in the block held."""
        block = self._P_block
        if block is None or not 0 <= k - block[0] < len(block[1]):
            rest = self.cov_steps - step % self.cov_steps  # steps up to the next boundary
            block = self._P_block = (k, self._covariance_at(np.arange(k, k + rest)))
        return block

    def _output_row(self, s: float, v: float, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_output_one` without the leading step axis: row (9,), covariance (9, 9)."""
        kern, tab, prm, _ = self._row_args or self._row_setup()
        if kern is None:
            sol, cov = self._output_one(s, v, P)
            return sol[0], cov[0]
        sol = np.empty(9)
        cov = np.empty((9, 9))
        kern(tab, prm, s, v, P, sol, cov)
        return sol, cov

    def _row_setup(self) -> tuple:
        """The step path's compiled kernels and their fixed arguments (once per reset):
        (:func:`_output_row` kernel or None, the map table as one array :func:`_row_table`,
        the parameters :func:`_row_params`, :func:`_step_row` kernel or None)."""
        table = self.table
        assert table is not None  # set by reset
        floor = self._output_floor().copy()
        if self.options.attitude_floor_rad is None:  # NaN + x is NaN: _output_one's NaN entries
            floor[6:9, :] = np.nan
            floor[:, 6:9] = np.nan
        prm = _row_params(table, self.dt, self.decay, self.clock_states, floor)
        fused = None if self.use_odometer else _step_row_kernel()  # the odometer's steps: the general path
        row = self._row_args = (_output_row_kernel(), _row_table(table), prm, fused)
        return row

    def _output_floor(self) -> np.ndarray:
        """The floors of :meth:`_outputs` (9, 9), fixed by the options."""
        opt = self.options
        att_floor = 0.0 if opt.attitude_floor_rad is None else opt.attitude_floor_rad**2
        self._floor = np.diag(np.repeat([opt.position_floor_m**2, opt.velocity_floor_mps**2, att_floor], 3))
        return self._floor

    def _output_one(self, s: float, v: float, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_outputs` of one state on Python floats (the same operations); the map
        interpolation and the Jacobian J in one compiled call when numba is installed
        (:func:`_map_row`, the same operations again), the covariance by :func:`_cov_two_columns`."""
        table, opt = self.table, self.options
        kern = _map_row_kernel()
        if kern is not None:
            sol = np.empty((1, 9))
            J = np.zeros((9, self.n_x))
            tab, prm = (self._row_args or self._row_setup())[1:3]
            kern(tab, int(prm[7]), table.length, table._inv, table._n, table.step, s, v, sol, J)
            floor = self.__dict__.get("_floor")
            if floor is None:  # the floors of _outputs, fixed by the options
                floor = self._output_floor()
            cov = (_cov_two_columns(J[:, 0], J[:, 1], P) + floor)[None]
            if opt.attitude_floor_rad is None:
                cov[:, 6:9, :] = np.nan
                cov[:, :, 6:9] = np.nan
            return sol, cov
        x = min(max(s, 0.0), table.length) * table._inv
        i = min(int(x), table._n - 2)
        u = x - i
        step, inv = table.step, table._inv
        y0, y1 = table.values[i, 3:12].tolist(), table.values[i + 1, 3:12].tolist()
        d0 = [d * step for d in table.derivs[i, 3:12].tolist()]
        d1 = [d * step for d in table.derivs[i + 1, 3:12].tolist()]
        uu = u * u
        w2 = (1 - u) * (1 - u)  # numpy's x ** 2 is x * x (Python's calls pow)
        h00, h10, h01, h11 = (1 + 2 * u) * w2, u * w2, uu * (3 - 2 * u), uu * (u - 1)
        vals = [h00 * y0[j] + h10 * d0[j] + h01 * y1[j] + h11 * d1[j] for j in range(9)]
        g00, g10, g01, g11 = 6 * uu - 6 * u, 3 * uu - 4 * u + 1, 6 * u - 6 * uu, 3 * uu - 2 * u
        dt_n = [(g00 * y0[j] + g10 * d0[j] + g01 * y1[j] + g11 * d1[j]) * inv for j in range(3, 6)]
        w0, w1 = table.w_n[i].tolist(), table.w_n[i + 1].tolist()
        w_n = [(1 - u) * w0[j] + u * w1[j] for j in range(3)]
        t_n = vals[3:6]
        heading = (vals[6] + math.pi) % (2.0 * math.pi) - math.pi  # np.remainder: Python's %
        sol = np.array([[vals[0], vals[1], vals[2], v * t_n[0], v * t_n[1], v * t_n[2], heading, vals[7], vals[8]]])
        pad = [0.0] * (self.n_x - 2)
        J = np.array([[t_n[0], 0.0, *pad], [t_n[1], 0.0, *pad], [t_n[2], 0.0, *pad],
                      [v * dt_n[0], t_n[0], *pad], [v * dt_n[1], t_n[1], *pad], [v * dt_n[2], t_n[2], *pad],
                      [w_n[0], 0.0, *pad], [w_n[1], 0.0, *pad], [w_n[2], 0.0, *pad]])
        floor = self.__dict__.get("_floor")
        if floor is None:  # the floors of _outputs, fixed by the options
            att_floor = 0.0 if opt.attitude_floor_rad is None else opt.attitude_floor_rad**2
            floor = self._floor = np.diag(np.repeat([opt.position_floor_m**2, opt.velocity_floor_mps**2, att_floor], 3))
        cov = (_cov_two_columns(J[:, 0], J[:, 1], P) + floor)[None]  # the operations of each row of _outputs
        if opt.attitude_floor_rad is None:
            cov[:, 6:9, :] = np.nan
            cov[:, :, 6:9] = np.nan
        return sol, cov

    def _check_health(self) -> None:
        d = np.diag(self.P)
        if not (np.all(np.isfinite(self.P)) and np.all(d >= -1e-12)):
            self.diverged = True

    def _extra(self, nis: float | None, dof: int) -> dict:
        x = self.x
        extra = {"s": float(x[0]), "speed": float(x[1]), "accel_bias": float(x[2]),
                 "sigma_s": math.sqrt(max(self.P[0, 0], 0.0)), "sigma_v": math.sqrt(max(self.P[1, 1], 0.0)),
                 "diverged": self.diverged, "n_updates": self.n_updates}
        if self.clock_states:
            extra["clock_bias_m"], extra["clock_drift_mps"] = float(x[3]), float(x[4])
        if self.use_odometer:
            extra["odometer_scale"] = float(x[self.i_scale])
            extra["odometer_nis"] = self.odo_nis
        return extra

    # ------------------------------------------------------------------ step
    def _advance(self, dv_y: float, ds2_y: float, obs: Any, step: int,
                 odometer_ds: float | None = None) -> tuple[np.ndarray | None, float | None, int]:
        """One step: mean, covariance at the step end, optional update. Returns (P, nis, dof)."""
        self._propagate_mean(dv_y, ds2_y)
        self.k_in += 1
        nis, dof = None, 0
        odo_due = self.use_odometer and self._odometer_due(odometer_ds, step)
        boundary = obs is not None or (step + 1) % self.cov_steps == 0 or odo_due
        if not boundary:
            return None, nis, dof
        block = self._P_block  # P(k) of the interval computed ahead (_interval_covariance), as step_batch's block
        if block is not None and 0 <= self.k_in - block[0] < len(block[1]):
            self.P = block[1][self.k_in - block[0]]
        else:
            self.P = self._covariance_at(np.array([self.k_in]))[0]
        if obs is not None:
            nis, dof = self._update(obs)
            self._check_health()
        if odo_due:
            nis, dof = self._sum_nis(nis, dof, *self._odometer_update())
            self._check_health()
        self._start_interval()
        return self.P, nis, dof

    def _step_one(self, measurement: Measurement) -> tuple[np.ndarray, np.ndarray, float | None, int]:
        """One navigation step by the general path (the mean on Python floats, then the
        boundary's covariance, update and odometer, or the interval's P): (solution row (9,),
        covariance (9, 9), nis, dof)."""
        dv = np.asarray(measurement.dv_r, dtype=float).tolist()  # body-y increments, floats (_along_increments)
        dv_y = dv[0][1]
        ds2_y = dv[1][1] if len(dv) >= 2 else 0.5 * self.dt * dv_y
        P, nis, dof = self._advance(dv_y, ds2_y, measurement.gnss, measurement.step,
                                    getattr(measurement, "odometer_ds_m", None))
        if P is None:  # between covariance boundaries: P(k) of the interval, computed ahead
            P = self._interval_covariance(self.k_in, measurement.step)
        self.t = measurement.t
        x = self.x.tolist()
        sol, cov = self._output_row(x[0], x[1], P)
        self._last_extra = None
        return sol, cov, nis, dof

    @property
    def last_extra(self) -> dict:
        """The diagnostics of the last step (s, speed, bias, sigmas, clock, ...), gathered
        on reading."""
        extra = self._last_extra
        if extra is None:
            extra = self._last_extra = self._extra(None, 0)
        return extra

    @last_extra.setter
    def last_extra(self, value: dict) -> None:
        self._last_extra = value

    def step_row(self, measurement: Measurement) -> StepRow:
        """:meth:`step` as ``(row (9,), covariance (9, 9), nis, nis_dof)`` (the
        :class:`~navsim.estimators.base.RowStepping` protocol): the same numbers, no
        :class:`Estimate` built.

        A step without a GNSS epoch that ends inside a covariance interval (and with no
        odometer) is one compiled call (:func:`_step_row`: the mean (AT.3)-(AT.7) and the
        output row at the interval's P(k), which depends on k only and comes from the block
        of :meth:`_interval_covariance`); every other step takes :meth:`_step_one`."""
        args = self._row_args or self._row_setup()
        fused = args[3]
        if fused is not None and measurement.gnss is None:
            step = measurement.step
            if (step + 1) % self.cov_steps:  # no covariance boundary at the step end
                k = self.k_in + 1
                block = self._P_block
                if block is None or not 0 <= k - block[0] < len(block[1]):
                    block = self._interval_block(k, step)
                dv_r = measurement.dv_r
                if type(dv_r) is not np.ndarray:
                    dv_r = np.asarray(dv_r, dtype=float)
                sol = np.empty(9)
                cov = np.empty((9, 9))
                if fused(args[1], args[2], self.x, dv_r, block[1], k - block[0], sol, cov) == 0:
                    self.k_in = k
                    self.t = measurement.t
                    self._last_extra = None
                    return sol, cov, None, None
        sol, cov, nis, dof = self._step_one(measurement)
        return sol, cov, nis, dof if nis is not None else None

    def step(self, measurement: Measurement) -> Estimate:
        """Process one navigation step (see the module docstring for the equations)."""
        s, cov, nis, dof = self.step_row(measurement)
        lat, lon, h, _, _, _, heading, pitch, roll = s.tolist()  # floats, not NumPy scalars
        return Estimate(t=measurement.t, lat=lat, lon=lon, h=h, velocity_n=s[3:6], heading=heading, pitch=pitch,
                        roll=roll, covariance=cov, nis=nis, nis_dof=dof, extra=self.last_extra)

    def step_batch(self, batch: MeasurementBatch) -> EstimateBatch:
        """n steps at once; the same numbers as repeated :meth:`step`."""
        n = len(batch)
        dv_y, ds2_y = self._along_increments(np.asarray(batch.dv_r, dtype=float), self.dt)
        dv_y, ds2_y = dv_y.tolist(), ds2_y.tolist()
        epochs = dict(batch.gnss)
        steps = np.asarray(batch.step).tolist()
        s_out = np.empty(n)
        v_out = np.empty(n)
        P_out = np.empty((n, self.n_x, self.n_x))
        nis_out = np.full(n, np.nan)
        dof_out = np.zeros(n, dtype=int)
        pending: list[int] = []  # steps of the current interval whose P is computed in one go
        pending_k: list[int] = []
        gravity_along = self.table.gravity_along
        dt, decay, clock = self.dt, self.decay, self.clock_states
        odo = self.use_odometer
        odo_ds: list = []
        if odo:
            raw = getattr(batch, "odometer_ds_m", None)
            odo_ds = [None] * n if raw is None else np.asarray(raw, dtype=float).tolist()
        half_dt, half_dt2 = 0.5 * dt, 0.5 * dt * dt
        x = self.x
        s, v, b = float(x[0]), float(x[1]), float(x[2])
        cb, cd = (float(x[3]), float(x[4])) if clock else (0.0, 0.0)
        for i in range(n):
            # the arithmetic of _propagate_mean on Python floats: (AT.5)-(AT.7), (AT.3), (AT.4)
            a = gravity_along(s + half_dt * v) - b
            s, v = s + v * dt + ds2_y[i] + half_dt2 * a, v + dv_y[i] + a * dt
            b = b * decay
            if clock:
                cb = cb + cd * dt
            self.k_in += 1
            s_out[i], v_out[i] = s, v
            pending.append(i)
            pending_k.append(self.k_in)
            obs = epochs.get(i)
            odo_due = odo and self._odometer_due(odo_ds[i], steps[i])
            if obs is None and not odo_due and (steps[i] + 1) % self.cov_steps != 0:
                continue
            x[0], x[1], x[2] = s, v, b
            if clock:
                x[3], x[4] = cb, cd
            P_block = self._covariance_at(np.array(pending_k))
            P_out[pending] = P_block
            self.P = P_block[-1]
            pending, pending_k = [], []
            if obs is not None:
                nis, dof = self._update(obs)
                self._check_health()
                x = self.x
                if nis is not None:
                    nis_out[i], dof_out[i] = nis, dof
                    P_out[i] = self.P
                    s_out[i], v_out[i] = x[0], x[1]
                s, v, b = float(x[0]), float(x[1]), float(x[2])
                if clock:
                    cb, cd = float(x[3]), float(x[4])
            if odo_due:
                nis_o, dof_o = self._odometer_update()
                self._check_health()
                x = self.x
                if nis_o is not None:
                    prev = None if math.isnan(nis_out[i]) else float(nis_out[i])
                    nis_out[i], dof_out[i] = self._sum_nis(prev, int(dof_out[i]), nis_o, dof_o)
                    s_out[i], v_out[i] = x[0], x[1]
                P_out[i] = self.P
                s, v, b = float(x[0]), float(x[1]), float(x[2])
                if clock:
                    cb, cd = float(x[3]), float(x[4])
            self._start_interval()
        x[0], x[1], x[2] = s, v, b
        if clock:
            x[3], x[4] = cb, cd
        if pending:
            P_out[pending] = self._covariance_at(np.array(pending_k))
        sol, cov = self._outputs(s_out, v_out, P_out)
        self.t = float(batch.t[-1])
        self.last_extra = self._extra(None, 0)
        return EstimateBatch(solution=sol, covariance=cov, nis=nis_out, nis_dof=dof_out)


def _row_table(table: TrackTable) -> np.ndarray:
    """The map table of the compiled row kernels as one (n, 2 c + 5) array: the c columns of
    ``table.values``, the c of ``table.derivs``, ``w_n`` (3), ``g_t`` and ``d g_t/ds`` times
    the node step (the lists of :meth:`TrackTable.gravity_along`): the same floats, one
    argument instead of five."""
    return np.ascontiguousarray(np.column_stack([table.values, table.derivs, table.w_n, np.array(table._g),
                                                 np.array(table._dg)]), dtype=float)


def _row_params(table: TrackTable, dt: float, decay: float, clock: bool, floor: np.ndarray) -> np.ndarray:
    """The fixed parameters of the row kernels, (89,): table length, 1 / node step, nodes,
    node step, dt, the Gauss-Markov decay, clock states 0/1, the column count c of
    ``table.values``, then the 9 x 9 output floor row by row."""
    head = [table.length, table._inv, table._n, table.step, dt, decay, 1.0 if clock else 0.0,
            table.values.shape[1]]
    return np.concatenate([np.array(head, dtype=float), np.asarray(floor, dtype=float).ravel()])


def _map_row(tab: np.ndarray, nc: int, length: float, inv: float, n: int, step: float, s: float, v: float,
             sol: np.ndarray, J: np.ndarray) -> None:
    """The map interpolation of :meth:`AlongTrackFilter._output_one` at arc length ``s`` and
    speed ``v`` (cubic Hermite on the table, linear in the rotation rates): fills ``sol``
    (1, 9) and the nonzero columns 0, 1 of ``J`` (9, n_x). ``tab`` is :func:`_row_table`
    (values in columns ``[0, nc)``, derivatives in ``[nc, 2 nc)``, ``w_n`` in ``[2 nc, 2 nc + 3)``).
    The same operations in the same order as the float form there (compiled by numba:
    :func:`_map_row_kernel`)."""
    x = min(max(s, 0.0), length) * inv
    i = min(int(x), n - 2) if x == x else 0  # NaN s: node 0 (u is NaN, so is every output), no read off the table
    u = x - i
    uu = u * u
    w2 = (1 - u) * (1 - u)
    h00, h10, h01, h11 = (1 + 2 * u) * w2, u * w2, uu * (3 - 2 * u), uu * (u - 1)
    g00, g10, g01, g11 = 6 * uu - 6 * u, 3 * uu - 4 * u + 1, 6 * u - 6 * uu, 3 * uu - 2 * u
    vals = np.empty(9)
    dt_n = np.empty(3)
    for j in range(9):
        y0, y1 = tab[i, 3 + j], tab[i + 1, 3 + j]
        d0, d1 = tab[i, nc + 3 + j] * step, tab[i + 1, nc + 3 + j] * step
        vals[j] = h00 * y0 + h10 * d0 + h01 * y1 + h11 * d1
        if 3 <= j < 6:
            dt_n[j - 3] = (g00 * y0 + g10 * d0 + g01 * y1 + g11 * d1) * inv
    heading = (vals[6] + math.pi) % (2.0 * math.pi) - math.pi
    sol[0, 0], sol[0, 1], sol[0, 2] = vals[0], vals[1], vals[2]
    sol[0, 3], sol[0, 4], sol[0, 5] = v * vals[3], v * vals[4], v * vals[5]
    sol[0, 6], sol[0, 7], sol[0, 8] = heading, vals[7], vals[8]
    w = 2 * nc
    for j in range(3):
        J[j, 0] = vals[3 + j]
        J[3 + j, 0] = v * dt_n[j]
        J[3 + j, 1] = vals[3 + j]
        J[6 + j, 0] = (1 - u) * tab[i, w + j] + u * tab[i + 1, w + j]


def _cov_two_columns(j0: np.ndarray, j1: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``J P J^T`` for a Jacobian J (..., 9, n) whose only nonzero columns are 0 and 1 (s and
    v), given as ``j0``, ``j1`` (..., 9), and P (..., n, n): ``(J P)[:, b] = j0 P[0, b] + j1 P[1, b]``,
    then ``cov[r, q] = (J P)[r, 0] j0[q] + (J P)[r, 1] j1[q]`` (the zero columns left out; the
    same operations, in the same order, as :func:`_output_row`'s loops)."""
    a0 = j0 * P[..., 0, 0, None] + j1 * P[..., 1, 0, None]
    a1 = j0 * P[..., 0, 1, None] + j1 * P[..., 1, 1, None]
    return a0[..., :, None] * j0[..., None, :] + a1[..., :, None] * j1[..., None, :]


def _output_row(tab: np.ndarray, prm: np.ndarray, s: float, v: float, P: np.ndarray, sol: np.ndarray,
                cov: np.ndarray) -> None:
    """One output row of :class:`AlongTrackFilter` (compiled, :func:`_output_row_kernel`): the
    solution (9,) by :func:`_map_row` and the covariance ``J P J^T + floor`` (9, 9) by the
    operations of :func:`_cov_two_columns`. ``tab``: :func:`_row_table`; ``prm``:
    :func:`_row_params` (the floor is its entries 8 to 88)."""
    J = np.zeros((9, 2))
    _map_row(tab, int(prm[7]), prm[0], prm[1], int(prm[2]), prm[3], s, v, sol.reshape((1, 9)), J)
    p00, p01, p10, p11 = P[0, 0], P[0, 1], P[1, 0], P[1, 1]
    a0 = np.empty(9)
    a1 = np.empty(9)
    for r in range(9):
        a0[r] = J[r, 0] * p00 + J[r, 1] * p10
        a1[r] = J[r, 0] * p01 + J[r, 1] * p11
    for r in range(9):
        for q in range(9):
            cov[r, q] = (a0[r] * J[q, 0] + a1[r] * J[q, 1]) + prm[8 + 9 * r + q]


def _step_row(tab: np.ndarray, prm: np.ndarray, x: np.ndarray, dv_r: np.ndarray, P_block: np.ndarray, j: int,
              sol: np.ndarray, cov: np.ndarray) -> int:
    """One step of :class:`AlongTrackFilter` between covariance boundaries (compiled,
    :func:`_step_row_kernel`): the mean (AT.3)-(AT.7) of ``_propagate_mean`` with
    ``TrackTable.gravity_along`` (the same float operations in the same order, ``x`` in
    place), then :func:`_output_row` at the new (s, v) with the interval's P, entry ``j``
    of ``P_block`` (:meth:`AlongTrackFilter._interval_covariance`). ``tab``: :func:`_row_table`
    (``g_t`` and ``d g_t/ds`` times the node step in its last two columns); ``prm``:
    :func:`_row_params`. Returns 1, x unchanged, when the mid-step arc length is not finite
    (the Python path then runs and raises as before), else 0."""
    length, inv, n, dt = prm[0], prm[1], int(prm[2]), prm[4]
    cg = 2 * int(prm[7]) + 3  # the g_t column; d g_t/ds * step next to it
    dv_y = dv_r[0, 1]
    ds2_y = dv_r[1, 1] if dv_r.shape[0] >= 2 else 0.5 * dt * dv_y
    s, v, b = x[0], x[1], x[2]
    sm = s + 0.5 * dt * v
    if not math.isfinite(sm):
        return 1
    xs = min(max(sm, 0.0), length) * inv  # gravity_along(sm)
    i = min(int(xs), n - 2)
    u = xs - i
    w = 1.0 - u
    grav = ((1 + 2 * u) * w * w * tab[i, cg] + u * w * w * tab[i, cg + 1]
            + u * u * (3 - 2 * u) * tab[i + 1, cg] + u * u * (u - 1) * tab[i + 1, cg + 1])
    a = grav - b  # (AT.5) mid-step grade
    x[1] = v + dv_y + a * dt  # (AT.6)
    x[0] = s + v * dt + ds2_y + 0.5 * dt * dt * a  # (AT.7)
    x[2] = b * prm[5]  # (AT.3) Gauss-Markov mean
    if prm[6] != 0.0:
        x[3] = x[3] + x[4] * dt  # (AT.4)
    _output_row(tab, prm, x[0], x[1], P_block[j], sol, cov)
    return 0


# The compiled row kernels and the kernel each one calls (compiled first, then put in the
# module's globals so that numba resolves the call to the compiled function).
_CALLS: dict[str, str | None] = {"_map_row": None, "_output_row": "_map_row", "_step_row": "_output_row"}
_KERNELS: dict[str, Any] = {}


def _row_kernel(name: str) -> Any:
    """The function ``name`` of :data:`_CALLS` compiled by numba (cached on disk, made once
    per process), or None without numba."""
    if name not in _KERNELS:
        from ..strapdown import compiled

        callee = _CALLS[name]
        if not compiled.available():
            _KERNELS[name] = None
        else:
            import numba

            if callee is not None:
                globals()[callee] = _row_kernel(callee)
            _KERNELS[name] = numba.njit(cache=True, nogil=True)(globals()[name])
    return _KERNELS[name]


def _map_row_kernel() -> Any:
    """:func:`_map_row` compiled, or None without numba."""
    return _row_kernel("_map_row")


def _output_row_kernel() -> Any:
    """:func:`_output_row` compiled (it calls the compiled :func:`_map_row`), or None."""
    return _row_kernel("_output_row")


def _step_row_kernel() -> Any:
    """:func:`_step_row` compiled (it calls the compiled :func:`_output_row`), or None."""
    return _row_kernel("_step_row")
