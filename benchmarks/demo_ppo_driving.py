"""SB3 PPO on navsim/TrainDriving-v0 against the naive constant-command driver (u = 0.3), on held-out seeds.

A two-station line (400 m -> 1500 m, dwell 10 s and 20 s), along-track estimator, one
decision per second. Usage: ``python benchmarks/demo_ppo_driving.py [--steps 3000]
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
    kwargs = {"motion": {"stations": [{"s_m": 400.0, "dwell_s": 10.0}, {"s_m": 1500.0, "dwell_s": 20.0}]}}

    def note(res):
        stops = [s for _, i in res for s in i["stops"] if "stop_error_m" in s]
        return f"{len(stops)}/{len(res)} stops served, unserved {sum(i.get('unserved', 0) for _, i in res)}"

    run("navsim/TrainDriving-v0", kwargs, lambda obs: np.array([0.3], np.float32), "constant command u = 0.3",
        steps, 2, range(1000, 1000 + args.seeds), extra=note)
