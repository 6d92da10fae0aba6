"""Loosely coupled EKF: error model Jacobian, batch = step, consistency, outage bridging."""

from __future__ import annotations

import dataclasses
import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from scipy.stats import chi2
from tolerances import assert_covariance_close, assert_same_arithmetic, assert_same_field, assert_same_solution

from navsim.earth import SPHERICAL, WGS84
from navsim.episode import make_context, measurement_batch, run_episode
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
    # states and NIS: the same operations in both paths, bit for bit; the covariance between
    # epochs: one (n, 9) @ (9, 81) product against n one-row ones (tests/tolerances.py)
    assert_same_solution(first.solution, sol)
    assert_same_arithmetic(first.nis, [np.nan if s.nis is None else s.nis for s in steps])
    assert_covariance_close(first.covariance, np.array([s.covariance for s in steps]))
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
    # states and NIS: the same operations in both paths, bit for bit; the covariance between
    # epochs: one (n, 9) @ (9, 81) product against n one-row ones (tests/tolerances.py)
    for field in ("est_lat", "est_lon", "est_h", "est_velocity_n", "est_hpr", "nis"):
        assert_same_field(getattr(a, field), getattr(b, field), field)
    assert_covariance_close(a.est_cov, b.est_cov)
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


# ----------------------------------------------------------------------- fix-error states
# (standalone receiver: a-priori atmosphere correction + ENU Gauss-Markov fix error)
def _engine_case(seconds=3.0):
    from navsim.episode import measurement_batch

    sc = _matched(seconds)
    sim = Simulator(sc)
    start = sim.reset(1)
    ctx = make_context(sim)
    chunk = next(iter(sim.chunks(10_000)))
    return ctx, start.prior, measurement_batch(chunk, np.asarray(sim.constellation.prn), sc.timing.nav_period_s)


def test_aux_gauss_markov_propagation_matches_the_closed_form():
    """AuxStateIns with a Gauss-Markov, a random-walk and a fast Gauss-Markov state over
    2.5 s (interval restarts every 0.7 s, an update at 1.2 s): variance sigma0^2 phi^2 +
    sigma^2 (1 - phi^2), the RW's P0 + q t, the mean decaying by phi, the cross-covariance
    of the update carried as Phi_15 P_na phi."""
    from navsim.estimators._inserror import AuxStateIns

    ctx, prior, batch = _engine_case()
    noise = ImuNoise.from_nominal(ctx.imu)
    T = np.array([5.0, np.inf, 0.8])
    sigma = np.array([2.0, 0.0, 0.5])  # stationary sigmas (GM); q of the RW below
    q = np.array([2 * 4.0 / 5.0, 0.3, 2 * 0.25 / 0.8])
    p0 = np.array([9.0, 1.0, 0.01])
    eng = AuxStateIns(ctx, prior, noise, interval_steps=70, aux_variance=p0, aux_psd=q, aux_tau_s=T)
    eng.aux = np.array([1.0, 2.0, -3.0])
    body = eng.prepare(batch.dtheta_sub, batch.dv_sub, batch.dtheta_r, batch.dv_r)
    eng.advance_body(body, 0, 120)  # 1.2 s, one interval restart inside
    t = 1.2
    phi = np.exp(-t / T)
    P = eng.full_covariance()[15:, 15:]
    expect = np.where(np.isfinite(T), p0 * phi**2 + sigma**2 * (1 - phi**2), p0 + q * t)
    np.testing.assert_allclose(np.diag(P), expect, rtol=1e-12)
    np.testing.assert_allclose(eng.aux_now(), np.array([1.0, 2.0, -3.0]) * phi, rtol=1e-12)
    # an update of position E with the sum of the two GM states correlates them with the INS
    H = np.zeros((1, 18))
    H[0, 0], H[0, 15], H[0, 17] = 1.0, 1.0, 1.0
    before = eng.aux_now()
    _, dx = eng.update(H, np.array([[1.0]]), np.array([0.7]))
    np.testing.assert_allclose(eng.aux, before - dx[15:], rtol=1e-14)
    P1 = eng.full_covariance()
    assert abs(P1[0, 15]) > 0.1
    eng.advance_body(body, 120, 250)  # 1.3 s more, restarts at 0.7 s and 1.4 s after the update
    s = 1.3
    ph = np.exp(-s / T)
    P2 = eng.full_covariance()
    np.testing.assert_allclose(P2[15:, 15:].diagonal(),
                               np.where(np.isfinite(T), P1[15:, 15:].diagonal() * ph**2 + sigma**2 * (1 - ph**2),
                                        P1[15:, 15:].diagonal() + q * s), rtol=1e-12)
    np.testing.assert_allclose(P2[15, 17], P1[15, 17] * ph[0] * ph[2], rtol=1e-12)
    # cross-covariance inside the current interval: Phi_15(tau) of the interval applied
    # to the block carried to its start, times phi of the auxiliary states
    tau = eng._j * eng.dt
    phi15 = eng._series.phi(np.array([tau]))[0]
    np.testing.assert_allclose(P2[:15, 15:], (phi15 @ eng.P_na) * np.exp(-tau / T), rtol=1e-12, atol=1e-15)
    assert np.all(np.isfinite(P2)) and np.allclose(P2, P2.T, atol=1e-12)


