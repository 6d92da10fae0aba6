"""The estimator runtime's steady-state doStep (its fast path) does what the full checks do.

``EstimatorRuntime.do_step`` takes a short path once the master's order is known and the
communication step is one navigation step; every case it does not accept goes through
``check_step``. Here two runtimes (no FMI layer: the runtimes of the embedded resources,
fed from one plant runtime) run the same episode, one with the fast path switched off:
every value of their stores is equal bit for bit after every step (the same operations
in the same order), and the misuses injected mid-run (a communication point off the
FMU's time, a skipped, repeated or stale ``time.step``, a wrong ``time.t_s``, another
``h``) are refused by both with the same message and leave both states unchanged.
"""

from __future__ import annotations

import zipfile

import numpy as np
import pytest

pytest.importorskip("pythonfmu")


def _runtimes(tmp_path, plant_fmu, estimator_fmu, fmi):
    from navsim.fmu.runtime import EstimatorRuntime, PlantRuntime

    class Slow(EstimatorRuntime):
        def do_step(self, t, h):
            self._fast = None  # the steady state never recorded: every step takes check_step
            super().do_step(t, h)

    for name, path in (("plant", plant_fmu), ("estimator", estimator_fmu)):
        with zipfile.ZipFile(path) as z:
            z.extractall(tmp_path / name)
    plant = PlantRuntime(str(tmp_path / "plant" / "resources"), fmi)
    fast = EstimatorRuntime(str(tmp_path / "estimator" / "resources"), fmi)
    slow = Slow(str(tmp_path / "estimator" / "resources"), fmi)
    return plant, fast, slow


def _inputs(est, plant):
    return [v.name for v in est.store.table if v.causality == "input" and v.name in plant.store.by_name]


def _transfer(plant, ests, names):
    for name in names:
        value = plant.store.read(name)
        for est in ests:
            est.store.write(name, value)


def _same_state(a, b):
    for kind in ("real", "int", "bool"):
        np.testing.assert_array_equal(a.store.arrays[kind], b.store.arrays[kind], err_msg=kind)
    assert (a.tick, a.processed, a.lagged, a.span) == (b.tick, b.processed, b.lagged, b.span)


def _refused_alike(ests, t, h):
    from navsim.fmu.runtime import FmuError

    messages = []
    for est in ests:
        before = {k: a.copy() for k, a in est.store.arrays.items()}
        with pytest.raises(FmuError) as info:
            est.do_step(t, h)
        messages.append(str(info.value))
        for k, a in est.store.arrays.items():
            np.testing.assert_array_equal(a, before[k], err_msg=k)
    assert messages[0] == messages[1]
    return messages[0]


@pytest.mark.parametrize("fmi", [2, 3])
def test_fast_path_equals_full_checks(fmi, request, tmp_path):
    plant, fast, slow = _runtimes(tmp_path, request.getfixturevalue(f"plant{fmi}"),
                                  request.getfixturevalue(f"estimator{fmi}"), fmi)
    ests = (fast, slow)
    full: list = []
    slow_full: list = []
    for est, calls in ((fast, full), (slow, slow_full)):
        def counted(t, h, check=est.check_step, calls=calls):
            calls.append(t)
            return check(t, h)
        est.check_step = counted
    names = _inputs(fast, plant)
    plant.exit_initialization_mode()
    _transfer(plant, ests, names)
    for est in ests:
        est.exit_initialization_mode()
    dt = plant.timing.nav_period_s
    seen = []
    for k in range(250):  # plant first (Gauss-Seidel), 2.5 GNSS epochs
        t = k * dt
        plant.do_step(t, dt)
        _transfer(plant, ests, names)
        if k == 120:  # the misuses, in steady state: each refused, then the step made as it should be
            seen.append(_refused_alike(ests, t + 0.5 * dt, dt))  # a communication point off the FMU's time
            seen.append(_refused_alike(ests, t, 2 * dt))  # another h (and skipped data)
            step = fast.store.read("time.step")
            for bad in (step + 1, step - 2, step - 1):  # skipped, repeated, stale
                for est in ests:
                    est.store.write("time.step", bad)
                seen.append(_refused_alike(ests, t, dt))
            for est in ests:
                est.store.write("time.step", step)
                est.store.write("time.t_s", plant.store.read("time.t_s") + 0.5 * dt)
            seen.append(_refused_alike(ests, t, dt))
            _transfer(plant, ests, names)
        for est in ests:
            est.do_step(t, dt)
        _same_state(fast, slow)
    assert fast.processed == slow.processed == 250
    # the fast path took every step but the first (the master's order not yet known) and
    # the six refused ones (a refusal leaves the steady state known: the next valid step is
    # a fast one again)
    assert len(full) == 1 + 6, len(full)
    assert len(slow_full) == 250 + 6
    for want in ("does not match the FMU's time", "spans 2 navigation step(s)", "skipped data", "repeated data",
                 "stale data", "time.t_s input"):
        assert any(want in m for m in seen), want


def test_compiled_solution_write_equals_numpy_path(tmp_path, request):
    """``_write_row`` through the compiled writer and through its NumPy path give the same
    store, bit for bit (copies, ``abs`` and the correctly rounded ``sqrt``), for a
    covariance with a negative and a negative-zero diagonal element and with and without
    an update (NaN NIS, dof 0); a row of another layout falls back to the NumPy path."""
    pytest.importorskip("numba")
    from navsim.fmu import runtime

    plant, fast, slow = _runtimes(tmp_path, request.getfixturevalue("plant2"), request.getfixturevalue("estimator2"), 2)
    writer = runtime._solution_writer()
    assert writer is not None
    rng = np.random.default_rng(5)
    a = rng.normal(size=(9, 9))
    cov = a @ a.T
    cov[3, 3], cov[7, 7] = -1e-18, -0.0
    row = rng.normal(size=12)[:9]  # a view, as lc-ekf's row is
    for nis, dof in ((None, None), (2.5, 6)):
        fast.processed = slow.processed = 41
        fast.nav_ticks = slow.nav_ticks = 1
        fast._writer, slow._writer = writer, None
        fast._write_row(row, cov, nis, dof, 0.41, 42)
        slow._write_row(row, cov, nis, dof, 0.41, 42)
        assert fast._writer is writer  # the compiled path was taken
        for kind in ("real", "int"):
            assert fast.store.arrays[kind].tobytes() == slow.store.arrays[kind].tobytes(), kind
    strided = rng.normal(size=18)[::2]  # not the compiled layout
    fast._write_row(strided, cov, None, None, 0.42, 43)
    slow._write_row(strided, cov, None, None, 0.42, 43)
    assert fast._writer is None  # the NumPy path from then on, which wrote the same values
    assert fast.store.real.tobytes() == slow.store.real.tobytes()
