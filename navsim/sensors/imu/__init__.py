"""IMU outputs: multiple integrals of the true motion and the truth-side error model.

The IMU of navsim delivers, per sample of length ``h`` ending at ``t_k + h``,

* the increments of the *multiple integrals* of seed 000, eq. (1.14)::

      dtheta_r[k, r-1] = int_{t_k}^{t_k+h} int_{t_k}^{tau_1} ... omega_ib_b(tau_r) dtau_r ... dtau_1

  and the same ``dv_r`` for the specific force ``f_b``; by Cauchy's formula for repeated
  integration the r-fold integral is ``int_{t_k}^{t_k+h} (t_k + h - tau)^(r-1)/(r-1)! g(tau)
  dtau``. ``dtheta_r[..., 0, :]`` is the ordinary increment (quasi-coordinate) ΔΘ;
* the rate-type outputs ``rate_b`` and ``accel_b`` at the sample instant ``t_k + h``.

True multiple integrals
-----------------------
:func:`multiple_integral_rule` gives Gauss-Legendre nodes and weights for all orders at
once, so the simulator evaluates the true rate and specific force at ``n_nodes`` instants
per sample and gets every ``dtheta_r`` to machine precision for smooth motion (exact for
polynomials of degree ``<= 2 n_nodes - r``; take ``n_nodes >= R + 2``, see the table
there). :func:`compose_multiple_integrals` builds the multiple integrals over a step of
``m`` samples exactly from the per-sample ones, and
:func:`harmonic_multiple_integrals` is the closed form for ``A sin(2 pi f t + phase)``
(vibration harmonics, tests).

Truth-side error model
----------------------
:class:`ImuErrorModel` (a gyro and an accelerometer :class:`SensorErrors` plus the gyro
g-sensitivity) is applied by :func:`apply_imu_errors` in the increment domain, for every
order r at once:

======================================  ====================================================
error                                   effect on the r-fold integral over one sample
======================================  ====================================================
scale factor ``S``, misalignment ``M``  ``(I + diag(S) + M) @ true_r`` (exact: linear)
gyro g-sensitivity ``G``                ``+ G @ dv_r(true)`` (exact)
bias ``b`` (constant, turn-on,          ``+ b h^r / r!``; Gauss-Markov and rate-random-walk
Gauss-Markov, rate random walk)         parts are held constant within a sample (below)
vibration ``A sin(2 pi f t + phi)``     closed-form r-fold integral (exact)
white noise of PSD ``q``                exact Gaussian vector of the R integrals, covariance
                                        ``q h^(i+j-1) / ((i+j-1) (i-1)! (j-1)!)``
quantization (LSB of ``dtheta_1``)      per output level, with residual carry (below)
======================================  ====================================================

Approximations and choices, stated once:

* **Gauss-Markov bias and rate random walk** are propagated exactly between sample
  boundaries (``b_{k+1} = exp(-h/tau) b_k + sigma sqrt(1 - exp(-2h/tau)) z``;
  ``b_{k+1} = b_k + N sqrt(h) z``) and held constant within a sample. The neglected
  within-sample wander has, on ``dtheta_1``, a standard deviation of
  ``sigma h sqrt(2 h / (3 tau))`` (Gauss-Markov, ``h << tau``) resp. ``N h^1.5 / sqrt(3)``
  (rate random walk): for the "navigation" preset at 100 Hz that is ~9e-13 rad, five
  orders below the angle-random-walk contribution ``ARW sqrt(h)`` ~ 9e-8 rad of the same
  sample.
* **Time as float64**: harmonics are evaluated at the phase ``omega t + phase`` from the
  float sample times, whose absolute error ``~ eps omega t`` is inherent (2.7e-12 relative
  at ``omega t ~ 1.6e3`` rad).
* **Rate-type outputs** carry the same error realisation as the increments: the bias and
  vibration values at the sample instant, and as white noise the *sample average* of the
  same white-noise realisation, ``noise(dtheta_1) / h``, i.e. white noise band-limited to
  the sample rate with ``sigma = sqrt(PSD / h)``.
* **Quantization**: ``quantization_lsb`` is the LSB of the first-order increment (rad,
  m/s). The r-fold integral output has LSB ``lsb h^(r-1)`` (a digital r-fold accumulator
  clocked at the sample period) and the rate output ``lsb / h``. Each output level and axis
  has its own residual carry, so the running sum of quantized outputs tracks the running
  sum of unquantized ones to within half an LSB forever. To vectorise it exactly, the
  carry is kept as an accumulator and an emitted count, and the accumulator is
  renormalised at fixed *global* sample indices (every ``QUANTIZATION_BLOCK`` samples),
  which keeps the result independent of how the samples are chunked.
* Scale factor and misalignment act on the true motion only, not on the other errors.

Randomness: :meth:`ImuState.initial` draws one ``(2, 2, 3)`` block (turn-on biases and the
stationary start of the Gauss-Markov states) and :func:`apply_imu_errors` draws one block
``rng.standard_normal((n, 6 (R + 2)))`` per call, whose width depends only on the number
R of integral orders, never on which errors are switched on. Rows are samples in time
order; columns are ``[sensor (gyro, accel)][slot (R white-noise integrals, Gauss-Markov
drive, rate-random-walk drive)][axis]``. So turning one error off changes no other draw
and chunking changes nothing (every recursive quantity lives in :class:`ImuState`).

References
----------
.. [1] Litmanovich Yu.A., "Determining the parameters of angular and translational motion
   of a rigid body from inertial information in the form of increments of multiple
   integrals of the measured quantities", 2002 (seed 000): eq. (1.14), section 6
   (pseudo-coning and pseudo-sculling from high-frequency harmonics).
.. [2] Sokolov S.V., Vdovichenko V.A., 2012 (seed 003): white-noise accelerometer
   intensity (1e-5 m/s^2)^2 of the worked example.
.. [3] Groves P.D., *Principles of GNSS, Inertial, and Multisensor Integrated Navigation
   Systems*, 2nd ed., Artech House, 2013: section 4.4 (IMU error model, quantization with
   residual carry); the IMU configurations of the book's MATLAB demos (BSD licence):
   consumer, tactical and aviation grade.
.. [4] i2Nav-WHU, KF-GINS / awesome-gins-datasets: tuned noise figures of the ICM-20602
   and ADIS16465 (ARW, VRW, Gauss-Markov bias sigma, 1 h correlation time); Leador-A15
   navigation-grade IMU (ARW 0.003 deg/sqrt(h), gyro bias instability 0.027 deg/h, VRW
   0.03 m/s/sqrt(h), accelerometer bias instability 15 mGal, correlation time 4 h) as
   quoted in the KF-GINS paper (GPS Solutions, 2025).
.. [5] IEEE Std 952-1997 / 1293-1998: ARW, rate random walk and bias instability as
   noise terms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import cholesky, hilbert

from ...errors import ConfigError
from . import kernel as _imu_kernel
from .._common import frozen_array

if TYPE_CHECKING:
    from ...types import NominalImu

__all__ = [
    "is_error_free",
    "MAX_ORDER",
    "QUANTIZATION_BLOCK",
    "PRESET_NAMES",
    "multiple_integral_rule",
    "apply_multiple_integral_rule",
    "compose_multiple_integrals",
    "harmonic_multiple_integrals",
    "white_noise_integral_covariance",
    "VibrationHarmonic",
    "SensorErrors",
    "ImuErrorModel",
    "ImuState",
    "ImuOutput",
    "apply_imu_errors",
    "apply_imu_errors_batch",
    "imu_preset",
    "nominal_noise",
    "nominal_imu",
    "first_order_recursion",
]

MAX_ORDER = 8
"""Largest number R of multiple-integral orders the error model handles."""

USE_KERNEL = True
"""Use the compiled white-noise pass when numba is installed (:mod:`navsim.sensors.imu.kernel`;
the numbers are the same either way)."""

QUANTIZATION_BLOCK = 1024
"""Quantizer accumulators are renormalised every this many samples (global index)."""

_SERIES_RADIUS = 3.0  # |i omega h| below which the phi functions use their power series

# Unit conversions used by the presets (SI inside).
_DEG = math.pi / 180.0
_DEG_PER_HOUR = _DEG / 3600.0  # deg/h -> rad/s
_DEG_PER_SQRT_HOUR = _DEG / 60.0  # deg/sqrt(h) -> rad/sqrt(s)
_PER_SQRT_HOUR = 1.0 / 60.0  # m/s/sqrt(h) -> m/s/sqrt(s)
_MICRO_G = 9.80665e-6  # micro-g -> m/s^2
_MGAL = 1.0e-5  # milligal -> m/s^2
_PPM = 1.0e-6
_DEG_PER_HOUR_PER_G = _DEG_PER_HOUR / 9.80665  # deg/h/g -> rad/s per m/s^2


# --------------------------------------------------------------------------------------
# True multiple integrals
# --------------------------------------------------------------------------------------


def _check_int(name: str, value: Any, low: int, high: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ConfigError(name, "an integer", value)
    if value < low or (high is not None and value > high):
        expect = f"an integer >= {low}" if high is None else f"an integer in [{low}, {high}]"
        raise ConfigError(name, expect, value)
    return int(value)


def _check_h(h: Any) -> float:
    try:
        value = float(h)
    except (TypeError, ValueError):
        raise ConfigError("h", "a positive sample length in s", h) from None
    if not (0.0 < value < math.inf):
        raise ConfigError("h", "a positive finite sample length in s", h)
    return value


def multiple_integral_rule(
    n_nodes: int = 4, order: int = 4
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gauss-Legendre rule for the r-fold integrals (1.14) over one sample.

    By Cauchy's formula the r-fold integral of ``g`` over ``[t_k, t_k + h]`` is
    ``h^r int_0^1 (1 - s)^(r-1) / (r-1)! g(t_k + s h) ds``; the rule applies the
    Gauss-Legendre nodes of ``[0, 1]`` to that integrand, so::

        I_r ~= h^r * sum_j weights[r-1, j] * g(t_k + nodes[j] * h)

    which is exact when ``g`` is a polynomial of degree ``<= 2 n_nodes - r``. The error
    on a harmonic of angular frequency ``omega`` scales as ``(omega h)^(2 n_nodes - r + 1)``;
    measured worst relative errors for R = 4 (order 1 .. 4):

    ==========  ===================  ===================  ===================
    omega h     n_nodes = 4          n_nodes = 5          n_nodes = 6
    ==========  ===================  ===================  ===================
    0.063       7e-16 .. 7.5e-13     ~1e-15               ~1e-15
    0.2         2e-15 .. 2.4e-10     6e-16 .. 1.5e-14     ~1e-15
    0.8         1e-10 .. 2.5e-7      4e-14 .. 2.4e-10     1e-15 .. 1.4e-13
    ==========  ===================  ===================  ===================

    so for machine precision on the higher orders use ``n_nodes >= R + 2`` (6 for R = 4)
    when the motion has content up to ``omega h ~ 0.2``.

    Parameters
    ----------
    n_nodes : int
        Number of nodes per sample (>= 1).
    order : int
        Number R of integral orders (1 <= R <= ``MAX_ORDER``).

    Returns
    -------
    nodes : ndarray, shape (n_nodes,)
        Fractions ``tau_j`` of the sample, in (0, 1), increasing.
    weights : ndarray, shape (order, n_nodes)
        ``weights[r-1, j] = w_j (1 - tau_j)^(r-1) / (r-1)!``.
    """
    n_nodes = _check_int("n_nodes", n_nodes, 1)
    order = _check_int("order", order, 1, MAX_ORDER)
    x, w = np.polynomial.legendre.leggauss(n_nodes)
    nodes = 0.5 * (x + 1.0)
    w01 = 0.5 * w
    r_minus_1 = np.arange(order)
    inv_fact = 1.0 / np.array([math.factorial(k) for k in r_minus_1], dtype=float)
    # (1.14) via Cauchy: kernel (1 - s)^(r-1) / (r-1)!
    weights = w01[None, :] * (1.0 - nodes)[None, :] ** r_minus_1[:, None] * inv_fact[:, None]
    return nodes, weights


