"""SB3 PPO on navsim/AdaptiveFilter-v0 against the untuned filter (a = 0), on held-out seeds.

The paper scenario shortened to 150 s with GNSS lost from 50 s to 110 s (lc-ekf, one
decision per second). The untuned filter is the env's default, deliberately mis-tuned
one (``untuned_scale = (1, 10)``: R x 10; see :mod:`navsim.envs.adaptive`); as a
reference, not a baseline to beat, the fixed action ``a = (0, -1)`` that restores the
estimator's own R. Shared code in ``_ppo_common.py``.

Usage: ``python benchmarks/demo_ppo_adaptive.py [--steps 6000] [--seeds 10] [--envs 4]
[--gamma 0.9] [--log-std-init -1]``;
``--quick`` for a pipeline check (a few hundred steps).
"""

from __future__ import annotations

import argparse

import numpy as np

import navsim.envs  # noqa: F401
from _ppo_common import compare, report, train

KWARGS = {"timing": {"duration_s": 150.0}, "outages": {"windows_s": [[50.0, 110.0]]}}


def note(res):
    return "horizontal RMSE %.2f m" % np.mean([i["episode_score"].horizontal_rmse_m for _, i in res])


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=6000)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--envs", type=int, default=4)
    ap.add_argument("--n-steps", type=int, default=128)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--gamma", type=float, default=0.9, help="discount (an action acts within a few decisions)")
    ap.add_argument("--log-std-init", type=float, default=-1.0, help="initial log std of the Gaussian policy")
    ap.add_argument("--figure", default="demo_ppo_adaptive.png", help="file name in results/, or 'none'")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    steps = 512 if args.quick else args.steps
    seeds = range(1000, 1000 + (2 if args.quick else args.seeds))
    policy, stats = train("navsim/AdaptiveFilter-v0", KWARGS, steps, args.envs, n_steps=args.n_steps,
                          ppo_kwargs={"learning_rate": args.lr, "gamma": args.gamma},
                          policy_kwargs={"log_std_init": args.log_std_init})
    policies = {"PPO (trained)": policy,
                "untuned filter a = (0, 0): R x 10": lambda obs: np.zeros(2, np.float32),
                "fixed a = (0, -1): the estimator's own R (reference)": lambda obs: np.array([0.0, -1.0], np.float32)}
    results = compare("navsim/AdaptiveFilter-v0", KWARGS, policies, seeds)
    report("navsim/AdaptiveFilter-v0", KWARGS, results, stats, seeds, list(policies)[1:], extra=note,
           figure=None if args.quick or args.figure == "none" else args.figure,
           train_note=f"; learning rate {args.lr:g}, discount {args.gamma:g}, initial log std {args.log_std_init:g}")
