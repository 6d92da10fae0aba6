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

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ...earth import WGS84, EarthModel, mat_en
from ...errors import ConfigError, check_nonnegative, file_value

# The receiver's own fixes live receiver-side (the estimators use them too); re-exported here.
from ...receiver import Fix, VelocityFix, least_squares_fix, velocity_fix
from .._common import frozen_array

if TYPE_CHECKING:
    from ...types import NominalGnss

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

C_LIGHT = 299_792_458.0
"""Speed of light in vacuum, m/s."""

OMEGA_E_GPS = 7.2921151467e-5
"""Earth rotation rate of IS-GPS-200, rad/s (used only to read/write YUMA node angles)."""

J2_WGS84 = 1.08262668e-3
"""Second zonal harmonic (WGS-84 / EGM96, NIMA TR8350.2), for the Walker node rate."""

SECONDS_PER_WEEK = 604_800.0

REFERENCE_ALMANAC = "gps_walker_24_6_1.alm"
"""File name of the packaged YUMA almanac (navsim/data/almanac)."""


# ====================================================================== constellations
@dataclass(frozen=True, slots=True, eq=False)
class Constellation:
    """Keplerian elements of a satellite constellation.

    Parameters
    ----------
    name : str
        Label, e.g. ``"gps"``.
    prn : ndarray of int, shape (m,)
        Satellite ids (PRN or slot numbers), unique.
    semi_major_axis_m, eccentricity, inclination_rad : ndarray, shape (m,)
        Orbit size, shape (0 <= e < 1) and inclination.
    raan_rad : ndarray, shape (m,)
        Right ascension (longitude) of the ascending node *measured from the Greenwich
        meridian at the reference epoch*, i.e. the ECEF longitude of the node at that
        instant (the almanac's Omega_0 - Omega_e t_oa).
    arg_perigee_rad : ndarray, shape (m,)
        Argument of perigee omega.
    mean_anomaly_rad : ndarray, shape (m,)
        Mean anomaly at the reference epoch.
    raan_rate_rps : ndarray, shape (m,)
        Inertial rate of the right ascension (node precession), rad/s.
    epoch_offset_s : float
        Scenario time of the reference epoch (the elements apply at t = epoch_offset_s).
    """

    name: str
    prn: np.ndarray
    semi_major_axis_m: np.ndarray
    eccentricity: np.ndarray
    inclination_rad: np.ndarray
    raan_rad: np.ndarray
    arg_perigee_rad: np.ndarray
    mean_anomaly_rad: np.ndarray
    raan_rate_rps: np.ndarray
    epoch_offset_s: float = 0.0

    _ELEMENTS = (
        "semi_major_axis_m",
        "eccentricity",
        "inclination_rad",
        "raan_rad",
        "arg_perigee_rad",
        "mean_anomaly_rad",
        "raan_rate_rps",
    )

    def __post_init__(self) -> None:
        prn = np.atleast_1d(np.asarray(self.prn))
        if prn.ndim != 1 or prn.size == 0 or not np.issubdtype(prn.dtype, np.integer):
            raise ConfigError("constellation.prn", "a non-empty 1-D integer array", self.prn)
        if np.unique(prn).size != prn.size:
            raise ConfigError("constellation.prn", "unique satellite ids", prn.tolist())
        object.__setattr__(self, "prn", frozen_array(prn, dtype=int))
        m = prn.size
        for name in self._ELEMENTS:
            value = np.asarray(getattr(self, name), dtype=float)
            if value.ndim == 0:
                value = np.full(m, float(value))
            if value.shape != (m,) or not np.all(np.isfinite(value)):
                raise ConfigError(
                    f"constellation.{name}", f"{m} finite values (one per satellite)", value
                )
            object.__setattr__(self, name, frozen_array(value))
        if np.any(self.semi_major_axis_m <= 0.0):
            raise ConfigError(
                "constellation.semi_major_axis_m", "positive values", self.semi_major_axis_m
            )
        if np.any((self.eccentricity < 0.0) | (self.eccentricity >= 1.0)):
            raise ConfigError(
                "constellation.eccentricity", "values in [0, 1)", self.eccentricity
            )
        epoch = float(self.epoch_offset_s)
        if not np.isfinite(epoch):
            raise ConfigError("constellation.epoch_offset_s", "a finite number", epoch)
        object.__setattr__(self, "epoch_offset_s", epoch)

    @property
    def n_satellites(self) -> int:
        """Number of satellites m."""
        return int(self.prn.size)

    def select(self, keep) -> Constellation:
        """A sub-constellation: ``keep`` is a boolean mask (m,) or an index array."""
        keep = np.asarray(keep)
        return Constellation(
            name=self.name,
            prn=self.prn[keep],
            **{name: getattr(self, name)[keep] for name in self._ELEMENTS},
            epoch_offset_s=self.epoch_offset_s,
        )


def _j2_node_rate(a: np.ndarray, e: np.ndarray, inc: np.ndarray, gm: float) -> np.ndarray:
    """Secular J2 node rate -1.5 n J2 (R/p)^2 cos i (Vallado sec. 9.6), rad/s."""
    n = np.sqrt(gm / a**3)
    p = a * (1.0 - e**2)
    return -1.5 * n * J2_WGS84 * (WGS84.a / p) ** 2 * np.cos(inc)


_WALKER = {
    # kind: (T, P, F, a [m], i [deg], first prn)
    "gps": (24, 6, 1, 26_559_700.0, 55.0, 1),
    "glonass": (24, 3, 1, 25_510_000.0, 64.8, 1),
}


