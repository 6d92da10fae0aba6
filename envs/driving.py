"""The driving task: run a train to a timetable on the navigation solution, stop at platform marks.

## Description
The agent is the driver (or the automatic train operation): every ``decision_period_s``
it sets the traction/brake command of a train (:mod:`navsim.envs.plant`) running a
timetable over the scenario's stations. The train's motion goes into the core simulator
as external motion; an attached estimator (default "along-track") turns the simulated
sensor data into a navigation solution, and the agent sees that solution, never the
truth. Precise stopping at a platform mark with GNSS lost in a tunnel is where
navigation quality meets control.

## Action space
``Box(-1, 1, (1,))``, read according to ``action_mode``:

* ``"command"`` (default): the command u (traction for u > 0, brake for u < 0), held over
  the decision period;
* ``"target_speed"``: a speed demand to the train's speed controller (the cruise control
  of an automatic train operation), ``v_ref = (a + 1) / 2 * v_top`` with ``v_top`` the
  timetable's cruise speed (``motion.cruise_speed_mps``; a = -1 asks to stop). The
  controller sets the command from the same speed estimate the agent sees, once per
  decision, and holds it over the period::

      u = clip(k_v (v_ref - max(v_hat, 0)), -1, 1)                    (D.1)

  with ``k_v = speed_gain`` (default 1.0 per m/s: with the 1 m/s^2 brake and 1-s
  decisions a braking error is removed in one period, (D.1) is dead-beat under braking).
  ``v_ref = 0`` never gives traction, so the train stops and stays stopped. The task
  (reward, stop judgement, observation) is the same in both modes; only the actuator
  the agent commands differs, so scores of the two modes compare directly.

Values outside [-1, 1] are clipped to it; a non-finite value applies the full brake
(u = -1, the safe command, in both modes); a wrong shape or a non-real dtype raises
:class:`~navsim.errors.ConfigError` before any state changes
(:func:`navsim.envs.spaces.check_action`).

## Observation space
``Box(13,)`` float32: distance from the *estimated* arc length to the next platform mark
(km, [-1, 50]); estimated along-track speed / 30 m/s ([-1, 2]); time to the scheduled
arrival at the next station / 600 s ([-5, 5]); the track grade at the estimated position
x 10 ([-1, 1]); the estimator's along-track position sigma / 10 m ([0, 100]); the
fraction of valid GNSS channels at the last epoch; the previous command u (in both action
modes the traction/brake command applied); 1 while the
train dwells at a station; the fraction of stations still to serve; then what a driver
reads off for the final approach, from the same estimate:

* the distance to the mark / 10 m ([-3, 3]: metre resolution near the mark, where the
  first entry's km scale cannot show it);
* the braking-curve margin ``(v_b(d) - v) / 2 m/s`` ([-5, 5]), with
  ``v_b(d) = sqrt(2 b_ref max(d, 0))`` the speed from which a constant deceleration
  ``b_ref`` (half the train's ``max_brake_decel_mps2``, a service brake) stops the train
  exactly at the mark, ``d`` the distance and ``v`` the speed estimates;
* the margin to the line speed ``(cruise_speed_mps - v) / 30 m/s`` ([-1, 2]; the
  timetable's cruise speed, the speed the schedule is built on);
* the time left before the scheduled departure from the current station while dwelling
  / 60 s ([0, 5]; 0 when not dwelling).

Every entry is of order one over the task (no normalisation wrapper is needed, though
SB3's ``VecNormalize`` does no harm).

## Rewards
Per decision period ``[t0, t1]``::

    r = -w_comfort * jerk^2 * T - w_energy * E_kWh - w_late * L / 60              (R.1)
    L = sum_{i not served} (max(0, t1 - a_i) - max(0, t0 - a_i))  (s)             (R.2)

with the jerk of the true motion over the period (m/s^3), the traction energy, and the
lateness L accruing, as time passes, at every station i not served (ahead of the train,
or missed) whose scheduled arrival ``a_i`` has passed: a station served late totals
``arrival - a_i``, one not served keeps accruing to the episode's end. Events, judged
on the true motion:

* a stop at a station (the true speed reaches 0 with the true arc length within
  ``stop_tolerance_m`` of the mark)::

      + stop_bonus * (1 - |stop error| / stop_tolerance_m) - w_early * max(0, early) / 60   (R.3)

  (earliness against the schedule, s); the train then dwells (commands are ignored)
  until ``max(arrival + dwell, scheduled departure)``;
* an overrun (passing the mark by more than ``stop_tolerance_m``: stopped beyond it, or
  200 m past it): ``-overrun``; the station is missed, i.e. not served: its lateness goes
  on accruing by (R.2) and it is charged as unserved at the end; the next station
  becomes the target;
* at the episode's end, for every station not served (never reached, or missed)::

      - unserved - w_late * L_rest / 60                                            (R.4)

  with ``L_rest`` (R.2) over [t_end, T] the lateness it would accrue up to the time
  limit T when the episode terminates before it (the last station served or missed);
  ``unserved`` stands for the lateness beyond T, which (R.2) cannot see.

So a missed station costs exactly ``overrun`` more than one never reached (the same
lateness to T, the same unserved charge): running through a station is worse than
standing still in front of it. Standing still costs the lateness of every station to T
plus ``unserved`` per station; driving through every station that plus ``overrun`` per
station and the energy; a driver keeping to the timetable earns the stop bonuses.
Defaults: w_comfort 0.05, w_energy 0.05 per kWh, stop_bonus 10, w_late 5 per minute,
w_early 0.2 per minute, overrun 20, unserved 40, stop_tolerance_m 2.
``info["unserved"]`` (at the end) counts the stations not served, ``info["missed"]`` the
overrun ones among them, ``info["late_charged_s"]`` the lateness charged so far.

Optional shaping (``progress_shaping`` = c_p per km, ``braking_shaping`` = c_b per m/s,
``approach_shaping`` = c_a; all default 0: off). A potential-based term in the sense of
Ng, Harada and Russell [2] is added to every period's reward::

    F = Phi(t1) - Phi(t0),
    Phi = -c_p * max(0, s_last - s) / 1000 m - c_b * max(0, v - v_b(s_next - s))
          - c_a * min(|s_next - s|, 50 m) / 50 m

on the true motion, with ``s_last`` the last station's mark, ``s_next`` the next mark
to serve and ``v_b`` the braking curve of the observation below (a service brake at
half the train's maximum): progress along the line is paid as it is made, speed in
excess of what still stops the train at the next mark is charged while it lasts, and
the last 50 m to the next mark are paid as they are closed (and charged back when the
mark is passed), so that a train stopped short of the mark sees what creeping on to it
gains. The terms of ``s_next`` are 0 once no station is left (the terminal state). Its
sum over an episode telescopes to ``Phi(end) - Phi(start)``, a term that depends only on
where and how fast the train ends (and on the station switches, where ``s_next``
changes); the optimal policies of the task are unchanged in the undiscounted sense of
[2], while a learner gets a dense signal before it first reaches a station.
``info["task_reward"]`` is always the reward without it (the task's score; the demos
evaluate on it).

## Starting state
At rest at the first station, departing at its dwell time; the schedule is the core's
jerk-limited minimum-time timetable (the scenario's ``motion`` section) stretched by
``1 + slack`` (default 5 %).

## Episode end
Terminated when the last station is served or missed (overrun); truncated when the
scenario's time runs out (the duration is extended to 1.25 x the scheduled journey).
``info["episode_score"]`` at the end: the estimator's navigation score over the episode
(unless ``episode_score=False``).

## Version History
* v0: initial version; lateness charged as it accrues, unserved stations charged at the
  end, an overrun misses the station instead of ending the episode (issue 15); a missed
  station counts as not served ((R.2), (R.4); issue 15: an overrun no longer costs less
  than never reaching the station); four
  final-approach entries appended to the observation and the optional progress shaping
  (issue 15, the learning demo); ``action_mode="target_speed"`` (issue 15, the learning
  demo; the default mode unchanged).

References
----------
.. [1] Yin J. et al., Research and development of automatic train operation for railway
       transportation systems: a survey, Transportation Research Part C 85, 2017 (ATO
       objectives: punctuality, stopping accuracy, comfort, energy).
.. [2] Ng A.Y., Harada D., Russell S., Policy invariance under reward transformations:
       theory and application to reward shaping, ICML 1999 (potential-based shaping).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike

from navsim.episode import step_batch
from navsim.errors import ConfigError
from navsim.motion import ExternalMotion

from .agent import resolve_estimator
from .chunks import EpisodeTape
from .navigation import resolve_scenario
from .plant import TrainParameters, TrainPlant
from .render import EnvRendering
from .spaces import check_action

if TYPE_CHECKING:
    from navsim.estimators.base import Estimator
    from navsim.scenario import Scenario
    from navsim.simulator import Chunk
    from navsim.track import Track

    from .render import FrameView, TrackRenderer

__all__ = ["DrivingEnv", "braking_curve_driver", "schedule_of"]



def braking_curve_driver(obs: np.ndarray, b: float = 0.45, k: float = 1.5, cruise_mps: float = 17.0) -> np.ndarray:
    """A reference driver for :class:`DrivingEnv` acting on the observation (the estimate).

    It follows the braking curve ``v_t = min(cruise, sqrt(2 b max(d - 0.5 m, 0)))`` (``d`` the
    estimated distance to the mark in m = ``obs[0]`` x 1000, ``v`` the estimated speed in m/s
    = ``obs[1]`` x 30, ``b`` the planned deceleration in m/s^2) with the proportional command
    ``u = k (v_t - v)``, holds the brake while dwelling (``obs[7]`` = 1), and creeps the
    last metres (``d < 3 m``, ``v < 0.6 m/s``: 0.15 traction, full brake inside 0.8 m).
    Returns the action, shape (1,), in [-1, 1].
    """
    d, v = obs[0] * 1000.0, obs[1] * 30.0
    if obs[7] > 0:
        return np.array([-1.0], np.float32)
    target = min(cruise_mps, math.sqrt(max(2 * b * max(d - 0.5, 0.0), 0.0)))
    u = k * (target - v)
    if d < 3.0 and v < 0.6:
        u = -1.0 if d < 0.8 else 0.15
    return np.array([np.clip(u, -1.0, 1.0)], np.float32)

def schedule_of(scenario: Scenario, slack: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(marks (m), dwell (s), scheduled arrival (s), scheduled departure (s)) per station.

    The arrival times of the core's jerk-limited timetable for the scenario's stations,
    stretched by ``1 + slack`` after the first departure.
    """
    from navsim.simulator import build_profile

    if scenario.motion.profile != "timetable":
        raise ConfigError("motion.profile", "'timetable' with stations for the driving task", scenario.motion.profile)
    profile = build_profile(scenario)
    marks = np.array([st.s_m for st in scenario.motion.stations])
    dwell = np.array([st.dwell_s for st in scenario.motion.stations])
    t = np.arange(0.0, profile.end_time + 1.0, 0.05)
    s = profile.evaluate(t)[0]
    arrival = np.array([t[np.argmax(s >= m - 1e-3)] for m in marks])
    depart0 = dwell[0]
    arrival = np.where(np.arange(len(marks)) == 0, 0.0, depart0 + (arrival - depart0) * (1.0 + slack))
    departure = arrival + dwell
    departure[0] = depart0
    return marks, dwell, arrival, departure


