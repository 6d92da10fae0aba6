"""CPU cost of the estimators: paper-ekf against lc-ekf, and every registered estimator.

1. paper-ekf against lc-ekf (issue 13's first row): the 1000-s paper-2012 episode (100 Hz
   navigation, 1 Hz GNSS, the 400-700 s outage), paper-ekf at the paper's 0.01-s covariance
   step with each engine (``engine="compiled"``: numba, ``engine="python"``: the reference)
   and lc-ekf, on the same pre-generated measurements, through ``step_batch`` (the way
   :func:`navsim.episode.run_episode` drives them). CPU time (``time.process_time``), the
   estimators interleaved in each of ``repeats`` rounds; medians and the ratios to lc-ekf
   of the same round. The compiled engine's one-off compilation (or loading from numba's
   disk cache) is timed separately, before the rounds. The largest difference between the
   two engines' solutions is printed too (same numbers to rounding).
2. The step-wise path: microseconds per navigation step through ``step`` (one
   ``Measurement`` at a time, as EstimatorAgent and the estimator FMU call it) against
   ``step_batch`` on the same ``step_seconds``-long episode (issue 11's goal: step /
   batch <= 1.5), interleaved rounds.
3. Every registered estimator: batch microseconds per step, the episode time, and the
   episode in units of a reference timed in the same process: filterpy's
   ``ExtendedKalmanFilter`` predict + update on a 15-state / 6-measurement problem (the
   loosely coupled filter's size), which removes most of the machine's speed and load.

Simulation time is excluded (measurements are generated first).

Run: ``python benchmarks/bench_estimators.py [duration_s] [step_seconds] [repeats]``
(defaults 1000 s, 20 s, 3).
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np

from navsim.episode import make_context, measurement_batch
from navsim.estimators import available, make
from navsim.estimators.paper_ekf import kernel as paper_ekf_kernel
from navsim.estimators.paper_ekf import PaperEkf
from navsim.scenario import load_scenario
from navsim.simulator import Simulator


def _filterpy_anchor(repeats: int = 2000) -> float:
    """Microseconds per predict+update of filterpy's EKF, 15 states, 6 measurements."""
    from filterpy.kalman import ExtendedKalmanFilter

    rng = np.random.default_rng(0)
    ekf = ExtendedKalmanFilter(dim_x=15, dim_z=6)
    ekf.F = np.eye(15) + 0.01 * rng.standard_normal((15, 15))
    ekf.Q = np.eye(15) * 1e-4
    ekf.R = np.eye(6)
    ekf.P = np.eye(15)
    H = np.zeros((6, 15))
    H[:, :6] = np.eye(6)

    def hjac(x):
        return H

    def hx(x):
        return H @ x

    z = np.zeros(6)
    t0 = time.process_time()
    for _ in range(repeats):
        ekf.predict()
        ekf.update(z, hjac, hx)
    return (time.process_time() - t0) / repeats * 1e6


def _batch_run(est, ctx, prior, batches):
    est.reset(ctx, prior)
    t0 = time.process_time()
    sol = [est.step_batch(b).solution for b in batches]
    return time.process_time() - t0, np.concatenate(sol)


def _step_run(est, ctx, prior, meas):
    est.reset(ctx, prior)
    step = est.step
    t0 = time.process_time()
    for m in meas:
        step(m)
    return (time.process_time() - t0) / len(meas) * 1e6


