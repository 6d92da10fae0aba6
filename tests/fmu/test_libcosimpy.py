"""A second, independent importer: libcosimpy (libcosim, FMI Library) runs the plant FMU."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("libcosimpy")

from libcosimpy.CosimExecution import CosimExecution  # noqa: E402
from libcosimpy.CosimObserver import CosimObserver  # noqa: E402
from libcosimpy.CosimSlave import CosimLocalSlave  # noqa: E402

from navsim.simulator import Simulator  # noqa: E402


def test_plant_fmu_under_libcosim_gives_the_core_numbers(plant2, scenario):
    try:  # quieten libcosim's debug log
        from libcosimpy.CosimEnums import CosimLogLevel
        from libcosimpy.CosimLogging import log_output_level

        log_output_level(CosimLogLevel.WARNING)
    except Exception:  # noqa: BLE001 - logging control differs between versions
        pass
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
