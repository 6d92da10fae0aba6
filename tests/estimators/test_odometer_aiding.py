"""Wheel-odometer aiding in the along-track filter and the loosely coupled EKF.

The consistency case is the antenna lever-arm case (tests/estimators/lever_arm_case.py:
the curves of the mountain railway at a constant 19.4 m/s, no body oscillation, matched
tactical IMU, white GNSS of 1 m / 0.05 m/s) with the antenna at the IMU, a GNSS outage,
and a rail tachometer without slip (the filters model the rest: turn-on and slowly
varying scale factor, white noise, pulse quantisation). Without oscillations the body
velocity is exactly forward, so the non-holonomic constraint holds.
"""

from __future__ import annotations

import dataclasses
import math
import os

import numpy as np
import pytest
from scipy.stats import chi2

from navsim.episode import make_context, measurement_batch, measurements, run_episode
from navsim.estimators import make
from navsim.estimators._inserror import NAV, N_STATES, body_velocity_terms, correct_state
from navsim.metrics import error_vector, nees
from navsim.rotations import mat_nb_from_hpr, mat_to_quat, quat_to_mat
from navsim.scenario import load_scenario
from navsim.simulator import Simulator
from navsim.strapdown.ins import InsState
from tolerances import assert_covariance_close, assert_same_arithmetic

from lever_arm_case import lever_scenario
from test_along_track import _along_errors, _nees2

NO_SLIP = {"enabled": True, "preset": "rail-tachometer", "overrides": {"slip_fraction": 0.0, "slide_fraction": 0.0}}


def _case(duration=100.0, outage=(40.0, 90.0), odometer=NO_SLIP):
    over = {"outages": {"windows_s": [list(outage)] if outage else []}}
    if odometer is not None:
        over["odometer"] = odometer
    return lever_scenario(duration, lever_arm_m=(0.0, 0.0, 0.0)).with_overrides(over)


# ----------------------------------------------------------------------- the Jacobian
def test_body_velocity_jacobian_by_finite_differences():
    """v_b(est) - v_b(true) = J x for a truth hypothesis correct_state(est, x)."""
    from navsim.earth import WGS84

    C = mat_nb_from_hpr(0.7, 0.03, -0.05)
    est = InsState(0.8, 0.3, 200.0, np.array([12.0, -15.0, 0.4]), mat_to_quat(C))
    vb, J = body_velocity_terms(C, est.velocity_n)
    np.testing.assert_allclose(vb, C.T @ est.velocity_n, atol=1e-14)

    def vb_of(state):
        return quat_to_mat(state.quat_nb).T @ np.asarray(state.velocity_n)

    rng = np.random.default_rng(0)
    for j in list(range(3, 9)):
        x = np.zeros(N_STATES)
        h = 1e-4 if j < 6 else 1e-6
        x[j] = h
        plus = vb - vb_of(correct_state(est, x[NAV], WGS84))
        x[j] = -h
        minus = vb - vb_of(correct_state(est, x[NAV], WGS84))
        np.testing.assert_allclose((plus - minus) / (2 * h), J[:, j], rtol=0, atol=1e-6)
    assert not J[:, :3].any() and not J[:, 9:].any()
    del rng


# ----------------------------------------------------------------------- off = today's filter
@pytest.mark.parametrize("name", ["lc-ekf", "along-track"])
def test_odometer_none_equals_the_filter_without_odometer(name):
    """The IMU and GNSS numbers do not depend on the odometer stream, so option "none"
    on the odometer scenario must give the estimates of the scenario without one."""
    with_odo, without = _case(30.0, (10.0, 25.0)), _case(30.0, (10.0, 25.0), odometer=None)
    a = run_episode(with_odo, make(name, odometer="none"), seed=4)
    b = run_episode(without, make(name), seed=4)
    assert np.array_equal(a.est_lat, b.est_lat) and np.array_equal(a.est_velocity_n, b.est_velocity_n)
    assert np.array_equal(a.est_cov, b.est_cov, equal_nan=True)
    c = run_episode(with_odo, make(name), seed=4)
    assert not np.array_equal(c.est_lat, b.est_lat)


