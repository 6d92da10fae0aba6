"""Satellite orbits and sky geometry: Kepler's equation (:func:`solve_kepler`), ECEF satellite
positions and ECEF-frame velocities by the GPS almanac algorithm of IS-GPS-200 (Table 20-IV)
with the mean motion from the Earth model's GM (:func:`satellite_states`), elevation and
azimuth (:func:`elevation_azimuth`, :func:`sky_geometry`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...earth import WGS84, EarthModel, mat_en
from ...errors import ConfigError
from ...types import FloatOrArray
from .constellation import Constellation


def solve_kepler(mean_anomaly: FloatOrArray, eccentricity: FloatOrArray, *, tol: float = 1e-14,
                 max_iter: int = 30) -> FloatOrArray:
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
    constellation: Constellation, t: FloatOrArray, earth: EarthModel = WGS84
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
    receiver_e: np.ndarray, sat_pos_e: np.ndarray, earth: EarthModel = WGS84
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
    t: FloatOrArray, position_e: np.ndarray, constellation: Constellation, earth: EarthModel = WGS84
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