def apply_multiple_integral_rule(
    values: ArrayLike, h: float, weights: ArrayLike
) -> NDArray[np.float64]:
    """Multiple integrals from the values of ``g`` at the nodes of each sample.

    Parameters
    ----------
    values : array_like, shape (n, n_nodes, 3)
        ``g(t_k + nodes[j] h)`` for each sample ``k`` (units of g).
    h : float
        Sample length, s.
    weights : array_like, shape (R, n_nodes)
        From :func:`multiple_integral_rule`.

    Returns
    -------
    ndarray, shape (n, R, 3)
        ``I_r`` in units of g times s^r.
    """
    h = _check_h(h)
    values = np.asarray(values, dtype=float)
    weights = np.asarray(weights, dtype=float)
    if values.ndim != 3 or weights.ndim != 2 or values.shape[1] != weights.shape[1]:
        raise ConfigError(
            "values", f"shape (n, {weights.shape[-1]}, 3) matching weights", values.shape
        )
    h_pow = h ** np.arange(1, weights.shape[0] + 1)
    return np.einsum("rj,nja->nra", weights * h_pow[:, None], values)


def compose_multiple_integrals(sub: ArrayLike, h: float) -> NDArray[np.float64]:
    """Multiple integrals over a step of ``m`` consecutive samples, from per-sample ones.

    With the step ending at ``T = t_0 + m h`` and sample ``j`` ending at
    ``e_j = t_0 + (j + 1) h``, the binomial expansion of the Cauchy kernel
    ``(T - tau)^(r-1) / (r-1)! = sum_q (e_j - tau)^(q-1)/(q-1)! d_j^(r-q)/(r-q)!`` with
    ``d_j = T - e_j`` gives the exact relation::

        I_r(step) = sum_j sum_{q=1..r} I_q(sample j) d_j^(r-q) / (r-q)!

    Parameters
    ----------
    sub : array_like, shape (n, m, R, 3)
        Per-sample r-fold integrals of ``n`` steps of ``m`` samples each.
    h : float
        Sample length, s.

    Returns
    -------
    ndarray, shape (n, R, 3)
        The r-fold integrals over each step of length ``m h``.
    """
    h = _check_h(h)
    sub = np.asarray(sub, dtype=float)
    if sub.ndim != 4 or sub.shape[-1] != 3 or sub.shape[1] < 1:
        raise ConfigError("sub", "shape (n, m, R, 3) with m >= 1", sub.shape)
    m, order = sub.shape[1], sub.shape[2]
    d = (m - 1 - np.arange(m)) * h  # distance from each sample end to the step end
    k = np.arange(order)[:, None] - np.arange(order)[None, :]  # r - q (0-based)
    k_pos = np.maximum(k, 0)
    inv_fact = 1.0 / np.array([math.factorial(int(v)) for v in k_pos.ravel()]).reshape(k.shape)
    coeff = np.where(k >= 0, d[:, None, None] ** k_pos[None] * inv_fact[None], 0.0)
    return np.einsum("jrq,njqa->nra", coeff, sub)


def _phi_functions(z: complex, order: int) -> NDArray[np.complex128]:
    """``J_r(z) = int_0^1 s^(r-1)/(r-1)! exp(-z s) ds`` for r = 1..order.

    Power series for ``|z| <= 3`` (no cancellation: the largest term is ~ the first),
    else the upward recurrence ``J_1 = (1 - e^-z)/z``, ``J_{r+1} = (J_r - e^-z / r!)/z``
    (integration by parts), which is stable for ``|z| > r``-ish and loses at most ~1
    digit at the switch-over for ``order <= 8``.
    """
    out = np.empty(order, dtype=complex)
    if abs(z) <= _SERIES_RADIUS:
        k = np.arange(60)
        pow_term = np.cumprod(np.concatenate(([1.0 + 0j], np.full(59, -z)))) / np.array(
            [math.factorial(int(i)) for i in k], dtype=float
        )  # (-z)^k / k!
        for r in range(1, order + 1):
            out[r - 1] = np.sum(pow_term / (k + r)) / math.factorial(r - 1)
    else:
        ez = np.exp(-z)
        out[0] = (1.0 - ez) / z
        for r in range(1, order):
            out[r] = (out[r - 1] - ez / math.factorial(r)) / z
    return out