@pytest.mark.parametrize("name", ["lc-ekf", "along-track"])
def test_step_batch_equals_repeated_step_with_odometer(name):
    sc = _case(12.0, (4.0, 10.0))
    sim = Simulator(sc)
    start = sim.reset(3)
    ctx = make_context(sim)
    assert ctx.odometer is not None and ctx.odometer.pulse_length_m == pytest.approx(math.pi * 0.92 / 200)
    prn = np.asarray(sim.constellation.prn)
    chunk = sim.advance(1200)
    a, b = make(name), make(name)
    a.reset(ctx, start.prior)
    b.reset(ctx, start.prior)
    first = a.step_batch(measurement_batch(chunk, prn, 0.01))
    steps = [b.step(m) for m in measurements(chunk, prn, 0.01)]
    sol = np.array([s.as_action() for s in steps])
    cov = np.array([s.covariance for s in steps])
    nis_step = np.array([np.nan if s.nis is None else s.nis for s in steps])
    if name == "along-track":  # one step loop serves both paths: bit for bit
        assert_same_arithmetic(first.solution, sol)
        assert_same_arithmetic(first.covariance, cov)
        assert_same_arithmetic(first.nis, nis_step)
    else:
        # lc-ekf sums the odometer increments and body velocities of an update interval
        # per call (np.sum / einsum over the call's rows) or step by step: the same
        # <= 100-term sums in another order, |dD| <= 2 gamma_100 D ~ 2e-14 D (D ~ 10 m per
        # 1-s interval: ~2e-13 m). Through 12 updates (gain <= 1) the states move by far
        # less than 1e-10 (m, m/s, rad); the NIS, a ratio ~ nu^2 / S with |nu| >= ~0.05 m
        # here, by less than 1e-9 relative. Latitude/longitude (rad, ~1e-7 per m) to 1e-16
        # plus one ulp of the value itself (~1.1e-16 at 0.7 rad: the rounding of the last
        # addition can land on either neighbour).
        lat_lon = np.abs(first.solution[:, :2] - sol[:, :2])
        assert np.all(lat_lon <= 1e-16 + np.spacing(np.abs(sol[:, :2]))), lat_lon.max()
        np.testing.assert_allclose(first.solution[:, 2:], sol[:, 2:], rtol=0, atol=1e-10)
        np.testing.assert_allclose(first.nis, nis_step, rtol=1e-9, equal_nan=True)
        # covariance: the Jacobians of the update carry the relative rounding of those
        # 100-term sums; bound per entry 2 gamma_100 sqrt(P_ii P_jj) (tests/tolerances.py)
        assert_covariance_close(first.covariance, cov, n_terms=100)
    # one odometer update per second, GNSS on the seconds outside the outage
    assert np.isfinite(first.nis).sum() == 12
    assert steps[-1].extra["odometer_scale"] == pytest.approx(
        a.engine.aux[0] if name == "lc-ekf" else a.x[a.i_scale], abs=1e-12)


# ----------------------------------------------------------------------- consistency
def _runs(name, seeds, duration, outage):
    sc = _case(duration, outage)
    sim = Simulator(sc)
    runs, nis = [], []
    for seed in seeds:
        rec = run_episode(sc, make(name), seed=seed, simulator=sim)
        runs.append(nees(error_vector(rec), rec.est_cov) if name == "lc-ekf" else _nees2(*_along_errors(rec)))
        ok = np.isfinite(rec.nis)
        nis.append((rec.nis[ok].sum(), rec.nis_dof[ok].sum()))
    return np.array(runs), np.sum(nis, axis=0), rec


@pytest.mark.parametrize("name, dof", [("lc-ekf", 9), ("along-track", 2)])
def test_consistency_short(name, dof):
    """4 seeds x 100 s with a 50-s outage (odometer alone from 40 to 90 s).

    Pooled NIS: the along-track filter's inside its exact chi-square bounds (sequential
    innovations of a consistent filter are independent). The loosely coupled filter is
    conservative by construction, so only the upper bound applies to it: its
    non-holonomic rows have R = (0.05 m/s)^2 against a true violation of zero here, and
    the quantisation error of consecutive spans (differences of carries) is negatively
    correlated where the filter takes it as white (measured odometer-update NIS/dof
    about 0.45, GNSS 1.04; mean NEES 6.5 of 9 over 8 seeds, 8.0 without the odometer).
    Mean NEES (correlated in time) within a loose factor of the dimension, overall and
    in the outage.
    """
    runs, (nis_sum, nis_dof), rec = _runs(name, range(4), 100.0, (40.0, 90.0))
    lo, hi = chi2.ppf([0.0005, 0.9995], nis_dof)
    assert nis_sum < hi, nis_sum / nis_dof
    if name == "along-track":
        assert lo < nis_sum, nis_sum / nis_dof
    mean = runs[:, 500:].mean()
    assert 0.5 * dof < mean < 1.5 * dof, mean
    assert 0.4 * dof < runs[:, 4000:9000].mean() < 1.5 * dof  # inside the outage


@pytest.mark.slow
@pytest.mark.parametrize("name, dof", [("lc-ekf", 9), ("along-track", 2)])
def test_consistency_20_seeds(name, dof):
    """NEES averaged over 20 seeds (200 s, outage 80-160 s) per second against the 95 %
    chi-square band (Bar-Shalom et al. 2001, 5.4.2): the along-track filter inside the
    two-sided band at most seconds; the loosely coupled filter, conservative by
    construction (see test_consistency_short), below the upper bound at most seconds and
    with its mean NEES between 0.5 and 1.1 times the dimension."""
    n = 20
    runs, (nis_sum, nis_dof), _ = _runs(name, range(n), 200.0, (80.0, 160.0))
    avg = runs[:, 99::100].mean(axis=0)[5:]
    lo, hi = chi2.ppf([0.025, 0.975], dof * n) / n
    print(f"\n{name}: mean NEES {avg.mean():.2f} (dof {dof}), inside {np.mean((avg > lo) & (avg < hi)):.2f}, "
          f"below upper {np.mean(avg < hi):.2f}, NIS/dof {nis_sum / nis_dof:.2f}")
    nis_lo, nis_hi = chi2.ppf([0.0005, 0.9995], nis_dof)
    assert nis_sum < nis_hi, nis_sum / nis_dof
    if name == "along-track":
        assert np.mean((avg > lo) & (avg < hi)) >= 0.8, (avg.mean(), lo, hi)
        assert nis_lo < nis_sum
    else:
        assert np.mean(avg < hi) >= 0.9, (avg.mean(), hi)
        assert 0.5 * dof < avg.mean() < 1.1 * dof


