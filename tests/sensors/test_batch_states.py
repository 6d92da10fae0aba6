"""The GNSS and outage models' batched calls read the arrays of the states they made
(:class:`navsim.sensors._common.RecentBatches`) instead of each state's attributes: the
same numbers as reading the states, and only for the very objects they made."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from navsim.scenario import load_scenario
from navsim.sensors import outages
from navsim.sensors.gnss import GnssState, error_model
from navsim.simulator import SimulatorBatch

# every random part of both models: receiver and satellite chains, a window, multipath, clock
OVER = {"timing": {"duration_s": 12.0},
        "outages": {"windows_s": [[3.0, 4.5]], "receiver_mean_outage_s": 1.5, "receiver_mean_available_s": 4.0,
                    "satellite_mean_outage_s": 2.0, "satellite_mean_available_s": 3.0}}
FIELDS = ("pseudorange_m", "pseudorange_rate_mps", "valid", "clock_bias_m", "clock_drift_mps")


def _run(monkeypatch: pytest.MonkeyPatch, memo: bool, name: str) -> tuple[list, list, int]:
    hits = []
    for module in (error_model, outages):
        recall = module._RECENT.recall

        def counted(states, recall=recall):
            found = recall(states) if memo else None
            hits.append(found is not None)
            return found

        monkeypatch.setattr(module._RECENT, "recall", counted)
    scenario = load_scenario(name).with_overrides(OVER)
    batch = SimulatorBatch(scenario, 5)
    batch.reset([11, 12, 13, 14, 15])
    out = []
    for _ in range(5):
        chunk = batch.advance(230)  # 2-3 epochs a chunk at 1 s / 0.01 s
        out.append([np.array(getattr(chunk.gnss, f)) for f in FIELDS] + [chunk.receiver_outage.copy()])
    states = [(sim.gnss_state, sim.outage_state) for sim in batch.members]
    monkeypatch.undo()
    return out, states, sum(hits)


@pytest.mark.parametrize("name", ["paper-2012", "urban-road"])
def test_remembered_arrays_give_the_numbers_of_the_states(monkeypatch, name):
    """A batch's GNSS epochs, outage flags and final states with the remembered arrays
    equal those read from the states bit for bit (and the arrays were used)."""
    with_memo, states_memo, hits = _run(monkeypatch, True, name)
    without, states_plain, no_hits = _run(monkeypatch, False, name)
    assert hits >= 8 and no_hits == 0  # every call after the first of each model
    for chunk_a, chunk_b in zip(with_memo, without):
        for a, b in zip(chunk_a, chunk_b):
            assert a.dtype == b.dtype and np.array_equal(a.view(np.uint8), b.view(np.uint8))
    for (g_a, o_a), (g_b, o_b) in zip(states_memo, states_plain):
        assert (g_a.t_s, g_a.clock_bias_m, g_a.clock_drift_mps) == (g_b.t_s, g_b.clock_bias_m, g_b.clock_drift_mps)
        assert np.array_equal(g_a.multipath, g_b.multipath) and not g_a.multipath.flags.writeable
        assert (o_a.t_s, o_a.receiver_out) == (o_b.t_s, o_b.receiver_out)
        assert np.array_equal(o_a.satellite_out, o_b.satellite_out) and not o_a.satellite_out.flags.writeable


def test_only_the_objects_made_are_recalled():
    """A list holding another state object (even the caller's own list, changed after the
    call), a subset or another order is read state by state."""
    recent = error_model._RECENT
    bias, drift, mp = np.array([1.0, 2.0, 3.0]), np.array([0.1, 0.2, 0.3]), np.arange(6.0).reshape(3, 2)
    made = GnssState._batch(5.0, bias, drift, mp)
    arrays = recent.recall(list(made))
    assert arrays is not None and arrays[0] == 5.0 and np.array_equal(arrays[3], mp)
    assert not arrays[1].flags.writeable and not arrays[3].flags.writeable
    other = dataclasses.replace(made[1], clock_bias_m=9.0)
    made[1] = other  # the returned list changed by its caller
    assert recent.recall(made) is None
    made[1] = recent.recall  # not a state at all
    assert recent.recall(made) is None
    first = GnssState._batch(5.0, bias, drift, mp)
    assert recent.recall(first[:2]) is None and recent.recall(first[::-1]) is None
    assert recent.recall([]) is None
    assert recent.recall(first) is not None

