"""The native vector environment: N navigation episodes stepped in one NumPy pass.

``gym.make_vec("navsim/PaperRail-v0", num_envs=N, vectorization_mode="vector_entry_point")``
builds :class:`NavigationVectorEnv`. Sub-environment j is the single
:class:`~navsim.envs.navigation.NavigationEnv` with seed ``seed + j`` (Gymnasium's
convention for vector resets): the same observations, rewards and scores, bit for bit.

How it is fast
    * The N episodes are the members of one :class:`navsim.simulator.SimulatorBatch`:
      all episodes of a scenario have the same length and time base and, with scripted
      motion, the same truth, so they run in lockstep. The truth (ideal IMU increments
      and the true state), the satellite geometry and the deterministic outage masks are
      computed once per chunk of ``chunk_steps`` steps; the sensor errors of the N
      members in one vectorised pass, each from its own random streams.
    * Each step serves views of the chunk's (N, steps, ...) arrays and computes the N
      rewards against the shared truth row: in one compiled loop when numba is installed
      (:func:`rewards_into`, the single env's operations member by member; it runs
      without the GIL, so a thread generating the next chunk is not held up by it), else
      in one vectorised NumPy expression.

Limits
    Autoreset mode NEXT_STEP (Gymnasium's default); resets are of all sub-environments
    at once (a partial ``reset_mask`` is refused: the lockstep needs it). Scripted motion
    only (the driving task, with external motion, is not vectorised natively; use
    ``"sync"`` or ``"async"``). With ``score=True`` the actions of the whole episode are
    kept for scoring: 72 bytes per step and sub-environment (the truth record is shared);
    a warning says so when that exceeds 2 GB (pass ``score=False`` for training).

Where the time goes
    Each member draws its own standard normals (36 per IMU sample of the paper scenario:
    4 orders of white-noise integrals plus two bias drives, 2 sensors x 3 axes), exactly
    as its single env does. With numba installed the draws of a group of members run in
    one compiled loop (:mod:`navsim.sensors.imu.kernel`: NumPy's ziggurat on each member's
    own bit generator, the same numbers), faster than NumPy's own fill; the chunk buffers
    are reused once no observation references them, and the members' sensor states are
    carried as arrays between chunks. ``benchmarks/bench_env.py`` prints the rate beside
    both draw limits (NumPy's fill and the compiled draws alone).

Threads
    ``threads=2`` or more: the next chunk is generated on a thread of its own (the chunk
    thread) while the steps of the current chunk are served (the chunks do not depend on
    the actions: scripted motion). The chunk thread generates the truth, then queues the
    IMU groups of the chunk (their draws and their arithmetic, one task per group of
    members), generates the GNSS, outage, odometer and barometer data, and then runs
    queued groups itself; the calling thread steps (reward, observation views, info) and,
    at the end of the chunk, runs queued groups too until the next chunk is done; with
    ``threads`` > 2, ``threads - 2`` more threads take groups from the queue. So at most
    ``threads`` threads compute (no more threads than cores asked for), none waits while
    a group is left, and the part of the work that is not split (the steps) overlaps with
    the generation instead of following it. The next chunk is started at the first step
    of the current one, when the caller holds only the current chunk's observations, so
    that it takes the output buffers of the previous chunk; a reset or ``close`` waits for
    a chunk being generated and discards it. The members' simulators (:attr:`sims`) are
    then one chunk ahead of the served step. Every member's numbers are those of
    ``threads=1`` (each group has its own members' streams and states).
"""

from __future__ import annotations

import collections
import math
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TYPE_CHECKING, Any, Sequence

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space
from numpy.typing import ArrayLike

from navsim.errors import ConfigError
from navsim.jit import available
from navsim.naverror import wrap_angle
from navsim.scenario import Scenario
from navsim.signals import Layout, ObservationCodec

from .chunks import EpisodeTape, chunk_truth_table, held_flags
from .navigation import resolve_scenario
from .spaces import ACTION_SCALE, action_space, check_action, layout_space

if TYPE_CHECKING:  # type hints only
    from navsim.metrics import EpisodeScore

__all__ = ["NavigationVectorEnv", "rewards_into", "USE_KERNEL"]

