"""Batch strapdown throughput of navsim.strapdown.ins.integrate, in IMU samples per second.

Measured in one process, on the same data (a vehicle at rest on WGS-84, 100 Hz navigation
steps with m = 2 IMU sub-samples per step, so 1 step = 2 IMU samples):

* ``integrate`` with sub-sample increments (two-sample coning/sculling, trapezoid);
* ``integrate`` with multiple integrals (invariant algorithms, exact position form);
* ``ins_step`` called once per step (how a stepped estimator uses the INS);
* a plain reference loop: the same equations written directly with numpy per step
  (first-order Euler on gravity/Coriolis, rotations through navsim.rotations), the
  usual first version of such code.

Anchor: pyins' numba strapdown integrator, 1.29 M samples/s warm on this kind of machine
(research/anchors-ins-gnss.md).

Run: ``python benchmarks/bench_ins.py [seconds]`` (default 300 s of data).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from navsim.earth import WGS84
from navsim.rotations import mat_nb_from_hpr, mat_to_quat, quat_from_rotvec, quat_multiply, quat_to_mat
from navsim.strapdown.ins import InsState, ins_step, integrate

SUB = 2
DT = 0.01


def _data(n: int):
    lat, h = 0.7, 100.0
    mat_nb = mat_nb_from_hpr(0.4, 0.05, -0.03)
    omega_b = mat_nb.T @ WGS84.earth_rate_n(lat)
    f_b = -mat_nb.T @ WGS84.gravity_n(lat, h)
    rng = np.random.default_rng(0)  # tiny noise so no step is trivially repeated
    dth = omega_b * DT / SUB + 1e-9 * rng.standard_normal((n, SUB, 3))
    dv = f_b * DT / SUB + 1e-7 * rng.standard_normal((n, SUB, 3))
    kernels = np.array([DT ** r / np.prod(np.arange(1, r + 1)) for r in range(1, 5)])
    th_r = dth.sum(1)[:, None, :] * (kernels / DT)[None, :, None]
    dv_r = dv.sum(1)[:, None, :] * (kernels / DT)[None, :, None]
    state = InsState(lat, 0.3, h, np.zeros(3), mat_to_quat(mat_nb))
    return state, dth, dv, th_r, dv_r


def plain_loop(state: InsState, dth, dv, dt: float, earth=WGS84):
    """Reference: a direct per-step numpy implementation (Euler, first-order terms)."""
    lat, lon, h = state.lat, state.lon, state.h
    v = state.velocity_n.copy()
    q = state.quat_nb.copy()
    for k in range(len(dth)):
        theta, dvel = dth[k].sum(0), dv[k].sum(0)
        r_n, r_e = earth.radii(lat)
        w_ie = earth.earth_rate_n(lat)
        w_en = earth.transport_rate_n(lat, h, v)
        g = earth.gravity_n(lat, h)
        v_new = v + quat_to_mat(q) @ (dvel + 0.5 * np.cross(theta, dvel)) + (g - np.cross(2 * w_ie + w_en, v)) * dt
        q = quat_multiply(quat_multiply(quat_from_rotvec(-(w_ie + w_en) * dt), q), quat_from_rotvec(theta))
        lat += 0.5 * (v[1] + v_new[1]) * dt / (r_n + h)
        lon += 0.5 * (v[0] + v_new[0]) * dt / ((r_e + h) * np.cos(lat))
        h += 0.5 * (v[2] + v_new[2]) * dt
        v = v_new
    return lat, lon, h, v, q


def _rate(seconds: float, steps: int) -> str:
    return f"{steps / seconds:10.0f} steps/s  {SUB * steps / seconds:10.0f} samples/s"


def main(duration_s: float = 300.0) -> None:
    n = int(round(duration_s / DT))
    state, dth, dv, th_r, dv_r = _data(n)
    print(f"navsim INS throughput, {n} steps of {DT} s, {SUB} IMU samples per step, WGS-84")
    integrate(state, dth[:100], dv[:100], dt=DT)  # warm-up

    t0 = time.perf_counter()
    integrate(state, dth, dv, dt=DT, coning="two-sample", sculling="two-sample", position="trapezoid")
    t1 = time.perf_counter()
    print(f"  integrate, sub-samples (two-sample, trapezoid)    {_rate(t1 - t0, n)}")

    t0 = time.perf_counter()
    integrate(state, None, None, th_r, dv_r, dt=DT)
    t1 = time.perf_counter()
    print(f"  integrate, multiple integrals (invariant, exact)  {_rate(t1 - t0, n)}")

    m = min(n, 5000)
    t0 = time.perf_counter()
    s = state
    for k in range(m):
        s = ins_step(s, dth[k], dv[k], dt=DT, coning="two-sample", sculling="two-sample", position="trapezoid")
    t1 = time.perf_counter()
    print(f"  ins_step per step ({m} steps)                   {_rate(t1 - t0, m)}")

    t0 = time.perf_counter()
    plain_loop(state, dth[:m], dv[:m], DT)
    t1 = time.perf_counter()
    print(f"  plain numpy loop, reference ({m} steps)         {_rate(t1 - t0, m)}")
    print("  anchor: pyins numba strapdown, warm                       1.29 M samples/s")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 300.0)
