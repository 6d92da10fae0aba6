"""Estimators as agents, and scoring any agent through the environment.

:class:`EstimatorAgent` turns an estimator (anything with ``reset(context, prior)`` and
``step(measurement) -> Estimate``, see :mod:`navsim.estimators.base`) into an agent of
the navigation env: it decodes the :class:`~navsim.types.Measurement` of each
observation with the signal codec (:class:`navsim.signals.ObservationCodec`; the same
arrays :func:`navsim.episode.measurements` hands out) and returns
the estimate as an :class:`EstimateAction`, an action array that also carries the
covariance, the NIS of an update and the estimator's CPU time, so the env's episode score
holds every figure of ``navsim run``.

:func:`evaluate` runs an agent over seeds and returns the per-episode scores.
"""

from __future__ import annotations

import time
from typing import Any, Iterable

import numpy as np

from navsim.errors import ConfigError
from navsim.estimators.base import row_stepping
from navsim.signals import MEASUREMENT_SIGNALS, Layout, ObservationCodec
from navsim.types import Estimate, Measurement

__all__ = ["EstimateAction", "EstimatorAgent", "evaluate"]


class EstimateAction(np.ndarray):
    """A (9,) action array carrying ``extras = (covariance, nis, nis_dof, cpu_s)``.

    It is an ordinary action for every wrapper and learner; the navigation env reads the
    extras into the episode record (covariance for NEES, NIS, CPU time). A view or copy of
    an EstimateAction keeps its extras; an EstimateAction made from any other array has
    ``(None, None, None, None)``.
    """

    # a slot, not an instance dict: setting the extras once per step stays cheap, and
    # the action object holds no dict for the garbage collector to walk
    __slots__ = ("extras",)
    extras: tuple

    @classmethod
    def of(cls, estimate: Estimate, cpu_s: float | None = None, scale: np.ndarray | None = None) -> "EstimateAction":
        """From an :class:`~navsim.estimators.base.Estimate`, divided by ``scale``
        (the env's ``info["action_scale"]``; None: physical units)."""
        v = estimate.velocity_n
        v0, v1, v2 = v.tolist() if isinstance(v, np.ndarray) else v  # floats: no NumPy scalar per entry
        out = np.array([estimate.lat, estimate.lon, estimate.h, v0, v1, v2, estimate.heading,
                        estimate.pitch, estimate.roll], dtype=float)
        if scale is not None:
            out /= scale
        action = out.view(cls)
        action.extras = (estimate.covariance, estimate.nis, estimate.nis_dof or 0, cpu_s)
        return action

    def __array_finalize__(self, obj: Any) -> None:
        # a view or copy of an EstimateAction keeps its extras (an exact type test: the
        # cheap case of act's per-step view of a plain array falls through at once)
        if type(obj) is EstimateAction:
            try:
                self.extras = obj.extras
            except AttributeError:  # obj's slot never set
                pass

    def __getattr__(self, name: str) -> Any:
        # called only when normal lookup fails: the slot of an action made from a plain
        # array and never set reads as "no extras"
        if name == "extras":
            return _NO_EXTRAS
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")


_NO_EXTRAS: tuple = (None, None, None, None)


def resolve_estimator(estimator: Any, options: dict | None = None) -> tuple[str, Any]:
    """``(name, estimator)``: a registry name is built with ``navsim.estimators.make``."""
    if isinstance(estimator, str):
        from navsim.estimators import make

        return estimator, make(estimator, **(options or {}))
    return type(estimator).__name__, estimator


