"""Earth models: conversions round-trip, gravity and radii against published values."""

import numpy as np
import pytest

from navsim.earth import SPHERICAL, WGS84, earth_model, mat_en
from navsim.errors import ConfigError

rng = np.random.default_rng(2)


@pytest.mark.parametrize("earth", [SPHERICAL, WGS84])
def test_geodetic_ecef_round_trip(earth):
    lat = rng.uniform(-np.pi / 2 + 1e-6, np.pi / 2 - 1e-6, 1000)
    lon = rng.uniform(-np.pi, np.pi, 1000)
    h = rng.uniform(-1e3, 2.5e7, 1000)
    xyz = earth.geodetic_to_ecef(lat, lon, h)
    lat2, lon2, h2 = earth.ecef_to_geodetic(xyz)
    np.testing.assert_allclose(lat2, lat, atol=1e-14)
    np.testing.assert_allclose(np.angle(np.exp(1j * (lon2 - lon))), 0, atol=1e-14)
    assert np.all(np.abs(h2 - h) < 1e-9 * np.maximum(1.0, np.abs(h)) + 1e-8)


def test_wgs84_published_values():
    # normal gravity at the equator and pole (TR8350.2 table 3.4)
    np.testing.assert_allclose(WGS84.gravity_n(0.0, 0.0)[2], -9.7803253359, rtol=1e-12)
    np.testing.assert_allclose(WGS84.gravity_n(np.pi / 2, 0.0)[2], -9.8321849378, rtol=1e-10)
    # free-air gradient about -3.086e-6 s^-2
    grad = (WGS84.gravity_n(0.8, 100.0)[2] - WGS84.gravity_n(0.8, 0.0)[2]) / 100.0
    assert abs(grad - 3.086e-6) < 0.01e-6
    # radii: R_N(0) = a(1-e2), R_E(pi/2) = a / sqrt(1-e2)
    r_n, r_e = WGS84.radii(np.array([0.0, np.pi / 2]))
    np.testing.assert_allclose(r_n[0], 6335439.327, atol=1e-3)
    np.testing.assert_allclose(r_e[1], 6399593.626, atol=1e-3)


def test_radii_derivative_by_finite_difference():
    lat = np.linspace(-1.4, 1.4, 11)
    d = 1e-6
    for i, deriv in enumerate(WGS84.radii_derivative(lat)):
        fd = (WGS84.radii(lat + d)[i] - WGS84.radii(lat - d)[i]) / (2 * d)
        np.testing.assert_allclose(deriv, fd, rtol=1e-6, atol=1e-3)


def test_spherical_gravity_is_gravitation_plus_centrifugal():
    lat, h = 0.7, 500.0
    g_n = SPHERICAL.gravity_n(lat, h)
    # centrifugal acceleration in ECEF, rotated to ENU
    r_e = SPHERICAL.geodetic_to_ecef(lat, 0.3, h)
    omega = np.array([0, 0, SPHERICAL.rate])
    centrifugal_n = mat_en(lat, 0.3) @ (-np.cross(omega, np.cross(omega, r_e)))
    np.testing.assert_allclose(g_n, centrifugal_n + [0, 0, -9.81], atol=1e-12)


def test_mat_en_is_rotation_and_transport_rate():
    m = mat_en(0.5, 1.0)
    np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(np.linalg.det(m), 1.0)
    # transport rate: finite difference of mat_en along a velocity
    lat, lon, h = 0.5, 1.0, 200.0
    v_n = np.array([30.0, -12.0, 1.0])
    r_n, r_e = WGS84.radii(lat)
    lat_rate = v_n[1] / (r_n + h)
    lon_rate = v_n[0] / ((r_e + h) * np.cos(lat))
    dt = 1e-3
    dm = (mat_en(lat + lat_rate * dt, lon + lon_rate * dt) - mat_en(lat - lat_rate * dt, lon - lon_rate * dt)) / (2 * dt)
    # d/dt mat_ne = mat_ne [omega_en_n x]  =>  mat_en dm^T ... use skew = m @ dm.T
    omega_skew = m @ dm.T
    omega = np.array([omega_skew[2, 1], omega_skew[0, 2], omega_skew[1, 0]])
    np.testing.assert_allclose(WGS84.transport_rate_n(lat, h, v_n), omega, rtol=1e-6)


def test_earth_model_lookup_error_names_field():
    with pytest.raises(ConfigError, match="earth: expected one of"):
        earth_model("flat")
