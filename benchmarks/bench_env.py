"""Speed of the Gymnasium face, side by side with CartPole in the same process.

Rows
----
* ``CartPole-v1`` through ``gym.make`` (Gymnasium's reference; constant action, reset at
  episode end);
* ``navsim/PaperRail-v0`` through ``gym.make`` (constant action; an episode is 100 000
  steps) and unwrapped;
* the native vector env (``vectorization_mode="vector_entry_point"``) at N = 64 and
  N = 1024 (and at N = 1024 with ``threads=2``), and Gymnasium's ``SyncVectorEnv`` at
  N = 64 for comparison, in env-steps per second. Timed windows always include
  simulator chunk generation (at least two chunk rounds); ``score=False`` (no episode
  record: scoring costs memory, not step time);
* the same at N = 1024 with the IMU error model's NumPy path (the compiled white-noise
  pass of :mod:`navsim.sensors.imu.kernel` switched off: the state before it);
* the floor of the sensor model: drawing, for N = 1024 members with their own
  generators, only the standard normals one env-step needs (6 (R + 2) = 36 per IMU
  sample, plus the GNSS and outage blocks of one epoch per ``steps_per_epoch`` steps),
  with nothing else computed, into buffers allocated and written once before the timed
  draws (a fresh 75 MB array per window would time page faults too). No implementation
  that keeps each member's numbers equal to its single env (its own PCG64 stream, the
  exact noise model) can step faster than this on one core with NumPy's draws; the
  simulator draws through a compiled loop when numba is installed (the same numbers,
  :mod:`navsim.sensors.imu.kernel`), and the last row times those draws alone, the
  limit of that path (the vector env can exceed the NumPy floor);

Timing: interleaved windows (one window of every row per round, all envs built first),
the median of ``--rounds`` windows per row; the machine's
load average is printed (the machine may be shared). The vector envs and the floor are
also given per CPU second of this process (``time.process_time``, all threads), the
figure to compare with the floor on a loaded machine; with ``threads=2`` CPU time
counts both threads, so its speed-up is read from the wall-clock column.

Usage: ``python benchmarks/bench_env.py [--rounds 3] [--quick]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import gymnasium as gym
import navsim.envs  # noqa: F401  (registers the ids)
import numpy as np

from navsim.sensors.imu import apply as imu_apply
from navsim.sensors.imu import kernel as _imu_kernel


def _single_rate(env, action, seconds: float) -> float:
    step = env.step
    n = 0
    t0 = time.perf_counter()
    deadline = t0 + seconds
    while True:
        for _ in range(1000):
            _, _, term, trunc, _ = step(action)
            if term or trunc:
                env.reset()
        n += 1000
        now = time.perf_counter()
        if now >= deadline:
            return n / (now - t0)


def _vector_rate(venv, steps: int) -> tuple[float, float]:
    """(member-steps per CPU second of this process, per wall second)."""
    n = venv.num_envs
    action = np.zeros((n, 9))
    c0, t0 = time.process_time(), time.perf_counter()
    for _ in range(steps):
        venv.step(action)
    return steps * n / (time.process_time() - c0), steps * n / (time.perf_counter() - t0)


def _draw_floor(n: int, steps: int, compiled: bool = False):
    """Member-steps per CPU second of drawing only the normals and uniforms of the paper
    scenario's sensors, for ``n`` members with their own generators, into buffers that are
    allocated and written once before timing (so no page faults are timed), one window per
    round (the returned function times one window). ``compiled``: through the compiled group draws the simulator uses with numba
    (:func:`navsim.sensors.imu.kernel.draws`, the same numbers) instead of NumPy's fills."""
    from navsim.scenario import load_scenario
    from navsim.simulator import Simulator

    sim = Simulator(load_scenario("paper-2012"))
    timing, orders, m = sim.timing, sim.scenario.imu.orders, len(sim.constellation.prn)
    rngs = [np.random.Generator(np.random.PCG64(j)) for j in range(n)]
    imu = np.empty((n, steps * timing.samples_per_step, 6 * (orders + 2)))
    epochs = max(1, steps // timing.steps_per_epoch)
    gnss, outages = np.empty((n, epochs, 2 + 3 * m)), np.empty((n, epochs, 1 + m))

    def draw():
        for j, rng in enumerate(rngs):
            rng.standard_normal(out=imu[j])
            rng.standard_normal(out=gnss[j])
            rng.random(out=outages[j])

    if compiled:
        normal, uniform = _imu_kernel.draws("normal"), _imu_kernel.draws("uniform")

        def draw():
            normal(rngs, imu)
            normal(rngs, gnss)
            uniform(rngs, outages)

    draw()  # touch every page

    def window() -> float:
        t0 = time.process_time()
        draw()
        return n * steps / (time.process_time() - t0)

    return window


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=2.0, help="length of a single-env window")
    parser.add_argument("--quick", action="store_true", help="one round, short windows, N = 64 only")
    args = parser.parse_args()
    rounds = 1 if args.quick else args.rounds
    seconds = 0.5 if args.quick else args.seconds

    cart = gym.make("CartPole-v1")
    cart.reset(seed=0)
    nav = gym.make("navsim/PaperRail-v0", score=False)
    nav.reset(seed=0)
    raw = gym.make("navsim/PaperRail-v0", score=False).unwrapped
    raw.reset(seed=0)
    zero = np.zeros(9)
    rates: dict[str, list[float]] = {"CartPole-v1 (gym.make)": [], "navsim/PaperRail-v0 (gym.make)": [],
                                     "navsim/PaperRail-v0 (unwrapped)": []}
    for _ in range(rounds):
        rates["CartPole-v1 (gym.make)"].append(_single_rate(cart, 0, seconds))
        rates["navsim/PaperRail-v0 (gym.make)"].append(_single_rate(nav, zero, seconds))
        rates["navsim/PaperRail-v0 (unwrapped)"].append(_single_rate(raw, zero, seconds))
    cart.close(), nav.close(), raw.close()
    single = statistics.median(rates["navsim/PaperRail-v0 (gym.make)"])
    cartpole = statistics.median(rates["CartPole-v1 (gym.make)"])

    vector_rows = [("native vector env, N = 64", 64, "vector_entry_point", 1),
                   ("SyncVectorEnv, N = 64", 64, "sync", 1)]
    if not args.quick:
        vector_rows.append(("native vector env, N = 1024", 1024, "vector_entry_point", 1))
        vector_rows.append(("native vector env, N = 1024, 2 threads", 1024, "vector_entry_point", 2))
        vector_rows.append(("native vector env, N = 1024, NumPy IMU path (no numba)", 1024, "vector_entry_point", 1))
    cpu: dict[str, list[float]] = {}
    envs = {}
    for label, n, mode, threads in vector_rows:
        extra = {"threads": threads} if mode == "vector_entry_point" else {}
        venv = gym.make_vec("navsim/PaperRail-v0", num_envs=n, vectorization_mode=mode, score=False, **extra)
        venv.reset(seed=0)
        chunk = getattr(venv.unwrapped, "chunk_steps", 4000)
        steps = 2 * chunk + 10 if not args.quick else chunk + 10
        if mode == "sync":
            steps = min(steps, 3000)
        envs[label] = (venv, steps)
        rates[label], cpu[label] = [], []
    floor_label = "floor: the draws alone, N = 1024 (reused buffers)"
    compiled_label = "the same draws through the compiled group draws (numba), N = 1024"
    floors = {floor_label: _draw_floor(1024, 256)}
    if _imu_kernel.available():
        floors[compiled_label] = _draw_floor(1024, 256, compiled=True)
    for _ in range(rounds):  # interleaved: one window of every row per round
        for label, (venv, steps) in envs.items():
            imu_apply.USE_KERNEL = "NumPy IMU path" not in label
            c, w = _vector_rate(venv, steps)
            rates[label].append(w)
            cpu[label].append(c)
        imu_apply.USE_KERNEL = True
        for label, window in floors.items():
            cpu.setdefault(label, []).append(window())
    for venv, _ in envs.values():
        venv.close()
    floor = cpu[floor_label]

    kernel = "compiled (numba)" if _imu_kernel.available() else "NumPy (numba not installed)"
    print(f"IMU white-noise pass: {kernel}. Load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores (the machine may be shared); median of "
          f"{rounds} window(s). Single envs: steps per wall second. Vector envs: member-steps per wall second, "
          "and per CPU second of this process (all its threads) beside the draw floor, which is CPU time on one "
          "core.\n")
    print("| env | steps/s (wall) | x CartPole | x single env | per CPU s | x floor (CPU) |")
    print("|---|---:|---:|---:|---:|---:|")
    floor_cpu = statistics.median(floor)
    for label in [*rates, *floors]:
        c = statistics.median(cpu[label]) if label in cpu else None
        cols = f"| {c:,.0f} | {c / floor_cpu:.2f} |" if c is not None else "| | |"
        if label in rates:
            rate = statistics.median(rates[label])
            print(f"| {label} | {rate:,.0f} | {rate / cartpole:.2f} | {rate / single:.2f} {cols}")
        else:
            print(f"| {label} | | | {cols}")
    if not args.quick:
        one, two = (statistics.median(rates[f"native vector env, N = 1024{x}"]) for x in ("", ", 2 threads"))
        print(f"\nthreads=2 / one thread at N = 1024 (wall): {two / one:.2f} (goal 1.7 on 2 idle cores; the load "
              "average above says how idle they were)")


if __name__ == "__main__":
    main()
