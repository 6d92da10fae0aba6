"""Unmodelled IMU scale factor / misalignment as rate- and acceleration-proportional noise
((RS.1), (RS.2) of navsim.estimators._inserror; options gyro_scale_sigma,
accel_scale_sigma, scale_tau_s of lc-ekf, tc-ekf, tc-ukf).

Closed forms: after an interval in which the attitude turned by theta in T seconds, the
next interval's Qc gets sigma_s^2 (theta / T)^2 tau I on the attitude block; with a mean
specific force f_n, sigma_a^2 |f_n + g_n|^2 tau I on the velocity block; nothing else
changes, and with both sigmas 0 (the default) the engine's numbers are the same as
before bit for bit (the term is not even formed).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from navsim import estimators
from navsim.episode import make_context, run_episode
from navsim.errors import ConfigError
from navsim.rotations import quat_to_mat
from navsim.scenario import load_scenario
from navsim.simulator import Simulator


def _axis_z(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("name", ["lc-ekf", "tc-ekf", "tc-ukf"])
def test_added_process_noise_is_the_closed_form(name):
    sc = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 5.0}})
    context, prior = make_context(sc), Simulator(sc).reset(0).prior
    sg, sa, tau = 0.02, 0.03, 4.0
    est = estimators.make(name, gyro_scale_sigma=sg, accel_scale_sigma=sa, scale_tau_s=tau)
    est.reset(context, prior)
    eng = est.engine
    base = eng.Qc.copy()
    st = eng.state
    C = quat_to_mat(st.quat_nb)
    theta, steps = 0.4, 50  # 0.4 rad in 0.5 s: 0.8 rad/s
    eng._mat_nb0 = _axis_z(-theta) @ C  # the attitude at the start of the interval that ends now
    eng._j = steps
    accel = np.array([3.0, -1.0, 0.5])
    g = np.asarray(eng.earth.gravity_n(st.lat, st.h), dtype=float)
    eng._f_sum = (accel - g) * (steps * eng.dt)  # the interval's specific-force sum: mean f_n = accel - g
    eng._start_interval(eng.covariance.copy())
    q = eng._series.q1
    rate = theta / (steps * eng.dt)
    expected = base.copy()
    expected[6:9, 6:9] += np.eye(3) * sg**2 * rate**2 * tau
    expected[3:6, 3:6] += np.eye(3) * sa**2 * float(accel @ accel) * tau
    # the angle from acos of the trace: a few ulp of rate^2 (|d acos| ~ eps / sin(theta))
    np.testing.assert_allclose(q, expected, rtol=1e-12, atol=1e-12 * np.max(np.abs(expected)))


def test_off_by_default_and_checked():
    sc = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 5.0}})
    a = run_episode(sc, estimators.make("lc-ekf"), seed=0)
    b = run_episode(sc, estimators.make("lc-ekf", gyro_scale_sigma=0.0, accel_scale_sigma=0.0), seed=0)
    np.testing.assert_array_equal(a.est_cov, b.est_cov)
    c = run_episode(sc, estimators.make("lc-ekf", gyro_scale_sigma=0.02), seed=0)
    assert np.max(np.diagonal(c.est_cov, axis1=1, axis2=2)[:, 6:9] - np.diagonal(a.est_cov, axis1=1, axis2=2)[:, 6:9]) >= 0.0
    for bad in ({"gyro_scale_sigma": -1.0}, {"scale_tau_s": 0.0}):
        with pytest.raises(ConfigError):
            estimators.make("tc-ukf", **bad)
        with pytest.raises(ConfigError):
            estimators.make("lc-ekf", **bad)
