"""Shared part of the SB3 PPO demos (demo_ppo_adaptive.py, demo_ppo_driving.py).

Train Stable-Baselines3 PPO (extra ``rl``) on a navsim task for a given number of env
steps on training seeds, then evaluate the deterministic policy and a baseline on
held-out seeds it never saw. Reported:

* the mean episode return of each policy with its 95 % Student-t interval over the seeds;
* the paired difference PPO - baseline, seed by seed (the same seed gives both policies
  the same sensor noise, so most of the seed-to-seed spread cancels), with its 95 %
  Student-t interval: the policy beats the baseline when the interval lies above 0;
* the training rate (env steps per wall second and per CPU second of this process) and
  the training time;
* a learning-curve figure (PNG next to the results section): the task return of every
  training episode against the env steps, with the baselines' held-out means.

Training set-up (the measured reasons are in CHANGELOG.md, issue 15): SB3's
``VecNormalize`` on the observations and the rewards (running mean / variance; the
returns of the two tasks are of order 10^2-10^3 and would otherwise swamp the value
loss), its statistics frozen for the evaluation; ``n_steps`` per env of the order of
an episode so that the policy is updated many times within the budget; torch limited
to one thread (a shared machine: more threads only spin).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"


def interval(values) -> tuple[float, float]:
    """Mean and the half-width of its 95 % Student-t interval."""
    from scipy import stats

    v = np.asarray(values, dtype=float)
    if len(v) < 2:
        return float(v.mean()), float("nan")
    return float(v.mean()), float(stats.t.ppf(0.975, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v)))


def episode_return(env, policy, seed: int) -> tuple[float, dict]:
    """Task return of one episode (``info["task_reward"]`` where the env gives it, else the reward)."""
    obs, info = env.reset(seed=seed)
    total = 0.0
    while True:
        obs, r, term, trunc, info = env.step(policy(obs))
        total += float(info.get("task_reward", r))
        if term or trunc:
            return total, info


def _curve_callback():
    from stable_baselines3.common.callbacks import BaseCallback

    class Curve(BaseCallback):
        """Task return of every finished training episode, with the env step it ended at."""

        def __init__(self):
            super().__init__()
            self.points: list[tuple[int, float]] = []
            self._acc = None

        def _on_step(self) -> bool:
            infos, rewards, dones = self.locals["infos"], self.locals["rewards"], self.locals["dones"]
            if self._acc is None:
                self._acc = np.zeros(len(infos))
            for j, info in enumerate(infos):
                # the raw reward (VecNormalize scales only what the learner sees): the task's part
                self._acc[j] += float(info.get("task_reward", self.training_env.get_original_reward()[j]))
                if dones[j]:
                    self.points.append((self.num_timesteps, float(self._acc[j])))
                    self._acc[j] = 0.0
            return True

    return Curve()


def train(env_id: str, kwargs: dict, steps: int, n_envs: int, *, train_kwargs: dict | None = None,
          n_steps: int = 128, policy_kwargs: dict | None = None, ppo_kwargs: dict | None = None, seed: int = 0):
    """PPO on ``n_envs`` copies of the env (training seeds from ``seed``); returns (policy, stats)."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from navsim.envs.sb3 import make_sb3_vec_env

    torch.set_num_threads(1)
    venv = make_sb3_vec_env(env_id, num_envs=n_envs, seed=seed, **kwargs, **(train_kwargs or {}))
    venv = VecNormalize(venv, norm_obs=True, norm_reward=True, gamma=(ppo_kwargs or {}).get("gamma", 0.99))
    model = PPO("MlpPolicy", venv, n_steps=n_steps, batch_size=64, seed=seed, device="cpu",
                policy_kwargs=policy_kwargs or {}, verbose=0, **(ppo_kwargs or {}))
    curve = _curve_callback()
    w0, c0 = time.perf_counter(), time.process_time()
    model.learn(total_timesteps=steps, callback=curve)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    venv.training = False
    venv.norm_reward = False

    def policy(obs):
        return model.predict(venv.normalize_obs(obs), deterministic=True)[0]

    stats = {"steps": int(model.num_timesteps), "wall_s": wall, "cpu_s": cpu, "curve": curve.points,
             "n_envs": n_envs, "n_steps": n_steps}
    venv.close()
    return policy, stats


def compare(env_id: str, kwargs: dict, policies: dict, eval_seeds, extra=None) -> dict:
    """Every policy on every held-out seed: {name: [(return, last info), ...]}."""
    import gymnasium as gym

    env = gym.make(env_id, **kwargs)
    return {name: [episode_return(env, policy, s) for s in eval_seeds] for name, policy in policies.items()}


def report(env_id: str, kwargs: dict, results: dict, stats: dict, eval_seeds, baselines: list[str], extra=None,
           figure: str | None = None, train_note: str = "") -> None:
    """Print the Markdown tables (and write the learning-curve figure)."""
    seeds = list(eval_seeds)
    print(f"{env_id}, {kwargs}{train_note}; PPO {stats['steps']} env steps on {stats['n_envs']} envs "
          f"(n_steps {stats['n_steps']} per env; training seeds from 0), evaluated on {len(seeds)} held-out seeds "
          f"{seeds[0]}..{seeds[-1]} (deterministic policy)\n")
    print("| policy | episode return, mean ± 95 % interval | notes |")
    print("|---|---|---|")
    for name, res in results.items():
        mean, half = interval([r for r, _ in res])
        print(f"| {name} | {mean:.2f} ± {half:.2f} | {extra(res) if extra else ''} |")
    ppo = np.array([r for r, _ in results["PPO (trained)"]])
    print("\n| paired by seed | difference of returns, mean ± 95 % interval | seeds where PPO is better |")
    print("|---|---|---|")
    for name in baselines:
        d = ppo - np.array([r for r, _ in results[name]])
        mean, half = interval(d)
        verdict = "PPO better" if mean - half > 0 else ("PPO worse" if mean + half < 0 else "no significant difference")
        print(f"| PPO - {name} | {mean:+.2f} ± {half:.2f} ({verdict}) | {int(np.sum(d > 0))}/{len(d)} |")
    print(f"\ntraining: {stats['steps']} env steps in {stats['wall_s']:.0f} s wall ({stats['cpu_s']:.0f} CPU s of this "
          f"process): {stats['steps'] / stats['wall_s']:.1f} env steps/s wall, "
          f"{stats['steps'] / stats['cpu_s']:.1f} per CPU s")
    if figure and stats["curve"]:
        _figure(figure, env_id, stats, {name: interval([r for r, _ in results[name]])[0] for name in results})
        print(f"\n![learning curve](results/{figure})")


def _figure(name: str, env_id: str, stats: dict, means: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x, y = np.array(stats["curve"]).T
    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=100)
    ax.plot(x, y, ".", ms=3, color="0.6", label="training episodes (task return)")
    k = max(1, len(y) // 10)
    if len(y) >= k:
        ax.plot(x[k - 1:], np.convolve(y, np.ones(k) / k, mode="valid"), color="C0", label=f"running mean of {k}")
    for i, (label, mean) in enumerate(means.items()):
        ax.axhline(mean, color=f"C{i + 1}", ls="--", lw=1, label=f"{label}: held-out mean")
    ax.set_xlabel("env steps")
    ax.set_ylabel("episode return")
    ax.set_title(f"SB3 PPO on {env_id}", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    RESULTS.mkdir(exist_ok=True)
    tmp = RESULTS / f".{name}.tmp.png"
    fig.savefig(tmp)
    plt.close(fig)
    tmp.replace(RESULTS / name)
