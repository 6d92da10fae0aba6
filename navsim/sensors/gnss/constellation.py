"""Satellite constellations: :class:`Constellation` (Keplerian almanac elements with a secular
node drift) and the Walker delta patterns T/P/F (Walker 1984) of GPS- and GLONASS-like sets,
their node drift the secular J2 rate Omega_dot = -1.5 n J2 (R/p)^2 cos i (Vallado 2013,
sec. 9.6).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ...earth import WGS84
from ...errors import ConfigError
from .._common import frozen_array
from .constants import J2_WGS84


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

    def select(self, keep: ArrayLike) -> Constellation:
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
