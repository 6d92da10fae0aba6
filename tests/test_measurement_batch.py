"""MeasurementBatch.of: one step as a batch of one, the inverse of ``measurement(0)``."""

from __future__ import annotations

import numpy as np
import pytest

from navsim.episode import measurements
from navsim.scenario import load_scenario
from navsim.simulator import Simulator
from navsim.types import MeasurementBatch


SENSORS = {"odometer": {"enabled": True, "preset": "rail-tachometer"}, "baro": {"enabled": True}}


@pytest.mark.parametrize("sensors", [{}, SENSORS])
def test_of_is_the_inverse_of_measurement(sensors):
    sc = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 1.5}, **sensors})
    sim = Simulator(sc)
    sim.reset(0)
    chunk = next(iter(sim.chunks(10_000)))
    ms = list(measurements(chunk, np.asarray(sim.constellation.prn), sc.timing.nav_period_s))
    assert any(m.gnss is not None for m in ms) and any(m.gnss is None for m in ms)
    for m in ms:
        back = MeasurementBatch.of(m).measurement(0)
        assert back.gnss is m.gnss
        for field in ("step", "t", "dt", "odometer_ds_m", "baro_alt_m"):
            assert getattr(back, field) == getattr(m, field), field
        for field in ("dtheta_r", "dv_r", "dtheta_sub", "dv_sub"):
            np.testing.assert_array_equal(getattr(back, field), getattr(m, field))
    if sensors:
        assert ms[-1].odometer_ds_m is not None and ms[-1].baro_alt_m is not None
