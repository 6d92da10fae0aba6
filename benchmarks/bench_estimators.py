"""CPU cost of every registered estimator, per navigation step and per 1000-s episode.

For each estimator of :func:`navsim.estimators.available` (those whose modules exist when
this runs): microseconds per step through the batch fast path ``step_batch`` when the
estimator has one (the way :func:`navsim.episode.run_episode` drives it) and through
``step``, on the same pre-generated measurements of the paper-2012 scenario (100 Hz
navigation, 1 Hz GNSS, the 400-700 s outage); the batch time of the whole 1000-s episode.
Simulation time is excluded (measurements are generated first).

Reference anchor, timed in the same process: filterpy's ``ExtendedKalmanFilter``
predict + update on a 15-state / 6-measurement problem (the loosely coupled filter's size).
Research notes quote 32-47 us for a filterpy EKF step and ~7.8 k IMU samples/s for pyins'
loosely coupled filter on this kind of machine.

The last column divides the episode time by the anchor, which removes most of the
machine's speed (and of the load of a shared machine) from the comparison.

Run: ``python benchmarks/bench_estimators.py [duration_s] [step_seconds]`` (defaults
1000 s of episode for the batch path, 20 s for the per-step path, which is slower).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from navsim.episode import make_context, measurement_batch
from navsim.estimators import available, make
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


def main(duration: float = 1000.0, step_seconds: float = 20.0) -> None:
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
    n_step = min(n, round(step_seconds / dt))
    print(f"scenario {sc.name}: {duration:.0f} s, {n} steps at {1 / dt:.0f} Hz (simulation {sim_time:.2f} s CPU)")
    anchor = _filterpy_anchor()
    print(f"{'estimator':<12} {'batch us/step':>14} {'step us/step':>13} {'episode s':>10} {'episode / anchor':>17}")
    for name in available():
        try:
            est = make(name)
        except Exception as exc:  # an estimator that cannot be built is reported, not fatal
            print(f"{name:<12} unavailable ({exc})")
            continue
        batch_us = episode = float("nan")
        if hasattr(est, "step_batch"):
            est.reset(ctx, start.prior)
            t0 = time.process_time()
            for b in batches:
                est.step_batch(b)
            episode = time.process_time() - t0
            batch_us = episode / n * 1e6
        est = make(name)
        est.reset(ctx, start.prior)
        done = 0
        t0 = time.process_time()
        for b in batches:
            for i in range(len(b)):
                if done >= n_step:
                    break
                est.step(b.measurement(i))
                done += 1
        step_us = (time.process_time() - t0) / max(done, 1) * 1e6
        if not np.isfinite(episode):
            episode = step_us * n * 1e-6
        print(f"{name:<12} {batch_us:>14.1f} {step_us:>13.1f} {episode:>10.2f} {episode / anchor * 1e3:>16.1f}k")
    print(f"{'filterpy EKF':<12} {'':>14} {anchor:>13.1f} {'':>10}  (predict+update, 15 states, 6 meas.)")
    print("'episode / anchor': the episode's CPU time in filterpy EKF steps, a machine-independent")
    print("figure (the lc-ekf goal, 2 s with a 32-47 us anchor, is 43-62 k).")


if __name__ == "__main__":
    args = [float(a) for a in sys.argv[1:3]]
    main(*args)