class EstimatorAgent:
    """An estimator driven by the navigation env's observations.

    Parameters
    ----------
    estimator : estimator object or str
        An object with ``reset(context, prior)`` and ``step(measurement)``, or the name
        of a bundled estimator (:func:`navsim.estimators.make`).
    name : str, optional
        Label of the episode scores (default: the registry name or the class name).
    cpu_time : bool, default True
        Measure the estimator's CPU time per step (``time.process_time()`` just before and
        just after its call; the episode score's ``step_time_us``, ``cpu_total_s`` and
        ``realtime_factor``). ``False`` skips the two clock reads (a system call each on
        some virtual machines) and records no CPU time: those three scores are then NaN,
        every other number is the same.
    **options
        Options of a named estimator.

    Notes
    -----
    An estimator with ``step_row`` may name, as ``step_row_fields`` (a tuple of
    :data:`IMU_FIELDS`), the IMU fields its ``step_row`` reads on a step without a GNSS
    epoch: the reused measurement object then reshapes only those in advance and the others
    on reading (the same values either way: a hint on cost, not on content). Without it all
    four are reshaped at every step.

    Examples
    --------
    >>> import gymnasium as gym, navsim
    >>> env = gym.make("navsim/PaperRail-v0", timing={"duration_s": 1.0})
    >>> agent = EstimatorAgent("ins-only")
    >>> obs, info = env.reset(seed=0); agent.reset(info)
    >>> obs, reward, terminated, truncated, info = env.step(agent.act(obs))
    >>> terminated or truncated
    False
    """

    def __init__(self, estimator: Any, name: str | None = None, *, cpu_time: bool = True, **options: Any) -> None:
        if not isinstance(cpu_time, bool):
            raise ConfigError("EstimatorAgent cpu_time", "True or False", cpu_time)
        self.cpu_time = cpu_time
        if options and not isinstance(estimator, str):
            raise ConfigError("EstimatorAgent options", "options only with an estimator name", options)
        default_name, estimator = resolve_estimator(estimator, options)
        self.name = name or default_name
        if not (callable(getattr(estimator, "reset", None)) and callable(getattr(estimator, "step", None))):
            raise ConfigError("estimator", "an object with reset(context, prior) and step(measurement)", estimator)
        self.estimator = estimator
        self._last: tuple | Estimate | None = None

    @property
    def last_estimate(self) -> Estimate | None:
        """The solution of the last :meth:`act` as an :class:`~navsim.types.Estimate` (None
        before the first). Through the fast path (``step_row``) it is built on reading,
        with an empty ``extra``."""
        last = self._last
        if last is None or isinstance(last, Estimate):
            return last
        t, row, cov, nis, dof = last
        lat, lon, h, ve, vn, vu, heading, pitch, roll = row.tolist()
        est = Estimate(t, lat, lon, h, np.array((ve, vn, vu)), heading, pitch, roll, covariance=cov, nis=nis,
                       nis_dof=dof)
        self._last = est
        return est

    def reset(self, info: dict) -> None:
        """Reset the estimator from the env's reset info (context, prior, channel order)."""
        context = info["context"]
        self.estimator.reset(context, info["prior"])
        self._prn = np.asarray(info["gnss_prn"])
        self.codec = ObservationCodec(Layout.of_context(context, len(self._prn)), self._prn)
        self._decode = self.codec.decode
        self._scale = np.asarray(info.get("action_scale", np.ones(9)), dtype=float)
        self._step = 0
        self._estimator_step = self.estimator.step
        self._step_row = row_stepping(self.estimator)
        eager = _eager_fields(self.estimator)
        self._view = _view_class(eager)(self.codec, eager)
        # what act() reads per step, in one tuple (one attribute lookup instead of five)
        self._fast = (None if self._step_row is None
                      else (self._step_row, self._view.fill, self._decode, self._scale,
                            time.process_time if self.cpu_time else None))
        self._last = None

    def measurement(self, obs: dict) -> Measurement:
        """The :class:`~navsim.types.Measurement` of one observation (with the wheel-odometer
        distance when the scenario has an odometer), decoded by :mod:`navsim.signals`."""
        m = self._decode(obs, self._step)
        self._step += 1
        return m

    def act(self, obs: dict) -> EstimateAction:
        """The estimator's solution for the observed step (with its extras).

        With an estimator that has the fast path ``step_row``
        (:class:`navsim.estimators.base.RowStepping`: the same numbers as ``step``), a step
        without a GNSS epoch is handed over as views of the observation's arrays in a
        reused measurement object (no :class:`~navsim.types.Measurement` and no
        :class:`~navsim.types.Estimate` built); otherwise the decoded measurement goes to
        ``step``. The CPU-time extra is ``time.process_time()`` read just before and just
        after the estimator's call (decoding and the action are not in it), as
        :func:`navsim.episode.run_episode` measures ``step``; None with ``cpu_time=False``.
        """
        k = self._step
        self._step = k + 1
        fast = self._fast
        if fast is None:
            return self._act_step(obs, k)
        step_row, fill, decode, scale, clock = fast
        m = decode(obs, k) if obs["gnss_new_epoch"].item() else fill(obs, k)
        if clock is None:
            row, cov, nis, dof = step_row(m)
            cpu = None
        else:
            t0 = clock()
            row, cov, nis, dof = step_row(m)
            cpu = clock() - t0
        self._last = (m.t, row, cov, nis, dof)
        out = (row / scale).view(EstimateAction)
        out.extras = (cov, nis, dof or 0, cpu)
        return out

    def _act_step(self, obs: dict, k: int) -> EstimateAction:
        """:meth:`act` of an estimator without ``step_row``: ``step`` on the decoded measurement."""
        m = self._decode(obs, k)
        if not self.cpu_time:
            estimate = self._estimator_step(m)
            self._last = estimate
            return EstimateAction.of(estimate, None, self._scale)
        clock = time.process_time
        t0 = clock()
        estimate = self._estimator_step(m)
        cpu = clock() - t0
        self._last = estimate
        return EstimateAction.of(estimate, cpu, self._scale)

    __call__ = act


