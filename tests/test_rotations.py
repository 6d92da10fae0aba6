"""Rotations: round trips, closed forms and finite differences."""

import numpy as np
import pytest

from navsim import rotations as rot
from navsim.earth import SPHERICAL, mat_en

rng = np.random.default_rng(1)


def random_angles(n=200):
    return (
        rng.uniform(-np.pi, np.pi, n),
        rng.uniform(-1.4, 1.4, n),
        rng.uniform(-np.pi, np.pi, n),
    )


def test_quat_mat_rotvec_round_trips():
    rotvec = rng.normal(size=(500, 3))
    rotvec *= (rng.uniform(0, np.pi - 1e-3, 500) / np.linalg.norm(rotvec, axis=1))[:, None]
    q = rot.quat_from_rotvec(rotvec)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(rot.quat_to_rotvec(q), rotvec, atol=1e-12)
    mat = rot.quat_to_mat(q)
    np.testing.assert_allclose(mat @ np.swapaxes(mat, 1, 2), np.broadcast_to(np.eye(3), mat.shape), atol=1e-14)
    np.testing.assert_allclose(rot.quat_to_mat(rot.mat_to_quat(mat)), mat, atol=1e-14)


def test_small_rotvec_series_matches_exact():
    v = np.array([[3e-5, -2e-5, 1e-5]])
    angle = np.linalg.norm(v)
    exact = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * v[0] / angle])
    np.testing.assert_allclose(rot.quat_from_rotvec(v)[0], exact, rtol=0, atol=1e-17)


def test_quat_product_composes_matrices():
    p = rot.quat_from_rotvec(rng.normal(size=(50, 3)))
    q = rot.quat_from_rotvec(rng.normal(size=(50, 3)))
    np.testing.assert_allclose(
        rot.quat_to_mat(rot.quat_multiply(p, q)), rot.quat_to_mat(p) @ rot.quat_to_mat(q), atol=1e-14
    )
    np.testing.assert_allclose(rot.quat_multiply(p, rot.quat_conjugate(p)), [[1, 0, 0, 0]] * 50, atol=1e-15)


def test_skew_is_cross_product():
    a, b = rng.normal(size=(2, 10, 3))
    np.testing.assert_allclose(np.einsum("nij,nj->ni", rot.skew(a), b), np.cross(a, b), atol=1e-15)


def test_hpr_round_trip_and_forward_axis():
    h, p, r = random_angles()
    mat = rot.mat_nb_from_hpr(h, p, r)
    for got, want in zip(rot.hpr_from_mat_nb(mat), (h, p, r)):
        np.testing.assert_allclose(got, want, atol=1e-12)
    forward = mat[:, :, 1]
    np.testing.assert_allclose(forward, np.stack([np.sin(h) * np.cos(p), np.cos(h) * np.cos(p), np.sin(p)], 1), atol=1e-15)
    # heading north, level: body axes are ENU (003: body and accompanying frames coincide)
    np.testing.assert_allclose(rot.mat_nb_from_hpr(0, 0, 0), np.eye(3))
    # positive roll puts the right side (body x) down
    assert rot.mat_nb_from_hpr(0, 0, 0.1)[2, 0] < 0


def test_body_rate_matches_finite_difference_of_attitude():
    h, p, r = random_angles(50)
    hd, pd, rd = rng.normal(size=(3, 50))
    dt = 1e-6
    m0 = rot.mat_nb_from_hpr(h - hd * dt, p - pd * dt, r - rd * dt)
    m1 = rot.mat_nb_from_hpr(h + hd * dt, p + pd * dt, r + rd * dt)
    mat = rot.mat_nb_from_hpr(h, p, r)
    # mat_nb' = mat_nb [omega_nb_b x]
    omega_skew = np.swapaxes(mat, 1, 2) @ (m1 - m0) / (2 * dt)
    omega_fd = np.stack([omega_skew[:, 2, 1], omega_skew[:, 0, 2], omega_skew[:, 1, 0]], 1)
    np.testing.assert_allclose(rot.body_rate_from_hpr_rates(h, p, r, hd, pd, rd), omega_fd, atol=1e-8)


