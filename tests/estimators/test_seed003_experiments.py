"""Seed 003 as the paper argues it: the observer ablation, the instants of the experiment
table and the deterministic checks (noise-free open-loop propagation from the truth).

Truths used: the simulator's exact motion (a noise-free IMU integrated by the filter model
must stay on it), the Lyapunov equation of the covariance without (13) (the reference
RK4 of :func:`navsim.estimators.paper_ekf.numerics.riccati_rk4` with zero observation), and the
GNSS epoch times of the scenario.
"""

from __future__ import annotations

import numpy as np
import pytest

from navsim.episode import make_context, measurement_batch
from navsim.estimators.paper_ekf import PaperEkf, paper_state
from navsim.estimators.paper_ekf.numerics import riccati_rk4 as _riccati_rk4
from navsim.paper.seed003 import _truth_state, gnss_epoch_times, outage_instants
from navsim.scenario import load_scenario
from navsim.simulator import Simulator


def _ideal(duration):
    return load_scenario("paper-2012").with_overrides({
        "timing": {"duration_s": duration}, "imu": {"preset": "ideal"},
        "outages": {"windows_s": [[0.0, duration + 1.0]]}})


def test_outage_instants_pick_the_step_before_the_first_update():
    t = np.round(np.arange(1, 1001) * 0.01, 10)  # steps ending at 0.01 .. 10.00 s
    epochs = np.array([1.0, 2.0, 3.0, 7.0, 8.0])  # outage [4, 7): epochs 4, 5, 6 missing
    i_pre, i_end = outage_instants(t, epochs, 4.0)
    assert t[i_pre] == pytest.approx(3.0)  # the last update before the outage
    assert t[i_end] == pytest.approx(6.99)  # not 7.00, which carries the first update
    assert outage_instants(t, epochs[:3], 4.0)[1] == len(t) - 1  # no update after: the end


def test_gnss_epoch_times_skip_the_outage():
    sim = Simulator(load_scenario("paper-2012").with_overrides(
        {"timing": {"duration_s": 12.0}, "outages": {"windows_s": [[4.0, 7.0]]}}))
    sim.reset(0)
    times = gnss_epoch_times(list(sim.chunks(500)))
    assert 7.0 in times and 3.0 in times
    assert not np.any((times >= 4.0) & (times < 7.0))


def _from_truth(duration, **options):
    sim = Simulator(_ideal(duration))
    start = sim.reset(0)
    ctx = make_context(sim)
    chunks = list(sim.chunks(1000))
    t, yt = _truth_state(ctx, chunks)
    tr0 = sim.truth_at(np.array([0.0]))
    y0 = paper_state(tr0.lat, tr0.lon, tr0.velocity_n, tr0.heading, tr0.pitch, tr0.roll, tr0.t, ctx.earth.rate)[0]
    est = PaperEkf(**options)
    est.reset(ctx, start.prior)
    est._Y = [float(v) for v in y0]
    prn = np.asarray(sim.constellation.prn)
    ys = []
    for c in chunks:
        est.step_batch(measurement_batch(c, prn, ctx.nav_period_s))
        ys.append(est.last_states[:, :5])
    return np.concatenate(ys) - yt, ctx


@pytest.mark.parametrize("input_model", ["polynomial", "mean"])
def test_open_loop_filter_model_stays_on_the_truth(input_model):
    """The deterministic check of the end-of-outage bias: (7)-(8) integrated open loop
    (observer off) from the true state with a noise-free IMU. Measured over 100 s:
    2e-8 m, 2e-12 m/s, 6e-15 rad - so the filter model and the truth agree (gravity,
    Earth rate, specific force, sample timing) far below the outage drift of metres."""
    e, ctx = _from_truth(20.0, observer=False, input_model=input_model)
    assert np.max(np.abs(e[:, 3])) * ctx.earth.a < 1e-6
    assert np.max(np.abs(e[:, 4])) < 1e-9
    assert np.max(np.abs(e[:, :3])) < 1e-12


def test_open_loop_with_printed_centrifugal_sign_drifts_as_predicted():
    """The same check with the printed sign: V_Y' is off by 2 Omega^2 r cos(phi) sin(phi)."""
    e, ctx = _from_truth(5.0, observer=False, as_printed="centrifugal")
    from navsim.earth import SPHERICAL

    phi = 0.8238  # latitude of the paper-2012 track, rad (47.2 deg)
    dv = 2 * SPHERICAL.rate ** 2 * SPHERICAL.a * np.cos(phi) * np.sin(phi)
    assert e[-1, 4] / 5.0 == pytest.approx(dv, rel=2e-3)


