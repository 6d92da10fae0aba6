"""A short learning run in the adaptive-filtering env: the cross-entropy method on a linear policy.

No deep-learning library: the policy is ``a = tanh(W x + b)`` (2 x 9 weights and 2
biases) on the env's observation x, and the cross-entropy method [1] searches its 20
parameters: sample a population around the mean, keep the elite by mean episode return
over the training seeds, refit mean and spread. It starts at zero, which is the untuned
filter (a = 0: the env's untuned filter, mis-tuned on purpose, R x 10 by default; see
:mod:`navsim.envs.adaptive`), so whatever it finds is measured against the untuned
filter on held-out seeds it never saw.

Usage: ``python benchmarks/demo_adaptive_cem.py [--scenario urban-road] [--duration 200]
[--iterations 4] [--population 8]``; prints the training curve and a held-out table.

References
----------
.. [1] Rubinstein R.Y., Kroese D.P., The Cross-Entropy Method, Springer 2004; for policy
       search: Szita I., Lőrincz A., Learning Tetris using the noisy cross-entropy
       method, Neural Computation 18(12), 2006 (the added noise on the spread).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import navsim.envs  # noqa: F401


def rollout(env, params: np.ndarray | None, seed: int) -> tuple[float, object]:
    obs, _ = env.reset(seed=seed)
    total = 0.0
    while True:
        if params is None:
            action = np.zeros(2, dtype=np.float32)
        else:
            w, b = params[:18].reshape(2, 9), params[18:]
            action = np.tanh(w @ obs + b).astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        total += reward
        if terminated or truncated:
            return total, info["episode_score"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenario", default="urban-road")
    parser.add_argument("--estimator", default="lc-ekf")
    parser.add_argument("--duration", type=float, default=200.0)
    parser.add_argument("--iterations", type=int, default=4)
    parser.add_argument("--population", type=int, default=8)
    parser.add_argument("--elite", type=int, default=3)
    parser.add_argument("--train-seeds", type=int, nargs="+", default=[100, 101])
    parser.add_argument("--test-seeds", type=int, nargs="+", default=[200, 201, 202, 203])
    args = parser.parse_args()

    env = gym.make("navsim/AdaptiveFilter-v0", scenario=args.scenario, estimator=args.estimator,
                   timing={"duration_s": args.duration})
    rng = np.random.default_rng(0)
    mean, sigma = np.zeros(20), np.full(20, 0.3)
    t0 = time.time()

    def fitness(p):
        return float(np.mean([rollout(env, p, s)[0] for s in args.train_seeds]))

    print(f"{args.scenario}, {args.estimator}, {args.duration:.0f} s episodes; train seeds {args.train_seeds}")
    print(f"iteration 0: untuned (mean) return {fitness(mean):.1f}  [{time.time() - t0:.0f} s]")
    for it in range(1, args.iterations + 1):
        pop = mean + sigma * rng.standard_normal((args.population, 20))
        pop[0] = mean  # keep the current mean in the population
        scores = np.array([fitness(p) for p in pop])
        elite = pop[np.argsort(scores)[-args.elite:]]
        mean = elite.mean(axis=0)
        sigma = elite.std(axis=0) + 0.02  # noisy CEM: a floor on the spread
        print(f"iteration {it}: best {scores.max():.1f}, population mean {scores.mean():.1f}  [{time.time() - t0:.0f} s]")

    print(f"\nheld-out seeds {args.test_seeds}")
    print(f"{'policy':10s} {'return':>10s} {'mean 3-D err m':>15s} {'horiz RMSE m':>13s} {'outage drift m':>15s}")
    steps = None
    for label, params in (("untuned", None), ("CEM", mean)):
        rows = [rollout(env, params, s) for s in args.test_seeds]
        ret = np.mean([r for r, _ in rows])
        steps = env.unwrapped.n_steps / env.unwrapped.steps_per_decision - 1
        hr = np.mean([sc.horizontal_rmse_m for _, sc in rows])
        od = np.nanmean([sc.outage_rms_drift_m for _, sc in rows]) if any(
            np.isfinite(sc.outage_rms_drift_m) for _, sc in rows) else float("nan")
        print(f"{label:10s} {ret:10.1f} {-ret / steps:15.2f} {hr:13.2f} {od:15.2f}")
    print(f"\nlearned parameters (W rows, b): {np.round(mean, 3).tolist()}")
    print(f"total time {time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
