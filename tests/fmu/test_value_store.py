"""The array-backed value store of the FMUs (navsim.fmu.runtime.ValueStore) and the
one-declaration path of a per-step signal: value references map to the table's layout
(FMI 2 one per element, FMI 3 one per variable after ``time``), host reads and writes go
through it with the type and causality checks, and a per-step signal declared in the
signal table is served by the plant FMU with no edit of the runtime."""

from __future__ import annotations

import numpy as np
import pytest
from navsim.fmu.runtime import FmuError, ValueStore
from navsim.fmu.variables import Var


def _table() -> list[Var]:
    return [
        Var("p.n", "int", "parameter", "fixed", "", "a parameter", 7),
        Var("a.x", "real", "input", "continuous", "m", "a scalar input", 0.5),
        Var("a.v", "real", "input", "discrete", "m", "a vector input", 0.0, (2, 3)),
        Var("a.flag", "bool", "output", "discrete", "", "a flag"),
        Var("a.name", "string", "parameter", "fixed", "", "a string", "x"),
        Var("a.y", "real", "output", "discrete", "m", "an output", None, (3,)),
    ]


def test_fmi2_value_references_are_elements_in_table_order():
    store = ValueStore(_table(), 2)
    assert len(store) == 1 + 1 + 6 + 1 + 1 + 3
    assert [store.first_vr[v.name] for v in _table()] == [0, 1, 2, 8, 9, 10]
    assert store.get([0], "int") == [7] and store.get([1], "real") == [0.5]  # start values
    assert store.get([9], "string") == ["x"] and store.get([8], "bool") == [False]
    store.set(list(range(2, 8)), [1.0, 2.0, 3.0, 4.0, 5.0, 6.0], "real", ("input",))
    np.testing.assert_array_equal(store.read("a.v"), [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    store.set([7, 2], [-6.0, -1.0], "real", ("input",))  # any order, not consecutive
    assert store.get([2, 7, 1], "real") == [-1.0, -6.0, 0.5]
    store.write("a.y", np.array([1.5, 2.5, 3.5]))
    assert store.get([12, 10], "real") == [3.5, 1.5]
    with pytest.raises(FmuError, match="expected a real"):
        store.get([0], "real")
    with pytest.raises(FmuError, match="cannot be set now"):
        store.set([10], [1.0], "real", ("input",))  # an output
    with pytest.raises(FmuError, match="expected a int"):
        store.get([len(store)], "int")
    store.set([9], ["y"], "string", ("parameter",))
    assert store.read("a.name") == "y"


def test_fmi3_one_reference_per_variable_after_time():
    store = ValueStore(_table(), 3)
    assert len(store) == 1 + 6 and store.first_vr["a.v"] == 3
    store.set_time(2.5)
    assert store.get([0], "real") == [2.5]
    store.set([3, 2], [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 9.0], "real", ("input",))  # a.v whole, then a.x
    assert store.read("a.x") == 9.0 and store.get([3], "real") == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    with pytest.raises(FmuError, match="expected 7 values"):
        store.set([3, 2], [1.0], "real", ("input",))
    with pytest.raises(FmuError, match="time"):
        store.set([0], [1.0], "real", ("input",))


def test_segments_merge_consecutive_elements():
    store = ValueStore(_table(), 2)
    segments = store.segments(["a.x", "a.v", "a.y"])  # consecutive in the real array (bool, string elsewhere)
    assert [(where, cols) for _, where, cols in segments] == [(slice(0, 10), slice(0, 10))]
    apart = store.segments(["a.x", "a.y"])  # a.v between them: two runs
    assert [(where, cols) for _, where, cols in apart] == [(slice(0, 1), slice(0, 1)), (slice(7, 10), slice(1, 4))]
    row = np.arange(10.0)
    for arr, where, cols in segments:
        arr[where] = row[cols]
    assert store.get(list(range(1, 8)) + [10, 11, 12], "real") == row.tolist()


def test_a_declared_per_step_signal_is_served_by_the_plant(fmu_dir, scenario, monkeypatch):
    """A new per-step signal of the odometer declared in the signal table alone (its chunk
    array, compose rule) is a plant output with the core's values, including the sum over
    a communication step of several navigation steps."""
    pytest.importorskip("pythonfmu")
    import navsim.fmu.runtime as fr
    import navsim.fmu.variables as fv
    from navsim.fmu.build import build_fmu
    from navsim.fmu.master import FmuInstance

    from navsim import signals
    from navsim.simulator import Simulator

    extra = signals.Signal("odometer_copy", "odometer", (1,), "m", "A new per-step output", "odometer.copy_m",
                           optional="odometer", source="odometer.ds_m", compose="sum")
    monkeypatch.setattr(fv, "SIGNALS", (*signals.SIGNALS, extra))
    monkeypatch.setattr(fr, "STEP_SIGNALS", (*signals.STEP_SIGNALS, extra))
    odo = scenario.with_overrides({"odometer": {"enabled": True}})
    plant = build_fmu(odo, "plant", 2, fmu_dir / "plant_extra.fmu")
    sim = Simulator(odo)
    sim.reset(2)
    core = sim.advance(40).odometer.ds_m
    with FmuInstance(plant, "p") as inst:
        inst.initialize({"seed": 2})
        got = []
        for k in range(20):
            inst.do_step(k * 0.01, 0.01)
            got.append(inst.get(["odometer.copy_m"])["odometer.copy_m"])
        np.testing.assert_array_equal(np.ravel(got), core[:20])
        for k in range(4):  # communication steps of 5 navigation steps: the exact sum (math.fsum)
            inst.do_step(0.2 + k * 0.05, 0.05)
            got5 = float(np.ravel(inst.get(["odometer.copy_m"])["odometer.copy_m"])[0])
            assert got5 == pytest.approx(float(np.sum(core[20 + 5 * k:25 + 5 * k])), rel=1e-15, abs=1e-15)
