"""SB3 PPO on navsim/TrainDriving-v0 against constant-command drivers, on held-out seeds.

A two-station line (400 m -> 900 m, dwell 5 s and 10 s) of mountain-railway with its IMU
and navigation at 50 Hz, along-track estimator, one decision per second. PPO drives
through the env's ``action_mode="target_speed"`` (the action is a speed demand to the
train's speed controller, (D.1) of :mod:`navsim.envs.driving`, acting on the speed
estimate); the task, its reward ((R.1)-(R.4): a station run through is not served) and
the stop judgement are those of the default command mode, so the baselines run in the
command mode on the same seeds and the returns compare directly. PPO trains with the
env's optional potential-based shaping (``progress_shaping``, ``braking_shaping``,
``approach_shaping``) and ``episode_score=False`` (no navigation score per training
episode; the same rewards bit for bit) and is scored, like the baselines, on the task
reward alone (``info["task_reward"]``).

Baselines: standing still, the constant command u = 0.3 (the naive driver: it drives
through the station), full traction, the constant speed demand of the line speed (a = 1
in the target-speed mode: drives through as well) and, as a reference that is not a
baseline to beat, the hand-written braking-curve driver on the estimate
(:func:`navsim.envs.driving.braking_curve_driver`). Shared code in ``_ppo_common.py``.

PPO settings: SB3's defaults (``MlpPolicy``, learning rate 3e-4, batch 64, 10 epochs,
clip 0.2, GAE lambda 0.95, initial log std 0, no entropy bonus) except
``n_steps=128`` per env (SB3's 2048 x 4 envs would give a handful of updates in the
budget), ``gamma=0.999`` (an episode is about 60 decisions; with 0.99 the unserved
charge at its end is discounted by about half, and a stop short of the mark looks
cheaper than it is) and ``VecNormalize`` on observations and rewards (``_ppo_common``).

Usage: ``python benchmarks/demo_ppo_driving.py [--steps 30720] [--seeds 10] [--envs 4]
[--shaping 20] [--braking-shaping 2] [--approach-shaping 10] [--action-mode target_speed]
[--gamma 0.999]``; ``--quick`` for a pipeline check (a few hundred steps).
"""

from __future__ import annotations

import argparse

import navsim.envs  # noqa: F401
import numpy as np
from _ppo_common import compare, report, train
from navsim.envs.driving import braking_curve_driver

# the line's IMU and navigation at 50 Hz instead of the scenario's 200 / 100 Hz: 1.7x faster episodes (the IMU
# error generation dominates a decision), the same task for every policy compared
LINE = {"motion": {"stations": [{"s_m": 400.0, "dwell_s": 5.0}, {"s_m": 900.0, "dwell_s": 10.0}]},
        "timing": {"tick_s": 0.02, "imu_period_s": 0.02, "nav_period_s": 0.02}}




def note(res):
    served = [s for _, i in res for s in i["stops"] if "stop_error_m" in s]
    err = np.array([abs(s["stop_error_m"]) for s in served])
    errs = f"stop error mean {err.mean():.2f} m, max {err.max():.2f} m" if len(err) else "no stop"
    over = sum(1 for _, i in res for s in i["stops"] if "overrun_m" in s)
    short = sum(i.get("unserved", 0) - i.get("missed", 0) for _, i in res)
    late = [s["late_s"] for s in served]
    lates = f", arrival vs schedule {np.mean(late):+.1f} s" if late else ""
    return f"{len(served)}/{len(res)} stations served ({errs}{lates}), {over} overruns, {short} never reached"


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=30720)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--envs", type=int, default=4)
    ap.add_argument("--n-steps", type=int, default=128)
    ap.add_argument("--shaping", type=float, default=20.0, help="progress_shaping of the training envs, per km")
    ap.add_argument("--braking-shaping", type=float, default=2.0, help="braking_shaping of the training envs, per m/s")
    ap.add_argument("--approach-shaping", type=float, default=10.0, help="approach_shaping of the training envs")
    ap.add_argument("--lr", type=float, default=3e-4)
    ap.add_argument("--log-std-init", type=float, default=0.0, help="initial log std of the Gaussian policy")
    ap.add_argument("--action-mode", default="target_speed", choices=["command", "target_speed"],
                    help="what PPO's action is (navsim.envs.driving, 'Action space')")
    ap.add_argument("--gamma", type=float, default=0.999)
    ap.add_argument("--ent-coef", type=float, default=0.0)
    ap.add_argument("--figure", default="demo_ppo_driving.png", help="file name in results/, or 'none'")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    steps = 512 if args.quick else args.steps
    seeds = range(1000, 1000 + (2 if args.quick else args.seeds))
    mode = {"action_mode": args.action_mode}
    policy, stats = train("navsim/TrainDriving-v0", {**LINE, **mode}, steps, args.envs, n_steps=args.n_steps,
                          train_kwargs={"progress_shaping": args.shaping, "braking_shaping": args.braking_shaping,
                                        "approach_shaping": args.approach_shaping, "episode_score": False},
                          ppo_kwargs={"learning_rate": args.lr, "gamma": args.gamma, "ent_coef": args.ent_coef},
                          policy_kwargs={"log_std_init": args.log_std_init})
    baselines = {"standing still (u = -1)": lambda obs: np.array([-1.0], np.float32),
                 "constant command u = 0.3": lambda obs: np.array([0.3], np.float32),
                 "full traction u = 1": lambda obs: np.array([1.0], np.float32),
                 "braking-curve driver (reference)": braking_curve_driver}
    # the same task and seeds; the PPO policy acts through its own action mode, the baselines through the command
    results = {**compare("navsim/TrainDriving-v0", {**LINE, **mode}, {"PPO (trained)": policy}, seeds),
               **compare("navsim/TrainDriving-v0", {**LINE, "action_mode": "target_speed"},
                         {"constant speed demand a = 1 (line speed)": lambda obs: np.array([1.0], np.float32)},
                         seeds),
               **compare("navsim/TrainDriving-v0", LINE, baselines, seeds)}
    report("navsim/TrainDriving-v0", LINE, results, stats, seeds,
           ["standing still (u = -1)", "constant command u = 0.3", "full traction u = 1",
            "constant speed demand a = 1 (line speed)", "braking-curve driver (reference)"], extra=note,
           figure=None if args.quick or args.figure == "none" else args.figure,
           train_note=f"; PPO in action_mode={args.action_mode!r}, training with progress_shaping={args.shaping:g}, "
                      f"braking_shaping={args.braking_shaping:g}, approach_shaping={args.approach_shaping:g}, "
                      f"learning rate {args.lr:g}, gamma {args.gamma:g}, "
                      f"ent_coef {args.ent_coef:g}, initial log std {args.log_std_init:g}")
