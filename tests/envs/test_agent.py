"""``EstimatorAgent``'s own per-step path: the reused step view (all IMU fields set in advance,
or only an estimator's ``step_row_fields`` with the others made on reading), the action and
its extras, against the decoded :class:`~navsim.types.Measurement` of the same observation.

The view's fields are reshapes of the observation's own arrays and the action is the same
division of the same row, so everything is compared bit for bit (``np.array_equal``)."""

from __future__ import annotations

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import navsim.envs  # noqa: E402,F401  (registers the ids)
from navsim.envs import EstimateAction, EstimatorAgent  # noqa: E402
from navsim.envs.agent import IMU_FIELDS  # noqa: E402

FIELDS = ("step", "t", "dt", "gnss", *IMU_FIELDS, "odometer_ds_m")


def _observations(scenario_over=None, env_id="navsim/PaperRail-v0"):
    env = gym.make(env_id, score=False, timing={"duration_s": 2.0}, **(scenario_over or {}))
    obs, info = env.reset(seed=2)
    out = []
    while True:
        out.append({k: np.array(v, copy=True) for k, v in obs.items()})
        obs, _, terminated, truncated, _ = env.step(np.zeros(9))
        if terminated or truncated:
            break
    env.close()
    return out, info


class _Recorder:
    """Reads every Measurement field in ``step_row`` and keeps the values; its row is fixed."""

    def __init__(self, fields=None) -> None:
        if fields is not None:
            self.step_row_fields = fields
        self.seen: list[dict] = []

    def reset(self, context, prior) -> None:
        self.row = np.array(prior.as_action(), dtype=float)
        self.seen = []

    def step(self, measurement):
        raise NotImplementedError

    def step_row(self, m):
        self.seen.append({f: getattr(m, f, None) for f in FIELDS})
        return self.row, None, None, None


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return a.shape == b.shape and np.array_equal(a, b)
    return type(a) is type(b) and a == b


@pytest.mark.parametrize("fields", [None, (), ("dv_r",), ("dtheta_r", "dv_r"), IMU_FIELDS])
def test_step_view_fields_equal_the_decoded_measurement(fields):
    observations, info = _observations()
    agent = EstimatorAgent(_Recorder(fields))
    agent.reset(info)
    for o in observations:
        agent.act(o)
    seen = agent.estimator.seen
    assert len(seen) == len(observations)
    n_view = 0
    for k, (o, got) in enumerate(zip(observations, seen)):
        ref = agent.codec.decode(o, k)
        if ref.gnss is None:
            n_view += 1
            for f in FIELDS:
                assert _same(got[f], getattr(ref, f, None)), (k, f)
    assert n_view == len(observations) - 2  # GNSS epochs at 1 s and 2 s: decoded, not viewed


def test_step_view_reads_the_odometer_of_each_step():
    observations, info = _observations({"odometer": {"enabled": True}})
    agent = EstimatorAgent(_Recorder(("dv_r",)))
    agent.reset(info)
    for o in observations:
        agent.act(o)
    ds = [s["odometer_ds_m"] for s in agent.estimator.seen]
    assert all(isinstance(x, float) for x in ds)
    assert ds == [float(o["odometer_ds"][0]) for o in observations]


def test_action_and_extras_of_the_fast_path():
    observations, info = _observations()
    agent = EstimatorAgent(_Recorder(("dv_r",)))
    agent.reset(info)
    scale = np.asarray(info["action_scale"])
    row = agent.estimator.row
    for o in observations:
        a = agent.act(o)
        assert type(a) is EstimateAction and a.shape == (9,)
        assert np.array_equal(np.asarray(a), row / scale)
        cov, nis, dof, cpu = a.extras
        assert cov is None and nis is None and dof == 0
        assert isinstance(cpu, float) and cpu >= 0.0
        assert a.copy().extras is a.extras and a[:].extras is a.extras  # views and copies keep them
    last = agent.last_estimate
    assert last is not None and last.t == float(observations[-1]["t"][0])
    assert np.array_equal(last.as_action(), row)


def test_the_hint_is_on_cost_not_content():
    """An estimator that names fewer fields than it reads still gets every field right."""
    from navsim.estimators import make

    observations, info = _observations()
    plain, hinted = EstimatorAgent(make("lc-ekf")), EstimatorAgent(make("lc-ekf"))
    hinted.estimator.step_row_fields = ("dv_r",)  # lc-ekf reads all four
    plain.reset(info)
    hinted.reset(info)
    for o in observations:
        x, y = plain.act(o), hinted.act(o)
        assert np.array_equal(np.asarray(x), np.asarray(y))
        assert np.array_equal(x.extras[0], y.extras[0])


@pytest.mark.parametrize("estimator", ["lc-ekf", "full-state-ekf"])
def test_without_cpu_time_the_same_solutions_and_no_cpu_score(estimator):
    """``cpu_time=False`` reads no clock: the same actions and covariances bit for bit (the
    estimator's call is the same; only the two clock reads around it are left out), the
    CPU extra None, and the episode score's CPU figures NaN while every accuracy figure
    is equal. lc-ekf takes the fast path (``step_row``), full-state-ekf ``step``."""
    import dataclasses
    import math

    from navsim.estimators import make

    scores, actions = {}, {}
    for timed in (True, False):
        env = gym.make("navsim/PaperRail-v0", timing={"duration_s": 3.0})
        agent = EstimatorAgent(make(estimator), cpu_time=timed)
        assert agent.cpu_time is timed
        obs, info = env.reset(seed=4)
        agent.reset(info)
        rows = []
        while True:
            a = agent.act(obs)
            rows.append((np.asarray(a).copy(), a.extras))
            obs, _, terminated, truncated, info = env.step(a)
            if terminated or truncated:
                break
        scores[timed], actions[timed] = info["episode_score"], rows
        env.close()
    for (a, ea), (b, eb) in zip(actions[True], actions[False]):
        assert np.array_equal(a, b)
        assert (ea[0] is None and eb[0] is None) or np.array_equal(ea[0], eb[0])
        assert isinstance(ea[3], float) and eb[3] is None
    cpu_fields = {"step_time_us", "cpu_total_s", "realtime_factor"}
    timed, untimed = dataclasses.asdict(scores[True]), dataclasses.asdict(scores[False])
    for key in cpu_fields:
        assert math.isfinite(timed[key]) and math.isnan(untimed[key]), key
    rest = [k for k in timed if k not in cpu_fields]
    assert "horizontal_rmse_m" in rest
    for key in rest:
        x, y = timed[key], untimed[key]
        assert (x == y) or (isinstance(x, float) and math.isnan(x) and math.isnan(y)) \
            or (isinstance(x, np.ndarray) and np.array_equal(x, y, equal_nan=True)), key


def test_cpu_time_must_be_a_bool():
    from navsim.errors import ConfigError

    with pytest.raises(ConfigError, match="cpu_time"):
        EstimatorAgent("ins-only", cpu_time="no")