def harmonic_multiple_integrals(
    amplitude: float,
    frequency_hz: float,
    phase: float,
    t0: ArrayLike,
    h: float,
    order: int,
) -> NDArray[np.float64]:
    """Closed-form r-fold integrals (1.14) of ``A sin(2 pi f t + phase)`` over samples.

    With ``omega = 2 pi f`` and ``u = t0 + h - tau``::

        I_r = Im[ A exp(i (omega (t0 + h) + phase)) h^r J_r(i omega h) ],
        J_r(z) = int_0^1 s^(r-1) / (r-1)! exp(-z s) ds

    Parameters
    ----------
    amplitude : float
        ``A`` (any unit).
    frequency_hz : float
        ``f``, Hz (0 gives the constant ``A sin(phase)``).
    phase : float
        rad.
    t0 : array_like, shape (n,)
        Sample start times, s.
    h : float
        Sample length, s.
    order : int
        Number R of orders.

    Returns
    -------
    ndarray, shape (n, order)
        ``I_r`` in units of A times s^r.
    """
    h = _check_h(h)
    order = _check_int("order", order, 1, 64)
    t0 = np.atleast_1d(np.asarray(t0, dtype=float))
    omega = 2.0 * math.pi * float(frequency_hz)
    j_r = _phi_functions(1j * omega * h, order)
    h_pow = h ** np.arange(1, order + 1)
    carrier = np.exp(1j * (omega * (t0 + h) + float(phase)))
    return float(amplitude) * np.imag(carrier[:, None] * (h_pow * j_r)[None, :])


@lru_cache(maxsize=None)
def _unit_noise_factor(order: int) -> NDArray[np.float64]:
    """Cholesky factor of ``C_ij = 1 / ((i+j-1) (i-1)! (j-1)!)`` (q = h = 1)."""
    inv_fact = 1.0 / np.array([math.factorial(i) for i in range(order)], dtype=float)
    # C = D H D with H the Hilbert matrix, D = diag(1/(i-1)!): chol(C) = D chol(H)
    factor = inv_fact[:, None] * cholesky(hilbert(order), lower=True)
    factor.setflags(write=False)
    return factor


def white_noise_integral_covariance(psd: float, h: float, order: int) -> NDArray[np.float64]:
    """Covariance of the r-fold integrals (r = 1..R) of white noise over one sample.

    ``Cov(I_i, I_j) = q h^(i+j-1) / ((i+j-1) (i-1)! (j-1)!)``, from
    ``I_r = int_0^h u^(r-1)/(r-1)! w dtau`` and ``E[w(t) w(s)] = q delta(t - s)``.

    Parameters
    ----------
    psd : float
        ``q``, e.g. (rad/s)^2/Hz = ARW^2.
    h : float
        Sample length, s.
    order : int
        R.

    Returns
    -------
    ndarray, shape (R, R)
    """
    h = _check_h(h)
    order = _check_int("order", order, 1, MAX_ORDER)
    i = np.arange(1, order + 1)
    s = i[:, None] + i[None, :] - 1
    fact = np.array([math.factorial(k) for k in range(order)], dtype=float)
    return psd * h**s / (s * fact[:, None] * fact[None, :])


# --------------------------------------------------------------------------------------
# Error model configuration
# --------------------------------------------------------------------------------------


def _vector3(name: str, value: Any, *, nonneg: bool = False, positive: bool = False) -> NDArray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(name, "a number or a 3-vector", value) from None
    if arr.ndim == 0:
        arr = np.full(3, float(arr))
    if arr.shape != (3,):
        raise ConfigError(name, "a number or a 3-vector", value)
    if positive:
        if not np.all((arr > 0.0) & (arr < math.inf)):
            raise ConfigError(name, "positive finite values", value)
    elif not np.all(np.isfinite(arr)):
        raise ConfigError(name, "finite values", value)
    if nonneg and np.any(arr < 0.0):
        raise ConfigError(name, "non-negative values", value)
    arr.setflags(write=False)
    return arr


def _matrix3(name: str, value: Any, *, zero_diagonal: bool = False) -> NDArray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(name, "a 3x3 matrix", value) from None
    if arr.ndim == 0 and arr == 0.0:
        arr = np.zeros((3, 3))
    if arr.shape != (3, 3) or not np.all(np.isfinite(arr)):
        raise ConfigError(name, "a finite 3x3 matrix", value)
    if zero_diagonal and np.any(np.diag(arr) != 0.0):
        raise ConfigError(name, "a zero diagonal (scale factors go in scale_factor)", value)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, slots=True, eq=False)
class VibrationHarmonic:
    """One harmonic ``amplitude * sin(2 pi frequency_hz t + phase_rad)`` added to a sensor.

    Two such harmonics on orthogonal gyro and accelerometer axes, 90 deg apart, give the
    pseudo-sculling error (6.1) of seed 000; on two orthogonal gyros, pseudo-coning (6.2).

    Parameters
    ----------
    amplitude : array_like, shape (3,)
        Per-axis amplitude, rad/s (gyro) or m/s^2 (accelerometer).
    frequency_hz : float
        Hz, >= 0.
    phase_rad : float
        rad.
    """

    amplitude: NDArray[np.float64]
    frequency_hz: float
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "amplitude", _vector3("vibration.amplitude", self.amplitude))
        freq = float(self.frequency_hz)
        if not (0.0 <= freq < math.inf):
            raise ConfigError(
                "vibration.frequency_hz", "a finite frequency >= 0", self.frequency_hz
            )
        phase = float(self.phase_rad)
        if not math.isfinite(phase):
            raise ConfigError("vibration.phase_rad", "a finite phase", self.phase_rad)
        object.__setattr__(self, "frequency_hz", freq)
        object.__setattr__(self, "phase_rad", phase)

    @classmethod
    def on_axis(
        cls, axis: int, amplitude: float, frequency_hz: float, phase_rad: float = 0.0
    ) -> VibrationHarmonic:
        """A harmonic on one body axis (0 = x right, 1 = y forward, 2 = z up)."""
        axis = _check_int("vibration.axis", axis, 0, 2)
        vec = np.zeros(3)
        vec[axis] = float(amplitude)
        return cls(vec, frequency_hz, phase_rad)

    def to_dict(self) -> dict[str, Any]:
        return {
            "amplitude": self.amplitude.tolist(),
            "frequency_hz": self.frequency_hz,
            "phase_rad": self.phase_rad,
        }

    def __eq__(self, other: object) -> bool:
        return isinstance(other, VibrationHarmonic) and self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]


def _as_harmonic(value: Any) -> VibrationHarmonic:
    if isinstance(value, VibrationHarmonic):
        return value
    if isinstance(value, Mapping):
        return VibrationHarmonic(**value)
    try:
        items = tuple(value)
    except TypeError:
        raise ConfigError(
            "vibration", "VibrationHarmonic or (amplitude, f_hz, phase)", value
        ) from None
    if len(items) not in (2, 3):
        raise ConfigError("vibration", "VibrationHarmonic or (amplitude, f_hz, phase)", value)
    return VibrationHarmonic(*items)


