"""The shared variable table: names, units, shapes; what the faces may see."""

from __future__ import annotations

import dataclasses


from navsim.fmu.variables import (UNITS, Dimensions, Var, action_variables, estimator_variables,
                                  observation_variables, plant_variables, scalar_names)

DIMS = Dimensions(channels=5, orders=3, samples_per_step=2)


def test_scalar_names_row_major_one_based():
    v = Var("gnss.sat_pos_e", "real", "output", "discrete", "m", "x", shape=(2, 3))
    assert scalar_names(v) == [f"gnss.sat_pos_e[{i},{j}]" for i in (1, 2) for j in (1, 2, 3)]
    assert scalar_names(Var("a", "real", "output", "discrete", "", "x")) == ["a"]


def test_tables_unique_names_known_units_and_sizes():
    for table in (plant_variables(DIMS), estimator_variables(DIMS)):
        names = [v.name for v in table]
        assert len(names) == len(set(names))
        assert all(v.unit == "" or v.unit in UNITS for v in table)
    plant = {v.name: v for v in plant_variables(DIMS)}
    assert plant["gnss.pseudorange_m"].shape == (5,)
    assert plant["imu.dtheta_sub"].shape == (2, 3)
    assert [n for n in plant if n.startswith("imu.dtheta_r")] == ["imu.dtheta_r1", "imu.dtheta_r2", "imu.dtheta_r3"]
    # r-fold integrals carry rad.s^(r-1) and m/s.s^(r-1)
    assert [plant[f"imu.dtheta_r{r}"].unit for r in (1, 2, 3)] == ["rad", "rad.s", "rad.s2"]
    assert [plant[f"imu.dv_r{r}"].unit for r in (1, 2, 3)] == ["m/s", "m", "m.s"]


def test_estimator_inputs_are_plant_outputs_of_same_kind_and_never_truth():
    plant = {v.name: v for v in plant_variables(DIMS)}
    inputs = [v for v in estimator_variables(DIMS) if v.causality == "input"]
    assert inputs
    for v in inputs:
        p = plant[v.name]
        assert p.causality == "output" and (p.type, p.shape, p.unit) == (v.type, v.shape, v.unit)
        assert not v.name.startswith("truth.")
    assert all(v.start is not None for v in inputs)


def test_observation_and_action_tables():
    obs = observation_variables(DIMS)
    assert not any(v.group in ("truth", "prior", "parameter") for v in obs)
    assert {"gnss.valid", "gnss.new_epoch", "imu.dv_r1", "time.t_s"} <= {v.name for v in obs}
    act = action_variables()
    # the order of Estimate.as_action: lat, lon, h, vE, vN, vU, heading, pitch, roll
    flat = [n for v in act for n in scalar_names(v)]
    assert flat == ["nav.lat_rad", "nav.lon_rad", "nav.h_m", "nav.velocity_n[1]", "nav.velocity_n[2]",
                    "nav.velocity_n[3]", "nav.heading_rad", "nav.pitch_rad", "nav.roll_rad"]
    assert all(v.low is not None and v.high is not None and v.low < v.high for v in act)


def test_dimensions_of_simulator(scenario):
    from navsim.simulator import Simulator

    sim = Simulator(scenario)
    d = Dimensions.of(sim)
    assert d == Dimensions(len(sim.constellation.prn), scenario.imu.orders, scenario.timing.samples_per_step)
    assert all(isinstance(x, int) for x in (d.channels, d.orders, d.samples_per_step)) and d.sensors == frozenset()
    odo = Dimensions.of(Simulator(scenario.with_overrides({"odometer": {"enabled": True}})))
    assert odo.sensors == frozenset({"odometer"})


def test_sensor_variables_come_from_the_signal_table(monkeypatch):
    """Every sensor signal of navsim.signals.SIGNALS is a plant output and an estimator
    input of the same name, unit and shape; a signal declared there appears in both FMUs
    (declared here with a flag the dimensions carry)."""
    import navsim.fmu.variables as fv
    from navsim import signals

    plant = {v.name: v for v in plant_variables(DIMS)}
    est = {v.name: v for v in estimator_variables(DIMS)}
    for sig in signals.SIGNALS:
        if not sig.observation or sig.optional:
            continue
        names = [f"{sig.fmu_name}{r}" for r in range(1, DIMS.orders + 1)] if sig.order_units else [sig.fmu_name]
        for name in names:
            assert plant[name].causality == "output" and est[name].causality == "input", name
            assert plant[name].description.endswith(sig.description) or sig.description in plant[name].description
    extra = signals.Signal("wheel_temp", "odometer", (1,), "", "A new sensor output", "odometer.temperature",
                           observation=True)
    monkeypatch.setattr(fv, "SIGNALS", (*signals.SIGNALS, extra))
    p = {v.name: v for v in fv.plant_variables(DIMS)}
    e = {v.name: v for v in fv.estimator_variables(DIMS)}
    assert p["odometer.temperature"].causality == "output" and p["odometer.temperature"].start is None
    assert e["odometer.temperature"].causality == "input" and e["odometer.temperature"].start == 0.0
    assert p["odometer.temperature"].shape == () and p["odometer.temperature"].description == "A new sensor output"
