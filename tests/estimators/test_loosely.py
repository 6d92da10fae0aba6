"""Loosely coupled EKF: error model Jacobian, batch = step, consistency, outage bridging."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.stats import chi2

from navsim.earth import SPHERICAL, WGS84
from navsim.episode import make_context, run_episode
from navsim.estimators import make
from navsim.estimators._inserror import ImuNoise, error_dynamics, transition
from navsim.metrics import error_vector, nees
from navsim.rotations import mat_from_rotvec, mat_nb_from_hpr, skew
from navsim.scenario import load_scenario
from navsim.simulator import Simulator


# ----------------------------------------------------------------------- F vs mechanisation
def _rates(earth, lat, h, v):
    r_n, r_e = (float(x) for x in earth.radii(lat))
    w_ie = earth.rate * np.array([0.0, math.cos(lat), math.sin(lat)])
    w_en = np.array([-v[1] / (r_n + h), v[0] / (r_e + h), v[0] * math.tan(lat) / (r_e + h)])
    return r_n, r_e, w_ie, w_en


def _derivative(earth, x, omega_b, f_b):
    """Time derivative of the nonlinear ENU mechanisation (navsim.strapdown.ins docstring)."""
    lat, lon, h, v, C = x
    r_n, r_e, w_ie, w_en = _rates(earth, lat, h, v)
    dlat = v[1] / (r_n + h)
    dlon = v[0] / ((r_e + h) * math.cos(lat))
    dv = C @ f_b - np.cross(2 * w_ie + w_en, v) + earth.gravity_n(lat, h)
    dC = C @ skew(omega_b) - skew(w_ie + w_en) @ C
    return dlat, dlon, v[2], dv, dC


def _error(earth, est, true):
    """Navigation error (9,) of est relative to true, module convention (psi from the skew part)."""
    lat, lon, h, v, C = true
    r_n, r_e = (float(x) for x in earth.radii(lat))
    d_e = (est[1] - lon) * (r_e + h) * math.cos(lat)
    d_n = (est[0] - lat) * (r_n + h)
    R = est[4] @ C.T
    psi = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return np.concatenate([[d_e, d_n, est[2] - h], est[3] - v, psi])


def _perturb(earth, true, dx):
    lat, lon, h, v, C = true
    r_n, r_e = (float(x) for x in earth.radii(lat))
    return (lat + dx[1] / (r_n + h), lon + dx[0] / ((r_e + h) * math.cos(lat)), h + dx[2], v + dx[3:6],
            mat_from_rotvec(dx[6:9]) @ C)


def _moved(x, d, s):
    return tuple(a + s * b for a, b in zip(x, d))


def _error_rate(earth, true, dx, omega_b, f_b, s=1.0):
    est = _perturb(earth, true, dx)
    d_true = _derivative(earth, true, omega_b, f_b)
    d_est = _derivative(earth, est, omega_b + dx[9:12], f_b + dx[12:15])
    plus = _error(earth, _moved(est, d_est, s), _moved(true, d_true, s))
    minus = _error(earth, _moved(est, d_est, -s), _moved(true, d_true, -s))
    return (plus - minus) / (2 * s)


@pytest.mark.parametrize("earth", [WGS84, SPHERICAL], ids=["wgs84", "spherical"])
def test_error_dynamics_matches_finite_differences_of_the_mechanisation(earth):
    lat, lon, h = 0.8, 0.4, 350.0
    v = np.array([15.0, -11.0, 0.7])
    C = mat_nb_from_hpr(0.6, 0.04, -0.03)
    omega_b = np.array([0.01, -0.02, 0.05])
    f_b = C.T @ np.array([0.4, -0.3, 9.9])
    true = (lat, lon, h, v, C)
    noise = ImuNoise(gyro_bias_tau_s=600.0, accel_bias_tau_s=900.0)
    F = error_dynamics(lat, h, v, C, C @ f_b, earth, noise)
    scales = np.array([10.0] * 3 + [1e-2] * 3 + [1e-5] * 3 + [1e-6] * 3 + [1e-4] * 3)
    J = np.zeros((15, 15))
    for k in range(15):
        e = np.zeros(15)
        e[k] = scales[k]
        J[:9, k] = (_error_rate(earth, true, e, omega_b, f_b) - _error_rate(earth, true, -e, omega_b, f_b)) / (2 * scales[k])
    J[9:12, 9:12] = -np.eye(3) / 600.0  # bias models are linear by definition
    J[12:15, 12:15] = -np.eye(3) / 900.0
    # compare column-scaled entries: F_ij * scale_j is the rate change from a typical error
    diff = np.abs(F - J) * scales
    size = np.abs(J) * scales
    assert np.all(diff <= 1e-4 * size + 1e-13), np.unravel_index(np.argmax(diff - 1e-4 * size), diff.shape)
    # the small terms are really there (not all zero): transport-rate, gravity gradient
    assert abs(F[6, 4]) > 0 and abs(F[5, 2]) > 0


def test_transition_series_matches_matrix_exponential():
    from scipy.linalg import expm

    C = mat_nb_from_hpr(0.3, 0.0, 0.0)
    noise = ImuNoise(gyro_psd=1e-8, accel_psd=1e-6, gyro_bias_sigma=1e-5, accel_bias_sigma=1e-3,
                     gyro_bias_tau_s=300.0, accel_bias_tau_s=300.0)
    F = error_dynamics(0.7, 100.0, np.array([20.0, 5.0, 0.0]), C, np.array([0.5, 0.2, 9.8]), WGS84, noise)
    from navsim.estimators._inserror import noise_density

    Qc = noise_density(noise)
    tau = 1.0
    phi, qd = transition(F, Qc, tau)
    np.testing.assert_allclose(phi, expm(F * tau), rtol=1e-5, atol=1e-9)  # F^5 tau^5/120 left out
    # Van Loan (1978): expm([[-F, Qc], [0, F^T]] tau) gives Qd
    n = 15
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n], M[:n, n:], M[n:, n:] = -F, Qc, F.T
    E = expm(M * tau)
    qd_exact = E[n:, n:].T @ E[:n, n:]
    scale = np.sqrt(np.outer(np.diag(qd_exact), np.diag(qd_exact)))
    rel = np.abs(qd - qd_exact) / scale
    assert np.nanmax(rel) < 1e-3, np.nanmax(rel)


# ----------------------------------------------------------------------- episodes
# truth matching the filter's model: tactical white noise and Gauss-Markov biases, no
# constant bias, scale factor, misalignment or quantization (the filter models none);
# white-noise GNSS (paper-2012 preset). The g-sensitivity of the preset (~2 deg/h) stays:
# it acts as a bias well inside the modelled bias sigma (25 deg/h).
_MATCHED = {"bias": 0.0, "scale_factor": 0.0, "misalignment": 0.0, "quantization_lsb": 0.0}


def _matched(duration, outages=()):
    return load_scenario("paper-2012").with_overrides({
        "timing": {"duration_s": duration}, "imu": {"preset": "tactical", "gyro": _MATCHED, "accel": _MATCHED},
        "gnss": {"preset": "paper-2012"}, "outages": {"windows_s": [list(w) for w in outages]},
        "initial": {"position_m": 5.0, "velocity_mps": 0.1, "attitude_deg": 0.2}})


def test_step_batch_equals_repeated_step():
    from navsim.episode import measurement_batch, measurements

    sc = _matched(12.0)
    sim = Simulator(sc)
    start = sim.reset(3)
    ctx = make_context(sim)
    prn = np.asarray(sim.constellation.prn)
    chunk = next(iter(sim.chunks(10_000)))
    a, b = make("lc-ekf"), make("lc-ekf")
    a.reset(ctx, start.prior)
    b.reset(ctx, start.prior)
    batch = measurement_batch(chunk, prn, sc.timing.nav_period_s)
    first = a.step_batch(dataclasses.replace(batch))
    steps = [b.step(m) for m in measurements(chunk, prn, sc.timing.nav_period_s)]
    sol = np.array([s.as_action() for s in steps])
    np.testing.assert_allclose(first.solution[:, :2], sol[:, :2], rtol=0, atol=1e-13)
    np.testing.assert_allclose(first.solution[:, 2:], sol[:, 2:], rtol=0, atol=1e-8)
    cov = np.array([s.covariance for s in steps])
    np.testing.assert_allclose(first.covariance, cov, rtol=1e-9, atol=1e-18)
    assert np.isfinite(first.nis).sum() == 12
    assert steps[-1].extra["diverged"] is False


def _consistency(seeds, duration):
    sc = _matched(duration)
    sim = Simulator(sc)
    nees_runs, nis_all = [], []
    for seed in seeds:
        rec = run_episode(sc, make("lc-ekf"), seed=seed, simulator=sim)
        nees_runs.append(nees(error_vector(rec), rec.est_cov))
        nis_all.append(rec.nis[np.isfinite(rec.nis)])
    return np.array(nees_runs), np.concatenate(nis_all), rec


def test_consistency_short():
    """Cheap version: 3 seeds x 60 s. NIS at the epochs are independent chi2(6) draws for a
    consistent filter, so their pooled mean has exact bounds; the NEES (9 dof, correlated
    in time) is checked on its mean over seeds and steps with a loose factor."""
    nees_runs, nis_all, rec = _consistency((0, 1, 2), 60.0)
    k = len(nis_all)
    lo, hi = chi2.ppf([0.005, 0.995], 6 * k) / k
    assert lo < nis_all.mean() < hi, (nis_all.mean(), lo, hi)
    assert 0.6 * 9 < np.nanmean(nees_runs) < 1.5 * 9, np.nanmean(nees_runs)


@pytest.mark.slow
def test_consistency_20_seeds():
    """NEES averaged over 20 seeds inside the two-sided 95 % chi-square band at >= 90 % of
    the GNSS epochs (Bar-Shalom et al. 2001, 5.4.2)."""
    seeds = range(20)
    nees_runs, nis_all, rec = _consistency(seeds, 200.0)
    epochs = np.flatnonzero(np.isfinite(rec.nis) | (np.arange(len(rec.t)) % 100 == 99))
    mean = nees_runs[:, epochs].mean(axis=0)
    lo, hi = chi2.ppf([0.025, 0.975], 9 * len(seeds)) / len(seeds)
    inside = np.mean((mean > lo) & (mean < hi))
    assert inside >= 0.9, (inside, mean.mean(), lo, hi)


def test_bridges_a_30_s_outage():
    sc = _matched(100.0, outages=[(50.0, 80.0)])
    rec = run_episode(sc, make("lc-ekf"), seed=5)
    e = error_vector(rec)
    end = np.searchsorted(rec.t, 80.0 - 1e-9)  # last step before the fixes return
    sigma = np.sqrt(np.diagonal(rec.est_cov[end]))
    before = np.sqrt(np.diagonal(rec.est_cov[np.searchsorted(rec.t, 50.0)]))
    # drift bounded: horizontal error of the tactical INS after 30 s well under 30 m and
    # inside 4 sigma of the filter's own prediction, which has grown over the outage
    assert np.hypot(*e[end, :2]) < 30.0
    assert np.all(np.abs(e[end, :6]) < 4.0 * sigma[:6])
    assert sigma[0] > 1.5 * before[0]
    # and the filter reconverges after the outage
    assert np.hypot(*e[-1, :2]) < 4.0 * np.hypot(*np.sqrt(np.diagonal(rec.est_cov[-1]))[:2])