@dataclass(frozen=True, slots=True, eq=False)
class SensorErrors:
    """Errors of one sensor triad (gyro or accelerometer); every field is per axis.

    Units below are for the gyro / the accelerometer. Scalars are broadcast to 3 axes.

    Parameters
    ----------
    bias : array_like, shape (3,)
        Constant (deterministic) bias, rad/s / m/s^2.
    turn_on_bias_sigma : array_like, shape (3,)
        Sigma of a random constant bias drawn once by :meth:`ImuState.initial`.
    bias_instability_sigma : array_like, shape (3,)
        Stationary sigma of the first-order Gauss-Markov bias, rad/s / m/s^2.
    bias_correlation_time_s : array_like, shape (3,)
        Its correlation time, s (> 0).
    white_noise_density : array_like, shape (3,)
        Root PSD of the white noise on the rate: angle random walk in rad/sqrt(s)
        (= (rad/s)/sqrt(Hz)) / velocity random walk in m/s/sqrt(s). PSD = square.
    rate_random_walk : array_like, shape (3,)
        Root PSD of the white noise driving a random-walk bias, rad/s/sqrt(s) /
        m/s^2/sqrt(s).
    scale_factor : array_like, shape (3,)
        Scale-factor errors (unitless; 1e-6 = 1 ppm).
    misalignment : array_like, shape (3, 3)
        Small-angle misalignment / non-orthogonality matrix with zero diagonal: the output
        is ``(I + diag(scale_factor) + misalignment) @ true``.
    quantization_lsb : float
        LSB of the first-order increment output, rad / m/s (0 = off).
    vibration : sequence of VibrationHarmonic
        Harmonics added to the sensed quantity (seed 000 section 6).
    """

    bias: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    turn_on_bias_sigma: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    bias_instability_sigma: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    bias_correlation_time_s: NDArray[np.float64] = 3600.0  # type: ignore[assignment]
    white_noise_density: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    rate_random_walk: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    scale_factor: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    misalignment: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    quantization_lsb: float = 0.0
    vibration: tuple[VibrationHarmonic, ...] = ()

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "bias", _vector3("bias", self.bias))
        for name in ("turn_on_bias_sigma", "bias_instability_sigma", "white_noise_density",
                     "rate_random_walk"):
            set_(self, name, _vector3(name, getattr(self, name), nonneg=True))
        set_(self, "bias_correlation_time_s",
             _vector3("bias_correlation_time_s", self.bias_correlation_time_s, positive=True))
        set_(self, "scale_factor", _vector3("scale_factor", self.scale_factor))
        set_(self, "misalignment", _matrix3("misalignment", self.misalignment, zero_diagonal=True))
        try:
            lsb = float(self.quantization_lsb)
        except (TypeError, ValueError):
            raise ConfigError("quantization_lsb", "a number >= 0", self.quantization_lsb) from None
        if not (0.0 <= lsb < math.inf):
            raise ConfigError("quantization_lsb", "a finite number >= 0", self.quantization_lsb)
        set_(self, "quantization_lsb", lsb)
        if isinstance(self.vibration, (VibrationHarmonic, Mapping)):
            raise ConfigError("vibration", "a sequence of harmonics", self.vibration)
        set_(self, "vibration", tuple(_as_harmonic(v) for v in self.vibration))

    @property
    def white_noise_psd(self) -> NDArray[np.float64]:
        """PSD of the white noise, (rad/s)^2/Hz / (m/s^2)^2/Hz, shape (3,)."""
        return self.white_noise_density**2

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and floats (TOML-ready); inverse of ``SensorErrors(**d)``."""
        return {
            "bias": self.bias.tolist(),
            "turn_on_bias_sigma": self.turn_on_bias_sigma.tolist(),
            "bias_instability_sigma": self.bias_instability_sigma.tolist(),
            "bias_correlation_time_s": self.bias_correlation_time_s.tolist(),
            "white_noise_density": self.white_noise_density.tolist(),
            "rate_random_walk": self.rate_random_walk.tolist(),
            "scale_factor": self.scale_factor.tolist(),
            "misalignment": self.misalignment.tolist(),
            "quantization_lsb": self.quantization_lsb,
            "vibration": [v.to_dict() for v in self.vibration],
        }

    def __eq__(self, other: object) -> bool:
        return isinstance(other, SensorErrors) and self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, slots=True, eq=False)
class ImuErrorModel:
    """Truth-side IMU error model: what the simulator does to the true increments.

    Parameters
    ----------
    gyro : SensorErrors
        Gyro triad errors (rad/s based units).
    accel : SensorErrors
        Accelerometer triad errors (m/s^2 based units).
    g_sensitivity : array_like, shape (3, 3)
        Gyro g-sensitivity, rad/s per m/s^2: adds ``G @ f_b`` to the rate and
        ``G @ dv_r`` to every ``dtheta_r``.
    name : str
        Label (the preset name or "custom").
    """

    gyro: SensorErrors = field(default_factory=SensorErrors)
    accel: SensorErrors = field(default_factory=SensorErrors)
    g_sensitivity: NDArray[np.float64] = 0.0  # type: ignore[assignment]
    name: str = "custom"

    def __post_init__(self) -> None:
        for part in ("gyro", "accel"):
            value = getattr(self, part)
            if isinstance(value, Mapping):
                value = SensorErrors(**value)
            if not isinstance(value, SensorErrors):
                raise ConfigError(part, "SensorErrors or a mapping of its fields", value)
            object.__setattr__(self, part, value)
        object.__setattr__(self, "g_sensitivity", _matrix3("g_sensitivity", self.g_sensitivity))
        object.__setattr__(self, "name", str(self.name))

    def to_dict(self) -> dict[str, Any]:
        """Plain nested dict (TOML-ready); ``ImuErrorModel.from_dict`` inverts it."""
        return {
            "name": self.name,
            "g_sensitivity": self.g_sensitivity.tolist(),
            "gyro": self.gyro.to_dict(),
            "accel": self.accel.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ImuErrorModel:
        """Build from :meth:`to_dict` output (or a scenario-file table)."""
        unknown = set(data) - {"name", "g_sensitivity", "gyro", "accel"}
        if unknown:
            raise ConfigError("imu", "keys among name, g_sensitivity, gyro, accel", sorted(unknown))
        return cls(
            gyro=SensorErrors(**data.get("gyro", {})),
            accel=SensorErrors(**data.get("accel", {})),
            g_sensitivity=data.get("g_sensitivity", 0.0),
            name=data.get("name", "custom"),
        )

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ImuErrorModel) and self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]


# --------------------------------------------------------------------------------------
# State and output
# --------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, eq=False)
class ImuState:
    """Everything recursive in the IMU error model. Index 0 = gyro, 1 = accelerometer.

    Parameters
    ----------
    sample_index : int
        Number of samples generated so far (the global index of the next sample).
    turn_on_bias : ndarray, shape (2, 3)
        Random constant biases drawn at turn-on, rad/s and m/s^2.
    bias_gauss_markov : ndarray, shape (2, 3)
        Gauss-Markov bias during the next sample.
    bias_random_walk : ndarray, shape (2, 3)
        Rate-random-walk bias during the next sample.
    quant_accumulator : ndarray, shape (2, MAX_ORDER + 1, 3)
        Quantizer accumulators (rows 0..R-1 the integral orders, row ``MAX_ORDER`` the
        rate output), in output units.
    quant_count : ndarray, shape (2, MAX_ORDER + 1, 3)
        LSB counts emitted within the current renormalisation block; the residual carry is
        ``quant_accumulator - lsb_level * quant_count`` (see :meth:`quantization_residual`).
    """

    sample_index: int
    turn_on_bias: NDArray[np.float64]
    bias_gauss_markov: NDArray[np.float64]
    bias_random_walk: NDArray[np.float64]
    quant_accumulator: NDArray[np.float64]
    quant_count: NDArray[np.float64]

    def __post_init__(self) -> None:
        index = _check_int("state.sample_index", self.sample_index, 0)
        object.__setattr__(self, "sample_index", index)
        shapes = {
            "turn_on_bias": (2, 3),
            "bias_gauss_markov": (2, 3),
            "bias_random_walk": (2, 3),
            "quant_accumulator": (2, MAX_ORDER + 1, 3),
            "quant_count": (2, MAX_ORDER + 1, 3),
        }
        for name, shape in shapes.items():
            arr = frozen_array(getattr(self, name))
            if arr.shape != shape:
                raise ConfigError(f"state.{name}", f"shape {shape}", arr.shape)
            object.__setattr__(self, name, arr)

    @classmethod
    def initial(cls, model: ImuErrorModel, rng: np.random.Generator) -> ImuState:
        """Turn-on state: draws one ``(2, 2, 3)`` block of standard normals.

        ``z[s, 0]`` gives the turn-on biases (``turn_on_bias_sigma * z``) and ``z[s, 1]``
        the Gauss-Markov biases from their stationary distribution
        (``bias_instability_sigma * z``); the random-walk biases start at zero.
        """
        z = rng.standard_normal((2, 2, 3))
        sensors = (model.gyro, model.accel)
        turn_on = np.stack([s.turn_on_bias_sigma for s in sensors]) * z[:, 0]
        gauss_markov = np.stack([s.bias_instability_sigma for s in sensors]) * z[:, 1]
        zeros_q = np.zeros((2, MAX_ORDER + 1, 3))
        return cls(0, turn_on, gauss_markov, np.zeros((2, 3)), zeros_q, zeros_q)

    @classmethod
    def _batch(cls, sample_index: int, turn_on: Sequence[NDArray], gauss_markov: NDArray, random_walk: NDArray,
               accumulator: NDArray, count: NDArray) -> list[ImuState]:
        """The states of B members after a batched call: each (B, ...) array is copied once
        to a read-only array and member j gets read-only views of row j (the shapes are
        those of the batch arrays by construction, so the per-member checks are skipped).
        ``turn_on`` holds the members' own (already read-only) turn-on biases."""
        rows = []
        for a in (gauss_markov, random_walk, accumulator, count):
            a = np.array(a, dtype=float, copy=True)
            a.setflags(write=False)
            rows.append(a)
        index = int(sample_index)
        out = []
        for j, t in enumerate(turn_on):
            state = object.__new__(cls)
            for name, value in zip(("turn_on_bias", "bias_gauss_markov", "bias_random_walk", "quant_accumulator",
                                    "quant_count"), (t, rows[0][j], rows[1][j], rows[2][j], rows[3][j])):
                object.__setattr__(state, name, value)
            object.__setattr__(state, "sample_index", index)
            out.append(state)
        return out

    def quantization_residual(
        self, model: ImuErrorModel, h: float, order: int
    ) -> NDArray[np.float64]:
        """Residual carry (unquantized minus quantized running sum), shape (2, R + 1, 3).

        Rows 0..R-1 are the integral orders, row R the rate output; zero where the
        sensor has no quantization.
        """
        lsb = _level_lsb(model, _check_h(h), _check_int("order", order, 1, MAX_ORDER))
        rows = list(range(order)) + [MAX_ORDER]
        acc = self.quant_accumulator[:, rows]
        count = self.quant_count[:, rows]
        return acc - lsb[:, :, None] * count

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ImuState) or other.sample_index != self.sample_index:
            return False
        return all(
            np.array_equal(getattr(self, n), getattr(other, n))
            for n in ("turn_on_bias", "bias_gauss_markov", "bias_random_walk",
                      "quant_accumulator", "quant_count")
        )

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, slots=True, eq=False)
class ImuOutput:
    """IMU measurements with errors for ``n`` samples.

    Attributes
    ----------
    dtheta_r : ndarray, shape (n, R, 3)
        Multiple integrals of the angular rate (1.14), rad s^(r-1).
    dv_r : ndarray, shape (n, R, 3)
        Multiple integrals of the specific force, m/s * s^(r-1).
    rate_b : ndarray, shape (n, 3)
        Angular-rate output at the sample instants ``t_start + h``, rad/s.
    accel_b : ndarray, shape (n, 3)
        Specific-force output at the sample instants, m/s^2.
    """

    dtheta_r: NDArray[np.float64]
    dv_r: NDArray[np.float64]
    rate_b: NDArray[np.float64]
    accel_b: NDArray[np.float64]


