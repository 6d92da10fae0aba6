"""GNSS only: LS fixes consistent with the noise; CV filter; batch = step."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.stats import chi2

from navsim.episode import make_context, measurement_batch, measurements, run_episode
from navsim.estimators import make
from navsim.estimators.base import row_of, row_stepping
from navsim.metrics import error_vector, nees
from navsim.scenario import load_scenario
from navsim.simulator import Simulator
from tolerances import assert_covariance_close, assert_same_arithmetic


def _scenario(duration=150.0, gnss="paper-2012", outages=()):
    return load_scenario("paper-2012").with_overrides({
        "timing": {"duration_s": duration}, "gnss": {"preset": gnss},
        "outages": {"windows_s": [list(w) for w in outages]}})


def _epoch_rows(rec):
    return np.flatnonzero(np.isclose((rec.t + 1e-9) % rec.scenario.timing.gnss_period_s, 0.0, atol=1e-6))


def test_ls_position_errors_consistent_with_the_noise():
    """At the epochs the LS fix error is N(0, sigma^2 (H^T H)^-1): the pooled NEES of
    position and velocity over the epochs (independent) lies in the exact chi-square band."""
    rec = run_episode(_scenario(150.0), make("gnss-ls"), seed=4)
    e = error_vector(rec)
    rows = _epoch_rows(rec)
    for block in (slice(0, 3), slice(3, 6)):
        values = nees(e[rows], rec.est_cov[rows], block)
        k = len(values)
        lo, hi = chi2.ppf([0.005, 0.995], 3 * k) / k
        assert lo < values.mean() < hi, (block, values.mean(), lo, hi)
    assert np.all(np.isnan(rec.est_hpr)) and np.all(np.isnan(rec.est_cov[:, 6:, 6:]))


def test_ls_ideal_gnss_is_exact_at_epochs_and_extrapolates_between():
    rec = run_episode(_scenario(20.0, gnss="ideal"), make("gnss-ls"), seed=0)
    e = error_vector(rec)
    rows = _epoch_rows(rec)
    assert np.abs(e[rows, :3]).max() < 1e-3 and np.abs(e[rows, 3:6]).max() < 1e-6
    # between epochs: constant-velocity extrapolation of a 20 m/s train, error << 20 m
    assert np.abs(e[rows[0]:, :3]).max() < 0.05
    held = run_episode(_scenario(20.0, gnss="ideal"), make("gnss-ls", extrapolate=False), seed=0)
    assert np.abs(error_vector(held)[rows[0]:, :3]).max() > 10.0  # holding lags by ~v T


def test_cv_filter_beats_single_epoch_fixes_and_is_consistent():
    sc = _scenario(150.0)
    ls = error_vector(run_episode(sc, make("gnss-ls"), seed=2))
    rec = run_episode(sc, make("gnss-cv"), seed=2)
    cv = error_vector(rec)
    late = slice(3000, None)
    assert np.sqrt(np.mean(cv[late, :3] ** 2)) < 0.6 * np.sqrt(np.mean(ls[late, :3] ** 2))
    nis = rec.nis[np.isfinite(rec.nis)]
    k = len(nis)
    hi = chi2.ppf(0.995, 6 * k) / k
    # the default accel_psd (0.1 m^2/s^3) is larger than a constant-speed train needs:
    # the filter is conservative (NIS ~ 4.9 of 6), never overconfident
    assert 0.6 * 6 < nis.mean() < hi, (nis.mean(), hi)
    assert 0.5 * 6 < np.nanmean(nees(cv, rec.est_cov, slice(0, 6))) < 1.5 * 6


def _episode(duration, outages=()):
    """Scenario, prior, context and the one chunk of a short paper-2012 episode, seed 0."""
    sc = _scenario(duration, outages=outages)
    sim = Simulator(sc)
    prior = sim.reset(0).prior
    ctx = make_context(sim)
    return sc, prior, ctx, np.asarray(sim.constellation.prn), next(iter(sim.chunks(10_000)))


def _slice(batch, a, b):
    """Steps a..b of a MeasurementBatch (epochs re-indexed)."""
    return dataclasses.replace(
        batch, step=batch.step[a:b], t=batch.t[a:b], dtheta_r=batch.dtheta_r[a:b], dv_r=batch.dv_r[a:b],
        dtheta_sub=batch.dtheta_sub[a:b], dv_sub=batch.dv_sub[a:b],
        gnss=tuple((j - a, obs) for j, obs in batch.gnss if a <= j < b))


def _rows(results):
    """Solution rows, covariances, NIS and dof of step-wise results (Estimate or StepRow)."""
    rows, covs, nis, dof = [], [], [], []
    for r in results:
        row, cov, n, d = row_of(r) if not isinstance(r, tuple) else r
        rows.append(row)
        covs.append(cov)
        nis.append(np.nan if n is None else n)
        dof.append(d or 0)
    return np.array(rows), np.array(covs), np.array(nis), np.array(dof)


@pytest.mark.parametrize("name,options", [("gnss-ls", {}), ("gnss-ls", {"extrapolate": False}), ("gnss-cv", {})])
def test_step_row_and_step_equal_step_batch_bit_for_bit(name, options):
    """The step-wise path (rows of the steps between fixes predicted ahead) gives the
    batch's numbers: the same prediction, elementwise over the steps, so bit for bit,
    through epochs and a 3-s outage; ``step_row`` is the agent's fast path."""
    sc, prior, ctx, prn, chunk = _episode(8.0, outages=[(2.5, 5.5)])
    a, b, c = (make(name, **options) for _ in range(3))
    for est in (a, b, c):
        est.reset(ctx, prior)
    assert row_stepping(b) is not None
    out = a.step_batch(measurement_batch(chunk, prn, sc.timing.nav_period_s))
    ms = list(measurements(chunk, prn, sc.timing.nav_period_s))
    for results in ([b.step_row(m) for m in ms], [c.step(m) for m in ms]):
        rows, covs, nis, dof = _rows(results)
        assert_same_arithmetic(rows, out.solution)
        assert_same_arithmetic(covs, out.covariance)
        assert_same_arithmetic(nis, out.nis)
        assert_same_arithmetic(dof, out.nis_dof)
    assert len(b._ahead.t) == b._ahead.span > 1  # the rows were predicted ahead
    # before the first fix the prior is extrapolated with the prior covariance
    assert np.allclose(out.covariance[0, :3, :3], prior.covariance[:3, :3], rtol=0.01)


