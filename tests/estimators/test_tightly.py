"""Tests of the tightly coupled EKF and UKF (navsim.estimators.tightly)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.stats import chi2

from navsim.earth import SPHERICAL, WGS84
from navsim.episode import make_context, measurement_batch, run_episode
from navsim.errors import ConfigError
from navsim.estimators import make
from navsim.estimators._inserror import joseph_update
from navsim.estimators.tightly import (
    TightlyCoupledEkf,
    TightlyCoupledUkf,
    observation_jacobian,
    predict_observables,
    sigma_points,
    unscented_predict,
    unscented_update,
)
from navsim.metrics import error_vector, nees
from navsim.scenario import load_scenario
from navsim.simulator import Simulator

CLEAN_STANDALONE = {"preset": "standalone", "overrides": {"ionosphere_zenith_m": 0.0, "troposphere_zenith_m": 0.0,
                                                          "multipath_sigma_m": 0.0}}


def _scenario(duration, outage=None, **more):
    over = {"timing": {"duration_s": duration}, "outages": {"windows_s": [outage] if outage else []}}
    over.update(more)
    return load_scenario("paper-2012").with_overrides(over)


class KeepSatellites:
    """Wrapper estimator: only the first k valid satellites of each epoch reach the filter."""

    def __init__(self, inner, k):
        self.inner, self.k = inner, k

    def reset(self, context, prior):
        self.inner.reset(context, prior)

    def _thin(self, obs):
        valid = np.zeros_like(obs.valid)
        valid[np.flatnonzero(obs.valid)[: self.k]] = True
        return dataclasses.replace(obs, valid=valid)

    def step(self, m):
        if m.gnss is not None:
            m = dataclasses.replace(m, gnss=self._thin(m.gnss))
        return self.inner.step(m)

    def step_batch(self, batch):
        return self.inner.step_batch(dataclasses.replace(batch, gnss=tuple((j, self._thin(o)) for j, o in batch.gnss)))


# ------------------------------------------------------------------------ construction
def test_registry_and_options():
    assert isinstance(make("tc-ekf"), TightlyCoupledEkf)
    assert isinstance(make("tc-ukf", alpha=0.5), TightlyCoupledUkf)
    with pytest.raises(ConfigError):
        make("tc-ekf", clock="sometimes")
    with pytest.raises(ConfigError):
        TightlyCoupledUkf(alpha=-1.0)
    with pytest.raises(ConfigError):
        make("tc-ekf", pseudorange_sigma_m=-1.0)


# ------------------------------------------------------------------------ Jacobians
@pytest.mark.parametrize("earth", [WGS84, SPHERICAL])
def test_observation_jacobian_against_finite_differences(earth):
    rng = np.random.default_rng(7)
    lat, lon, h = 0.8, 0.6, 120.0
    v_n = np.array([12.0, -25.0, 0.7])
    cb, cd = 35.0, 2.0
    r_e = earth.geodetic_to_ecef(lat, lon, h)
    up = r_e / np.linalg.norm(r_e)
    sat_pos = []
    while len(sat_pos) < 6:  # satellites above the horizon at ~26 600 km
        d = rng.standard_normal(3)
        d /= np.linalg.norm(d)
        p = d * 26.6e6
        if (p - r_e) @ up > 0:
            sat_pos.append(p)
    sat_pos = np.array(sat_pos)
    sat_vel = rng.standard_normal((6, 3)) * 2500.0
    J = observation_jacobian(lat, lon, h, v_n, sat_pos, sat_vel, earth, 17)
    r_n, r_e_rad = (float(x) for x in earth.radii(lat))

    def observe(x):
        # x: error-state-like perturbation (E, N, U m; vE, vN, vU; ...; cb, cd)
        la = lat + x[1] / (r_n + h)
        lo = lon + x[0] / ((r_e_rad + h) * np.cos(lat))
        rho, rate = predict_observables(la, lo, h + x[2], v_n + x[3:6], cb + x[15], cd + x[16], sat_pos, sat_vel,
                                        earth)
        return np.concatenate([rho, rate])

    x0 = np.zeros(17)
    fd = np.zeros_like(J)
    for k, step in [(0, 1.0), (1, 1.0), (2, 1.0), (3, 0.1), (4, 0.1), (5, 0.1), (15, 1.0), (16, 0.1)]:
        e = np.zeros(17)
        e[k] = step
        fd[:, k] = (observe(x0 + e) - observe(x0 - e)) / (2 * step)
    m = len(sat_pos)
    assert np.allclose(fd[:m], J[:m], atol=1e-7)  # pseudorange rows (values ~1)
    assert np.allclose(fd[m:], J[m:], atol=1e-9)  # rate rows (position terms ~1e-4)
    assert np.max(np.abs(J[m:, 0:3])) > 1e-5  # the small terms are present
    assert np.all(J[:, 6:15] == 0.0)


# ------------------------------------------------------------------------ UKF == KF
def _linear_toy(seed=0, n=5, m=3, steps=8):
    rng = np.random.default_rng(seed)
    F = np.eye(n) + 0.1 * rng.standard_normal((n, n))
    H = rng.standard_normal((m, n))
    A = rng.standard_normal((n, n))
    Q = 0.01 * A @ A.T + 1e-3 * np.eye(n)
    R = rng.uniform(0.5, 2.0, m)
    zs = rng.standard_normal((steps, m)) * 3.0
    x0 = rng.standard_normal(n)
    B = rng.standard_normal((n, n))
    P0 = B @ B.T + np.eye(n)
    return F, H, Q, R, zs, x0, P0


@pytest.mark.parametrize("alpha, beta, kappa", [(1.0, 2.0, 0.0), (1e-3, 2.0, 0.0), (0.5, 0.0, 3.0)])
def test_ukf_reproduces_the_kalman_filter_on_a_linear_model(alpha, beta, kappa):
    # small alpha makes weights of order 1/alpha^2 = 1e6 that cancel: ~6 digits are lost
    tol = 1e-14 / alpha**2 * 100
    F, H, Q, R, zs, x0, P0 = _linear_toy()
    x_kf, P_kf = x0.copy(), P0.copy()
    x_u, P_u = x0.copy(), P0.copy()
    for z in zs:
        # Kalman filter: P = F P F' + Q, Joseph update
        x_kf, P_kf = F @ x_kf, F @ P_kf @ F.T + Q
        dx, P_kf, nis_kf = joseph_update(P_kf, H, np.diag(R), z - H @ x_kf)
        x_kf = x_kf + dx
        # UKF with the same linear model
        x_u, P_u, _ = unscented_predict(x_u, P_u, lambda X: X @ F.T, Q, alpha, beta, kappa)
        x_u, P_u, nis_u, _ = unscented_update(x_u, P_u, lambda X: X @ H.T, z, R, alpha, beta, kappa)
        assert nis_u == pytest.approx(nis_kf, rel=tol)
    assert np.allclose(x_u, x_kf, rtol=tol, atol=tol)
    assert np.allclose(P_u, P_kf, rtol=tol, atol=tol)


def test_sigma_points_guard_the_cholesky():
    # a covariance that is not positive definite (rounding made one eigenvalue negative)
    rng = np.random.default_rng(3)
    A = rng.standard_normal((6, 3))
    P = A @ A.T  # rank 3
    w, v = np.linalg.eigh(P)
    w[0] = -1e-9
    P_bad = (v * w) @ v.T
    X, Wm, Wc, fallbacks = sigma_points(np.zeros(6), P_bad)
    assert fallbacks > 0
    assert np.all(np.isfinite(X))
    cov = (X.T * Wc) @ X  # the points still carry P (to the jitter)
    assert np.allclose(cov, P_bad, atol=1e-5 * np.max(np.diag(P)))
    # zero-variance states (an IMU without bias) get no spread and no fallback
    P0 = np.diag([4.0, 1.0, 0.0, 0.0])
    X, *_, fallbacks = sigma_points(np.zeros(4), P0)
    assert fallbacks == 0 and np.all(X[:, 2:] == 0.0)


# ------------------------------------------------------------------------ stepping
@pytest.mark.parametrize("cls", [TightlyCoupledEkf, TightlyCoupledUkf])
def test_batch_equals_step(cls):
    sc = _scenario(4.0, outage=[2.5, 3.5])
    a = run_episode(sc, cls(), seed=4, use_batch=True)
    b = run_episode(sc, cls(), seed=4, use_batch=False)
    assert np.allclose(a.est_lat, b.est_lat, rtol=0, atol=1e-13)
    assert np.allclose(a.est_velocity_n, b.est_velocity_n, rtol=0, atol=1e-9)
    assert np.allclose(a.est_cov, b.est_cov, rtol=1e-9, atol=1e-12)
    assert np.allclose(np.nan_to_num(a.nis), np.nan_to_num(b.nis), rtol=1e-9)
    assert np.count_nonzero(~np.isnan(a.nis)) == 3  # epochs at 1, 2 and 4 s (3 s lost)


def test_ukf_agrees_with_ekf_when_the_model_is_nearly_linear():
    sc = _scenario(60.0)
    a = run_episode(sc, TightlyCoupledEkf(), seed=5)
    b = run_episode(sc, TightlyCoupledUkf(), seed=5)
    ea, eb = error_vector(a), error_vector(b)
    sigma = np.sqrt(np.diagonal(a.est_cov, axis1=1, axis2=2))
    assert np.max(np.abs(ea[:, :6] - eb[:, :6]) / sigma[:, :6]) < 1e-3
    assert np.allclose(a.est_cov, b.est_cov, rtol=1e-3, atol=1e-12)


@pytest.mark.parametrize("n_sats, factor", [(2, 0.9), (3, 0.3)])
def test_works_with_too_few_satellites_for_a_fix(n_sats, factor):
    """2-3 satellites (no LS fix possible): less drift than the free INS. With two the
    direction normal to both lines of sight (and its velocity) is not observed, so the
    gain is modest; with three (clock compensated) the position is observed."""
    sc = _scenario(120.0)
    tc = run_episode(sc, KeepSatellites(TightlyCoupledEkf(), n_sats), seed=6)
    ins = run_episode(sc, make("ins-only"), seed=6)
    e_tc = np.linalg.norm(error_vector(tc)[:, :3], axis=1)
    e_ins = np.linalg.norm(error_vector(ins)[:, :3], axis=1)
    assert np.count_nonzero(~np.isnan(tc.nis)) == 120
    assert np.all(tc.nis_dof[~np.isnan(tc.nis)] == 2 * n_sats)
    assert e_tc[-1] < factor * e_ins[-1]
    assert np.mean(e_tc[-3000:]) < factor * np.mean(e_ins[-3000:])


def test_divergence_becomes_a_flag_not_a_crash():
    sc = _scenario(15.0)
    sim = Simulator(sc)
    start = sim.reset(0)
    est = TightlyCoupledEkf(divergence_epochs=3)
    est.reset(make_context(sim), start.prior)
    chunk = sim.advance(sc.timing.steps)
    batch = measurement_batch(chunk, np.asarray(sim.constellation.prn), sc.timing.nav_period_s)
    # corrupt every pseudorange by an offset the model cannot absorb
    rng = np.random.default_rng(0)
    bad = tuple((j, dataclasses.replace(o, pseudorange_m=o.pseudorange_m + rng.uniform(-5e4, 5e4, o.valid.size)))
                for j, o in batch.gnss)
    out = est.step_batch(dataclasses.replace(batch, gnss=bad))
    assert est.last_extra["diverged"] is True
    assert np.all(np.isfinite(out.covariance))


def test_clock_states_track_the_receiver_clock():
    sc = _scenario(60.0, gnss=CLEAN_STANDALONE)
    sim = Simulator(sc)
    start = sim.reset(2)
    ctx = make_context(sim)
    assert ctx.gnss.clock_modelled
    for cls in (TightlyCoupledEkf, TightlyCoupledUkf):
        est = cls()
        est.reset(ctx, start.prior)
        sim.reset(2)
        chunk = sim.advance(sc.timing.steps)
        est.step_batch(measurement_batch(chunk, np.asarray(sim.constellation.prn), sc.timing.nav_period_s))
        extra = est.last_extra
        assert extra["clock_bias_m"] == pytest.approx(chunk.gnss.clock_bias_m[-1], abs=5.0)  # of ~3000 m
        assert extra["clock_drift_mps"] == pytest.approx(chunk.gnss.clock_drift_mps[-1], abs=0.2)  # of ~60 m/s


def test_clock_none_runs_with_fifteen_states():
    sc = _scenario(20.0)
    est = TightlyCoupledEkf(clock="none")
    rec = run_episode(sc, est, seed=1)
    assert est.engine.n_states == 15
    assert "clock_bias_m" not in est.last_extra
    assert np.max(np.linalg.norm(error_vector(rec)[-500:, :3], axis=1)) < 30.0


# ------------------------------------------------------------------------ consistency
def _nees_runs(cls, sc, seeds):
    out = []
    for seed in seeds:
        rec = run_episode(sc, cls(), seed=seed)
        out.append(nees(error_vector(rec), rec.est_cov))
    return np.array(out)


def _inside_fraction(values, n_seeds, dof=9):
    per_second = values[:, 99::100].mean(axis=0)
    lo, hi = chi2.ppf(0.025, dof * n_seeds) / n_seeds, chi2.ppf(0.975, dof * n_seeds) / n_seeds
    return np.mean((per_second > lo) & (per_second < hi)), per_second


def test_nees_short():
    """Cheap version: paper-2012 (60 s, outage 30-45 s), 4 seeds, 9-component NEES.

    Samples are correlated in time, so the mean over seeds and time gets a broad band
    around the expected 9; the per-second seed averages must mostly lie in the 95 % band.
    """
    n = 4
    values = _nees_runs(TightlyCoupledEkf, _scenario(60.0, outage=[30.0, 45.0]), range(n))
    inside, per_second = _inside_fraction(values, n)
    assert 0.6 * 9 < values[:, 1000:].mean() < 1.6 * 9
    assert inside > 0.6


@pytest.mark.slow
@pytest.mark.parametrize("cls", [TightlyCoupledEkf, TightlyCoupledUkf])
def test_nees_paper_scenario_20_seeds(cls):
    """paper-2012 (1000 s, GNSS lost 400-700 s), 20 seeds: per-second NEES averaged over
    the seeds inside the 95 % chi-square band at least 85 % of the time."""
    n = 20
    values = _nees_runs(cls, load_scenario("paper-2012"), range(n))
    inside, _ = _inside_fraction(values, n)
    assert inside > 0.85


@pytest.mark.slow
def test_nees_clock_case_20_seeds():
    """The clock case: standalone receiver without atmosphere and multipath (the filter's
    model), 300 s with a 60-s outage, 20 seeds."""
    n = 20
    sc = _scenario(300.0, outage=[150.0, 210.0], gnss=CLEAN_STANDALONE)
    values = _nees_runs(TightlyCoupledEkf, sc, range(n))
    inside, _ = _inside_fraction(values, n)
    assert inside > 0.85