# --------------------------------------------------------------------------------------
# Applying the errors
# --------------------------------------------------------------------------------------


def _mat3_apply(mat: NDArray, vec: NDArray) -> NDArray:
    """``mat @ vec`` over the last axis of ``vec`` (..., 3), without tiny-matrix BLAS calls."""
    return (
        vec[..., 0, None] * mat[:, 0] + vec[..., 1, None] * mat[:, 1] + vec[..., 2, None] * mat[:, 2]
    )


def _level_lsb(model: ImuErrorModel, h: float, order: int) -> NDArray[np.float64]:
    """LSB of each output level, shape (2, R + 1): ``lsb h^(r-1)`` then ``lsb / h``."""
    base = np.array([model.gyro.quantization_lsb, model.accel.quantization_lsb])
    scale = np.concatenate((h ** np.arange(order), [1.0 / h]))
    return base[:, None] * scale[None, :]


def _first_order_recursion(phi: NDArray, drive: NDArray, start: NDArray) -> NDArray:
    """``x_{k+1} = phi x_k + drive_k`` per channel along axis 1; returns x_1..x_n.

    ``drive`` is (B, n, ...) (B members, n samples), ``start`` (B, ...), ``phi`` broadcasts
    against ``start``. ``scipy.signal.lfilter`` with ``zi = phi * x_0`` evaluates exactly
    ``y_k = drive_k + phi * y_{k-1}``, so the result does not depend on chunking nor on
    how many members are filtered together. All-zero input (the error switched off)
    gives exact zeros without filtering.
    """
    n = drive.shape[1]
    if not (drive.any() or start.any()):
        return np.zeros(drive.shape)
    out = np.empty(drive.shape)  # C order: the reshaped views below must share its memory
    if n <= 16:  # a few samples (step-by-step use): the plain recursion, same arithmetic
        x = start.copy()
        for k in range(n):
            x = drive[:, k] + phi * x  # y_k = drive_k + phi y_{k-1}, as lfilter evaluates it
            out[:, k] = x
        return out
    from scipy.signal import lfilter  # lazy: scipy.signal costs ~0.7 s to import

    b = drive.shape[0]
    flat_drive = drive.reshape(b, n, -1)
    flat_out = out.reshape(b, n, -1)  # a view (out is C-contiguous)
    flat_start = start.reshape(b, -1)
    for c, p in enumerate(np.broadcast_to(phi, start.shape[1:]).ravel()):
        flat_out[:, :, c], _ = lfilter([1.0], [1.0, -p], flat_drive[:, :, c], axis=1, zi=p * flat_start[:, c, None])
    return out


first_order_recursion = _first_order_recursion
"""Public name of the batched first-order recursion (used by the odometer's Gauss-Markov term)."""


def _quantize(
    values: NDArray, lsb: NDArray, acc: NDArray, count: NDArray, start_index: int
) -> tuple[NDArray, NDArray, NDArray]:
    """Quantize with residual carry, vectorised over samples; channels along axis 1.

    Within a renormalisation block, ``acc_k = acc_{k-1} + y_k`` (sequential cumsum),
    ``count_k = rint(acc_k / lsb)`` and the output is ``lsb (count_k - count_{k-1})``,
    which is the residual-carry quantizer ``q_k = lsb rint((y_k + res_{k-1}) / lsb)`` of
    Groves (2013) written on running sums. At every global sample index that is a
    multiple of ``QUANTIZATION_BLOCK`` both are shifted by the count
    (``acc -= lsb count``, ``count = 0``), keeping the accumulator small.
    """
    n = values.shape[0]
    out = np.empty_like(values)
    i = 0
    while i < n:
        g = start_index + i
        stop = min(n, i + QUANTIZATION_BLOCK - g % QUANTIZATION_BLOCK)
        sums = np.cumsum(np.concatenate((acc[None], values[i:stop]), axis=0), axis=0)[1:]
        counts = np.rint(sums / lsb)
        out[i:stop] = np.diff(np.concatenate((count[None], counts), axis=0), axis=0) * lsb
        acc, count = sums[-1], counts[-1]
        if (start_index + stop) % QUANTIZATION_BLOCK == 0:
            acc = acc - lsb * count
            count = np.zeros_like(count)
        i = stop
    return out, acc, count


def _check_truth_inputs(t_start, dtheta_r, dv_r, omega_b, f_b):
    dtheta_r = np.asarray(dtheta_r, dtype=float)
    dv_r = np.asarray(dv_r, dtype=float)
    if dtheta_r.ndim != 3 or dtheta_r.shape[-1] != 3 or not 1 <= dtheta_r.shape[1] <= MAX_ORDER:
        raise ConfigError("dtheta_r", f"shape (n, R, 3) with 1 <= R <= {MAX_ORDER}", dtheta_r.shape)
    n = dtheta_r.shape[0]
    if dv_r.shape != dtheta_r.shape:
        raise ConfigError("dv_r", f"shape {dtheta_r.shape} like dtheta_r", dv_r.shape)
    t_start = np.asarray(t_start, dtype=float)
    if t_start.shape != (n,):
        raise ConfigError("t_start", f"shape ({n},)", t_start.shape)
    omega_b = np.asarray(omega_b, dtype=float)
    f_b = np.asarray(f_b, dtype=float)
    if omega_b.shape != (n, 3):
        raise ConfigError("omega_b", f"shape ({n}, 3)", omega_b.shape)
    if f_b.shape != (n, 3):
        raise ConfigError("f_b", f"shape ({n}, 3)", f_b.shape)
    return t_start, dtheta_r, dv_r, omega_b, f_b


def _kernel_sensor(kern, s_idx, sensor, out, rate, z, order, members, turn_on, gm_start, sigma_gm, rrw_start,
                   rrw_gain, varying, h_r_fact, t_start, t_end, h, noise_factor, scale_density, dest=None):
    """One sensor's outputs (B, n, R, 3), (B, n, 3) with the compiled white-noise pass.

    ``out`` (n, R, 3) and ``rate`` (n, 3) are the noise-free values shared by the members
    (after scale factor, misalignment and g-sensitivity). The bias and vibration terms are
    added in the order of the NumPy path (bias, then each harmonic, then the noise), never
    in place (``out`` may be the caller's array). ``dest``: (out_r, out_rate) to write into.
    """
    base_r, base_rate = out[None], rate[None]
    constant = sensor.bias + turn_on[:, s_idx]  # (B, 3)
    if np.any(constant) or np.any(gm_start[:, s_idx]) or np.any(sigma_gm[s_idx]) \
            or np.any(rrw_start[:, s_idx]) or np.any(rrw_gain[s_idx]):
        bias = constant[:, None] + varying[:, :, s_idx]  # (B, n, 3)
        base_r = base_r + bias[:, :, None, :] * h_r_fact[None, None, :, None]  # b h^r / r!
        base_rate = base_rate + bias
    for harm in sensor.vibration:
        integrals = harmonic_multiple_integrals(1.0, harm.frequency_hz, harm.phase_rad, t_start, h, order)
        base_r = base_r + (integrals[:, :, None] * harm.amplitude[None, None, :])[None]
        wave = np.sin(2.0 * math.pi * harm.frequency_hz * t_end + harm.phase_rad)
        base_rate = base_rate + (wave[:, None] * harm.amplitude[None, :])[None]
    n = out.shape[0]
    if dest is None:
        out_r, out_rate = np.empty((members, n, order, 3)), np.empty((members, n, 3))
    else:
        out_r, out_rate = dest
    kern(z.reshape(members, n, -1), s_idx * 3 * (order + 2), noise_factor, np.ascontiguousarray(scale_density), h,
         np.broadcast_to(base_r, out_r.shape), np.broadcast_to(base_rate, out_rate.shape), out_r, out_rate)
    return out_r, out_rate


