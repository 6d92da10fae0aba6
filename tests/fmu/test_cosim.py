"""Plant + estimator FMUs connected give the episode score of `navsim run`."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("fmpy")

from navsim import estimators  # noqa: E402
from navsim.episode import run_episode  # noqa: E402
from navsim.metrics import score_episode  # noqa: E402

SEED = 3
CPU = {"estimator", "step_time_us", "cpu_total_s", "realtime_factor"}


@pytest.fixture(scope="module")
def reference(scenario):
    return run_episode(scenario, estimators.make("lc-ekf"), seed=SEED, use_batch=False)


@pytest.mark.parametrize("fmi", [2, 3])
def test_master_loop_equals_run_episode(fmi, request, scenario, reference):
    from navsim.fmu.master import cosimulate

    record = cosimulate(request.getfixturevalue(f"plant{fmi}"), request.getfixturevalue(f"estimator{fmi}"),
                        seed=SEED)
    for field in ("truth_s", "truth_lat", "truth_h", "truth_velocity_n", "truth_hpr", "est_lat", "est_lon", "est_h",
                  "est_velocity_n", "est_hpr", "est_cov", "nis", "nis_dof", "gnss_t", "gnss_n_valid",
                  "gnss_receiver_outage"):
        np.testing.assert_array_equal(getattr(record, field), getattr(reference, field), err_msg=field)
    assert record.prior.lat == reference.prior.lat
    np.testing.assert_array_equal(record.prior.covariance, reference.prior.covariance)
    got, want = score_episode(record).to_flat_dict(), score_episode(reference).to_flat_dict()
    assert {k: got[k] for k in got if k not in CPU} == {k: want[k] for k in want if k not in CPU}
    assert got["nis_updates"] > 0 and got["outage_count"] == 1


def test_score_matches_batch_runner(scenario, reference):
    """`navsim run` uses the estimator's batch path: same score to rounding."""
    batch = run_episode(scenario, estimators.make("lc-ekf"), seed=SEED)
    a, b = score_episode(batch).to_flat_dict(), score_episode(reference).to_flat_dict()
    for k, v in a.items():
        if k not in CPU and isinstance(v, float):
            assert v == pytest.approx(b[k], rel=1e-7, abs=1e-9), k


def test_estimator_fmu_refuses_other_steps(estimator3):
    from navsim.fmu.master import FmuCallError, FmuInstance

    with FmuInstance(estimator3, "e") as inst:
        inst.initialize()
        with pytest.raises(FmuCallError, match="exactly one navigation step"):
            inst.do_step(0.0, 0.02)
