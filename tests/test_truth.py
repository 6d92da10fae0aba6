"""True motion: mutual consistency of position, velocity, attitude, rate and specific force.

The check is independent of the formulas in navsim.motion: it differentiates the true
trajectory numerically in the *inertial* frame (ECEF rotated by Omega t) and compares
    f_b = C_bi (d2 r_i / dt2 - gravitation_i)   and   [omega_ib_b x] = C_bi dC_ib/dt
with what the motion module computes analytically from the track geometry.
"""


import numpy as np
import pytest

from navsim.earth import SPHERICAL, WGS84, mat_en
from navsim.motion import ConstantSpeed, Oscillation, Station, Timetable, true_state
from navsim.trackio import load_bundled_track


def rot_ie(earth, t):
    """i <- e rotation at time t (frames coincide at t = 0)."""
    ang = earth.rate * np.asarray(t)
    c, s = np.cos(ang), np.sin(ang)
    z, o = np.zeros_like(ang), np.ones_like(ang)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def gravitation_e(earth, truth):
    g_e = np.einsum("nji,nj->ni", mat_en(truth.lat, truth.lon), earth.gravity_n(truth.lat, truth.h))
    omega = np.array([0.0, 0.0, earth.rate])
    centrifugal = -np.cross(omega, np.cross(omega, truth.position_e))
    return g_e - centrifugal


CASES = [
    ("paper-2012", SPHERICAL, ConstantSpeed(20.0, s0=100.0), ()),
    ("mountain-railway", WGS84, ConstantSpeed(22.0, s0=2000.0),
     (Oscillation("roll", 0.01, 1.3), Oscillation("pitch", 0.004, 0.8, 0.3))),
    ("urban-road", WGS84, Timetable((Station(50.0, 5.0), Station(900.0, 5.0)), cruise_speed=14.0, max_accel=2.0, max_decel=2.5, jerk_time=1.0), ()),
]


@pytest.mark.parametrize("track_name,earth,profile,osc", CASES, ids=[c[0] for c in CASES])
def test_specific_force_and_rate_match_inertial_finite_differences(track_name, earth, profile, osc):
    track = load_bundled_track(track_name, earth=earth)
    t0 = np.linspace(5.0, 60.0, 12)
    if isinstance(profile, Timetable):
        # the stencils must not straddle a ramp end, where the jerk has a kink
        events = profile._event_times
        t0 = t0[np.min(np.abs(t0[:, None] - events[None, :]), axis=1) > 0.25]
    # step: rounding of ~6.4e6 m positions (ulp 1e-9 m) costs ~64 ulp / (24 d^2) = 1.1e-5
    # m/s^2 at d = 0.015 s; truncation stays below that even where the urban road's
    # spline curvature ripples over a few metres
    d = 0.015
    stencil = np.array([-2, -1, 0, 1, 2]) * d
    t = (t0[:, None] + stencil[None, :]).ravel()
    truth = true_state(track, profile, t, osc)
    r_i = np.einsum("nij,nj->ni", rot_ie(earth, t), truth.position_e).reshape(len(t0), 5, 3)
    # fourth-order central second difference
    acc_i = (-r_i[:, 0] + 16 * r_i[:, 1] - 30 * r_i[:, 2] + 16 * r_i[:, 3] - r_i[:, 4]) / (12 * d * d)
    mid = slice(2, None, 5)
    mat_ie_mid = rot_ie(earth, t[mid])
    grav_i = np.einsum("nij,nj->ni", mat_ie_mid, gravitation_e(earth, truth)[mid])
    mat_ib = np.einsum("nij,njk,nkl->nil", rot_ie(earth, t), np.swapaxes(mat_en(truth.lat, truth.lon), -1, -2), truth.mat_nb)
    mat_ib = mat_ib.reshape(len(t0), 5, 3, 3)
    f_b_fd = np.einsum("nji,nj->ni", mat_ib[:, 2], acc_i - grav_i)
    np.testing.assert_allclose(truth.specific_force_b[mid], f_b_fd, atol=3e-5)
    # attitude rate: a short step (matrix entries are O(1), so rounding is ~eps/d)
    d_rate = 1e-3
    t_rate = (t0[:, None] + np.array([-2, -1, 0, 1, 2])[None, :] * d_rate).ravel()
    truth_r = true_state(track, profile, t_rate, osc)
    mat_ib = np.einsum("nij,njk,nkl->nil", rot_ie(earth, t_rate),
                       np.swapaxes(mat_en(truth_r.lat, truth_r.lon), -1, -2), truth_r.mat_nb).reshape(len(t0), 5, 3, 3)
    dmat = (mat_ib[:, 0] - 8 * mat_ib[:, 1] + 8 * mat_ib[:, 3] - mat_ib[:, 4]) / (12 * d_rate)
    omega_skew = np.einsum("nji,njk->nik", mat_ib[:, 2], dmat)
    omega_fd = np.stack([omega_skew[:, 2, 1], omega_skew[:, 0, 2], omega_skew[:, 1, 0]], -1)
    np.testing.assert_allclose(truth_r.omega_ib_b[mid], omega_fd, atol=1e-10)
    # velocity: ECEF FD of position
    r_e = truth.position_e.reshape(len(t0), 5, 3)
    v_fd = (r_e[:, 0] - 8 * r_e[:, 1] + 8 * r_e[:, 3] - r_e[:, 4]) / (12 * d)
    np.testing.assert_allclose(truth.velocity_e[mid], v_fd, atol=1e-6)


def test_stationary_vehicle_feels_gravity_and_earth_rate():
    track = load_bundled_track("mountain-railway", earth=WGS84)
    truth = true_state(track, ConstantSpeed(0.0, s0=500.0), np.array([0.0, 10.0]))
    g_n = WGS84.gravity_n(truth.lat, truth.h)
    f_n = np.einsum("nij,nj->ni", truth.mat_nb, truth.specific_force_b)
    np.testing.assert_allclose(f_n, -g_n, atol=1e-12)
    w_n = np.einsum("nij,nj->ni", truth.mat_nb, truth.omega_ib_b)
    np.testing.assert_allclose(w_n, WGS84.earth_rate_n(truth.lat), atol=1e-18)
    np.testing.assert_allclose(np.linalg.norm(truth.omega_ib_b, axis=1), WGS84.rate, rtol=1e-12)