USE_KERNEL = True
"""Rewards by the compiled loop (:func:`rewards_into`) when numba is installed; False: the
NumPy expression (the same numbers up to the arctangent's last bit, see :func:`rewards_into`)."""


def _wrap(x: float) -> float:
    """:func:`navsim.naverror.wrap_angle_scalar` in numba's subset: ``phase(exp(i x))``.

    ``1j * x`` is the complex ``(0 x - 0) + (0 + x) i``: its real part is +-0, whose
    exponential is exactly 1, and its imaginary part ``0 + x`` (-0 becomes +0); so
    ``exp(1j x) = (cos y, sin y)`` with y = 0 + x, and the phase is ``atan2(sin y, cos y)``
    with the C library's functions, as CPython's ``cmath`` computes them (nan for
    non-finite x, as ``wrap_angle_scalar``)."""
    if x - x != 0.0:
        return math.nan
    y = 0.0 + x
    return math.atan2(math.sin(y), math.cos(y))


def rewards_into(a: np.ndarray, sc: np.ndarray, row: np.ndarray, w_pos: float, w_vel: float, w_att: float,
                 cap: float, out: np.ndarray) -> None:
    """The N rewards of a step into ``out`` (N,): for member j, with ``a`` (N, 9) the
    solutions, ``sc`` (9,) the action scale and ``row`` the truth row
    (:data:`~navsim.envs.chunks.TRUTH_COLUMNS`), the operations of the single env's step
    (:meth:`~navsim.envs.navigation.NavigationEnv.step`, in its order, Python floats)::

        dE = wrap(a1 s1 - lon) (R_E + h) cos(lat),  dN = (a0 s0 - lat) (R_N + h),  dU = a2 s2 - h
        e  = w_pos sqrt(dE^2 + dN^2 + dU^2) [+ w_vel sqrt(|a_v s_v - v|^2)] [+ w_att sqrt(|wrap(a_att s_att - att)|^2)]
        r  = -e if e < cap else -cap                      (nan -> -cap)

    with ``wrap`` the principal angle of :func:`navsim.naverror.wrap_angle_scalar` (the C
    library's sin, cos and atan2, as ``cmath``). Compiled by numba (no fused
    multiply-adds: the same roundings as the Python floats), so member j's reward is its
    single env's bit for bit; the NumPy path (:func:`navsim.naverror.wrap_angle`) takes
    NumPy's arctangent, which may differ in the last bit."""
    for j in range(a.shape[0]):
        de = _wrap(a[j, 1] * sc[1] - row[1]) * row[10] * row[11]
        dn = (a[j, 0] * sc[0] - row[0]) * row[9]
        du = a[j, 2] * sc[2] - row[2]
        e = w_pos * math.sqrt(de * de + dn * dn + du * du)
        if w_vel:
            d0 = a[j, 3] * sc[3] - row[3]
            d1 = a[j, 4] * sc[4] - row[4]
            d2 = a[j, 5] * sc[5] - row[5]
            e = e + w_vel * math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if w_att:
            d0 = _wrap(a[j, 6] * sc[6] - row[6])
            d1 = _wrap(a[j, 7] * sc[7] - row[7])
            d2 = _wrap(a[j, 8] * sc[8] - row[8])
            e = e + w_att * math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        out[j] = -e if e < cap else -cap


_compiled: dict[str, Any] = {}
_compile_lock = threading.Lock()


def _rewards_kernel() -> Any:
    """:func:`rewards_into` compiled (numba, ``nogil``, cached on disk), or None without
    numba or with :data:`USE_KERNEL` off."""
    if not USE_KERNEL or not available():
        return None
    kernel = _compiled.get("rewards_into")
    if kernel is None:
        with _compile_lock:  # the calling thread and a chunk thread may get here at once
            kernel = _compiled.get("rewards_into")
            if kernel is None:
                import numba

                global _wrap
                if not isinstance(_wrap, numba.core.registry.CPUDispatcher):
                    _wrap = numba.njit(cache=True, nogil=True)(_wrap)
                kernel = numba.njit(cache=True, nogil=True)(rewards_into)
                _compiled["rewards_into"] = kernel
    return kernel


