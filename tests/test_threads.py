"""The core's BLAS thread limit (navsim.threads): set locally, restored, a speed setting only."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from navsim import threads
from navsim.scenario import load_scenario
from navsim.simulator import Simulator


def _blas_threads() -> list[int]:
    return [d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"]


@pytest.fixture
def restore_limit():
    before = threads.core_blas_threads()
    yield
    threads.set_core_blas_threads(before)


def test_limit_is_local_and_restored(restore_limit):
    threads.set_core_blas_threads(1)
    with threadpool_limits(2, user_api="blas"):
        assert set(_blas_threads()) == {2}
        with threads.blas_limit():
            assert set(_blas_threads()) == {1}
            with threads.blas_limit():  # nested: still limited, inner exit does not restore
                assert set(_blas_threads()) == {1}
            assert set(_blas_threads()) == {1}
        assert set(_blas_threads()) == {2}  # the caller's setting is back
        threads.set_core_blas_threads(None)  # no limit: BLAS left alone
        with threads.blas_limit():
            assert set(_blas_threads()) == {2}


def test_limit_applies_inside_generation(restore_limit, monkeypatch):
    """The simulator's chunk generation runs with the limit in force."""
    seen = []
    sim = Simulator(load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 2.0}}))
    original = sim.truthgen._blocks

    def spy(*args, **kwargs):
        seen.append(_blas_threads())
        return original(*args, **kwargs)

    monkeypatch.setattr(sim.truthgen, "_blocks", spy)
    threads.set_core_blas_threads(1)
    sim.reset(0)
    with threadpool_limits(2, user_api="blas"):
        sim.advance(100)
    assert seen and all(set(s) == {1} for s in seen)


@pytest.mark.parametrize("bad", [0, -1, 1.5, "2"])
def test_bad_limit_refused(bad, restore_limit):
    with pytest.raises(ValueError):
        threads.set_core_blas_threads(bad)


def test_numbers_do_not_depend_on_the_limit(restore_limit):
    """Truth and ideal IMU at 1 kHz (1000-sample blocks: products large enough for OpenBLAS
    to split over threads) are bit for bit the same with one BLAS thread and with two: GEMM
    splits the result's rows/columns over threads, never the inner sums."""
    period = 1e-3
    scenario = load_scenario("paper-2012").with_overrides({
        "timing": {"tick_s": period, "imu_period_s": period, "nav_period_s": period, "duration_s": 6.0},
        "gnss": {"enabled": False}, "imu": {"preset": "ideal"}})
    out = {}
    for limit in (1, None):
        threads.set_core_blas_threads(limit)
        sim = Simulator(scenario)
        sim.reset(0)
        with threadpool_limits(2, user_api="blas"):
            chunk = sim.advance(6000)
        out[limit] = chunk
    a, b = out[1], out[None]
    np.testing.assert_array_equal(a.imu.dtheta_r, b.imu.dtheta_r)
    np.testing.assert_array_equal(a.imu.dv_r, b.imu.dv_r)
    np.testing.assert_array_equal(a.truth.position_e, b.truth.position_e)
    np.testing.assert_array_equal(a.truth.mat_nb, b.truth.mat_nb)
