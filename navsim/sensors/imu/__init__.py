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

Modules
-------
* :mod:`~navsim.sensors.imu.integrals`: true multiple integrals, the white-noise covariance.
* :mod:`~navsim.sensors.imu.error_model`: :class:`SensorErrors`, :class:`ImuErrorModel`.
* :mod:`~navsim.sensors.imu.state`: :class:`ImuState`, :class:`ImuOutput`.
* :mod:`~navsim.sensors.imu.apply`: :func:`apply_imu_errors` (``apply.USE_KERNEL`` switches the
  compiled pass off).
* :mod:`~navsim.sensors.imu.kernel`: the compiled white-noise pass (numba, extra ``fast``).
* :mod:`~navsim.sensors.imu.presets`: the presets, :func:`nominal_imu`.

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

from .apply import (
    QUANTIZATION_BLOCK,
    apply_imu_errors,
    apply_imu_errors_batch,
    apply_imu_errors_batch_state,
    first_order_recursion,
)
from .error_model import ImuErrorModel, SensorErrors, VibrationHarmonic
from .integrals import (
    MAX_ORDER,
    apply_multiple_integral_rule,
    compose_multiple_integrals,
    harmonic_multiple_integrals,
    multiple_integral_rule,
    white_noise_integral_covariance,
)
from .presets import PRESET_NAMES, imu_preset, is_error_free, nominal_imu, nominal_noise
from .state import BatchImuState, ImuOutput, ImuState

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
    "BatchImuState",
    "ImuOutput",
    "apply_imu_errors",
    "apply_imu_errors_batch",
    "apply_imu_errors_batch_state",
    "imu_preset",
    "nominal_noise",
    "nominal_imu",
    "first_order_recursion",
]