def apply_imu_errors(
    t_start: ArrayLike,
    h: float,
    dtheta_r: ArrayLike,
    dv_r: ArrayLike,
    omega_b: ArrayLike,
    f_b: ArrayLike,
    model: ImuErrorModel,
    state: ImuState,
    rng: np.random.Generator,
) -> tuple[ImuOutput, ImuState]:
    """Apply the IMU error model to ``n`` consecutive samples of true data.

    Parameters
    ----------
    t_start : array_like, shape (n,)
        Start time of each sample, s (sample k covers ``[t_start[k], t_start[k] + h]``).
    h : float
        Sample length, s.
    dtheta_r, dv_r : array_like, shape (n, R, 3)
        True multiple integrals (1.14) of ``omega_ib_b`` (rad s^(r-1)) and of ``f_b``
        (m/s s^(r-1)), R <= ``MAX_ORDER``.
    omega_b, f_b : array_like, shape (n, 3)
        True angular rate (rad/s) and specific force (m/s^2) at ``t_start + h``.
    model : ImuErrorModel
    state : ImuState
        From :meth:`ImuState.initial` or the previous call.
    rng : numpy.random.Generator
        Draws exactly one ``(n, 6 (R + 2))`` block of standard normals.

    Returns
    -------
    output : ImuOutput
    new_state : ImuState

    See Also
    --------
    apply_imu_errors_batch : the same for B IMUs on one true motion (this function is
        its B = 1 case).
    """
    output, states = apply_imu_errors_batch(t_start, h, dtheta_r, dv_r, omega_b, f_b, model, [state], [rng])
    return ImuOutput(output.dtheta_r[0], output.dv_r[0], output.rate_b[0], output.accel_b[0]), states[0]


def apply_imu_errors_batch(
    t_start: ArrayLike,
    h: float,
    dtheta_r: ArrayLike,
    dv_r: ArrayLike,
    omega_b: ArrayLike,
    f_b: ArrayLike,
    model: ImuErrorModel,
    states: Sequence[ImuState],
    rngs: Sequence[np.random.Generator],
    out: ImuOutput | None = None,
) -> tuple[ImuOutput, list[ImuState]]:
    """Apply one error model to B IMUs that sense the same true motion, in one pass.

    Member j gets exactly the numbers of ``apply_imu_errors(..., states[j], rngs[j])``
    (the same draws from its own generator, the same floating-point operations, applied
    elementwise over a leading member axis). This is how the native vector environment
    simulates N episodes of a scenario in lockstep.

    Parameters
    ----------
    t_start, h, dtheta_r, dv_r, omega_b, f_b, model
        As :func:`apply_imu_errors`; the true data are shared by all members.
    states : sequence of B ImuState
        Their ``sample_index`` must be equal (lockstep).
    rngs : sequence of B numpy.random.Generator
        Generator j draws one ``(n, 6 (R + 2))`` block.
    out : ImuOutput, optional
        Arrays (views allowed) of the output shapes to write the result into; it is then
        the returned output (the simulator's chunk buffers, saving a copy).

    Returns
    -------
    output : ImuOutput
        Arrays with a leading member axis: ``dtheta_r`` (B, n, R, 3), ``rate_b`` (B, n, 3).
    new_states : list of B ImuState
    """
    h = _check_h(h)
    if not isinstance(model, ImuErrorModel):
        raise ConfigError("model", "an ImuErrorModel", type(model).__name__)
    states = list(states)
    rngs = list(rngs)
    if not states or len(rngs) != len(states):
        raise ConfigError("rngs", f"one generator per state ({len(states)}, at least one)", len(rngs))
    for state in states:
        if not isinstance(state, ImuState):
            raise ConfigError("state", "an ImuState", type(state).__name__)
    index = states[0].sample_index
    if any(s.sample_index != index for s in states):
        raise ConfigError("states", "states at the same sample_index (lockstep)",
                          sorted({s.sample_index for s in states}))
    t_start, dtheta_r, dv_r, omega_b, f_b = _check_truth_inputs(t_start, dtheta_r, dv_r, omega_b, f_b)
    n, order = dtheta_r.shape[:2]
    members = len(states)

    if n == 0:
        empty = np.zeros((members, 0, order, 3))
        return ImuOutput(empty, empty.copy(), np.zeros((members, 0, 3)), np.zeros((members, 0, 3))), states

    # One block per member and call; width fixed by R only.
    z = np.empty((members, n, 6 * (order + 2)))
    for j, rng in enumerate(rngs):
        rng.standard_normal(out=z[j])
    # each slot used is copied once to a contiguous (member, sample, axis) array, so the
    # elementwise passes below run over long contiguous arrays (the numbers are those
    # of the draw order above)
    z = z.reshape(members, n, 2, order + 2, 3)
    slots: dict[tuple[int, int], NDArray] = {}

    def slot(s_idx: int, k: int) -> NDArray:
        """Draw slot k of sensor s_idx as a contiguous (B, n, 3) array (copied once)."""
        if (s_idx, k) not in slots:
            slots[s_idx, k] = np.ascontiguousarray(z[:, :, s_idx, k])
        return slots[s_idx, k]

    sensors = (model.gyro, model.accel)
    r = np.arange(1, order + 1)
    h_r_fact = h**r / np.array([math.factorial(int(k)) for k in r], dtype=float)  # h^r / r!
    turn_on = np.stack([s.turn_on_bias for s in states])  # (B, 2, 3)
    gm_start = np.stack([s.bias_gauss_markov for s in states])
    rrw_start = np.stack([s.bias_random_walk for s in states])

    # Gauss-Markov and rate-random-walk biases: exact discrete propagation between
    # samples, held constant within each sample (see the module docstring). Switched
    # off (zero sigma and state) they stay exactly zero and nothing is computed.
    sigma_gm = np.stack([s.bias_instability_sigma for s in sensors])
    tau = np.stack([s.bias_correlation_time_s for s in sensors])
    rrw_gain = np.stack([s.rate_random_walk for s in sensors]) * math.sqrt(h)
    zero_bias = np.zeros((members, n, 2, 3))
    if sigma_gm.any() or gm_start.any():
        phi = np.exp(-h / tau)
        gm_coef = sigma_gm * np.sqrt(-np.expm1(-2.0 * h / tau))  # (2, 3)
        gm_drive = gm_coef[None, None] * z[:, :, :, order]  # (B, n, 2, 3)
        gm_next = _first_order_recursion(phi, gm_drive, gm_start)  # b_1..b_n
    else:
        gm_next = zero_bias
    if rrw_gain.any() or rrw_start.any():
        rrw_drive = rrw_gain[None, None] * z[:, :, :, order + 1]
        rrw_next = _first_order_recursion(np.ones((2, 3)), rrw_drive, rrw_start)
    else:
        rrw_next = zero_bias
    if gm_next is zero_bias and rrw_next is zero_bias:
        varying = zero_bias  # both switched off: the sum below is exact zeros too
    else:
        varying = np.concatenate((gm_start[:, None], gm_next[:, :-1]), axis=1)
        varying += np.concatenate((rrw_start[:, None], rrw_next[:, :-1]), axis=1)

    density = np.stack([s.white_noise_density for s in sensors])  # (2, 3)
    noise_factor = _unit_noise_factor(order)
    noise_scale = math.sqrt(h) * h ** (r - 1)  # white-noise integral r scales as h^(r - 1/2)
    lsb_levels = _level_lsb(model, h, order)
    rows = list(range(order)) + [MAX_ORDER]
    acc_new = np.stack([s.quant_accumulator for s in states])  # (B, 2, MAX_ORDER + 1, 3)
    count_new = np.stack([s.quant_count for s in states])
    t_end = t_start + h
    kern = _imu_kernel.kernel() if USE_KERNEL else None
    dest_output = out  # (the name ``out`` is reused below)
    dest_all = None if out is None else ((out.dtheta_r, out.rate_b), (out.dv_r, out.accel_b))
    outputs = []
    for s_idx, (sensor, true_r, true_rate) in enumerate(
        ((model.gyro, dtheta_r, omega_b), (model.accel, dv_r, f_b))
    ):
        # Scale factor and misalignment: linear, so exact on every order.
        transform = np.eye(3) + np.diag(sensor.scale_factor) + sensor.misalignment
        if np.array_equal(transform, np.eye(3)):
            out, rate = true_r, true_rate
        else:
            out, rate = _mat3_apply(transform, true_r), _mat3_apply(transform, true_rate)

        # Gyro g-sensitivity on the true specific force (exact on every order).
        if s_idx == 0 and np.any(model.g_sensitivity):
            out = out + _mat3_apply(model.g_sensitivity, dv_r)
            rate = rate + _mat3_apply(model.g_sensitivity, f_b)
        if kern is not None and np.any(density[s_idx]) and not lsb_levels[s_idx, 0] > 0.0:
            # compiled white-noise pass (navsim.sensors.imu.kernel): the same terms in the
            # same order as below, without repeating the shared values per member
            dest = None if dest_all is None else dest_all[s_idx]
            outputs.append(_kernel_sensor(kern, s_idx, sensor, out, rate, z, order, members, turn_on, gm_start,
                                          sigma_gm, rrw_start, rrw_gain, varying, h_r_fact, t_start, t_end, h,
                                          noise_factor, noise_scale[:, None] * density[s_idx][None, :], dest))
            continue
        # from here on the members differ; ``out`` in the layout (R, B, n, 3)
        out = np.repeat(out.transpose(1, 0, 2)[:, None], members, axis=1)
        rate = np.repeat(rate[None], members, axis=0)  # (B, n, 3)

        # Biases: constant + turn-on + Gauss-Markov + rate random walk (members without
        # a bias add exact zeros).
        constant = sensor.bias + turn_on[:, s_idx]  # (B, 3)
        if np.any(constant) or np.any(gm_start[:, s_idx]) or np.any(sigma_gm[s_idx]) \
                or np.any(rrw_start[:, s_idx]) or np.any(rrw_gain[s_idx]):
            bias = constant[:, None] + varying[:, :, s_idx]  # (B, n, 3)
            out += bias[None] * h_r_fact[:, None, None, None]  # b h^r / r!
            rate += bias

        # Vibration harmonics: closed-form multiple integrals (seed 000, section 6).
        for harm in sensor.vibration:
            integrals = harmonic_multiple_integrals(
                1.0, harm.frequency_hz, harm.phase_rad, t_start, h, order
            )
            out += integrals.T[:, None, :, None] * harm.amplitude[None, None, None, :]
            wave = np.sin(2.0 * math.pi * harm.frequency_hz * t_end + harm.phase_rad)
            rate += wave[:, None] * harm.amplitude[None, :]

        # White noise: exact joint draw of the R integrals, Cov = q h^(i+j-1) / (...).
        if np.any(density[s_idx]):
            for i in range(order):  # lower-triangular Cholesky factor times the draws
                unit = noise_factor[i, 0] * slot(s_idx, 0)  # slots 0..R-1: white
                for q in range(1, i + 1):
                    unit += noise_factor[i, q] * slot(s_idx, q)
                noise_i = unit * (noise_scale[i] * density[s_idx])
                out[i] += noise_i
                if i == 0:
                    rate += noise_i / h  # sample average: sigma = sqrt(PSD / h)

        # Quantization with residual carry, per output level and axis (members side by
        # side as channels: the running sums are per column).
        if lsb_levels[s_idx, 0] > 0.0:
            width = 3 * (order + 1)
            values = np.concatenate((out, rate[None]), axis=0).transpose(2, 1, 0, 3)  # (n, B, R + 1, 3)
            q, acc, count = _quantize(
                values.reshape(n, members * width),
                np.tile(np.repeat(lsb_levels[s_idx], 3), members),
                acc_new[:, s_idx, rows].reshape(-1),
                count_new[:, s_idx, rows].reshape(-1),
                index,
            )
            q = q.reshape(n, members, order + 1, 3)
            out, rate = q[:, :, :order].transpose(1, 0, 2, 3), q[:, :, order].transpose(1, 0, 2)
            acc_new[:, s_idx, rows] = acc.reshape(members, order + 1, 3)
            count_new[:, s_idx, rows] = count.reshape(members, order + 1, 3)
        else:
            out = out.transpose(1, 2, 0, 3)  # (B, n, R, 3)
        outputs.append((out, rate))

    new_states = ImuState._batch(index + n, [s.turn_on_bias for s in states], gm_next[:, -1], rrw_next[:, -1],
                                 acc_new, count_new)
    if dest_all is None:
        return ImuOutput(dtheta_r=outputs[0][0], dv_r=outputs[1][0], rate_b=outputs[0][1],
                         accel_b=outputs[1][1]), new_states
    for (values, rate), (dest_r, dest_rate) in zip(outputs, dest_all):
        if values is not dest_r:  # the kernel wrote in place
            dest_r[...] = values
            dest_rate[...] = rate
    return dest_output, new_states


