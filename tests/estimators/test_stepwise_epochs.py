"""The step-wise GNSS-epoch paths of lc-ekf, tc-ekf and tc-ukf against their batch path.

At a GNSS epoch without odometer, barometer or lever arm, ``step`` runs the epoch's fix
(lc-ekf), the INS step on the engine's one-step path and the update directly, without a
batch of one (``_epoch_step``). The operations are those of ``step_batch`` in the same
order, so states and NIS must be equal bit for bit, through an outage (epochs whose
channels are all invalid: no fix, no update) and after it. The covariance between epochs
is one (n, 9) @ (9, 81) product in batch and one row at a time in step: equal to the
rounding of a 9-term sum (tests/tolerances.py).
"""

from __future__ import annotations

import numpy as np
import pytest
from tolerances import assert_covariance_close, assert_same_field

from navsim.episode import run_episode
from navsim.estimators import make
from navsim.scenario import load_scenario


@pytest.mark.parametrize("name", ["lc-ekf", "tc-ekf", "tc-ukf"])
def test_epoch_step_path_equals_batch_through_an_outage(name, monkeypatch):
    sc = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 7.0},
                                                     "outages": {"windows_s": [[2.5, 4.5]]}})
    batch = run_episode(sc, make(name), seed=2, use_batch=True)
    est = make(name)
    calls = []
    inner = est.step_batch
    monkeypatch.setattr(est, "step_batch", lambda b: calls.append(len(b)) or inner(b))
    step = run_episode(sc, est, seed=2, use_batch=False)
    assert calls == []  # every epoch took the direct path
    for field in ("est_lat", "est_lon", "est_h", "est_velocity_n", "est_hpr", "nis"):
        assert_same_field(getattr(step, field), getattr(batch, field), field)
    assert_covariance_close(step.est_cov, batch.est_cov, n_terms=9)
    updates = np.isfinite(batch.nis)
    assert updates.sum() == 5  # epochs at 1, 2, 5, 6, 7 s; 3 and 4 s fall in the outage
