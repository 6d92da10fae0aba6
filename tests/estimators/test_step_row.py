"""The step-wise fast path ``step_row`` (``navsim.estimators.base.RowStepping``) and
``EstimatorAgent``'s use of it.

``step_row`` runs the operations of ``step`` in the same order and only skips building the
:class:`Estimate` and its diagnostics, so row, covariance and NIS equal ``step``'s bit for
bit. Against ``step_batch``: position and velocity bit for bit (the same operations), the
attitude angles as ``tolerances.assert_same_solution`` (libm's atan2/asin in the compiled
one-step INS path, NumPy's in the batch); the covariance between epochs is
one (n, 9) @ (9, 81) product in batch and one row at a time step by step, so it is held
to the rounding of a 9-term sum (tests/tolerances.py). ``EstimatorAgent`` hands a step
without a GNSS epoch over as views of the observation in a reused object; its actions and
their extras must equal those of the agent that calls ``step`` on decoded measurements.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from tolerances import assert_covariance_close, assert_same_arithmetic, assert_same_solution

from navsim.episode import make_context, measurement_batch
from navsim.estimators import make
from navsim.estimators.base import RowStepping, row_stepping
from navsim.scenario import load_scenario
from navsim.simulator import Simulator

FAST = ["lc-ekf", "tc-ekf", "tc-ukf", "along-track", "paper-ekf"]
OVER = {"timing": {"duration_s": 4.0}, "outages": {"windows_s": [[1.5, 2.5]]}}


def _inputs(seed: int = 3):
    sc = load_scenario("paper-2012").with_overrides(OVER)
    sim = Simulator(sc)
    start = sim.reset(seed)
    ctx = make_context(sim)
    batch = measurement_batch(sim.advance(round(4.0 / ctx.nav_period_s)), np.asarray(sim.constellation.prn),
                              ctx.nav_period_s)
    return ctx, start.prior, batch


def _nis(x) -> float:
    return math.nan if x is None else float(x)


@pytest.mark.parametrize("name", FAST)
def test_step_row_equals_step_and_batch(name):
    ctx, prior, batch = _inputs()
    a, b, c = make(name), make(name), make(name)
    assert isinstance(b, RowStepping)
    for est in (a, b, c):
        est.reset(ctx, prior)
    ms = [batch.measurement(i) for i in range(len(batch))]
    by_step = [a.step(m) for m in ms]
    by_row = [b.step_row(m) for m in ms]
    ref = c.step_batch(batch)
    rows = np.array([r[0] for r in by_row])
    assert_same_arithmetic(rows, np.array([e.as_action() for e in by_step]), "row vs step")
    assert_same_arithmetic(np.array([r[1] for r in by_row]), np.array([e.covariance for e in by_step]), "cov vs step")
    assert_same_arithmetic([_nis(r[2]) for r in by_row], [_nis(e.nis) for e in by_step], "nis vs step")
    assert [r[3] for r in by_row] == [e.nis_dof for e in by_step]
    assert_same_solution(rows, ref.solution, "vs batch")
    assert_same_arithmetic([_nis(r[2]) for r in by_row], ref.nis, "nis vs batch")
    assert_covariance_close(np.array([r[1] for r in by_row]), ref.covariance, n_terms=9)
    assert sum(r[2] is not None for r in by_row) == 3  # epochs at 1, 3, 4 s; 2 s falls in the outage


class _StepOnly:
    """The same estimator seen through ``reset`` and ``step`` only (the agent's general path)."""

    def __init__(self, inner) -> None:
        self.inner = inner

    def reset(self, context, prior) -> None:
        self.inner.reset(context, prior)

    def step(self, measurement):
        return self.inner.step(measurement)


@pytest.mark.parametrize("name", [*FAST, "gnss-ls", "gnss-cv"])  # the GNSS-only ones: tests/estimators/test_gnss_only.py
def test_agent_fast_path_equals_step_path(name):
    gym = pytest.importorskip("gymnasium")
    import navsim.envs  # noqa: F401  (registers the ids)
    from navsim.envs import EstimatorAgent

    env = gym.make("navsim/PaperRail-v0", score=False, **OVER)
    obs, info = env.reset(seed=1)
    observations = []
    zero = np.zeros(9)
    while True:
        observations.append({k: np.array(v, copy=True) for k, v in obs.items()})
        obs, _, terminated, truncated, _ = env.step(zero)
        if terminated or truncated:
            break
    env.close()
    fast, plain = EstimatorAgent(make(name)), EstimatorAgent(_StepOnly(make(name)))
    fast.reset(info)
    plain.reset(info)
    assert fast._step_row is not None and plain._step_row is None
    for o in observations:
        x, y = fast.act(o), plain.act(o)
        assert_same_arithmetic(np.asarray(x), np.asarray(y), name)
        assert_same_arithmetic(x.extras[0], y.extras[0], "covariance")
        assert _nis(x.extras[1]) == _nis(y.extras[1]) or (x.extras[1] is None and y.extras[1] is None)
        assert x.extras[2] == y.extras[2]
    last, ref = fast.last_estimate, plain.last_estimate
    assert_same_arithmetic(last.as_action(), ref.as_action(), "last estimate")


def test_agent_keeps_step_of_a_subclass_that_overrides_it():

    from navsim.estimators.loosely import LooselyCoupledEkf

    class Shifted(LooselyCoupledEkf):
        def step(self, measurement):
            return super().step(measurement)

    assert row_stepping(Shifted()) is None
    est = LooselyCoupledEkf()
    assert row_stepping(est) == est.step_row
