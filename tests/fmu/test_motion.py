"""An external co-simulation FMU (C train dynamics) as the motion source."""

from __future__ import annotations

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")

from navsim import estimators  # noqa: E402
from navsim.episode import run_episode  # noqa: E402
from navsim.errors import ConfigError  # noqa: E402
from navsim.fmu.motion import FmuDrivenSimulator, FmuMotionSource, MotionMapping, parse_mapping  # noqa: E402

TRACTION = {"F_traction": 2.0e5}
OFFSET = 100.0


def test_simulator_driven_by_the_train_fmu_follows_its_trajectory(train_fmu, scenario):
    ref = fmpy.simulate_fmu(str(train_fmu), stop_time=scenario.timing.duration_s, step_size=0.01,
                            start_values=TRACTION)
    source = FmuMotionSource(train_fmu, MotionMapping("s", "v", "a", s_offset_m=OFFSET, inputs=TRACTION), 0.01)
    try:
        sim = FmuDrivenSimulator(scenario, source)
        assert sim.scenario.motion.profile == "external" and sim.scenario.motion.start_s_m == OFFSET
        rec = run_episode(sim.scenario, estimators.make("ins-only"), seed=1, simulator=sim, chunk_steps=64)
        rec2 = run_episode(sim.scenario, estimators.make("ins-only"), seed=1, simulator=sim, chunk_steps=7)
    finally:
        source.close()
    # the quintic Hermite profile passes through every pushed sample
    np.testing.assert_allclose(rec.truth_s, OFFSET + ref["s"][1:], rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(rec.truth_velocity_n, axis=1), ref["v"][1:], rtol=1e-9)
    # the train accelerates (traction > resistance): speed grows from 10 m/s
    assert ref["v"][-1] > 10.5
    # reset restarts the FMU: a second episode is identical, whatever the chunking
    np.testing.assert_array_equal(rec.truth_lat, rec2.truth_lat)
    np.testing.assert_array_equal(rec.est_lat, rec2.est_lat)


def test_plant_fmu_with_motion_inputs_equals_driven_simulator(train_fmu, plant2, scenario):
    """Train FMU -> plant FMU inputs (Gauss-Seidel master) == FmuDrivenSimulator in the core."""
    from navsim.fmu.master import FmuInstance

    source = FmuMotionSource(train_fmu, MotionMapping("s", "v", "a", s_offset_m=OFFSET, inputs=TRACTION), 0.01)
    try:
        sim = FmuDrivenSimulator(scenario, source)
        sim.reset(4)
        chunk = sim.advance(200)
    finally:
        source.close()
    train = FmuInstance(train_fmu, "train")
    plant = FmuInstance(plant2, "plant")
    try:
        train.initialize(TRACTION)
        x0 = train.get(["s", "v", "a"])
        plant.initialize({"seed": 4, "motion.use_inputs": True, "motion.s_m": OFFSET + x0["s"],
                          "motion.speed_mps": x0["v"], "motion.accel_mps2": x0["a"]})
        s_out, dv = [], []
        for k in range(200):
            train.do_step(k * 0.01, 0.01)
            x = train.get(["s", "v", "a"])
            plant.set({"motion.s_m": OFFSET + x["s"], "motion.speed_mps": x["v"], "motion.accel_mps2": x["a"]})
            plant.do_step(k * 0.01, 0.01)
            y = plant.get(["truth.s_m", "imu.dv_r1[2]"])
            s_out.append(y["truth.s_m"])
            dv.append(y["imu.dv_r1[2]"])
    finally:
        train.free()
        plant.free()
    np.testing.assert_array_equal(s_out, chunk.truth.s)
    np.testing.assert_array_equal(dv, chunk.imu.dv_r[:, 0, 1])


def test_mapping_parsing_and_errors(train_fmu):
    m = parse_mapping("s=x,speed=v,accel=none,offset=12.5,scale=-1", ["F_traction=3e5", "flag=true"])
    assert (m.position, m.speed, m.accel, m.s_offset_m, m.s_scale) == ("x", "v", None, 12.5, -1.0)
    assert m.inputs == {"F_traction": 3e5, "flag": True}
    with pytest.raises(ConfigError, match="--motion-map"):
        parse_mapping("pos=x")
    with pytest.raises(ConfigError, match="s_scale"):
        MotionMapping(s_scale=2.0)
    with pytest.raises(ConfigError, match="motion_map"):
        FmuMotionSource(train_fmu, MotionMapping("x", "v", "a"), 0.01)


def test_backward_difference_when_no_acceleration_output(train_fmu):
    source = FmuMotionSource(train_fmu, MotionMapping("s", "v", None, inputs=TRACTION), 0.01)
    try:
        source.start()
        _, v1, a1 = source.step()
        _, v2, a2 = source.step()
    finally:
        source.close()
    assert a2 == pytest.approx((v2 - v1) / 0.01, rel=1e-12) and 0.3 < a2 < 0.6