def test_euler_krylov_round_trip_and_printed_entries():
    a, b, g = random_angles()
    a = a / 3  # alpha in (-pi/2, pi/2)
    mat = rot.euler_krylov_matrix(a, b, g)
    np.testing.assert_allclose(mat @ np.swapaxes(mat, 1, 2), np.broadcast_to(np.eye(3), mat.shape), atol=1e-14)
    for got, want in zip(rot.euler_krylov_from_matrix(mat), (a, b, g)):
        np.testing.assert_allclose(got, want, atol=1e-12)
    # Appendix 1, element (1,1) and (3,2) as printed
    np.testing.assert_allclose(mat[:, 0, 0], np.sin(b) * np.sin(a) * np.sin(g) + np.cos(b) * np.cos(g))
    np.testing.assert_allclose(mat[:, 2, 1], -np.sin(a))


def test_euler_krylov_rate_matrix_matches_finite_difference():
    a, b, g = random_angles(50)
    a = a / 3
    ad, bd, gd = rng.normal(size=(3, 50))
    dt = 1e-6
    d0 = rot.euler_krylov_matrix(a - ad * dt, b - bd * dt, g - gd * dt)
    d1 = rot.euler_krylov_matrix(a + ad * dt, b + bd * dt, g + gd * dt)
    d = rot.euler_krylov_matrix(a, b, g)
    # D maps reference -> body: D' = -[omega_b x] D
    omega_skew = -(d1 - d0) / (2 * dt) @ np.swapaxes(d, 1, 2)
    omega_b = np.stack([omega_skew[:, 2, 1], omega_skew[:, 0, 2], omega_skew[:, 1, 0]], 1)
    rates = np.einsum("nij,nj->ni", rot.euler_krylov_rate_matrix(a, g), omega_b)
    np.testing.assert_allclose(rates, np.stack([ad, bd, gd], 1), atol=1e-7)


def test_printed_kinematic_matrix_is_alpha_beta_swapped():
    """003 eq. (1) prints Phi(beta, gamma) = our Phi with alpha -> beta (module notes)."""
    b, g = 0.3, -0.7
    printed = np.array([
        [np.sin(g) / np.cos(b), np.cos(g) / np.cos(b), 0],
        [np.cos(g), -np.sin(g), 0],
        [np.sin(g) * np.tan(b), np.cos(g) * np.tan(b), 1],
    ])
    ours = rot.euler_krylov_rate_matrix(b, g)
    np.testing.assert_allclose(printed[[1, 0, 2]], ours, atol=1e-15)
    # and it is not the kinematic matrix of D as printed (unless rows/angles are swapped)
    assert not np.allclose(printed, ours)


@pytest.mark.parametrize("lat,lon", [(0.3, 0.7), (-1.1, 2.9), (0.0, 0.0)])
def test_b_matrix_of_003_is_enu(lat, lon):
    """B = D(-phi, lambda, 0) in the paper's Greenwich axes (xi, eta, zeta) = (y, z, x)."""
    b_paper = rot.euler_krylov_matrix(-lat, lon, 0.0)
    perm = np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]])  # ECEF -> (xi, eta, zeta)
    np.testing.assert_allclose(b_paper @ perm, mat_en(lat, lon), atol=1e-15)
    # the paper's eq. (4) in its own axes equals our geodetic_to_ecef permuted
    r, h = SPHERICAL.a, 100.0
    xi = (r + h) * np.cos(lat) * np.sin(lon)
    eta = (r + h) * np.sin(lat)
    zeta = (r + h) * np.cos(lat) * np.cos(lon)
    np.testing.assert_allclose(perm @ SPHERICAL.geodetic_to_ecef(lat, lon, h), [xi, eta, zeta], atol=1e-8)