class _MapTable:
    """Track positions, tangents and grades at 1 m spacing, for projecting estimates."""

    def __init__(self, track: Track, step_m: float = 1.0):
        from navsim.track import track_frame

        n = int(math.ceil(track.length / step_m)) + 1
        self.s = np.linspace(0.0, track.length, n)
        frame = track_frame(track, self.s)
        self.lat, self.lon = frame.lat, frame.lon
        self.heading = frame.heading
        self.sin_pitch = np.sin(frame.pitch)
        r_n, r_e = track.earth.radii(frame.lat)
        self.k_n = r_n + frame.h
        self.k_e = (r_e + frame.h) * np.cos(frame.lat)
        self.step = float(self.s[1] - self.s[0])

        self._sin_pitch = self.sin_pitch.tolist()
        self._last = len(self.s) - 1

    def sin_grade(self, s: float) -> float:
        """sin(pitch) at arc length s (linear interpolation in the 1 m table)."""
        x = min(max(s, 0.0), self.s[-1]) / self.step
        i = min(int(x), self._last - 1)
        f = x - i
        return (1.0 - f) * self._sin_pitch[i] + f * self._sin_pitch[i + 1]

    def grade_table(self) -> tuple[list[float], float, float]:
        """(sin(pitch) values, step, end) of :meth:`sin_grade`, for the plant's inline path."""
        return self._sin_pitch, self.step, float(self.s[-1])

    def project(self, lat: float, lon: float, s_guess: float, window_m: float = 300.0) -> float:
        """Arc length of the track point nearest to (lat, lon), searched near s_guess."""
        if not (math.isfinite(lat) and math.isfinite(lon)):
            return s_guess
        i0 = max(0, int((s_guess - window_m) / self.step))
        i1 = min(len(self.s), int((s_guess + window_m) / self.step) + 2)
        dn = (self.lat[i0:i1] - lat) * self.k_n[i0:i1]
        de = (self.lon[i0:i1] - lon) * self.k_e[i0:i1]
        return float(self.s[i0 + int(np.argmin(dn * dn + de * de))])


