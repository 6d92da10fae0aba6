"""The plant FMU under fmpy gives the core's numbers for the same scenario and seed."""

from __future__ import annotations

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import simulate_fmu  # noqa: E402

from navsim.simulator import Simulator  # noqa: E402

SEED = 7


def _core(scenario, seed=SEED):
    sim = Simulator(scenario)
    start = sim.reset(seed)
    return sim, start, sim.advance(scenario.timing.steps)


@pytest.mark.parametrize("fmi", [2, 3])
def test_simulate_fmu_equals_core(fmi, request, scenario):
    path = request.getfixturevalue(f"plant{fmi}")
    sim, start, chunk = _core(scenario)
    n_sat = len(sim.constellation.prn)
    if fmi == 2:
        names = (["truth.s_m", "truth.lat_rad", "truth.h_m", "gnss.new_epoch", "gnss.t_s"]
                 + [f"imu.dv_r1[{i}]" for i in (1, 2, 3)] + [f"imu.dtheta_r3[{i}]" for i in (1, 2, 3)]
                 + [f"gnss.pseudorange_m[{j}]" for j in range(1, n_sat + 1)]
                 + [f"gnss.valid[{j}]" for j in range(1, n_sat + 1)])
    else:
        names = ["truth.s_m", "truth.lat_rad", "truth.h_m", "gnss.new_epoch", "gnss.t_s", "imu.dv_r1",
                 "imu.dtheta_r3", "gnss.pseudorange_m", "gnss.valid"]
    dt = scenario.timing.nav_period_s
    res = simulate_fmu(str(path), stop_time=scenario.timing.duration_s, step_size=dt, output=names,
                       start_values={"seed": SEED})
    assert len(res) == scenario.timing.steps + 1
    r = res[1:]  # the row at t0 holds the start values

    def col(base, k=None):
        if fmi == 2:
            return np.column_stack([r[f"{base}[{i}]"] for i in range(1, k + 1)])
        return np.asarray(r[base].tolist()) if k else r[base]

    np.testing.assert_array_equal(r["truth.s_m"], chunk.truth.s)
    np.testing.assert_array_equal(r["truth.lat_rad"], chunk.truth.lat)
    np.testing.assert_array_equal(r["truth.h_m"], chunk.truth.h)
    np.testing.assert_array_equal(col("imu.dv_r1", 3), chunk.imu.dv_r[:, 0])
    np.testing.assert_array_equal(col("imu.dtheta_r3", 3), chunk.imu.dtheta_r[:, 2])
    epochs = np.flatnonzero(r["gnss.new_epoch"])
    np.testing.assert_array_equal(epochs, chunk.gnss_step)
    np.testing.assert_array_equal(r["gnss.t_s"][epochs], chunk.gnss.t)
    np.testing.assert_array_equal(col("gnss.pseudorange_m", n_sat)[epochs], chunk.gnss.pseudorange_m)
    np.testing.assert_array_equal(col("gnss.valid", n_sat)[epochs].astype(bool), chunk.gnss.valid)
    assert chunk.gnss.valid[(chunk.gnss.t > 2.0) & (chunk.gnss.t < 4.0)].sum() == 0  # the outage window


def test_prior_and_initial_outputs(plant3, scenario):
    from navsim.fmu.master import FmuInstance

    sim, start, _ = _core(scenario)
    with FmuInstance(plant3, "p") as inst:
        inst.initialize({"seed": SEED})
        out = inst.get(["prior.lat_rad", "prior.velocity_n", "prior.heading_rad", "truth.s_m", "gnss.prn",
                        "navsim.config_hash", "navsim.version"])
    import navsim

    assert out["prior.lat_rad"] == start.prior.lat and out["prior.heading_rad"] == start.prior.heading
    np.testing.assert_array_equal(out["prior.velocity_n"], start.prior.velocity_n)
    np.testing.assert_array_equal(out["gnss.prn"], sim.constellation.prn)
    assert out["truth.s_m"] == start.truth.s[0]
    assert out["navsim.config_hash"] == scenario.config_hash() and out["navsim.version"] == navsim.__version__


def test_long_communication_step_composes_navigation_steps(plant2, scenario):
    """A step of 2 ticks equals the core run with a 2-sample navigation step."""
    from navsim.fmu.master import FmuInstance

    coarse = scenario.with_overrides({"timing": {"nav_period_s": 0.02}})
    _, _, ref = _core(coarse)
    with FmuInstance(plant2, "p") as inst:
        inst.initialize({"seed": SEED})
        names = [f"imu.dtheta_r{r}[{i}]" for r in (1, 2, 3, 4) for i in (1, 2, 3)] + ["time.steps_in_interval"]
        rows = []
        for k in range(20):
            inst.do_step(k * 0.02, 0.02)
            rows.append(inst.get(names))
    got = np.array([[row[f"imu.dtheta_r{r}[{i}]"] for r in (1, 2, 3, 4) for i in (1, 2, 3)] for row in rows])
    assert all(row["time.steps_in_interval"] == 2 for row in rows)
    np.testing.assert_allclose(got, ref.imu.dtheta_r[:20].reshape(20, 12), rtol=1e-12, atol=1e-20)


def test_parameters_change_the_scenario(plant3, scenario):
    """Noise and preset parameters reach the simulator: ideal GNSS gives zero-noise pseudoranges."""
    from navsim.fmu.master import FmuInstance

    with FmuInstance(plant3, "p") as inst:
        inst.initialize({"seed": 1, "gnss.pseudorange_sigma_m": 0.0, "outages.windows_s": "[]"})
        for k in range(100):
            inst.do_step(k * 0.01, 0.01)
        out = inst.get(["navsim.config_hash", "gnss.valid"])
    ref = scenario.with_overrides({"gnss": {"overrides": {"pseudorange_sigma_m": 0.0}}, "outages": {"windows_s": []}})
    assert out["navsim.config_hash"] == ref.config_hash() != scenario.config_hash()
    _, _, chunk = _core(ref, seed=1)
    assert out["gnss.valid"].tolist() == chunk.gnss.valid[0].tolist()
