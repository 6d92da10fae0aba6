"""A second, independent importer: libcosimpy (libcosim, FMI Library) runs the plant FMU
alone, and plant + estimator connected by name.

libcosim's fixed-step algorithm is a Jacobi master (every slave steps on the values
exchanged at the start of the step), whatever order the slaves were added in: the
estimator FMU's solution after the step ending at (k+1)*dt is run_episode's of step k-1
(``nav.lag_steps`` = 1, ``nav.t_s`` = k*dt). Equality is bit for bit: the estimator
runs ``step`` on the very float64 values run_episode(use_batch=False) feeds it.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("libcosimpy")

from libcosimpy.CosimEnums import CosimVariableCausality, CosimVariableType  # noqa: E402
from libcosimpy.CosimExecution import CosimExecution  # noqa: E402
from libcosimpy.CosimObserver import CosimObserver  # noqa: E402
from libcosimpy.CosimSlave import CosimLocalSlave  # noqa: E402

from navsim import estimators  # noqa: E402
from navsim.episode import run_episode  # noqa: E402
from navsim.simulator import Simulator  # noqa: E402

SEED = 3
NAV = ["nav.lat_rad", "nav.lon_rad", "nav.h_m", "nav.velocity_n[1]", "nav.velocity_n[2]", "nav.velocity_n[3]",
       "nav.heading_rad", "nav.pitch_rad", "nav.roll_rad", "nav.t_s"]


def _quiet():
    try:  # quieten libcosim's debug log
        from libcosimpy.CosimLogging import CosimLogLevel, log_output_level

        log_output_level(CosimLogLevel.WARNING)
    except Exception:  # noqa: BLE001 - logging control differs between versions
        pass


def _variables(ex, idx):
    return {v.name.decode(): v for v in ex.slave_variables(idx)}


def test_plant_fmu_under_libcosim_gives_the_core_numbers(plant2, scenario):
    _quiet()
    steps, seed = 150, 5
    ex = CosimExecution.from_step_size(step_size=int(round(scenario.timing.nav_period_s * 1e9)))  # ns
    slave = CosimLocalSlave(fmu_path=str(plant2), instance_name="plant")
    idx = ex.add_local_slave(local_slave=slave)
    ref = {v.name.decode(): v.reference for v in ex.slave_variables(idx)}
    ex.integer_initial_value(idx, ref["seed"], seed)
    observer = CosimObserver.create_last_value()
    ex.add_observer(observer)
    names = ["truth.s_m", "truth.lat_rad", "time.t_s", "imu.dv_r1[1]", "imu.dv_r1[2]", "imu.dv_r1[3]"]
    assert ex.step(steps)
    got = dict(zip(names, observer.last_real_values(idx, [ref[n] for n in names])))
    sim = Simulator(scenario)
    sim.reset(seed)
    chunk = sim.advance(steps)
    assert got["time.t_s"] == chunk.t[-1]
    assert got["truth.s_m"] == chunk.truth.s[-1] and got["truth.lat_rad"] == chunk.truth.lat[-1]
    np.testing.assert_array_equal([got[f"imu.dv_r1[{i}]"] for i in (1, 2, 3)], chunk.imu.dv_r[-1, 0])


def _connect(ex, type_, *refs) -> bool:
    """libcosim's connection by variable type (0 = success). libcosimpy 0.0.6's
    ``connect_integer_variables`` looks up a misspelt attribute and raises, so integers go
    through the C function it wraps (``cosim_execution_connect_integer_variables``)."""
    if type_ == CosimVariableType.INTEGER.value:
        fn = getattr(ex, "_CosimExecution__connect_int_variables", None)
        if fn is not None:
            return fn(ex._CosimExecution__ptr, *refs) == 0
        return ex.connect_integer_variables(*refs) == 0
    method = {CosimVariableType.REAL.value: ex.connect_real_variables,
              CosimVariableType.BOOLEAN.value: ex.connect_boolean_variables,
              CosimVariableType.STRING.value: ex.connect_string_variables}[type_]
    return method(*refs) == 0


def run_pair(ex, plant_idx, est_idx, steps):
    """Connect every estimator input to the plant output of the same name, step ``steps``
    times and return the rows of the estimator's nav.* values and nav.step after each step."""
    pv, ev = _variables(ex, plant_idx), _variables(ex, est_idx)
    n = 0
    for name, v in ev.items():
        if v.causality == CosimVariableCausality.INPUT.value:
            src = pv[name]
            assert src.causality == CosimVariableCausality.OUTPUT.value and src.type == v.type, name
            assert _connect(ex, v.type, plant_idx, src.reference, est_idx, v.reference), name
            n += 1
    ex.integer_initial_value(plant_idx, pv["seed"].reference, SEED)
    observer = CosimObserver.create_last_value()
    ex.add_observer(observer)
    refs = [ev[k].reference for k in NAV]
    int_refs = [ev["nav.step"].reference, ev["nav.lag_steps"].reference]
    rows, counters = [], []
    for _ in range(steps):
        assert ex.step(1), "libcosim step failed"
        rows.append(observer.last_real_values(est_idx, refs))
        counters.append(observer.last_integer_values(est_idx, int_refs))
    return n, np.array(rows), np.array(counters)


@pytest.mark.parametrize("plant_first", [True, False], ids=["plant-added-first", "estimator-added-first"])
def test_plant_and_estimator_under_libcosim_equal_run_episode_lagged(plant_first, plant2, estimator2, scenario):
    _quiet()
    dt = scenario.timing.nav_period_s
    n = scenario.timing.steps
    ex = CosimExecution.from_step_size(step_size=int(round(dt * 1e9)))
    slaves = {"plant": CosimLocalSlave(fmu_path=str(plant2), instance_name="plant"),
              "estimator": CosimLocalSlave(fmu_path=str(estimator2), instance_name="estimator")}
    order = ["plant", "estimator"] if plant_first else ["estimator", "plant"]
    idx = {name: ex.add_local_slave(local_slave=slaves[name]) for name in order}
    connections, rows, counters = run_pair(ex, idx["plant"], idx["estimator"], n)
    assert connections > 280
    ref = run_episode(scenario, estimators.make("lc-ekf"), seed=SEED, use_batch=False)
    want = np.column_stack([ref.est_lat, ref.est_lon, ref.est_h, ref.est_velocity_n, ref.est_hpr, ref.t])
    np.testing.assert_array_equal(counters[:, 0], np.arange(n))  # Jacobi: one step behind
    np.testing.assert_array_equal(counters[:, 1], np.ones(n))
    np.testing.assert_array_equal(rows[1:], want[:n - 1])  # bit for bit (see the module docstring)
