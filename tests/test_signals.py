"""The signal table and its codec (navsim.signals): round trips against the simulator's own
measurements, and the table's declarations."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from navsim.episode import measurements
from navsim.scenario import load_scenario
from navsim.signals import (
    OBS_KEYS,
    SIGNALS,
    SOLUTION_FIELDS,
    UNIT_EXPONENTS,
    Layout,
    ObservationCodec,
    observation_signals,
)
from navsim.simulator import Simulator, SimulatorBatch
from navsim.types import STATE_LABELS, NavSolution

# 3 s of the mountain railway with the odometer on and an outage: epochs with and without
# valid channels, odometer distances, 10 IMU samples per step.
OVER = {"timing": {"duration_s": 3.0}, "outages": {"windows_s": [[1.0, 2.5]]},
        "odometer": {"enabled": True, "preset": "rail-tachometer"}}


def _sim(over=OVER):
    sim = Simulator(load_scenario("mountain-railway").with_overrides(over))
    sim.reset(3)
    return sim


def _same_measurement(a, b) -> None:
    """Field by field, arrays bit for bit (the codec only reshapes the simulator's arrays)."""
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if f.name == "gnss":
            assert (x is None) == (y is None)
            if x is not None:
                for g in dataclasses.fields(x):
                    assert np.array_equal(getattr(x, g.name), getattr(y, g.name)), g.name
        elif isinstance(x, np.ndarray):
            assert x.shape == y.shape and np.array_equal(x, y), f.name
        else:
            assert x == y, f.name


def test_decode_of_the_encoded_chunk_is_the_simulators_measurement():
    sim = _sim()
    prn = np.asarray(sim.constellation.prn)
    codec = ObservationCodec(Layout.of(sim.scenario, len(prn)), prn)
    n_epochs = n_valid_epochs = 0
    for chunk in sim.chunks(70):  # several chunks, epochs inside and at chunk ends
        rows = codec.encode_chunk(chunk)
        assert all(not v.flags.writeable and len(v) == len(chunk) for v in rows.values())
        for i, want in enumerate(measurements(chunk, prn, sim.timing.nav_period_s)):
            got = codec.decode(codec.observation(rows, i), want.step)
            _same_measurement(got, want)
            if want.gnss is not None:
                n_epochs += 1
                n_valid_epochs += bool(want.gnss.valid.any())
    assert n_epochs > 2 and 0 < n_valid_epochs < n_epochs  # both kinds of epoch were checked


def test_encode_measurement_inverts_decode():
    sim = _sim()
    prn = np.asarray(sim.constellation.prn)
    codec = ObservationCodec(Layout.of(sim.scenario, len(prn)), prn)
    chunk = next(sim.chunks(200))
    rows = codec.encode_chunk(chunk)
    for i in (0, 9, 10, 11, 199):
        obs = codec.observation(rows, i)
        back = codec.encode_measurement(codec.decode(obs, i))
        assert list(back) == list(obs)
        for key in obs:
            assert back[key].dtype == obs[key].dtype and np.array_equal(back[key], obs[key]), key


def test_batch_observations_are_the_members_single_observations():
    sc = load_scenario("mountain-railway").with_overrides(OVER)
    batch = SimulatorBatch(sc, 3)
    batch.reset([5, 6, 7])
    prn = np.asarray(batch.members[0].constellation.prn)
    codec = ObservationCodec(Layout.of(sc, len(prn)), prn)
    singles = []
    for seed in (5, 6, 7):
        s = Simulator(sc)
        s.reset(seed)
        singles.append(codec.encode_chunk(s.advance(120)))
    obs_at = codec.encode_batch_chunk(batch.advance(120))
    for i in (0, 9, 10, 55, 119):
        obs = obs_at(i)
        assert list(obs) == list(singles[0])
        for j in range(3):
            for key, rows in singles[j].items():
                assert np.array_equal(obs[key][j], rows[i]), (key, i, j)


def test_observation_signals_follow_the_layout():
    sc = load_scenario("paper-2012")
    plain = Layout.of(sc, 24)
    with_odo = dataclasses.replace(plain, odometer=True)
    assert tuple(s.name for s in observation_signals(plain)) == OBS_KEYS
    assert tuple(s.name for s in observation_signals(with_odo)) == OBS_KEYS + ("odometer_ds",)
    sizes = {s.name: s.size(plain) for s in observation_signals(plain)}
    R, m = sc.imu.orders, sc.timing.samples_per_step
    assert sizes["dtheta_r"] == 3 * R and sizes["dv_sub"] == 3 * m and sizes["sat_pos_e"] == 3 * 24
    terminal = ObservationCodec(plain, np.arange(24)).terminal()
    assert terminal["t"][0] == sc.timing.duration_s
    assert all(not np.any(v) for k, v in terminal.items() if k != "t")


def test_bounds_are_the_closed_form_integral_bounds():
    """r-fold integral of a quantity bounded by B over dt: B dt^r / r! (module docstring)."""
    sc = load_scenario("paper-2012")
    layout = Layout.of(sc, 24)
    dt = layout.nav_period_s
    sig = next(s for s in SIGNALS if s.name == "dv_r")
    low, high = sig.bounds(layout)
    want = [500.0 * dt**r / math.factorial(r) for r in range(1, layout.orders + 1) for _ in range(3)]
    assert np.allclose(high, want, rtol=1e-15, atol=0) and np.array_equal(low, -high)
    for s in observation_signals(dataclasses.replace(layout, odometer=True)):
        lo, hi = s.bounds(layout)
        assert lo.shape == hi.shape == (s.size(layout),) and np.all(np.isfinite(hi)) and np.all(lo < hi), s.name


def test_table_declarations():
    names = [s.name for s in SIGNALS]
    fmu = [s.fmu_name for s in SIGNALS]
    assert len(set(names)) == len(names) and len(set(fmu)) == len(fmu)
    for s in SIGNALS:
        assert s.description and all(u in UNIT_EXPONENTS for u in (s.unit, *s.order_units) if u)
        if s.order_units:  # one unit per multiple-integral order, dimensions rising by seconds
            assert s.shape == ("R", 3) and len(s.order_units) >= 4
    assert SOLUTION_FIELDS == ("lat", "lon", "h", "vE", "vN", "vU", "heading", "pitch", "roll")
    sol = NavSolution(1.0, 0.1, 0.2, 3.0, np.array([1.0, 2.0, 3.0]), 0.4, 0.5, 0.6)
    assert sol.as_action().tolist() == [0.1, 0.2, 3.0, 1.0, 2.0, 3.0, 0.4, 0.5, 0.6]
    assert len(STATE_LABELS) == 9
    with pytest.raises(ValueError):
        dataclasses.replace(SIGNALS[0], unit="furlong")