def test_aux_random_walk_path_is_unchanged_by_infinite_correlation_times():
    """aux_tau_s of infinities (or None) is the random-walk engine, number for number."""
    from navsim.estimators._inserror import AuxStateIns

    ctx, prior, batch = _engine_case(2.0)
    noise = ImuNoise.from_nominal(ctx.imu)
    out = []
    for tau in (None, [np.inf, np.inf]):
        eng = AuxStateIns(ctx, prior, noise, interval_steps=50, aux_variance=[1e-4, 4.0], aux_psd=[1e-6, 0.1],
                          aux_tau_s=tau)
        body = eng.prepare(batch.dtheta_sub, batch.dv_sub, batch.dtheta_r, batch.dv_r)
        eng.advance_body(body, 0, 130)
        H = np.zeros((2, 17))
        H[0, 0], H[0, 15], H[1, 2], H[1, 16] = 1.0, 1.0, 1.0, 1.0
        eng.update(H, np.eye(2), np.array([0.3, -0.2]))
        rows, _ = eng.advance_body(body, 130)
        out.append((eng.full_covariance(), eng.aux_now(), rows))
    for a, b in zip(out[0], out[1]):
        assert np.array_equal(a, b)
    with pytest.raises(Exception):
        AuxStateIns(ctx, prior, noise, aux_variance=[1.0], aux_psd=[1.0], aux_tau_s=[0.0])


def _standalone(duration, multipath=True, name="paper-2012"):
    gnss = {"preset": "standalone"}
    if not multipath:
        gnss["overrides"] = {"multipath_sigma_m": 0.0}
    return load_scenario(name).with_overrides({
        "timing": {"duration_s": duration}, "imu": {"preset": "tactical", "gyro": _MATCHED, "accel": _MATCHED},
        "gnss": gnss, "initial": {"position_m": 5.0, "velocity_mps": 0.1, "attitude_deg": 0.2}})


