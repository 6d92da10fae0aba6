"""FMU doStep cost under fmpy against its floor, in one process (issue 11's FMU goals).

For the bundled ``paper-2012`` scenario (0.01 s navigation step, 24 GNSS channels,
4 multiple-integral orders), seed 0, communication step = one navigation step:

* ``empty``: an empty pythonfmu FMU (FMI 2, one output, ``do_step`` returns at once):
  the floor of any pythonfmu doStep under fmpy;
* ``core``: the core's ``Simulator.step()`` on the same scenario, in steady state (the
  first chunk generated before timing, as for the FMUs);
* ``plant``: navsim's plant FMU doStep, FMI 2 and FMI 3 (the C guard of
  :mod:`navsim.fmu.guard` in front of the shim), in steady state; goal <= 2 x
  (empty + core);
* ``lc-ekf batch``: CPU time per step of lc-ekf's ``step_batch`` in ``run_episode``;
  ``estimator``: the estimator FMU's doStep (FMI 2, lc-ekf) fed with the plant's outputs
  (only its doStep timed); goal <= 2 x (empty + lc-ekf batch).

* ``estimator`` FMI 3: the same under FMI 3 (pythonfmu3).
* ``lc-ekf step`` / ``lc-ekf step_row``: CPU time per step of lc-ekf's ``step``
  (``run_episode(use_batch=False)``) and of its ``step_row`` fast path on the episode's
  measurements (the path the estimator FMU calls); the estimator FMU's doStep against
  empty + ``step_row`` shows what the FMU layer (FMI calls, checks, value store) adds.
* a second table splits the estimator FMU's doStep and lc-ekf's ``step_row`` (each step
  timed alone, medians) into the steps without a GNSS epoch and those with one, and
  gives their difference less the empty doStep: the FMU layer's own cost per step.

Rows are timed in interleaved rounds; the medians are printed, in microseconds of CPU
time of this process per step (``time.process_time``; the FMUs run in this process), so
that a shared machine's descheduling does not count and every row is the same measure as
the estimators' per-step CPU times. Only the same-process ratios are meaningful.

Run: ``python benchmarks/bench_fmu.py [steps] [rounds]`` (default 1000 3).
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _empty_fmu import build_empty_fmu



def main(steps: int = 1000, rounds: int = 3) -> None:
    from navsim import estimators
    from navsim.episode import make_context, measurement_batch, run_episode
    from navsim.fmu.build import build_fmu
    from navsim.fmu.master import Connection, FmuInstance
    from navsim.scenario import load_scenario
    from navsim.simulator import Simulator

    warm = 1100  # past the simulator's first 1000-step chunk
    scenario = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": (warm + steps) * 0.01 + 1.0}})
    dt = scenario.timing.nav_period_s
    clock = time.process_time  # CPU time: the same measure as run_episode's step_time_s
    times: dict[str, list[float]] = {}

    def add(key, value):
        times.setdefault(key, []).append(value)

    with tempfile.TemporaryDirectory() as tmp:
        empty = build_empty_fmu(tmp)
        plants = {fmi: build_fmu(scenario, "plant", fmi, Path(tmp) / f"plant{fmi}.fmu") for fmi in (2, 3)}
        est_paths = {fmi: build_fmu(scenario, "estimator", fmi, Path(tmp) / f"est{fmi}.fmu", estimator="lc-ekf")
                     for fmi in (2, 3)}
        sim = Simulator(scenario)
        start = sim.reset(0)
        context = make_context(sim)
        prn = np.asarray(sim.constellation.prn)
        meas = [b.measurement(i) for b in (measurement_batch(c, prn, dt) for c in sim.chunks(10_000))
                for i in range(len(b))]
        epoch = np.array([m.gnss is not None for m in meas[warm:warm + steps]])  # the timed steps with a GNSS epoch
        for _ in range(rounds):
            with FmuInstance(empty, "empty") as inst:
                inst.initialize()
                for k in range(warm):
                    inst.do_step(k * dt, dt)
                t0 = clock()
                for k in range(warm, warm + steps):
                    inst.do_step(k * dt, dt)
                add("empty", (clock() - t0) / steps)
            sim = Simulator(scenario)
            sim.reset(0)
            for _k in range(warm):
                sim.step()
            t0 = clock()
            for _k in range(steps):
                sim.step()
            add("core", (clock() - t0) / steps)
            for fmi, path in plants.items():
                with FmuInstance(path, "plant") as inst:
                    inst.initialize({"seed": 0})
                    for k in range(warm):
                        inst.do_step(k * dt, dt)
                    t0 = clock()
                    for k in range(warm, warm + steps):
                        inst.do_step(k * dt, dt)
                    add(f"plant{fmi}", (clock() - t0) / steps)
            record = run_episode(scenario, estimators.make("lc-ekf"), seed=0)
            add("lc_batch", float(record.step_time_s[warm:].mean()))
            record = run_episode(scenario, estimators.make("lc-ekf"), seed=0, use_batch=False)
            add("lc_step", float(record.step_time_s[warm:].mean()))
            lc = estimators.make("lc-ekf")
            lc.reset(context, start.prior)
            step_row = lc.step_row
            for m in meas[:warm]:
                step_row(m)
            t0 = clock()
            for m in meas[warm:warm + steps]:
                step_row(m)
            add("lc_row", (clock() - t0) / steps)
            lc.reset(context, start.prior)  # again, each step timed alone (as the FMU's doSteps are)
            for m in meas[:warm]:
                step_row(m)
            each = []
            for m in meas[warm:warm + steps]:
                t0 = clock()
                step_row(m)
                each.append(clock() - t0)
            add("lc_row_quiet", float(np.median(np.asarray(each)[~epoch])))
            add("lc_row_epoch", float(np.median(np.asarray(each)[epoch])))
            for fmi, est_path in est_paths.items():
                plant, est = FmuInstance(plants[fmi], "plant"), FmuInstance(est_path, "estimator")
                try:
                    plant.initialize({"seed": 0})
                    est.initialize({})
                    push = Connection(plant, est).push

                    push()
                    each = []
                    for k in range(warm + steps):
                        plant.do_step(k * dt, dt)
                        push()
                        t0 = clock()
                        est.do_step(k * dt, dt)
                        if k >= warm:
                            each.append(clock() - t0)
                    add(f"estimator{fmi}", sum(each) / steps)
                    add(f"estimator{fmi}_quiet", float(np.median(np.asarray(each)[~epoch])))
                    add(f"estimator{fmi}_epoch", float(np.median(np.asarray(each)[epoch])))
                finally:
                    plant.free()
                    est.free()
    med = {k: statistics.median(v) for k, v in times.items()}
    floor_plant = med["empty"] + med["core"]
    floor_est = med["empty"] + med["lc_batch"]
    us = 1e6
    print(f"paper-2012, {steps} communication steps of {dt:g} s after {warm} warm-up steps, under fmpy; "
          f"CPU time of this process per step, median of {rounds} interleaved round(s)")
    print()
    print("| case | us per step | floor | ratio | goal |")
    print("|---|---:|---|---:|---:|")
    print(f"| empty pythonfmu FMU doStep (FMI 2) | {med['empty'] * us:.1f} | | | |")
    print(f"| core Simulator.step() | {med['core'] * us:.1f} | | | |")
    for fmi in (2, 3):
        m = med[f"plant{fmi}"]
        print(f"| plant FMU doStep, FMI {fmi} | {m * us:.1f} | empty + core = {floor_plant * us:.1f} us "
              f"| {m / floor_plant:.2f} | <= 2 |")
    print(f"| lc-ekf step_batch per step (run_episode) | {med['lc_batch'] * us:.1f} | | | |")
    for fmi in (2, 3):
        m = med[f"estimator{fmi}"]
        print(f"| estimator FMU doStep (lc-ekf, FMI {fmi}) | {m * us:.1f} | empty + lc-ekf batch = "
              f"{floor_est * us:.1f} us | {m / floor_est:.2f} | <= 2 |")
    print(f"| lc-ekf step() per step | {med['lc_step'] * us:.1f} | | | |")
    floor_row = med["empty"] + med["lc_row"]
    print(f"| lc-ekf step_row per step (the estimator FMU's path) | {med['lc_row'] * us:.1f} | | | |")
    for fmi in (2, 3):
        m = med[f"estimator{fmi}"]
        print(f"| estimator FMU doStep (FMI {fmi}) against its own step_row path | {m * us:.1f} | empty + lc-ekf "
              f"step_row = {floor_row * us:.1f} us | {m / floor_row:.2f} | |")
    print()
    print(f"Each step timed alone, median over the {int((~epoch).sum())} timed steps without a GNSS epoch and the "
          f"{int(epoch.sum())} with one (the FMU's own cost: doStep against empty + step_row on the same steps)")
    print()
    print("| case | steps without an epoch, us | with an epoch, us |")
    print("|---|---:|---:|")
    print(f"| lc-ekf step_row | {med['lc_row_quiet'] * us:.1f} | {med['lc_row_epoch'] * us:.1f} |")
    for fmi in (2, 3):
        q, e = med[f"estimator{fmi}_quiet"], med[f"estimator{fmi}_epoch"]
        print(f"| estimator FMU doStep (FMI {fmi}) | {q * us:.1f} | {e * us:.1f} |")
    for fmi in (2, 3):
        q, e = med[f"estimator{fmi}_quiet"], med[f"estimator{fmi}_epoch"]
        print(f"| FMU doStep - (empty + step_row), FMI {fmi} | {(q - med['empty'] - med['lc_row_quiet']) * us:.1f} "
              f"| {(e - med['empty'] - med['lc_row_epoch']) * us:.1f} |")

if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
