"""The loop-free (scan) integrator against the sequential loop and against analytic truth.

Truth: the analytic trajectories of test_ins.py (exact increments by Gauss-Legendre
quadrature). The scan method solves the same discrete equations as the loop, so the two
must agree to rounding; "rounding" is measured here, not assumed: the sequential loop's own
sensitivity to 1-ulp perturbations of its inputs gives the scale.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_ins import Trajectory, _errors, _stationary

from navsim.earth import SPHERICAL, WGS84
from navsim.errors import ConfigError
from navsim.rotations import quat_conjugate, quat_from_rotvec, quat_multiply, quat_to_rotvec
from navsim.strapdown import ins
from navsim.strapdown.ins import body_terms, integrate, integrate_body_terms
from navsim.strapdown.scan import _prefix, integrate_scan, prefix_quat_products
from tolerances import EPS, gamma

R_EARTH = 6.4e6


def _differences(a, b):
    """Max |a - b|: horizontal (m), height (m), velocity (m/s), quaternion components."""
    horizontal = max(np.abs(a.lat - b.lat).max(), np.abs(a.lon - b.lon).max()) * R_EARTH
    return (horizontal, np.abs(a.h - b.h).max(), np.abs(a.velocity_n - b.velocity_n).max(),
            np.abs(a.quat_nb - b.quat_nb).max())


@pytest.fixture(scope="module")
def moving():
    traj = Trajectory(WGS84)
    dt, n = 0.01, 20_000  # 200 s at 100 Hz
    return traj, dt, traj.increments(dt, n)


def test_prefix_products_equal_the_sequential_product():
    rng = np.random.default_rng(3)
    for n in (1, 2, 3, 17, 33, 100, 1001):
        q = quat_from_rotvec(rng.normal(scale=0.3, size=(n, 3)))
        ref = q.copy()
        for k in range(1, n):
            ref[k] = quat_multiply(ref[k - 1], q[k])
        # another association of the same n - 1 products: each Hamilton product rounds its
        # 4-term sums (gamma_4 relative on unit quaternions); the loop chains n - 1 of them,
        # the scan at most n - 1 along any path. Bound: 2 (n - 1) gamma_4 (+ 2 ulp for n = 1)
        bound = 2.0 * max(n - 1, 1) * gamma(4) + 2.0 * EPS
        np.testing.assert_allclose(prefix_quat_products(q), ref, rtol=0, atol=bound)
    # the order matters (non-commutative): reversing the factors gives another product
    q = quat_from_rotvec(rng.normal(scale=0.3, size=(40, 3)))
    assert np.abs(_prefix(q[::-1].T.copy())[:, -1] - prefix_quat_products(q)[-1]).max() > 1e-3


@pytest.mark.parametrize("kind", ["multiple-integrals", "sub-samples"])
def test_scan_reproduces_the_loop_to_rounding(moving, kind):
    traj, dt, (dth, dv, th_r, dv_r) = moving
    if kind == "multiple-integrals":
        t = body_terms(None, None, th_r, dv_r, dt)
    else:
        t = body_terms(dth, dv, None, None, dt, "two-sample", "two-sample", "trapezoid")
    state = traj.state(0.0)
    args = (t.quat_body, t.dv_body, t.ds_body, t.rule, dt, WGS84)
    seq = integrate_body_terms(state, *args, method="sequential")
    stats = {}
    scan = integrate_scan(state, *args, stats=stats)
    diff = _differences(scan, seq)
    # the loop's own rounding scale: its change under 1-ulp perturbations of every input
    rng = np.random.default_rng(7)

    def ulp(x):
        return None if x is None else x * (1.0 + 2.2e-16 * rng.choice([-1.0, 1.0], size=x.shape))

    pert = integrate_body_terms(state, ulp(t.quat_body), ulp(t.dv_body), ulp(t.ds_body), t.rule, dt, WGS84,
                                method="sequential")
    scale = _differences(pert, seq)
    print(f"{kind}: scan - loop {diff}; loop under 1-ulp inputs {scale}; {stats}")
    assert diff[0] <= 3 * 7.2e-10  # <= 3 ulp of latitude (1 ulp of 0.9 rad = 7.1e-10 m)
    assert diff[1] < 1e-10 and diff[2] < 1e-11 and diff[3] < 1e-13
    assert diff[1] <= 50 * max(scale[1], 1e-13) and diff[2] <= 50 * scale[2] and diff[3] <= 50 * scale[3]
    # against the analytic truth the scan is as accurate as the loop
    e_seq, e_scan = _errors(traj, seq, dt), _errors(traj, scan, dt)
    assert e_scan[0] <= e_seq[0] * 1.01 + 2e-9
    assert e_scan[1] <= e_seq[1] * 1.01 + 1e-11
    assert e_scan[2] <= e_seq[2] * 2.0 + 1e-13
    assert stats["splits"] == 0 and stats["iterations"] <= 5 * stats["windows"]


def test_chunks_at_window_boundaries_give_the_same_numbers(moving):
    traj, dt, (dth, dv, th_r, dv_r) = moving
    n, window = 5000, 1000
    t = body_terms(None, None, th_r[:n], dv_r[:n], dt)
    state = traj.state(0.0)

    def run(s, a, b):
        return integrate_body_terms(s, t.quat_body[a:b], t.dv_body[a:b], t.ds_body[a:b], t.rule, dt, WGS84,
                                    method="scan", window=window)

    whole = run(state, 0, n)
    first = run(state, 0, 2 * window)
    second = run(first.final, 2 * window, n)
    for name in ("lat", "lon", "h", "velocity_n", "quat_nb"):
        joined = np.concatenate([getattr(first, name), getattr(second, name)[1:]])
        np.testing.assert_array_equal(joined, getattr(whole, name))
    assert second.final_compensation == whole.final_compensation
    # elsewhere the window boundaries move: rounding-level differences only
    first = run(state, 0, 1234)
    second = run(first.final, 1234, n)
    joined = ins.InsSolution(*(np.concatenate([getattr(first, k), getattr(second, k)[1:]])
                               for k in ("lat", "lon", "h", "velocity_n", "quat_nb")))
    diff = _differences(joined, whole)
    assert diff[0] <= 2 * 7.2e-10 and diff[1] < 1e-11 and diff[2] < 1e-12 and diff[3] < 1e-14


@pytest.mark.parametrize("earth", [WGS84, SPHERICAL], ids=["wgs84", "spherical"])
def test_stationary_vehicle_stays_put_with_scan(earth):
    dt, n = 0.01, 20_000
    state, dth, dv = _stationary(earth, n, dt)
    sol = integrate(state, dth, dv, dt=dt, earth=earth, coning="two-sample", sculling="two-sample",
                    position="trapezoid", method="scan")
    r_n, r_e = earth.radii(state.lat)
    assert np.abs(sol.lat - state.lat).max() * r_n < 1e-6
    assert np.abs(sol.lon - state.lon).max() * r_e < 1e-6
    assert np.abs(sol.h - state.h).max() < 1e-6
    assert np.abs(sol.velocity_n).max() < 1e-8
    err = quat_to_rotvec(quat_multiply(quat_conjugate(state.quat_nb), sol.quat_nb))
    assert np.abs(err).max() < 1e-10


def test_split_windows_still_reproduce_the_loop(moving):
    # one iteration per window never converges: every window is split down to short
    # pieces; the solution is still the loop's
    traj, dt, (dth, dv, th_r, dv_r) = moving
    n = 300
    t = body_terms(None, None, th_r[:n], dv_r[:n], dt)
    state = traj.state(0.0)
    args = (t.quat_body, t.dv_body, t.ds_body, t.rule, dt, WGS84)
    stats = {}
    scan = integrate_scan(state, *args, window=n, max_iterations=2, stats=stats)
    seq = integrate_body_terms(state, *args, method="sequential")
    assert stats["splits"] > 0
    diff = _differences(scan, seq)
    assert diff[0] <= 2 * 7.2e-10 and diff[1] < 1e-11 and diff[2] < 1e-12 and diff[3] < 1e-14


def test_public_entry_points_and_methods(moving):
    traj, dt, (dth, dv, th_r, dv_r) = moving
    n = 500
    state = traj.state(0.0)
    ref = integrate(state, None, None, th_r[:n], dv_r[:n], dt=dt, method="sequential")
    t = body_terms(None, None, th_r[:n], dv_r[:n], dt)
    via_terms = integrate_body_terms(state, t.quat_body, t.dv_body, t.ds_body, t.rule, dt, method="sequential")
    legacy = ins._run(state, t.quat_body, t.dv_body, t.ds_body, t.rule, dt, WGS84)  # the old private name
    auto = integrate(state, None, None, th_r[:n], dv_r[:n], dt=dt)  # n < AUTO_SCAN_MIN_STEPS: the loop
    for sol in (via_terms, legacy, auto):
        np.testing.assert_array_equal(sol.lat, ref.lat)
        np.testing.assert_array_equal(sol.quat_nb, ref.quat_nb)
    # the terms are the registry's: rotation vector and first-order increments
    np.testing.assert_allclose(t.dtheta_first, th_r[:n, 0], rtol=0, atol=0)
    np.testing.assert_allclose(t.dv_first, dv_r[:n, 0], rtol=0, atol=0)
    np.testing.assert_array_equal(t.quat_body, quat_from_rotvec(t.rotvec_body))
    assert len(t) == n
    with pytest.raises(ConfigError, match="method"):
        integrate(state, None, None, th_r[:n], dv_r[:n], dt=dt, method="fast")
    with pytest.raises(ConfigError, match="window"):
        integrate(state, None, None, th_r[:n], dv_r[:n], dt=dt, method="scan", window=0)
    with pytest.raises(ConfigError, match="ds_body"):
        integrate_body_terms(state, t.quat_body, t.dv_body, None, None, dt)
    with pytest.raises(ConfigError, match="rule"):
        integrate_body_terms(state, t.quat_body, t.dv_body, None, "simpson", dt)


def test_auto_uses_the_scan_for_long_runs(moving):
    traj, dt, (dth, dv, th_r, dv_r) = moving
    n = ins.AUTO_SCAN_MIN_STEPS
    state = traj.state(0.0)
    auto = integrate(state, None, None, th_r[:n], dv_r[:n], dt=dt)
    scan = integrate(state, None, None, th_r[:n], dv_r[:n], dt=dt, method="scan")
    np.testing.assert_array_equal(auto.velocity_n, scan.velocity_n)