def main(duration: float = 1000.0, step_seconds: float = 20.0, repeats: int = 3) -> None:
    repeats = int(repeats)
    sc = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": duration}})
    sim = Simulator(sc)
    start = sim.reset(0)
    ctx = make_context(sim)
    prn = np.asarray(sim.constellation.prn)
    dt = sc.timing.nav_period_s
    t0 = time.process_time()
    batches = [measurement_batch(chunk, prn, dt) for chunk in sim.chunks(10_000)]
    sim_time = time.process_time() - t0
    n = sum(len(b) for b in batches)
    print(f"paper-2012 scenario, {duration:.0f} s episode: {n} navigation steps at {1 / dt:.0f} Hz, GNSS at "
          f"{1 / sc.timing.gnss_period_s:.0f} Hz (simulation {sim_time:.2f} s CPU, not counted)\n")

    # ---- 1. paper-ekf against lc-ekf
    compiled = paper_ekf_kernel.available()
    engines = ["compiled", "python"] if compiled else ["python"]
    print("### paper-ekf against lc-ekf\n")
    if compiled:
        sim_w = Simulator(sc)
        start_w = sim_w.reset(0)
        small = measurement_batch(sim_w.advance(10), prn, dt)
        warm = PaperEkf(engine="compiled")
        t0 = time.process_time()
        warm.reset(make_context(sim_w), start_w.prior)
        warm.step_batch(small)
        first = time.process_time() - t0
        print(f"compiled engine, first call in this process (numba compilation, or loading its disk cache, "
              f"plus one batch): {first:.2f} s CPU, not counted below\n")
    else:
        print("numba is not installed: the compiled engine is not measured (pip install 'navsim-track[fast]')\n")
    times: dict[str, list[float]] = {"lc-ekf": []}
    times.update({f"paper-ekf ({e})": [] for e in engines})
    sols = {}
    for _ in range(repeats):
        times["lc-ekf"].append(_batch_run(make("lc-ekf"), ctx, start.prior, batches)[0])
        for e in engines:
            cpu, sols[e] = _batch_run(PaperEkf(engine=e), ctx, start.prior, batches)
            times[f"paper-ekf ({e})"].append(cpu)
    print(f"CPU time of the whole episode through step_batch, {repeats} interleaved rounds; covariance step "
          f"{dt} s (the paper's)\n")
    print("| estimator | median s | min s | max s | us per step | / lc-ekf (median of per-round ratios) |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, ts in times.items():
        ratio = statistics.median(t / r for t, r in zip(ts, times["lc-ekf"]))
        print(f"| {name} | {statistics.median(ts):.2f} | {min(ts):.2f} | {max(ts):.2f} | "
              f"{statistics.median(ts) / n * 1e6:.1f} | {ratio:.2f} |")
    print("\nGoal (issue 13): paper-ekf at most lc-ekf's CPU in the same run (ratio <= 1).")
    if compiled:
        a, b = sols["python"], sols["compiled"]
        ok = np.isfinite(a[:, 0])
        scale = np.abs(a[ok]).max(axis=0)
        rel = (np.abs(a[ok] - b[ok]) / scale).max(axis=0)
        print(f"Largest difference compiled - python over the episode, relative to each output's scale: "
              f"position {rel[:3].max():.1e}, velocity {rel[3:6].max():.1e}, attitude {rel[6:9].max():.1e}.")

    # ---- 2. the step-wise path
    sc_s = sc.with_overrides({"timing": {"duration_s": step_seconds}})
    sim_s = Simulator(sc_s)
    start_s = sim_s.reset(0)
    ctx_s = make_context(sim_s)
    batches_s = [measurement_batch(chunk, prn, dt) for chunk in sim_s.chunks(10_000)]
    n_s = sum(len(b) for b in batches_s)
    meas_s = [b.measurement(i) for b in batches_s for i in range(len(b))]  # built once, outside the timing
    print("\n### Step-wise path (`step`, one measurement at a time) against `step_batch`\n")
    print(f"The first {step_seconds:.0f} s of the episode ({n_s} steps, GNSS epochs and the start-up included in both); "
          f"CPU time per navigation step, median of {repeats} interleaved rounds\n")
    print("| estimator | batch us/step | step us/step | step / batch |")
    print("|---|---:|---:|---:|")
    step_rows = [("lc-ekf", lambda: make("lc-ekf"))] + [(f"paper-ekf ({e})", lambda e=e: PaperEkf(engine=e))
                                                       for e in engines]
    res = {name: ([], []) for name, _ in step_rows}
    for _ in range(repeats):
        for name, factory in step_rows:
            res[name][0].append(_batch_run(factory(), ctx_s, start_s.prior, batches_s)[0] / n_s * 1e6)
            res[name][1].append(_step_run(factory(), ctx_s, start_s.prior, meas_s))
    for name, (bt, st) in res.items():
        ratio = statistics.median(s_ / b_ for s_, b_ in zip(st, bt))
        print(f"| {name} | {statistics.median(bt):.1f} | {statistics.median(st):.1f} | {ratio:.2f} |")
    print("\nGoal (issue 11): step / batch <= 1.5. The `Measurement` objects are built before the timing "
          "(`MeasurementBatch.measurement(i)`, the caller's cost: EstimatorAgent decodes them from the observation, "
          "`bench_stepwise.py` times that path).")

    # ---- 3. every estimator
    anchor = _filterpy_anchor()
    print("\n### Every registered estimator (batch)\n")
    print("| estimator | batch us/step | episode s | episode / anchor |")
    print("|---|---:|---:|---:|")
    for name in available():
        try:
            est = make(name)
        except Exception as exc:  # an estimator that cannot be built is reported, not fatal
            print(f"| {name} | unavailable ({exc}) | | |")
            continue
        if not hasattr(est, "step_batch"):
            print(f"| {name} | no batch path | | |")
            continue
        episode = _batch_run(est, ctx, start.prior, batches)[0]
        print(f"| {name} | {episode / n * 1e6:.1f} | {episode:.2f} | {episode / anchor * 1e3:.1f} k |")
    print(f"\nAnchor: filterpy ExtendedKalmanFilter predict + update (15 states, 6 measurements) = {anchor:.1f} us "
          "in this process; 'episode / anchor' is the episode's CPU time in such steps, a machine-independent "
          "figure. paper-ekf here uses the default engine (compiled when numba is installed).")


if __name__ == "__main__":
    main(*[float(a) for a in sys.argv[1:4]])