def test_observer_off_covariance_is_the_lyapunov_equation():
    """observer=False: one step of the covariance equals the RK4 of R' = A R + R A^T + Q
    (the reference form with h = 0, S = 0), and the epoch update has no Z_ax row."""
    sim = Simulator(load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 3.0}}))
    start = sim.reset(1)
    ctx = make_context(sim)
    prn = np.asarray(sim.constellation.prn)
    chunk = sim.advance(150)
    batch = measurement_batch(chunk, prn, ctx.nav_period_s)
    one = PaperEkf(observer=False)
    one.reset(ctx, start.prior)
    p0, y0 = one._P.copy(), list(one._Y)
    inp = one._prepare(chunk.imu.dtheta_r[:1], chunk.imu.dv_r[:1])[0].tolist()
    A, _, Q, _, sig2, _ = one._coefficients(y0, inp[0:3], inp[3:6], 0.0)
    expect = _riccati_rk4(p0, A, np.zeros(5), Q, np.zeros(5), sig2, ctx.nav_period_s)
    got = one.step(batch.measurement(0)).extra["state_cov"]
    # two code paths (quadratic form vs direct RK4): rounding relative to the correlation
    # scale sqrt(P_ii P_jj) of each entry, not to the entry (off-diagonals near 1e-20)
    scale = np.sqrt(np.outer(np.diag(expect), np.diag(expect)))
    assert np.max(np.abs(got - expect) / scale) < 1e-12
    # epochs: 2 m observables without the observer, 2 m + 1 with Z_ax stacked (faithful)
    off, on = PaperEkf(observer=False), PaperEkf()
    off.reset(ctx, start.prior)
    on.reset(ctx, start.prior)
    out_off, out_on = off.step_batch(batch), on.step_batch(batch)
    j = int(chunk.gnss_step[0])
    n_sat = int(np.asarray(chunk.gnss.valid[0]).sum())
    assert out_off.nis_dof[j] == 2 * n_sat and out_on.nis_dof[j] == 2 * n_sat + 1
    # (13) resolves one attitude axis within a second (to ~1e-5 rad); without it the
    # attitude is seen only through the GNSS and stays near its prior after 1.5 s
    low = [np.linalg.eigvalsh(e.last_state_cov[-1, :3, :3])[0] for e in (off, on)]
    assert low[0] > 100 * low[1]


def test_observer_option_validated():
    from navsim.errors import ConfigError

    with pytest.raises(ConfigError):
        PaperEkf(observer="yes")
    assert PaperEkf().config.observer is True


# ---------------------------------------------------------------------------- scenario variants
def test_harmonic_speed_profile_against_finite_differences():
    from navsim.motion import ConstantSpeed

    prof = ConstantSpeed(20.0, s0=5.0, amplitude=5.0, period=300.0)
    t = np.linspace(0.0, 1000.0, 2001)
    s, v, a = prof.evaluate(t)
    h = 1e-3
    sp, vp, _ = prof.evaluate(t + h)
    sm, vm, _ = prof.evaluate(t - h)
    np.testing.assert_allclose((sp - sm) / (2 * h), v, rtol=0, atol=1e-7)  # central differences, s ~ 2e4 m
    np.testing.assert_allclose((vp - vm) / (2 * h), a, rtol=0, atol=1e-8)
    assert s[0] == 5.0 and v.min() == pytest.approx(15.0) and v.max() == pytest.approx(25.0)
    assert np.abs(a).max() == pytest.approx(2 * np.pi * 5.0 / 300.0)
    plain = ConstantSpeed(20.0, s0=5.0)
    assert all(np.array_equal(x, y) for x, y in zip(ConstantSpeed(20.0, 5.0, 0.0).evaluate(t), plain.evaluate(t)))


def test_bundled_variants_as_documented():
    from navsim.scenario import list_scenarios

    assert {"paper-2012-accelerating", "paper-2012-one-satellite"} <= set(list_scenarios())
    sim = Simulator(load_scenario("paper-2012-accelerating"))
    tr = sim.truth_at(np.linspace(0.0, 1000.0, 4001))
    assert 14.99 < tr.speed.min() < 15.01 and 24.99 < tr.speed.max() < 25.01
    assert tr.s[-1] < sim.track.length  # stays on the 24-km track
    sim = Simulator(load_scenario("paper-2012-one-satellite").with_overrides(
        {"timing": {"duration_s": 1000.0}, "outages": {"windows_s": []}, "imu": {"preset": "ideal"}}))
    sim.reset(0)
    prn = np.asarray(sim.constellation.prn)
    for chunk in sim.chunks(25_000):
        valid = np.asarray(chunk.gnss.valid)
        assert np.all(valid.sum(axis=1) == 1) and set(prn[valid.any(axis=0)]) == {18}
        k = np.asarray(chunk.gnss_step)
        lat, lon = chunk.truth.lat[k], chunk.truth.lon[k]
        sp, cp, sl, cl = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
        d = chunk.gnss.sat_pos_e[:, prn == 18, :][:, 0] - chunk.truth.position_e[k]
        up = np.stack([cp * cl, cp * sl, sp], -1)
        north = np.stack([-sp * cl, -sp * sl, cp], -1)
        el = np.degrees(np.arcsin(np.sum(d * up, 1) / np.linalg.norm(d, axis=1)))
        assert np.all((el > 50.0) & (el < 61.0))
        assert np.all(np.sum(d * north, 1) < 0)  # to the south: along the northbound track


