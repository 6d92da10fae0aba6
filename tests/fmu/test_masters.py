"""Plant + estimator FMUs under any master: Jacobi, Gauss-Seidel in both orders, sub-steps.

The estimator FMU reads the plant's step counter (``time.step``) and processes each plant
step once and in order. Under a plant-first Gauss-Seidel master its output after the
communication step ending at (k+1)*dt is run_episode's estimate of step k; under a Jacobi
master (or Gauss-Seidel stepping the estimator first) it is run_episode's estimate of
step k-1, and ``nav.t_s`` says so. Equality is bit for bit: the FMU runs the estimator's
``step`` on the very numbers ``run_episode(..., use_batch=False)`` feeds it (the plant's
outputs are the simulator's float64 values, copied, never recomputed), so the same
floating-point operations run in the same order. Data that skip or repeat are refused
with an error status and a log line.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("fmpy")

from navsim import estimators  # noqa: E402
from navsim.episode import run_episode  # noqa: E402
from navsim.fmu.master import FmuCallError, FmuInstance, _Plan  # noqa: E402

SEED = 3
NAV = ["nav.lat_rad", "nav.lon_rad", "nav.h_m", "nav.velocity_n", "nav.heading_rad", "nav.pitch_rad",
       "nav.roll_rad", "nav.covariance", "nav.nis", "nav.t_s", "nav.step", "nav.lag_steps"]


@pytest.fixture(scope="module")
def reference(scenario):
    return run_episode(scenario, estimators.make("lc-ekf"), seed=SEED, use_batch=False)


class PlainMaster:
    """A generic fixed-step master over fmpy, written as a new user would: every
    estimator input connected to the plant output of the same name, one transfer of all
    connections per step. ``order``: "jacobi" (both step on the values of t, then the
    exchange), "plant-first" / "estimator-first" (Gauss-Seidel)."""

    def __init__(self, plant_path, est_path, seed=SEED):
        self.plant = FmuInstance(plant_path, "plant")
        self.est = FmuInstance(est_path, "estimator")
        self.plant.initialize({"seed": seed})
        self.est.initialize()
        inputs = [n for n, v in self.est.variables.items() if v.causality == "input"]
        self.src, self.dst = _Plan(self.plant, inputs), _Plan(self.est, inputs)
        self.nav = _Plan(self.est, [n for n in self.est.variables if n.startswith("nav.")])
        self.connections = len(inputs)
        self.transfer()

    def transfer(self):
        raw = self.src.fetch()
        for t, (vrs, _) in self.dst.groups.items():
            self.est.set_raw(t, vrs, raw[t])

    def step(self, t, h, order):
        if order == "plant-first":
            self.plant.do_step(t, h)
            self.transfer()
            self.est.do_step(t, h)
        elif order == "estimator-first":
            self.est.do_step(t, h)
            self.plant.do_step(t, h)
            self.transfer()
        else:
            for fmu in (self.plant, self.est):  # either order: both see the values of t
                fmu.do_step(t, h)
            self.transfer()
        return self.nav.unpack(self.nav.fetch())

    def run(self, n, h, order):
        return [self.step(k * h, h, order) for k in range(n)]

    def close(self):
        self.plant.free()
        self.est.free()


def _solution(rows):
    return np.array([[r["nav.lat_rad"], r["nav.lon_rad"], r["nav.h_m"], *np.ravel(r["nav.velocity_n"]),
                      r["nav.heading_rad"], r["nav.pitch_rad"], r["nav.roll_rad"]] for r in rows])


def _reference_solution(ref):
    return np.column_stack([ref.est_lat, ref.est_lon, ref.est_h, ref.est_velocity_n, ref.est_hpr])


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("order, lag", [("plant-first", 0), ("estimator-first", 1), ("jacobi", 1)])
def test_plain_master_equals_run_episode_with_its_lag(fmi, order, lag, request, scenario, reference):
    m = PlainMaster(request.getfixturevalue(f"plant{fmi}"), request.getfixturevalue(f"estimator{fmi}"))
    try:
        if fmi == 2:
            assert m.connections > 280  # 283 scalar connections for 24 channels and 4 orders
        n, dt = scenario.timing.steps, scenario.timing.nav_period_s
        rows = m.run(n, dt, order)
    finally:
        m.close()
    steps = np.array([r["nav.step"] for r in rows])
    np.testing.assert_array_equal(steps, np.arange(1, n + 1) - lag)
    np.testing.assert_array_equal([r["nav.lag_steps"] for r in rows], np.full(n, lag))
    np.testing.assert_array_equal([r["nav.t_s"] for r in rows], steps * dt)  # the time it refers to
    got, want = _solution(rows[lag:]), _reference_solution(reference)[:n - lag]
    np.testing.assert_array_equal(got, want)  # same operations in the same order: bit for bit
    np.testing.assert_array_equal(np.array([r["nav.covariance"] for r in rows[lag:]]).reshape(-1, 9, 9),
                                  reference.est_cov[:n - lag])
    np.testing.assert_array_equal([r["nav.nis"] for r in rows[lag:]], reference.nis[:n - lag])
    if lag:  # before the first plant step arrives the output is the prior, at t = 0
        assert rows[0]["nav.step"] == 0 and rows[0]["nav.t_s"] == 0.0
        assert rows[0]["nav.lat_rad"] == reference.prior.lat


@pytest.mark.parametrize("master", ["plant-first", "estimator-first", "jacobi"])
def test_cosimulate_record_is_run_episode_under_every_master(master, plant2, estimator2, reference):
    """navsim's own master aligns each estimate with the plant step it refers to: the
    record equals run_episode's (minus the last step a lagged master never delivers)."""
    from navsim.fmu.master import cosimulate

    record = cosimulate(plant2, estimator2, seed=SEED, master=master)
    m = len(record.t)
    assert m == len(reference.t) - (master != "plant-first")
    for field in ("t", "truth_s", "truth_lat", "truth_velocity_n", "truth_hpr", "est_lat", "est_lon", "est_h",
                  "est_velocity_n", "est_hpr", "est_cov", "nis", "nis_dof"):
        np.testing.assert_array_equal(getattr(record, field), getattr(reference, field)[:m], err_msg=field)
    keep = reference.gnss_t <= record.t[-1] + 1e-9
    np.testing.assert_array_equal(record.gnss_t, reference.gnss_t[keep])
    np.testing.assert_array_equal(record.gnss_n_valid, reference.gnss_n_valid[keep])