IMU_FIELDS = ("dtheta_r", "dv_r", "dtheta_sub", "dv_sub")
"""The IMU fields of :class:`~navsim.types.Measurement` (each an (n, 3) reshape of its flat
observation entry)."""


class _StepView:
    """The fields of :class:`~navsim.types.Measurement` for a step without a GNSS epoch,
    refilled for every such step with views of the observation's arrays (the decoding of
    :meth:`navsim.signals.ObservationCodec.decode`, without building a value). The optional
    sensors' readings are the codec's :attr:`~navsim.signals.ObservationCodec.measurement_signals`
    (each declared once in :mod:`navsim.signals`); a field of a sensor the scenario lacks is None.

    The IMU fields named in ``eager`` are set by :meth:`fill`; the others (an estimator's
    ``step_row_fields`` leaves them out, see :class:`EstimatorAgent`) are made on reading,
    the same reshape of the same observation entry, by the properties of :func:`_view_class`."""

    def __init__(self, codec: ObservationCodec, eager: tuple[str, ...] = IMU_FIELDS) -> None:
        self.dt = float(codec.layout.nav_period_s)
        self.gnss = None
        for sig in MEASUREMENT_SIGNALS:
            setattr(self, sig.measurement, None)
        self._optional = tuple((sig.name, sig.measurement) for sig in codec.measurement_signals)
        self._eager = eager
        self._obs: dict = {}

    def fill(self, obs: dict, step: int) -> "_StepView":
        """Refill from observation ``obs`` of step ``step``; returns the view itself."""
        self.step = step
        self.t = obs["t"].item()  # float(obs["t"][0]): the same Python float
        # attribute stores, not writes into __dict__ (that would turn off CPython's inline
        # attribute values for the object, and every read of the estimator gets slower)
        self.dtheta_r = obs["dtheta_r"].reshape(-1, 3)
        self.dv_r = obs["dv_r"].reshape(-1, 3)
        self.dtheta_sub = obs["dtheta_sub"].reshape(-1, 3)
        self.dv_sub = obs["dv_sub"].reshape(-1, 3)
        for key, field in self._optional:
            value = obs.get(key)
            setattr(self, field, None if value is None else float(value[0]))
        return self

    def _fill_eager(self, obs: dict, step: int) -> "_StepView":
        """:meth:`fill` of a view whose IMU fields outside ``eager`` are made on reading."""
        self.step = step
        self.t = obs["t"].item()
        self._obs = obs
        for key in self._eager:
            setattr(self, key, obs[key].reshape(-1, 3))
        for key, field in self._optional:
            value = obs.get(key)
            setattr(self, field, None if value is None else float(value[0]))
        return self


