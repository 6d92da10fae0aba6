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
  pass of :mod:`navsim.sensors.imu.kernel` switched off: the state before it) and the
  rewards by NumPy (``navsim.envs.vector.USE_KERNEL`` off): no compiled code;
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

Timing: interleaved windows (one window of every row per round, all envs built first and
stepped through two chunks before the first window, so that both output buffer sets are
written), the median of ``--rounds`` windows per row; the machine's load average is
printed (the machine may be shared). A vector env's window is a whole number of chunks
and starts at a chunk's first step, so it holds the generation of as many chunks as it
serves (with ``threads=2`` the next chunk is generated ahead while the current one is
served: a window must not end with a chunk half generated). The vector envs and the floor
are also given per CPU second of this process (``time.process_time``, all threads), the
figure to compare with the floor on a loaded machine; with ``threads=2`` CPU time counts
every thread, so its speed-up is read from the wall-clock column. Beside the wall-clock
ratio of ``threads=2`` to one thread the benchmark prints

* the parallel efficiency E = (one thread's CPU time per member-step) / (2 x the two
  threads' wall time per member-step): 1 when the two cores do the one-thread work in
  half the time, less sensitive to other processes than the wall-clock ratio (the
  reference is CPU time);
* the serial fraction f = 1 / E - 1 (the Karp-Flatt metric for 2 processors: the
  speed-up S = 2 E is that of Amdahl's law with a fraction f that does not run in
  parallel, S = 1 / (f + (1 - f) / 2));
* the CPU cost of the second thread: CPU time per member-step with two threads over one
  (thread hand-offs, shared caches and memory bandwidth, the GIL);
* the calling thread's share of the CPU time with two threads (``time.thread_time``: the
  steps themselves, the rest runs on the chunk and IMU threads).

The goal of issue 13 (``threads=2`` at least 1.7 times one thread on two idle cores) is E
>= 0.85, i.e. f <= 0.18, when the two threads cost no more CPU than one. Where the two
threads' time goes in those windows is printed next (per chunk, through wrappers around
the env's chunk generation and loading): the chunk thread's CPU time and the calling
thread's as shares of the wall time, and the calling thread's time off CPU split into its
wait for the end of the next chunk and the rest (waiting for the GIL, or its core given
to another process or by the hypervisor: this benchmark cannot tell those apart).

The machine's own ceiling (with numba): the compiled group draws alone, N = 1024 members
on one thread against two threads drawing 512 members each at the same time (no Python
between, nothing shared but the cores, caches and memory), in interleaved windows; its
wall-clock ratio is the most two threads can give on this machine for work of this kind,
and its CPU ratio what the second thread costs by itself. The vector env's threads=2 / 1
is printed beside it as a fraction of that ceiling.

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
from navsim.envs import vector as _vector

from navsim.sensors.imu import apply as imu_apply
from navsim.sensors.imu import kernel as _imu_kernel


def _use_kernels(on: bool) -> None:
    """The compiled IMU pass and the vector env's compiled rewards on or off (the row
    without numba)."""
    imu_apply.USE_KERNEL = _vector.USE_KERNEL = on


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


def _vector_rate(venv, steps: int) -> tuple[float, float, float]:
    """(member-steps per CPU second of this process, per wall second, per CPU second of
    the calling thread)."""
    n = venv.num_envs
    action = np.zeros((n, 9))
    c0, t0, m0 = time.process_time(), time.perf_counter(), time.thread_time()
    for _ in range(steps):
        venv.step(action)
    return (steps * n / (time.process_time() - c0), steps * n / (time.perf_counter() - t0),
            steps * n / (time.thread_time() - m0))


class _ThreadClock:
    """Where the two threads of a ``threads=2`` vector env spend a window: instance-level
    wrappers (per chunk, not per step) around the env's chunk generation (run on the chunk
    thread) and its chunk loading (the calling thread, which runs queued IMU groups and
    then waits for the chunk there). Sums of wall and thread CPU seconds; a chunk counts
    when its generation ends, so the chunk thread's sum is that of the timed windows to
    within one chunk (of four per window)."""

    def __init__(self, env) -> None:
        self.chunk_cpu = self.load_wall = self.load_cpu = 0.0
        make, load = env._make_chunk, env._load_chunk

        def make_chunk():
            c0 = time.thread_time()
            try:
                return make()
            finally:
                self.chunk_cpu += time.thread_time() - c0

        def load_chunk():
            t0, c0 = time.perf_counter(), time.thread_time()
            try:
                return load()
            finally:
                self.load_wall += time.perf_counter() - t0
                self.load_cpu += time.thread_time() - c0

        env._make_chunk, env._load_chunk = make_chunk, load_chunk


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


