"""INS mechanisation: round trips of exact increments of analytic trajectories.

The truth is built from geometry alone: lat, lon, h are given functions of time, the
ENU velocity and its derivative follow from the radii of curvature and their derivatives,
the attitude from heading, pitch and roll functions; the specific force is
``v' + (2 w_ie + w_en) x v - g`` and the body rate ``C_bn (w_ie + w_en) + w_nb``. The
increments are integrated by Gauss-Legendre quadrature (8 nodes per sub-interval, exact to
rounding for these smooth integrands), the multiple integrals through the Cauchy kernel
``(t_k+1 - tau)^(r-1) / (r-1)!``.
"""

from __future__ import annotations

from math import factorial

import numpy as np
import pytest

from navsim.earth import SPHERICAL, WGS84
from navsim.errors import ConfigError
from navsim.rotations import (
    body_rate_from_hpr_rates,
    mat_nb_from_hpr,
    mat_to_quat,
    quat_conjugate,
    quat_multiply,
    quat_to_rotvec,
)
from navsim.strapdown.ins import InsState, ins_step, integrate, resolve_methods


class Trajectory:
    """lat = lat0 + c t, lon = lon0 + d t, h = h0 + A sin(w_h t); analytic attitude."""

    def __init__(self, earth, lat0=0.9, lon0=0.5, h0=100.0, c=3e-6, d=2e-6, amp_h=5.0, w_h=0.05,
                 psi0=0.3, psi_dot=0.02, pitch_amp=0.05, w_p=0.3, roll_amp=0.04, w_r=0.5):
        self.earth = earth
        self.lat0, self.lon0, self.h0, self.c, self.d = lat0, lon0, h0, c, d
        self.amp_h, self.w_h = amp_h, w_h
        self.psi0, self.psi_dot = psi0, psi_dot
        self.pitch_amp, self.w_p, self.roll_amp, self.w_r = pitch_amp, w_p, roll_amp, w_r

    def kinematics(self, t):
        e = self.earth
        t = np.asarray(t, dtype=float)
        lat = self.lat0 + self.c * t
        lon = self.lon0 + self.d * t
        h = self.h0 + self.amp_h * np.sin(self.w_h * t)
        hd = self.amp_h * self.w_h * np.cos(self.w_h * t)
        hdd = -self.amp_h * self.w_h**2 * np.sin(self.w_h * t)
        rn, re = e.radii(lat)
        drn, dre = e.radii_derivative(lat)
        cl, sl = np.cos(lat), np.sin(lat)
        v = np.stack([(re + h) * cl * self.d, (rn + h) * self.c, hd], -1)
        vdot = np.stack(
            [self.d * ((dre * self.c + hd) * cl - (re + h) * sl * self.c), self.c * (drn * self.c + hd), hdd], -1
        )
        heading = self.psi0 + self.psi_dot * t
        pitch = self.pitch_amp * np.sin(self.w_p * t)
        roll = self.roll_amp * np.sin(self.w_r * t)
        mat_nb = mat_nb_from_hpr(heading, pitch, roll)
        omega_nb_b = body_rate_from_hpr_rates(
            heading, pitch, roll, self.psi_dot + 0 * t,
            self.pitch_amp * self.w_p * np.cos(self.w_p * t), self.roll_amp * self.w_r * np.cos(self.w_r * t),
        )
        omega_in_n = e.earth_rate_n(lat) + e.transport_rate_n(lat, h, v)
        f_n = vdot + np.cross(e.earth_rate_n(lat) + omega_in_n, v) - e.gravity_n(lat, h)
        omega_ib_b = np.einsum("...ji,...j->...i", mat_nb, omega_in_n) + omega_nb_b
        f_b = np.einsum("...ji,...j->...i", mat_nb, f_n)
        return {"lat": lat, "lon": lon, "h": h, "v": v, "mat_nb": mat_nb, "omega_ib_b": omega_ib_b, "f_b": f_b}

    def increments(self, dt, n, m=2, orders=4, nodes=8):
        """dtheta_sub, dv_sub (n, m, 3) and dtheta_r, dv_r (n, orders, 3)."""
        x, w = np.polynomial.legendre.leggauss(nodes)
        hs = dt / m
        starts = np.arange(n)[:, None] * dt + np.arange(m)[None, :] * hs
        tq = starts[..., None] + 0.5 * hs * (x + 1.0)
        kin = self.kinematics(tq)
        wq = 0.5 * hs * w
        dth = np.einsum("q,nmqi->nmi", wq, kin["omega_ib_b"])
        dv = np.einsum("q,nmqi->nmi", wq, kin["f_b"])
        lever = dt - (tq - np.arange(n)[:, None, None] * dt)  # t_k+1 - tau
        kernels = [lever ** (r - 1) / factorial(r - 1) for r in range(1, orders + 1)]
        th_r = np.stack([np.einsum("q,nmq,nmqi->ni", wq, k, kin["omega_ib_b"]) for k in kernels], 1)
        dv_r = np.stack([np.einsum("q,nmq,nmqi->ni", wq, k, kin["f_b"]) for k in kernels], 1)
        return dth, dv, th_r, dv_r

    def state(self, t):
        k = self.kinematics(np.array([t]))
        return InsState(k["lat"][0], k["lon"][0], k["h"][0], k["v"][0], mat_to_quat(k["mat_nb"][0]))


