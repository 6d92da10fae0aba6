"""Step-wise cost of the estimators and the FMUs against their batch and core references.

Everything runs in one process on the bundled ``paper-2012`` scenario (0.01 s navigation
step, 1 Hz GNSS, 24 channels, 4 multiple-integral orders), seed 0:

1. **Estimators step by step.** For lc-ekf, tc-ekf, tc-ukf, along-track and paper-ekf, the
   CPU time per navigation step (``time.process_time``)

   * ``batch``: ``step_batch`` on the episode's chunks, the way
     :func:`navsim.episode.run_episode` drives it (the reference);
   * ``step``: ``Estimator.step`` on the same data as :class:`Measurement` objects;
   * ``agent``: ``EstimatorAgent.act`` on the observations the env produced for the same
     seed (decoding, the estimator's ``step_row`` fast path, or ``step`` for an estimator
     without it, and the action), the README's Gymnasium loop without the env's own cost.

   * ``agent floor``: ``EstimatorAgent.act`` driving :class:`ConstantRow`, whose ``step_row``
     returns one fixed row: the agent's own cost per step (decoding or the step view, the
     CPU clock read twice, the action with its extras), to read the other agent rows
     against.
   * ``agent, cpu_time=False``: the same two rows with ``EstimatorAgent(...,
     cpu_time=False)``, which reads no CPU clock and records no CPU time (the solutions
     are the same; the position column covers both agents).

   ``agent / batch`` is the figure the issue sets a goal for (<= 1.5); ``(batch + agent
   floor) / batch`` is that ratio for an estimator whose step costs exactly its batch
   share, the least a step path through the agent can reach. The last column is
   the largest position difference (m, local level) between the agent's solutions and
   the batch solutions over the episode: the step path must give the numbers of
   ``run_episode``. A second table splits the ``step`` and ``agent`` costs into the steps
   that end at a GNSS epoch and the others (each call timed alone).
2. **FMU doStep** under fmpy (FMI 2), communication step = one navigation step: an empty
   pythonfmu FMU (one output, ``do_step`` returns at once), the core's
   ``Simulator.step()``, the plant FMU, and the estimator FMU (lc-ekf) fed with the plant's
   outputs (only its ``doStep`` is timed). Goals: plant <= 2 x (empty + core step),
   estimator <= 2 x (empty + the estimator's batch cost per step). The FMU runtime's
   value layer is the array-backed store of :mod:`navsim.fmu.runtime`.
3. **The README's Gymnasium loop** (``gym.make`` + ``EstimatorAgent(estimators.make("lc-ekf"))``)
   over a whole episode against ``run_episode`` of the same scenario, estimator and seed
   (both include the simulation), wall time, with the two episode scores.

Timing: the rows of a table are timed in interleaved rounds and the median is printed;
the machine may be shared, so the ratios (same process, same rounds) are the figures to
trust.

Usage: ``python benchmarks/bench_stepwise.py [--quick] [--rounds 3] [--duration 30]
[--episode 1000] [--fmu-steps 2000] [--no-fmu] [--no-gym] [--estimators along-track,lc-ekf]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

from _empty_fmu import build_empty_fmu

import numpy as np

ESTIMATORS = ("lc-ekf", "tc-ekf", "tc-ukf", "along-track", "paper-ekf")
FLOOR = "agent floor (constant step_row)"


class ConstantRow:
    """An estimator whose ``step_row`` returns one fixed row (no covariance, no NIS): what
    ``EstimatorAgent.act`` costs by itself."""

    def reset(self, context, prior) -> None:
        self.row = np.array(prior.as_action(), dtype=float)

    def step(self, measurement):
        raise NotImplementedError("ConstantRow is driven through step_row")

    def step_row(self, measurement):
        return self.row, None, None, None


def _position_error_m(a: np.ndarray, b: np.ndarray, earth) -> float:
    """Largest local-level distance between two (n, 9) solution arrays, m."""
    lat = a[:, 0]
    r_n, r_e = earth.radii(lat)
    dn = (a[:, 0] - b[:, 0]) * (np.asarray(r_n) + a[:, 2])
    de = (a[:, 1] - b[:, 1]) * (np.asarray(r_e) + a[:, 2]) * np.cos(lat)
    du = a[:, 2] - b[:, 2]
    return float(np.max(np.sqrt(dn * dn + de * de + du * du)))


def _episode_inputs(duration: float):
    """(scenario, simulator start, context, batches, measurements, env observations, env info)."""
    import gymnasium as gym

    import navsim.envs  # noqa: F401  (registers the ids)
    from navsim.episode import make_context, measurement_batch
    from navsim.scenario import load_scenario
    from navsim.simulator import Simulator

    scenario = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": duration}})
    sim = Simulator(scenario)
    start = sim.reset(0)
    context = make_context(sim)
    prn = np.asarray(sim.constellation.prn)
    dt = scenario.timing.nav_period_s
    batches = [measurement_batch(chunk, prn, dt) for chunk in sim.chunks(10_000)]
    meas = [b.measurement(i) for b in batches for i in range(len(b))]
    env = gym.make("navsim/PaperRail-v0", timing={"duration_s": duration}, score=False)
    obs, info = env.reset(seed=0)
    observations = []
    zero = np.zeros(9)
    while True:
        observations.append({k: np.array(v, copy=True) for k, v in obs.items()})
        obs, _, terminated, truncated, _ = env.step(zero)
        if terminated or truncated:
            break
    env.close()
    return scenario, start, context, batches, meas, observations, info


def estimator_table(duration: float, rounds: int, only: tuple[str, ...] = ESTIMATORS) -> tuple[list[str], dict[str, float]]:
    from navsim.envs import EstimatorAgent
    from navsim.estimators import available, make

    scenario, start, context, batches, meas, observations, info = _episode_inputs(duration)
    n = len(meas)
    names = [e for e in only if e in available()]
    times: dict[tuple[str, str], list[float]] = {}
    solutions: dict[tuple[str, str], np.ndarray] = {}
    clock = time.process_time
    for _ in range(rounds):
        for name in names:
            est = make(name)
            est.reset(context, start.prior)
            t0 = clock()
            out = [est.step_batch(b) for b in batches]
            times.setdefault((name, "batch"), []).append((clock() - t0) / n)
            solutions[(name, "batch")] = np.concatenate([o.solution for o in out])

            est = make(name)
            est.reset(context, start.prior)
            step = est.step
            t0 = clock()
            for m in meas:
                step(m)
            times.setdefault((name, "step"), []).append((clock() - t0) / n)

            for key, timed in (("agent", True), ("untimed", False)):
                agent = EstimatorAgent(make(name), cpu_time=timed)
                agent.reset(info)
                act = agent.act
                rows = []
                t0 = clock()
                for o in observations[:n]:
                    rows.append(act(o))
                times.setdefault((name, key), []).append((clock() - t0) / n)
                solutions[(name, key)] = np.array(rows) * np.asarray(info["action_scale"])
        for key, timed in (("agent", True), ("untimed", False)):
            agent = EstimatorAgent(ConstantRow(), cpu_time=timed)
            agent.reset(info)
            act = agent.act
            t0 = clock()
            for o in observations[:n]:
                act(o)
            times.setdefault((FLOOR, key), []).append((clock() - t0) / n)
    lines = [f"paper-2012, {duration:g} s episode ({n} navigation steps), seed 0; CPU time per navigation "
             f"step, median of {rounds} interleaved round(s)", "",
             "| estimator | batch (us/step) | step (us/step) | agent (us/step) | step / batch | agent / batch "
             "| (batch + agent floor) / batch | agent, cpu_time=False (us/step) | its / batch | its (batch + floor) "
             "/ batch | max position difference agent vs batch (m) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    batch_cost = {}
    floor = statistics.median(times[(FLOOR, "agent")])
    floor_untimed = statistics.median(times[(FLOOR, "untimed")])
    for name in names:
        b, s, a, u = (statistics.median(times[(name, k)]) for k in ("batch", "step", "agent", "untimed"))
        batch_cost[name] = b
        diff = max(_position_error_m(solutions[(name, k)], solutions[(name, "batch")], context.earth)
                   for k in ("agent", "untimed"))
        lines.append(f"| {name} | {b * 1e6:.1f} | {s * 1e6:.1f} | {a * 1e6:.1f} | {s / b:.2f} | {a / b:.2f} "
                     f"| {(b + floor) / b:.2f} | {u * 1e6:.1f} | {u / b:.2f} | {(b + floor_untimed) / b:.2f} "
                     f"| {diff:.1e} |")
    lines.append(f"| {FLOOR} | | | {floor * 1e6:.1f} | | | | {floor_untimed * 1e6:.1f} | | | |")
    lines += ["", "Goal (issue 11): agent / batch <= 1.5 for every row. The column (batch + agent floor) / batch "
              "is the ratio an agent step would have if the estimator's step cost exactly its batch share: "
              "the least any per-step path through EstimatorAgent can reach on this machine. "
              "`EstimatorAgent(..., cpu_time=False)` reads no CPU clock around the estimator's call (two system "
              "calls per step here) and records no CPU time; its columns are measured the same way. The "
              "position difference is the largest of both agents against the batch path."]
    lines += [""] + split_table(names, context, start, meas, observations, info, rounds)
    return lines, batch_cost


def split_table(names, context, start, meas, observations, info, rounds: int) -> list[str]:
    """Where the step-wise time goes: ``step`` and ``EstimatorAgent.act`` timed call by call
    (CPU clock around each call, its own cost included), split into the steps that end at
    a GNSS epoch and the others."""
    from navsim.envs import EstimatorAgent
    from navsim.estimators import make

    clock = time.process_time
    epoch = [m.gnss is not None for m in meas]
    n_epoch = sum(epoch)
    times: dict[tuple[str, str], list[float]] = {}
    for _ in range(rounds):
        for name in names:
            est = make(name)
            est.reset(context, start.prior)
            agent = EstimatorAgent(make(name))
            agent.reset(info)
            for path, call, items in (("step", est.step, meas), ("agent", agent.act, observations[:len(meas)])):
                at_epoch = other = 0.0
                for item, is_epoch in zip(items, epoch):
                    t0 = clock()
                    call(item)
                    dt = clock() - t0
                    if is_epoch:
                        at_epoch += dt
                    else:
                        other += dt
                times.setdefault((name, path + " epoch"), []).append(at_epoch / max(n_epoch, 1))
                times.setdefault((name, path + " other"), []).append(other / max(len(meas) - n_epoch, 1))
        agent = EstimatorAgent(ConstantRow())
        agent.reset(info)
        at_epoch = other = 0.0
        for item, is_epoch in zip(observations[:len(meas)], epoch):
            t0 = clock()
            agent.act(item)
            dt = clock() - t0
            if is_epoch:
                at_epoch += dt
            else:
                other += dt
        times.setdefault((FLOOR, "agent epoch"), []).append(at_epoch / max(n_epoch, 1))
        times.setdefault((FLOOR, "agent other"), []).append(other / max(len(meas) - n_epoch, 1))
    lines = [f"Where the step-wise time goes: each call timed alone (CPU clock around it), {n_epoch} steps "
             f"ending at a GNSS epoch and {len(meas) - n_epoch} others; median of {rounds} round(s)", "",
             "| estimator | step at an epoch (us) | step, other steps (us) | agent at an epoch (us) "
             "| agent, other steps (us) |", "|---|---:|---:|---:|---:|"]
    for name in names:
        v = [statistics.median(times[(name, k)]) * 1e6 for k in ("step epoch", "step other", "agent epoch",
                                                                   "agent other")]
        lines.append(f"| {name} | {v[0]:.0f} | {v[1]:.1f} | {v[2]:.0f} | {v[3]:.1f} |")
    v = [statistics.median(times[(FLOOR, k)]) * 1e6 for k in ("agent epoch", "agent other")]
    lines.append(f"| {FLOOR} | | | {v[0]:.0f} | {v[1]:.1f} |")
    return lines




def fmu_table(steps: int, rounds: int, lc_batch_s: float | None) -> list[str]:
    from navsim.fmu.build import build_fmu
    from navsim.fmu.master import Connection, FmuInstance
    from navsim.scenario import load_scenario
    from navsim.simulator import Simulator

    scenario = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": steps * 0.01 + 1.0}})
    dt = scenario.timing.nav_period_s
    times: dict[str, list[float]] = {}
    clock = time.perf_counter  # the FMU runs in this process; wall time of the calls
    with tempfile.TemporaryDirectory() as tmp:
        empty = build_empty_fmu(tmp)
        plant_path = build_fmu(scenario, "plant", 2, Path(tmp) / "plant.fmu")
        est_path = build_fmu(scenario, "estimator", 2, Path(tmp) / "est.fmu", estimator="lc-ekf")
        for _ in range(rounds):
            with FmuInstance(empty, "empty") as inst:
                inst.initialize()
                t0 = clock()
                for k in range(steps):
                    inst.do_step(k * dt, dt)
                times.setdefault("empty", []).append((clock() - t0) / steps)
            sim = Simulator(scenario)
            t0 = clock()
            sim.reset(0)
            for _k in range(steps):
                sim.step()  # buffers 1000 steps ahead: the generation is included
            times.setdefault("core", []).append((clock() - t0) / steps)
            plant = FmuInstance(plant_path, "plant")
            est = FmuInstance(est_path, "estimator")
            try:
                plant.initialize({"seed": 0})
                est.initialize({})
                push = Connection(plant, est).push

                push()
                plant_t = est_t = 0.0
                for k in range(steps):
                    t0 = clock()
                    plant.do_step(k * dt, dt)
                    t1 = clock()
                    push()
                    t2 = clock()
                    est.do_step(k * dt, dt)
                    t3 = clock()
                    plant_t += t1 - t0
                    est_t += t3 - t2
                times.setdefault("plant", []).append(plant_t / steps)
                times.setdefault("estimator", []).append(est_t / steps)
            finally:
                plant.free()
                est.free()
    med = {k: statistics.median(v) for k, v in times.items()}
    floor_plant = med["empty"] + med["core"]
    lines = [f"paper-2012, {steps} communication steps of {dt:g} s, FMI 2 under fmpy; wall time per doStep, "
             f"median of {rounds} round(s)", "",
             "| case | us per step | reference | ratio | goal |", "|---|---:|---|---:|---:|",
             f"| empty pythonfmu FMU doStep | {med['empty'] * 1e6:.1f} | | | |",
             f"| core Simulator.step() | {med['core'] * 1e6:.1f} | | | |",
             f"| plant FMU doStep | {med['plant'] * 1e6:.1f} | empty + core step = {floor_plant * 1e6:.1f} us "
             f"| {med['plant'] / floor_plant:.2f} | <= 2 |"]
    if lc_batch_s is not None:
        floor_est = med["empty"] + lc_batch_s
        lines.append(f"| estimator FMU (lc-ekf) doStep | {med['estimator'] * 1e6:.1f} | empty + lc-ekf batch = "
                     f"{floor_est * 1e6:.1f} us | {med['estimator'] / floor_est:.2f} | <= 2 |")
    else:
        lines.append(f"| estimator FMU (lc-ekf) doStep | {med['estimator'] * 1e6:.1f} | | | |")
    lines += ["", "The lc-ekf batch cost is the CPU time per step of the table above; the FMU rows are wall "
              "time of calls made in this process."]
    return lines


def gym_table(duration: float) -> list[str]:
    import gymnasium as gym

    import navsim.envs  # noqa: F401
    from navsim import estimators
    from navsim.envs import EstimatorAgent
    from navsim.episode import run_episode
    from navsim.metrics import score_episode
    from navsim.scenario import load_scenario

    clock = time.perf_counter
    t0 = clock()
    env = gym.make("navsim/PaperRail-v0", timing={"duration_s": duration})
    agent = EstimatorAgent(estimators.make("lc-ekf"))
    obs, info = env.reset(seed=0)
    agent.reset(info)
    steps = 0
    while True:
        obs, reward, terminated, truncated, info = env.step(agent.act(obs))
        steps += 1
        if terminated or truncated:
            break
    gym_s = clock() - t0
    gym_rmse = info["episode_score"].horizontal_rmse_m
    env.close()
    scenario = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": duration}})
    t0 = clock()
    record = run_episode(scenario, estimators.make("lc-ekf"), seed=0)
    run_s = clock() - t0
    run_rmse = score_episode(record).to_flat_dict()["horizontal_rmse_m"]
    return [f"The README's Gymnasium loop with lc-ekf on navsim/PaperRail-v0, {duration:g} s episode "
            f"({steps} steps), seed 0, wall time including the simulation", "",
            "| path | s | steps/s | x run_episode | horizontal RMSE (m) |", "|---|---:|---:|---:|---:|",
            f"| run_episode (batch) | {run_s:.2f} | {steps / run_s:,.0f} | 1.00 | {run_rmse:.6f} |",
            f"| gym.make + EstimatorAgent | {gym_s:.2f} | {steps / gym_s:,.0f} | {gym_s / run_s:.2f} "
            f"| {gym_rmse:.6f} |"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="short episodes, one round")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--duration", type=float, default=30.0, help="episode length of the estimator table, s")
    ap.add_argument("--episode", type=float, default=1000.0, help="episode length of the Gymnasium loop, s")
    ap.add_argument("--fmu-steps", type=int, default=2000, help="communication steps per FMU row (>= 1000: "
                    "the simulator buffers 1000 steps ahead)")
    ap.add_argument("--no-fmu", action="store_true", help="leave out the FMU table")
    ap.add_argument("--estimators", default=",".join(ESTIMATORS), help="comma-separated rows of the estimator "
                    "tables (default: all five)")
    ap.add_argument("--no-gym", action="store_true", help="leave out the Gymnasium loop")
    args = ap.parse_args()
    if args.quick:
        args.rounds, args.duration, args.episode, args.fmu_steps = 1, 10.0, 20.0, 1000
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"load average {load:.2f} on {os.cpu_count()} cores")
    print()
    print("### Estimators: step-wise against batch")
    print()
    lines, batch_cost = estimator_table(args.duration, args.rounds, tuple(args.estimators.split(",")))
    print("\n".join(lines))
    if not args.no_fmu:
        print()
        print("### FMU doStep")
        print()
        print("\n".join(fmu_table(args.fmu_steps, args.rounds, batch_cost.get("lc-ekf"))))
    if not args.no_gym:
        print()
        print("### Gymnasium loop against run_episode")
        print()
        print("\n".join(gym_table(args.episode)))


if __name__ == "__main__":
    main()