def test_fix_error_option_and_white_default_without_atmosphere():
    from navsim.estimators.loosely import fix_error_model

    with pytest.raises(Exception):
        make("lc-ekf", fix_error="gm")
    with pytest.raises(Exception):
        make("lc-ekf", fix_error_tau_s=(100.0, -1.0))
    # no atmosphere in the context: "auto" is "white", number for number
    sc = _matched(15.0)
    a = run_episode(sc, make("lc-ekf"), seed=2)
    b = run_episode(sc, make("lc-ekf", fix_error="white"), seed=2)
    assert np.array_equal(a.est_lat, b.est_lat) and np.array_equal(a.est_cov, b.est_cov)
    # with it, "auto" adds three states (LC.7) and changes the solution
    sim = Simulator(_standalone(5.0))
    start = sim.reset(0)
    ctx = make_context(sim)
    est = make("lc-ekf")
    est.reset(ctx, start.prior)
    assert est.engine.n_aux == 3
    sigma, tau = fix_error_model(ctx.gnss, start.prior.h)
    k_hi, k_ui = 0.15, 2.0
    assert sigma[2] == pytest.approx(math.hypot(k_ui * 4.5, 3.6 * 0.12 * math.exp(-start.prior.h / 8000.0)))
    assert sigma[0] == sigma[1] == pytest.approx(math.hypot(k_hi * 4.5, 0.55 * 0.12 * math.exp(-start.prior.h / 8000.0)))
    np.testing.assert_allclose(np.diag(est.engine.full_covariance())[15:], sigma**2)
    assert list(tau) == [1200.0, 1200.0, 7200.0]


def test_zenith_delay_factors_of_the_least_squares_fix():
    """FIX_ZENITH_FACTORS against the fix error of a 1-m zenith delay (tightly's mapping),
    12 h of the bundled GPS constellation at two scenario sites, 10 deg mask: vertical
    factors within 10 % of the RMS, horizontal ones above the per-axis RMS; the
    correlation the time constants rest on (vertical: raw autocorrelation > 0.95 at 1 h;
    horizontal: 1/e time of the centred autocorrelation 0.5-2 ks)."""
    from navsim.earth import mat_en
    from navsim.estimators.loosely import FIX_ZENITH_FACTORS
    from navsim.estimators.tightly import atmosphere_delays
    from navsim.sensors.gnss import elevation_azimuth, least_squares_fix, satellite_states

    t = np.arange(0.0, 12 * 3600.0, 30.0)
    for name in ("mountain-railway", "paper-2012"):
        sim = Simulator(load_scenario(name))
        prior = sim.reset(0).prior
        earth = sim.earth
        r = earth.geodetic_to_ecef(prior.lat, prior.lon, prior.h)
        pos, _ = satellite_states(sim.constellation, t, earth)
        el, _, rng = elevation_azimuth(np.repeat(r[None], len(t), 0), pos, earth)
        valid = el > math.radians(10.0)
        iono, tropo = atmosphere_delays(prior.lat, prior.lon, 0.0, pos, 1.0, 1.0, earth)
        c_en = mat_en(prior.lat, prior.lon)
        for kind, delay in (("ionosphere", iono), ("troposphere", tropo)):
            fix = least_squares_fix(pos, rng + delay, valid, initial=np.repeat(r[None], len(t), 0))
            e = (fix.position_e - r) @ c_en.T
            rms = np.sqrt(np.mean(e**2, axis=0))
            k_h, k_u = FIX_ZENITH_FACTORS[kind]
            assert np.mean(e[:, 2]) > 0.0 and abs(rms[2] / k_u - 1.0) < 0.1, (name, kind, rms)
            assert np.all(rms[:2] < k_h), (name, kind, rms)
            lag = 120  # 1 h
            assert np.mean(e[:-lag, 2] * e[lag:, 2]) / np.mean(e[:, 2] ** 2) > 0.95
            for axis in (0, 1):
                x = e[:, axis] - e[:, axis].mean()
                ac = np.array([np.mean(x[:-k] * x[k:]) for k in range(1, 200)]) / np.mean(x * x)
                one_e = 30.0 * (1 + np.argmax(ac < math.exp(-1.0)))
                assert 500.0 < one_e < 2000.0, (name, kind, axis, one_e)


def _standalone_runs(seeds, duration, multipath, fix_error="auto"):
    sc = _standalone(duration, multipath)
    sim = Simulator(sc)
    values, nis_all, vertical = [], [], []
    for seed in seeds:
        rec = run_episode(sc, make("lc-ekf", fix_error=fix_error), seed=seed, simulator=sim)
        e = error_vector(rec)
        values.append(nees(e, rec.est_cov))
        nis_all.append(rec.nis[np.isfinite(rec.nis)])
        vertical.append(e[rec.t > 20.0, 2])
    return np.array(values), np.concatenate(nis_all), np.concatenate(vertical)


