"""GNSS: constellations, pseudorange and Doppler, receiver clock (the fixes: :mod:`navsim.receiver`).

The observables are those of seed 003 (eqs. (2), (3) and their ECEF form (6)):

* pseudorange (code measurement), eq. (2)::

      Z_R = |r_sat_e - r_e| + W_R

* pseudorange rate (the Doppler observable, "pseudo-velocity"), eq. (3)::

      Z_V = (r_sat_e - r_e) . (v_sat_e - v_e) / |r_sat_e - r_e| + W_V

  i.e. the time derivative of the geometric range in the Greenwich (ECEF) frame, both
  velocities being ECEF-frame derivatives (the satellite velocity therefore contains the
  ``-omega_ie x r`` term of the rotating frame). Eq. (3) is exactly d|r_sat - r|/dt; we
  found no misprint in (2), (3) or (6). Seed 003 writes its Greenwich axes as
  (xi, eta, zeta) = (y_e, z_e, x_e), a cyclic permutation of standard ECEF, so the
  formulas hold unchanged in the ECEF axes used here (see :mod:`navsim.earth`).

Seed 003 lumps all errors into white noise W_R, W_V (15 m and 0.5 m/s in its example,
receiver clock "compensated"). :class:`GnssErrorModel` reproduces that ("paper-2012") and
adds, for standalone studies, a two-state receiver clock (bias, drift) driven by the
Allan-variance coefficients h0, h-2, ionospheric and tropospheric delays with elevation
mapping functions, and first-order Gauss-Markov multipath per satellite.

Simplification (shared with seed 003 eq. (2)): the geometric range is taken between the
satellite and receiver positions *at the same (reception) instant* in ECEF. Signal
transit time (~70 ms, the satellite moves ~270 m inertially meanwhile) and the Sagnac
(Earth-rotation) correction (up to ~30 m) are not modelled. Simulator and estimators use
the same model, so nothing is inconsistent; just do not feed real receiver data through
these functions without those corrections. Satellite clock errors (af0, af1 of the
almanac) are treated as corrected.

Orbits are Keplerian with a secular node drift (the J2 rate for the Walker sets, the
almanac value for YUMA files), propagated with the GPS almanac algorithm of IS-GPS-200
(Table 20-IV) with the mean motion from the Earth model's GM.

Modules
-------
* :mod:`~navsim.sensors.gnss.constants`: speed of light, IS-GPS-200 Earth rate, J2.
* :mod:`~navsim.sensors.gnss.constellation`: :class:`Constellation`, Walker sets.
* :mod:`~navsim.sensors.gnss.yuma`: YUMA almanac files, the packaged almanac.
* :mod:`~navsim.sensors.gnss.orbits`: Kepler, satellite states, elevation and azimuth.
* :mod:`~navsim.sensors.gnss.antenna`: the antenna lever arm (LA.1)-(LA.2).
* :mod:`~navsim.sensors.gnss.error_model`: :class:`GnssErrorModel`, epoch simulation.
* The receiver's least-squares fixes: :mod:`navsim.receiver` (re-exported here).

References
----------
.. [1] Sokolov S.V., Vdovichenko S.S. (2012), seed 003, eqs. (2), (3), (4), (6) and the
       example (sigma_R = 15 m, sigma_V = 0.5 m/s).
.. [2] IS-GPS-200, Navstar GPS Space Segment / Navigation User Interfaces, Table 20-IV
       (user algorithm for ephemeris / almanac): Omega_k = Omega_0 + (Omega_dot -
       Omega_e_dot) t_k - Omega_e_dot t_oa; Omega_e_dot = 7.2921151467e-5 rad/s.
.. [3] Walker J.G. (1984), Satellite constellations, J. British Interplanetary Society
       37, 559-572 (Walker delta patterns T/P/F).
.. [4] GLONASS Interface Control Document, ed. 5.1 (2008), section 3.5: 24 satellites in
       3 planes 120 deg apart, 8 per plane, 15 deg argument-of-latitude shift between
       planes (= Walker 24/3/1), a = 25 510 km, i = 64.8 deg.
.. [5] Vallado D.A., Fundamentals of Astrodynamics and Applications, 4th ed., 2013,
       section 9.6: secular J2 node rate Omega_dot = -1.5 n J2 (R/p)^2 cos i.
.. [6] Brown R.G., Hwang P.Y.C., Introduction to Random Signals and Applied Kalman
       Filtering, 4th ed., 2012, section 9.3: two-state clock model with
       S_f = h0/2, S_g = 2 pi^2 h_-2 and its discrete process noise; Table 9.1 typical
       TCXO values h0 = 2e-19, h_-1 = 7e-21, h_-2 = 2e-20 (flicker h_-1 is not
       representable by the two-state model and is omitted).
.. [7] Allan variance of white FM and random-walk FM: sigma_y^2(tau) = h0/(2 tau)
       + (2 pi^2/3) h_-2 tau (IEEE Std 1139-2008; NIST TN 1337).
.. [8] Misra P., Enge P., Global Positioning System: Signals, Measurements and
       Performance, 2nd ed., 2006, chapter 5: single-layer (thin-shell, 350 km)
       ionospheric obliquity factor 1/sqrt(1 - (R cos E / (R + h_I))^2).
.. [9] RTCA DO-229D (2006), Appendix A.4.2.4: tropospheric mapping function
       m(E) = 1.001 / sqrt(0.002001 + sin^2 E); and J.2.4 airborne multipath
       sigma = 0.13 + 0.53 exp(-E/10 deg) m (the shape used for multipath here).
.. [10] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated
       Navigation Systems, 2nd ed., 2013, sections 14.2.3 and 14.3.3: the
       antenna lever arm (:func:`antenna_state`).
"""

# The receiver's own fixes live receiver-side (the estimators use them too); re-exported here.
from ...receiver import Fix, VelocityFix, least_squares_fix, velocity_fix
from .antenna import antenna_state
from .constants import C_LIGHT, REFERENCE_ALMANAC
from .constants import J2_WGS84 as J2_WGS84  # public constants outside __all__
from .constants import OMEGA_E_GPS as OMEGA_E_GPS
from .constants import SECONDS_PER_WEEK as SECONDS_PER_WEEK
from .constellation import Constellation, walker_constellation
from .error_model import GnssEpochs, GnssErrorModel, GnssState, simulate_epochs, simulate_epochs_batch
from .orbits import SkyGeometry, elevation_azimuth, satellite_states, sky_geometry, solve_kepler
from .yuma import load_yuma, reference_almanac, write_yuma

__all__ = [
    "C_LIGHT",
    "Constellation",
    "walker_constellation",
    "load_yuma",
    "write_yuma",
    "reference_almanac",
    "REFERENCE_ALMANAC",
    "solve_kepler",
    "satellite_states",
    "elevation_azimuth",
    "SkyGeometry",
    "sky_geometry",
    "antenna_state",
    "GnssErrorModel",
    "GnssState",
    "GnssEpochs",
    "simulate_epochs",
    "simulate_epochs_batch",
    "Fix",
    "VelocityFix",
    "least_squares_fix",
    "velocity_fix",
]