def walker_constellation(
    kind: str = "gps",
    *,
    phase_rad: float = 0.0,
    anomaly_offset_rad: float = 0.0,
    eccentricity: float | np.ndarray = 0.0,
    arg_perigee_rad: float | np.ndarray = 0.0,
    node_precession: bool = True,
    epoch_offset_s: float = 0.0,
) -> Constellation:
    """A GPS-like or GLONASS-like Walker delta constellation T/P/F.

    ``"gps"``: Walker 24/6/1, a = 26 559.7 km, i = 55 deg - a uniform stand-in for the
    published 24-slot GPS baseline (6 planes A-F 60 deg apart, 4 slots each; the real
    slots are unevenly spaced within a plane, which the Walker pattern does not copy).
    ``"glonass"``: Walker 24/3/1, a = 25 510 km, i = 64.8 deg, which *is* the GLONASS
    ICD pattern (3 planes, 8 slots 45 deg apart, 15 deg shift between planes).

    Satellite j (0..S-1, S = T/P) of plane p (0..P-1) has
    RAAN = phase + 2 pi p / P and mean argument of latitude (omega + M)
    = anomaly_offset + 2 pi j / S + 2 pi F p / T (Walker 1984).

    Parameters
    ----------
    kind : {"gps", "glonass"}
    phase_rad : float
        Rotation of the whole constellation about the Earth's axis (the node longitude
        of plane 0 at the reference epoch); varies the geometry seen by a scenario.
    anomaly_offset_rad : float
        Advance of every satellite along its orbit at the reference epoch.
    eccentricity, arg_perigee_rad : float or ndarray (T,)
        Orbit shape (0 for the nominal circular Walker pattern).
    node_precession : bool
        Include the secular J2 node rate (about -7.8e-9 rad/s for GPS).
    epoch_offset_s : float
        Scenario time of the reference epoch.
    """
    try:
        total, planes, f, a, inc_deg, first = _WALKER[kind]
    except (KeyError, TypeError):
        raise ConfigError("constellation.kind", f"one of {sorted(_WALKER)}", kind) from None
    per_plane = total // planes
    plane = np.repeat(np.arange(planes), per_plane)
    slot = np.tile(np.arange(per_plane), planes)
    raan = float(phase_rad) + 2.0 * np.pi * plane / planes
    mean_anomaly = (
        float(anomaly_offset_rad)
        + 2.0 * np.pi * slot / per_plane
        + 2.0 * np.pi * f * plane / total  # Walker inter-plane phasing
    )
    sma = np.full(total, a)
    argp = np.broadcast_to(np.asarray(arg_perigee_rad, dtype=float), (total,))
    mean_anomaly = mean_anomaly - argp  # the Walker slot fixes the mean argument of latitude
    ecc = np.broadcast_to(np.asarray(eccentricity, dtype=float), (total,)).copy()
    inc = np.full(total, np.radians(inc_deg))
    rate = _j2_node_rate(sma, ecc, inc, WGS84.gm) if node_precession else np.zeros(total)
    return Constellation(
        name=kind,
        prn=np.arange(first, first + total),
        semi_major_axis_m=sma,
        eccentricity=ecc,
        inclination_rad=inc,
        raan_rad=np.angle(np.exp(1j * raan)),
        arg_perigee_rad=argp,
        mean_anomaly_rad=np.angle(np.exp(1j * mean_anomaly)),
        raan_rate_rps=rate,
        epoch_offset_s=epoch_offset_s,
    )


# ---------------------------------------------------------------------------- YUMA
_YUMA_KEYS = {
    "id": "id",
    "health": "health",
    "eccentricity": "eccentricity",
    "timeofapplicability": "toa",
    "orbitalinclination": "inclination",
    "rateofrightascen": "raan_rate",
    "sqrt(a)": "sqrt_a",
    "rightascenat": "raan0",  # "at Week" or "at TOA"
    "argumentofperigee": "arg_perigee",
    "meananom": "mean_anomaly",
    "af0": "af0",
    "af1": "af1",
    "week": "week",
}
_YUMA_REQUIRED = (
    "id",
    "eccentricity",
    "toa",
    "inclination",
    "raan_rate",
    "sqrt_a",
    "raan0",
    "arg_perigee",
    "mean_anomaly",
    "week",
)


def _yuma_key(label: str) -> str | None:
    compact = re.sub(r"\s+", "", label).lower()
    for prefix, key in _YUMA_KEYS.items():
        if compact.startswith(prefix):
            return key
    return None


def load_yuma(
    path: str | Path,
    *,
    epoch_offset_s: float = 0.0,
    healthy_only: bool = True,
    name: str | None = None,
) -> Constellation:
    """Read a YUMA almanac (the text format published by the US Coast Guard NAVCEN).

    Each record starts with a ``******** Week N almanac for PRN-xx ********`` line and
    holds ``label: value`` lines (ID, Health, Eccentricity, Time of Applicability(s),
    Orbital Inclination(rad), Rate of Right Ascen(r/s), SQRT(A) (m 1/2), Right Ascen at
    Week(rad), Argument of Perigee(rad), Mean Anom(rad), Af0(s), Af1(s/s), week).

    All records are brought to one reference epoch, the time of applicability of the
    first record, which is placed at scenario time ``epoch_offset_s``. The stored node
    angle is Omega_0 - Omega_e t_oa (IS-GPS-200 Table 20-IV, Omega_e of IS-GPS-200);
    records with another week/t_oa are propagated (mean anomaly and node) to the common
    epoch. Week numbers are used as written (the same 1024-week roll-over is assumed).

    Raises
    ------
    ConfigError
        On a malformed file; the message names the file and the line.
    """
    path = Path(path)
    try:
        lines = path.read_text(encoding="ascii", errors="replace").splitlines()
    except OSError as exc:
        raise ConfigError("almanac", "a readable YUMA file", str(path)) from exc
    source = str(path.name)
    records: list[dict[str, float]] = []
    starts: list[int] = []
    current: dict[str, float] | None = None
    for number, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("*"):
            current = {}
            records.append(current)
            starts.append(number)
            continue
        if current is None:
            raise ConfigError(
                f"line {number}", "a '******** Week N almanac for PRN-xx' header", file_value(line), source
            )
        label, sep, value = line.partition(":")
        key = _yuma_key(label) if sep else None
        if key is None:
            raise ConfigError(f"line {number}", "a YUMA 'label: value' line", file_value(line), source)
        try:
            number_value = float(value.strip())
        except ValueError:
            raise ConfigError(
                f"line {number}", "a number", file_value(value.strip()), source
            ) from None
        if not np.isfinite(number_value):
            raise ConfigError(f"line {number}", "a finite number", file_value(value), source)
        if key in current:
            raise ConfigError(f"line {number}", "one value of each label per record", file_value(line), source)
        current[key] = number_value
    if not records:
        raise ConfigError("almanac", "at least one YUMA record", str(path.name), source)
    for rec, start in zip(records, starts):
        missing = [k for k in _YUMA_REQUIRED if k not in rec]
        if missing:
            raise ConfigError(
                f"record at line {start}", f"fields {missing} to be present", sorted(rec), source
            )
        if not 0.0 <= rec["eccentricity"] < 1.0 or rec["sqrt_a"] <= 0.0:
            raise ConfigError(
                f"record at line {start}",
                "0 <= Eccentricity < 1 and SQRT(A) > 0",
                (rec["eccentricity"], rec["sqrt_a"]),
                source,
            )
    if healthy_only:
        records = [r for r in records if r.get("health", 0.0) == 0.0]
        if not records:
            raise ConfigError("almanac", "at least one healthy satellite", str(path.name), source)
    gm = WGS84.gm
    week = np.array([r["week"] for r in records])
    toa = np.array([r["toa"] for r in records])
    t_abs = week * SECONDS_PER_WEEK + toa
    shift = t_abs[0] - t_abs  # propagate each record to the first record's epoch
    a = np.array([r["sqrt_a"] for r in records]) ** 2
    raan_rate = np.array([r["raan_rate"] for r in records])
    n = np.sqrt(gm / a**3)
    # IS-GPS-200: Omega_k = Omega_0 + (Omega_dot - Omega_e) t_k - Omega_e t_oa
    node = np.array([r["raan0"] for r in records]) - OMEGA_E_GPS * toa
    node = node + (raan_rate - OMEGA_E_GPS) * shift
    mean_anomaly = np.array([r["mean_anomaly"] for r in records]) + n * shift
    prn = np.array([int(round(r["id"])) for r in records])
    return Constellation(
        name=name or path.stem,
        prn=prn,
        semi_major_axis_m=a,
        eccentricity=np.array([r["eccentricity"] for r in records]),
        inclination_rad=np.array([r["inclination"] for r in records]),
        raan_rad=np.angle(np.exp(1j * node)),
        arg_perigee_rad=np.array([r["arg_perigee"] for r in records]),
        mean_anomaly_rad=np.angle(np.exp(1j * mean_anomaly)),
        raan_rate_rps=raan_rate,
        epoch_offset_s=epoch_offset_s,
    )