@pytest.mark.parametrize("multipath", [True, False], ids=["multipath", "no-multipath"])
def test_standalone_receiver_consistency_short(multipath):
    """paper-2012 track, matched tactical IMU, standalone receiver, 2 seeds x 100 s.
    White fixes (the filter before): NEES in the hundreds / thousands (the uncorrected
    atmosphere puts the fix ~16 m high). "auto": mean NEES ~6.3 (measured 6.3 / 6.4 with
    and without multipath over 3 seeds x 200 s); without multipath the white part is the
    filter's model, so the pooled NIS lies inside its exact chi-square bounds; with it the
    nominal sigma (hypot(1, 3) m, the horizon multipath) is conservative: NIS/dof ~0.6."""
    values, nis, up = _standalone_runs((0, 1), 100.0, multipath)
    old, _, up_old = _standalone_runs((0,), 100.0, multipath, "white")
    assert np.nanmean(old) > 300.0 and np.sqrt(np.mean(up_old**2)) > 12.0
    assert 0.45 * 9 < np.nanmean(values) < 1.3 * 9, np.nanmean(values)
    assert np.sqrt(np.mean(up**2)) < 6.0
    k = len(nis)
    lo, hi = chi2.ppf([0.005, 0.995], 6 * k) / k
    if multipath:
        assert 0.4 < nis.mean() / 6 < 0.8
    else:
        assert lo < nis.mean() < hi, (nis.mean(), lo, hi)


def test_fix_error_states_batch_equals_step():
    sc = _standalone(8.0)
    a = run_episode(sc, make("lc-ekf"), seed=4, use_batch=True)
    b = run_episode(sc, make("lc-ekf"), seed=4, use_batch=False)
    # states and NIS: the same operations in both paths, bit for bit; the covariance between
    # epochs: one (n, 9) @ (9, 81) product against n one-row ones (tests/tolerances.py)
    for field in ("est_lat", "est_lon", "est_h", "est_velocity_n", "est_hpr", "nis"):
        assert_same_field(getattr(a, field), getattr(b, field), field)
    assert_covariance_close(a.est_cov, b.est_cov)


@pytest.mark.slow
@pytest.mark.parametrize("multipath", [True, False], ids=["multipath", "no-multipath"])
def test_standalone_receiver_consistency_20_seeds(multipath):
    """20 seeds x 200 s of the short case. The atmosphere is the same draw in every seed
    (5 m vertical ionosphere against the a-priori 1.50 +- 4.5 m: 0.78 sigma; 2.4 m
    troposphere against 2.448 +- 0.12 m), so the NEES averaged over seeds does not
    average the fix-error states and is not chi2(9 M)/M. Measured: mean NEES 6.89 with,
    6.93 without multipath (white fixes: ~570 / ~3000); per-second seed averages never
    above the 95 % band and inside it at 25 % of the seconds, below it otherwise (the
    filter is conservative: the draw is 0.78 sigma, and the horizontal fix-error sigma
    0.68 m covers the worst geometry); NIS/dof 0.57 / 1.006; vertical RMS 3.7 m."""
    values, nis, up = _standalone_runs(range(20), 200.0, multipath)
    per_second = values[:, 99::100].mean(axis=0)
    lo, hi = chi2.ppf([0.025, 0.975], 9 * 20) / 20
    assert 0.6 * 9 < np.nanmean(values) < 1.1 * 9, np.nanmean(values)
    assert np.mean(per_second > hi) < 0.05
    k = len(nis)
    if not multipath:  # the white part is the model: exact bounds of the pooled NIS
        n_lo, n_hi = chi2.ppf([0.005, 0.995], 6 * k) / k
        assert n_lo < nis.mean() < n_hi, (nis.mean(), n_lo, n_hi)
    assert np.sqrt(np.mean(up**2)) < 6.0


# ----------------------------------------------------------------------- against the old code
_REFERENCE = os.environ.get("NAVSIM_REFERENCE_TREE")

