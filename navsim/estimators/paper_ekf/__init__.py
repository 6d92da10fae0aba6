"""The track-model INS/GNSS filter of seed 003 (Sokolov & Vdovichenko 2012).

The vehicle moves on a known track written as longitude and height functions of latitude,
lambda(phi), h(phi) (:mod:`navsim.track`). Position and velocity then have one degree of
freedom each, and the filter state shrinks to the paper's reduced vector (eq. (8))::

    Y = [alpha, beta, gamma, phi, V_Y]

alpha, beta, gamma being the Euler-Krylov angles of the body relative to the *inertial*
frame (Appendix 1, :func:`navsim.rotations.euler_krylov_matrix`; the inertial frame
coincides with the Greenwich frame at t = 0), phi the latitude and V_Y the north velocity.
East and up velocity follow from the track (003, after (6))::

    V_X = lambda'(phi) cos(phi) V_Y,    V_Z = h'(phi) V_Y / (r + h).

Equations implemented
---------------------
* State equations (7)-(8) with F, F1 of Appendix 2: ``[alpha', beta', gamma'] =
  Phi (Z_d - W_d)``, ``phi' = V_Y / (r + h)``, ``V_Y' = C_(2)^T (Z_a - W_a) + Coriolis,
  transport and centrifugal terms``, where ``C = D(alpha, beta, gamma) B^T`` maps ENU to
  body and ``B = D(-phi, lambda(phi) + Omega t, 0)`` maps the inertial frame (paper axes
  xi, eta, zeta = y_e, z_e, x_e) to ENU.
* The autonomous accelerometer observer (13): because the vehicle stays on the track,
  ``V_X = k(phi) V_Y`` with ``k = lambda' cos(phi)`` holds at all times, so the east
  equation of (1), (12), and the derivative of the constraint, (10)-(11), must agree.
  Equating them gives the x-accelerometer as a function of the state and of the other two
  accelerometers. Written compactly with ``u = e - k n`` (the east minus k times the north
  unit vector, body components ``u_b = C u_n``) and ``f_E - k f_N = u_b . Z_a``::

      u_b . Z_a = G(phi, V_Y),   G = k A(phi, V_Y) + k_phi V_Y^2 / (r + h) - B(phi, V_Y)
      Z_ax = H_a(Y, Z_ay, Z_az) + H_w W_a,
      H_a = (G - u_b,y Z_ay - u_b,z Z_az) / u_b,x,   H_w = u_b^T / u_b,x

  where A is the non-specific-force part of V_Y' (7) and B that of V_X' (12). This is
  (13) term by term (``c11 - k c12 = u_b,x``, ``k c22 - c21 = -u_b,y``, ...; the literal
  transcription :func:`printed_observer_13` is checked against it in the tests).
* The continuous filter (14) between GNSS epochs: ``Y' = F + K (Z_ax - H_a)``,
  ``K = (R dH_a/dY^T + F1 D_A H_w^T) (H_w D_a H_w^T)^-1`` and the Riccati equation for R,
  i.e. the Kalman-Bucy filter with correlated process and measurement noise (W_a drives
  V_Y and is in Z_ax).
* The discrete update (16) at GNSS epochs with the pseudoranges and Dopplers (9) of every
  valid satellite (H_R(phi), H_V(phi, V_Y), ECEF geometry from lambda(phi), h(phi),
  ``V_S = [k, 1, h'/(r+h)] V_Y``) stacked, as in (15), with the accelerometer
  observation. During outages (no valid satellite) only the accelerometer observer runs.

Printed formulas that are wrong (evidence in ``tests/estimators/test_paper_ekf.py``)
-----------------------------------------------------------------------------------
* Kinematics: the printed Phi(beta, gamma) of (1)/(7) is the kinematic matrix of D with
  alpha and beta interchanged (see :mod:`navsim.rotations`); used literally it drives the
  angles away from the true attitude within seconds (alpha ~ -phi ~ -47 deg here).
  Corrected: ``[alpha', beta', gamma'] = Phi(alpha, gamma) omega`` (finite differences of D).
* Centrifugal sign: (1), (7), Appendix 2 and (13) carry ``+Omega^2 (r+h) cos(phi)
  sin(phi)`` in V_Y'; the plumb-line gravity has ``-`` (:meth:`navsim.earth.EarthModel.
  gravity_n`). On the spherical Earth of the example that is a 2 x 0.017 = 0.034 m/s^2 error
  of the north acceleration.
* Appendix 3's H_w is ``(c11 - k c12)^-1 [C_(1)^T - k C_(2)^T]`` multiplied by the braces
  ``{(2 Omega + ...) V_Y (sin phi - ...)}`` that belong to H_a (the page break of the
  appendix spliced the end of H_a into H_w; H_a itself is cut off there). The dimensionally
  correct H_w is the one of (13), ``(c11 - k c12)^-1 [C_(1)^T - k C_(2)^T]``; navsim uses it
  in both modes. (1)'s Coriolis term (printed ``+ omega x V`` with 2 Omega on the north
  but not on the vertical Earth-rate component) is not needed: (7) and (12), which the
  filter uses, agree with ``-(2 omega_ie + omega_en) x V``.
* B: one place prints ``B = D(lambda + Omega t, -phi, 0)``; with D as printed only ``D(-phi,
  lambda + Omega t, 0)`` is the ENU frame (module notes of :mod:`navsim.rotations`); used
  throughout. Weighed together with Phi (:mod:`navsim.paper.seed003`, "Which printed matrix
  is wrong"): one misprint in Appendix 1 - alpha and beta interchanged in the printed D -
  makes both the printed Phi(beta, gamma) and the printed B exactly right, so the misprint
  most economically sits in D (printed once), not in Phi (printed three times) and B;
  navsim's choice (D as printed, Phi(alpha, gamma), B = D(-phi, lambda + Omega t, 0)) is
  the same filter with alpha and beta renamed.
* (16) weighs Z_ax with the intensity D_a as if it were a variance; a step-mean
  accelerometer sample has variance ``H_w D_a H_w^T / dt``, used here.

Modes
-----
``mode="faithful"``
    The paper's model: spherical Earth (r = the context Earth's radius if it is
    spherical, else :data:`navsim.earth.SPHERICAL`), the reduced 5-state, no receiver
    clock, white sensor noise only, Z_ax stacked into the epoch update (16).
    ``as_printed=False`` (default) uses the corrected kinematics and centrifugal sign;
    ``as_printed=True`` keeps both printed errors, or pass a subset of
    ``{"kinematics", "centrifugal"}`` to show one effect at a time.
``mode="extended"``
    Where the printed model falls short, each switched on only when needed:
    receiver clock bias and drift states (two-state clock, PSDs of the nominal GNSS spec)
    when ``context.gnss.clock_modelled`` (a standalone receiver's pseudoranges are off
    by thousands of metres otherwise); WGS-84 radii R_N, R_E in phi' = V_Y/(R_N + h),
    ``k = lambda' cos(phi) (R_E + h)/(R_N + h)``, the transport rates and the ellipsoidal
    ECEF position when ``context.earth`` is WGS-84 (the normal gravity has no north
    component there, so the centrifugal term of (7) drops); first-order Gauss-Markov
    accelerometer and gyro bias states (3 + 3) when the nominal IMU has bias sigmas
    (the accelerometer observer is biased one-to-one by an accelerometer bias, and a gyro
    bias integrates into the angles during an outage); Z_ax is *not* stacked into the
    epoch update (the continuous observer has already used that step's sample, so (16)
    counts one step twice, a 1 % effect on one second's accelerometer information);
    step-mean inputs (below). Not modelled in either mode: ionospheric and tropospheric
    delays and multipath correlation (a standalone receiver leaves metre-level position
    biases), IMU scale factors and misalignments (absorbed partly by the bias states).
Any track
    The equations need lambda(phi), h(phi). A :class:`~navsim.track.PolynomialTrack` is
    used exactly; a :class:`~navsim.track.PiecewisePolynomialTrack` of degree <= 3 piece by
    piece; any other track (e.g. a :class:`~navsim.track.SplineTrack` from waypoints) is
    turned into a *locally* interpolated lambda(phi), h(phi): quintic Hermite pieces in phi
    between nodes every ``node_step_m`` that match the track's exact value, slope and
    curvature (:class:`TrackFunctions`) - in both modes, since without lambda(phi) there
    is no filter. (A least-squares :func:`navsim.track.fit_polynomial_track` fit was tried
    first and rejected: its curvature errors become lateral-acceleration errors far above
    the accelerometer noise the observer (13) trusts.) Tracks whose latitude turns back
    cannot be written this way (ConfigError); near east-west headings (k -> infinity,
    u_b,x -> 0) the observer degrades. Use an arc-length estimator for those.

Antenna lever arm (navsim extension; option ``lever_arm``)
----------------------------------------------------------
The paper has no lever arm: its (2)-(3) measure the ranges and Dopplers at the track point
pos(phi), where the IMU is. navsim's receiver measures at the antenna, at
``context.gnss.lever_arm_b_m`` = l (body axes x right, y forward, z up) from the IMU
(:func:`navsim.sensors.gnss.antenna_state`). With ``lever_arm="auto"`` (default) and a
non-zero arm, the epoch update predicts the antenna's observables, in both modes, with the
filter's own attitude (the Euler-Krylov angles) and gyro rate::

    r_a = pos(phi) + C_eb l,                                                 (LA.1)
    v_a = V_Y t_e(phi) + C_eb (omega_ib_b x l) - omega_ie x C_eb l,          (LA.2)
    C_eb = C_ne(phi, lambda) C_nb = C_ne B(phi, lambda + Omega t) D^T(alpha, beta, gamma)
         = C_ep(t) D^T,   C_ep(t) = [[sin Omega t, 0, cos Omega t],
                                     [cos Omega t, 0, -sin Omega t], [0, 1, 0]]

(the ENU frame drops out of C_ne B: the paper's inertial axes xi, eta, zeta = y, z, x of
the Greenwich frame at t = 0, turned by the Earth's rotation; the tests check it against
:func:`navsim.earth.mat_en` and :func:`navsim.rotations.euler_krylov_matrix`). omega_ib_b is
the step-mean gyro rate dtheta_1/dt of the epoch's step, minus the gyro-bias states when
present. The measurement Jacobian (:meth:`PaperEkf.gnss_observation`) gains the attitude
columns (LA.4) - ``dD/dtheta_i = -[a_i x] D`` moves the antenna by ``C_ep D^T (a_i x l)``
and turns its velocity - and, with bias states, the gyro-bias columns of (LA.2); the
phi column (complex step) and the V_Y column are taken at the antenna (its line of sight).
The state vector is unchanged (faithful mode keeps the paper's 5 states); the output
stays the IMU's (track point). With a zero arm (or ``lever_arm="none"``: uncompensated,
the paper's model) the code is the paper's, number for number. The arm also makes the
GNSS observe attitude, weakly (3 m x 1 mrad = 3 mm).

Numerical choices
-----------------
* Inputs inside a step: navsim gives the r-fold integrals dtheta_r, dv_r (r = 1..R) of the
  step. ``input_model="polynomial"`` reconstructs omega(t) and f(t) as the
  polynomial of degree R-1 whose r-fold integrals match them exactly (an R x R inversion
  of ``I_r = dt^r sum_j c_j j!/(j+r)!``), so the RK4 stages see the rates at the step
  start, middle and end and Simpson's rule on the cubic returns dtheta_1, dv_1 exactly.
  ``input_model="mean"`` uses dtheta_1/dt, dv_1/dt. The polynomial is the default in
  faithful mode (white sensor noise, consistent across orders); extended mode defaults to
  the mean, because the reconstruction weights at the step ends are large ([-4, 60, -360,
  840] for R = 4 at the start) and amplify anything that makes the orders inconsistent -
  quantization of the first increment of a real IMU made the tactical preset's heading
  jump by 30 mrad in one step.
* The state (14) is integrated by RK4 every navigation step with the gain held over the
  step. The Riccati equation is integrated by RK4 with its coefficients (dF/dY,
  dH_a/dY, Q, correlation, H_w D_a H_w^T) frozen at the start of each covariance interval
  of ``cov_step_s`` (default: the navigation step; it must divide the GNSS period, and
  intervals end at epochs); the gain is held over the interval and the output covariance
  of the steps inside it is interpolated linearly. The gain K(t) = (R dH^T + S)/sigma^2
  of a fresh filter is enormous (the accelerometer observer resolves one attitude axis to
  ~1e-6 rad in a second, the prior is 1.7e-3 rad): the equations are stiff at the start,
  with rate ``dH K ~ 1/t``. Where ``rate x interval > stiffness_limit`` the interval is
  shortened, down to adaptive sub-steps of ``stiffness_limit / rate`` inside a step
  (about 2 ln(rate0 dt) / stiffness_limit sub-steps in all, ~30 at the start of the
  example), each with fresh coefficients and gain.
* The Jacobians of F and H_a are analytic in the angles and V_Y and use the complex-step
  derivative in phi (exact to rounding, no subtraction error; the track polynomials and
  radii are complex-safe); the tests compare them with central finite differences.
* Engines (option ``engine``). The filter is a sequential recursion - the coefficients of
  each covariance interval depend on the state, whose gain depends on the covariance - so
  nothing can be batched over steps without changing the filter; what a step costs is its
  arithmetic plus the interpreter's overhead. The reference engine (``"python"``)
  computes the stage values, the Jacobians, Q, S and sigma^2 in one scalar pass
  (:mod:`~navsim.estimators.paper_ekf.mechanization`; on the sphere the phi-derivatives are
  written out by the chain rule instead of a second, complex-step pass; the tests hold them
  to the complex step of the stage function), and integrates the Riccati equation as
  ``R' = [R; I]^T H [R; I]`` with ``H = [[-g g^T, Abar^T], [Abar, Qbar]]`` (``g = h /
  sigma``, ``Abar = A - S h^T / sigma^2``, ``Qbar = Q - S S^T / sigma^2``): two small
  matrix products per RK4 stage; same numbers as the direct form to rounding. The
  compiled engine (``"compiled"``, :mod:`navsim.estimators.paper_ekf.kernel`, numba,
  optional extra ``fast``; ``"auto"`` picks it when numba is installed) runs the same
  expressions in the same order for the steps between GNSS epochs, with the matrix
  products as loops, and hands the start-up sub-steps, failures and epoch updates (16)
  back to the reference code; it also computes the outputs, and the step-wise
  :meth:`PaperEkf.step` does a step without an epoch in one compiled call. The two engines
  agree to rounding (the tolerance and its reason: ``tests/estimators/
  test_paper_ekf_engine.py``; figures: ``benchmarks/RESULTS.md``).
* The prior (9 x 9 over ENU position, velocity, attitude) is projected on the state by
  weighted least squares along the track (phi and V_Y) and by the attitude Jacobian.
* Output: lat = phi, lon = lambda(phi), h = h(phi), velocity_n = [k V_Y, V_Y, m V_Y],
  heading/pitch/roll of ``mat_nb = B(phi, lambda + Omega t) D^T``; the 9 x 9 covariance
  is ``J R J^T`` with J the Jacobian of that conversion (rank 5: position errors only along
  the track; attitude errors psi = mat_nb sum_i a_i dtheta_i - theta_n dphi about ENU axes,
  theta_n = [-1, lambda' cos phi, lambda' sin phi] dphi the rotation of the ENU frame).

Modules
-------
* :mod:`~navsim.estimators.paper_ekf.config`: the options, validated (:class:`PaperEkfConfig`).
* :mod:`~navsim.estimators.paper_ekf.track_functions`: lambda(phi), h(phi) of the track
  (:class:`TrackFunctions`).
* :mod:`~navsim.estimators.paper_ekf.filter`: the estimator :class:`PaperEkf` (options,
  reset, step, step_row, step_batch), built from one layer per part of the filter:
* :mod:`~navsim.estimators.paper_ekf.state`: the model's constants, :func:`paper_state` (8),
  the prior's projection on the state.
* :mod:`~navsim.estimators.paper_ekf.mechanization`: (7)-(8) and the observer (13), the
  stage function and the one-pass coefficients of (14).
* :mod:`~navsim.estimators.paper_ekf.covariance`: (14)'s Riccati equation as a quadratic
  form, the gain.
* :mod:`~navsim.estimators.paper_ekf.gnss`: the measurement model (9) with the lever arm,
  the epoch update (16).
* :mod:`~navsim.estimators.paper_ekf.outputs`: the navigation solution and its covariance.
* :mod:`~navsim.estimators.paper_ekf.python_engine`: the reference engine (``engine="python"``).
* :mod:`~navsim.estimators.paper_ekf.compiled_engine`: the compiled engine's buffers, hand-overs
  and step-wise paths.
* :mod:`~navsim.estimators.paper_ekf.numerics`: the polynomial input model and the Riccati RK4.
* :mod:`~navsim.estimators.paper_ekf.kernel`: the compiled engine (numba, extra ``fast``).
* :mod:`~navsim.estimators.paper_ekf.printed`: the printed formulas, literally, for the checks.

References
----------
.. [003] Sokolov S.V., Vdovichenko S.S., "Synthesis of algorithms of inertial-satellite
   navigation systems on the basis of spatial models of motion", Nauchnoe
   Priborostroenie, 2012 (seed 003): eqs. (1), (7)-(16), Appendices 1-3.
.. [2] Tikhonov V.I., Kharisov V.N., Statistical analysis and synthesis of radio
   engineering devices and systems, 1991 (ref. [6] of 003): Gaussian continuous-discrete
   filtering.
.. [3] Brown R.G., Hwang P.Y.C., Introduction to Random Signals and Applied Kalman
   Filtering, 4th ed., 2012: Kalman-Bucy filter with correlated process and measurement
   noise (sec. 8.2), two-state clock model (sec. 9.3), Joseph form.
.. [4] Martins J.R.R.A., Sturdza P., Alonso J.J., "The complex-step derivative
   approximation", ACM TOMS 29 (2003) 245-262.
.. [5] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
   Systems, 2nd ed., 2013, sec. 2.4 and 5.4 (local-level mechanisation), 14.2.3 and
   14.3.3 (the lever arm in the measurement models).
"""


from .config import PaperEkfConfig
from .filter import PaperEkf, paper_state
from .numerics import input_polynomial_matrix
from .printed import printed_observer_13, printed_state_rhs
from .track_functions import TrackFunctions

__all__ = [
    "PaperEkf",
    "PaperEkfConfig",
    "TrackFunctions",
    "paper_state",
    "input_polynomial_matrix",
    "printed_observer_13",
    "printed_state_rhs",
]
