"""SB3 PPO on navsim/AdaptiveFilter-v0 against the untuned filter (a = 0), on held-out seeds.

The paper scenario shortened to 150 s with GNSS lost from 50 s to 110 s (lc-ekf, one
decision per second). PPO starts with a narrow exploration (log std -1) around a = 0,
the untuned filter. Usage: ``python benchmarks/demo_ppo_adaptive.py [--steps 3000]
[--seeds 3]``; shared code in ``_ppo_common.py``.
"""

from __future__ import annotations

import argparse

import numpy as np

import navsim.envs  # noqa: F401
from _ppo_common import run

if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    steps = 512 if args.quick else args.steps
    kwargs = {"timing": {"duration_s": 150.0}, "outages": {"windows_s": [[50.0, 110.0]]}}
    run("navsim/AdaptiveFilter-v0", kwargs, lambda obs: np.zeros(2, np.float32), "untuned filter (a = 0)", steps, 2,
        range(1000, 1000 + args.seeds), policy_kwargs={"log_std_init": -1.0},
        extra=lambda res: "horizontal RMSE %.1f m" % np.mean([i["episode_score"].horizontal_rmse_m for _, i in res]))
