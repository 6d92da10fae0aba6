"""The native vector environment: N navigation episodes stepped in one NumPy pass.

``gym.make_vec("navsim/PaperRail-v0", num_envs=N, vectorization_mode="vector_entry_point")``
builds :class:`NavigationVectorEnv`. Sub-environment j is the single
:class:`~navsim.envs.navigation.NavigationEnv` with seed ``seed + j`` (Gymnasium's
convention for vector resets): the same observations, rewards and scores, bit for bit.

How it is fast
    * One simulator is built; the other N - 1 are shallow copies sharing the immutable
      parts (track, constellation, sensor models, truth generator); each has its own
      random streams and sensor states, set by its ``reset``.
    * All episodes of a scenario have the same length and time base, so the N episodes
      run in lockstep: every ``chunk_steps`` steps each simulator generates a chunk and
      the chunks are stacked into (steps, N, ...) arrays; GNSS epochs fall at the same
      steps for all N.
    * The truth generator's output (ideal IMU increments and the true state, a
      deterministic function of the scenario and the time) is computed once per chunk
      and served to all N simulators (:class:`SharedTruth`): only the sensor errors
      differ between sub-environments.
    * Each step serves views of the stacked arrays and computes the N rewards in one
      vectorised expression.

Limits
    Autoreset mode NEXT_STEP (Gymnasium's default); resets are of all sub-environments
    at once (a partial ``reset_mask`` is refused: the lockstep needs it). Scripted motion
    only (the driving task, with external motion, is not vectorised natively; use
    ``"sync"`` or ``"async"``). With ``score=True`` the actions of the whole episode are
    kept for scoring: 72 bytes per step and sub-environment.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from navsim.errors import ConfigError
from navsim.scenario import Scenario

from .chunks import EpisodeTape, prepare_chunk
from .navigation import resolve_scenario, wrap_array
from .spaces import ACTION_SCALE, action_space, observation_space

__all__ = ["NavigationVectorEnv", "SharedTruth"]


class SharedTruth:
    """A truth generator shared by simulators stepping in lockstep.

    ``samples(i0, n)`` of the wrapped :class:`navsim.truthgen.TruthGenerator` is a pure
    function of the scenario and the sample range; the last result is kept and handed to
    every simulator asking for the same range. ``_cache.clear()`` (what
    :meth:`Simulator.reset` calls) clears the wrapped generator's block cache too.
    """

    class _Cache(dict):
        def __init__(self, owner):
            super().__init__()
            self.owner = owner

        def clear(self):
            self.owner.inner._cache.clear()
            self.owner._key = None
            self.owner._value = None

    def __init__(self, inner):
        self.inner = inner
        self._cache = SharedTruth._Cache(self)
        self._key = None
        self._value = None
        self.hits = 0

    def samples(self, i0: int, n: int):
        key = (int(i0), int(n))
        if key != self._key:
            self._value = self.inner.samples(i0, n)
            self._key = key
        else:
            self.hits += 1
        return self._value

    def __getattr__(self, name):
        return getattr(self.inner, name)


def _default_chunk(num_envs: int) -> int:
    """Steps per chunk: about 2^19 env-steps buffered (about 300 MB), within [100, 4000]."""
    return int(min(4000, max(100, 2**19 // max(num_envs, 1))))


class NavigationVectorEnv(gym.vector.VectorEnv):
    """N navigation episodes of one scenario in one NumPy pass (see the module docstring).

    Parameters are those of :class:`~navsim.envs.navigation.NavigationEnv` plus
    ``num_envs``; ``chunk_steps`` defaults to about 2^19 / N (memory bound), and
    ``share_truth`` (default True) switches the shared truth generator.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": [], "render_fps": 20}

    def __init__(self, num_envs: int = 1, scenario: str | Scenario = "paper-2012", *, render_mode: str | None = None,
                 truth_in_info: bool = False, reward_weights=(1.0, 0.0, 0.0), reward_cap: float = 1e4,
                 score: bool = True, chunk_steps: int | None = None, physical_action: bool = False,
                 share_truth: bool = True, max_episode_steps: int | None = None, **overrides: Any) -> None:
        from navsim.episode import make_context
        from navsim.motion import ExternalMotion
        from navsim.simulator import Simulator

        if int(num_envs) != num_envs or num_envs < 1:
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
        self.num_envs = int(num_envs)
        self.scenario = resolve_scenario(scenario, overrides)
        base = Simulator(self.scenario)
        if isinstance(base.profile, ExternalMotion):
            raise ConfigError("motion.profile", "scripted motion for the native vector env", "external")
        if share_truth:
            base.truthgen = SharedTruth(base.truthgen)
        self.sims = [base] + [copy.copy(base) for _ in range(self.num_envs - 1)]
        self.context = make_context(base)
        self.prn = np.asarray(base.constellation.prn)
        self.truth_in_info = bool(truth_in_info)
        self.reward_weights = weights
        self.reward_cap = float(reward_cap)
        self.score = bool(score)
        self.chunk_steps = int(chunk_steps) if chunk_steps is not None else _default_chunk(self.num_envs)
        if self.chunk_steps < 1:
            raise ConfigError("chunk_steps", "a positive integer", chunk_steps)
        self.physical_action = bool(physical_action)
        self.action_scale = np.ones(9) if self.physical_action else ACTION_SCALE.copy()
        timing = self.scenario.timing
        self.n_steps = timing.steps
        self.n_sats = len(self.prn)
        self.single_observation_space = observation_space(timing, self.scenario.imu.orders, self.n_sats)
        self.single_action_space = action_space(self.physical_action)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.render_mode = None
        self._config = {"scenario": self.scenario.name, "config_hash": self.scenario.config_hash(),
                        "scenario_toml": self.scenario.to_toml()}
        self._k = -1
        self._autoreset = False
        self._rngs = None
        self.tapes: list[EpisodeTape] | None = None
        self.closed = False

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | list | None = None, options: dict | None = None):
        """Reset all sub-environments; ``seed`` int s gives sub-env j the seed s + j."""
        if options and "reset_mask" in options and not np.all(options["reset_mask"]):
            raise ConfigError("options.reset_mask", "all True (the native vector env resets all at once)",
                              options["reset_mask"])
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

    def _reset_all(self, seeds: list):
        # as NavigationEnv.reset: a missing seed is drawn from the sub-env's generator
        self.seeds = [int(s) if s is not None else int(rng.integers(0, 2**63 - 1)) for s, rng in zip(seeds, self._rngs)]
        self.priors = [sim.reset(s).prior for sim, s in zip(self.sims, self.seeds)]
        self._k = 0
        self._autoreset = False
        self.tapes = [EpisodeTape(self.n_steps) for _ in range(self.num_envs)] if self.score else None
        self._held = [(False, 0)] * self.num_envs
        self._load_chunk()
        n = self.num_envs
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

    def _load_chunk(self) -> None:
        n_env, C = self.num_envs, self.chunk_steps
        parts = []
        for j, sim in enumerate(self.sims):
            pc = prepare_chunk(sim.advance(C), sim.earth, self.n_sats, *self._held[j], rows=False,
                               per_step_gnss=False)
            self._held[j] = (pc.last_outage, pc.last_n_valid)
            if self.tapes is not None:
                self.tapes[j].add_chunk(pc)
            parts.append(pc)
        first = parts[0]
        c = first.n

        def stack(name):
            return np.stack([getattr(p, name) for p in parts], axis=1)

        self._t = np.repeat(first.t[:, None, :], n_env, axis=1)
        self._dtheta_r, self._dv_r = stack("dtheta_r"), stack("dv_r")
        self._dtheta_sub, self._dv_sub = stack("dtheta_sub"), stack("dv_sub")
        self._truth = stack("truth")
        self._new_epoch = stack("new_epoch")
        self._outage = np.stack([np.asarray(p.receiver_outage, dtype=bool) for p in parts], axis=1)
        self._n_valid = np.stack([np.asarray(p.n_valid, dtype=np.int64) for p in parts], axis=1)
        self._ones = np.ones((c, n_env), dtype=bool)
        self._epoch_at = first.epoch_at
        if first.valid is not None:
            self._valid = stack("valid")
            self._pr, self._prr = stack("pseudorange_m"), stack("pseudorange_rate_mps")
            self._sat_pos, self._sat_vel = stack("sat_pos_e"), stack("sat_vel_e")
        self._c = c
        self._i = 0
        if self.tapes is not None:
            self._actions = np.empty((c, n_env, 9))

    def _obs(self, i: int) -> dict:
        j = self._epoch_at[i]
        n, k = self.num_envs, self.n_sats
        if j < 0:
            gnss = {"gnss_valid": np.zeros((n, k), dtype=np.int8), "pseudorange_m": np.zeros((n, k)),
                    "pseudorange_rate_mps": np.zeros((n, k)), "sat_pos_e": np.zeros((n, 3 * k)),
                    "sat_vel_e": np.zeros((n, 3 * k))}
        else:
            gnss = {"gnss_valid": self._valid[j], "pseudorange_m": self._pr[j], "pseudorange_rate_mps": self._prr[j],
                    "sat_pos_e": self._sat_pos[j], "sat_vel_e": self._sat_vel[j]}
        return {"t": self._t[i], "dtheta_r": self._dtheta_r[i], "dv_r": self._dv_r[i], "dtheta_sub": self._dtheta_sub[i],
                "dv_sub": self._dv_sub[i], "gnss_new_epoch": self._new_epoch[i], **gnss}

    def _step_info(self, i: int) -> dict:
        info = {"receiver_outage": self._outage[i], "_receiver_outage": self._ones[i],
                "gnss_n_valid": self._n_valid[i], "_gnss_n_valid": self._ones[i]}
        if self.truth_in_info:
            info["truth"] = self._truth[i, :, :9].copy()
            info["_truth"] = self._ones[i]
        return info

    # ------------------------------------------------------------------ step
    def step(self, actions):
        """Score the N solutions of the last observed step and serve the next step."""
        n = self.num_envs
        if self._k < 0:
            raise RuntimeError("NavigationVectorEnv.step: call reset() first")
        if self._autoreset:
            obs, info = self._reset_all([None] * n)
            return obs, np.zeros(n), np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), info
        a = np.asarray(actions, dtype=np.float64)
        if a.shape != (n, 9):
            raise ConfigError("actions", f"an array of shape ({n}, 9)", a.shape)
        i = self._i
        row = self._truth[i]
        sc = self.action_scale
        d_lon = a[:, 1] * sc[1] - row[:, 1]
        d_lon = wrap_array(d_lon)  # as the single env: the same rounding
        de = d_lon * row[:, 10]
        dn = (a[:, 0] * sc[0] - row[:, 0]) * row[:, 9]
        du = a[:, 2] * sc[2] - row[:, 2]
        w_pos, w_vel, w_att = self.reward_weights
        e = w_pos * np.sqrt(de * de + dn * dn + du * du)
        if w_vel:
            d = a[:, 3:6] * sc[3:6] - row[:, 3:6]
            e = e + w_vel * np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
        if w_att:
            d = wrap_array(a[:, 6:9] * sc[6:9] - row[:, 6:9])
            e = e + w_att * np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
        reward = -np.where(e < self.reward_cap, e, self.reward_cap)
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

    def _flush_actions(self, used: int) -> None:
        if self.tapes is None:
            return
        block = self._actions[:used]
        for j, tape in enumerate(self.tapes):
            tape.actions.extend(block[:, j].tolist())

    def _terminal_obs(self) -> dict:
        n = self.num_envs
        sp = self.single_observation_space
        obs = {key: np.zeros((n, *sp[key].shape), dtype=sp[key].dtype) for key in sp}
        obs["t"][:] = self.scenario.timing.duration_s
        return obs

    def _score(self, j: int):
        from navsim.metrics import score_episode

        record = self.tapes[j].record(self.scenario, self.seeds[j], self._agent, self.sims[j].earth, self.priors[j],
                                      self.action_scale)
        return score_episode(record, track=self.sims[j].track)

    def close_extras(self, **kwargs) -> None:
        self.sims = []
        self.tapes = None