_DUMP = textwrap.dedent("""
    import sys
    sys.path.insert(0, sys.argv[1])
    import numpy as np
    from navsim.scenario import load_scenario
    from navsim.episode import run_episode
    from navsim.estimators import make
    options = {"fix_error": "white"} if sys.argv[3] == "new" else {}
    cases = {
        "paper-2012": (load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 40.0}}), {}),
        "mountain-white": (load_scenario("mountain-railway").with_overrides({"timing": {"duration_s": 40.0}}),
                           options),
        "mountain-odometer-white": (load_scenario("mountain-railway").with_overrides({
            "timing": {"duration_s": 40.0}, "odometer": {"enabled": True, "preset": "rail-tachometer"}}), options),
    }
    out = {}
    for name, (sc, opts) in cases.items():
        rec = run_episode(sc, make("lc-ekf", **opts), seed=3)
        out[name] = np.column_stack([rec.est_lat, rec.est_lon, rec.est_h, rec.est_velocity_n])
        out[name + "/cov"] = rec.est_cov
        out[name + "/nis"] = rec.nis
    np.savez(sys.argv[2], **out)
""")


@pytest.mark.skipif(not _REFERENCE, reason="set NAVSIM_REFERENCE_TREE to a checkout before the fix-error states")
def test_white_fixes_are_bit_identical_to_the_reference_tree(tmp_path):
    """fix_error="white" (and "auto" without atmosphere) is the filter before the
    fix-error states, number for number: paper-2012 (default options), mountain-railway's
    standalone receiver with white fixes, and the same with the rail tachometer (the
    random-walk AuxStateIns path). The reference runs in a subprocess on the tree named
    by NAVSIM_REFERENCE_TREE (e.g. ``git worktree add <dir> <commit>``)."""
    here = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    files = {}
    for label, tree in (("ref", _REFERENCE), ("new", here)):
        files[label] = tmp_path / f"{label}.npz"
        subprocess.run([sys.executable, "-c", _DUMP, tree, str(files[label]), label], check=True,
                       env={**os.environ, "PYTHONPATH": tree})
    ref, new = np.load(files["ref"]), np.load(files["new"])
    assert sorted(ref.files) == sorted(new.files)
    for key in ref.files:
        assert np.array_equal(ref[key], new[key], equal_nan=True), key


def test_one_epoch_fixes_equal_the_batched_fixes_bit_for_bit():
    """gnss_fixes of one epoch calls the compiled kernels directly (loosely._one_epoch_fixes):
    the same kernels on the same inputs as the batched call, so every output is the same
    bit for bit, including epochs with too few usable channels and no starting point."""
    from navsim.estimators.loosely import gnss_fixes
    from navsim.receiver import epoch_kernels

    if epoch_kernels() is None:
        pytest.skip("numba (extra 'fast') not installed: one path only")
    sc = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 3.0}})
    sim = Simulator(sc)
    start = sim.reset(0)
    batch = measurement_batch(sim.advance(300), np.asarray(sim.constellation.prn), sc.timing.nav_period_s)
    obs = [o for _, o in batch.gnss]
    few = dataclasses.replace(obs[0], valid=np.asarray(obs[0].valid) & (np.cumsum(obs[0].valid) <= 3))
    nan = dataclasses.replace(obs[1], pseudorange_m=np.where(np.arange(len(obs[1].valid)) == 2, np.nan,
                                                             obs[1].pseudorange_m))
    initial = sim.earth.geodetic_to_ecef(start.prior.lat, start.prior.lon, start.prior.h)
    for o in (*obs, few, nan):
        for init in (initial, None):
            one = gnss_fixes((o,), 4, init)
            two = gnss_fixes((o, o), 4, init)  # the batched wrappers
            for a, b in zip(one, two):
                assert a.dtype == b.dtype and a.shape[1:] == b.shape[1:]
                np.testing.assert_array_equal(a[0], b[0], strict=True)
    assert not gnss_fixes((few,), 4, initial)[0][0]