def write_yuma(
    constellation: Constellation, path: str | Path, *, week: int = 0, toa_s: float = 0.0
) -> None:
    """Write ``constellation`` as a YUMA almanac with time of applicability ``toa_s``.

    The reference epoch of the constellation becomes (week, toa_s); satellite clock terms
    are written as zero and every satellite as healthy. :func:`load_yuma` reads it back
    (to the printed precision, about 10 significant digits).
    """
    c = constellation
    node0 = np.angle(np.exp(1j * (c.raan_rad + OMEGA_E_GPS * toa_s)))
    out = []
    for j in range(c.n_satellites):
        prn = int(c.prn[j])
        out += [
            f"******** Week {week} almanac for PRN-{prn:02d} ********",
            f"{'ID:':<28}{prn:02d}",
            f"{'Health:':<28}000",
            f"{'Eccentricity:':<28}{c.eccentricity[j]:.10E}",
            f"{'Time of Applicability(s):':<28}{toa_s:.4f}",
            f"{'Orbital Inclination(rad):':<28}{c.inclination_rad[j]:.10f}",
            f"{'Rate of Right Ascen(r/s):':<28}{c.raan_rate_rps[j]:.10E}",
            f"{'SQRT(A)  (m 1/2):':<28}{np.sqrt(c.semi_major_axis_m[j]):.6f}",
            f"{'Right Ascen at Week(rad):':<28}{node0[j]:.10E}",
            f"{'Argument of Perigee(rad):':<28}{c.arg_perigee_rad[j]:.10E}",
            f"{'Mean Anom(rad):':<28}{c.mean_anomaly_rad[j]:.10E}",
            f"{'Af0(s):':<28}{0.0:.10E}",
            f"{'Af1(s/s):':<28}{0.0:.10E}",
            f"{'week:':<28}{week}",
            "",
        ]
    Path(path).write_text("\n".join(out), encoding="ascii")


def reference_almanac(*, epoch_offset_s: float = 0.0) -> Constellation:
    """The packaged YUMA almanac: a GPS-like Walker 24/6/1 with small eccentricities.

    See ``navsim/data/almanac/README.md`` for how it was generated (no real almanac).
    """
    from importlib.resources import as_file, files

    resource = files("navsim").joinpath("data", "almanac", REFERENCE_ALMANAC)
    with as_file(resource) as path:
        return load_yuma(path, epoch_offset_s=epoch_offset_s, name="gps-walker-almanac")


# ====================================================================== orbits
def solve_kepler(mean_anomaly, eccentricity, *, tol: float = 1e-14, max_iter: int = 30):
    """Eccentric anomaly E with E - e sin E = M, by vectorised Newton iteration.

    Parameters
    ----------
    mean_anomaly, eccentricity : array_like (broadcast), rad and -
        ``0 <= e < 1``.

    Returns
    -------
    ndarray
        E, rad, on the same branch as M (E - e sin E = M to ~1e-15 rad).
    """
    mean_anomaly = np.asarray(mean_anomaly, dtype=float)
    e = np.asarray(eccentricity, dtype=float)
    m_wrapped = np.remainder(mean_anomaly + np.pi, 2.0 * np.pi) - np.pi  # in [-pi, pi)
    ecc = np.broadcast_to(e, m_wrapped.shape)
    big = np.pi * np.sign(m_wrapped)
    big = np.where(big == 0.0, np.pi, big)
    anomaly = np.where(ecc < 0.8, m_wrapped, big)  # standard starting values
    for _ in range(max_iter):
        step = (anomaly - ecc * np.sin(anomaly) - m_wrapped) / (1.0 - ecc * np.cos(anomaly))
        anomaly = anomaly - step
        if np.all(np.abs(step) <= tol):
            break
    return anomaly + (mean_anomaly - m_wrapped)


