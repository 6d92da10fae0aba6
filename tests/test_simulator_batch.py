"""SimulatorBatch: B lockstep episodes equal B independent simulators, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from navsim.errors import ConfigError
from navsim.io import chunk_arrays
from navsim.scenario import load_scenario
from navsim.simulator import Simulator, SimulatorBatch

CASES = {
    # white noise only, 100 Hz, constant speed on the polynomial track
    "paper": ("paper-2012", {"timing": {"duration_s": 12.0}}),
    # every IMU error (Gauss-Markov, quantization, scale factor...), the full GNSS error
    # model and random receiver and satellite dropouts
    "mems": ("paper-2012", {"timing": {"duration_s": 12.0}, "imu": {"preset": "consumer-mems"},
                            "gnss": {"preset": "standalone"},
                            "outages": {"receiver_mean_outage_s": 2.0, "receiver_mean_available_s": 4.0,
                                        "satellite_mean_outage_s": 3.0, "satellite_mean_available_s": 5.0}}),
    # two IMU samples per navigation step (composition of multiple integrals)
    "two-samples": ("paper-2012", {"timing": {"duration_s": 6.0, "tick_s": 0.005, "imu_period_s": 0.005},
                                   "imu": {"preset": "tactical"}}),
    # an error-free IMU (the members share the truth's increments)
    "ideal": ("paper-2012", {"timing": {"duration_s": 4.0}, "imu": {"preset": "ideal"}}),
}


def _equal(a: dict, b: dict) -> list[str]:
    return [k for k in a if a[k].shape != b[k].shape or not np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f")]


@pytest.mark.parametrize("case", sorted(CASES))
def test_members_equal_single_simulators(case):
    name, overrides = CASES[case]
    scenario = load_scenario(name).with_overrides(overrides)
    seeds = [3, 11, 12]
    batch = SimulatorBatch(scenario, len(seeds))
    starts = batch.reset(seeds)
    sizes = (1, 37, 250, 10_000)  # uneven chunks, across GNSS epochs and quantizer blocks
    batch_chunks = [batch.advance(k) for k in sizes if not batch.done]
    assert batch.done
    for j, seed in enumerate(seeds):
        single = Simulator(scenario)
        start = single.reset(seed)
        for field in ("lat", "lon", "h", "velocity_n", "heading", "pitch", "roll", "covariance"):
            np.testing.assert_array_equal(getattr(start.prior, field), getattr(starts[j].prior, field))
        for k, chunk_b in zip(sizes, batch_chunks):
            mine = chunk_arrays(chunk_b.member(j))
            ref = chunk_arrays(single.advance(k))
            assert not _equal(ref, mine), f"member {j} differs in {_equal(ref, mine)}"
    # the members really differ from each other (their own streams)
    last = batch_chunks[-1]
    if case != "ideal":
        assert not np.array_equal(last.imu.dtheta_r[0], last.imu.dtheta_r[1])
        assert not np.array_equal(last.gnss.pseudorange_m[0], last.gnss.pseudorange_m[1])


def test_tunnel_outages_in_lockstep():
    """Tunnels on the mountain railway: the deterministic mask is shared, still per member."""
    scenario = load_scenario("mountain-railway")
    batch = SimulatorBatch(scenario.with_overrides({"timing": {"duration_s": 30.0}}), 2)
    batch.reset([0, 1])
    chunk = batch.advance(3000)
    single = Simulator(scenario.with_overrides({"timing": {"duration_s": 30.0}}))
    single.reset(1)
    ref = single.advance(3000)
    np.testing.assert_array_equal(chunk.receiver_outage[1], ref.receiver_outage)
    np.testing.assert_array_equal(chunk.gnss.valid[1], ref.gnss.valid)


def test_bad_input():
    scenario = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 1.0}})
    with pytest.raises(ConfigError, match="size"):
        SimulatorBatch(scenario, 0)
    batch = SimulatorBatch(scenario, 2)
    with pytest.raises(ConfigError, match="seeds"):
        batch.reset([1, 2, 3])
    with pytest.raises(RuntimeError, match="reset"):
        batch.advance(1)
    with pytest.raises(ConfigError, match="external"):
        SimulatorBatch(scenario.with_overrides({"motion": {"profile": "external"}}), 2)
    batch.reset([1, 2])
    batch.advance(100)
    with pytest.raises(RuntimeError, match="over"):
        batch.advance(1)


@pytest.mark.parametrize("threads", [1, 2])
def test_groups_and_threads_change_no_number(threads):
    """More members than one IMU group (IMU_GROUP), optionally on two threads."""
    from navsim.simulator import IMU_GROUP

    scenario = load_scenario("paper-2012").with_overrides(
        {"timing": {"duration_s": 1.5}, "imu": {"preset": "consumer-mems"}})
    size = IMU_GROUP + 3
    batch = SimulatorBatch(scenario, size, threads=threads)
    batch.reset(list(range(100, 100 + size)))
    chunk = batch.advance(150)
    batch.close()
    batch.close()
    for j in (0, IMU_GROUP - 1, IMU_GROUP, size - 1):
        single = Simulator(scenario)
        single.reset(100 + j)
        ref = chunk_arrays(single.advance(150))
        mine = chunk_arrays(chunk.member(j))
        assert not _equal(ref, mine), f"member {j} differs in {_equal(ref, mine)}"
