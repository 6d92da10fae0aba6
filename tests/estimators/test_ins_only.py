"""INS only: ideal data stays on truth; the covariance grows as the error model says."""

from __future__ import annotations

import dataclasses

import numpy as np
from tolerances import assert_covariance_close, assert_same_solution

from navsim.episode import make_context, measurement_batch, measurements, run_episode
from navsim.estimators import make
from navsim.estimators._inserror import ErrorStateIns, ImuNoise, compensate_increments
from navsim.estimators.base import NominalImu
from navsim.metrics import error_vector
from navsim.scenario import load_scenario
from navsim.simulator import Simulator
from navsim.strapdown.ins import integrate


def _scenario(duration=60.0, imu="ideal", **initial):
    return load_scenario("paper-2012").with_overrides({
        "timing": {"duration_s": duration}, "imu": {"preset": imu},
        "initial": {"position_m": 0.0, "velocity_mps": 0.0, "attitude_deg": 0.0, **initial}})


def test_ideal_imu_exact_prior_stays_on_truth():
    rec = run_episode(_scenario(60.0), make("ins-only"), seed=0)
    e = error_vector(rec)
    assert np.abs(e[:, :3]).max() < 1e-6  # m after 60 s
    assert np.abs(e[:, 3:6]).max() < 1e-9
    assert np.abs(e[:, 6:]).max() < 1e-12
    assert np.all(rec.est_cov == 0.0)  # nothing uncertain, no noise: nothing grows


def _engine_run(nominal: NominalImu, prior_sigmas, duration=30.0):
    sc = _scenario(duration)
    sim = Simulator(sc)
    start = sim.reset(0)
    ctx = dataclasses.replace(make_context(sim), imu=nominal)
    prior = dataclasses.replace(start.prior, covariance=np.diag(np.repeat(np.square(prior_sigmas), 3)))
    est = make("ins-only")
    est.reset(ctx, prior)
    prn = np.asarray(sim.constellation.prn)
    out = [est.step_batch(measurement_batch(c, prn, sc.timing.nav_period_s)) for c in sim.chunks(10_000)]
    return np.concatenate([o.covariance for o in out]), sc.timing.nav_period_s


def test_covariance_growth_matches_closed_forms():
    """Short-time closed forms (t << Schuler period): velocity random walk gives
    P_v = q t, P_r = q t^3 / 3; a tilt uncertainty s gives horizontal P_v = (g s t)^2;
    angle random walk P_psi = q_g t; a gyro bias sigma b gives P_psi = (b t)^2."""
    g, t_end = 9.81, 30.0
    q = 1e-4  # VRW^2, m^2/s^3
    cov, dt = _engine_run(NominalImu(accel_vrw=np.sqrt(q)), (0.0, 0.0, 0.0), t_end)
    t = (np.arange(len(cov)) + 1) * dt
    np.testing.assert_allclose(cov[:, 5, 5], q * t, rtol=2e-3)
    np.testing.assert_allclose(cov[-1, 2, 2], q * t_end**3 / 3, rtol=2e-3)
    s = 1e-3
    cov, _ = _engine_run(NominalImu(), (0.0, 0.0, s), t_end)
    np.testing.assert_allclose(cov[-1, 3, 3], (g * s * t_end) ** 2, rtol=0.02)
    np.testing.assert_allclose(cov[-1, 4, 4], (g * s * t_end) ** 2, rtol=0.02)
    cov, _ = _engine_run(NominalImu(gyro_arw=1e-4), (0.0, 0.0, 0.0), t_end)
    np.testing.assert_allclose(cov[-1, 8, 8], 1e-8 * t_end, rtol=1e-3)
    b = 1e-5
    cov, _ = _engine_run(NominalImu(gyro_bias_sigma=b, gyro_bias_tau_s=1e9), (0.0, 0.0, 0.0), t_end)
    np.testing.assert_allclose(cov[-1, 8, 8], (b * t_end) ** 2, rtol=1e-3)
    # horizontal position from a gyro bias: P_r = (g b t^3 / 6)^2
    np.testing.assert_allclose(cov[-1, 0, 0], (g * b * t_end**3 / 6) ** 2, rtol=0.02)


def test_step_batch_equals_repeated_step():
    sc = _scenario(3.0, imu="consumer-mems", position_m=3.0, velocity_mps=0.1, attitude_deg=0.5)
    sim = Simulator(sc)
    start = sim.reset(1)
    ctx = make_context(sim)
    prn = np.asarray(sim.constellation.prn)
    chunk = next(iter(sim.chunks(10_000)))
    a, b = make("ins-only", covariance_period_s=0.37), make("ins-only", covariance_period_s=0.37)
    a.reset(ctx, start.prior)
    b.reset(ctx, start.prior)
    out = a.step_batch(measurement_batch(chunk, prn, sc.timing.nav_period_s))
    steps = [b.step(m) for m in measurements(chunk, prn, sc.timing.nav_period_s)]
    # states and NIS: the same operations in both paths, bit for bit; the covariance between
    # epochs: one (n, 9) @ (9, 81) product against n one-row ones (tests/tolerances.py)
    assert_same_solution(out.solution, [s.as_action() for s in steps])
    assert_covariance_close(out.covariance, np.array([s.covariance for s in steps]))


def test_engine_reproduces_integrate_and_bias_compensation():
    """The engine's own body terms give integrate()'s numbers; its linear bias removal
    agrees with removing the bias from the raw increments to well below the IMU noise."""
    sc = _scenario(5.0, imu="ideal")
    sim = Simulator(sc)
    start = sim.reset(0)
    ctx = make_context(sim)
    chunk = next(iter(sim.chunks(10_000)))
    imu = chunk.imu
    arrays = (imu.dtheta_sample[:, :, 0], imu.dv_sample[:, :, 0], imu.dtheta_r, imu.dv_r)
    engine = ErrorStateIns(ctx, start.prior, ImuNoise())
    rows, _ = engine.advance(*arrays)
    ref = integrate(engine.__class__(ctx, start.prior, ImuNoise()).state, *arrays, dt=ctx.nav_period_s,
                    earth=ctx.earth)
    np.testing.assert_array_equal(rows[:, 0], ref.lat[1:])
    np.testing.assert_array_equal(rows[:, 3:6], ref.velocity_n[1:])
    # a consumer-grade bias (1e-3 rad/s, 0.1 m/s^2) removed both ways
    bg, ba = np.array([1e-3, -2e-3, 1.5e-3]), np.array([0.1, -0.05, 0.08])
    engine = ErrorStateIns(ctx, start.prior, ImuNoise())
    engine.gyro_bias, engine.accel_bias = bg, ba
    rows, _ = engine.advance(*arrays)
    comp = compensate_increments(*arrays, bg, ba, ctx.nav_period_s)
    ref = integrate(engine.__class__(ctx, start.prior, ImuNoise()).state, *comp, dt=ctx.nav_period_s, earth=ctx.earth)
    r_n = 6.4e6
    assert np.abs(rows[:, 0] - ref.lat[1:]).max() * r_n < 1e-6  # m over 5 s
    assert np.abs(rows[:, 3:6] - ref.velocity_n[1:]).max() < 1e-7  # m/s