def satellite_states(
    constellation: Constellation, t, earth: EarthModel = WGS84
) -> tuple[np.ndarray, np.ndarray]:
    """Satellite positions and velocities in ECEF.

    Parameters
    ----------
    constellation : Constellation
    t : array_like, shape (n_t,) or scalar
        Scenario times, s.
    earth : EarthModel
        Supplies GM (mean motion) and the rotation rate.

    Returns
    -------
    pos_e, vel_e : ndarray, shape (n_t, m, 3)
        Position (m) and ECEF-frame velocity (m/s) in ECEF axes. The velocity is the
        analytic derivative, ``R v_pf + (Omega_dot - omega_ie) z x r_e``: the inertial
        orbital velocity plus node precession minus ``omega_ie x r`` of the rotating
        frame.
    """
    c = constellation
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if t.ndim != 1:
        raise ConfigError("t", "a 1-D array of times", t.shape)
    dt = t[:, None] - c.epoch_offset_s  # (n_t, m) after broadcasting
    a, e = c.semi_major_axis_m, c.eccentricity
    n = np.sqrt(earth.gm / a**3)  # mean motion
    anomaly = solve_kepler(c.mean_anomaly_rad + n * dt, e)  # Kepler's equation
    cos_e, sin_e = np.cos(anomaly), np.sin(anomaly)
    q = np.sqrt(1.0 - e**2)
    x_pf = a * (cos_e - e)  # perifocal coordinates
    y_pf = a * q * sin_e
    e_dot = n / (1.0 - e * cos_e)
    vx_pf = -a * sin_e * e_dot
    vy_pf = a * q * cos_e * e_dot
    node_rate = c.raan_rate_rps - earth.rate
    node = c.raan_rad + node_rate * dt  # IS-GPS-200: Omega_k in ECEF
    cw, sw = np.cos(c.arg_perigee_rad), np.sin(c.arg_perigee_rad)
    ci, si = np.cos(c.inclination_rad), np.sin(c.inclination_rad)
    co, so = np.cos(node), np.sin(node)
    # columns of R3(-Omega) R1(-i) R3(-omega): perifocal P and Q axes in ECEF
    p_axis = np.stack(
        [co * cw - so * sw * ci, so * cw + co * sw * ci, np.broadcast_to(sw * si, co.shape)],
        axis=-1,
    )
    q_axis = np.stack(
        [-co * sw - so * cw * ci, -so * sw + co * cw * ci, np.broadcast_to(cw * si, co.shape)],
        axis=-1,
    )
    pos_e = x_pf[..., None] * p_axis + y_pf[..., None] * q_axis
    vel_e = vx_pf[..., None] * p_axis + vy_pf[..., None] * q_axis
    # d/dt of the node rotation: (Omega_dot - omega_ie) z x r
    vel_e = vel_e + node_rate[..., None] * np.stack(
        [-pos_e[..., 1], pos_e[..., 0], np.zeros_like(pos_e[..., 0])], axis=-1
    )
    return pos_e, vel_e