def _errors(traj, sol, dt):
    k = traj.kinematics(dt * np.arange(len(sol)))
    rn, re = traj.earth.radii(k["lat"])
    north = (sol.lat - k["lat"]) * (rn + k["h"])
    east = (sol.lon - k["lon"]) * (re + k["h"]) * np.cos(k["lat"])
    position = np.abs(np.stack([east, north, sol.h - k["h"]], -1)).max()
    velocity = np.abs(sol.velocity_n - k["v"]).max()
    attitude = np.abs(quat_to_rotvec(quat_multiply(quat_conjugate(mat_to_quat(k["mat_nb"])), sol.quat_nb))).max()
    return position, velocity, attitude


def _stationary(earth, n, dt, lat=0.7, h=250.0, hpr=(0.4, 0.1, -0.2), m=2):
    """Exact increments of a vehicle at rest on the rotating Earth (constant in body)."""
    mat_nb = mat_nb_from_hpr(*hpr)
    omega_b = mat_nb.T @ earth.earth_rate_n(lat)
    f_b = -mat_nb.T @ earth.gravity_n(lat, h)
    dtheta_sub = np.broadcast_to(omega_b * dt / m, (n, m, 3))
    dv_sub = np.broadcast_to(f_b * dt / m, (n, m, 3))
    state = InsState(lat, 0.2, h, np.zeros(3), mat_to_quat(mat_nb))
    return state, dtheta_sub, dv_sub


# simple closures with the registry signatures (constant-rate models)
def _one_sample(dtheta_sub, dtheta_r, dt=None):
    return np.sum(dtheta_sub, axis=1)


def _first_order(dtheta_sub, dv_sub, dtheta_r, dv_r, dt=None):
    dth, dv = np.sum(dtheta_sub, axis=1), np.sum(dv_sub, axis=1)
    return dv + 0.5 * np.cross(dth, dv)


@pytest.mark.parametrize("earth", [WGS84, SPHERICAL], ids=["wgs84", "spherical"])
def test_stationary_vehicle_stays_put(earth):
    dt, n = 0.01, 20_000  # 200 s at 100 Hz
    state, dth, dv = _stationary(earth, n, dt)
    sol = integrate(state, dth, dv, dt=dt, earth=earth, coning=_one_sample, sculling=_first_order,
                    position="trapezoid")
    r_n, r_e = earth.radii(state.lat)
    assert np.abs(sol.lat - state.lat).max() * r_n < 1e-6
    assert np.abs(sol.lon - state.lon).max() * r_e < 1e-6
    assert np.abs(sol.h - state.h).max() < 1e-6
    assert np.abs(sol.velocity_n).max() < 1e-8
    err = quat_to_rotvec(quat_multiply(quat_conjugate(state.quat_nb), sol.quat_nb))
    assert np.abs(err).max() < 1e-10  # rounding only


def test_ignoring_the_frame_rotation_would_fail():
    # the same stationary data with the earth-rate increments removed must drift: proof
    # that the test above exercises the omega_in and Coriolis terms
    dt, n = 0.01, 2000
    state, dth, dv = _stationary(WGS84, n, dt)
    sol = integrate(state, np.zeros_like(dth), dv, dt=dt, earth=WGS84, coning="one-sample",
                    sculling="first-order", position="trapezoid")
    err = quat_to_rotvec(quat_multiply(quat_conjugate(state.quat_nb), sol.quat_nb[-1]))
    assert np.linalg.norm(err) > 0.5 * WGS84.rate * n * dt


@pytest.fixture(scope="module")
def moving():
    traj = Trajectory(WGS84)
    dt, n = 0.01, 20_000  # 200 s at 100 Hz
    return traj, dt, traj.increments(dt, n)


def test_moving_vehicle_round_trip_multiple_integrals(moving):
    traj, dt, (dth, dv, th_r, dv_r) = moving
    sol = integrate(traj.state(0.0), None, None, th_r, dv_r, dt=dt, earth=WGS84)  # auto: invariant
    position, velocity, attitude = _errors(traj, sol, dt)
    assert position < 1e-5 and velocity < 1e-8 and attitude < 1e-11


def test_moving_vehicle_round_trip_sub_samples(moving):
    traj, dt, (dth, dv, th_r, dv_r) = moving
    sol = integrate(traj.state(0.0), dth, dv, dt=dt, earth=WGS84, coning="two-sample", sculling="two-sample",
                    position="trapezoid")
    position, velocity, attitude = _errors(traj, sol, dt)
    assert position < 1e-5 and velocity < 1e-8 and attitude < 1e-11


