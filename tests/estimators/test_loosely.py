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


# ----------------------------------------------------------------------- antenna lever arm
def _antenna_enu_difference(earth, est, omega_est, lever, x):
    """[r_a; v_a](est) - [r_a; v_a](truth) in the ENU axes of the estimate, with the truth
    hypothesis ``correct_state(est, x)`` and rate ``omega_est - eg`` (the module's
    convention), both antennas from navsim.sensors.gnss.antenna_state (ECEF)."""
    from navsim.earth import mat_en
    from navsim.estimators._inserror import BG, NAV, correct_state
    from navsim.rotations import quat_to_mat
    from navsim.sensors.gnss import antenna_state

    def antenna(st, omega):
        c_en = mat_en(st.lat, st.lon)
        r = earth.geodetic_to_ecef(st.lat, st.lon, st.h)
        return antenna_state(r, c_en.T @ np.asarray(st.velocity_n), c_en.T @ quat_to_mat(st.quat_nb), omega, lever,
                             earth)

    true = correct_state(est, x[NAV], earth)
    r1, v1 = antenna(est, omega_est)
    r0, v0 = antenna(true, omega_est - x[BG])
    m_en = mat_en(est.lat, est.lon)
    return np.concatenate([m_en @ (r1 - r0), m_en @ (v1 - v0)])


@pytest.mark.parametrize("earth", [WGS84, SPHERICAL], ids=["wgs84", "spherical"])
def test_lever_arm_jacobian_matches_finite_differences(earth):
    """L of lever_arm_terms (LA.3) against central differences of the exact antenna
    position/velocity difference; the predicted offsets against antenna_state."""
    from navsim.estimators._inserror import lever_arm_terms
    from navsim.rotations import mat_to_quat
    from navsim.strapdown.ins import InsState

    lat, lon, h = 0.81, 0.21, 640.0
    C = mat_nb_from_hpr(2.1, 0.02, -0.05)
    est = InsState(lat, lon, h, np.array([12.0, -14.0, 0.3]), mat_to_quat(C))
    omega = np.array([0.03, -0.02, 0.08])
    lever = np.array([0.4, 1.5, 3.0])
    w_ie = earth.rate * np.array([0.0, math.cos(lat), math.sin(lat)])
    arm_n, arm_vel_n, L = lever_arm_terms(C, omega, lever, w_ie)
    zero = _antenna_enu_difference(earth, est, omega, lever, np.zeros(15))
    np.testing.assert_allclose(zero, 0.0, atol=1e-9)
    np.testing.assert_allclose(arm_n, C @ lever, atol=1e-15)
    np.testing.assert_allclose(arm_vel_n, C @ np.cross(omega, lever) - np.cross(w_ie, C @ lever), atol=1e-15)
    _, _, L0 = lever_arm_terms(C, omega, np.zeros(3), w_ie)
    fd = np.zeros((2, 6, 15))
    for j, arm in enumerate((lever, np.zeros(3))):
        for k, step in [*((i, 1.0) for i in range(3)), *((i, 0.1) for i in range(3, 6)),
                        *((i, 1e-3) for i in range(6, 12))]:
            e = np.zeros(15)
            e[k] = step
            fd[j, :, k] = (_antenna_enu_difference(earth, est, omega, arm, e)
                           - _antenna_enu_difference(earth, est, omega, arm, -e)) / (2 * step)
    # the antenna at the IMU: the identity blocks (up to the ENU axes turning with the
    # position, ~v/R = 3e-6, which the INS error model owns, not the lever arm)
    np.testing.assert_allclose(fd[1], L0, rtol=0, atol=5e-6)
    # the lever-arm part; 1e-6: the ENU frame turns with the position (|l| / R ~ 5e-7 m
    # per m, left out of L) and the ECEF round-off (~1e-9 m) over the 3 mm displacements
    np.testing.assert_allclose(fd[0] - fd[1], L - L0, rtol=0, atol=1e-6)
    assert np.max(np.abs(L[3:6, 6:9])) > 0.1 and np.max(np.abs(L[3:6, 9:12])) > 1.0  # the terms are there


def _lever_runs(name, seeds, duration, sim=None, **options):
    from lever_arm_case import figures, lever_scenario

    sc = lever_scenario(duration)
    sim = sim or Simulator(sc)
    out = []
    for seed in seeds:
        rec = run_episode(sc, make(name, **options), seed=seed, simulator=sim)
        out.append((rec, figures(rec)))
    return out, sim