def elevation_azimuth(
    receiver_e, sat_pos_e, earth: EarthModel = WGS84
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Elevation, azimuth and range of satellites seen from receivers.

    Parameters
    ----------
    receiver_e : array_like, shape (k, 3)
        Receiver ECEF positions, m.
    sat_pos_e : array_like, shape (k, m, 3)
        Satellite ECEF positions, m.

    Returns
    -------
    elevation, azimuth, range_m : ndarray, shape (k, m)
        Elevation above the local (geodetic) horizon, rad in [-pi/2, pi/2]; azimuth
        clockwise from north, rad in [0, 2 pi); geometric range, m. NaN where the input
        is NaN.
    """
    receiver_e = np.asarray(receiver_e, dtype=float)
    sat_pos_e = np.asarray(sat_pos_e, dtype=float)
    lat, lon, _ = earth.ecef_to_geodetic(receiver_e)
    los_e = sat_pos_e - receiver_e[..., None, :]
    los_n = np.einsum("...ij,...mj->...mi", mat_en(lat, lon), los_e)
    range_m = np.linalg.norm(los_e, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        elevation = np.arcsin(np.clip(los_n[..., 2] / range_m, -1.0, 1.0))
    azimuth = np.remainder(np.arctan2(los_n[..., 0], los_n[..., 1]), 2.0 * np.pi)
    return elevation, azimuth, range_m


@dataclass(frozen=True, slots=True, eq=False)
class SkyGeometry:
    """Satellite states and line-of-sight geometry at a set of epochs.

    Attributes
    ----------
    sat_pos_e, sat_vel_e : ndarray (k, m, 3)
        Satellite ECEF position (m) and ECEF-frame velocity (m/s).
    range_m, elevation, azimuth : ndarray (k, m)
        Geometric range (m), elevation and azimuth (rad) from the receiver.
    height_m : ndarray (k,)
        Receiver height above the Earth model, m.
    """

    sat_pos_e: np.ndarray
    sat_vel_e: np.ndarray
    range_m: np.ndarray
    elevation: np.ndarray
    azimuth: np.ndarray
    height_m: np.ndarray


def sky_geometry(
    t, position_e, constellation: Constellation, earth: EarthModel = WGS84
) -> SkyGeometry:
    """Satellite states and elevation/azimuth for receivers at ``position_e`` (k, 3).

    Use it to compute the elevations an outage model needs before
    :func:`simulate_epochs`, and pass the result on as ``geometry=`` to avoid recomputing.
    """
    position_e = np.asarray(position_e, dtype=float)
    sat_pos_e, sat_vel_e = satellite_states(constellation, t, earth)
    elevation, azimuth, range_m = elevation_azimuth(position_e, sat_pos_e, earth)
    _, _, height = earth.ecef_to_geodetic(position_e)
    return SkyGeometry(sat_pos_e, sat_vel_e, range_m, elevation, azimuth, height)


# ====================================================================== antenna
def antenna_state(position_e, velocity_e, mat_eb, omega_ib_b, lever_arm_b, earth: EarthModel = WGS84):
    """ECEF position and ECEF-frame velocity of an antenna at a lever arm from the IMU.

    Parameters
    ----------
    position_e, velocity_e : array_like (..., 3)
        ECEF position (m) and velocity relative to the Earth (m/s) of the IMU.
    mat_eb : array_like (..., 3, 3)
        Body-to-ECEF attitude matrix (``mat_en(lat, lon).T @ mat_nb``).
    omega_ib_b : array_like (..., 3)
        Body rate relative to inertial space in body axes, rad/s.
    lever_arm_b : array_like (3,) or (..., 3)
        Antenna phase centre relative to the IMU in body axes (x right, y forward,
        z up), m.
    earth : EarthModel
        Its rotation rate Omega gives ``omega_ie_e = [0, 0, Omega]``.

    Returns
    -------
    position_e, velocity_e : ndarray (..., 3)
        Of the antenna::

            r_a = r + C_eb l                                               (LA.1)
            v_a = v + C_eb (omega_ib_b x l) - omega_ie_e x (C_eb l)       (LA.2)

    (LA.2) is the time derivative of (LA.1) in the ECEF frame, ``dC_eb/dt = C_eb
    [omega_eb_b x]`` with ``omega_eb_b = omega_ib_b - C_be omega_ie_e``; the ECEF form of
    the lever-arm relations of Groves (2013), sections 14.2.3 and 14.3.3. tests/sensors/test_lever_arm.py checks
    (LA.2) against finite differences of (LA.1) along a true trajectory.
    """
    position_e = np.asarray(position_e, dtype=float)
    velocity_e = np.asarray(velocity_e, dtype=float)
    mat_eb = np.asarray(mat_eb, dtype=float)
    lever = np.asarray(lever_arm_b, dtype=float)
    omega = np.asarray(omega_ib_b, dtype=float)
    arm_e = np.einsum("...ij,...j->...i", mat_eb, lever)  # C_eb l
    turn_b = np.cross(omega, lever)  # omega_ib_b x l
    rate = earth.rate
    # omega_ie_e x (C_eb l) with omega_ie_e = [0, 0, Omega]
    earth_turn = np.stack([-rate * arm_e[..., 1], rate * arm_e[..., 0], np.zeros_like(arm_e[..., 0])], axis=-1)
    position_a = position_e + arm_e  # (LA.1)
    velocity_a = velocity_e + np.einsum("...ij,...j->...i", mat_eb, turn_b) - earth_turn  # (LA.2)
    return position_a, velocity_a


# ====================================================================== error model
@dataclass(frozen=True, slots=True)
class GnssErrorModel:
    """Truth-side GNSS error model (what the simulator draws, not what a filter assumes).

    Parameters
    ----------
    pseudorange_sigma_m : float
        White pseudorange noise, m (seed 003: 15 m).
    doppler_sigma_mps : float
        White pseudorange-rate noise, m/s (seed 003: 0.5 m/s).
    elevation_mask_deg : float
        Satellites below this elevation are not tracked.
    clock_enabled : bool
        Receiver clock error on/off (seed 003 treats it as compensated: off).
    clock_bias_m, clock_drift_mps : float
        Initial clock bias c*dt (m) and drift c*dt_dot (m/s).
    clock_h0, clock_h_2 : float
        Allan-variance coefficients of white FM (s) and random-walk FM (1/s). Defaults
        are the typical TCXO of Brown & Hwang Table 9.1 (h0 = 2e-19, h-2 = 2e-20).
    ionosphere_zenith_m : float
        Vertical ionospheric code delay, m (0 = off), mapped with the thin-shell
        obliquity factor at ``ionosphere_shell_height_m``.
    troposphere_zenith_m : float
        Zenith tropospheric delay at sea level, m (0 = off), scaled by
        exp(-h / troposphere_scale_height_m) and mapped with the DO-229 function.
    multipath_sigma_m : float
        Multipath standard deviation at the horizon, m (0 = off); it falls as
        exp(-E / multipath_elevation_scale_deg). Each satellite's multipath is a
        first-order Gauss-Markov process with correlation time
        ``multipath_time_constant_s``. Multipath enters the pseudorange only.
    """

    pseudorange_sigma_m: float = 15.0
    doppler_sigma_mps: float = 0.5
    elevation_mask_deg: float = 5.0
    clock_enabled: bool = False
    clock_bias_m: float = 0.0
    clock_drift_mps: float = 0.0
    clock_h0: float = 2e-19
    clock_h_2: float = 2e-20
    ionosphere_zenith_m: float = 0.0
    ionosphere_shell_height_m: float = 350_000.0
    troposphere_zenith_m: float = 0.0
    troposphere_scale_height_m: float = 8_000.0
    multipath_sigma_m: float = 0.0
    multipath_elevation_scale_deg: float = 10.0
    multipath_time_constant_s: float = 30.0

    def __post_init__(self) -> None:
        for name in (
            "pseudorange_sigma_m",
            "doppler_sigma_mps",
            "clock_h0",
            "clock_h_2",
            "ionosphere_zenith_m",
            "troposphere_zenith_m",
            "multipath_sigma_m",
        ):
            object.__setattr__(self, name, check_nonnegative(f"gnss.{name}", getattr(self, name)))
        for name in (
            "ionosphere_shell_height_m",
            "troposphere_scale_height_m",
            "multipath_elevation_scale_deg",
            "multipath_time_constant_s",
        ):
            value = check_nonnegative(f"gnss.{name}", getattr(self, name))
            if value == 0.0:
                raise ConfigError(f"gnss.{name}", "a positive number", getattr(self, name))
            object.__setattr__(self, name, value)
        mask = float(self.elevation_mask_deg)
        if not -90.0 <= mask < 90.0:
            raise ConfigError("gnss.elevation_mask_deg", "a value in [-90, 90)", mask)
        object.__setattr__(self, "elevation_mask_deg", mask)
        if not isinstance(self.clock_enabled, (bool, np.bool_)):
            raise ConfigError("gnss.clock_enabled", "true or false", self.clock_enabled)
        for name in ("clock_bias_m", "clock_drift_mps"):
            value = float(getattr(self, name))
            if not np.isfinite(value):
                raise ConfigError(f"gnss.{name}", "a finite number", value)
            object.__setattr__(self, name, value)

    PRESETS = ("paper-2012", "standalone", "ideal")

    @classmethod
    def preset(cls, name: str) -> GnssErrorModel:
        """Named models.

        ``"paper-2012"``
            Seed 003's example: white noise only, 15 m and 0.5 m/s, no clock error; the
            paper gives no mask, navsim uses 5 deg.
        ``"standalone"``
            An uncorrected standalone receiver: 1 m code noise, 0.05 m/s Doppler noise,
            TCXO clock (initial 10 us bias = 2998 m, 0.2 ppm drift = 60 m/s), 5 m
            vertical ionosphere, 2.4 m zenith troposphere, 3 m horizon multipath
            (30 s correlation), 10 deg mask.
        ``"ideal"``
            No error at all (mask 0 deg).
        """
        if name == "paper-2012":
            return cls(pseudorange_sigma_m=15.0, doppler_sigma_mps=0.5, elevation_mask_deg=5.0)
        if name == "standalone":
            return cls(
                pseudorange_sigma_m=1.0,
                doppler_sigma_mps=0.05,
                elevation_mask_deg=10.0,
                clock_enabled=True,
                clock_bias_m=1e-5 * C_LIGHT,
                clock_drift_mps=0.2e-6 * C_LIGHT,
                ionosphere_zenith_m=5.0,
                troposphere_zenith_m=2.4,
                multipath_sigma_m=3.0,
            )
        if name == "ideal":
            return cls(pseudorange_sigma_m=0.0, doppler_sigma_mps=0.0, elevation_mask_deg=0.0)
        raise ConfigError("gnss.preset", f"one of {list(cls.PRESETS)}", name)

    def nominal(self, lever_arm_b_m: Sequence[float] = (0.0, 0.0, 0.0)) -> NominalGnss:
        """The receiver specification an estimator is told (:class:`navsim.types.NominalGnss`).

        Code sigma = hypot(white noise, multipath sigma at the horizon); the clock, when
        on, with initial sigmas max(|bias|, 100 m), max(|drift|, 1 m/s) and the PSDs
        c^2 h0 / 2, 2 pi^2 c^2 h_-2 (Brown & Hwang sec. 9.3). Atmosphere: the designer
        knows the receiver is single-frequency and uncorrected (the delays are on), not
        the delays. A-priori values a receiver applies from standard models: ionosphere,
        the constant (night-time) term of the GPS broadcast (Klobuchar) model,
        5 ns = 1.50 m (navsim broadcasts no coefficients); sigma 4.5 m, DO-229D J.2.3
        tau_vert at mid-latitudes (the bundled scenarios lie at 44-47 deg). Troposphere,
        DO-229D A.4.2.4 at sea level and 45 deg, annual mean (P 1015.75 hPa,
        T 283.15 K, e 11.66 hPa): 2.313 m dry + 0.135 m wet = 2.448 m; sigma 0.12 m,
        DO-229D sigma_TVE. Thin shell at 350 km (Klobuchar), exponential height law with
        the 8 km scale height of the standard atmosphere. ``lever_arm_b_m``: the antenna
        lever arm as surveyed at installation (body axes, m).
        """
        from ...types import NominalGnss

        clock = bool(self.clock_enabled)
        iono, tropo = self.ionosphere_zenith_m > 0.0, self.troposphere_zenith_m > 0.0
        return NominalGnss(
            pseudorange_sigma_m=float(np.hypot(self.pseudorange_sigma_m, self.multipath_sigma_m)),
            doppler_sigma_mps=float(self.doppler_sigma_mps),
            clock_modelled=clock,
            clock_bias_sigma_m=max(abs(self.clock_bias_m), 100.0) if clock else 0.0,
            clock_drift_sigma_mps=max(abs(self.clock_drift_mps), 1.0) if clock else 0.0,
            clock_phase_psd=C_LIGHT**2 * self.clock_h0 / 2.0 if clock else 0.0,
            clock_freq_psd=2.0 * math.pi**2 * C_LIGHT**2 * self.clock_h_2 if clock else 0.0,
            atmosphere_modelled=bool(iono or tropo),
            ionosphere_zenith_m=5e-9 * C_LIGHT if iono else 0.0,
            ionosphere_zenith_sigma_m=4.5 if iono else 0.0,
            troposphere_zenith_m=2.448 if tropo else 0.0,
            troposphere_zenith_sigma_m=0.12 if tropo else 0.0,
            lever_arm_b_m=tuple(float(x) for x in lever_arm_b_m),
        )

    # ----------------------------------------------------------------- pieces
    @property
    def clock_psd(self) -> tuple[float, float]:
        """(S_f, S_g): white-FM and random-walk-FM intensities in m^2/s and m^2/s^3.

        S_f = c^2 h0 / 2, S_g = c^2 2 pi^2 h_-2 (Brown & Hwang sec. 9.3).
        """
        return (
            C_LIGHT**2 * self.clock_h0 / 2.0,
            C_LIGHT**2 * 2.0 * np.pi**2 * self.clock_h_2,
        )

    def clock_allan_variance(self, tau) -> np.ndarray:
        """Allan variance sigma_y^2(tau) = h0/(2 tau) + (2 pi^2/3) h_-2 tau of the clock."""
        tau = np.asarray(tau, dtype=float)
        return self.clock_h0 / (2.0 * tau) + 2.0 * np.pi**2 / 3.0 * self.clock_h_2 * tau

    def ionosphere_delay_m(self, elevation, earth: EarthModel = WGS84) -> np.ndarray:
        """Slant ionospheric delay, m: zenith delay x thin-shell obliquity factor."""
        elevation = np.asarray(elevation, dtype=float)
        ratio = earth.a * np.cos(elevation) / (earth.a + self.ionosphere_shell_height_m)
        return self.ionosphere_zenith_m / np.sqrt(1.0 - ratio**2)

    def troposphere_delay_m(self, elevation, height_m) -> np.ndarray:
        """Slant tropospheric delay, m: scaled zenith delay x DO-229 mapping function."""
        elevation = np.asarray(elevation, dtype=float)
        height = np.asarray(height_m, dtype=float)
        zenith = self.troposphere_zenith_m * np.exp(-height / self.troposphere_scale_height_m)
        return zenith * 1.001 / np.sqrt(0.002001 + np.sin(elevation) ** 2)

    def multipath_sigma(self, elevation) -> np.ndarray:
        """Multipath standard deviation at elevation E, m: sigma_mp exp(-E / E0)."""
        elevation = np.clip(np.asarray(elevation, dtype=float), 0.0, None)
        return self.multipath_sigma_m * np.exp(
            -elevation / np.radians(self.multipath_elevation_scale_deg)
        )

    @staticmethod
    def draw_width(n_satellites: int) -> int:
        """Width of the per-epoch block of standard normals: 2 clock + 3 per satellite."""
        return 2 + 3 * int(n_satellites)


@dataclass(frozen=True, slots=True, eq=False)
class GnssState:
    """Recursive truth-side GNSS error state carried between calls.

    Attributes
    ----------
    t_s : float
        Time of the last simulated epoch (NaN before the first one).
    clock_bias_m, clock_drift_mps : float
        Receiver clock bias and drift at ``t_s`` (at the first epoch if NaN).
    multipath : ndarray (m,)
        Unit-variance Gauss-Markov states, one per satellite (scaled by the
        elevation-dependent sigma when applied).
    """

    t_s: float
    clock_bias_m: float
    clock_drift_mps: float
    multipath: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "multipath", frozen_array(self.multipath))

    @classmethod
    def initial(
        cls, model: GnssErrorModel, constellation: Constellation, rng: np.random.Generator
    ) -> GnssState:
        """State before the first epoch: the model's initial clock, stationary multipath.

        Always draws m standard normals (whether multipath is on or not), so switching
        multipath does not shift the stream.
        """
        multipath = rng.standard_normal(constellation.n_satellites)
        bias = model.clock_bias_m if model.clock_enabled else 0.0
        drift = model.clock_drift_mps if model.clock_enabled else 0.0
        return cls(float("nan"), bias, drift, multipath)


@dataclass(frozen=True, slots=True, eq=False)
class GnssEpochs:
    """GNSS measurements at k epochs for m satellites (arrays, invalid entries = 0).

    Attributes
    ----------
    t : (k,) s
    sat_pos_e, sat_vel_e : (k, m, 3) ECEF m, m/s
    pseudorange_m : (k, m)
    pseudorange_rate_mps : (k, m)  d(range)/dt + clock drift + noise (003 eq. (3))
    valid : (k, m) bool  tracked (above the mask, visible, finite)
    elevation, azimuth : (k, m) rad
    clock_bias_m, clock_drift_mps : (k,)  truth-side receiver clock (for metrics only)
    """

    t: np.ndarray
    sat_pos_e: np.ndarray
    sat_vel_e: np.ndarray
    pseudorange_m: np.ndarray
    pseudorange_rate_mps: np.ndarray
    valid: np.ndarray
    elevation: np.ndarray
    azimuth: np.ndarray
    clock_bias_m: np.ndarray
    clock_drift_mps: np.ndarray

    @property
    def n_valid(self) -> np.ndarray:
        """Number of valid satellites per epoch, (k,)."""
        return self.valid.sum(axis=1)

    @classmethod
    def concatenate(cls, parts: Sequence[GnssEpochs]) -> GnssEpochs:
        """Join chunks along the epoch axis."""
        names = cls.__slots__
        return cls(**{n: np.concatenate([getattr(p, n) for p in parts]) for n in names})


def _clock_cholesky(model: GnssErrorModel, dt: np.ndarray):
    """Cholesky factor entries of the two-state clock process noise over dt (Brown & Hwang 9.3)."""
    s_f, s_g = model.clock_psd
    q_bb = s_f * dt + s_g * dt**3 / 3.0
    q_bd = s_g * dt**2 / 2.0
    q_dd = s_g * dt
    l00 = np.sqrt(q_bb)
    with np.errstate(invalid="ignore", divide="ignore"):
        l10 = np.where(l00 > 0.0, q_bd / l00, 0.0)
    l11 = np.sqrt(np.clip(q_dd - l10**2, 0.0, None))
    return l00, l10, l11


def simulate_epochs(
    t,
    position_e,
    velocity_e,
    constellation: Constellation,
    model: GnssErrorModel,
    state: GnssState,
    rng: np.random.Generator,
    earth: EarthModel = WGS84,
    visible=None,
    *,
    geometry: SkyGeometry | None = None,
) -> tuple[GnssEpochs, GnssState]:
    """Simulate pseudoranges and pseudorange rates at k epochs.

    Parameters
    ----------
    t : array_like (k,)
        Epoch times, s, strictly increasing and after ``state.t_s``.
    position_e, velocity_e : array_like (k, 3)
        True receiver ECEF position (m) and ECEF-frame velocity (m/s). NaN rows give
        invalid epochs.
    constellation, model, state, rng
        ``rng`` is the GNSS stream; one block ``standard_normal((k, 2 + 3 m))`` is drawn
        per call (row = epoch: 2 clock, m code, m Doppler, m multipath), so the result is
        chunk-invariant and independent of what is switched on or visible.
    earth : EarthModel
    visible : array_like (k, m) bool, optional
        Visibility from :func:`navsim.sensors.outages.visibility` (True = signal
        present).
    geometry : SkyGeometry, optional
        Precomputed :func:`sky_geometry` for the same t, position_e and constellation.

    Returns
    -------
    epochs : GnssEpochs
    new_state : GnssState

    Notes
    -----
    pseudorange = rho + b + I + T + MP + w_R (003 eq. (2) plus the optional terms),
    pseudorange rate = (r_s - r).(v_s - v)/rho + b_dot + w_V (003 eq. (3)). rho is the
    geometric range at the reception instant (no light time, no Sagnac), as in (2).
    Atmospheric delay rates (below 1 cm/s) are left out of the Doppler observable.
    This is the one-receiver case of :func:`simulate_epochs_batch`.
    """
    if visible is not None:
        visible = np.asarray(visible, dtype=bool)[None]
    epochs, states = simulate_epochs_batch(t, position_e, velocity_e, constellation, model, [state], [rng], earth,
                                           visible, geometry=geometry)
    return GnssEpochs(**{name: getattr(epochs, name)[0] for name in GnssEpochs.__slots__}), states[0]


def simulate_epochs_batch(
    t,
    position_e,
    velocity_e,
    constellation: Constellation,
    model: GnssErrorModel,
    states: Sequence[GnssState],
    rngs: Sequence[np.random.Generator],
    earth: EarthModel = WGS84,
    visible=None,
    *,
    geometry: SkyGeometry | None = None,
) -> tuple[GnssEpochs, list[GnssState]]:
    """:func:`simulate_epochs` for B receivers at the same place (one true motion).

    The geometry (satellite states, ranges, range rates, elevations, atmospheric delays)
    is computed once; receiver j draws its own block from ``rngs[j]`` and gets exactly the
    numbers of ``simulate_epochs(..., states[j], rngs[j], visible=visible[j])``.

    Parameters
    ----------
    t, position_e, velocity_e, constellation, model, earth, geometry
        As :func:`simulate_epochs`, shared by all receivers.
    states : sequence of B GnssState, all at the same ``t_s`` (lockstep).
    rngs : sequence of B numpy.random.Generator
    visible : array_like (B, k, m) bool, optional

    Returns
    -------
    epochs : GnssEpochs
        Every array with a leading receiver axis (B, k, ...); the shared ones (``t``,
        ``sat_pos_e``, ``sat_vel_e``, ``elevation``, ``azimuth``) as read-only broadcast
        views.
    new_states : list of B GnssState
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    k, m = t.size, constellation.n_satellites
    states, rngs = list(states), list(rngs)
    members = len(states)
    if not states or len(rngs) != members:
        raise ConfigError("rngs", f"one generator per state ({members}, at least one)", len(rngs))
    position_e = np.asarray(position_e, dtype=float).reshape(k, 3) if k else np.zeros((0, 3))
    velocity_e = np.asarray(velocity_e, dtype=float).reshape(k, 3) if k else np.zeros((0, 3))
    for state in states:
        if state.multipath.shape != (m,):
            raise ConfigError("state.multipath", f"shape ({m},)", state.multipath.shape)
    t_s = states[0].t_s
    if any(not (s.t_s == t_s or (math.isnan(s.t_s) and math.isnan(t_s))) for s in states):
        raise ConfigError("states", "states at the same epoch time (lockstep)", sorted({s.t_s for s in states}))
    if not np.all(np.isfinite(t)):
        raise ConfigError("t", "finite times", t)
    dt = np.diff(np.concatenate([[t_s], t]))
    increasing = np.all(dt[1:] > 0.0) and (not np.isfinite(t_s) or k == 0 or dt[0] > 0.0)
    if not increasing:
        raise ConfigError("t", f"strictly increasing times after state.t_s={t_s}", t)
    if visible is None:
        visible = np.ones((1, k, m), dtype=bool)
    else:
        visible = np.broadcast_to(np.asarray(visible, dtype=bool), (members, k, m))
    geo = geometry if geometry is not None else sky_geometry(t, position_e, constellation, earth)
    if geo.range_m.shape != (k, m):
        raise ConfigError("geometry", f"a SkyGeometry for ({k}, {m}) epochs x satellites", geo.range_m.shape)

    draws = np.empty((members, k, GnssErrorModel.draw_width(m)))
    for j, rng in enumerate(rngs):
        rng.standard_normal(out=draws[j])
    z_clock, z_code = draws[:, :, :2], draws[:, :, 2 : 2 + m]
    z_doppler, z_mp = draws[:, :, 2 + m : 2 + 2 * m], draws[:, :, 2 + 2 * m :]

    # ---- recursive parts: receiver clock and multipath, epoch by epoch (members at once)
    first = not np.isfinite(t_s)
    step = np.where(np.isfinite(dt), dt, 0.0)
    l00, l10, l11 = _clock_cholesky(model, step)
    phi = np.exp(-step / model.multipath_time_constant_s)
    kick = np.sqrt(1.0 - phi**2)
    bias = np.empty((members, k))
    drift = np.empty((members, k))
    multipath = np.empty((members, k, m))
    b = np.array([s.clock_bias_m for s in states])
    d = np.array([s.clock_drift_mps for s in states])
    x = np.stack([s.multipath for s in states])
    clock_on = model.clock_enabled
    for j in range(k):
        if not (first and j == 0):
            if clock_on:
                # two-state clock: b += d dt + w_b, d += w_d, cov(w) = Q(dt)
                b = b + d * step[j] + l00[j] * z_clock[:, j, 0]
                d = d + l10[j] * z_clock[:, j, 0] + l11[j] * z_clock[:, j, 1]
            x = phi[j] * x + kick[j] * z_mp[:, j]  # first-order Gauss-Markov
        bias[:, j], drift[:, j] = b, d
        multipath[:, j] = x

    # ---- measurements: the geometry once, the errors per member
    los_e = geo.sat_pos_e - position_e[:, None, :]
    rel_vel_e = geo.sat_vel_e - velocity_e[:, None, :]
    rho = geo.range_m
    with np.errstate(invalid="ignore", divide="ignore"):
        range_rate = np.einsum("kmi,kmi->km", los_e, rel_vel_e) / rho  # (3)
    elevation = geo.elevation
    pseudorange = rho + bias[:, :, None] + model.pseudorange_sigma_m * z_code  # (2)
    if model.ionosphere_zenith_m > 0.0:
        pseudorange = pseudorange + model.ionosphere_delay_m(elevation, earth)
    if model.troposphere_zenith_m > 0.0:
        pseudorange = pseudorange + model.troposphere_delay_m(elevation, geo.height_m[:, None])
    if model.multipath_sigma_m > 0.0:
        pseudorange = pseudorange + model.multipath_sigma(elevation) * multipath
    pseudorange_rate = range_rate + drift[:, :, None] + model.doppler_sigma_mps * z_doppler

    finite = np.isfinite(pseudorange) & np.isfinite(pseudorange_rate) & np.isfinite(elevation)
    with np.errstate(invalid="ignore"):
        above = elevation >= np.radians(model.elevation_mask_deg)
    valid = above & visible & finite
    zero = np.zeros(())

    def shared(a):
        return np.broadcast_to(a, (members, *a.shape))

    epochs = GnssEpochs(
        t=shared(t.copy()),
        sat_pos_e=shared(geo.sat_pos_e),
        sat_vel_e=shared(geo.sat_vel_e),
        pseudorange_m=np.where(valid, pseudorange, zero),
        pseudorange_rate_mps=np.where(valid, pseudorange_rate, zero),
        valid=valid,
        elevation=shared(np.where(np.isfinite(elevation), elevation, zero)),
        azimuth=shared(np.where(np.isfinite(geo.azimuth), geo.azimuth, zero)),
        clock_bias_m=bias,
        clock_drift_mps=drift,
    )
    if not k:
        return epochs, states
    return epochs, [GnssState(float(t[-1]), float(b[j]), float(d[j]), x[j]) for j in range(members)]