@pytest.mark.parametrize("name", ["gnss-ls", "gnss-cv"])
def test_step_wise_times_of_another_source_and_a_changed_option(name):
    """Steps at times other than the simulator's ``(step + 1) dt`` are predicted alone, and
    an option changed between epochs (``set_noise_scale``: gnss-cv's ``accel_psd``; gnss-ls
    ``accel_psd`` by hand) is used from the next step on: still the batch's numbers."""
    sc, prior, ctx, prn, chunk = _episode(4.0)
    dt = sc.timing.nav_period_s
    batch = measurement_batch(chunk, prn, dt)
    shifted = dataclasses.replace(batch, t=batch.t + 0.25 * dt)  # the fixes keep their own epoch times
    cut = len(batch) // 2 + 7  # between two epochs
    a, b = make(name), make(name)
    a.reset(ctx, prior)
    b.reset(ctx, prior)

    def change(est):
        if name == "gnss-cv":
            est.set_noise_scale(4.0, 1.0)
        else:
            est.accel_psd = 4.0 * est.accel_psd

    first = a.step_batch(_slice(shifted, 0, cut))
    change(a)
    second = a.step_batch(_slice(shifted, cut, len(batch)))
    steps = []
    for i in range(len(batch)):
        if i == cut:
            change(b)
        steps.append(b.step_row(shifted.measurement(i)))
    rows, covs, _, _ = _rows(steps)
    assert len(b._ahead.t) == 1  # not the simulator's times: each step predicted alone
    assert_same_arithmetic(rows, np.concatenate([first.solution, second.solution]))
    assert_same_arithmetic(covs, np.concatenate([first.covariance, second.covariance]))
    unchanged = make(name)
    unchanged.reset(ctx, prior)
    ref = unchanged.step_batch(shifted)
    assert_same_arithmetic(covs[:cut], ref.covariance[:cut])
    assert not np.array_equal(covs[cut + 1], ref.covariance[cut + 1])  # the change took effect