# --------------------------------------------------------------------------------------
# Presets and the nominal specification
# --------------------------------------------------------------------------------------

def is_error_free(model: ImuErrorModel) -> bool:
    """True if the model adds no error at all (its output equals the true increments).

    The simulator then skips :func:`apply_imu_errors` and draws nothing from the IMU
    stream; no other stream is affected, so this changes no other number.
    """
    for sensor in (model.gyro, model.accel):
        for name in ("bias", "turn_on_bias_sigma", "bias_instability_sigma", "white_noise_density",
                     "rate_random_walk", "scale_factor", "misalignment"):
            if np.any(getattr(sensor, name)):
                return False
        if sensor.quantization_lsb or sensor.vibration:
            return False
    return not np.any(model.g_sensitivity)


PRESET_NAMES = ("ideal", "paper-2012", "consumer-mems", "tactical", "navigation")

# Quantization levels of the Groves demos are given for the rate-type output (m/s^2,
# rad/s) at the demos' 100 Hz IMU rate; the increment LSB is that level times 0.01 s.
_GROVES_DT = 0.01


def _split_m(matrix_ppm: Sequence[Sequence[float]]) -> tuple[NDArray, NDArray]:
    """Groves' combined scale-factor / cross-coupling matrix -> (scale, misalignment)."""
    m = np.array(matrix_ppm, dtype=float) * _PPM
    return np.diag(m).copy(), m - np.diag(np.diag(m))