@pytest.fixture(scope="module")
def half_tick_pair(fmu_dir, scenario):
    """A scenario whose navigation step is two ticks (as mountain-railway): h = one tick."""
    pytest.importorskip("pythonfmu")
    from navsim.fmu.build import build_fmu

    fine = scenario.with_overrides({"timing": {"tick_s": 0.005}})
    return (fine, build_fmu(fine, "plant", 2, fmu_dir / "plant_tick.fmu"),
            build_fmu(fine, "estimator", 2, fmu_dir / "est_tick.fmu", estimator="lc-ekf"))


@pytest.mark.parametrize("order", ["plant-first", "jacobi"])
def test_communication_step_of_one_tick(order, half_tick_pair):
    """h = half a navigation step: the estimator holds when no plant step ended and takes
    each plant step once, at the half step where it arrives (Jacobi: one tick later)."""
    fine, plant, est = half_tick_pair
    ref = run_episode(fine, estimators.make("lc-ekf"), seed=SEED, use_batch=False)
    m = PlainMaster(plant, est)
    try:
        rows = m.run(2 * 100, 0.005, order)
    finally:
        m.close()
    steps = np.array([r["nav.step"] for r in rows])
    # plant-first: step k ends at tick 2k+2 and is processed then; Jacobi: one tick later
    want = (np.arange(1, 201) - (order == "jacobi")) // 2
    np.testing.assert_array_equal(steps, want)
    fresh = [i for i in range(len(rows)) if steps[i] and (i == 0 or steps[i] != steps[i - 1])]
    np.testing.assert_array_equal(_solution([rows[i] for i in fresh]), _reference_solution(ref)[:len(fresh)])