def _default_chunk(num_envs: int) -> int:
    """Steps per chunk: about 2^18 env-steps buffered (about 100 MB), within [64, 4000]."""
    return int(min(4000, max(64, 2**18 // max(num_envs, 1))))


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


class _Task:
    """One IMU group of a chunk (:func:`navsim.simulator._imu_errors`), run once by the
    thread that takes it from the queue."""

    __slots__ = ("fn", "args", "done", "error", "tasks")

    def __init__(self, tasks: _GroupTasks, fn: Any, args: tuple) -> None:
        self.tasks, self.fn, self.args = tasks, fn, args
        self.done = threading.Event()
        self.error: BaseException | None = None

    def run(self) -> None:
        try:
            self.fn(*self.args)
        except BaseException as exc:  # noqa: BLE001  (handed to the thread that waits for the chunk)
            self.error = exc
        finally:
            self.done.set()

    def result(self) -> None:
        """Run the queued groups (this one among them, if still queued), then wait for this one."""
        self.tasks.help_until(None)
        self.done.wait()
        if self.error is not None:
            raise self.error


class _GroupTasks:
    """The executor of the vector env's :class:`~navsim.simulator.SimulatorBatch` with
    ``threads`` >= 2: a queue of IMU groups run by the threads that wait for them (the
    chunk thread when it waits for its IMU pass, the calling thread when it waits for the
    chunk) and by ``extra`` threads of its own (``threads`` - 2), so that no more threads
    compute than asked for. Each group runs once, on whichever thread takes it."""

    def __init__(self, extra: int) -> None:
        self._cond = threading.Condition(threading.Lock())
        self._queue: collections.deque[_Task] = collections.deque()
        self._closed = False
        self._threads = [threading.Thread(target=self._serve, name=f"navsim-vector-imu_{k}", daemon=True)
                         for k in range(extra)]
        for thread in self._threads:
            thread.start()

    def submit(self, fn: Any, *args: Any) -> _Task:
        task = _Task(self, fn, args)
        with self._cond:
            self._queue.append(task)
            self._cond.notify()
        return task

    def help_until(self, future: Any) -> None:
        """Run queued groups until the queue is empty and (with a ``future``) the future
        is done: the calling thread waits for the chunk by working on it."""
        if future is not None:
            future.add_done_callback(lambda _: self._wake())
        while True:
            with self._cond:
                while not self._queue and future is not None and not future.done():
                    self._cond.wait()
                if not self._queue:
                    return
                task = self._queue.popleft()
            task.run()

    def _wake(self) -> None:
        with self._cond:
            self._cond.notify_all()

    def _serve(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._closed:
                    self._cond.wait()
                if self._closed:
                    return
                task = self._queue.popleft()
            task.run()

    def shutdown(self, wait: bool = True) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        if wait:
            for thread in self._threads:
                thread.join()


class NavigationVectorEnv(gym.vector.VectorEnv):
    """N navigation episodes of one scenario in one NumPy pass (see the module docstring).

    Parameters are those of :class:`~navsim.envs.navigation.NavigationEnv` plus
    ``num_envs``; ``chunk_steps`` defaults to about 2^18 / N (memory bound); ``threads``
    (default 1): 2 or more generate the next chunk ahead on a thread of its own, its IMU
    groups run by ``threads`` threads in all, the calling thread among them (module
    docstring, "Threads"; the numbers do not change).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": [], "render_fps": 20}

    def __init__(self, num_envs: int = 1, scenario: str | Scenario = "paper-2012", *, render_mode: str | None = None,
                 truth_in_info: bool = False, reward_weights: Sequence[float] = (1.0, 0.0, 0.0),
                 reward_cap: float = 1e4,
                 score: bool = True, chunk_steps: int | None = None, physical_action: bool = False,
                 max_episode_steps: int | None = None, threads: int = 1, **overrides: Any) -> None:
        from navsim.episode import make_context
        from navsim.simulator import SimulatorBatch

        if isinstance(num_envs, bool) or int(num_envs) != num_envs or num_envs < 1:
            raise ConfigError("num_envs", "a positive integer", num_envs)
        if render_mode is not None:
            raise ConfigError("render_mode", "None for the native vector env (render a single env)", render_mode)
        if max_episode_steps is not None:
            raise ConfigError("max_episode_steps", "None (an episode is the scenario's duration)", max_episode_steps)
        weights = tuple(float(w) for w in reward_weights)
        if len(weights) != 3 or not all(w >= 0.0 and math.isfinite(w) for w in weights):
            raise ConfigError("reward_weights", "three non-negative finite weights (pos, vel, att)", reward_weights)
        if not (reward_cap > 0.0 and math.isfinite(reward_cap)):
            raise ConfigError("reward_cap", "a positive finite number", reward_cap)
        if chunk_steps is not None and (int(chunk_steps) != chunk_steps or chunk_steps < 1):
            raise ConfigError("chunk_steps", "a positive integer", chunk_steps)
        self.num_envs = int(num_envs)
        self.scenario = resolve_scenario(scenario, overrides)
        if isinstance(threads, bool) or int(threads) != threads or threads < 1:
            raise ConfigError("threads", "a positive integer", threads)
        # threads >= 2: the next chunk is generated on a thread of its own while the steps
        # of the current one are served (the chunks do not depend on the actions), its
        # IMU groups run by the threads that wait for them (module docstring, "Threads")
        self._loader: ThreadPoolExecutor | None = None
        self._next: Future[tuple] | None = None  # the Future of the next chunk
        self._tasks = _GroupTasks(int(threads) - 2) if threads > 1 else None
        try:
            self.batch = SimulatorBatch(self.scenario, self.num_envs, threads=threads, executor=self._tasks)
        except BaseException:
            if self._tasks is not None:  # its own threads (threads > 2) would wait forever
                self._tasks.shutdown()
            raise
        if self._tasks is not None:
            self._loader = ThreadPoolExecutor(1, thread_name_prefix="navsim-vector-chunk")
        base = self.batch.members[0]
        self.context = make_context(base)
        self.prn = np.asarray(base.constellation.prn)
        self.truth_in_info = bool(truth_in_info)
        self.reward_weights = weights
        self.reward_cap = float(reward_cap)
        self.score = bool(score)
        self.chunk_steps = int(chunk_steps) if chunk_steps is not None else _default_chunk(self.num_envs)
        record_bytes = 72 * self.num_envs * self.scenario.timing.steps
        if self.score and record_bytes > 2e9:
            gym.logger.warn(f"NavigationVectorEnv: score=True keeps every action for the episode scores, "
                            f"{record_bytes / 1e9:.1f} GB for {self.num_envs} envs x {self.scenario.timing.steps} "
                            f"steps; pass score=False when the scores are not needed")
        self.physical_action = bool(physical_action)
        self.action_scale = np.ones(9) if self.physical_action else ACTION_SCALE.copy()
        timing = self.scenario.timing
        self.n_steps = timing.steps
        self.n_sats = len(self.prn)
        self._has_odometer = bool(self.scenario.odometer.enabled)
        self.single_observation_space: gym.spaces.Dict = layout_space(Layout.of(self.scenario, self.n_sats))  # by the Signals
        self.single_action_space = action_space(self.physical_action)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.render_mode = None
        self._config = {"scenario": self.scenario.name, "config_hash": self.scenario.config_hash(),
                        "scenario_toml": self.scenario.to_toml()}
        n = self.num_envs
        self.codec = ObservationCodec(Layout.of(self.scenario, self.n_sats), self.prn)
        self._ones = _frozen(np.ones(n, dtype=bool))
        self._falses = _frozen(np.zeros(n, dtype=bool))
        self._k = -1
        self._autoreset = False
        self._rngs: list[np.random.Generator] = []  # the sub-envs' seeding generators, set by reset()
        self.tapes: list[EpisodeTape] | None = None
        self.closed = False

    @property
    def sims(self) -> list:
        """The N member simulators (:attr:`batch` ``.members``)."""
        return self.batch.members

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | list | None = None, options: dict | None = None) -> tuple[dict[str, np.ndarray],
              dict[str, Any]]:
        """Reset all sub-environments; ``seed`` int s gives sub-env j the seed s + j."""
        if options and "reset_mask" in options and not np.all(options["reset_mask"]):
            raise ConfigError("options.reset_mask", "all True (the native vector env resets all at once)",
                              options["reset_mask"])
        seeds: list[int | None]
        if seed is None:
            seeds = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + j for j in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ConfigError("seed", f"an int or {self.num_envs} seeds", seed)
        self._rngs = [seeding.np_random(s)[0] for s in seeds]
        self._agent = str(options["agent"]) if options and "agent" in options else "agent"
        return self._reset_all(seeds)

    def _reset_all(self, seeds: list[int | None]) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        self._drain()
        # as NavigationEnv.reset: a missing seed is drawn from the sub-env's generator
        self.seeds = [int(s) if s is not None else int(rng.integers(0, 2**63 - 1)) for s, rng in zip(seeds, self._rngs)]
        self.priors = [start.prior for start in self.batch.reset(self.seeds)]
        self._k = 0
        self._autoreset = False
        self.tapes = None
        if self.score:  # one truth record shared by the members' tapes (the truth is the same)
            first = EpisodeTape(self.n_steps)
            self.tapes = [first] + [EpisodeTape(self.n_steps, truth_of=first) for _ in range(self.num_envs - 1)]
        n = self.num_envs
        self._held: tuple[np.ndarray, np.ndarray] = (np.zeros(n, dtype=bool), np.zeros(n, dtype=np.int64))
        self._load_chunk()
        info = {"context": np.array([self.context] * n, dtype=object), "prior": np.array(self.priors, dtype=object),
                "gnss_prn": np.tile(self.prn, (n, 1)), "seed": np.array(self.seeds),
                "action_scale": np.tile(self.action_scale, (n, 1))}
        for key, value in self._config.items():
            info[key] = np.array([value] * n, dtype=object)
        info.update(self._step_info(0))
        for key in list(info):
            if not key.startswith("_"):
                info["_" + key] = np.ones(n, dtype=bool)
        return self._obs(0), info

    def _make_chunk(self) -> tuple:
        """The next chunk and what its steps serve: the shared truth rows, the observation
        views, the held outage flags and satellite counts. On the chunk thread with
        ``threads`` >= 2 (one chunk at a time, in order: the held flags carry over)."""
        n_env = self.num_envs
        chunk = self.batch.advance(self.chunk_steps)
        truth, epoch_at = chunk_truth_table(chunk, self.batch.members[0].earth)  # (c, 12) shared by the members
        obs = self.codec.encode_batch_chunk(chunk)  # step i -> dict of (N, ...) views
        g = chunk.gnss
        n_valid_epoch = g.valid.sum(axis=2) if g is not None else np.zeros((n_env, 0), dtype=np.int64)
        outage, n_valid = held_flags(epoch_at, chunk.receiver_outage, n_valid_epoch, *self._held)
        self._held = (outage[:, -1].copy(), n_valid[:, -1].copy())
        return chunk, truth, obs, _frozen(outage.T), _frozen(n_valid.T)  # flags (c, N)

    def _load_chunk(self) -> None:
        if self._next is not None:  # generated ahead (threads >= 2)
            future, self._next = self._next, None
            assert self._tasks is not None
            self._tasks.help_until(future)  # run IMU groups of it until it is done
            made = future.result()
        else:
            made = self._make_chunk()
        chunk, self._truth, self._obs, self._outage, self._n_valid = made
        c = len(chunk)
        if self.tapes is not None:
            for j, tape in enumerate(self.tapes):
                tape.add_chunk(chunk.member(j))
            self._actions = np.empty((c, self.num_envs, 9))
        self._c = c
        self._i = 0

    def _step_info(self, i: int) -> dict:
        info = {"receiver_outage": self._outage[i], "_receiver_outage": self._ones,
                "gnss_n_valid": self._n_valid[i], "_gnss_n_valid": self._ones}
        if self.truth_in_info:
            info["truth"] = np.tile(self._truth[i, :9], (self.num_envs, 1))
            info["_truth"] = self._ones
        return info

    # ------------------------------------------------------------------ step
    def step(self, actions: ArrayLike) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Score the N solutions of the last observed step and serve the next step."""
        n = self.num_envs
        if self._k < 0:
            raise RuntimeError("NavigationVectorEnv.step: call reset() first")
        if self._autoreset:
            obs, info = self._reset_all([None] * n)
            return obs, np.zeros(n), np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), info
        a = check_action(actions, (n, 9), f"{n} x 9 real numbers (one solution per member, an array of shape "
                         f"({n}, 9))", name="actions")  # before any state changes; non-finite rows: -reward_cap
        i = self._i
        if i == 0 and self._loader is not None and self._next is None and not self.batch.done:
            # the first step of a chunk: the caller now holds this chunk's observations
            # only, so the next chunk can take the output buffers of the previous one
            self._next = self._loader.submit(self._make_chunk)
        row = self._truth[i]  # the truth is the same for every member
        sc = self.action_scale
        w_pos, w_vel, w_att = self.reward_weights
        kernel = _rewards_kernel()
        if kernel is not None:  # compiled, without the GIL: the single env's operations
            reward = np.empty(n)
            kernel(a, sc, row, w_pos, w_vel, w_att, self.reward_cap, reward)
        else:
            reward = self._rewards_numpy(a, row)
        if self.tapes is not None:
            self._actions[i] = a
        info = self._step_info(i)
        self._k += 1
        i += 1
        if i == self._c:
            self._flush_actions(i)
        if self._k == self.n_steps:
            if i != self._c:
                self._flush_actions(i)
            obs = self._terminal_obs()
            if self.tapes is not None:
                scores = np.empty(n, dtype=object)
                for j in range(n):
                    scores[j] = self._score(j)
                info["episode_score"] = scores
                info["_episode_score"] = np.ones(n, dtype=bool)
            self._autoreset = True
            return obs, reward, np.zeros(n, dtype=bool), np.ones(n, dtype=bool), info
        if i == self._c:
            self._load_chunk()
            i = 0
        self._i = i
        return self._obs(i), reward, np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), info

    def _rewards_numpy(self, a: np.ndarray, row: np.ndarray) -> np.ndarray:
        """The N rewards as one NumPy expression (without numba; :func:`rewards_into`)."""
        sc = self.action_scale
        w_pos, w_vel, w_att = self.reward_weights
        # the navigation error of navsim.naverror, the same operations as the single env
        de = wrap_angle(a[:, 1] * sc[1] - row[1]) * row[10] * row[11]
        dn = (a[:, 0] * sc[0] - row[0]) * row[9]
        du = a[:, 2] * sc[2] - row[2]
        e = w_pos * np.sqrt(de * de + dn * dn + du * du)
        if w_vel:
            d = a[:, 3:6] * sc[3:6] - row[3:6]
            e = e + w_vel * np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
        if w_att:
            d = wrap_angle(a[:, 6:9] * sc[6:9] - row[6:9])
            e = e + w_att * np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
        return -np.where(e < self.reward_cap, e, self.reward_cap)

    def _flush_actions(self, used: int) -> None:
        if self.tapes is None:
            return
        block = self._actions[:used]
        for j, tape in enumerate(self.tapes):
            tape.actions.extend(block[:, j].tolist())

    def _terminal_obs(self) -> dict:
        n = self.num_envs
        sp = self.single_observation_space
        obs = {key: np.zeros((n, *(space.shape or ())), dtype=space.dtype) for key, space in sp.items()}
        obs["t"][:] = self.scenario.timing.duration_s
        return obs

    def _score(self, j: int) -> EpisodeScore:
        from navsim.metrics import score_episode

        assert self.tapes is not None  # score=True

        record = self.tapes[j].record(self.scenario, self.seeds[j], self._agent, self.sims[j].earth, self.priors[j],
                                      self.action_scale)
        return score_episode(record, track=self.sims[j].track)

    def _drain(self) -> None:
        """Wait for a chunk being generated ahead (a reset or close discards it)."""
        if self._next is not None:
            future, self._next = self._next, None
            try:
                future.result()
            except Exception:  # noqa: BLE001  (its chunk is discarded, and so is its error)
                pass

    def close_extras(self, **kwargs: Any) -> None:
        self._drain()
        if self._loader is not None:
            self._loader.shutdown(wait=True)
            self._loader = None
        self.batch.close()
        self.batch.members = []
        self.tapes = None
