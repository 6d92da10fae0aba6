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


@pytest.mark.parametrize("fmi", [2, 3])
def test_step_row_path_equals_step_path(fmi, request, monkeypatch):
    """The estimator FMU steps lc-ekf through ``step_row`` (a view of its value store
    between GNSS epochs): the same operations as ``step`` on a Measurement, so every
    output equals the ``step`` path's (forced by hiding ``step_row``) bit for bit."""
    from navsim.estimators.base import row_stepping
    from navsim.fmu import runtime
    from navsim.fmu.master import cosimulate

    plant, est = request.getfixturevalue(f"plant{fmi}"), request.getfixturevalue(f"estimator{fmi}")
    seen: list = []

    def spy(estimator):
        fast = row_stepping(estimator)
        seen.append(fast)
        return fast

    monkeypatch.setattr(runtime, "row_stepping", spy)
    fast = cosimulate(plant, est, seed=SEED)
    assert len(seen) == 1 and seen[0] is not None  # the FMU (in this process) took the step_row path
    monkeypatch.setattr(runtime, "row_stepping", lambda estimator: None)
    slow = cosimulate(plant, est, seed=SEED)
    for field in ("est_lat", "est_lon", "est_h", "est_velocity_n", "est_hpr", "est_cov", "nis", "nis_dof"):
        np.testing.assert_array_equal(getattr(fast, field), getattr(slow, field), err_msg=field)
    assert np.isfinite(fast.nis).sum() > 0  # the episode had updates (GNSS epochs through a Measurement)


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
        # the call, its status and the FMU's log line (FmuInstance.do_step formats them only on failure)
        with pytest.raises(FmuCallError, match=r"^e: doStep\(t=0\.0, h=0\.03\) failed \(error\): doStep refused: .*"
                                               "spans 3 navigation steps, which do not divide the GNSS period"):
            inst.do_step(0.0, 0.03)
        with pytest.raises(FmuCallError, match="not a whole number"):
            inst.do_step(0.0, 0.015)


def test_odometer_through_the_fmus(fmu_dir, scenario):
    """With [odometer] enabled the plant outputs odometer.ds_m / odometer.pulses and the
    estimator FMU feeds them to lc-ekf: the same numbers as run_episode."""
    pytest.importorskip("pythonfmu")
    from navsim.fmu.build import build_fmu
    from navsim.fmu.master import cosimulate
    from navsim.fmu.variables import Dimensions, plant_variables

    odo = scenario.with_overrides({"odometer": {"enabled": True}})
    plant = build_fmu(odo, "plant", 2, fmu_dir / "plant_odo.fmu")
    est = build_fmu(odo, "estimator", 2, fmu_dir / "estimator_odo.fmu", estimator="lc-ekf")
    names = {v.name for v in plant_variables(Dimensions(channels=24, orders=4, samples_per_step=1, sensors=frozenset({"odometer"})))}
    assert {"odometer.ds_m", "odometer.pulses"} <= names
    record = cosimulate(plant, est, seed=SEED)
    reference = run_episode(odo, estimators.make("lc-ekf"), seed=SEED, use_batch=False)
    for field in ("est_lat", "est_lon", "est_h", "est_velocity_n", "est_hpr", "est_cov", "nis"):
        np.testing.assert_array_equal(getattr(record, field), getattr(reference, field), err_msg=field)
    # the odometer changed the solution (it is really used)
    plain = run_episode(scenario, estimators.make("lc-ekf"), seed=SEED, use_batch=False)
    assert not np.array_equal(plain.est_lat, reference.est_lat)
    # a communication step of 5 navigation steps gives the sum of their pulses and distances
    from navsim.fmu.master import FmuInstance
    from navsim.simulator import Simulator

    sim = Simulator(odo)
    sim.reset(SEED)
    core = sim.advance(100).odometer
    with FmuInstance(plant, "p") as inst:
        inst.initialize({"seed": SEED})
        for k in range(20):
            inst.do_step(k * 0.05, 0.05)
            row = inst.get(["odometer.ds_m", "odometer.pulses"])
            assert row["odometer.pulses"] == int(core.pulses[5 * k:5 * k + 5].sum())
            assert row["odometer.ds_m"] == pytest.approx(float(core.ds_m[5 * k:5 * k + 5].sum()), rel=1e-15, abs=1e-15)


def test_estimator_fmu_builds_no_simulator(estimator2, scenario, tmp_path, monkeypatch):
    """The estimator FMU takes its context from make_context(scenario) and the prior
    covariance from the [initial] section: no Simulator is built (its constructor is made
    to fail here); the covariance is the one the simulator's prior carries."""
    import zipfile

    import navsim.simulator
    from navsim.fmu.runtime import EstimatorRuntime
    from navsim.simulator import Simulator

    want = Simulator(scenario).reset(0).prior.covariance
    with zipfile.ZipFile(estimator2) as z:
        z.extractall(tmp_path)

    def refuse(*args, **kwargs):
        raise AssertionError("the estimator FMU built a Simulator")

    monkeypatch.setattr(navsim.simulator.Simulator, "__init__", refuse)
    rt = EstimatorRuntime(str(tmp_path / "resources"), 2)
    rt.exit_initialization_mode()
    np.testing.assert_array_equal(rt.prior_covariance, want)
    assert rt.context.nav_period_s == scenario.timing.nav_period_s and rt.context.orders == scenario.imu.orders
    assert rt.context.config_hash == scenario.config_hash()
    assert len(rt.prn) == rt.dims.channels == 24