def _lazy_field(key: str) -> property:
    def get(self: _StepView) -> np.ndarray:
        return self._obs[key].reshape(-1, 3)

    return property(get, doc=f"``{key}`` of the observation as (n, 3), made on reading")


_VIEW_CLASSES: dict[tuple[str, ...], type] = {}


def _view_class(eager: tuple[str, ...]) -> type:
    """The :class:`_StepView` class whose IMU fields outside ``eager`` are properties (made once
    per field set)."""
    cls = _VIEW_CLASSES.get(eager)
    if cls is None:
        lazy: dict[str, Any] = {key: _lazy_field(key) for key in IMU_FIELDS if key not in eager}
        if lazy:
            lazy["fill"] = _StepView._fill_eager
        cls = _VIEW_CLASSES[eager] = type("_StepView", (_StepView,), lazy) if lazy else _StepView
    return cls


def _eager_fields(estimator: Any) -> tuple[str, ...]:
    """The IMU fields ``fill`` sets for ``estimator``: its ``step_row_fields`` among
    :data:`IMU_FIELDS` (all of them when it declares none)."""
    declared = getattr(estimator, "step_row_fields", None)
    if declared is None:
        return IMU_FIELDS
    return tuple(key for key in IMU_FIELDS if key in tuple(declared))


def _as_agent(agent_or_estimator: Any) -> Any:
    if isinstance(agent_or_estimator, (str, EstimatorAgent)):
        return agent_or_estimator if isinstance(agent_or_estimator, EstimatorAgent) else EstimatorAgent(agent_or_estimator)
    if callable(getattr(agent_or_estimator, "act", None)) and callable(getattr(agent_or_estimator, "reset", None)):
        return agent_or_estimator  # an agent: reset(info), act(obs)
    return EstimatorAgent(agent_or_estimator)


def evaluate(agent_or_estimator: Any, env_id: Any = "navsim/PaperRail-v0", seeds: Iterable[int] = (0,),
             **env_kwargs: Any) -> list:
    """Run an agent (or estimator) through the navigation env over ``seeds``.

    Parameters
    ----------
    agent_or_estimator : EstimatorAgent, estimator object, estimator name, or an agent
        with ``reset(info)`` and ``act(obs) -> action``.
    env_id : str or gymnasium.Env
        A registered id (``"navsim/PaperRail-v0"``) or an env instance (kept open).
    seeds : iterable of int
    **env_kwargs
        Passed to :func:`gymnasium.make` (scenario overrides, reward options).

    Returns
    -------
    list of navsim.metrics.EpisodeScore
        One per seed, the figures ``navsim run`` reports for the same estimator,
        scenario and seed (the CPU figures are the agent's own time).
    """
    import gymnasium as gym

    from .registration import register_envs

    register_envs()
    agent = _as_agent(agent_or_estimator)
    own = isinstance(env_id, str)
    env = gym.make(env_id, **env_kwargs) if own else env_id
    name = getattr(agent, "name", type(agent).__name__)
    scores = []
    try:
        for seed in seeds:
            obs, info = env.reset(seed=int(seed), options={"agent": name})
            agent.reset(info)
            act = agent.act
            step = env.step
            while True:
                obs, reward, terminated, truncated, info = step(act(obs))
                if terminated or truncated:
                    break
            score = info.get("episode_score")
            if score is None:
                raise ConfigError("env score", "an env that scores episodes (score=True)", env_kwargs.get("score"))
            scores.append(score)
    finally:
        if own:
            env.close()
    return scores
