"""Earth models and frame conversions.

Two models share one interface (:class:`EarthModel`):

* :data:`SPHERICAL` - the spherical Earth of seed 003: radius ``r``, rotation rate
  ``Omega`` and a *constant* gravitational acceleration ``g`` along the radius. With the
  centrifugal term this gives the plumb-line gravity used in 003 eq. (1) (with the sign of
  the centrifugal term corrected, see :meth:`EarthModel.gravity_n`).
* :data:`WGS84` - the WGS-84 ellipsoid with Somigliana normal gravity and the
  second-order free-air correction of NIMA TR8350.2 (eq. 4-3).

Frames (see the package docstring): ``e`` is ECEF (x through lat 0 lon 0, z to the north
pole); ``n`` is the local-level East-North-Up frame, the "accompanying frame" S of 003
(X east, Y north, Z up). Seed 003 writes the Greenwich frame as (xi, eta, zeta) with
xi = (r+h) cos(phi) sin(lambda), eta = (r+h) sin(phi), zeta = (r+h) cos(phi) cos(lambda)
(eq. 4); that is (xi, eta, zeta) = (y_e, z_e, x_e), a cyclic permutation, so every
formula of 003 holds unchanged in standard ECEF after relabelling.

All angles are radians, lengths metres, times seconds. Functions broadcast over leading
dimensions.

References
----------
.. [1] Sokolov S.V., Vdovichenko S.S. (2012), seed 003, eqs. (1), (4), (5).
.. [2] NIMA TR8350.2, Department of Defense World Geodetic System 1984, 3rd ed., 2000:
       a = 6378137 m, 1/f = 298.257223563, GM = 3.986004418e14 m^3/s^2,
       omega = 7.292115e-5 rad/s, gamma_e = 9.7803253359, k = 0.00193185265241.
.. [3] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., 2013, sections 2.4 (curvilinear position) and 2.4.7 (gravity).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .types import FloatOrArray

__all__ = [
    "EarthModel",
    "SPHERICAL",
    "WGS84",
    "earth_model",
    "mat_en",
]


@dataclass(frozen=True, slots=True)
class EarthModel:
    """An Earth: ellipsoid, rotation rate and gravity model.

    Parameters
    ----------
    name : str
        ``"spherical"`` or ``"wgs84"``.
    a : float
        Equatorial radius, m (the sphere's radius ``r`` for the spherical model).
    f : float
        Flattening (0 for the sphere).
    rate : float
        Earth rotation rate Omega, rad/s.
    gm : float
        Gravitational constant GM, m^3/s^2 (used by the WGS-84 gravity and by orbits).
    g0 : float
        Spherical model only: constant gravitational acceleration g, m/s^2.
    """

    name: str
    a: float
    f: float
    rate: float
    gm: float
    g0: float = 0.0

    # ------------------------------------------------------------------ geometry
    @property
    def e2(self) -> float:
        """First eccentricity squared."""
        return self.f * (2.0 - self.f)

    def radii(self, lat: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Meridian and prime-vertical radii of curvature.

        Returns
        -------
        r_meridian, r_prime_vertical : ndarray
            R_N (north-south) and R_E (east-west), m. Both equal ``a`` on the sphere.
        """
        lat = np.asarray(lat, dtype=float)
        if self.f == 0.0:
            r = np.full_like(lat, self.a)
            return r, r.copy()
        s2 = np.sin(lat) ** 2
        w = np.sqrt(1.0 - self.e2 * s2)
        r_e = self.a / w
        r_n = self.a * (1.0 - self.e2) / w**3
        return r_n, r_e

    def radii_derivative(self, lat: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """d R_N / d lat and d R_E / d lat, m/rad."""
        lat = np.asarray(lat, dtype=float)
        if self.f == 0.0:
            z = np.zeros_like(lat)
            return z, z.copy()
        s, c = np.sin(lat), np.cos(lat)
        w2 = 1.0 - self.e2 * s * s
        dw2 = -2.0 * self.e2 * s * c
        r_n = self.a * (1.0 - self.e2) * w2**-1.5
        r_e = self.a * w2**-0.5
        return -1.5 * r_n * dw2 / w2, -0.5 * r_e * dw2 / w2

    def geodetic_to_ecef(self, lat: FloatOrArray, lon: FloatOrArray, h: FloatOrArray) -> np.ndarray:
        """Geodetic latitude, longitude (rad) and height (m) to ECEF, shape (..., 3)."""
        lat, lon, h = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (lat, lon, h)))
        _, r_e = self.radii(lat)
        clat = np.cos(lat)
        return np.stack(
            [
                (r_e + h) * clat * np.cos(lon),
                (r_e + h) * clat * np.sin(lon),
                (r_e * (1.0 - self.e2) + h) * np.sin(lat),
            ],
            axis=-1,
        )

    def ecef_to_geodetic(self, xyz: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """ECEF (..., 3) to geodetic latitude, longitude (rad) and height (m).

        Exact for the sphere; for the ellipsoid a Newton iteration on latitude from the
        spherical start, converged to below 1e-15 rad for heights from -1e5 m to GNSS orbit.
        """
        xyz = np.asarray(xyz, dtype=float)
        x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
        lon = np.arctan2(y, x)
        p = np.hypot(x, y)
        if self.f == 0.0:
            lat = np.arctan2(z, p)
            return lat, lon, np.hypot(p, z) - self.a
        e2 = self.e2
        lat = np.arctan2(z, p * (1.0 - e2))
        for _ in range(6):
            s = np.sin(lat)
            r_e = self.a / np.sqrt(1.0 - e2 * s * s)
            lat = np.arctan2(z + e2 * r_e * s, p)
        s, c = np.sin(lat), np.cos(lat)
        # height along the normal, well conditioned at all latitudes
        h = p * c + z * s - self.a * np.sqrt(1.0 - e2 * s * s)
        return lat, lon, h

    # ------------------------------------------------------------------ rates
    def earth_rate_n(self, lat: FloatOrArray) -> np.ndarray:
        """omega_ie_n = Omega [0, cos(lat), sin(lat)] in ENU, shape (..., 3), rad/s."""
        lat = np.asarray(lat, dtype=float)
        return self.rate * np.stack([np.zeros_like(lat), np.cos(lat), np.sin(lat)], axis=-1)

    def transport_rate_n(self, lat: FloatOrArray, h: FloatOrArray, velocity_n: FloatOrArray) -> np.ndarray:
        """omega_en_n, the rate of the ENU frame relative to the Earth, rad/s, (..., 3).

        omega_en_n = [-v_N / (R_N + h), v_E / (R_E + h), v_E tan(lat) / (R_E + h)]
        (003 eq. (1), the matrix U-check, with r -> R_N, R_E on the ellipsoid).
        """
        lat = np.asarray(lat, dtype=float)
        velocity_n = np.asarray(velocity_n, dtype=float)
        r_n, r_e = self.radii(lat)
        v_e, v_n = velocity_n[..., 0], velocity_n[..., 1]
        return np.stack(
            [-v_n / (r_n + h), v_e / (r_e + h), v_e * np.tan(lat) / (r_e + h)], axis=-1
        )

    # ------------------------------------------------------------------ gravity
    def gravity_n(self, lat: FloatOrArray, h: FloatOrArray) -> np.ndarray:
        """Plumb-line gravity (gravitation plus centrifugal) in ENU, m/s^2, (..., 3).

        Spherical model: gravitation ``-g`` along Up plus the centrifugal acceleration
        ``Omega^2 (r+h) cos(lat) [0, -sin(lat), cos(lat)]``. Seed 003 eq. (1) subtracts
        ``[0, -Omega^2 (r+h) cos sin, Omega^2 (r+h) cos^2 + g]``, i.e. it puts the
        centrifugal term with the opposite sign; the physics (and navsim's truth) uses the
        sign above. The printed sign is kept only in the paper estimator's faithful mode.

        WGS-84: Somigliana normal gravity on the ellipsoid with the second-order height
        correction (NIMA TR8350.2 eq. 4-3), along -Up; the deflection of the normal
        gravity vector off the ellipsoid normal above the surface (< 1e-6 g at 1 km)
        is neglected, as in the usual local-level mechanisation.
        """
        lat = np.asarray(lat, dtype=float)
        h = np.asarray(h, dtype=float)
        lat, h = np.broadcast_arrays(lat, h)
        zero = np.zeros_like(lat)
        if self.name == "spherical":
            rc = self.rate**2 * (self.a + h) * np.cos(lat)
            return np.stack([zero, -rc * np.sin(lat), rc * np.cos(lat) - self.g0], axis=-1)
        s2 = np.sin(lat) ** 2
        gamma_e, k = 9.7803253359, 0.00193185265241  # TR8350.2 table 3.4
        gamma = gamma_e * (1.0 + k * s2) / np.sqrt(1.0 - self.e2 * s2)
        m = self.rate**2 * self.a**2 * self.a * (1.0 - self.f) / self.gm
        gamma_h = gamma * (
            1.0
            - 2.0 / self.a * (1.0 + self.f + m - 2.0 * self.f * s2) * h
            + 3.0 / self.a**2 * h**2
        )
        return np.stack([zero, zero, -gamma_h], axis=-1)


SPHERICAL = EarthModel(
    name="spherical", a=6_371_000.0, f=0.0, rate=7.292115e-5, gm=3.986004418e14, g0=9.81
)
"""The spherical Earth of seed 003. The paper prints no numbers for r, Omega, g; navsim
uses the mean radius 6371 km, the WGS-84 rotation rate and g = 9.81 m/s^2."""

WGS84 = EarthModel(
    name="wgs84", a=6_378_137.0, f=1.0 / 298.257223563, rate=7.292115e-5, gm=3.986004418e14
)
"""WGS-84 (NIMA TR8350.2)."""


def earth_model(name: str) -> EarthModel:
    """Look up an Earth model by name (``"spherical"`` or ``"wgs84"``)."""
    from .errors import ConfigError

    models = {"spherical": SPHERICAL, "wgs84": WGS84}
    try:
        return models[name]
    except (KeyError, TypeError):
        raise ConfigError("earth", f"one of {sorted(models)}", name) from None


def mat_en(lat: FloatOrArray, lon: FloatOrArray) -> np.ndarray:
    """Rotation matrix from ECEF to ENU, shape (..., 3, 3); rows are E, N, U in ECEF.

    This is the matrix B(phi, lambda) of 003 eq. (5), written in standard ECEF axes:
    ``velocity_n = mat_en @ velocity_e``.
    """
    lat = np.asarray(lat, dtype=float)
    lon = np.asarray(lon, dtype=float)
    lat, lon = np.broadcast_arrays(lat, lon)
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    zero = np.zeros_like(lat)
    east = np.stack([-so, co, zero], axis=-1)
    north = np.stack([-sl * co, -sl * so, cl], axis=-1)
    up = np.stack([cl * co, cl * so, sl], axis=-1)
    return np.stack([east, north, up], axis=-2)
