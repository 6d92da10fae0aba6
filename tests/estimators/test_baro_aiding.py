"""Barometric height aiding of lc-ekf (LC.9) and tc-ekf (TC.10): off is the filter of before
bit for bit, step equals batch, aiding bounds the vertical error through a GNSS outage,
and the covariance it claims is consistent (chi-square bounds over seeds)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2
from tolerances import assert_same_solution

from navsim import estimators
from navsim.episode import make_context, measurement_batch, run_episode
from navsim.scenario import load_scenario
from navsim.simulator import Simulator

FILTERS = ("lc-ekf", "tc-ekf")


def _scenario(duration, outage_start, baro=True, imu="tactical"):
    over = {"timing": {"duration_s": duration}, "outages": {"windows_s": [[outage_start, duration]]},
            "imu": {"preset": imu}}
    if baro:
        over["baro"] = {"enabled": True}
    return load_scenario("paper-2012").with_overrides(over)


@pytest.mark.parametrize("name", FILTERS)
def test_off_is_the_filter_of_before_bit_for_bit(name):
    # the barometer's stream is its own: with baro="none" the filter sees exactly the data
    # of a scenario without a barometer, so every number is the same
    plain = run_episode(_scenario(15.0, 10.0, baro=False), estimators.make(name), seed=4)
    ignored = run_episode(_scenario(15.0, 10.0), estimators.make(name, baro="none"), seed=4)
    np.testing.assert_array_equal(plain.est_h, ignored.est_h)
    np.testing.assert_array_equal(plain.est_cov, ignored.est_cov)
    aided = run_episode(_scenario(15.0, 10.0), estimators.make(name), seed=4)
    assert not np.array_equal(plain.est_h, aided.est_h)


@pytest.mark.parametrize("name", FILTERS)
def test_step_equals_batch_with_the_barometer(name):
    sc = _scenario(6.0, 3.0)
    sim = Simulator(sc)
    start, chunks = sim.run(1, chunk_steps=600)
    ctx = make_context(sc)
    batch_est, step_est = estimators.make(name), estimators.make(name)
    batch_est.reset(ctx, start.prior)
    step_est.reset(ctx, start.prior)
    batch = measurement_batch(chunks[0], sim.constellation.prn, sc.timing.nav_period_s)
    out = batch_est.step_batch(batch)
    rows = np.array([step_est.step(batch.measurement(i)).as_action() for i in range(len(batch))])
    # the step path runs the batch code on a batch of one at update steps and the engine's
    # one-step path in between: the same operations (module docstrings), bit for bit, but
    # for the attitude angles' atan2/asin (tests/tolerances.py)
    assert_same_solution(rows, out.solution)
    assert np.count_nonzero(out.nis_dof) >= 5  # the 1-s baro updates happened


def _end_errors(name, scenario, seeds, **options):
    """Vertical error, its claimed variance and the 9-dof NEES at the last step of each seed."""
    rows = []
    for seed in seeds:
        r = run_episode(scenario, estimators.make(name, **options), seed=seed)
        cov = r.est_cov[-1]
        dr_u = r.est_h[-1] - r.truth_h[-1]
        rows.append((dr_u, cov[2, 2]))
    return np.array(rows)


@pytest.mark.parametrize("name", FILTERS)
def test_aiding_bounds_the_vertical_error_in_an_outage(name):
    # tactical IMU, 50-s outage: without the barometer the INS vertical channel drifts by
    # metres; with it the error stays at the altimeter bias the filter could calibrate (~1 m)
    seeds = (0, 1)
    aided = _end_errors(name, _scenario(70.0, 20.0), seeds)
    free = _end_errors(name, _scenario(70.0, 20.0), seeds, baro="none")
    rms_aided = float(np.sqrt(np.mean(aided[:, 0] ** 2)))
    rms_free = float(np.sqrt(np.mean(free[:, 0] ** 2)))
    assert rms_aided < 0.5 * rms_free, (rms_aided, rms_free)
    # the claimed vertical sigma shrinks too (the bias state bounds it)
    assert np.all(aided[:, 1] < free[:, 1])
    # consistency at the end of the outage: sum of e^2 / P over seeds ~ chi2(len(seeds))
    stat = float(np.sum(aided[:, 0] ** 2 / aided[:, 1]))
    assert stat < chi2.isf(1e-3, len(seeds)), stat


@pytest.mark.slow
@pytest.mark.parametrize("name", FILTERS)
def test_aiding_consistency_over_twenty_seeds(name):
    seeds = range(20)
    aided = _end_errors(name, _scenario(300.0, 100.0), seeds)
    free = _end_errors(name, _scenario(300.0, 100.0), seeds, baro="none")
    rms_aided = float(np.sqrt(np.mean(aided[:, 0] ** 2)))
    rms_free = float(np.sqrt(np.mean(free[:, 0] ** 2)))
    print(f"{name}: vertical RMS at the end of the 200-s outage {rms_free:.2f} m without, {rms_aided:.2f} m "
          f"with the barometer; mean e^2/P {np.mean(aided[:, 0] ** 2 / aided[:, 1]):.2f}")
    assert rms_aided < 0.5 * rms_free
    stat = float(np.sum(aided[:, 0] ** 2 / aided[:, 1]))  # ~ chi2(20) for a consistent filter
    assert chi2.ppf(0.005, 20) < stat < chi2.isf(0.005, 20), stat
