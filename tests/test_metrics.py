"""Metrics against closed forms on synthetic episode records.

The records are built here from the simulator's truth (no estimator): the "estimate" is
truth plus an error we choose, so every figure has a closed form.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from scipy import stats

from navsim.episode import EpisodeRecord
from navsim.errors import ConfigError
from navsim.metrics import (
    ACCURACY_FIELDS,
    EpisodeScore,
    aggregate,
    detect_divergence,
    error_series,
    error_stats,
    find_outages,
    integrated_autocorrelation_time,
    monte_carlo_nees,
    nees_summary,
    nis_summary,
    score_episode,
)
from navsim.scenario import load_scenario
from navsim.simulator import Simulator, build_track

WINDOWS = [[20.0, 35.0], [40.0, 50.0]]
SCENARIO = load_scenario("paper-2012").with_overrides(
    {"timing": {"duration_s": 60.0}, "outages": {"windows_s": WINDOWS}})


@pytest.fixture(scope="module")
def world():
    sim = Simulator(SCENARIO)
    start = sim.reset(0)
    n = SCENARIO.timing.steps
    dt = SCENARIO.timing.nav_period_s
    t = (np.arange(n) + 1) * dt
    truth = sim.truth_at(t)
    gnss_t = np.arange(1, 61, dtype=float)
    n_valid = np.where(np.any([(gnss_t >= a) & (gnss_t < b) for a, b in WINDOWS], axis=0), 0, 7)
    return {"sim": sim, "prior": start.prior, "t": t, "truth": truth, "gnss_t": gnss_t, "n_valid": n_valid,
            "track": build_track(SCENARIO), "dt": dt}


def make_record(world, d_enu=None, dv=None, dheading=None, cov=None, nis=None, nis_dof=None, step_time=None,
                n_valid=None, est_lat=None) -> EpisodeRecord:
    """Truth plus chosen errors: d_enu (n, 3) m in the true ENU frame, dv (n, 3) m/s,
    dheading (n,) rad."""
    tr, t = world["truth"], world["t"]
    n = len(t)
    earth = world["sim"].earth
    d_enu = np.zeros((n, 3)) if d_enu is None else np.broadcast_to(d_enu, (n, 3))
    r_n, r_e = earth.radii(tr.lat)
    lat = tr.lat + d_enu[:, 1] / (r_n + tr.h)
    lon = tr.lon + d_enu[:, 0] / ((r_e + tr.h) * np.cos(tr.lat))
    hpr = np.column_stack([tr.heading, tr.pitch, tr.roll])
    est_hpr = hpr.copy()
    if dheading is not None:
        est_hpr[:, 0] += dheading
    return EpisodeRecord(
        scenario=SCENARIO, seed=0, estimator="synthetic", earth=earth, t=t, truth_s=tr.s, truth_lat=tr.lat,
        truth_lon=tr.lon, truth_h=tr.h, truth_velocity_n=tr.velocity_n, truth_hpr=hpr,
        est_lat=lat if est_lat is None else est_lat, est_lon=lon, est_h=tr.h + d_enu[:, 2],
        est_velocity_n=tr.velocity_n + (0.0 if dv is None else dv), est_hpr=est_hpr, est_cov=cov,
        nis=np.full(n, np.nan) if nis is None else nis, nis_dof=np.zeros(n, int) if nis_dof is None else nis_dof,
        step_time_s=np.full(n, 2e-6) if step_time is None else step_time,
        gnss_t=world["gnss_t"], gnss_n_valid=world["n_valid"] if n_valid is None else n_valid,
        gnss_receiver_outage=np.zeros(len(world["gnss_t"]), bool), prior=world["prior"],
    )


# ------------------------------------------------------------------ position split
def test_constant_east_offset_gives_rmse_three_and_split_by_heading(world):
    rec = make_record(world, d_enu=[3.0, 0.0, 0.0])
    series = error_series(rec, world["track"])
    heading = world["truth"].heading  # the vehicle's heading, from the motion model (no oscillations here)
    np.testing.assert_allclose(series.horizontal_m, 3.0, rtol=1e-9)
    np.testing.assert_allclose(series.along_m, 3.0 * np.sin(heading), atol=1e-6)
    np.testing.assert_allclose(series.cross_m, 3.0 * np.cos(heading), atol=1e-6)  # east of a north-going track: right
    score = score_episode(rec, series=series)
    for key in ("horizontal_rmse_m", "horizontal_max_m", "horizontal_final_m", "horizontal_cep50_m", "horizontal_cep95_m"):
        assert getattr(score, key) == pytest.approx(3.0, rel=1e-9)
    assert score.along_track_rmse_m == pytest.approx(3.0 * math.sqrt(np.mean(np.sin(heading) ** 2)), rel=1e-6)
    assert score.cross_track_rmse_m == pytest.approx(3.0 * math.sqrt(np.mean(np.cos(heading) ** 2)), rel=1e-6)
    assert score.vertical_rmse_m == pytest.approx(0.0, abs=1e-9)
    assert score.velocity_rms_mps == 0.0 and score.attitude_rms_deg < 1e-6
    assert not score.diverged and math.isnan(score.anees)


def test_offset_along_the_velocity_is_pure_along_track(world):
    v = world["truth"].velocity_n[:, :2]
    u = v / np.linalg.norm(v, axis=1, keepdims=True)
    d = np.column_stack([5.0 * u, np.full(len(u), -2.0)])
    score = score_episode(make_record(world, d_enu=d), track=world["track"])
    assert score.along_track_rmse_m == pytest.approx(5.0, rel=1e-6)
    assert score.cross_track_max_m < 1e-5
    assert score.vertical_rmse_m == pytest.approx(2.0, rel=1e-9)
    left = np.column_stack([-u[:, 1], u[:, 0]]) * 4.0  # 4 m to the left: cross-track -4
    series = error_series(make_record(world, d_enu=np.column_stack([left, np.zeros(len(u))])), world["track"])
    np.testing.assert_allclose(series.cross_m, -4.0, atol=1e-5)


def test_velocity_and_heading_offsets(world):
    rec = make_record(world, dv=np.array([0.3, -0.4, 0.0]), dheading=0.01)
    score = score_episode(rec, track=world["track"])
    assert score.velocity_rms_mps == pytest.approx(0.5, rel=1e-12)
    assert score.velocity_max_mps == pytest.approx(0.5, rel=1e-12)
    # heading is the outermost rotation Rz(-heading): the error rotation is 0.01 rad about Up
    assert score.attitude_rms_deg == pytest.approx(math.degrees(0.01), rel=1e-8)
    assert score.heading_rms_deg == pytest.approx(math.degrees(0.01), rel=1e-9)


def test_percentiles_of_a_ramp():
    x = np.linspace(0.0, 10.0, 1001)  # |error| uniform on [0, 10]
    st = error_stats(-x)
    assert st.p50 == pytest.approx(5.0) and st.p95 == pytest.approx(9.5)
    assert st.rms == pytest.approx(math.sqrt(np.mean(x**2))) and st.max == 10.0 and st.final == 10.0
    st = error_stats(np.array([1.0, np.nan]))
    assert st.rms == 1.0 and math.isnan(st.final)


# ------------------------------------------------------------------ outages
def test_linear_drift_in_outages_gives_known_maxima(world):
    """Error grows at 0.5 m/s since the last epoch with a fix: the maximum inside an
    outage is reached one step before the fix comes back."""
    t, gt, ok = world["t"], world["gnss_t"], world["n_valid"] >= 4
    good_t = gt[ok]
    idx = np.searchsorted(good_t, t + 1e-9, side="right") - 1
    last_fix = np.where(idx >= 0, good_t[np.clip(idx, 0, None)], 0.0)
    rate = 0.5
    rec = make_record(world, d_enu=np.column_stack([rate * (t - last_fix), np.zeros((len(t), 2))]))
    score = score_episode(rec, track=world["track"])
    dt = world["dt"]
    expected = [rate * (35.0 - dt - 19.0), rate * (50.0 - dt - 39.0)]
    assert score.outage_count == 2
    assert score.outage_total_s == pytest.approx(25.0)
    assert [o.max_drift_m for o in score.outages] == pytest.approx(expected, rel=1e-9)
    assert [o.t_max for o in score.outages] == pytest.approx([35.0 - dt, 50.0 - dt])
    assert score.outage_max_drift_m == pytest.approx(max(expected), rel=1e-9)
    assert score.outage_rms_drift_m == pytest.approx(math.sqrt((expected[0] ** 2 + expected[1] ** 2) / 2), rel=1e-9)
    assert all(o.closed for o in score.outages)


def test_find_outages_at_the_episode_edges():
    gnss_t = np.arange(1.0, 11.0)
    n_valid = np.array([0, 3, 5, 6, 6, 2, 6, 6, 0, 0])
    out = find_outages(gnss_t, n_valid, t_start=0.0, t_end=10.0, gnss_period_s=1.0)
    assert [(o.t_first, o.t_last, o.n_epochs) for o in out] == [(1.0, 2.0, 2), (6.0, 6.0, 1), (9.0, 10.0, 2)]
    assert [(o.t_from, o.t_to, o.closed) for o in out] == [(0.0, 3.0, True), (5.0, 7.0, True), (8.0, 10.0, False)]
    assert find_outages(gnss_t, np.full(10, 9), 0.0, 10.0) == []
    with pytest.raises(ConfigError):
        find_outages(gnss_t, n_valid[:3], 0.0, 10.0)


def test_open_outage_counts_the_last_step(world):
    n_valid = world["n_valid"].copy()
    n_valid[-5:] = 2  # epochs 56..60: GNSS never comes back
    t = world["t"]
    d = np.column_stack([np.where(t > 55.0, t - 55.0, 0.0), np.zeros((len(t), 2))])
    score = score_episode(make_record(world, d_enu=d, n_valid=n_valid), track=world["track"])
    last = score.outages[-1]
    assert not last.closed and last.t_from == 55.0 and last.t_to == pytest.approx(60.0)
    assert last.max_drift_m == pytest.approx(5.0, rel=1e-9)


# ------------------------------------------------------------------ consistency
def _spd(rng, d, scale):
    a = rng.standard_normal((d, d))
    return scale * (a @ a.T / d + np.eye(d))


def _gaussian_record(world, inflate=1.0, seed=1):
    rng = np.random.default_rng(seed)
    n = len(world["t"])
    p6 = _spd(rng, 6, 4.0)
    p6[3:, 3:] *= 0.01  # velocities in m/s
    p6[:3, 3:] *= 0.1
    p6[3:, :3] *= 0.1
    e = rng.standard_normal((n, 6)) @ np.linalg.cholesky(p6).T * inflate
    cov = np.full((n, 9, 9), np.nan)
    cov[:, :6, :6] = p6  # attitude not estimated: nan, skipped
    cov[:10] = np.nan  # no covariance at all in the first steps: skipped
    return make_record(world, d_enu=e[:, :3], dv=e[:, 3:], cov=cov), p6


def test_gaussian_errors_give_anees_near_the_dimension(world):
    rec, _ = _gaussian_record(world)
    score = score_episode(rec, track=world["track"])
    n = len(world["t"]) - 10
    assert score.nees_components == "dE,dN,dU,dvE,dvN,dvU" and score.nees_dof == 6
    assert score.anees_lower < score.anees < score.anees_upper
    assert abs(score.anees - 6.0) < 4.0 * math.sqrt(2 * 6 / n)  # 4 sigma of the mean of chi2(6)
    assert abs(score.nees_in_bounds_fraction - 0.95) < 4.0 * math.sqrt(0.95 * 0.05 / n)
    assert 0.8 * n < score.nees_n_eff <= n  # white errors: tau near 1
    # the bounds are chi2(d N_eff)/N_eff
    lo, hi = stats.chi2.ppf([0.025, 0.975], 6 * score.nees_n_eff) / score.nees_n_eff
    assert (score.anees_lower, score.anees_upper) == pytest.approx((lo, hi))


def test_overconfident_covariance_is_flagged(world):
    rec, _ = _gaussian_record(world, inflate=2.0)
    score = score_episode(rec, track=world["track"])
    assert score.anees == pytest.approx(24.0, rel=0.05)
    assert score.anees > score.anees_upper
    assert score.nees_in_bounds_fraction < 0.7


def test_nees_summary_with_wide_confidence(world):
    rec, p6 = _gaussian_record(world, seed=7)
    series = error_series(rec, world["track"])
    ns = nees_summary(series.error, rec.est_cov, confidence=0.999)
    assert ns.dof == 6 and ns.lower < ns.anees < ns.upper
    # the per-step NEES is e^T P^-1 e with the errors we drew
    e = series.error[20, :6]
    assert ns.series[20] == pytest.approx(e @ np.linalg.solve(p6, e), rel=1e-6)
    assert nees_summary(series.error, None) is None


def test_integrated_autocorrelation_time_of_ar1():
    """AR(1) with coefficient rho: tau = (1 + rho) / (1 - rho)."""
    rng = np.random.default_rng(3)
    for rho in (0.0, 0.5, 0.9):
        w = rng.standard_normal(200_000)
        x = np.empty_like(w)
        x[0] = w[0] / math.sqrt(1 - rho**2)
        from scipy.signal import lfilter

        x = lfilter([1.0], [1.0, -rho], w, zi=[rho * x[0]])[0]
        tau = integrated_autocorrelation_time(x)
        assert tau == pytest.approx((1 + rho) / (1 - rho), rel=0.12)


def test_nis_summary_of_chi_square_draws():
    rng = np.random.default_rng(5)
    n = 4000
    dof = rng.integers(4, 9, n)
    nis = rng.chisquare(dof)
    full_nis, full_dof = np.full(3 * n, np.nan), np.zeros(3 * n, int)
    full_nis[::3], full_dof[::3] = nis, dof
    s = nis_summary(full_nis, full_dof, confidence=0.999)
    assert s.updates == n and s.mean_dof == pytest.approx(dof.mean())
    assert s.lower < s.normalised < s.upper
    assert s.normalised == pytest.approx(nis.sum() / dof.sum())
    assert abs(s.in_bounds_fraction - 0.999) < 4 * math.sqrt(0.999 * 0.001 / n) + 1e-3
    big = nis_summary(2.0 * full_nis, full_dof)
    assert big.normalised > big.upper
    assert nis_summary(np.full(5, np.nan), np.zeros(5, int)) is None


def test_nis_enters_the_score(world):
    n = len(world["t"])
    nis, dof = np.full(n, np.nan), np.zeros(n, int)
    nis[99::100], dof[99::100] = 5.0, 5
    score = score_episode(make_record(world, nis=nis, nis_dof=dof), track=world["track"])
    assert score.nis_updates == 60 and score.anis == 5.0 and score.nis_normalised == 1.0
    lo, hi = stats.chi2.ppf([0.025, 0.975], 300) / 300
    assert (score.nis_normalised_lower, score.nis_normalised_upper) == pytest.approx((lo, hi))


def test_monte_carlo_nees_of_consistent_runs():
    rng = np.random.default_rng(11)
    runs = rng.chisquare(9, size=(25, 2000))
    runs[3, :100] = np.nan
    mc = monte_carlo_nees(runs, 9)
    assert mc.runs[0] == 24 and mc.runs[-1] == 25
    assert mc.anees == pytest.approx(9.0, rel=0.01)
    assert abs(mc.in_bounds_fraction - 0.95) < 4 * math.sqrt(0.95 * 0.05 / 1900)
    assert mc.upper[-1] == pytest.approx(stats.chi2.ppf(0.975, 225) / 25)
    bad = monte_carlo_nees(3.0 * runs, 9)
    assert bad.in_bounds_fraction < 0.01


# ------------------------------------------------------------------ divergence, CPU, output
def test_divergence_by_threshold_and_by_nan(world):
    t = world["t"]
    d = np.column_stack([np.where(t >= 30.0, 2000.0, 1.0), np.zeros((len(t), 2))])
    score = score_episode(make_record(world, d_enu=d), track=world["track"])
    assert score.diverged and score.diverged_at_s == pytest.approx(30.0)
    assert score.divergence_reason.startswith("horizontal error 2000 m > 1000 m at 30 s")
    ok = score_episode(make_record(world, d_enu=d), track=world["track"], divergence_threshold_m=5000.0)
    assert not ok.diverged and ok.diverged_at_s != ok.diverged_at_s and ok.divergence_reason == ""
    # RMS of 1 m for 29.99 s and 2000 m for 30.01 s: the figure a non-diverged episode gets
    assert ok.horizontal_rmse_m == pytest.approx(math.sqrt(np.mean(d[:, 0] ** 2)), rel=1e-6)
    lat = world["truth"].lat.copy()
    lat[-1] = np.nan
    nan_score = score_episode(make_record(world, est_lat=lat), track=world["track"])
    assert nan_score.diverged and nan_score.diverged_at_s == pytest.approx(60.0)
    assert "non-finite position estimate at 60 s (1 of 6000 steps)" in nan_score.divergence_reason
    # never the figure of the finite fraction (which would be 0 m here)
    assert math.isnan(nan_score.horizontal_rmse_m) and math.isnan(nan_score.horizontal_final_m)
    with pytest.raises(ConfigError):
        score_episode(make_record(world), track=world["track"], divergence_threshold_m=0.0)


def _accuracy_all_nan(score) -> bool:
    flat = score.to_flat_dict()
    return all(flat[k] is None for k in ACCURACY_FIELDS) and all(
        math.isnan(o.max_drift_m) for o in score.outages)


def test_consistent_filter_is_not_diverged(world):
    """White errors drawn from the claimed covariance: NEES ~ chi2(6) at every step, so the
    per-step 0.9999 quantile (27.9) is exceeded at ~1e-4 of the steps and never at 80 %
    of a 20-s window; the figures are those of the drawn errors."""
    rec, _ = _gaussian_record(world)
    score = score_episode(rec, track=world["track"])
    assert not score.diverged and score.divergence_reason == "" and math.isnan(score.diverged_at_s)
    series = error_series(rec, world["track"])
    h = np.hypot(series.error[:, 0], series.error[:, 1])
    assert score.horizontal_rmse_m == pytest.approx(math.sqrt(np.mean(h**2)), rel=1e-12)
    assert math.isfinite(score.outage_rms_drift_m)
    # twice the claimed sigma (NEES ~ 4 chi2(6), above 27.9 at 32 % of the steps): inconsistent, not diverged
    assert not score_episode(_gaussian_record(world, inflate=2.0)[0], track=world["track"]).diverged


def test_covariance_100_times_too_small_for_30_s_is_diverged(world):
    """The same errors, the claimed covariance divided by 100 for 15 s < t <= 45 s: the NEES is
    100 chi2(6) there, above 27.9 except at P(chi2(6) < 0.279) = 4e-4 of the steps, which
    fills every 20-s window inside those 30 s; the accuracy figures become NaN."""
    rec, _ = _gaussian_record(world)
    t = world["t"]
    claimed = rec.est_cov
    cov = claimed.copy()
    cov[(t > 15.0 + 1e-9) & (t <= 45.0 + 1e-9)] /= 100.0
    rec = dataclasses.replace(rec, est_cov=cov)
    score = score_episode(rec, track=world["track"])
    assert score.diverged
    assert 15.0 < score.diverged_at_s <= 15.0 + 5 * world["dt"]  # the first steps of the bad stretch
    assert "NEES > 27.86 (chi2(6) 0.9999 quantile)" in score.divergence_reason
    assert _accuracy_all_nan(score)
    assert math.isfinite(score.anees) and score.anees > score.anees_upper  # consistency figures kept
    # a 40-s window needs 32 s above the quantile: 30 s are not enough
    assert not score_episode(rec, track=world["track"], divergence_nees_window_s=40.0).diverged
    # 10 s of it do not fill 80 % of a 20-s window either
    short = cov.copy()
    short[t > 25.0 + 1e-9] = claimed[t > 25.0 + 1e-9]
    assert not score_episode(dataclasses.replace(rec, est_cov=short), track=world["track"]).diverged


def test_filter_that_blows_up(world):
    """Horizontal error 10^((t - 0.005)/3) m (crosses 1000 m at t = 9.005 s, between two
    steps), then no estimate at all (NaN) from 40 s: diverged at the step t = 9.01 s, both reasons given, and every
    accuracy and consistency figure NaN (none from the finite first 40 s)."""
    t = world["t"]
    err = np.minimum(10.0 ** ((t - 0.005) / 3.0), 1e9)
    d = np.column_stack([err, np.zeros((len(t), 2))])
    lat = make_record(world, d_enu=d).est_lat.copy()
    lat[t >= 40.0 - 1e-9] = np.nan
    score = score_episode(make_record(world, d_enu=d, est_lat=lat), track=world["track"])  # no covariance
    first = t[np.argmax(err > 1000.0)]
    assert score.diverged and score.diverged_at_s == pytest.approx(9.01) and first == pytest.approx(9.01)
    assert score.divergence_reason.startswith("horizontal error 1003.8") and "> 1000 m at 9.01 s" in score.divergence_reason
    assert "; non-finite position estimate at 40 s (2001 of 6000 steps)" in score.divergence_reason
    assert _accuracy_all_nan(score)
    # with a (constant, few-metre) covariance the NEES check fires first, long before 1000 m,
    # and the consistency figures are NaN too: they would come from the finite 40 s
    with_cov = score_episode(make_record(world, d_enu=d, est_lat=lat, cov=_gaussian_record(world)[0].est_cov),
                             track=world["track"])
    assert with_cov.diverged_at_s < first and with_cov.divergence_reason.startswith("NEES > 27.86")
    assert _accuracy_all_nan(with_cov) and math.isnan(with_cov.anees) and math.isnan(with_cov.nees_in_bounds_fraction)
    # the bench means leave it out and say so through n
    fine = score_episode(_gaussian_record(world)[0], track=world["track"])
    agg = aggregate([fine, score])
    assert agg["horizontal_rmse_m"].n == 1 and agg["horizontal_rmse_m"].mean == fine.horizontal_rmse_m
    assert agg["diverged"].n == 2 and agg["diverged"].mean == 0.5


def test_divergence_checks_on_partial_quantities():
    """Check 1 on velocity / attitude only where they are reported at some step."""
    t = np.arange(1, 101) * 0.1
    pos = np.zeros((100, 3))
    never = np.full((100, 3), np.nan)
    h = np.zeros(100)
    assert not detect_divergence(t, {"position": pos, "velocity": never, "attitude": never}, h).diverged
    vel = np.zeros((100, 3))
    vel[50:] = np.inf
    div = detect_divergence(t, {"position": pos, "velocity": vel}, h)
    assert div.diverged and div.non_finite and div.at_s == pytest.approx(5.1)
    assert div.reason == "non-finite velocity estimate at 5.1 s (50 of 100 steps)"
    for bad in ({"nees_quantile": 1.0}, {"nees_window_s": 0.0}, {"threshold_m": -1.0}):
        with pytest.raises(ConfigError):
            detect_divergence(t, {"position": pos}, h, **bad)


def test_step_time_in_microseconds(world):
    n = len(world["t"])
    cpu = np.linspace(1e-6, 3e-6, n)
    score = score_episode(make_record(world, step_time=cpu), track=world["track"])
    assert score.step_time_us == pytest.approx(2.0)
    assert score.cpu_total_s == pytest.approx(cpu.sum())
    assert score.realtime_factor == pytest.approx(60.0 / cpu.sum())


def test_flat_dict_is_json_safe_with_units(world):
    score = score_episode(make_record(world, d_enu=[1.0, 0.0, 0.0]), track=world["track"])
    flat = score.to_flat_dict()
    for key in ("horizontal_rmse_m", "horizontal_final_m", "outage_max_drift_m", "anees", "step_time_us"):
        assert key in flat
    assert flat["anees"] is None and flat["nis_normalised"] is None
    assert all(not isinstance(v, (dict, list, tuple)) for v in flat.values())
    text = json.dumps(flat, allow_nan=False)
    assert json.loads(text)["horizontal_rmse_m"] == pytest.approx(1.0)
    units = EpisodeScore.units()
    assert set(units) == set(flat)
    suffix = {"m": "_m", "m/s": "_mps", "s": "_s", "us": "_us", "deg": "_deg"}
    for key, unit in units.items():
        if unit:
            assert key.endswith(suffix[unit]), key


# ------------------------------------------------------------------ aggregation
def _rows(values):
    return [{"horizontal_rmse_m": v} for v in values]


def test_aggregate_t_interval_against_the_table():
    out = aggregate(_rows([1.0, 2.0, 3.0, 4.0]))["horizontal_rmse_m"]
    half = 3.182446 * math.sqrt(5.0 / 3.0) / 2.0  # t_{0.975, 3} from the table; s^2 = 5/3
    assert out.mean == 2.5 and out.n == 4 and out.unit == "m"
    assert (out.low, out.high) == pytest.approx((2.5 - half, 2.5 + half), rel=1e-6)


def test_aggregate_percentile_and_missing_values():
    rows = _rows(list(np.arange(1.0, 101.0))) + [{"horizontal_rmse_m": None}]
    out = aggregate(rows, method="percentile")["horizontal_rmse_m"]
    assert out.n == 100 and out.mean == 50.5
    assert (out.low, out.high) == pytest.approx((3.475, 97.525))  # linear interpolation at 2.475 and 97.525 - 1
    one = aggregate(_rows([7.0]))["horizontal_rmse_m"]
    assert one.mean == 7.0 and one.low != one.low
    with pytest.raises(ConfigError):
        aggregate(_rows([1.0]), method="bootstrap")


def test_aggregate_of_scores(world):
    scores = [score_episode(make_record(world, d_enu=[a, 0.0, 0.0]), track=world["track"]) for a in (1.0, 3.0)]
    out = aggregate(scores)
    assert out["horizontal_rmse_m"].mean == pytest.approx(2.0)
    assert out["diverged"].mean == 0.0 and out["anees"].n == 0


def test_anees_bounds_cover_time_correlated_errors():
    """Stationary AR(1) errors (rho = 0.95, covariance I): the time-average NEES falls
    inside its bounds in about 95 % of episodes because the bounds use N / tau; bounds
    that treated the steps as independent would be about 6 times too narrow."""
    from scipy.signal import lfilter

    rng = np.random.default_rng(21)
    n, rho, reps = 4000, 0.95, 200
    cov = np.full((n, 9, 9), np.nan)
    cov[:, :3, :3] = np.eye(3)
    inside = naive_inside = 0
    for _ in range(reps):
        w = rng.standard_normal((n, 3)) * math.sqrt(1 - rho**2)
        e = lfilter([1.0], [1.0, -rho], w, axis=0, zi=rho * rng.standard_normal((1, 3)))[0]
        err = np.full((n, 9), np.nan)
        err[:, :3] = e
        s = nees_summary(err, cov)
        inside += s.lower <= s.anees <= s.upper
        lo, hi = stats.chi2.ppf([0.025, 0.975], 3 * n) / n
        naive_inside += lo <= s.anees <= hi
    assert 0.88 <= inside / reps <= 0.995  # binomial sd 0.015 around 0.95
    assert naive_inside / reps < 0.6
