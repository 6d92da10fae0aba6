"""The navigation environment: one navsim scenario as a Gymnasium env.

## Description
Each step the agent receives the sensor data of one navigation step (IMU increments and
multiple integrals, and at GNSS epochs the per-channel pseudoranges, Doppler and
satellite states) and answers with its navigation solution at the end of that step.
It is the loop of :func:`navsim.episode.run_episode` turned inside out: the agent is the
estimator. The env is a translation of :class:`navsim.simulator.Simulator`; it has no
physics of its own, and truth never enters the observation.

## Observation space
A :class:`gymnasium.spaces.Dict` of float64 boxes with finite bounds; see
:mod:`navsim.envs.spaces` for the table. ``FlattenObservation`` works. With a wheel
odometer in the scenario (``odometer={"enabled": True}``) the key ``odometer_ds`` (the
distance counted over the step, m) is added.

## Action space
``Box(-1, 1, (9,))``: the solution ``[lat, lon, h, vE, vN, vU, heading, pitch, roll]``
(rad, m, m/s, rad) at the end time ``obs["t"]`` of the observation the agent last
received, divided by :data:`navsim.envs.spaces.ACTION_SCALE` (powers of two: exact;
:func:`~navsim.envs.spaces.solution_to_action` converts). ``physical_action=True`` takes
the solution in its own units instead. An
:class:`~navsim.envs.agent.EstimateAction` (an ndarray subclass, what
:class:`~navsim.envs.agent.EstimatorAgent` returns) may also carry the 9 x 9 covariance,
the NIS of an update and the agent's CPU time; they feed the episode score.

## Rewards
``r = -min(e, reward_cap)`` with the weighted error of the action against the truth at
the same time::

    e = w_pos |dr_n| + w_vel |dv_n| + w_att |(dheading, dpitch, droll)|

``dr_n = (dE, dN, dU)`` the local-level position error of
:func:`navsim.naverror.local_level_error` (the one the metrics use: ``dE = wrap(dlon)
(R_E + h) cos(lat)``, ``dN = dlat (R_N + h)``, ``dU = dh`` at the true position),
``dv_n`` in m/s, angle differences wrapped to (-pi, pi] by
:func:`navsim.naverror.wrap_angle`, in rad. Defaults ``reward_weights=(1, 0, 0)``: minus the 3-D position error in
metres. A non-finite action gets ``-reward_cap`` (default 1e4); values outside the box are
scored as they come (never clipped). An action that is not 9 real numbers (wrong shape,
bool / complex / string / object dtype) raises :class:`~navsim.errors.ConfigError` before
any state changes (:func:`navsim.envs.spaces.check_action`), so the episode goes on.

## Starting state
``reset(seed)`` resets the simulator with that seed (the same numbers as
``navsim run`` with ``--seed``); without a seed the env draws one from its own
generator. The observation is the data of the first step ``[0, dt]``.

## Episode end
After ``timing.steps`` actions the episode is *truncated* (the scenario's duration is
a time limit; nothing terminates a navigation episode). The final observation is the
empty observation at ``t = duration``.

## Info
At reset: ``context`` (:class:`navsim.estimators.base.Context`: map, Earth, time base,
nominal sensors), ``prior`` (:class:`navsim.simulator.Prior`), ``gnss_prn`` (channel
order), ``seed``, ``scenario``, ``config_hash`` and ``scenario_toml`` (the resolved
scenario). Every step: ``receiver_outage`` (bool, the latest GNSS epoch was a
whole-receiver outage) and ``gnss_n_valid`` (valid channels at the latest epoch).
``truth`` (the true state in the action layout) only with ``truth_in_info=True``. At the
episode end: ``episode_score`` (:class:`navsim.metrics.EpisodeScore`, the figures of
``navsim run``) unless ``score=False``.

## Arguments
``gym.make("navsim/PaperRail-v0", **kwargs)``: ``render_mode`` ("rgb_array", "human"),
``truth_in_info``, ``reward_weights``, ``reward_cap``, ``score``, ``chunk_steps`` (steps
generated per vectorised simulator pass) and any scenario section as an override,
e.g. ``timing={"duration_s": 60}``, ``imu={"preset": "tactical"}``,
``outages={"windows_s": [[20, 40]]}``.

## Version History
* v0: initial version.

References
----------
.. [1] Towers M. et al., Gymnasium: a standard interface for reinforcement learning
       environments, arXiv:2407.17032, 2024 (env API, spaces, vector envs).
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Any, Sequence

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike

from navsim.errors import ConfigError
from navsim.naverror import local_level_error_scalar, wrap_angle, wrap_angle_scalar
from navsim.scenario import Scenario, load_scenario
from navsim.signals import Layout, ObservationCodec

from .chunks import EpisodeTape, PreparedChunk, prepare_chunk
from .render import EnvRendering
from .spaces import ACTION_SCALE, action_space, check_action, layout_space

if TYPE_CHECKING:  # type hints only
    from navsim.metrics import EpisodeScore

    from .render import TrackRenderer

__all__ = ["NavigationEnv", "resolve_scenario", "SCENARIO_SECTIONS"]

SCENARIO_SECTIONS = tuple(f.name for f in dataclasses.fields(Scenario) if f.name != "base_dir")
"""The scenario's sections and top-level keys, read from :class:`~navsim.scenario.Scenario` (a new
sensor section is an env keyword by its declaration)."""


def resolve_scenario(scenario: str | Scenario, overrides: dict) -> Scenario:
    """A scenario by name / path / object with nested ``overrides`` merged in.

    Raises :class:`~navsim.errors.ConfigError` naming an override key that is not a
    scenario section.
    """
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    for key in overrides:
        if key not in SCENARIO_SECTIONS:
            raise ConfigError(f"env kwarg {key}", f"an env option or a scenario section {SCENARIO_SECTIONS}", key)
    return sc.with_overrides(overrides) if overrides else sc


def wrap_array(x: np.ndarray) -> np.ndarray:
    """The angle wrap of the rewards (:func:`navsim.naverror.wrap_angle`), kept by this name."""
    return wrap_angle(x)


class NavigationEnv(EnvRendering, gym.Env):
    """A navsim scenario as a Gymnasium environment (see the module docstring).

    Parameters
    ----------
    scenario : str or Scenario
        Bundled scenario name, TOML path or a Scenario object.
    render_mode : {None, "rgb_array", "human"}
    truth_in_info : bool
        Put the true state (action layout) in ``info["truth"]`` each step (for
        supervised learning; off by default).
    reward_weights : (3,) floats
        ``(w_pos, w_vel, w_att)`` of the reward (see the module docstring).
    reward_cap : float
        Largest error counted by the reward (also the penalty of a non-finite action).
    score : bool
        Record the episode and put its score in the final info.
    chunk_steps : int
        Navigation steps generated per simulator pass.
    physical_action : bool
        Take the solution in physical units (action box not normalised).
    **overrides
        Scenario sections, merged into the scenario (nested dicts).
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 100.0}  # per instance: 1 / nav_period_s

    def __init__(self, scenario: str | Scenario = "paper-2012", *, render_mode: str | None = None,
                 truth_in_info: bool = False, reward_weights: Sequence[float] = (1.0, 0.0, 0.0),
                 reward_cap: float = 1e4,
                 score: bool = True, chunk_steps: int = 10_000, physical_action: bool = False,
                 **overrides: Any) -> None:
        from navsim.episode import make_context
        from navsim.simulator import Simulator

        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError("render_mode", f"None or one of {self.metadata['render_modes']}", render_mode)
        weights = tuple(float(w) for w in reward_weights)
        if len(weights) != 3 or not all(w >= 0.0 and math.isfinite(w) for w in weights):
            raise ConfigError("reward_weights", "three non-negative finite weights (pos, vel, att)", reward_weights)
        if not (reward_cap > 0.0 and math.isfinite(reward_cap)):
            raise ConfigError("reward_cap", "a positive finite number", reward_cap)
        if int(chunk_steps) != chunk_steps or chunk_steps < 1:
            raise ConfigError("chunk_steps", "a positive integer", chunk_steps)
        self.scenario = resolve_scenario(scenario, overrides)
        self.sim = Simulator(self.scenario)
        self.context = make_context(self.sim)
        self.prn = np.asarray(self.sim.constellation.prn)
        self.render_mode = render_mode
        # frames at the real time rate: one frame per navigation step
        self.metadata = {**type(self).metadata, "render_fps": 1.0 / self.scenario.timing.nav_period_s}
        self.truth_in_info = bool(truth_in_info)
        self.reward_weights = weights
        self.reward_cap = float(reward_cap)
        self.score = bool(score)
        self.chunk_steps = int(chunk_steps)
        timing = self.scenario.timing
        self.n_steps = timing.steps
        k = len(self.prn)
        self._odometer = bool(self.scenario.odometer.enabled)
        self.observation_space = layout_space(Layout.of(self.scenario, k))  # every optional sensor by its Signal
        self.physical_action = bool(physical_action)
        self.action_space = action_space(self.physical_action)
        self.action_scale = np.ones(9) if self.physical_action else ACTION_SCALE.copy()
        self._s_lat, self._s_lon, self._s_h = (float(x) for x in self.action_scale[:3])
        self.codec = ObservationCodec(Layout.of(self.scenario, k), self.prn)
        self._config = {"scenario": self.scenario.name, "config_hash": self.scenario.config_hash(),
                        "scenario_toml": self.scenario.to_toml()}
        self._pc: PreparedChunk | None = None
        self._k = -1
        self._renderer: TrackRenderer | None = None
        self.tape: EpisodeTape | None = None
        self.last_score: EpisodeScore | None = None
        self.agent_name = "agent"

    # ------------------------------------------------------------------ episode
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start an episode. ``options={"agent": name}`` labels the episode score."""
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**63 - 1))
        self.seed_value = int(seed)
        if options and "agent" in options:
            self.agent_name = str(options["agent"])
        start = self.sim.reset(self.seed_value)
        self.prior = start.prior
        self._k = 0
        self.tape = EpisodeTape(self.n_steps) if self.score else None
        self.last_score = None
        self._load_chunk(False, 0)
        info = {"context": self.context, "prior": self.prior, "gnss_prn": self.prn.copy(), "seed": self.seed_value,
                "action_scale": self.action_scale.copy(),
                **self._config, **self._step_info(0)}
        if self._renderer is not None:
            self._renderer.reset(self)
        if self.render_mode == "human":
            self.render()
        return self._obs(0), info

    def _load_chunk(self, held_outage: bool, held_n_valid: int) -> None:
        chunk = self.sim.advance(self.chunk_steps)
        self._pc = prepare_chunk(chunk, self.sim.earth, self.codec, held_outage, held_n_valid)
        self._obs_rows = tuple(self._pc.obs.items())
        self._i = 0
        self._truth_rows = self._pc.truth_rows
        if self.tape is not None:
            self.tape.add_chunk(self._pc)

    def _obs(self, i: int) -> dict:
        return {key: rows[i] for key, rows in self._obs_rows}

    def _step_info(self, i: int) -> dict:
        pc = self._pc
        assert pc is not None  # loaded by reset
        info = {"receiver_outage": pc.receiver_outage[i], "gnss_n_valid": pc.n_valid[i]}
        if self.truth_in_info:
            info["truth"] = pc.truth[i, :9].copy()
        return info

    def step(self, action: ArrayLike) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Score the solution of the last observed step and serve the next step."""
        k = self._k
        if k < 0 or k >= self.n_steps:
            raise RuntimeError("NavigationEnv.step: call reset() first (the episode is over or not started)")
        i = self._i
        row = self._truth_rows[i]
        if type(action) is np.ndarray and action.shape == (9,) and action.dtype.kind == "f":
            a = action.tolist()
        else:
            a = self._action_list(action, k)  # checks shape and dtype before any state changes
        # reward: minus the weighted error, local-level linearisation (module docstring)
        de, dn, du = local_level_error_scalar(a[0] * self._s_lat, a[1] * self._s_lon, a[2] * self._s_h,
                                              row[0], row[1], row[2], row[9], row[10], row[11])
        w_pos, w_vel, w_att = self.reward_weights
        e = w_pos * math.sqrt(de * de + dn * dn + du * du)
        if w_vel or w_att:
            e = self._other_error(e, a, row)
        cap = self.reward_cap
        reward = -e if e < cap else -cap  # nan -> -cap
        tape = self.tape
        if tape is not None:
            tape.actions.append(a)
        pc = self._pc
        assert pc is not None  # loaded by reset (k >= 0)
        info = {"receiver_outage": pc.receiver_outage[i], "gnss_n_valid": pc.n_valid[i]}
        if self.truth_in_info:
            info["truth"] = pc.truth[i, :9].copy()
        k += 1
        self._k = k
        if k == self.n_steps:
            obs = self.codec.terminal()
            if tape is not None:
                self.last_score = self._score()
                info["episode_score"] = self.last_score
            if self.render_mode == "human":
                self.render()
            return obs, reward, False, True, info
        i += 1
        if i == pc.n:
            self._load_chunk(pc.last_outage, pc.last_n_valid)
            i = 0
        self._i = i
        if self.render_mode == "human":
            self.render()
        return self._obs(i), reward, False, False, info

    def _other_error(self, e: float, a: list, row: list) -> float:
        """Add the velocity and attitude terms to the weighted error e."""
        sc = self.action_scale
        _, w_vel, w_att = self.reward_weights
        if w_vel:
            d = [a[j] * sc[j] - row[j] for j in (3, 4, 5)]
            e = e + w_vel * math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        if w_att:
            d = [wrap_angle_scalar(a[j] * sc[j] - row[j]) for j in (6, 7, 8)]
            e = e + w_att * math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        return float(e)

    def _action_list(self, action: ArrayLike, k: int) -> list:
        """The action as 9 floats (checked first); records the extras of an EstimateAction."""
        arr = check_action(action, (9,), "9 real numbers [lat, lon, h, vE, vN, vU, heading, pitch, roll] "
                           "(an array of shape (9,))")
        if isinstance(action, np.ndarray):
            extras = getattr(action, "extras", None)
            if extras is not None and self.tape is not None:
                cov, nis, dof, cpu = extras
                if cov is not None:
                    self.tape.cov[k] = cov
                if nis is not None:
                    self.tape.nis[k] = (nis, dof)
                if cpu is not None:
                    self.tape.cpu[k] = cpu
        return arr.tolist()

    def _score(self) -> EpisodeScore:
        from navsim.metrics import score_episode

        assert self.tape is not None  # called only with score=True
        record = self.tape.record(self.scenario, self.seed_value, self.agent_name, self.sim.earth, self.prior,
                                  self.action_scale)
        self.last_record = record
        return score_episode(record, track=self.sim.track)
