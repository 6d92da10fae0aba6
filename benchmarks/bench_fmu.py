"""FMU doStep cost under fmpy against its floor, in one process (issue 11's FMU goals).

For the bundled ``paper-2012`` scenario (0.01 s navigation step, 24 GNSS channels,
4 multiple-integral orders), seed 0, communication step = one navigation step, every row
in steady state (1100 warm-up steps: past the simulator's first 1000-step chunk):

Table 1, the goals of issue 11 (each row timed over its own loop):

* ``empty``: an empty pythonfmu FMU (FMI 2, one output, ``do_step`` returns at once) and
  an empty pythonfmu3 FMU (FMI 3, the independent variable and one output), ``doStep``
  back to back: the floor of any pythonfmu / pythonfmu3 doStep under fmpy; each FMI
  version's rows are read against the empty FMU of the same version;
* ``core``: the core's ``Simulator.step()``;
* ``plant``: navsim's plant FMU doStep, FMI 2 and FMI 3 (the C guard of
  :mod:`navsim.fmu.guard` in front of the shim); goal <= 2 x (empty + core);
* ``lc-ekf batch``: CPU time per step of lc-ekf's ``step_batch`` in ``run_episode``;
  ``estimator``: the estimator FMU's doStep (lc-ekf) in a plant-first master loop (plant
  doStep, the ~300 values moved by ``Connection.push``, estimator doStep; only the
  estimator's doStep timed), FMI 2 and FMI 3; goal <= 2 x (empty + lc-ekf batch);
* ``lc-ekf step`` / ``step_row``: lc-ekf's ``step`` (``run_episode(use_batch=False)``)
  and its ``step_row`` fast path (the path the estimator FMU calls) called back to back
  on the episode's measurements.

Table 2, the same master loop with its own references (one loop per FMI version): each
communication step the plant steps and its outputs go to the estimator FMU and, the same
values, to a *null* FMU (pythonfmu / pythonfmu3, as many input values per type as the
estimator FMU, ``do_step`` returns at once, the values taken with one slice assignment);
then three calls, each timed alone, in an order that rotates every GNSS period (the one of
the three that runs first after the transfer pays the cold caches, most at an epoch): the
estimator FMU's doStep, the null FMU's doStep, and the ``step_row`` of a twin lc-ekf on the
same measurement (the same numbers: ``tests/fmu/test_cosim.py``). Medians over the steps
without a GNSS epoch and those with one, and means; the FMU layer's own cost is the
estimator doStep less the null doStep and the twin step_row of the same steps.

Why table 1's estimator rows sit far above empty + step_row: the empty doStep and the
step_row there run back to back on hot caches, the estimator FMU's doStep after the plant
step and the transfer; table 2 gives both references in the FMU's own loop.

``benchmarks/bench_stepwise.py``'s FMU table measures the same ratio differently: wall
time (``perf_counter``), no warm-up (the first steps, with the estimator's reset and the
compile caches' first calls, are in), FMI 2 only, and the lc-ekf batch cost of its own
table (the 1000-s paper episode with its 300-s GNSS outage, where lc-ekf's batch cost per
step is lower); so its ratio is higher than this one's for the same FMUs.

Times are CPU time of this process per step (``time.process_time``; the FMUs run in
this process), medians over interleaved rounds, in microseconds; only the same-process
ratios are meaningful.

Run: ``python benchmarks/bench_fmu.py [steps] [rounds]`` (default 1000 3).
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
from _empty_fmu import build_empty_fmu

NULL_SLAVE = textwrap.dedent("""\
    import numpy as np
    from {pkg} import {base}, {causality}, {variability}, {real}, {int_}, Boolean
    {imports}
    COUNTS = {counts!r}  # input values per type


    class NullBench{fmi}({base}):
        \"\"\"The estimator FMU's input value count, nothing computed: a pythonfmu doStep's floor.\"\"\"

        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            {time}
            self._first, self._values = {{}}, {{}}
            for type_, cls in (("real", {real}), ("int", {int_}), ("bool", Boolean)):
                dtype = {{"real": float, "int": int}}.get(type_, bool)
                values = self._values[type_] = np.zeros(COUNTS.get(type_, 0), dtype=dtype)
                for i in range(len(values)):
                    var = cls(f"{{type_}}{{i}}", causality={causality}.input,
                              variability=None if type_ == "real" else {variability}.discrete,
                              getter=lambda v=values, i=i: v[i].item(), setter=lambda x: None)
                    self.register_variable(var)
                    self._first.setdefault(type_, var.value_reference)

        def _put(self, type_, vrs, values):  # one slice assignment, as navsim's value store makes it
            a = vrs[0] - self._first[type_]
            self._values[type_][a:a + len(values)] = values

        def do_step(self, current_time, step_size):
            return {ok}

        def {set_real}(self, vrs, values):
            self._put("real", vrs, values)

        def {set_int}(self, vrs, values):
            self._put("int", vrs, values)

        def set_boolean(self, vrs, values):
            self._put("bool", vrs, values)
    """)
_FMI3_TIME = ('self.time = 0.0\n        self.register_variable(Float64("time", causality=Fmi3Causality.independent, '
              'variability=Fmi3Variability.continuous))')
_NULL_NAMES = {
    2: dict(pkg="pythonfmu", base="Fmi2Slave", causality="Fmi2Causality", variability="Fmi2Variability", real="Real",
            int_="Integer", imports="", time="", ok="True", set_real="set_real", set_int="set_integer"),
    3: dict(pkg="pythonfmu3", base="Fmi3Slave", causality="Fmi3Causality", variability="Fmi3Variability", real="Float64",
            int_="Int32", imports="from pythonfmu3.fmi3slave import Fmi3StepResult\n", time=_FMI3_TIME,
            ok="Fmi3StepResult()", set_real="set_float64", set_int="set_int32"),
}


def build_null_fmu(folder: str | Path, fmi: int, counts: dict[str, int]) -> Path:
    """Build the null FMU (FMI 2 with pythonfmu, FMI 3 with pythonfmu3) with ``counts``
    input values per type (``real``/``int``/``bool``, scalar variables) in ``folder``."""
    if fmi == 2:
        from pythonfmu.builder import FmuBuilder
    else:
        from pythonfmu3.builder import FmuBuilder
    out = Path(folder) / f"null{fmi}"
    out.mkdir(exist_ok=True)
    script = out / f"null_bench{fmi}.py"  # one module name per FMI version: the shims import it by name
    script.write_text(NULL_SLAVE.format(fmi=fmi, counts=counts, **_NULL_NAMES[fmi]))
    return Path(FmuBuilder.build_FMU(script, dest=out))


def _feed(conn, null, null_vrs: dict[str, list[int]]) -> None:
    """The plant's outputs to the estimator FMU (``conn``) and the same values to the null FMU."""
    raw = conn.push()
    for t, vrs in null_vrs.items():
        null.set_raw(t, vrs, raw[t])


