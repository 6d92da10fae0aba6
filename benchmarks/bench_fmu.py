"""Plant FMU steps per second under fmpy, beside the core stepped directly, in one process.

For the bundled ``paper-2012`` scenario (0.01 s navigation step, 24 GNSS channels,
4 multiple-integral orders) over ``steps`` navigation steps, seed 0:

* core ``Simulator.step()`` (buffered single steps, what the FMU runtime calls) and
  ``Simulator.advance(steps)`` (one vectorised chunk), after a warm-up episode;
* the plant FMU under fmpy, FMI 2 (pythonfmu) and FMI 3 (pythonfmu3), communication
  step = one navigation step: ``doStep`` alone, and ``doStep`` plus reading every
  output (what a master connecting all signals does).

The machine is shared: only same-process ratios are meaningful.

Run: ``python benchmarks/bench_fmu.py [steps]`` (default 2000).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path


def main(steps: int = 2000) -> None:
    from navsim.fmu.build import build_fmu
    from navsim.fmu.master import FmuInstance, _Plan
    from navsim.scenario import load_scenario
    from navsim.simulator import Simulator

    scenario = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": steps * 0.01 + 1.0}})
    rows = []
    sim = Simulator(scenario)
    sim.reset(0)
    sim.advance(steps)  # warm-up (first-use costs of the truth generator)
    sim.reset(0)
    t0 = time.perf_counter()
    for _ in range(steps):
        sim.step()
    rows.append(("core Simulator.step()", steps / (time.perf_counter() - t0)))
    sim.reset(0)
    t0 = time.perf_counter()
    sim.advance(steps)
    rows.append(("core Simulator.advance(n), one chunk", steps / (time.perf_counter() - t0)))
    with tempfile.TemporaryDirectory() as tmp:
        for fmi in (2, 3):
            path = build_fmu(scenario, "plant", fmi, Path(tmp) / f"plant{fmi}.fmu")
            for read_all in (False, True):
                with FmuInstance(path, "plant") as inst:
                    inst.initialize({"seed": 0})
                    outputs = [n for n, v in inst.variables.items() if v.causality == "output"]
                    plan = _Plan(inst, outputs)
                    inst.do_step(0.0, 0.01)  # warm-up
                    t0 = time.perf_counter()
                    for k in range(1, steps):
                        inst.do_step(k * 0.01, 0.01)
                        if read_all:
                            plan.unpack(plan.fetch())
                    rate = (steps - 1) / (time.perf_counter() - t0)
                what = f"doStep + get all {len(outputs)} outputs" if read_all else "doStep only"
                rows.append((f"plant FMU, FMI {fmi}, fmpy: {what}", rate))
    core = rows[0][1]
    print(f"paper-2012, {steps} navigation steps of 0.01 s")
    print(f"{'case':58s} {'steps/s':>10s} {'vs core step()':>15s}")
    for name, rate in rows:
        print(f"{name:58s} {rate:10.0f} {rate / core:15.2f}")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