# ----------------------------------------------------------------------- benefit
def test_odometer_bounds_the_outage_drift_of_the_loosely_coupled_ekf():
    """60-s outage, matched tactical IMU: the odometer and the NHC hold the horizontal
    error at the last step before the fixes return to a fraction of the free INS drift
    (measured, seeds 0/1/2: 25.5/31.4/70.2 m without, 2.2/0.75/1.4 m with), inside
    4 sigma of the filter's covariance either way."""
    sc = _case(100.0, (30.0, 90.0))
    end = 8998  # t = 89.99 s; the epoch at 90 s is valid again
    for seed in (1, 2):
        drift = {}
        for opt in ("none", "auto"):
            rec = run_episode(sc, make("lc-ekf", odometer=opt), seed=seed)
            e = error_vector(rec)
            drift[opt] = float(np.hypot(*e[end, :2]))
            sigma = np.sqrt(np.diagonal(rec.est_cov[end]))
            assert np.all(np.abs(e[end, :6]) < 4.0 * sigma[:6]), (opt, e[end, :6] / sigma[:6])
        assert drift["auto"] < 0.1 * drift["none"], drift


def _tunnels(scenario):
    """(first epoch lost, first epoch back) times of the receiver outages over 10 s."""
    sim = Simulator(scenario)
    sim.reset(0)
    out = np.concatenate([c.receiver_outage for c in sim.chunks(20_000)])
    t = (np.arange(len(out)) + 1) * scenario.timing.gnss_period_s
    edges = np.flatnonzero(np.diff(np.concatenate([[0], out.astype(int), [0]])))
    spans = [(t[a], t[b - 1] + scenario.timing.gnss_period_s) for a, b in zip(edges[::2], edges[1::2])]
    return [s for s in spans if s[1] - s[0] > 10.0]


@pytest.mark.slow
def test_outage_drift_figures_mountain_railway():
    """Drift at the end of each tunnel of the full mountain railway (1960 s, standalone
    receiver, rail tachometer with slip), with and without the odometer, tactical and
    consumer IMU, lc-ekf and along-track. Writes a figure to $NAVSIM_FIGURES if set."""
    rows = []
    for imu in ("tactical", "consumer-mems"):
        base = load_scenario("mountain-railway").with_overrides({"imu": {"preset": imu}})
        sc = base.with_overrides({"odometer": {"enabled": True, "preset": "rail-tachometer"}})
        tunnels = _tunnels(sc)
        assert len(tunnels) == 3
        sim = Simulator(sc)
        for name in ("lc-ekf", "along-track"):
            for opt in ("none", "auto"):
                rec = run_episode(sc, make(name, odometer=opt), seed=0, simulator=sim)
                e = error_vector(rec)
                for k, (t0, t1) in enumerate(tunnels):
                    i = np.searchsorted(rec.t, t1 - 1e-9) - 1  # the last step before the fix
                    rows.append((imu, name, opt, k, t1 - t0, float(np.hypot(*e[i, :2]))))
    table = {(r[0], r[1], r[2], r[3]): r[5] for r in rows}
    for imu in ("tactical", "consumer-mems"):
        longest = 1  # the 3-km tunnel
        assert table[(imu, "lc-ekf", "auto", longest)] < 0.2 * table[(imu, "lc-ekf", "none", longest)]
    print("\nimu, estimator, odometer, tunnel, length s, horizontal error at exit m")
    for r in rows:
        print(f"{r[0]:14s} {r[1]:12s} {r[2]:5s} {r[3]} {r[4]:6.0f} {r[5]:10.2f}")
    folder = os.environ.get("NAVSIM_FIGURES")
    if folder:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
        for ax, imu in zip(axes, ("tactical", "consumer-mems")):
            labels, x = [], np.arange(3)
            for j, (name, opt) in enumerate([(n, o) for n in ("lc-ekf", "along-track") for o in ("none", "auto")]):
                vals = [table[(imu, name, opt, k)] for k in range(3)]
                ax.bar(x + 0.2 * j - 0.3, vals, 0.2, label=f"{name}, odometer={opt}")
            ax.set_yscale("log")
            ax.set_xticks(x, [f"tunnel {k + 1}" for k in range(3)])
            ax.set_title(f"mountain-railway, {imu} IMU")
            ax.set_ylabel("horizontal error at tunnel exit, m")
        axes[0].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(folder, "odometer_outage_drift.png"), dpi=120)
