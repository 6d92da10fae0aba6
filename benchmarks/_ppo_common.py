"""Shared part of the SB3 PPO demos (demo_ppo_adaptive.py, demo_ppo_driving.py).

Train Stable-Baselines3 PPO (extra ``rl``) on a navsim task for a given number of env
steps on training seeds, then evaluate the deterministic policy and a baseline on
held-out seeds it never saw: mean episode return with a 95 % Student-t interval, and the
training rate (env steps per wall second and per CPU second of this process).
"""

from __future__ import annotations

import math
import time

import numpy as np


def interval(values) -> tuple[float, float]:
    """Mean and the half-width of its 95 % Student-t interval."""
    from scipy import stats

    v = np.asarray(values, dtype=float)
    if len(v) < 2:
        return float(v.mean()), float("nan")
    return float(v.mean()), float(stats.t.ppf(0.975, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v)))


def episode_return(env, policy, seed: int) -> tuple[float, dict]:
    obs, info = env.reset(seed=seed)
    total = 0.0
    while True:
        obs, r, term, trunc, info = env.step(policy(obs))
        total += float(r)
        if term or trunc:
            return total, info


def run(env_id: str, kwargs: dict, baseline, baseline_name: str, steps: int, n_envs: int, eval_seeds,
        policy_kwargs: dict | None = None, extra=None) -> None:
    import gymnasium as gym
    from stable_baselines3 import PPO

    from navsim.envs.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env(env_id, num_envs=n_envs, seed=0, **kwargs)  # training seeds 0, 1, ... (SB3 seeding)
    model = PPO("MlpPolicy", venv, n_steps=max(64, steps // (4 * n_envs)), batch_size=64, seed=0, device="cpu",
                policy_kwargs=policy_kwargs or {}, verbose=0)
    w0, c0 = time.perf_counter(), time.process_time()
    model.learn(total_timesteps=steps)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    venv.close()
    env = gym.make(env_id, **kwargs)
    ppo = lambda obs: model.predict(obs, deterministic=True)[0]  # noqa: E731
    rows = []
    for name, policy in (("PPO (trained)", ppo), (baseline_name, baseline)):
        results = [episode_return(env, policy, s) for s in eval_seeds]
        mean, half = interval([r for r, _ in results])
        note = extra(results) if extra else ""
        rows.append(f"| {name} | {mean:.2f} ± {half:.2f} | {note} |")
    print(f"{env_id}, {kwargs}; PPO {model.num_timesteps} env steps on {n_envs} envs (training seeds from 0), "
          f"evaluated on held-out seeds {list(eval_seeds)} (deterministic policy)\n")
    print("| policy | episode return, mean ± 95 % interval | notes |")
    print("|---|---|---|")
    print("\n".join(rows))
    print(f"\ntraining: {model.num_timesteps / wall:.1f} env steps/s wall, {model.num_timesteps / cpu:.1f} per CPU s "
          f"of this process ({wall:.0f} s wall)")