def test_lever_arm_compensation_short():
    """1.5 m forward / 3 m up on the curves of mountain-railway, 60 s, 3 seeds (truth =
    the filter's model, tests/estimators/lever_arm_case.py). Compensated: pooled NIS
    inside its exact chi-square bounds, mean NEES near 9, horizontal RMS ~0.26 m
    (measured 0.21-0.31 m). Uncompensated (the context's arm zeroed, or the option
    ``lever_arm="none"``: the same numbers): horizontal RMS ~1.6 m, vertical ~3 m
    (the arm), NEES ~240."""
    from lever_arm_case import zero_lever_context

    runs, sim = _lever_runs("lc-ekf", (0, 1, 2), 60.0)
    nis = np.concatenate([r.nis[np.isfinite(r.nis)] for r, _ in runs])
    k = len(nis)
    lo, hi = chi2.ppf([0.005, 0.995], 6 * k) / k
    assert lo < nis.mean() < hi, (nis.mean(), lo, hi)
    assert 0.6 * 9 < np.mean([f["nees"].mean() for _, f in runs]) < 1.5 * 9
    assert max(f["h_rms"] for _, f in runs) < 0.5
    (bad, f_bad), = _lever_runs("lc-ekf", (0,), 60.0, sim, lever_arm="none")[0]
    assert f_bad["h_rms"] > 1.2 and 2.5 < f_bad["up_rms"] < 3.5 and f_bad["nees"].mean() > 100.0
    # the same filter told a zero lever arm through the context
    start = sim.reset(0)
    est = make("lc-ekf")
    est.reset(zero_lever_context(make_context(sim)), start.prior)
    from navsim.episode import measurement_batch

    prn = np.asarray(sim.constellation.prn)
    sol = np.concatenate([est.step_batch(measurement_batch(c, prn, 0.01)).solution for c in sim.chunks(2000)])
    assert np.array_equal(sol[:, 0], bad.est_lat) and np.array_equal(sol[:, 3:6], bad.est_velocity_n)


def test_lever_arm_batch_equals_step_and_vanishing_arm():
    """batch = step with a lever arm; and an arm of 1e-9 m runs the compensated code path to
    the numbers of the antenna-at-the-IMU path (continuity at zero)."""
    from lever_arm_case import lever_scenario

    sc = lever_scenario(6.0)
    a = run_episode(sc, make("lc-ekf"), seed=4, use_batch=True)
    b = run_episode(sc, make("lc-ekf"), seed=4, use_batch=False)
    np.testing.assert_allclose(a.est_lat, b.est_lat, rtol=0, atol=1e-13)
    np.testing.assert_allclose(a.est_velocity_n, b.est_velocity_n, rtol=0, atol=1e-8)
    np.testing.assert_allclose(a.est_cov, b.est_cov, rtol=1e-9, atol=1e-18)
    tiny = lever_scenario(6.0, lever_arm_m=(1e-9, -1e-9, 1e-9))
    zero = lever_scenario(6.0, lever_arm_m=(0.0, 0.0, 0.0))
    c, d = run_episode(tiny, make("lc-ekf"), seed=4), run_episode(zero, make("lc-ekf"), seed=4)
    e = error_vector(c) - error_vector(d)
    assert np.max(np.abs(e[:, :6])) < 1e-6 and np.max(np.abs(e[:, 6:])) < 1e-9
    assert np.max(np.abs(e)) > 0.0  # ... through different code


@pytest.mark.slow
def test_lever_arm_consistency_20_seeds():
    """20 seeds x 100 s: per-second NEES averaged over the seeds inside the two-sided 95 %
    chi-square band at >= 85 % of the seconds; horizontal RMS (all seeds, after 20 s)
    below 0.4 m, against > 1.2 m uncompensated (1 seed)."""
    runs, sim = _lever_runs("lc-ekf", range(20), 100.0)
    values = np.array([nees(error_vector(r), r.est_cov) for r, _ in runs])
    per_second = values[:, 99::100].mean(axis=0)
    lo, hi = chi2.ppf([0.025, 0.975], 9 * 20) / 20
    assert np.mean((per_second > lo) & (per_second < hi)) >= 0.85
    assert np.sqrt(np.mean([f["h_rms"] ** 2 for _, f in runs])) < 0.4