def main(steps: int = 1000, rounds: int = 3) -> None:
    from navsim.fmu.build import build_fmu
    from navsim.fmu.master import Connection, FmuInstance

    from navsim import estimators
    from navsim.episode import make_context, measurement_batch, run_episode
    from navsim.scenario import load_scenario
    from navsim.simulator import Simulator

    warm = 1100  # past the simulator's first 1000-step chunk
    scenario = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": (warm + steps) * 0.01 + 1.0}})
    dt = scenario.timing.nav_period_s
    period = scenario.timing.steps_per_epoch  # the rotation of table 2's order
    clock = time.process_time  # CPU time: the same measure as run_episode's step_time_s
    times: dict[str, list[float]] = {}

    def add(key: str, value: float) -> None:
        times.setdefault(key, []).append(value)

    with tempfile.TemporaryDirectory() as tmp:
        empties = {fmi: build_empty_fmu(tmp, fmi) for fmi in (2, 3)}
        plants = {fmi: build_fmu(scenario, "plant", fmi, Path(tmp) / f"plant{fmi}.fmu") for fmi in (2, 3)}
        est_paths = {fmi: build_fmu(scenario, "estimator", fmi, Path(tmp) / f"est{fmi}.fmu", estimator="lc-ekf")
                     for fmi in (2, 3)}
        nulls: dict[int, Path] = {}
        sim = Simulator(scenario)
        start = sim.reset(0)
        context = make_context(sim)
        prn = np.asarray(sim.constellation.prn)
        meas = [b.measurement(i) for b in (measurement_batch(c, prn, dt) for c in sim.chunks(10_000))
                for i in range(len(b))]
        epoch = np.array([m.gnss is not None for m in meas[warm:warm + steps]])  # the timed steps with a GNSS epoch
        for _ in range(rounds):
            for fmi, empty in empties.items():
                with FmuInstance(empty, "empty") as inst:
                    inst.initialize()
                    for k in range(warm):
                        inst.do_step(k * dt, dt)
                    t0 = clock()
                    for k in range(warm, warm + steps):
                        inst.do_step(k * dt, dt)
                    add(f"empty{fmi}", (clock() - t0) / steps)
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
            for fmi, est_path in est_paths.items():  # table 1: the estimator FMU alone in the master loop
                plant, est = FmuInstance(plants[fmi], "plant"), FmuInstance(est_path, "estimator")
                try:
                    plant.initialize({"seed": 0})
                    est.initialize({})
                    push = Connection(plant, est).push
                    push()
                    spent = 0.0
                    for k in range(warm + steps):
                        plant.do_step(k * dt, dt)
                        push()
                        t0 = clock()
                        est.do_step(k * dt, dt)
                        if k >= warm:
                            spent += clock() - t0
                    add(f"estimator{fmi}", spent / steps)
                finally:
                    plant.free()
                    est.free()
            for fmi, est_path in est_paths.items():  # table 2: estimator, null FMU and twin step_row in one loop
                plant, est = FmuInstance(plants[fmi], "plant"), FmuInstance(est_path, "estimator")
                conn = Connection(plant, est)
                counts = {t: n for t, (_, n) in conn.dst.groups.items()}
                if fmi not in nulls:
                    nulls[fmi] = build_null_fmu(tmp, fmi, counts)
                null = FmuInstance(nulls[fmi], "null")
                try:
                    plant.initialize({"seed": 0})
                    est.initialize({})
                    null.initialize()
                    null_vrs = {t: [v.valueReference for v in null.md.modelVariables if v.name.startswith(t)
                                    and v.name[len(t):].isdigit()] for t in counts}
                    _feed(conn, null, null_vrs)
                    twin = estimators.make("lc-ekf")
                    twin.reset(context, start.prior)
                    twin_row = twin.step_row
                    each: dict[str, list[float]] = {"est": [], "null": [], "twin": []}
                    for k in range(warm + steps):
                        plant.do_step(k * dt, dt)
                        _feed(conn, null, null_vrs)
                        turn = (k // period) % 3
                        for job in ("est", "null", "twin")[turn:] + ("est", "null", "twin")[:turn]:
                            t0 = clock()
                            if job == "est":
                                est.do_step(k * dt, dt)
                            elif job == "null":
                                null.do_step(k * dt, dt)
                            else:
                                twin_row(meas[k])
                            spent = clock() - t0
                            if k >= warm:
                                each[job].append(spent)
                    for job, values in each.items():
                        arr = np.asarray(values)
                        add(f"{job}{fmi}_quiet", float(np.median(arr[~epoch])))
                        add(f"{job}{fmi}_epoch", float(np.median(arr[epoch])))
                        add(f"{job}{fmi}_mean", float(arr.mean()))
                    layer = np.asarray(each["est"]) - np.asarray(each["null"]) - np.asarray(each["twin"])
                    add(f"layer{fmi}_quiet", float(np.median(layer[~epoch])))
                    add(f"layer{fmi}_epoch", float(np.median(layer[epoch])))
                    add(f"layer{fmi}_mean", float(layer.mean()))
                finally:
                    plant.free()
                    est.free()
                    null.free()
    med = {k: statistics.median(v) for k, v in times.items()}
    floor_plant = {fmi: med[f"empty{fmi}"] + med["core"] for fmi in (2, 3)}
    floor_est = {fmi: med[f"empty{fmi}"] + med["lc_batch"] for fmi in (2, 3)}
    us = 1e6
    print(f"paper-2012, {steps} communication steps of {dt:g} s after {warm} warm-up steps, under fmpy; "
          f"CPU time of this process per step, median of {rounds} interleaved round(s)")
    print()
    print("| case | us per step | floor | ratio | goal |")
    print("|---|---:|---|---:|---:|")
    print(f"| empty pythonfmu FMU doStep (FMI 2) | {med['empty2'] * us:.1f} | | | |")
    print(f"| empty pythonfmu3 FMU doStep (FMI 3) | {med['empty3'] * us:.1f} | | | |")
    print(f"| core Simulator.step() | {med['core'] * us:.1f} | | | |")
    for fmi in (2, 3):
        m = med[f"plant{fmi}"]
        print(f"| plant FMU doStep, FMI {fmi} | {m * us:.1f} | empty (FMI {fmi}) + core = "
              f"{floor_plant[fmi] * us:.1f} us | {m / floor_plant[fmi]:.2f} | <= 2 |")
    print(f"| lc-ekf step_batch per step (run_episode) | {med['lc_batch'] * us:.1f} | | | |")
    for fmi in (2, 3):
        m = med[f"estimator{fmi}"]
        print(f"| estimator FMU doStep (lc-ekf, FMI {fmi}) | {m * us:.1f} | empty (FMI {fmi}) + lc-ekf batch = "
              f"{floor_est[fmi] * us:.1f} us | {m / floor_est[fmi]:.2f} | <= 2 |")
    print(f"| lc-ekf step() per step | {med['lc_step'] * us:.1f} | | | |")
    print(f"| lc-ekf step_row per step, back to back | {med['lc_row'] * us:.1f} | | | |")
    print()
    print(f"The estimator FMU's own master loop: after the plant's doStep and the transfer, the estimator FMU's "
          f"doStep, a null FMU's doStep (the estimator FMU's input value count, nothing done) and a twin lc-ekf's "
          f"step_row, each timed alone, in an order rotating every {period} steps; medians over the "
          f"{int((~epoch).sum())} steps without a GNSS epoch and the {int(epoch.sum())} with one, and means")
    print()
    print("| FMI | case | without an epoch, us | with an epoch, us | mean, us |")
    print("|---|---|---:|---:|---:|")
    labels = {"est": "estimator FMU doStep (lc-ekf)", "null": "null FMU doStep (same value count)",
              "twin": "twin lc-ekf step_row", "layer": "FMU layer: estimator - null - step_row"}
    for fmi in (2, 3):
        for job, label in labels.items():
            print(f"| {fmi} | {label} | {med[f'{job}{fmi}_quiet'] * us:.1f} | {med[f'{job}{fmi}_epoch'] * us:.1f} "
                  f"| {med[f'{job}{fmi}_mean'] * us:.1f} |")
    for fmi in (2, 3):
        ref = med[f"null{fmi}_mean"] + med[f"twin{fmi}_mean"]
        print(f"| {fmi} | estimator doStep / (null + step_row), means | | | {med[f'est{fmi}_mean'] / ref:.2f} |")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