class DrivingEnv(EnvRendering, gym.Env):
    """A train driven on the navigation solution (see the module docstring).

    Parameters
    ----------
    scenario : str or Scenario
        A scenario with a timetable (default "mountain-railway"); its motion becomes
        external, driven by the plant.
    estimator : str or estimator object
        Default "along-track".
    decision_period_s, slack, stop_tolerance_m : float
    weights : dict, optional
        Overrides of ``comfort, energy, stop_bonus, late, early, overrun, unserved``.
    train : TrainParameters, optional
    truth_in_info : bool
        Put the true s, v, a in the info.
    action_mode : {"command", "target_speed"}
        What the action is (module docstring, "Action space"): the traction/brake command
        (default) or the speed demand of (D.1).
    speed_gain : float
        k_v of (D.1), per m/s (target_speed mode only; default 1.0).
    episode_score : bool
        Record the episode and put the estimator's navigation score in the last info
        (default True). False (training, where only the reward counts) skips the
        recording and the scoring; rewards, observations and the other infos are the
        same (bit for bit). Rendering records the episode either way.
    progress_shaping, braking_shaping, approach_shaping : float
        c_p (per km of progress toward the last mark), c_b (per m/s above the braking
        curve) and c_a (for the last 50 m to the next mark) of the optional
        potential-based shaping (default 0: the task's reward only).
    **overrides
        Scenario sections.
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 1.0}  # per instance: 1 / decision_period_s
    WEIGHTS = {"comfort": 0.05, "energy": 0.05, "stop_bonus": 10.0, "late": 5.0, "early": 0.2, "overrun": 20.0,
               "unserved": 40.0}
    observation_space: gym.spaces.Box
    estimator: Estimator

    def __init__(self, scenario: str | Scenario = "mountain-railway", *, estimator: str | Estimator = "along-track",
                 estimator_options: dict | None = None, decision_period_s: float = 1.0, slack: float = 0.05,
                 stop_tolerance_m: float = 2.0, weights: dict | None = None, train: TrainParameters | None = None,
                 truth_in_info: bool = False, progress_shaping: float = 0.0,
                 braking_shaping: float = 0.0, approach_shaping: float = 0.0, action_mode: str = "command",
                 speed_gain: float = 1.0, episode_score: bool = True,
                 render_mode: str | None = None, **overrides: Any) -> None:
        from navsim.episode import make_context
        from navsim.simulator import Simulator

        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError("render_mode", f"None or one of {self.metadata['render_modes']}", render_mode)
        base = resolve_scenario(scenario, overrides)
        self.marks, self.dwell, self.sched_arr, self.sched_dep = schedule_of(base, float(slack))
        timing = base.timing
        ratio = decision_period_s / timing.nav_period_s
        if not (ratio >= 1 and abs(ratio - round(ratio)) < 1e-9):
            raise ConfigError("decision_period_s", f"a whole multiple of nav_period_s={timing.nav_period_s}",
                              decision_period_s)
        if not stop_tolerance_m > 0:
            raise ConfigError("stop_tolerance_m", "a positive distance, m", stop_tolerance_m)
        self.weights = dict(self.WEIGHTS)
        for key, value in (weights or {}).items():
            if key not in self.WEIGHTS:
                raise ConfigError(f"weights.{key}", f"one of {sorted(self.WEIGHTS)}", key)
            self.weights[key] = float(value)
        period = timing.gnss_period_s
        duration = math.ceil(1.25 * self.sched_arr[-1] / period) * period
        self.scenario = base.with_overrides({
            "motion": {"profile": "external", "start_s_m": float(self.marks[0]), "speed_mps": 0.0},
            "timing": {"duration_s": float(duration)},
        })
        self.steps_per_decision = int(round(ratio))
        self.dt = timing.nav_period_s
        self.sim = Simulator(self.scenario)
        self.context = make_context(self.sim)
        self.prn = np.asarray(self.sim.constellation.prn)
        self.map = _MapTable(self.sim.track)
        self.plant = TrainPlant(self.map.sin_grade, train or TrainParameters(), grade_table=self.map.grade_table())
        self.estimator_name, self.estimator = resolve_estimator(estimator, estimator_options)
        self.stop_tolerance_m = float(stop_tolerance_m)
        self.truth_in_info = bool(truth_in_info)
        for name, value in (("progress_shaping", progress_shaping), ("braking_shaping", braking_shaping),
                            ("approach_shaping", approach_shaping)):
            if not (value >= 0.0 and math.isfinite(value)):
                raise ConfigError(name, "a non-negative finite weight", value)
        self.progress_shaping, self.braking_shaping = float(progress_shaping), float(braking_shaping)
        self.approach_shaping = float(approach_shaping)
        self._shaped = bool(self.progress_shaping or self.braking_shaping or self.approach_shaping)
        if action_mode not in ("command", "target_speed"):
            raise ConfigError("action_mode", "'command' or 'target_speed'", action_mode)
        if not (speed_gain > 0.0 and math.isfinite(speed_gain)):
            raise ConfigError("speed_gain", "a positive finite gain, per m/s", speed_gain)
        self.action_mode, self.speed_gain = action_mode, float(speed_gain)
        self._b_ref = 0.5 * self.plant.p.max_brake_decel_mps2  # service brake of the braking-curve entry
        self._line_speed = float(base.motion.cruise_speed_mps)
        self.render_mode = render_mode
        self.episode_score = bool(episode_score)
        self._record = self.episode_score or render_mode is not None
        self.metadata = {**type(self).metadata, "render_fps": 1.0 / (self.steps_per_decision * self.dt)}
        self._renderer: TrackRenderer | None = None
        self.n_steps = self.scenario.timing.steps
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        low = np.array([-1, -1, -5, -1, 0, 0, -1, 0, 0, -3, -5, -1, 0], dtype=np.float32)
        high = np.array([50, 2, 5, 1, 100, 1, 1, 1, 1, 3, 5, 2, 5], dtype=np.float32)
        self.observation_space = gym.spaces.Box(low, high, dtype=np.float32)
        self._k = -1

    # ------------------------------------------------------------------ episode
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**63 - 1))
        self.seed_value = int(seed)
        start = self.sim.reset(self.seed_value)
        self.prior = start.prior
        self.estimator.reset(self.context, self.prior)
        self.plant.reset(float(self.marks[0]), 0.0)
        self.tape = EpisodeTape(self.n_steps if self._record else 0)
        self.target = 1  # the next station to serve
        self.hold_until = float(self.sched_dep[0])  # dwell at the first station
        self.t = 0.0
        self._k = 0
        self._u = 0.0
        self._a_prev = self.plant.a
        self._s_hat = float(self.marks[0])
        self._v_hat, self._sigma_s, self._frac_valid = 0.0, 0.0, 0.0
        self.energy_kwh = 0.0
        self.late_charged_s = 0.0
        self.stops: list[dict] = []
        self.missed: list[int] = []  # stations overrun: not served
        info = {"context": self.context, "prior": self.prior, "seed": self.seed_value, "marks_m": self.marks.copy(),
                "scheduled_arrival_s": self.sched_arr.copy(), "scheduled_departure_s": self.sched_dep.copy()}
        if self._renderer is not None:
            self._renderer.reset(self)
        if self.render_mode == "human":
            self.render()
        return self._observation(), info

    def _observation(self) -> np.ndarray:
        i = min(self.target, len(self.marks) - 1)
        held = 1.0 if self.t < self.hold_until else 0.0
        d = float(self.marks[i] - self._s_hat)
        v_brake = math.sqrt(2.0 * self._b_ref * max(d, 0.0))
        x = np.array([d / 1000.0, self._v_hat / 30.0, (self.sched_arr[i] - self.t) / 600.0,
                      10.0 * self.map.sin_grade(self._s_hat), self._sigma_s / 10.0,
                      self._frac_valid, self._u, held, (len(self.marks) - self.target) / len(self.marks),
                      d / 10.0, (v_brake - self._v_hat) / 2.0, (self._line_speed - self._v_hat) / 30.0,
                      max(self.hold_until - self.t, 0.0) / 60.0])
        return np.clip(x, self.observation_space.low, self.observation_space.high).astype(np.float32)

    def _lateness(self, t0: float, t1: float) -> float:
        """Lateness (s) accruing over [t0, t1] at the stations not served: those ahead and those missed."""
        due = self.sched_arr[self.target:]
        if self.missed:
            due = np.concatenate([self.sched_arr[self.missed], due])
        return float(np.sum(np.maximum(t1 - due, 0.0) - np.maximum(t0 - due, 0.0)))

    def _potential(self, s: float, v: float, target: int) -> float:
        """Phi of the optional shaping (module docstring) at true (s, v), next station ``target``."""
        phi = -self.progress_shaping * max(0.0, float(self.marks[-1]) - s) / 1000.0
        if target < len(self.marks) and self.braking_shaping:
            v_b = math.sqrt(2.0 * self._b_ref * max(float(self.marks[target]) - s, 0.0))
            phi -= self.braking_shaping * max(0.0, v - v_b)
        if target < len(self.marks) and self.approach_shaping:
            phi -= self.approach_shaping * min(abs(float(self.marks[target]) - s), 50.0) / 50.0
        return phi

    def _navigate(self, n: int) -> Chunk:
        """Push the plant's motion for n steps, simulate, run the estimator; update the
        navigation-derived observation parts."""
        from navsim.episode import measurement_batch

        chunk = self.sim.advance(n)
        out = step_batch(self.estimator, measurement_batch(chunk, self.prn, self.dt))
        if self._record:
            self.tape.add_chunk(chunk)
            self.tape.add_estimates(chunk.step0, out)
        sol = out.solution[-1]
        self._s_hat = self.map.project(float(sol[0]), float(sol[1]), self._s_hat)
        j = min(int(round(self._s_hat / self.map.step)), len(self.map.s) - 1)
        psi = float(self.map.heading[j])
        self._v_hat = float(sol[3] * math.sin(psi) + sol[4] * math.cos(psi))
        if out.covariance is not None and np.all(np.isfinite(out.covariance[-1, :2, :2])):
            tang = np.array([math.sin(psi), math.cos(psi)])
            self._sigma_s = math.sqrt(max(float(tang @ out.covariance[-1, :2, :2] @ tang), 0.0))
        if chunk.gnss is not None and len(chunk.gnss.t):
            self._frac_valid = float(chunk.gnss.valid[-1].sum()) / len(self.prn)
        return chunk

    def step(self, action: ArrayLike) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._k < 0 or self._k >= self.n_steps:
            raise RuntimeError("DrivingEnv.step: call reset() first")
        n = min(self.steps_per_decision, self.n_steps - self._k)
        dwelling = self.t < self.hold_until
        u = float(check_action(action, (1,), "1 real number in [-1, 1] (traction > 0, brake < 0)")[0])
        if math.isfinite(u) and self.action_mode == "target_speed":  # (D.1) on the speed estimate
            v_ref = 0.5 * (min(max(u, -1.0), 1.0) + 1.0) * self._line_speed
            u = self.speed_gain * (v_ref - max(self._v_hat, 0.0))
        u = -1.0 if dwelling or not math.isfinite(u) else min(max(u, -1.0), 1.0)  # nan / inf: full brake
        self._u = 0.0 if dwelling else u
        k0 = self._k
        phi0 = self._potential(self.plant.s, self.plant.v, self.target) if self._shaped else 0.0
        s, v, a, energy_j = self.plant.advance(u, self.dt, n)
        if s[-1] > self.sim.track.length:
            s = np.minimum(s, self.sim.track.length)  # buffer stop at the end of the line
        times = (k0 + 1 + np.arange(n)) * self.dt
        profile = self.sim.profile
        assert isinstance(profile, ExternalMotion), "the scenario's motion is external (__init__)"
        for tk, sk, vk, ak in zip(times.tolist(), s.tolist(), v.tolist(), a.tolist()):
            profile.push(tk, sk, vk, ak)  # (P.1)-(P.2) states into the external motion
        self._navigate(n)
        self._k = k0 + n
        self.t = self._k * self.dt
        w = self.weights
        period = n * self.dt
        jerk = (a[-1] - self._a_prev) / period
        self._a_prev = float(a[-1])
        e_kwh = energy_j / 3.6e6
        self.energy_kwh += e_kwh
        reward = -w["comfort"] * jerk * jerk * period - w["energy"] * e_kwh
        # lateness accrues, over this period, at every station not served (ahead, or missed) whose arrival has passed
        late_inc = self._lateness(k0 * self.dt, self.t)
        reward -= w["late"] * late_inc / 60.0
        self.late_charged_s += late_inc
        terminated = False
        info: dict = {"energy_kwh": self.energy_kwh, "station": self.target, "late_charged_s": self.late_charged_s}
        # stop events, judged on the true motion
        if not dwelling and self.target < len(self.marks):
            mark = float(self.marks[self.target])
            s_true, v_true = float(s[-1]), float(v[-1])
            if s_true > mark + self.stop_tolerance_m and (v_true == 0.0 or s_true > mark + 200.0):
                reward -= w["overrun"]  # the station is missed (unserved); the train goes on to the next one
                info["overrun_m"] = s_true - mark
                self.stops.append({"station": self.target, "overrun_m": s_true - mark, "t": self.t})
                self.missed.append(self.target)
                self.target += 1
            elif v_true == 0.0 and abs(s_true - mark) <= self.stop_tolerance_m:
                stop_error = s_true - mark
                late = self.t - float(self.sched_arr[self.target])
                reward += w["stop_bonus"] * (1.0 - abs(stop_error) / self.stop_tolerance_m)
                reward -= w["early"] * max(-late, 0.0) / 60.0  # lateness was charged as it accrued
                self.stops.append({"station": self.target, "stop_error_m": stop_error, "late_s": late, "t": self.t})
                info["stop_error_m"], info["late_s"] = stop_error, late
                self.hold_until = max(self.t + float(self.dwell[self.target]), float(self.sched_dep[self.target]))
                self.target += 1
            if self.target == len(self.marks):
                terminated = True
        if terminated or self._k >= self.n_steps:
            # stations never reached and stations missed: the unserved charge, and (ended before the time limit)
            # the lateness they would accrue up to it
            unserved = len(self.marks) - self.target + len(self.missed)
            rest = self._lateness(self.t, self.n_steps * self.dt) if self._k < self.n_steps else 0.0
            reward -= w["late"] * rest / 60.0 + w["unserved"] * unserved
            self.late_charged_s += rest
            info["late_charged_s"] = self.late_charged_s
            info["unserved"] = unserved
            info["missed"] = len(self.missed)
        info["task_reward"] = float(reward)
        if self._shaped:  # potential-based, on the true motion
            reward += self._potential(float(s[-1]), float(v[-1]), self.target) - phi0
        if self.truth_in_info:
            info["truth"] = {"s": float(s[-1]), "speed": float(v[-1]), "accel": float(a[-1])}
        truncated = not terminated and self._k >= self.n_steps
        if (terminated or truncated) and not self.episode_score:
            info["stops"] = list(self.stops)
            self.steps_done = self._k
            self._k = self.n_steps  # the episode is over
        elif terminated or truncated:
            from navsim.metrics import score_episode

            steps = self._k
            tape = self.tape
            tape.n = steps  # score the simulated part of the episode
            for name in ("s", "lat", "lon", "h", "velocity_n", "hpr"):
                setattr(tape, name, getattr(tape, name)[:steps])
            if tape.cov_array is not None:
                tape.cov_array = tape.cov_array[:steps]
            if tape.nis_array is not None and tape.nis_dof_array is not None:  # made together
                tape.nis_array, tape.nis_dof_array = tape.nis_array[:steps], tape.nis_dof_array[:steps]
            scen = self.scenario.with_overrides({"timing": {"duration_s": steps * self.dt}}) if steps < self.n_steps \
                else self.scenario
            record = tape.record(scen, self.seed_value, self.estimator_name, self.sim.earth, self.prior)
            info["episode_score"] = score_episode(record, track=self.sim.track)
            info["stops"] = list(self.stops)
            self.steps_done = steps
            self._k = self.n_steps  # the episode is over
        if self.render_mode == "human":
            self.render()
        return self._observation(), float(reward), terminated, truncated, info

    # ------------------------------------------------------------------ rendering
    def render_view(self) -> FrameView:
        """What a frame shows (:mod:`navsim.envs.render`): the train's true and estimated
        position and speed, the stations, the next stop."""
        from .render import FrameView, tape_view

        duration = self.scenario.timing.duration_s
        lat_m = np.interp(self.marks, self.map.s, self.map.lat)
        lon_m = np.interp(self.marks, self.map.s, self.map.lon)
        if self._k <= 0:
            lat0, lon0 = np.interp([self.marks[0]], self.map.s, self.map.lat), np.interp([self.marks[0]], self.map.s,
                                                                                         self.map.lon)
            return FrameView(0.0, duration, lat0, lon0, marks_lat=lat_m, marks_lon=lon_m)
        if self.target < len(self.marks):
            i = self.target
            status = (f"next: station {i} at {self.marks[i]:.0f} m, due {self.sched_arr[i]:.0f} s; "
                      f"served {i - 1}/{len(self.marks) - 1}; {self.energy_kwh:.2f} kWh")
        else:
            status = f"all {len(self.marks) - 1} stations served; {self.energy_kwh:.2f} kWh"
        view = tape_view(self.tape, self._k, self.tape.actions, 1.0, self.dt, duration,
                         self.scenario.timing.gnss_period_s, strip="speed", status=status)
        view.marks_lat, view.marks_lon = lat_m, lon_m
        return view

