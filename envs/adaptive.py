"""Adaptive filtering: the agent scales the noise of an attached estimator.

## Description
The setting of RL-tuned Kalman filters: a bundled estimator runs on the scenario's
sensor data; every ``decision_period_s`` (default one GNSS period) the agent chooses
two factors, on the process-noise PSDs (Q) and on the measurement-noise variances (R) of
the estimator, which then runs the next interval with them (one ``step_batch`` call).
The reward is minus the estimator's mean position error over the interval, so an agent
can learn to inflate Q through an outage, distrust GNSS in a canyon, and so on. The env
owns no physics: the simulator makes the data, the estimator filters it.

## Action space
``Box(-1, 1, (2,))``: ``q_scale = q0 * max_scale ** a[0]``, ``r_scale = r0 * max_scale **
a[1]`` (default ``max_scale = 10``: factors 0.1..10 around the untuned filter);
``a = (0, 0)`` is the untuned filter, whose factors ``(q0, r0) = untuned_scale`` are
applied at every reset.
Values outside [-1, 1] are clipped to it; a non-finite value, a wrong shape or a
non-real dtype raises :class:`~navsim.errors.ConfigError` before any state changes
(:func:`navsim.envs.spaces.check_action`).

## The untuned filter (default: deliberately mis-tuned)
By default ``untuned_scale = (1, 10)``: the filter the agent starts from has 10 times the
measurement-noise variances its estimator sets for the receiver (R x 10: a filter set up
for a worse receiver, which under-weights good fixes), so that there is something to
tune; ``a[1] = -1`` restores the estimator's own R. With ``untuned_scale = (1, 1)`` the
untuned filter is the estimator as it is, which on a consistent filter (lc-ekf on the
white-noise GNSS of "paper-2012") leaves little to gain from a fixed setting: R x 0.1 and
R x 10 do worse on average, and the Q factors of the action range change nothing measurable there
(the tactical IMU's PSDs add far less to the one-second prediction than the covariance
already holds). Measured figures in CHANGELOG.md (issue 15).

## Observation space
``Box(9,)`` float32, what the filter itself knows (never truth): log10 of its horizontal
and vertical position sigma (m, clipped to [-3, 6]); log10(1 + NIS/dof) of its last
update (0 without one); the fraction of valid channels at the last epoch; the fraction
of the interval's epochs with at least 4 valid channels; the time since the last epoch
with 4 or more channels (s / 100, at most 10); the previous action (2); the progress
t / duration.

## Rewards
``-min(mean_k |dr_k|, reward_cap)`` over the interval's navigation steps, ``dr`` the 3-D
position error in metres (the local-level linearisation of
:class:`~navsim.envs.navigation.NavigationEnv`); a non-finite solution gets
``-reward_cap``.

## Episode end
Truncated at the scenario's end; ``info["episode_score"]`` is the estimator's
:class:`~navsim.metrics.EpisodeScore` over the whole episode.

## Noise scaling
The factors go through the estimator's public ``set_noise_scale(process, measurement)``
(:class:`navsim.estimators.base.NoiseScaling`; every bundled estimator declares where
its Q and R live, :class:`navsim.estimators.base.NoiseScalable`, and any third-party
estimator may implement it). Q factors multiply PSDs, R factors multiply variances
(sigmas by its square root), relative to the values of the estimator's last reset. A
changed Q takes effect at the estimator's next covariance interval (1 s by default, the
decision period).

## Version History
* v0: initial version; the untuned filter mis-tuned by default (``untuned_scale = (1,
  10)``, issue 15: the estimator as it is left nothing to learn).

References
----------
.. [1] Gao X. et al., RL-AKF: an adaptive Kalman filter navigation algorithm based on
       reinforcement learning for ground vehicles, Remote Sensing 12(11):1704, 2020
       (the action scales the filter's noise covariances; reward from the position error).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike

from navsim.episode import step_batch
from navsim.errors import ConfigError
from navsim.estimators.base import NoiseScaling
from navsim.naverror import local_level_error, position_error_norm

from .agent import resolve_estimator
from .chunks import EpisodeTape
from .navigation import resolve_scenario
from .render import EnvRendering
from .spaces import check_action

if TYPE_CHECKING:  # type hints only
    from navsim.earth import EarthModel
    from navsim.scenario import Scenario
    from navsim.simulator import Chunk
    from navsim.types import EstimateBatch, MeasurementBatch

    from .render import FrameView, TrackRenderer

__all__ = ["AdaptiveFilterEnv", "NoiseAdapter"]

class NoiseAdapter:
    """Scale the process and measurement noise of an estimator after its reset.

    Parameters
    ----------
    estimator : an object with the public ``set_noise_scale(process, measurement)`` of
        :class:`navsim.estimators.base.NoiseScaling` (every bundled estimator has it).
    """

    def __init__(self, estimator: Any):
        if not isinstance(estimator, NoiseScaling):
            raise ConfigError("estimator", "an estimator with set_noise_scale(process, measurement) "
                              "(navsim.estimators.base.NoiseScaling)", type(estimator).__name__)
        self.estimator = estimator

    def capture(self) -> None:
        """Nothing to save: the estimator scales relative to its own last reset."""

    def set(self, q_scale: float, r_scale: float) -> None:
        """Apply the factors (relative to the values of the estimator's last reset)."""
        self.estimator.set_noise_scale(q_scale, r_scale)


class AdaptiveFilterEnv(EnvRendering, gym.Env):
    """An estimator whose Q and R an agent scales (see the module docstring).

    Parameters
    ----------
    scenario : str or Scenario
        Default "paper-2012" (GNSS lost 400-700 s).
    estimator : str or estimator object
        Default "lc-ekf"; ``estimator_options`` for a named one.
    decision_period_s : float
        Time between decisions (a whole number of navigation steps), default 1 s.
    chunk_steps : int
        Navigation steps the simulator generates per pass (rounded down to whole decision
        intervals, at least one); the estimator is served one interval at a time from
        it. The numbers do not depend on it (chunk-invariant generation); a short chunk
        pays the generator's fixed cost per pass (truth block fits, sensor set-up) at
        every decision.
    max_scale : float
        Largest factor around the untuned filter (the action maps to ``max_scale ** a``).
    untuned_scale : (float, float)
        ``(q0, r0)``, the factors of the untuned filter ``a = (0, 0)`` on the estimator's
        own Q and R; default ``(1, 10)``, mis-tuned on purpose (module docstring);
        ``(1, 1)`` for the estimator as it is.
    reward_cap : float
    **overrides
        Scenario sections.
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 1.0}  # per instance: 1 / decision_period_s
    observation_space: gym.spaces.Box
    _pos: int  # the next step of the current chunk (set with the chunk)

    def __init__(self, scenario: str | Scenario = "paper-2012", *, estimator: Any = "lc-ekf",
                 estimator_options: dict | None = None,
                 decision_period_s: float = 1.0, max_scale: float = 10.0,
                 untuned_scale: tuple[float, float] = (1.0, 10.0), reward_cap: float = 1e4,
                 chunk_steps: int = 10_000, render_mode: str | None = None, **overrides: Any) -> None:
        from navsim.episode import make_context
        from navsim.simulator import Simulator

        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError("render_mode", f"None or one of {self.metadata['render_modes']}", render_mode)
        if not (max_scale > 1.0 and math.isfinite(max_scale)):
            raise ConfigError("max_scale", "a finite factor > 1", max_scale)
        try:
            q0, r0 = (float(x) for x in untuned_scale)
        except (TypeError, ValueError):
            raise ConfigError("untuned_scale", "two positive finite factors (Q, R)", untuned_scale) from None
        if not all(x > 0.0 and math.isfinite(x) for x in (q0, r0)):
            raise ConfigError("untuned_scale", "two positive finite factors (Q, R)", untuned_scale)
        self.untuned_scale = (q0, r0)
        self.scenario = resolve_scenario(scenario, overrides)
        timing = self.scenario.timing
        ratio = decision_period_s / timing.nav_period_s
        if not (ratio >= 1 and abs(ratio - round(ratio)) < 1e-9):
            raise ConfigError("decision_period_s", f"a whole multiple of nav_period_s={timing.nav_period_s}",
                              decision_period_s)
        self.steps_per_decision = int(round(ratio))
        if int(chunk_steps) != chunk_steps or chunk_steps < 1:
            raise ConfigError("chunk_steps", "a positive integer", chunk_steps)
        self.chunk_steps = max(1, int(chunk_steps) // self.steps_per_decision) * self.steps_per_decision
        self._chunk: Chunk | None = None
        self.sim = Simulator(self.scenario)
        self.context = make_context(self.sim)
        self.prn = np.asarray(self.sim.constellation.prn)
        self.estimator_name, self.estimator = resolve_estimator(estimator, estimator_options)
        self.adapter = NoiseAdapter(self.estimator)
        self.max_scale = float(max_scale)
        self.reward_cap = float(reward_cap)
        self.render_mode = render_mode
        self.metadata = {**type(self).metadata, "render_fps": 1.0 / (self.steps_per_decision * timing.nav_period_s)}
        self._renderer: TrackRenderer | None = None
        self._scales = (1.0, 1.0)
        self.n_steps = timing.steps
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        low = np.array([-3, -3, 0, 0, 0, 0, -1, -1, 0], dtype=np.float32)
        high = np.array([6, 6, 6, 1, 1, 10, 1, 1, 1], dtype=np.float32)
        self.observation_space = gym.spaces.Box(low, high, dtype=np.float32)
        self._k = -1

    def _features(self, out: EstimateBatch, chunk: _Interval) -> np.ndarray:
        cov = out.covariance
        if cov is not None and np.all(np.isfinite(cov[-1, :3, :3])):
            hs = math.sqrt(max(cov[-1, 0, 0] + cov[-1, 1, 1], 1e-12))
            vs = math.sqrt(max(cov[-1, 2, 2], 1e-12))
        else:
            hs = vs = 1e6
        nis = out.nis[np.isfinite(out.nis)]
        dof = out.nis_dof[np.isfinite(out.nis)]
        if nis.size:
            self._last_nis = math.log10(1.0 + float(nis[-1]) / max(int(dof[-1]), 1))
        g = chunk.gnss
        if g is not None and len(g.t):
            n_valid = g.valid.sum(axis=1)
            self._frac_valid = float(n_valid[-1]) / len(self.prn)
            good = n_valid >= 4
            avail = float(good.mean())
            if good.any():
                self._last_fix_t = float(g.t[np.flatnonzero(good)[-1]])
        else:
            avail = 0.0
        t = float(chunk.t[-1])
        x = np.array([math.log10(hs), math.log10(vs), self._last_nis, self._frac_valid, avail,
                      (t - self._last_fix_t) / 100.0, self._prev[0], self._prev[1], t / self.scenario.timing.duration_s])
        return np.clip(x, self.observation_space.low, self.observation_space.high).astype(np.float32)

    def _run_interval(self) -> tuple[_Interval, EstimateBatch]:
        """Run the estimator over the next decision interval, served from the generated chunk."""
        from navsim.episode import measurement_batch

        chunk = self._chunk
        if chunk is None or self._pos >= len(chunk):
            chunk = self._chunk = self.sim.advance(self.chunk_steps)  # generation is chunk-invariant: the same numbers
            self._batch = measurement_batch(chunk, self.prn, self.scenario.timing.nav_period_s)
            self.tape.add_chunk(chunk)
            self._pos = 0
        a = self._pos
        b = min(a + self.steps_per_decision, len(chunk))
        out = step_batch(self.estimator, _slice_batch(self._batch, a, b))
        self.tape.add_estimates(chunk.step0 + a, out)
        self._pos = b
        self._k = chunk.step0 + b
        return _Interval(chunk, a, b), out

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**63 - 1))
        self.seed_value = int(seed)
        start = self.sim.reset(self.seed_value)
        self.prior = start.prior
        self.estimator.reset(self.context, self.prior)
        self.adapter.capture()
        self.adapter.set(*self.untuned_scale)
        self.tape = EpisodeTape(self.n_steps)
        self._chunk = None
        self._prev = (0.0, 0.0)
        self._last_nis, self._frac_valid, self._last_fix_t = 0.0, 0.0, 0.0
        chunk, out = self._run_interval()  # the first interval runs untuned
        info = {"context": self.context, "prior": self.prior, "seed": self.seed_value, "q_scale": self.untuned_scale[0],
                "r_scale": self.untuned_scale[1], "config_hash": self.scenario.config_hash()}
        self._scales = self.untuned_scale
        if self._renderer is not None:
            self._renderer.reset(self)
        if self.render_mode == "human":
            self.render()
        return self._features(out, chunk), info

    def step(self, action: ArrayLike) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._k < 0 or self._k >= self.n_steps:
            raise RuntimeError("AdaptiveFilterEnv.step: call reset() first")
        a = check_action(action, (2,), "2 real numbers in [-1, 1] (log-scale factors on Q and R)")
        if not np.all(np.isfinite(a)):  # a factor max_scale ** nan has no meaning: refused, nothing changed
            raise ConfigError("action", "2 finite numbers in [-1, 1] (log-scale factors on Q and R)",
                              "a non-finite value")
        a = np.clip(a, -1.0, 1.0)
        q, r = self.untuned_scale[0] * self.max_scale ** a[0], self.untuned_scale[1] * self.max_scale ** a[1]
        self.adapter.set(q, r)
        self._scales = (float(q), float(r))
        self._prev = (float(a[0]), float(a[1]))
        chunk, out = self._run_interval()
        err = _position_error(out.solution, chunk.truth, self.sim.earth)
        e = float(np.mean(err))
        reward = -e if e < self.reward_cap else -self.reward_cap
        obs = self._features(out, chunk)
        info: dict[str, Any] = {"q_scale": float(q), "r_scale": float(r), "receiver_outage": bool(chunk.receiver_outage[-1])
                if len(chunk.receiver_outage) else False, "position_error_m": e}
        truncated = self._k >= self.n_steps
        if truncated:
            from navsim.metrics import score_episode

            record = self.tape.record(self.scenario, self.seed_value, f"{self.estimator_name}+agent", self.sim.earth,
                                      self.prior)
            info["episode_score"] = score_episode(record, track=self.sim.track)
        if self.render_mode == "human":
            self.render()
        return obs, reward, False, truncated, info

    # ------------------------------------------------------------------ rendering
    def render_view(self) -> FrameView:
        """What a frame shows (:mod:`navsim.envs.render`): the estimator's path and error, the factors."""
        from .render import FrameView, tape_view

        timing = self.scenario.timing
        if self._k < 0:  # before the first reset
            return FrameView(0.0, timing.duration_s, np.zeros(0), np.zeros(0))
        q, r = self._scales
        return tape_view(self.tape, self._k, self.tape.actions, 1.0, timing.nav_period_s, timing.duration_s,
                         timing.gnss_period_s, status=f"{self.estimator_name}: Q x {q:.3g}, R x {r:.3g}")



class _Interval:
    """Steps a..b of a simulator chunk: what the features and the reward read."""

    def __init__(self, chunk: Chunk, a: int, b: int):
        tr = chunk.truth
        self.t = chunk.t[a:b]
        self.truth = _Truth(tr.lat[a:b], tr.lon[a:b], tr.h[a:b])
        self.gnss: _Epochs | None = None
        self.receiver_outage: np.ndarray = np.zeros(0, dtype=bool)
        if chunk.gnss is not None:
            local = np.asarray(chunk.gnss_step)
            sel = np.flatnonzero((local >= a) & (local < b))
            self.gnss = _Epochs(chunk.gnss.t[sel], chunk.gnss.valid[sel])
            self.receiver_outage = np.asarray(chunk.receiver_outage)[sel]

    def __len__(self) -> int:
        return len(self.t)


class _Truth:
    def __init__(self, lat: np.ndarray, lon: np.ndarray, h: np.ndarray):
        self.lat, self.lon, self.h = lat, lon, h


class _Epochs:
    def __init__(self, t: np.ndarray, valid: np.ndarray):
        self.t, self.valid = t, valid


def _slice_batch(batch: MeasurementBatch, a: int, b: int) -> MeasurementBatch:
    """Steps a..b of a MeasurementBatch (epochs re-indexed)."""
    if a == 0 and b == len(batch):
        return batch
    from navsim.types import MeasurementBatch

    return MeasurementBatch(step=batch.step[a:b], t=batch.t[a:b], dt=batch.dt, dtheta_r=batch.dtheta_r[a:b],
                            dv_r=batch.dv_r[a:b], dtheta_sub=batch.dtheta_sub[a:b], dv_sub=batch.dv_sub[a:b],
                            gnss=tuple((j - a, obs) for j, obs in batch.gnss if a <= j < b),
                            odometer_ds_m=None if batch.odometer_ds_m is None else batch.odometer_ds_m[a:b])


def _position_error(solution: np.ndarray, truth: _Truth, earth: EarthModel) -> np.ndarray:
    """3-D position error (m) per step (:func:`navsim.naverror.local_level_error`); inf where not finite."""
    d_e, d_n, d_u = local_level_error(solution[:, 0], solution[:, 1], solution[:, 2], truth.lat, truth.lon,
                                      truth.h, earth)
    err = position_error_norm(d_e, d_n, d_u)
    return np.where(np.isfinite(err), err, np.inf)
