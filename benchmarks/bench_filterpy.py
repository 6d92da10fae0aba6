"""Cost per navigation step of the filterpy-based baselines against navsim's own engines.

Rows: lc-ekf vs lc-ekf-filterpy and tc-ekf vs tc-ekf-filterpy (filterpy's
ExtendedKalmanFilter.update doing the Kalman arithmetic), tc-ukf vs tc-ukf-filterpy
(filterpy's UnscentedKalmanFilter.update and MerweScaledSigmaPoints; see
navsim/estimators/filterpy_based.py) on paper-2012, estimator CPU time per navigation step
(``EpisodeRecord.step_time_s``, process CPU), median of interleaved repeats in one process,
and the largest difference of the position estimates.

Usage: ``python benchmarks/bench_filterpy.py [--duration 300] [--repeats 3] [--quick]``
"""

from __future__ import annotations

import argparse
import statistics

import numpy as np

from navsim import estimators
from navsim.episode import run_episode
from navsim.scenario import load_scenario

PAIRS = (("lc-ekf", "lc-ekf-filterpy"), ("tc-ekf", "tc-ekf-filterpy"), ("tc-ukf", "tc-ukf-filterpy"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--duration", type=float, default=300.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="60 s, 2 repeats")
    args = ap.parse_args()
    duration, repeats = (60.0, 2) if args.quick else (args.duration, args.repeats)
    sc = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": duration}})
    print(f"paper-2012, {duration:g} s ({sc.timing.steps} navigation steps), seed 0, {repeats} interleaved repeats\n")
    print("| navsim engine | us/step | filterpy-based | us/step | ratio | max position difference, m |")
    print("|---|---|---|---|---|---|")
    for ours, theirs in PAIRS:
        cost = {ours: [], theirs: []}
        recs = {}
        for _ in range(repeats):
            for name in (ours, theirs):
                rec = run_episode(sc, estimators.make(name), seed=0)
                cost[name].append(float(np.nansum(rec.step_time_s)) / len(rec.t) * 1e6)
                recs[name] = rec
        a, b = recs[ours], recs[theirs]
        d = max(np.max(np.abs(a.est_lat - b.est_lat)) * 6.4e6, np.max(np.abs(a.est_lon - b.est_lon)) * 6.4e6,
                np.max(np.abs(a.est_h - b.est_h)))
        ca, cb = statistics.median(cost[ours]), statistics.median(cost[theirs])
        print(f"| {ours} | {ca:.1f} | {theirs} | {cb:.1f} | {cb / ca:.2f} | {d:.1e} |")


if __name__ == "__main__":
    main()