def _draw_ceiling(n: int, steps: int):
    """The compiled group draws of :func:`_draw_floor` (the IMU block only) for ``n``
    members: one window on this thread, or two threads drawing ``n / 2`` members each at
    once. Returns a function timing one window: (wall s, CPU s of the process)."""
    from concurrent.futures import ThreadPoolExecutor

    from navsim.scenario import load_scenario
    from navsim.simulator import Simulator

    sim = Simulator(load_scenario("paper-2012"))
    timing, orders = sim.timing, sim.scenario.imu.orders
    rngs = [np.random.Generator(np.random.PCG64(j)) for j in range(n)]
    imu = np.empty((n, steps * timing.samples_per_step, 6 * (orders + 2)))
    normal = _imu_kernel.draws("normal")
    half = n // 2
    pool = ThreadPoolExecutor(2, thread_name_prefix="bench-ceiling")
    normal(rngs, imu)  # touch every page (and compile)

    def window(threads: int) -> tuple[float, float]:
        c0, t0 = time.process_time(), time.perf_counter()
        if threads == 1:
            normal(rngs, imu)
        else:
            parts = [pool.submit(normal, rngs[:half], imu[:half]), pool.submit(normal, rngs[half:], imu[half:])]
            for part in parts:
                part.result()
        return time.perf_counter() - t0, time.process_time() - c0

    window.close = pool.shutdown  # type: ignore[attr-defined]
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
    main_cpu: dict[str, list[float]] = {}
    envs = {}
    for label, n, mode, threads in vector_rows:
        extra = {"threads": threads} if mode == "vector_entry_point" else {}
        venv = gym.make_vec("navsim/PaperRail-v0", num_envs=n, vectorization_mode=mode, score=False, **extra)
        venv.reset(seed=0)
        chunk = getattr(venv.unwrapped, "chunk_steps", 4000)
        # whole chunks from a chunk's first step: 4 at N = 1024 (256 steps each), 2 at N = 64
        steps = (4 if n >= 1024 else 2) * chunk if not args.quick else chunk
        if mode == "sync":
            steps = min(steps, 3000)
        _use_kernels("NumPy IMU path" not in label)
        for _ in range(2 * chunk if mode == "vector_entry_point" else 0):  # warm-up: both buffer sets written
            venv.step(np.zeros((n, 9)))
        _use_kernels(True)
        if threads == 2:
            clock = _ThreadClock(venv.unwrapped)  # installed after the warm-up: timed windows only
        envs[label] = (venv, steps)
        rates[label], cpu[label], main_cpu[label] = [], [], []
    floor_label = "floor: the draws alone, N = 1024 (reused buffers)"
    compiled_label = "the same draws through the compiled group draws (numba), N = 1024"
    floors = {floor_label: _draw_floor(1024, 256)}
    if _imu_kernel.available():
        floors[compiled_label] = _draw_floor(1024, 256, compiled=True)
    ceiling = _draw_ceiling(1024, 256) if _imu_kernel.available() and not args.quick else None
    ceiling_times: dict[int, list[tuple[float, float]]] = {1: [], 2: []}
    for _ in range(rounds):  # interleaved: one window of every row per round
        if ceiling is not None:
            for threads in (1, 2, 1, 2):  # two windows each (short ones)
                ceiling_times[threads].append(ceiling(threads))
        for label, (venv, steps) in envs.items():
            _use_kernels("NumPy IMU path" not in label)
            c, w, m = _vector_rate(venv, steps)
            rates[label].append(w)
            cpu[label].append(c)
            main_cpu[label].append(m)
        _use_kernels(True)
        for label, window in floors.items():
            cpu.setdefault(label, []).append(window())
    for venv, _ in envs.values():
        venv.close()
    floor = cpu[floor_label]

    kernel = "compiled (numba)" if _imu_kernel.available() else "NumPy (numba not installed)"
    print(f"IMU white-noise pass: {kernel}. Load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores "
          f"(the machine may be shared); median of "
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
        one_label, two_label = "native vector env, N = 1024", "native vector env, N = 1024, 2 threads"
        one, two = (statistics.median(rates[x]) for x in (one_label, two_label))
        one_cpu, two_cpu = (statistics.median(cpu[x]) for x in (one_label, two_label))
        efficiency = two / (2.0 * one_cpu)  # (1-thread CPU s per member-step) / (2 x 2-thread wall s per member-step)
        two_main = statistics.median(main_cpu[two_label])
        print(f"\nthreads=2 / one thread at N = 1024 (wall): {two / one:.2f} (goal 1.7 on 2 idle cores; the load "
              f"average above says how idle they were); parallel efficiency E = (one thread's CPU time) / (2 x two "
              f"threads' wall time) per member-step: {efficiency:.2f} (goal 0.85); serial fraction 1/E - 1: "
              f"{1.0 / efficiency - 1.0:.2f}; CPU time per member-step, two threads / one: {one_cpu / two_cpu:.2f}; "
              f"the calling thread's share of the two threads' CPU time: {two_cpu / two_main:.2f}")
        # the windows' wall and calling-thread CPU seconds in all, from their rates
        member_steps = envs[two_label][1] * envs[two_label][0].num_envs
        wall = sum(member_steps / r for r in rates[two_label])
        main = sum(member_steps / r for r in main_cpu[two_label])
        waiting = (clock.load_wall - clock.load_cpu) / wall
        print(f"\nThe two threads in those windows ({wall:.2f} s of wall time in all): the chunk thread on CPU "
              f"{clock.chunk_cpu / wall:.0%} of the wall time (generating the next chunk, with the IMU groups it "
              f"takes); the calling thread on CPU {main / wall:.0%} (its steps, and the IMU groups it takes while "
              f"it waits for the chunk), off CPU {waiting:.0%} waiting for the chunk's end and "
              f"{1.0 - main / wall - waiting:.0%} at other times (the GIL, other processes, the hypervisor)")
        if ceiling is not None:
            ceiling.close()  # type: ignore[attr-defined]
            wall1, wall2 = (statistics.median(w for w, _ in ceiling_times[t]) for t in (1, 2))
            cpu1, cpu2 = (statistics.median(c for _, c in ceiling_times[t]) for t in (1, 2))
            print(f"\nMachine ceiling (the compiled draws alone, N = 1024 on one thread against 2 x 512 at once, "
                  f"{len(ceiling_times[1])} interleaved windows each): two threads / one {wall1 / wall2:.2f} in wall "
                  f"time, CPU two / one {cpu2 / cpu1:.2f}; the vector env's threads=2 / 1 is "
                  f"{(two / one) / (wall1 / wall2):.2f} of that ceiling")


if __name__ == "__main__":
    main()
