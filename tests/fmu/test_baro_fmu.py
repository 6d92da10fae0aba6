"""The barometric altimeter through the FMUs: the plant outputs baro.altitude_m (the name,
unit and description of its signal in navsim.signals), the estimator FMU feeds it to
lc-ekf, and the pair gives run_episode's numbers bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("fmpy")

from navsim import estimators  # noqa: E402
from navsim.episode import run_episode  # noqa: E402
from navsim.signals import BARO_KEY, signal  # noqa: E402

SEED = 3


def test_baro_through_the_fmus(fmu_dir, scenario):
    pytest.importorskip("pythonfmu")
    from navsim.fmu.build import build_fmu
    from navsim.fmu.master import FmuInstance, cosimulate
    from navsim.fmu.variables import Dimensions, estimator_variables, plant_variables
    from navsim.simulator import Simulator

    baro = scenario.with_overrides({"baro": {"enabled": True}})
    dims = Dimensions.of_scenario(baro, 24)
    name = signal(BARO_KEY).fmu_name
    assert name in {v.name for v in plant_variables(dims) if v.causality == "output"}
    assert name in {v.name for v in estimator_variables(dims) if v.causality == "input"}
    assert name not in {v.name for v in plant_variables(Dimensions.of_scenario(scenario, 24))}
    plant = build_fmu(baro, "plant", 2, fmu_dir / "plant_baro.fmu")
    est = build_fmu(baro, "estimator", 2, fmu_dir / "estimator_baro.fmu", estimator="lc-ekf")
    record = cosimulate(plant, est, seed=SEED)
    reference = run_episode(baro, estimators.make("lc-ekf"), seed=SEED, use_batch=False)
    for field in ("est_lat", "est_lon", "est_h", "est_velocity_n", "est_hpr", "est_cov", "nis"):
        np.testing.assert_array_equal(getattr(record, field), getattr(reference, field), err_msg=field)
    blind = run_episode(baro, estimators.make("lc-ekf", baro="none"), seed=SEED, use_batch=False)
    assert not np.array_equal(blind.est_h, reference.est_h)  # the reading is really used
    sim = Simulator(baro)
    sim.reset(SEED)
    core = sim.advance(10).baro.altitude_m
    with FmuInstance(plant, "p") as inst:
        inst.initialize({"seed": SEED})
        got = []
        for k in range(10):
            inst.do_step(k * 0.01, 0.01)
            got.append(inst.get([name])[name])
    np.testing.assert_array_equal(np.array(got, dtype=float).ravel(), core)