def _log_tail(inst, seen):
    return " ".join(msg for _, msg in inst.log[seen:])


def test_a_step_of_several_navigation_steps_is_refused(plant2, estimator2):
    """h = 2 navigation steps: the plant composes two steps' increments, which the
    estimator cannot take one by one: error status and a log line, no silent numbers.
    A transfer the master skips shows as a jump of the counter: refused as well."""
    m = PlainMaster(plant2, estimator2)
    try:
        seen = len(m.est.log)
        with pytest.raises(FmuCallError, match=r"h = 0.02 s spans 2 navigation steps"):
            m.est.do_step(0.0, 0.02)
        assert "spans 2 navigation steps" in _log_tail(m.est, seen)
        m.est.do_step(0.0, 0.01)  # the refused step changed nothing: retry with one step
        m.plant.do_step(0.0, 0.01)
        m.plant.do_step(0.01, 0.01)  # a lost transfer: the plant is at step 2, the input went 0 -> 2
        m.transfer()
        with pytest.raises(FmuCallError, match=r"skipped data: .* jumped from 0 to 2"):
            m.est.do_step(0.01, 0.01)
    finally:
        m.close()


def test_stale_repeated_and_unconnected_data_are_refused(plant2, estimator2, reference):
    m = PlainMaster(plant2, estimator2)
    try:
        m.run(3, 0.01, "plant-first")
        m.plant.do_step(0.03, 0.01)  # a master that forgets the transfer: the estimator sees step 3 again
        with pytest.raises(FmuCallError, match=r"stale data: .*time.step input is 3 at t = 0.03 s, where a plant-first .* gives 4"):
            m.est.do_step(0.03, 0.01)
        m.transfer()  # the refused step changed nothing: the master may retry
        m.est.do_step(0.03, 0.01)
        row = m.nav.unpack(m.nav.fetch())
        assert row["nav.step"] == 4 and row["nav.lat_rad"] == reference.est_lat[3]
        m.est.set({"time.step": 2})  # replayed older data
        with pytest.raises(FmuCallError, match="repeated data: .*went back from 4 to 2"):
            m.est.do_step(0.04, 0.01)
    finally:
        m.close()
    est = FmuInstance(estimator2, "alone")  # time.step never connected
    try:
        est.initialize()
        est.do_step(0.0, 0.01)  # first step: no plant step has ended yet at t = 0 (a Jacobi master)
        with pytest.raises(FmuCallError, match=r"stale data: .*is time.step connected\?"):
            est.do_step(0.01, 0.01)
    finally:
        est.free()


@pytest.mark.slow
@pytest.mark.parametrize("master", ["plant-first", "estimator-first", "jacobi"])
def test_errors_at_20_s_under_every_master(master, fmu_dir, scenario):
    """The figures of the README: horizontal error at 20 s beside run_episode's
    (`pytest -m slow tests/fmu/test_masters.py -s`)."""
    from navsim.fmu.build import build_fmu
    from navsim.fmu.master import cosimulate
    from navsim.metrics import error_series

    sc = scenario.with_overrides({"timing": {"duration_s": 21.0}, "outages": {"windows_s": []}})
    plant = build_fmu(sc, "plant", 2, fmu_dir / "plant21.fmu")
    est = build_fmu(sc, "estimator", 2, fmu_dir / "est21.fmu", estimator="lc-ekf")
    ref = run_episode(sc, estimators.make("lc-ekf"), seed=0, use_batch=False)
    rec = cosimulate(plant, est, seed=0, master=master)
    k = int(round(20.0 / sc.timing.nav_period_s)) - 1
    a, b = error_series(rec).horizontal_m[k], error_series(ref).horizontal_m[k]
    print(f"\n{master}: horizontal error at t = {rec.t[k]:.2f} s: FMUs {a:.3f} m, run_episode {b:.3f} m")
    assert a == b
