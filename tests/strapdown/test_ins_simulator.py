"""Free-inertial round trip: navsim's INS on the simulator's ideal IMU output.

Measured on this machine (the slow tests print their figures):
1000 s of the paper scenario, best algorithms (multiple integrals): 2e-7 m horizontal at
100 Hz and 2e-5 m at 10 Hz; with the one-sample / first-order / rectangle algorithms
2.4e-2 m and 0.24 m. pyins' figures on this kind of machine: 0.075 m over 30 min at
100 Hz and 8.5 m at 10 Hz (increments).
"""

import numpy as np
import pytest

from navsim.rotations import mat_to_quat, quat_to_mat, quat_to_rotvec
from navsim.scenario import load_scenario
from navsim.simulator import Simulator
from navsim.strapdown.ins import InsState, integrate


def free_inertial(name, duration, nav, imu, **methods):
    sc = load_scenario(name).with_overrides({
        "timing": {"duration_s": duration, "tick_s": imu, "imu_period_s": imu, "nav_period_s": nav},
        "imu": {"preset": "ideal"}, "gnss": {"enabled": False}})
    sim = Simulator(sc)
    start = sim.reset(0)
    chunks = list(sim.chunks(50_000))

    def cat(get):
        return np.concatenate([get(c) for c in chunks])

    t0 = start.truth
    state = InsState(lat=t0.lat[0], lon=t0.lon[0], h=t0.h[0], velocity_n=t0.velocity_n[0],
                     quat_nb=mat_to_quat(t0.mat_nb[0]))
    sol = integrate(state, dtheta_sub=cat(lambda c: c.imu.dtheta_sub), dv_sub=cat(lambda c: c.imu.dv_sub),
                    dtheta_r=cat(lambda c: c.imu.dtheta_r), dv_r=cat(lambda c: c.imu.dv_r), dt=nav,
                    earth=sim.earth, **methods)
    lat, lon, h = cat(lambda c: c.truth.lat), cat(lambda c: c.truth.lon), cat(lambda c: c.truth.h)
    r_n, r_e = sim.earth.radii(lat)
    horizontal = np.hypot((sol.lat[1:] - lat) * (r_n + h), (sol.lon[1:] - lon) * (r_e + h) * np.cos(lat))
    velocity = np.linalg.norm(sol.velocity_n[1:] - cat(lambda c: c.truth.velocity_n), axis=1)
    rel = quat_to_mat(sol.quat_nb[1:]) @ np.swapaxes(cat(lambda c: c.truth.mat_nb), 1, 2)
    attitude = np.linalg.norm(quat_to_rotvec(mat_to_quat(rel)), axis=1)
    return horizontal, velocity, attitude


def test_free_inertial_100s_at_100hz_is_exact_to_rounding():
    hor, vel, att = free_inertial("paper-2012", 100.0, 0.01, 0.01)
    assert hor.max() < 1e-6 and vel.max() < 1e-8 and att.max() < 1e-12


def test_multiple_integral_algorithms_beat_one_sample_on_the_track():
    best = free_inertial("mountain-railway", 60.0, 0.01, 0.005)
    crude = free_inertial("mountain-railway", 60.0, 0.01, 0.005, coning="one-sample", sculling="first-order",
                          position="rectangle")
    assert best[0][-1] < crude[0][-1] / 100
    assert best[2][-1] < crude[2][-1] / 10


@pytest.mark.slow
@pytest.mark.parametrize("rate_hz,bound_m", [(100.0, 1e-5), (10.0, 1e-3)])
def test_free_inertial_1000s_paper_scenario(rate_hz, bound_m):
    hor, vel, att = free_inertial("paper-2012", 1000.0, 1 / rate_hz, 1 / rate_hz)
    print(f"{rate_hz:.0f} Hz, 1000 s: horizontal {hor[-1]:.2e} m, velocity {vel[-1]:.2e} m/s, attitude {att[-1]:.2e} rad")
    assert hor[-1] < bound_m
