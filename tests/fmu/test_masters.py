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


@pytest.fixture(scope="module")
def k_step_reference(scenario):
    """run_episode of the scenario with a navigation step of k dt, per k (cached)."""
    cache = {}

    def get(k):
        if k not in cache:
            dt = scenario.timing.nav_period_s
            coarse = scenario.with_overrides({"timing": {"nav_period_s": k * dt}})
            cache[k] = run_episode(coarse, estimators.make("lc-ekf"), seed=SEED, use_batch=False)
        return cache[k]
    return get


@pytest.mark.parametrize("k", [2, 5])
@pytest.mark.parametrize("order, lagged", [("plant-first", 0), ("estimator-first", 1), ("jacobi", 1)])
def test_communication_step_of_k_navigation_steps(k, order, lagged, plant2, estimator2, scenario, k_step_reference):
    """h = k dt: the plant composes the k steps' multiple integrals, the estimator takes
    each interval as one navigation update of k dt. The numbers are run_episode's on the
    scenario with [timing] nav_period_s = k dt, bit for bit: the IMU samples and GNSS
    epochs are the same, the composition of the k steps (plant) and of the k samples
    (simulator) is the same contraction element by element (compose_multiple_integrals,
    whatever the batch length), and lc-ekf's automatic strapdown choice reads the
    multiple integrals only. nav.t_s / nav.step count plant steps of dt; a lagged master
    is one communication step (k navigation steps) behind."""
    ref = k_step_reference(k)
    dt = scenario.timing.nav_period_s
    n = scenario.timing.steps // k
    m = PlainMaster(plant2, estimator2)
    try:
        rows = m.run(n, k * dt, order)
    finally:
        m.close()
    steps = np.array([r["nav.step"] for r in rows])
    np.testing.assert_array_equal(steps, k * (np.arange(1, n + 1) - lagged))
    np.testing.assert_array_equal([r["nav.lag_steps"] for r in rows], np.full(n, k * lagged))
    np.testing.assert_array_equal([r["nav.t_s"] for r in rows], steps * dt)
    assert len(ref.t) == n and abs(ref.t[0] - k * dt) < 1e-15
    got, want = _solution(rows[lagged:]), _reference_solution(ref)[:n - lagged]
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(np.array([r["nav.covariance"] for r in rows[lagged:]]).reshape(-1, 9, 9),
                                  ref.est_cov[:n - lagged])
    np.testing.assert_array_equal([r["nav.nis"] for r in rows[lagged:]], ref.nis[:n - lagged])
    # every GNSS epoch of the episode was processed (none lost inside an interval): one
    # NIS per epoch with valid satellites, as in run_episode
    assert np.isfinite(ref.nis).sum() > 0
    assert np.isfinite([r["nav.nis"] for r in rows[lagged:]]).sum() == np.isfinite(ref.nis[:n - lagged]).sum()


def _log_tail(inst, seen):
    return " ".join(msg for _, msg in inst.log[seen:])


def test_steps_that_cannot_be_served_are_refused(plant2, estimator2):
    """h = 3 dt does not divide the GNSS period (100 steps): epochs would fall inside
    intervals; refused at the first step with an error status and a log line. A span
    that changes, a plant stepped with another h and a lost transfer are refused too."""
    m = PlainMaster(plant2, estimator2)
    try:
        seen = len(m.est.log)
        with pytest.raises(FmuCallError, match=r"h = 0.03 s spans 3 navigation steps, which do not divide the GNSS"):
            m.est.do_step(0.0, 0.03)
        assert "do not divide the GNSS period" in _log_tail(m.est, seen)
        m.plant.do_step(0.0, 0.01)  # the plant stepped with h = dt, the estimator with 2 dt
        m.transfer()
        with pytest.raises(FmuCallError, match=r"skipped data: .* jumped from 0 to 1, where .* takes 2 navigation"):
            m.est.do_step(0.0, 0.02)
        m.plant.do_step(0.01, 0.01)
        m.transfer()
        m.est.do_step(0.0, 0.02)  # the refused steps changed nothing: both at step 2 now
        assert m.nav.unpack(m.nav.fetch())["nav.step"] == 2
        m.plant.do_step(0.02, 0.02)
        with pytest.raises(FmuCallError, match=r"spans 1 navigation step\(s\) where the earlier steps spanned 2"):
            m.est.do_step(0.02, 0.01)
        m.plant.do_step(0.04, 0.02)  # a lost transfer: the input goes 2 -> 6 for a step of 2
        m.transfer()
        with pytest.raises(FmuCallError, match=r"skipped data: .* jumped from 2 to 6"):
            m.est.do_step(0.02, 0.02)
    finally:
        m.close()
    m = PlainMaster(plant2, estimator2)  # a lost transfer with h = dt
    try:
        m.est.do_step(0.0, 0.01)
        m.plant.do_step(0.0, 0.01)
        m.plant.do_step(0.01, 0.01)
        m.transfer()
        with pytest.raises(FmuCallError, match=r"skipped data: .* jumped from 0 to 2"):
            m.est.do_step(0.01, 0.01)
    finally:
        m.close()


def test_an_estimator_that_needs_sub_samples_refuses_k_steps(fmu_dir, scenario):
    """Two IMU samples per navigation step and lc-ekf told to use two-sample coning and
    sculling: it runs with h = dt, but a composed interval carries one sample, so h = 2 dt
    is refused with an error status and a log line naming the estimator and the reason."""
    pytest.importorskip("pythonfmu")
    from navsim.fmu.build import build_fmu

    fine = scenario.with_overrides({"timing": {"tick_s": 0.005, "imu_period_s": 0.005}})
    path = build_fmu(fine, "estimator", 2, fmu_dir / "est_two_sample.fmu", estimator="lc-ekf",
                     estimator_options='coning = "two-sample"\nsculling = "two-sample"')
    for h, ok in ((0.01, True), (0.02, False)):
        est = FmuInstance(path, "e")
        try:
            est.initialize()
            steps = round(h / 0.01)
            est.set({"time.step": steps, "time.t_s": steps * 0.01})  # a plant-first master's first transfer
            if ok:
                est.do_step(0.0, h)
                assert est.get(["nav.step"])["nav.step"] == 1
            else:
                seen = len(est.log)
                with pytest.raises(FmuCallError, match=r"estimator 'lc-ekf' refused the data of plant step 2 "
                                                       r"\(navigation step 2 x 0.01 s\)"):
                    est.do_step(0.0, h)
                assert "dtheta_sub" in _log_tail(est, seen)
        finally:
            est.free()


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
