"""Shared error-state INS machinery: the 15-state ENU error model and a propagation engine.

Used by the INS-only, loosely coupled and (optionally) tightly coupled estimators. Two
layers:

* pure functions of the linearised error model: :func:`error_dynamics` (the continuous
  matrix F), :func:`noise_density` (Qc), :func:`transition` (Phi and Qd over a time span by
  the series below), :func:`joseph_update`, :func:`correct_state`,
  :func:`compensate_increments`, :func:`solution_rows`, :func:`lever_arm_terms` (the
  GNSS antenna's offset, velocity and their error partials (LA.3) for the aided filters);
* :class:`ErrorStateIns`, a stateful engine: the INS mechanisation of
  :func:`navsim.strapdown.ins.integrate` on bias-compensated increments, the 15 x 15
  covariance propagated once per *covariance interval*, and closed-loop (feedback)
  measurement updates. An estimator owns one engine, calls :meth:`ErrorStateIns.advance`
  with the IMU data of one or many steps and :meth:`ErrorStateIns.update` with a linear
  (linearised) measurement of the error state;
* :class:`AuxStateIns`, the same engine with auxiliary error states whose dynamics do not
  involve the INS errors (random walks: e.g. a wheel-odometer scale factor), and
  :func:`body_velocity_terms`, the body-frame velocity and its error partials of the
  odometer / non-holonomic-constraint updates.

Error state (15,), every navigation error "estimate minus truth" as in
:mod:`navsim.estimators.base`::

    x = [dE, dN, dU (m),  dvE, dvN, dvU (m/s),  psiE, psiN, psiU (rad),
         eg_x, eg_y, eg_z (rad/s),  ea_x, ea_y, ea_z (m/s^2)]

``psi``: ``mat_nb_est = (I + [psi x]) mat_nb_true``. ``eg``, ``ea``: the *residual* gyro and
accelerometer biases in body axes, ``b_true - b_est``, i.e. what is left in the compensated
outputs ``omega_est = omega_true + eg``, ``f_est = f_true + ea``. The feedback adds the
estimated residual to the bias estimate (``b_est += eg_hat``) and removes the navigation
errors from the INS (``lat -= dN / (R_N + h)`` ..., ``mat_nb <- (I - [psi x]) mat_nb``).

Error dynamics (derived here in ENU with metric position errors; Groves 2013 eqs.
(14.63)-(14.71) give the NED/curvilinear form of the same model)::

    psi'  = -omega_in x psi - d omega_in + C eg                         (a)
    dv'   = -f_n x psi + C ea - (2 omega_ie + omega_en) x dv
            - (2 d omega_ie + d omega_en) x v + dg                       (b)
    dN'   = dvN + vU/RN' dN - vN/RN' dU                                 (c)
    dE'   = dvE + (R_E,lat L'/RE' + vU/RE' - tan(L) L') dE
            - vE (R_E,lat/RE' - tan L) dN/RN' - vE/RE' dU                (d)
    dU'   = dvU
    eg'   = -eg / tau_g + w_g,    ea' = -ea / tau_a + w_a               (e)

with ``RN' = R_N + h``, ``RE' = R_E + h``, ``L' = vN / RN'``, ``R_E,lat = dR_E/dlat``,
``C = mat_nb``, ``f_n = C f_b`` and ``d omega``, ``dg`` the first-order changes of the Earth
rate, transport rate and gravity with dL = dN/RN', dh = dU, dv. (a) follows from
differentiating ``C_est = (I + Psi) C`` with both attitude equations of
:mod:`navsim.strapdown.ins`; (c), (d) from ``dN = RN' dlat``, ``dE = RE' cos(L) dlon``.
tests/estimators/test_loosely.py checks F against finite differences of the nonlinear
mechanisation equations.

Unmodelled scale factor and misalignment (options, off by default): the attitude error
grows by ``-C S omega`` with S the gyros' scale-factor/misalignment matrix; with the
elements of S independent of sigma_s, ``cov(C S omega) = sigma_s^2 |omega|^2 I`` for any
C, so it is covered as isotropic attitude noise of PSD

    q_S = sigma_s^2 |omega|^2 tau_S                                                (RS.1)

added to Qc's attitude block for each covariance interval, |omega| the mean rate of the
interval before (the angle of the attitude change over it divided by its length, as the
mean specific force), tau_S the correlation time of S omega (``scale_tau_s``, about
the length of a turn: the error of one turn adds coherently, sigma_s^2 |omega|^2 T^2
for a turn of T at a constant rate, which (RS.1) gives for T = tau_S). The
accelerometers' matrix S_a likewise, on the velocity block:

    q_Sa = sigma_a^2 |f_n + g_n|^2 tau_S                                           (RS.2)

with the kinematic acceleration ``f_n + g_n`` of the interval before (the gravity part
of ``S_a f`` is constant in body axes while the vehicle stays level, a bias the bias
states absorb).

Noise: white gyro and accelerometer noise enter (a), (b) through C with PSDs ARW^2 and
VRW^2 (isotropic, so C drops out of Qc); the biases are first-order Gauss-Markov with the
nominal sigma and correlation time, driving PSD ``2 sigma^2 / tau``, plus the
rate-random-walk PSD (``tau = inf`` makes them random walks / random constants).

Covariance intervals (the speed device)
---------------------------------------
Propagating a 15 x 15 covariance at every 100 Hz step costs more than the INS itself. The
engine builds F once per *interval* (at most ``interval_steps`` navigation steps, ended
early by a measurement update) from the state at the interval start and the mean
specific force ``f_n`` of the previous interval, and uses over the interval

    Phi(tau) = I + F tau + F^2 tau^2/2 + F^3 tau^3/6 + F^4 tau^4/24     (4th-order series)
    Qd(tau)  = int_0^tau Phi(s) Qc Phi(s)^T ds   with Phi(s) to 2nd order:
             = Qc tau + A tau^2/2 + B tau^3/3 + C3 tau^4/4 + D tau^5/5,
      A = F Qc + Qc F^T,  B = F Qc F^T + (F^2 Qc + Qc F^2T)/2,
      C3 = (F^2 Qc F^T + F Qc F^2T)/2,  D = F^2 Qc F^2T / 4
    P(tau)   = Phi(tau) P0 Phi(tau)^T + Qd(tau)                          # P = F P F^T + Q

The reported covariance at every step inside the interval is this P(tau) (so NEES is
meaningful between GNSS epochs too), and the covariance at the interval end starts the
next one. The chain position <- velocity <- attitude <- gyro bias is cubic in tau; the
fourth-order term carries its coupling with the bias correlation time and the Earth and
transport rates (the tests compare Phi with expm(F tau)). Everything used at step j of an
interval is known at step j, so stepping one step at a time and advancing many steps at once give the same
numbers (to rounding): the contract of ``step_batch``.

Bias compensation: the biases are constant between updates. :func:`body_terms` computes
the body-frame strapdown terms of a whole batch once from the raw IMU data (the same
registry methods and second-order rotation terms as :func:`navsim.strapdown.ins.integrate`),
and :meth:`BodyTerms.compensated` removes the current bias estimates from them linearly,
exact to first order in the biases and for the bilinear rotation terms (derivation there);
the remainder is of order ``b x omega' T^3`` per step. The sequential loop is the
strapdown module's own (:func:`navsim.strapdown.ins.integrate_body_terms`, run with
``method="sequential"``). :func:`compensate_increments` removes constant
biases from raw increments exactly (``b dt^r / r!`` per order), the reference the tests
compare the linear form with.

Modules
-------
* :mod:`~navsim.estimators._inserror.model`: the state layout, :class:`ImuNoise`, F, Qc, the
  transition series, the Joseph update, the correction, the lever-arm terms.
* :mod:`~navsim.estimators._inserror.terms`: the body-frame strapdown terms and their bias
  compensation.
* :mod:`~navsim.estimators._inserror.engine`: :class:`ErrorStateIns` and its auxiliary-state forms.

References
----------
.. [1] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., Artech House, 2013: sections 14.2 (INS error propagation,
       local-navigation-frame form), 14.1.3 (closed-loop correction), 3.2.2 and 3.4
       (discrete system and process noise, Joseph form).
.. [2] Savage P.G., Strapdown Analytics, 2nd ed., 2007, ch. 12 (error equations).
.. [3] Van Loan C.F. (1978), Computing integrals involving the matrix exponential, IEEE
       TAC 23(3): the integral that the Qd series above truncates.
.. [4] Groves (2013) [1], sections 14.2.3 and 14.3.3: the antenna lever arm in the
       measurement models (:func:`lever_arm_terms`).
"""

from .engine import AuxBlocksIns, AuxStateIns, ErrorStateIns, body_velocity_terms, nis_threshold
from .model import (
    ATT,
    BA,
    BG,
    N_STATES,
    NAV,
    POS,
    VEL,
    ImuNoise,
    compensate_increments,
    correct_state,
    error_dynamics,
    joseph_update,
    lever_arm_terms,
    noise_density,
    solution_rows,
    state_from_prior,
    transition,
)
from .terms import BodyTerms, StepTerms, body_terms

__all__ = [
    "N_STATES",
    "POS",
    "VEL",
    "ATT",
    "BG",
    "BA",
    "NAV",
    "ImuNoise",
    "error_dynamics",
    "noise_density",
    "transition",
    "joseph_update",
    "correct_state",
    "lever_arm_terms",
    "compensate_increments",
    "solution_rows",
    "state_from_prior",
    "BodyTerms",
    "StepTerms",
    "body_terms",
    "ErrorStateIns",
    "AuxBlocksIns",
    "AuxStateIns",
    "body_velocity_terms",
    "nis_threshold",
]
