"""Where a TrainDriving-v0 decision's CPU time goes, and the training configuration's speed-up.

The demo's line (benchmarks/demo_ppo_driving.py: 400 -> 900 m, IMU and navigation at
50 Hz, along-track estimator, one decision per second = 50 navigation steps), driven by
the braking-curve driver (a stop) and by a fixed random command sequence (an overrun),
episode after episode. Two configurations, in alternating rounds in this process:

* reference: the plant's generic path (``sin_grade`` called per RK4 stage) and the
  episode recorded and scored (``episode_score=True``): the env as it was;
* training: the plant's grade table inline (:class:`navsim.envs.plant.TrainPlant`,
  ``grade_table``) and ``episode_score=False`` (no recording, no navigation score):
  the configuration the PPO demo trains in.

Both give the same observations, rewards and infos bit for bit (checked here on every
episode, and in ``tests/envs/test_driving.py``). Reported: CPU time per decision
(``time.process_time``: on a shared machine the figure to compare), the ratio, and the
training configuration's breakdown by part (the plant, the push of its states into the
external motion, the simulator's chunk, the estimator, the rest of the env step).

Usage: ``python benchmarks/bench_driving.py [--rounds 3] [--episodes 3] [--quick]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import gymnasium as gym
import navsim.envs  # noqa: F401  (registers the ids)
import numpy as np
from navsim.envs import driving
from navsim.envs.driving import braking_curve_driver

import navsim.episode

LINE = {"motion": {"stations": [{"s_m": 400.0, "dwell_s": 5.0}, {"s_m": 900.0, "dwell_s": 10.0}]},
        "timing": {"tick_s": 0.02, "imu_period_s": 0.02, "nav_period_s": 0.02}}


def _replay(seed: int):
    """A fixed random command sequence (mean 0.4: it runs through the station), whatever is observed."""
    fixed = iter(np.clip(np.random.default_rng(seed).normal(0.4, 0.7, 10_000), -1, 1).astype(np.float32))
    return lambda obs: next(fixed).reshape(1)


def _episodes(env, n: int, seed0: int) -> tuple[list, int]:
    """n episodes alternating the driver and a fixed random sequence; (traces, decisions)."""
    traces, steps = [], 0
    for j in range(n):
        policy = braking_curve_driver if j % 2 == 0 else _replay(seed0 + j)
        obs, _ = env.reset(seed=seed0 + j)
        trace = [obs.tobytes()]
        while True:
            obs, r, term, trunc, info = env.step(policy(obs))
            trace.append((obs.tobytes(), r))
            steps += 1
            if term or trunc:
                break
        traces.append(trace)
    return traces, steps


class _Timer:
    """Wrap callables and add up the CPU time spent in them."""

    def __init__(self):
        self.spent: dict[str, float] = {}

    def wrap(self, name: str, fn):
        self.spent[name] = 0.0

        def timed(*args, **kwargs):
            c = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.spent[name] += time.process_time() - c

        return timed


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--episodes", type=int, default=4)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    rounds, episodes = (1, 2) if args.quick else (args.rounds, args.episodes)
    ref = gym.make("navsim/TrainDriving-v0", **LINE).unwrapped
    ref.plant._table = None  # the generic path
    fast = gym.make("navsim/TrainDriving-v0", episode_score=False, **LINE).unwrapped
    _episodes(ref, 1, 0), _episodes(fast, 1, 0)  # warm-up (first-use compilation)
    per = {"reference": [], "training": []}
    equal = True
    for _ in range(rounds):
        out = {}
        for name, env in (("reference", ref), ("training", fast)):
            c = time.process_time()
            out[name], steps = _episodes(env, episodes, 100)
            per[name].append((time.process_time() - c) / steps)
        equal &= out["reference"] == out["training"]
    # breakdown of the training configuration
    timer = _Timer()
    fast.plant.advance = timer.wrap("plant (RK4 of (P.1)-(P.2))", fast.plant.advance)
    fast.sim.profile.push = timer.wrap("push into the external motion", fast.sim.profile.push)
    fast.sim.advance = timer.wrap("simulator chunk (truth, IMU, GNSS)", fast.sim.advance)
    step_batch, measurement_batch = driving.step_batch, navsim.episode.measurement_batch
    driving.step_batch = timer.wrap("estimator (along-track step_batch)", step_batch)
    navsim.episode.measurement_batch = timer.wrap("measurement batch", measurement_batch)
    try:
        c = time.process_time()
        _, steps = _episodes(fast, episodes, 100)
        total = time.process_time() - c
    finally:
        driving.step_batch, navsim.episode.measurement_batch = step_batch, measurement_batch
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    r, f = statistics.median(per["reference"]), statistics.median(per["training"])
    print(f"navsim/TrainDriving-v0 on the demo line (50 Hz, along-track), {episodes} episodes per round, {rounds} "
          f"rounds (median), load average {load}; observations and rewards of the two configurations "
          f"{'equal bit for bit' if equal else 'DIFFERENT'}\n")
    print("| configuration | CPU ms per decision | ratio to the reference |")
    print("|---|---|---|")
    print(f"| reference (generic plant path, episode recorded and scored) | {1e3 * r:.2f} | 1.00 |")
    print(f"| training (plant grade table inline, `episode_score=False`) | {1e3 * f:.2f} | {f / r:.2f} |")
    print(f"\nbreakdown of the training configuration ({steps} decisions, {1e3 * total / steps:.2f} CPU ms each):\n")
    print("| part | CPU ms per decision | share |")
    print("|---|---|---|")
    rest = total
    for name, spent in timer.spent.items():
        rest -= spent
        print(f"| {name} | {1e3 * spent / steps:.2f} | {spent / total:.0%} |")
    print(f"| the rest of the env step (observation, reward, projection) | {1e3 * rest / steps:.2f} "
          f"| {rest / total:.0%} |")


if __name__ == "__main__":
    main()
