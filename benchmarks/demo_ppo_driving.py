"""SB3 PPO on navsim/TrainDriving-v0 against the naive constant-command driver (u = 0.3), on held-out seeds.

A two-station line (400 m -> 1500 m, dwell 10 s and 20 s), along-track estimator, one
decision per second. PPO trains with the env's optional potential-based progress
shaping (``progress_shaping``; see :mod:`navsim.envs.driving`) and is scored, like the
baselines, on the task reward alone (``info["task_reward"]``). Baselines: the constant
command u = 0.3 (the naive driver: it drives through the station), full traction, and,
as a reference that is not a baseline to beat, the hand-written braking-curve driver
on the estimate of ``tests/envs/test_driving.py``. Shared code in ``_ppo_common.py``.

Usage: ``python benchmarks/demo_ppo_driving.py [--steps 15000] [--seeds 10] [--envs 4]
[--shaping 20] [--braking-shaping 2]``; ``--quick`` for a pipeline check (a few hundred steps).
"""

from __future__ import annotations

import argparse

import navsim.envs  # noqa: F401
import numpy as np
from _ppo_common import compare, report, train
from navsim.envs.driving import braking_curve_driver

LINE = {"motion": {"stations": [{"s_m": 400.0, "dwell_s": 10.0}, {"s_m": 1500.0, "dwell_s": 20.0}]}}




def note(res):
    served = [s for _, i in res for s in i["stops"] if "stop_error_m" in s]
    err = np.mean([abs(s["stop_error_m"]) for s in served]) if served else float("nan")
    over = sum(1 for _, i in res for s in i["stops"] if "overrun_m" in s)
    return (f"{len(served)}/{len(res)} stops served (mean abs. stop error {err:.2f} m), {over} overruns, "
            f"unserved {sum(i.get('unserved', 0) for _, i in res)}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=15000)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--envs", type=int, default=4)
    ap.add_argument("--n-steps", type=int, default=128)
    ap.add_argument("--shaping", type=float, default=20.0, help="progress_shaping of the training envs, per km")
    ap.add_argument("--braking-shaping", type=float, default=2.0, help="braking_shaping of the training envs, per m/s")
    ap.add_argument("--lr", type=float, default=3e-4)
    ap.add_argument("--log-std-init", type=float, default=0.0, help="initial log std of the Gaussian policy")
    ap.add_argument("--figure", default="demo_ppo_driving.png", help="file name in results/, or 'none'")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    steps = 512 if args.quick else args.steps
    seeds = range(1000, 1000 + (2 if args.quick else args.seeds))
    policy, stats = train("navsim/TrainDriving-v0", LINE, steps, args.envs, n_steps=args.n_steps,
                          train_kwargs={"progress_shaping": args.shaping, "braking_shaping": args.braking_shaping},
                          ppo_kwargs={"learning_rate": args.lr}, policy_kwargs={"log_std_init": args.log_std_init})
    policies = {"PPO (trained)": policy,
                "constant command u = 0.3": lambda obs: np.array([0.3], np.float32),
                "full traction u = 1": lambda obs: np.array([1.0], np.float32),
                "braking-curve driver (reference)": braking_curve_driver}
    results = compare("navsim/TrainDriving-v0", LINE, policies, seeds)
    report("navsim/TrainDriving-v0", LINE, results, stats, seeds,
           ["constant command u = 0.3", "full traction u = 1", "braking-curve driver (reference)"], extra=note,
           figure=None if args.quick or args.figure == "none" else args.figure,
           train_note=f"; training with progress_shaping={args.shaping:g}, braking_shaping={args.braking_shaping:g}, "
                      f"learning rate {args.lr:g}, initial log std {args.log_std_init:g}")