def imu_preset(name: str) -> ImuErrorModel:
    """A named IMU error model.

    ``"ideal"``
        No error at all.
    ``"paper-2012"``
        Seed 003's worked example: white noise only. The accelerometer "intensity
        (1e-5 m/s^2)^2" is read as a PSD, i.e. VRW = 1e-5 m/s/sqrt(s) (= 6e-4
        m/s/sqrt(h), about 1 micro-g/sqrt(Hz)). The gyro noise is not printed; we take a
        navigation-grade ARW of 0.002 deg/sqrt(h) (the aviation-grade value of the Groves
        (2013) demos, also the HG9900-class "high-accuracy" grade of gnss-ins-sim).
    ``"consumer-mems"``
        ICM-20602 class: ARW 0.2 deg/sqrt(h), VRW 0.2 m/s/sqrt(h), Gauss-Markov bias
        sigma 200 deg/h and 1000 mGal with 1 h correlation time (KF-GINS
        awesome-gins-datasets tuned values); constant biases, scale factor /
        cross-coupling, g-sensitivity and quantization (0.1 m/s^2, 2e-3 rad/s at 100 Hz)
        of the Groves consumer-grade demo.
    ``"tactical"``
        ADIS16465 class: ARW 0.1 deg/sqrt(h), VRW 0.1 m/s/sqrt(h), Gauss-Markov bias
        sigma 25 deg/h and 200 mGal, 1 h (awesome-gins-datasets); constant biases (900
        micro-g, 9 deg/h), scale factor / cross-coupling, g-sensitivity and quantization
        (1e-2 m/s^2, 2e-4 rad/s at 100 Hz) of the Groves tactical-grade demo.
    ``"navigation"``
        Leador-A15 figures quoted in the KF-GINS paper: ARW 0.003 deg/sqrt(h), VRW 0.03
        m/s/sqrt(h), Gauss-Markov bias instability 0.027 deg/h and 15 mGal with 4 h
        correlation time; constant biases (30 micro-g, 0.0009 deg/h), scale factor /
        cross-coupling and quantization (5e-5 m/s^2, 1e-6 rad/s at 100 Hz) of the Groves
        aviation-grade demo (which has no g-sensitivity).

    Parameters
    ----------
    name : str
        One of :data:`PRESET_NAMES`.

    Returns
    -------
    ImuErrorModel
    """
    if name == "ideal":
        return ImuErrorModel(name="ideal")
    if name == "paper-2012":
        return ImuErrorModel(
            gyro=SensorErrors(white_noise_density=0.002 * _DEG_PER_SQRT_HOUR),
            accel=SensorErrors(white_noise_density=1.0e-5),  # (1e-5 m/s^2)^2 read as PSD
            name="paper-2012",
        )
    if name == "consumer-mems":
        sa, ma = _split_m([[50000, -15000, 10000], [-7500, -60000, 12500], [-12500, 5000, 20000]])
        sg, mg = _split_m([[40000, -14000, 12500], [0, -30000, -7500], [0, 0, -17500]])
        return ImuErrorModel(
            gyro=SensorErrors(
                bias=np.array([-180.0, 260.0, -160.0]) * _DEG_PER_HOUR,
                bias_instability_sigma=200.0 * _DEG_PER_HOUR,
                bias_correlation_time_s=3600.0,
                white_noise_density=0.2 * _DEG_PER_SQRT_HOUR,
                scale_factor=sg,
                misalignment=mg,
                quantization_lsb=2.0e-3 * _GROVES_DT,
            ),
            accel=SensorErrors(
                bias=np.array([9000.0, -13000.0, 8000.0]) * _MICRO_G,
                bias_instability_sigma=1000.0 * _MGAL,
                bias_correlation_time_s=3600.0,
                white_noise_density=0.2 * _PER_SQRT_HOUR,
                scale_factor=sa,
                misalignment=ma,
                quantization_lsb=1.0e-1 * _GROVES_DT,
            ),
            g_sensitivity=np.array(
                [[90.0, -110.0, -60.0], [-50.0, 190.0, -160.0], [30.0, 110.0, -130.0]]
            )
            * _DEG_PER_HOUR_PER_G,
            name="consumer-mems",
        )
    if name == "tactical":
        sa, ma = _split_m([[500, -300, 200], [-150, -600, 250], [-250, 100, 450]])
        sg, mg = _split_m([[400, -300, 250], [0, -300, -150], [0, 0, -350]])
        return ImuErrorModel(
            gyro=SensorErrors(
                bias=np.array([-9.0, 13.0, -8.0]) * _DEG_PER_HOUR,
                bias_instability_sigma=25.0 * _DEG_PER_HOUR,
                bias_correlation_time_s=3600.0,
                white_noise_density=0.1 * _DEG_PER_SQRT_HOUR,
                scale_factor=sg,
                misalignment=mg,
                quantization_lsb=2.0e-4 * _GROVES_DT,
            ),
            accel=SensorErrors(
                bias=np.array([900.0, -1300.0, 800.0]) * _MICRO_G,
                bias_instability_sigma=200.0 * _MGAL,
                bias_correlation_time_s=3600.0,
                white_noise_density=0.1 * _PER_SQRT_HOUR,
                scale_factor=sa,
                misalignment=ma,
                quantization_lsb=1.0e-2 * _GROVES_DT,
            ),
            g_sensitivity=np.array([[0.9, -1.1, -0.6], [-0.5, 1.9, -1.6], [0.3, 1.1, -1.3]])
            * _DEG_PER_HOUR_PER_G,
            name="tactical",
        )
    if name == "navigation":
        sa, ma = _split_m([[100, -120, 80], [-60, -120, 100], [-100, 40, 90]])
        sg, mg = _split_m([[8, -120, 100], [0, -6, -60], [0, 0, -7]])
        return ImuErrorModel(
            gyro=SensorErrors(
                bias=np.array([-0.0009, 0.0013, -0.0008]) * _DEG_PER_HOUR,
                bias_instability_sigma=0.027 * _DEG_PER_HOUR,
                bias_correlation_time_s=4.0 * 3600.0,
                white_noise_density=0.003 * _DEG_PER_SQRT_HOUR,
                scale_factor=sg,
                misalignment=mg,
                quantization_lsb=1.0e-6 * _GROVES_DT,
            ),
            accel=SensorErrors(
                bias=np.array([30.0, -45.0, 26.0]) * _MICRO_G,
                bias_instability_sigma=15.0 * _MGAL,
                bias_correlation_time_s=4.0 * 3600.0,
                white_noise_density=0.03 * _PER_SQRT_HOUR,
                scale_factor=sa,
                misalignment=ma,
                quantization_lsb=5.0e-5 * _GROVES_DT,
            ),
            name="navigation",
        )
    raise ConfigError("imu.preset", f"one of {', '.join(PRESET_NAMES)}", name)


def nominal_noise(model: ImuErrorModel) -> dict[str, Any]:
    """Nominal noise figures an estimator may be told (the specification, not the draws).

    The constant bias enters as a sigma: its RMS over the three axes (so the per-axis
    truth values are not revealed), combined with the turn-on sigma.

    Returns
    -------
    dict
        ``gyro_arw`` (rad/sqrt(s)), ``accel_vrw`` (m/s/sqrt(s)), ``gyro_noise_psd``,
        ``accel_noise_psd``, ``{gyro,accel}_bias_sigma`` (constant + turn-on),
        ``{gyro,accel}_bias_instability_sigma`` and ``..._bias_correlation_time_s``
        (Gauss-Markov), ``{gyro,accel}_rate_random_walk``, ``{gyro,accel}_scale_factor_sigma``
        (RMS over axes), ``{gyro,accel}_quantization_lsb``; arrays of shape (3,) except
        the LSBs. Units as in :class:`SensorErrors`.
    """
    result: dict[str, Any] = {
        "gyro_arw": model.gyro.white_noise_density.copy(),
        "accel_vrw": model.accel.white_noise_density.copy(),
        "gyro_noise_psd": model.gyro.white_noise_psd,
        "accel_noise_psd": model.accel.white_noise_psd,
    }
    for label, sensor in (("gyro", model.gyro), ("accel", model.accel)):
        rms_bias = math.sqrt(float(np.mean(sensor.bias**2)))
        result[f"{label}_bias_sigma"] = np.sqrt(sensor.turn_on_bias_sigma**2 + rms_bias**2)
        result[f"{label}_bias_instability_sigma"] = sensor.bias_instability_sigma.copy()
        result[f"{label}_bias_correlation_time_s"] = sensor.bias_correlation_time_s.copy()
        result[f"{label}_rate_random_walk"] = sensor.rate_random_walk.copy()
        rms_scale = math.sqrt(float(np.mean(sensor.scale_factor**2)))
        result[f"{label}_scale_factor_sigma"] = np.full(3, rms_scale)
        result[f"{label}_quantization_lsb"] = sensor.quantization_lsb
    return result


def nominal_imu(model: ImuErrorModel) -> NominalImu:
    """The IMU datasheet an estimator is told (:class:`navsim.types.NominalImu`).

    From :func:`nominal_noise`: RMS over the axes of the white-noise densities and rate
    random walks; bias sigma = hypot(RMS of the constant + turn-on sigma, RMS of the
    Gauss-Markov instability sigma); correlation time = the shortest of the axes.
    """
    from ...types import NominalImu

    nominal = nominal_noise(model)

    def rms(x: Any) -> float:
        return float(np.sqrt(np.mean(np.square(x))))

    return NominalImu(
        gyro_arw=rms(nominal["gyro_arw"]), accel_vrw=rms(nominal["accel_vrw"]),
        gyro_bias_sigma=float(np.hypot(rms(nominal["gyro_bias_sigma"]), rms(nominal["gyro_bias_instability_sigma"]))),
        accel_bias_sigma=float(np.hypot(rms(nominal["accel_bias_sigma"]), rms(nominal["accel_bias_instability_sigma"]))),
        gyro_bias_tau_s=float(np.min(nominal["gyro_bias_correlation_time_s"])),
        accel_bias_tau_s=float(np.min(nominal["accel_bias_correlation_time_s"])),
        gyro_rrw=rms(nominal["gyro_rate_random_walk"]), accel_rrw=rms(nominal["accel_rate_random_walk"]),
    )