def test_rectangle_rule_is_worse_than_exact_form(moving):
    traj, dt, (dth, dv, th_r, dv_r) = moving
    n = 2000
    exact = integrate(traj.state(0.0), None, None, th_r[:n], dv_r[:n], dt=dt, earth=WGS84, position="exact-invariant")
    rect = integrate(traj.state(0.0), None, None, th_r[:n], dv_r[:n], dt=dt, earth=WGS84, position="rectangle")
    assert _errors(traj, rect, dt)[0] > 100 * _errors(traj, exact, dt)[0]


def test_second_order_in_step_size():
    # position error at 10 Hz vs 5 Hz steps over 200 s on the spherical Earth
    traj = Trajectory(SPHERICAL)
    errs = []
    for dt in (0.2, 0.1):
        n = int(round(200 / dt))
        _, _, th_r, dv_r = traj.increments(dt, n)
        errs.append(_errors(traj, integrate(traj.state(0.0), None, None, th_r, dv_r, dt=dt, earth=SPHERICAL), dt))
    assert errs[1][1] < errs[0][1] / 3  # velocity: at least second order
    assert errs[1][0] < 1e-3


def test_chunks_give_the_same_numbers(moving):
    traj, dt, (dth, dv, th_r, dv_r) = moving
    n1, n2 = 70, 130
    whole = integrate(traj.state(0.0), dth[: n1 + n2], dv[: n1 + n2], th_r[: n1 + n2], dv_r[: n1 + n2], dt=dt)
    first = integrate(traj.state(0.0), dth[:n1], dv[:n1], th_r[:n1], dv_r[:n1], dt=dt)
    second = integrate(first.final, dth[n1:n1 + n2], dv[n1:n1 + n2], th_r[n1:n1 + n2], dv_r[n1:n1 + n2], dt=dt)
    for name in ("lat", "lon", "h", "velocity_n", "quat_nb"):
        joined = np.concatenate([getattr(first, name), getattr(second, name)[1:]])
        np.testing.assert_array_equal(joined, getattr(whole, name))


def test_ins_step_is_one_row_of_integrate(moving):
    traj, dt, (dth, dv, th_r, dv_r) = moving
    sol = integrate(traj.state(0.0), dth[:20], dv[:20], dt=dt, coning="two-sample", sculling="two-sample",
                    position="trapezoid")
    state = traj.state(0.0)
    for k in range(20):
        state = ins_step(state, dth[k], dv[k], dt=dt, coning="two-sample", sculling="two-sample",
                         position="trapezoid")
    np.testing.assert_array_equal(state.velocity_n, sol.velocity_n[-1])
    np.testing.assert_array_equal(state.quat_nb, sol.quat_nb[-1])
    assert (state.lat, state.lon, state.h) == (sol.lat[-1], sol.lon[-1], sol.h[-1])
    assert state.compensation == sol.final_compensation


def test_resolve_methods_picks_the_richest_inputs():
    n = 3
    sub = np.zeros((n, 2, 3))
    r4 = np.zeros((n, 4, 3))
    assert resolve_methods(None, None, None, None, None, r4, r4) == ("invariant", "invariant-4.4", "exact-invariant")
    assert resolve_methods(None, None, None, sub, sub) == ("two-sample", "two-sample", "trapezoid")
    assert resolve_methods("one-sample", None, "rectangle", sub, sub)[::2] == ("one-sample", "rectangle")
    one = np.zeros((n, 1, 3))
    assert resolve_methods(None, None, None, one, one) == ("one-sample", "first-order", "trapezoid")


def test_bad_inputs_raise_config_errors():
    state, dth, dv = _stationary(WGS84, 4, 0.01)
    with pytest.raises(ConfigError, match="dt"):
        integrate(state, dth, dv, dt=0.0)
    with pytest.raises(ConfigError, match="coning"):
        integrate(state, dth, dv, dt=0.01, coning="no-such-method")
    with pytest.raises(ConfigError, match="dv_sub"):
        integrate(state, dth, dv[:, :, :2], dt=0.01)
    with pytest.raises(ConfigError, match="increments"):
        integrate(state, dth, dv[:3], dt=0.01)
    with pytest.raises(ConfigError, match="quat_nb"):
        InsState(0.1, 0.2, 0.0, np.zeros(3), [1.0, 0.1, 0.0, 0.0])
    with pytest.raises(ConfigError, match="lat"):
        InsState(2.0, 0.2, 0.0, np.zeros(3), [1.0, 0.0, 0.0, 0.0])
    with pytest.raises(ConfigError, match="dtheta_sub"):
        ins_step(state, dth[:2], dv[:2], dt=0.01)


@pytest.mark.slow
@pytest.mark.parametrize("earth", [WGS84, SPHERICAL], ids=["wgs84", "spherical"])
def test_project_target_1000_s_at_100_hz(earth):
    # better than 1 cm, 1 mm/s and 1e-6 rad over 1000 s at 100 Hz with exact increments
    traj = Trajectory(earth)
    dt, n = 0.01, 100_000
    _, _, th_r, dv_r = traj.increments(dt, n)
    position, velocity, attitude = _errors(traj, integrate(traj.state(0.0), None, None, th_r, dv_r, dt=dt,
                                                           earth=earth), dt)
    assert position < 1e-5 and velocity < 1e-8 and attitude < 1e-11
