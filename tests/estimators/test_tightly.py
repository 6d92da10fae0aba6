"""Tests of the tightly coupled EKF and UKF (navsim.estimators.tightly)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.stats import chi2
from tolerances import assert_covariance_close, assert_same_field

from navsim.earth import SPHERICAL, WGS84
from navsim.episode import make_context, measurement_batch, run_episode
from navsim.errors import ConfigError
from navsim.estimators import make
from navsim.estimators._inserror import joseph_update
from navsim.estimators.tightly import (
    TightlyCoupledEkf,
    TightlyCoupledUkf,
    atmosphere_delays,
    atmosphere_jacobian,
    ionosphere_obliquity,
    observation_jacobian,
    predict_observables,
    sigma_points,
    troposphere_mapping,
    unscented_predict,
    unscented_update,
)
from navsim.metrics import error_vector, nees
from navsim.scenario import load_scenario
from navsim.sensors.gnss import GnssErrorModel, elevation_azimuth
from navsim.simulator import Simulator

CLEAN_STANDALONE = {"preset": "standalone", "overrides": {"ionosphere_zenith_m": 0.0, "troposphere_zenith_m": 0.0,
                                                          "multipath_sigma_m": 0.0}}
# the atmosphere on, multipath off: the filter's model when it estimates the zenith delays
ATMOSPHERE_STANDALONE = {"preset": "standalone", "overrides": {"multipath_sigma_m": 0.0}}


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
    with pytest.raises(ConfigError):
        make("tc-ukf", atmosphere="klobuchar")
    with pytest.raises(ConfigError):
        make("tc-ekf", ionosphere_tau_s=0.0)
    make("tc-ekf", troposphere_tau_s=np.inf)  # random constant: allowed


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


# ------------------------------------------------------------------------ atmosphere
def _satellites(earth, lat, lon, h, n, seed, min_elevation_deg=3.0):
    """n random satellites at ~26 600 km above ``min_elevation_deg`` (ECEF, m)."""
    rng = np.random.default_rng(seed)
    r_e = earth.geodetic_to_ecef(lat, lon, h)
    up = np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])  # geodetic vertical
    out = []
    while len(out) < n:
        d = rng.standard_normal(3)
        p = d / np.linalg.norm(d) * 26.6e6
        los = p - r_e
        if los @ up / np.linalg.norm(los) > np.sin(np.radians(min_elevation_deg)):
            out.append(p)
    return np.array(out)


def test_mapping_functions_closed_form():
    r, shell = 6_378_137.0, 350_000.0
    assert ionosphere_obliquity(np.pi / 2, shell, r) == 1.0  # zenith
    assert troposphere_mapping(np.pi / 2) == pytest.approx(1.0, abs=1e-12)  # 1.001 = sqrt(1.002001)
    # the thin shell by geometry: a ray leaving the receiver (radius R) at elevation E
    # meets the shell (radius R + h_I) at zenith angle z; F = 1 / cos z
    for elev in np.radians([0.0, 5.0, 10.0, 30.0, 60.0, 89.0]):
        p = np.array([0.0, r])
        d = np.array([np.cos(elev), np.sin(elev)])
        b = p @ d
        t = -b + np.sqrt(b * b + (r + shell) ** 2 - r * r)
        q = p + t * d
        cos_z = d @ q / np.linalg.norm(q)
        assert ionosphere_obliquity(elev, shell, r) == pytest.approx(1.0 / cos_z, rel=1e-12)
    # horizon value of the shell: (R + h) / sqrt((R + h)^2 - R^2) = 3.07
    assert ionosphere_obliquity(0.0, shell, r) == pytest.approx((r + shell) / np.sqrt((r + shell) ** 2 - r * r))
    # DO-229: horizon value 1.001 / sqrt(0.002001) = 22.38, ~1 / sin E at high elevation
    assert troposphere_mapping(0.0) == pytest.approx(22.377, abs=1e-3)
    for elev in np.radians([30.0, 45.0, 60.0, 75.0]):
        assert troposphere_mapping(elev) * np.sin(elev) == pytest.approx(1.0, abs=3e-3)
    e = np.radians(np.linspace(0.0, 90.0, 91))  # both fall monotonically from the horizon
    assert np.all(np.diff(ionosphere_obliquity(e)) < 0) and np.all(np.diff(troposphere_mapping(e)) < 0)


@pytest.mark.parametrize("earth", [WGS84, SPHERICAL])
def test_slant_delays_match_the_simulator_model(earth):
    """The filter's own formulas reproduce navsim.sensors.gnss.GnssErrorModel's delays
    (the test reads the truth model; the estimator never does)."""
    model = GnssErrorModel.preset("standalone")
    lat, lon, h = 0.83, 0.62, 650.0
    sat = _satellites(earth, lat, lon, h, 8, seed=11, min_elevation_deg=1.0)
    elevation, _, _ = elevation_azimuth(earth.geodetic_to_ecef(lat, lon, h)[None], sat[None], earth)
    kw = dict(shell_height_m=model.ionosphere_shell_height_m, scale_height_m=model.troposphere_scale_height_m)
    iono, tropo = atmosphere_delays(lat, lon, h, sat, model.ionosphere_zenith_m, model.troposphere_zenith_m, earth,
                                    **kw)
    assert np.allclose(iono, model.ionosphere_delay_m(elevation[0], earth), rtol=1e-10, atol=0)
    assert np.allclose(tropo, model.troposphere_delay_m(elevation[0], h), rtol=1e-10, atol=0)
    e = np.radians(np.linspace(0.0, 90.0, 19))
    assert np.allclose(model.ionosphere_delay_m(e, earth),
                       model.ionosphere_zenith_m * ionosphere_obliquity(e, model.ionosphere_shell_height_m, earth.a))
    assert np.allclose(model.troposphere_delay_m(e, h),
                       model.troposphere_zenith_m * np.exp(-h / 8000.0) * troposphere_mapping(e))
    # the vectorised form (the UKF's sigma points) equals point-by-point evaluation
    lats, lons, hs = lat + np.array([0.0, 1e-4, -2e-4]), lon + np.array([0.0, 3e-4, 1e-4]), h + np.array([0, 40, -90])
    zi, zt = np.array([5.0, 4.0, 6.0]), np.array([2.4, 2.5, 2.3])
    vi, vt = atmosphere_delays(lats, lons, hs, sat, zi, zt, earth, **kw)
    for j in range(3):
        i1, t1 = atmosphere_delays(lats[j], lons[j], hs[j], sat, zi[j], zt[j], earth, **kw)
        assert np.allclose(vi[j], i1, rtol=1e-14) and np.allclose(vt[j], t1, rtol=1e-14)


@pytest.mark.parametrize("earth", [WGS84, SPHERICAL])
def test_atmosphere_jacobian_against_finite_differences(earth):
    lat, lon, h = 0.8, 0.6, 1200.0
    iono_z, tropo_z = 4.0, 2.45
    sat = _satellites(earth, lat, lon, h, 7, seed=5, min_elevation_deg=5.0)
    J = atmosphere_jacobian(lat, lon, h, sat, iono_z, tropo_z, earth)
    r_n, r_e_rad = (float(x) for x in earth.radii(lat))

    def total(x):  # x = [dE, dN, dU (m), dI_z, dT_z (m)]
        la = lat + x[1] / (r_n + h)
        lo = lon + x[0] / ((r_e_rad + h) * np.cos(lat))
        i, t = atmosphere_delays(la, lo, h + x[2], sat, iono_z + x[3], tropo_z + x[4], earth)
        return i + t

    fd = np.zeros_like(J)
    for k, step in enumerate([50.0, 50.0, 50.0, 0.1, 0.1]):
        e = np.zeros(5)
        e[k] = step
        fd[:, k] = (total(e) - total(-e)) / (2 * step)
    assert np.allclose(fd[:, :3], J[:, :3], rtol=1e-5, atol=1e-11)  # position terms ~1e-6..1e-4
    assert np.allclose(fd[:, 3:], J[:, 3:], rtol=1e-10, atol=0)  # mapping factors ~1..10
    assert np.max(np.abs(J[:, :2])) > 1e-6  # the elevation terms are present
    assert np.all(J[:, 2] < 0)  # higher receiver: less troposphere below it


def test_context_tells_a_nominal_atmosphere_not_the_truth():
    def context(gnss):
        sim = Simulator(_scenario(5.0, gnss=gnss))
        sim.reset(0)
        return make_context(sim).gnss

    assert not context({"preset": "paper-2012"}).atmosphere_modelled
    assert not context(CLEAN_STANDALONE).atmosphere_modelled
    nominal, truth = context({"preset": "standalone"}), GnssErrorModel.preset("standalone")
    assert nominal.atmosphere_modelled
    # a-priori values from standard models, not the simulator's delays, which lie within
    # the stated 1-sigma of them
    assert nominal.ionosphere_zenith_m != truth.ionosphere_zenith_m
    assert nominal.troposphere_zenith_m != truth.troposphere_zenith_m
    assert abs(truth.ionosphere_zenith_m - nominal.ionosphere_zenith_m) < nominal.ionosphere_zenith_sigma_m
    assert abs(truth.troposphere_zenith_m - nominal.troposphere_zenith_m) < nominal.troposphere_zenith_sigma_m
    # the estimator module imports nothing of the truth-side sensor models
    import ast
    import inspect

    import navsim.estimators.tightly as module
    tree = ast.parse(inspect.getsource(module))
    imported = [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    imported += [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    assert imported and not any("sensors" in name for name in imported)


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
def _assert_batch_equals_step(a, b):
    """States, NIS and the covariance at the epochs run the same operations in both paths
    (the clock and atmosphere means are propagated from the last update by the step
    count): bit for bit. The covariance reported between epochs is one (n, 9) @ (9, 81)
    product in batch and n one-row products in step: equal to the rounding of a 9-term
    sum (tests/tolerances.py)."""
    for field in ("est_lat", "est_lon", "est_h", "est_velocity_n", "est_hpr", "nis"):
        assert_same_field(getattr(a, field), getattr(b, field), field)
    assert_covariance_close(a.est_cov, b.est_cov, n_terms=9)


@pytest.mark.parametrize("cls", [TightlyCoupledEkf, TightlyCoupledUkf])
def test_batch_equals_step(cls):
    sc = _scenario(4.0, outage=[2.5, 3.5])
    a = run_episode(sc, cls(), seed=4, use_batch=True)
    b = run_episode(sc, cls(), seed=4, use_batch=False)
    _assert_batch_equals_step(a, b)
    assert np.count_nonzero(~np.isnan(a.nis)) == 3  # epochs at 1, 2 and 4 s (3 s lost)


@pytest.mark.parametrize("cls", [TightlyCoupledEkf, TightlyCoupledUkf])
def test_batch_equals_step_with_atmosphere(cls):
    sc = _scenario(4.0, outage=[2.5, 3.5], gnss=ATMOSPHERE_STANDALONE)
    a_est, b_est = cls(), cls()
    a = run_episode(sc, a_est, seed=4, use_batch=True)
    b = run_episode(sc, b_est, seed=4, use_batch=False)
    assert a_est.engine.n_states == 19 and a_est.engine.with_atmosphere
    _assert_batch_equals_step(a, b)
    for key in ("ionosphere_zenith_m", "troposphere_zenith_m", "clock_bias_m", "clock_drift_mps"):
        assert a_est.last_extra[key] == b_est.last_extra[key]  # means propagated from the last update


@pytest.mark.parametrize("gnss", [None, ATMOSPHERE_STANDALONE])
def test_ukf_agrees_with_ekf_when_the_model_is_nearly_linear(gnss):
    """With the atmosphere, this also checks that the EKF's linearised slant delays
    (TC.7, its H) and the UKF's exact ones (TC.6, its sigma points) are assembled alike.
    There, covariances are compared relative to sigma_i sigma_j (a few cross terms are
    nearly zero: their ratio says nothing)."""
    sc = _scenario(60.0, **({"gnss": gnss} if gnss else {}))
    a = run_episode(sc, TightlyCoupledEkf(), seed=5)
    b = run_episode(sc, TightlyCoupledUkf(), seed=5)
    ea, eb = error_vector(a), error_vector(b)
    sigma = np.sqrt(np.diagonal(a.est_cov, axis1=1, axis2=2))
    assert np.max(np.abs(ea[:, :6] - eb[:, :6]) / sigma[:, :6]) < 1e-3
    if gnss is None:
        assert np.allclose(a.est_cov, b.est_cov, rtol=1e-3, atol=1e-12)
    else:
        assert np.max(np.abs(a.est_cov - b.est_cov) / (sigma[:, :, None] * sigma[:, None, :])) < 1e-6
        assert np.allclose(np.diagonal(a.est_cov, axis1=1, axis2=2), np.diagonal(b.est_cov, axis1=1, axis2=2),
                           rtol=1e-4)


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


@pytest.mark.parametrize("cls", [TightlyCoupledEkf, TightlyCoupledUkf])
def test_nees_atmosphere_short(cls):
    """Cheap consistency check with the atmosphere on (standalone, multipath off: the
    filter's model): 90 s with an outage 45-60 s, 4 seeds. Without the atmospheric
    states the same filter's NEES is hundreds of times too large; with them the mean
    lies in a broad band around 9 and the per-second seed means mostly in the 95 % band.
    The zenith ionospheric delay (5 m in the simulator; a-priori 1.5 +- 4.5 m) is
    learnt: posterior sigma below the prior's half, estimate within 3 sigma of the truth."""
    n = 4
    sc = _scenario(90.0, outage=[45.0, 60.0], gnss=ATMOSPHERE_STANDALONE)
    truth_iono = GnssErrorModel.preset("standalone").ionosphere_zenith_m
    values = []
    for seed in range(n):
        est = cls()
        rec = run_episode(sc, est, seed=seed)
        values.append(nees(error_vector(rec), rec.est_cov))
        a = est.engine.atm_index
        sigma_iono = np.sqrt(est.engine.full_covariance()[a, a])
        assert sigma_iono < 0.5 * est.context.gnss.ionosphere_zenith_sigma_m
        assert abs(est.last_extra["ionosphere_zenith_m"] - truth_iono) < 3.0 * sigma_iono
    values = np.array(values)
    inside, _ = _inside_fraction(values, n)
    assert 0.6 * 9 < values[:, 1000:].mean() < 1.6 * 9
    assert inside > 0.6
    if cls is TightlyCoupledEkf:  # the gap this closes: the filter blind to the atmosphere
        rec = run_episode(sc, cls(atmosphere="none"), seed=0)
        assert nees(error_vector(rec), rec.est_cov)[1000:].mean() > 100 * 9


def test_atmosphere_states_reduce_the_horizontal_error():
    """Full standalone receiver (multipath too, not modelled beyond its sigma), 100 s,
    2 seeds: horizontal RMS error after 30 s with the atmospheric states well below that
    of the filter blind to the atmosphere (measured 0.43 vs 1.26 m; 1000-s figures are in
    the module notes)."""
    sc = _scenario(100.0, gnss={"preset": "standalone"})
    sim = Simulator(sc)
    rms = {}
    for atmosphere in ("none", "auto"):
        err = [error_vector(run_episode(sc, TightlyCoupledEkf(atmosphere=atmosphere), seed=s, simulator=sim))[3000:, :2]
               for s in range(2)]
        rms[atmosphere] = float(np.sqrt(np.mean(np.square(err)) * 2))
    assert rms["auto"] < 0.6 * rms["none"]


@pytest.mark.slow
@pytest.mark.parametrize("cls", [TightlyCoupledEkf, TightlyCoupledUkf])
def test_nees_atmosphere_20_seeds(cls):
    """The atmosphere case: standalone receiver with ionosphere and troposphere, without
    multipath (the filter's model), 300 s with a 60-s outage, 20 seeds."""
    n = 20
    sc = _scenario(300.0, outage=[150.0, 210.0], gnss=ATMOSPHERE_STANDALONE)
    values = _nees_runs(cls, sc, range(n))
    inside, _ = _inside_fraction(values, n)
    assert 0.7 * 9 < values[:, 1000:].mean() < 1.3 * 9
    assert inside > 0.85


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


# ------------------------------------------------------------------------ antenna lever arm
def _lever_filter(gnss, seed=2):
    """An EKF reset on a lever-arm scenario, its INS state moved to a curve with a tilted,
    turning body; returns the filter and the satellites of one epoch."""
    from lever_arm_case import lever_scenario

    from navsim.estimators._inserror import BG
    from navsim.rotations import mat_nb_from_hpr, mat_to_quat
    from navsim.strapdown.ins import InsState

    sc = lever_scenario(2.0).with_overrides({"gnss": gnss})
    sim = Simulator(sc)
    start = sim.reset(seed)
    chunk = sim.advance(200)
    est = TightlyCoupledEkf()
    est.reset(make_context(sim), start.prior)
    eng = est.engine
    st = eng.state
    eng.state = InsState(st.lat, st.lon, st.h, np.array([11.0, -15.0, 0.4]),
                         mat_to_quat(mat_nb_from_hpr(2.4, 0.03, -0.06)))
    eng.gyro_bias = np.array([1e-5, -2e-5, 3e-5])
    est._omega_ib_b = np.array([0.02, -0.03, 0.07])
    if eng.with_clock:
        eng.clock = np.array([12.0, 0.3])
    g = chunk.gnss
    ok = g.valid[-1]
    return est, g.sat_pos_e[-1][ok], g.sat_vel_e[-1][ok], BG


@pytest.mark.parametrize("gnss", [{"preset": "paper-2012"}, ATMOSPHERE_STANDALONE | {"lever_arm_m": [0.4, 1.5, 3.0]}],
                         ids=["white", "atmosphere"])
def test_lever_arm_observation_model_against_finite_differences(gnss):
    """h and J = dh/dx of the EKF (TC.8)-(TC.9) (with the atmosphere (TC.6)-(TC.7) in the
    second case): central differences of h at the truth hypotheses ``correct_state(INS, x)``
    with rate ``omega - eg`` and the clock and zenith delays minus their errors. Also the
    UKF's hx at the zero sigma point is the EKF's h."""
    import copy

    from navsim.estimators._inserror import correct_state

    est, sat_pos, sat_vel, BG = _lever_filter(gnss)
    assert est._with_lever
    eng = est.engine
    n = eng.n_states
    h0, J = est.observation_model(sat_pos, sat_vel)

    def observe(x):
        other = copy.deepcopy(est)
        e = other.engine
        e.state = correct_state(eng.state, x[:9], eng.earth)
        other._omega_ib_b = est._omega_ib_b - x[BG]
        if e.with_clock:
            e.clock = eng.clock - x[15:17]
        if e.with_atmosphere:
            a = e.atm_index
            e.atm = eng.atm - x[a:a + 2]
        return other.observation_model(sat_pos, sat_vel)[0]

    # five-point stencil (4th order) with steps large against the ECEF round-off (~1e-8 m)
    steps = [10.0] * 3 + [1.0] * 3 + [2e-2] * 3 + [2e-2] * 3 + [0.0] * 3 + [10.0, 1.0] + [1.0, 1.0]
    fd = np.zeros_like(J)
    for k in range(n):
        if steps[k] == 0.0:
            continue  # accelerometer biases: not in the observables
        e = np.zeros(n)
        e[k] = steps[k]
        # h(est) - h(truth(x)) = J x
        fd[:, k] = (8 * (observe(-e) - observe(e)) - (observe(-2 * e) - observe(2 * e))) / (12 * steps[k])
    m = len(sat_pos)
    # pseudorange rows, values ~1: 1e-6 for the turn of the ENU axes with the position
    # (the arm turns with them, |l| / R = 5e-7 per metre, left out like the base model's
    # v / R terms) and the ECEF round-off (1e-7 here)
    np.testing.assert_allclose(fd[:m], J[:m], rtol=0, atol=1e-6)
    np.testing.assert_allclose(fd[:m, 6:], J[:m, 6:], rtol=0, atol=3e-7)
    np.testing.assert_allclose(fd[m:], J[m:], rtol=0, atol=2e-9)  # rate rows, position terms ~1e-4
    assert np.max(np.abs(J[:m, 6:9])) > 1.0 and np.max(np.abs(J[m:, 9:12])) > 1.0  # the lever-arm terms
    # the UKF's nonlinear model at the zero sigma point
    ukf = TightlyCoupledUkf()
    ukf.__dict__.update({k: v for k, v in est.__dict__.items() if k != "options"})
    captured = {}

    def capture(mean, P, hx, z, R, *args):
        captured["h"] = hx(np.zeros((1, n)))[0]
        return mean, P, 0.0, 0

    ukf.unscented_update = capture  # the UKF's update hook (filterpy_based replaces it the same way)
    ukf._kalman(eng.full_covariance(), sat_pos, sat_vel, h0, np.ones(len(h0)), m)
    np.testing.assert_allclose(captured["h"], h0, rtol=0, atol=1e-7)


@pytest.mark.parametrize("cls", [TightlyCoupledEkf, TightlyCoupledUkf])
def test_lever_arm_batch_equals_step(cls):
    from lever_arm_case import lever_scenario

    sc = lever_scenario(4.0).with_overrides({"gnss": ATMOSPHERE_STANDALONE | {"lever_arm_m": [0.4, 1.5, 3.0]}})
    a = run_episode(sc, cls(), seed=4, use_batch=True)
    b = run_episode(sc, cls(), seed=4, use_batch=False)
    _assert_batch_equals_step(a, b)
    assert np.count_nonzero(np.isfinite(a.nis)) == 4


@pytest.mark.parametrize("cls", [TightlyCoupledEkf, TightlyCoupledUkf])
def test_lever_arm_compensation_short(cls):
    """1.5 m forward / 3 m up on the curves of mountain-railway, 60 s, 3 seeds (truth =
    the filter's model, tests/estimators/lever_arm_case.py). Compensated: the pooled NIS
    (sum over epochs against chi2 of the summed dof) inside its 99 % bounds, mean NEES
    near 9, horizontal RMS < 0.5 m (measured 0.22-0.30 m). Uncompensated
    (``lever_arm="none"``): horizontal RMS ~1.6 m, vertical ~3 m, NEES ~900."""
    from lever_arm_case import figures, lever_scenario

    sc = lever_scenario(60.0)
    sim = Simulator(sc)
    nis, dof, mean_nees = 0.0, 0, []
    for seed in range(3):
        rec = run_episode(sc, cls(), seed=seed, simulator=sim)
        ok = np.isfinite(rec.nis)
        nis += rec.nis[ok].sum()
        dof += int(rec.nis_dof[ok].sum())
        f = figures(rec)
        mean_nees.append(f["nees"].mean())
        assert f["h_rms"] < 0.5
    assert chi2.ppf(0.005, dof) < nis < chi2.ppf(0.995, dof), (nis / dof)
    assert 0.6 * 9 < np.mean(mean_nees) < 1.5 * 9
    if cls is TightlyCoupledEkf:
        f = figures(run_episode(sc, cls(lever_arm="none"), seed=0, simulator=sim))
        assert f["h_rms"] > 1.2 and 2.5 < f["up_rms"] < 3.5 and f["nees"].mean() > 100.0


@pytest.mark.slow
@pytest.mark.parametrize("cls", [TightlyCoupledEkf, TightlyCoupledUkf])
def test_lever_arm_nees_20_seeds(cls):
    """20 seeds x 100 s of the lever-arm case: per-second seed means of the NEES inside the
    95 % chi-square band at >= 85 % of the seconds, horizontal RMS < 0.4 m."""
    from lever_arm_case import figures, lever_scenario

    sc = lever_scenario(100.0)
    sim = Simulator(sc)
    values, h_rms = [], []
    for seed in range(20):
        rec = run_episode(sc, cls(), seed=seed, simulator=sim)
        values.append(nees(error_vector(rec), rec.est_cov))
        h_rms.append(figures(rec)["h_rms"])
    inside, _ = _inside_fraction(np.array(values), 20)
    assert inside > 0.85
    assert np.sqrt(np.mean(np.square(h_rms))) < 0.4