# ---------------------------------------------------------------------------- which printed matrix is wrong
def test_one_misprint_in_appendix_1_explains_both_printed_phi_and_b():
    """If Appendix 1's D has alpha and beta interchanged (D'(a, b, g) = D(b, a, g), i.e.
    the first-listed angle is the first rotation), then (a) the printed kinematic matrix
    Phi(beta, gamma) of (1)/(7)/Appendix 2 is exactly the kinematic matrix of D', and (b)
    the printed definition B = D'(lambda + Omega t, -phi, 0) is exactly the ENU frame
    D(-phi, lambda + Omega t, 0) navsim uses. One misprint (printed once) against two."""
    from navsim.rotations import euler_krylov_matrix

    def d_swapped(a, b, g):
        return euler_krylov_matrix(b, a, g)

    rng = np.random.default_rng(12)
    for _ in range(5):
        lam_t, phi = rng.uniform(-3, 3), rng.uniform(-1.4, 1.4)
        assert np.array_equal(d_swapped(lam_t, -phi, 0.0), euler_krylov_matrix(-phi, lam_t, 0.0))
        a, b, g = rng.uniform(-1.2, 1.2, 3)
        w = rng.normal(size=3)
        sg, cg, cb, tb = np.sin(g), np.cos(g), np.cos(b), np.tan(b)
        phi_printed = np.array([[sg / cb, cg / cb, 0.0], [cg, -sg, 0.0], [sg * tb, cg * tb, 1.0]])
        rates = phi_printed @ w
        h = 1e-6  # central difference of D' along the printed rates: dD'/dt = -[w x] D'
        ddt = (d_swapped(*(np.array([a, b, g]) + h * rates)) - d_swapped(*(np.array([a, b, g]) - h * rates))) / (2 * h)
        wx = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
        np.testing.assert_allclose(ddt, -wx @ d_swapped(a, b, g), atol=1e-8)
        # ... while with D as printed the same rates do not integrate it
        ddt_d = (euler_krylov_matrix(*(np.array([a, b, g]) + h * rates))
                 - euler_krylov_matrix(*(np.array([a, b, g]) - h * rates))) / (2 * h)
        assert np.abs(ddt_d + wx @ euler_krylov_matrix(a, b, g)).max() > 1e-3


# ---------------------------------------------------------------------------- navsim paper 003
def _check_rows(rows, refs):
    exp = [r for r in rows if "values" in r]
    assert {r["ref"] for r in exp} >= refs
    for r in exp:
        vals = np.asarray(r["values"])
        assert r["n_seeds"] == len(vals) >= 2 and np.all(np.isfinite(vals))
        assert r["navsim"] == pytest.approx(np.mean(np.abs(vals)))  # computed from the per-seed values
        assert r["ci95"][0] <= r["navsim"] <= r["ci95"][1] and r["max_abs"] == pytest.approx(np.max(np.abs(vals)))
    # not constants: the seeds differ, the filters differ
    lat = {r["quantity"]: r["values"] for r in exp if r["quantity"].startswith("|latitude")}
    assert all(v[0] != v[1] for v in lat.values())
    assert len({tuple(v) for v in lat.values()}) == len(lat)


def test_experiment_table_one_scenario_short():
    """The experiment machinery on the one-satellite variant, 2 seeds x 60 s (quick)."""
    from navsim.paper import seed003_experiments as sx

    agg = sx.experiment(seeds=[0, 1], quick=True, processes=1, scenarios=["one satellite"])
    rows = sx.experiment_rows(agg, 0.1)
    _check_rows(rows, {"003 one satellite"})
    speed = [r for r in rows if r["ref"] == "003 speed"]
    assert len(speed) == 3 and all(r["navsim"] > 0 for r in speed)
    text = sx.verdicts(agg, 0.1)
    assert len(text) == 3 and all("one satellite" in t for t in text)


@pytest.mark.slow
def test_navsim_paper_003_quick_smoke(capsys):
    """`navsim paper 003 --quick --json`: every experiment row exists with finite, computed values."""
    import json

    from navsim.cli import main

    assert main(["paper", "003", "--quick", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    _check_rows(rows, {"003 observer ablation", "003 full-state filter", "003 one satellite", "003 accelerating",
                       "003 end of outage"})
    det = [r for r in rows if r["ref"] == "003 deterministic check"]
    assert len(det) == 6 and all(abs(r["navsim"]) < 1e-6 for r in det)
    assert sum(r["ref"] == "003 verdict" for r in rows) == 3
