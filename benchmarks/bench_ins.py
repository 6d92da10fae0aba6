"""Batch strapdown throughput of navsim.strapdown.ins.integrate, beside pyins in one process.

Measured in one process, on the same data (a vehicle at rest on WGS-84, 100 Hz navigation
steps with m = 2 IMU sub-samples per step, so 1 step = 2 IMU samples):

* ``integrate`` with sub-sample increments (two-sample coning/sculling, trapezoid) and
  with multiple integrals (invariant algorithms, exact position form), each with
  ``method="sequential"`` (the per-step loop) and ``method="scan"`` (loop-free:
  navsim.strapdown.scan), whole call (body terms + integration) and integration alone
  (``integrate_body_terms`` on precomputed terms);
* pyins (PyPI python-ins) strapdown, warm (numba compiled): the public
  ``strapdown.Integrator.integrate`` (pandas in and out) and its numba kernel
  ``pyins._numba_integrate.integrate`` alone. pyins does one attitude/velocity update per
  increment, so its samples/s are its updates/s; it takes coning/sculling-corrected
  increments as input (``compute_increments_from_imu``, not timed here);
* ``ins_step`` called once per step and a plain per-step numpy loop (small counts).

The machine is shared: only same-process ratios are meaningful. Research notes quote pyins
at 1.29 M samples/s warm on a quiet machine of this kind.

* with ``--kernels`` first a table per navigation update, CPU time, interleaved repeats:
  ``method="compiled"`` (the sequential loop compiled by numba,
  :mod:`navsim.strapdown.compiled`), the same kernel called alone into output arrays
  written once before (``integrate_body_terms`` allocates its (n + 1)-row outputs per
  call, and their first touch costs page faults, which a loaded machine makes dear),
  ``method="scan"``, pyins's numba kernel and a plain compiled loop of quaternion/velocity
  updates written here (numba; no Earth model, no outputs stored), the issue's reference.

Run: ``python benchmarks/bench_ins.py [--kernels] [steps ...]`` (default 100000 1000000).
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from navsim.earth import WGS84
from navsim.rotations import mat_nb_from_hpr, mat_to_quat, quat_from_rotvec, quat_multiply, quat_to_mat
from navsim.strapdown.ins import InsState, ins_step

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


def _rate(seconds: float, steps: int, samples_per_step: int = SUB) -> str:
    return f"{steps / seconds / 1e3:9.0f} k steps/s {samples_per_step * steps / seconds / 1e3:9.0f} k samples/s"


def _best(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def pyins_runners(n: int):
    """pyins Integrator.integrate and its numba kernel on n increments (None if not installed)."""
    try:
        import pandas as pd
        from pyins import strapdown
        from pyins._numba_integrate import integrate as kernel
    except ImportError:
        return None
    rng = np.random.default_rng(0)
    pva = pd.Series({"lat": 40.0, "lon": 20.0, "alt": 100.0, "VN": 0.0, "VE": 0.0, "VD": 0.0,
                     "roll": 1.0, "pitch": 2.0, "heading": 30.0})
    theta = 1e-7 + 1e-9 * rng.standard_normal((n, 3))
    dv = np.array([0.001, 0.002, -0.098]) + 1e-7 * rng.standard_normal((n, 3))
    inc = pd.DataFrame({"dt": DT, "theta_x": theta[:, 0], "theta_y": theta[:, 1], "theta_z": theta[:, 2],
                        "dv_x": dv[:, 0], "dv_y": dv[:, 1], "dv_z": dv[:, 2]}, index=np.arange(1, n + 1) * DT)
    strapdown.Integrator(pva).integrate(inc.iloc[:100])  # warm-up: numba compilation

    def public():
        strapdown.Integrator(pva).integrate(inc)

    lla = np.zeros((n + 1, 3))
    lla[0] = [40.0, 20.0, 100.0]
    vel = np.zeros((n + 1, 3))
    mat = np.zeros((n + 1, 3, 3))
    mat[0] = np.eye(3)
    dts = np.full(n, DT)

    def raw():
        kernel(dts, lla, vel, mat, theta, dv, 0, True)

    return public, raw


def reference_loop():
    """A plain compiled loop of quaternion/velocity updates (numba), the issue's reference:
    per step the rotation vector's quaternion (sin, cos, sqrt), one quaternion product and
    normalisation, the body-to-navigation rotation of the velocity increment plus gravity,
    and a position sum. No Earth rate, transport rate, Coriolis or radii. None without numba."""
    try:
        import numba
    except ImportError:
        return None

    @numba.njit(cache=True)
    def loop(theta, dv, dt, q, v, p):
        q0, q1, q2, q3 = q[0], q[1], q[2], q[3]
        v0, v1, v2 = v[0], v[1], v[2]
        p0, p1, p2 = p[0], p[1], p[2]
        for k in range(theta.shape[0]):
            x, y, z = theta[k, 0], theta[k, 1], theta[k, 2]
            a = math.sqrt(x * x + y * y + z * z)
            c, s = math.cos(0.5 * a), (math.sin(0.5 * a) / a if a > 0.0 else 0.5)
            b0, b1, b2, b3 = c, s * x, s * y, s * z
            q0, q1, q2, q3 = (q0 * b0 - q1 * b1 - q2 * b2 - q3 * b3, q0 * b1 + q1 * b0 + q2 * b3 - q3 * b2,
                              q0 * b2 - q1 * b3 + q2 * b0 + q3 * b1, q0 * b3 + q1 * b2 - q2 * b1 + q3 * b0)
            n = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
            q0, q1, q2, q3 = q0 * n, q1 * n, q2 * n, q3 * n
            dx, dy, dz = dv[k, 0], dv[k, 1], dv[k, 2]
            v0 += (q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3) * dx + 2 * (q1 * q2 - q0 * q3) * dy \
                + 2 * (q1 * q3 + q0 * q2) * dz
            v1 += 2 * (q1 * q2 + q0 * q3) * dx + (q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3) * dy \
                + 2 * (q2 * q3 - q0 * q1) * dz
            v2 += 2 * (q1 * q3 - q0 * q2) * dx + 2 * (q2 * q3 + q0 * q1) * dy \
                + (q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) * dz - 9.81 * dt
            p0 += v0 * dt
            p1 += v1 * dt
            p2 += v2 * dt
        q[0], q[1], q[2], q[3] = q0, q1, q2, q3
        v[0], v[1], v[2] = v0, v1, v2
        p[0], p[1], p[2] = p0, p1, p2

    return loop


def _cpu(fn, repeat: int) -> float:
    """Median CPU seconds of ``repeat`` calls."""
    times = []
    for _ in range(repeat):
        c0 = time.process_time()
        fn()
        times.append(time.process_time() - c0)
    return sorted(times)[len(times) // 2]


def kernel_table(n: int = 200_000, repeat: int = 5) -> None:
    """Per navigation update, CPU time, interleaved: navsim's compiled loop, scan and
    sequential integrators on precomputed body terms, pyins's numba kernel, the reference loop."""
    from navsim.strapdown import compiled
    from navsim.strapdown.ins import body_terms, integrate_body_terms

    state, dth, dv, th_r, dv_r = _data(n)
    terms = body_terms(dth, dv, None, None, DT, coning="two-sample", sculling="two-sample", position="trapezoid")
    args = (terms.quat_body, terms.dv_body, terms.ds_body, terms.rule, DT, WGS84)
    runs = {}
    if compiled.available():
        integrate_body_terms(state, *(a[:10] if isinstance(a, np.ndarray) else a for a in args), method="compiled")
        runs["navsim compiled loop (numba), two-sample + trapezoid"] = lambda: integrate_body_terms(
            state, *args, method="compiled")
        # the same kernel call into output arrays allocated and written once before: without
        # the page faults of integrate_body_terms' fresh (n + 1)-row outputs (80 bytes a step)
        kern, consts = compiled.kernel(), compiled.earth_constants(WGS84)
        start = np.array([state.lat, state.lon, state.h, *state.compensation, *state.velocity_n, *state.quat_nb])
        outs = (np.empty((3, n + 1)), np.empty((n + 1, 3)), np.empty((n + 1, 4)), np.empty(3))
        qb, dvb, no_ds = np.ascontiguousarray(terms.quat_body), np.ascontiguousarray(terms.dv_body), np.zeros((1, 3))
        runs["navsim compiled loop, the kernel alone into reused outputs"] = lambda: kern(
            consts, start, qb, dvb, no_ds, False, True, DT, *outs)
    runs["navsim scan (NumPy), two-sample + trapezoid"] = lambda: integrate_body_terms(state, *args, method="scan")
    pyins = pyins_runners(n)
    if pyins is not None:
        runs["pyins numba kernel (one update per increment)"] = pyins[1]
    ref = reference_loop()
    if ref is not None:
        theta, dvel = dth.sum(1), dv.sum(1)
        q, v, p = np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), np.zeros(3)
        ref(theta[:10], dvel[:10], DT, q, v, p)
        runs["plain compiled quaternion/velocity loop (reference)"] = lambda: ref(theta, dvel, DT, q, v, p)
    times = {k: [] for k in runs}
    for _ in range(repeat):
        for k, fn in runs.items():
            times[k].append(_cpu(fn, 1))
    med = {k: sorted(v)[len(v) // 2] for k, v in times.items()}
    py_key = "pyins numba kernel (one update per increment)"
    ref_key = "plain compiled quaternion/velocity loop (reference)"
    print(f"\nPer navigation update, {n} updates, CPU time, median of {repeat} interleaved repeats "
          "(integration alone: body terms precomputed):\n")
    print("| integrator | M updates/CPU s | x pyins kernel | x reference loop |")
    print("|---|---:|---:|---:|")
    for k, t in med.items():
        xp = f"{med[py_key] / t:.2f}" if py_key in med else "-"
        xr = f"{med[ref_key] / t:.2f}" if ref_key in med else "-"
        print(f"| {k} | {n / t / 1e6:.2f} | {xp} | {xr} |")


def main(sizes=(100_000, 1_000_000)) -> None:
    from navsim.strapdown.ins import body_terms, integrate_body_terms

    print("navsim INS throughput beside pyins (same process), 100 Hz steps, 2 IMU samples per step, WGS-84")
    for n in sizes:
        repeat = 3 if n <= 200_000 else 1
        state, dth, dv, th_r, dv_r = _data(n)
        print(f"\n{n} steps ({n * DT:.0f} s)")
        runners = pyins_runners(n)
        if runners is None:
            print("  pyins not installed (pip install python-ins): no same-process reference")
        else:
            public, raw = runners
            t = _best(public, repeat)
            print(f"  pyins Integrator.integrate (pandas API)         {_rate(t, n, 1)}")
            t = _best(raw, repeat)
            print(f"  pyins numba kernel alone                        {_rate(t, n, 1)}")
        cases = (
            ("two-sample, trapezoid", (dth, dv, None, None),
             dict(coning="two-sample", sculling="two-sample", position="trapezoid")),
            ("invariant, exact (multiple integrals)", (None, None, th_r, dv_r), {}),
        )
        for label, arrays, methods in cases:
            terms = body_terms(*arrays, DT, **methods)
            args = (terms.quat_body, terms.dv_body, terms.ds_body, terms.rule, DT, WGS84)
            t_terms = _best(lambda: body_terms(*arrays, DT, **methods), repeat)
            for method in ("sequential", "scan", "compiled"):
                reps = 1 if method == "sequential" else repeat
                t_int = _best(lambda: integrate_body_terms(state, *args, method=method), reps)
                print(f"  navsim {method:10s} {label:38s} integration {_rate(t_int, n)}")
                print(f"  navsim {method:10s} {label:38s} + body terms {_rate(t_int + t_terms, n)}")

    m = 5000
    state, dth, dv, th_r, dv_r = _data(m)
    t0 = time.perf_counter()
    s = state
    for k in range(m):
        s = ins_step(s, dth[k], dv[k], dt=DT, coning="two-sample", sculling="two-sample", position="trapezoid")
    t1 = time.perf_counter()
    print(f"\n  ins_step per step ({m} steps)                   {_rate(t1 - t0, m)}")
    t0 = time.perf_counter()
    plain_loop(state, dth[:m], dv[:m], DT)
    t1 = time.perf_counter()
    print(f"  plain numpy loop, reference ({m} steps)         {_rate(t1 - t0, m)}")


if __name__ == "__main__":
    # python benchmarks/bench_ins.py [--kernels] [steps ...]: --kernels first prints the
    # per-update table (compiled loop, scan, pyins kernel, reference loop)
    if "--kernels" in sys.argv:
        kernel_table()
    sizes = tuple(int(float(x)) for x in sys.argv[1:] if x != "--kernels") or (100_000, 1_000_000)
    print("\n```")
    main(sizes)
    print("```")
