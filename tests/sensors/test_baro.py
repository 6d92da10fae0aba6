"""Barometric altimeter (navsim.sensors.baro): the standard atmosphere against its published
table, the error statistics against their closed forms, chunk invariance, and the
simulator wiring (its own stream appended last: every other stream unchanged)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navsim.errors import ConfigError
from navsim.scenario import load_scenario
from navsim.sensors.baro import (
    BaroConfig,
    BaroModel,
    BaroState,
    pressure_altitude,
    pressure_at,
    pressure_gradient,
    simulate_baro,
    simulate_baro_batch,
)
from navsim.simulator import Simulator, SimulatorBatch


def test_standard_atmosphere_table():
    # U.S. Standard Atmosphere 1976, table I by geometric altitude Z (printed to 5 digits):
    # 1 km 8.9876e4 Pa, 5 km 5.4048e4 Pa, 11 km 2.2700e4 Pa. (BA.1) is in geopotential
    # height H = r0 Z / (r0 + Z), r0 = 6356766 m (its eq. (18)).
    z = np.array([0.0, 1000.0, 5000.0, 11000.0])
    h = 6356766.0 * z / (6356766.0 + z)
    printed = np.array([101325.0, 8.9876e4, 5.4048e4, 2.2700e4])
    np.testing.assert_allclose(pressure_at(h), printed, rtol=6e-5)  # about half a unit of the 5th digit


def test_pressure_altitude_inverts_pressure():
    h = np.linspace(-500.0, 9000.0, 97)
    # the two power laws are inverses; the error is rounding, ~1e-12 of T0/L = 44 km
    np.testing.assert_allclose(pressure_altitude(pressure_at(h)), h, rtol=0, atol=1e-8)


def test_pressure_gradient_is_the_hydrostatic_derivative():
    h = np.array([0.0, 300.0, 2500.0])
    step = 1e-2
    fd = (pressure_at(h + step) - pressure_at(h - step)) / (2 * step)
    # central difference error ~ step^2 P''' / 6 ~ 1e-9 Pa/m; rounding ~ 1e-16 * 1e5 / 1e-2 = 1e-9
    np.testing.assert_allclose(pressure_gradient(h), fd, rtol=0, atol=1e-6)
    assert pressure_gradient(0.0) == pytest.approx(-1.2250 * 9.80665, rel=1e-4)  # rho0 = 1.2250 kg/m^3


def _draw(model, members=4000, n=16, dt=0.1, seed=1, h=100.0):
    rngs = [np.random.default_rng(seed)] * members  # one generator: consecutive independent blocks
    states = [BaroState.initial(model, r) for r in rngs]
    out, _ = simulate_baro_batch(np.full(n, h), model, states, rngs, dt=dt)
    return out


def test_bias_is_a_stationary_gauss_markov_process():
    sigma, tau, dt = 10.0, 1.0, 0.1
    model = BaroModel(bias_sigma_pa=sigma, bias_tau_s=tau)
    out = _draw(model, n=16, dt=dt)  # n <= 16: the plain recursion (no scipy.signal import)
    B = out.bias_pa.shape[0]
    # noise and rounding off: the reading is the true pressure plus the bias
    np.testing.assert_allclose(out.pressure_pa - pressure_at(100.0), out.bias_pa, rtol=0, atol=1e-9)
    k0 = 1
    for lag in (0, 1, 5, 10, 14):
        prod = out.bias_pa[:, k0] * out.bias_pa[:, k0 + lag]
        expected = sigma**2 * math.exp(-lag * dt / tau)  # E[b_k b_k+j] = sigma^2 phi^j (BA.2)
        rho = math.exp(-lag * dt / tau)
        se = sigma**2 * math.sqrt((1.0 + rho**2) / B)  # sd of a product of two correlated normals / sqrt(B)
        assert abs(prod.mean() - expected) < 5 * se, (lag, prod.mean(), expected)


def test_white_noise_variance_and_independence():
    sigma = 2.0
    out = _draw(BaroModel(noise_sigma_pa=sigma), members=2000, n=20)
    e = out.pressure_pa - pressure_at(100.0)
    n = e.size
    var = float(np.mean(e**2))
    # n var / sigma^2 ~ chi2(n): sd of var / sigma^2 is sqrt(2 / n)
    assert abs(var / sigma**2 - 1.0) < 5 * math.sqrt(2.0 / n)
    lag1 = float(np.mean(e[:, 1:] * e[:, :-1])) / sigma**2
    assert abs(lag1) < 5 / math.sqrt(e[:, 1:].size)
    # in altitude: the pressure noise over |dP/dh| (first order; the curvature adds ~1e-6 m)
    alt = out.altitude_m - 100.0
    assert float(np.std(alt)) == pytest.approx(sigma / abs(float(pressure_gradient(100.0))), rel=0.02)


def test_quantisation_step_and_uniform_error():
    q, sigma = 0.5, 2.0
    rounded = _draw(BaroModel(noise_sigma_pa=sigma, resolution_pa=q), members=2000, n=20, seed=7)
    raw = _draw(BaroModel(noise_sigma_pa=sigma), members=2000, n=20, seed=7)  # the same draws, unrounded
    steps = rounded.pressure_pa / q
    np.testing.assert_allclose(steps, np.rint(steps), rtol=0, atol=1e-6)  # whole multiples of q
    err = rounded.pressure_pa - raw.pressure_pa
    assert np.max(np.abs(err)) <= q / 2 + 1e-9
    n = err.size
    # uniform on [-q/2, q/2]: mean 0, variance q^2 / 12, sd of the sample variance q^2 sqrt(1/180 / n)
    assert abs(float(err.mean())) < 5 * q / math.sqrt(12 * n)
    assert abs(float(np.mean(err**2)) - q**2 / 12) < 5 * q**2 * math.sqrt(1.0 / 180.0 / n)


def test_chunk_invariance_and_batch_members():
    model = BaroModel.preset("bmp280")
    h = np.linspace(50.0, 80.0, 57)
    whole, s_whole = simulate_baro(h, model, BaroState.initial(model, np.random.default_rng(3)),
                                   np.random.default_rng(4), dt=0.01)
    rng0, rng = np.random.default_rng(3), np.random.default_rng(4)
    state = BaroState.initial(model, rng0)
    parts = []
    for a, b in ((0, 20), (20, 21), (21, 57)):  # a long call (lfilter) and short ones (plain loop)
        out, state = simulate_baro(h[a:b], model, state, rng, dt=0.01)
        parts.append(out.altitude_m)
    np.testing.assert_array_equal(np.concatenate(parts), whole.altitude_m)
    assert state == s_whole
    rngs = [np.random.default_rng(10 + j) for j in range(3)]
    states = [BaroState.initial(model, r) for r in rngs]
    batch, _ = simulate_baro_batch(h, model, states, rngs, dt=0.01)
    rngs = [np.random.default_rng(10 + j) for j in range(3)]
    for j in range(3):
        single, _ = simulate_baro(h, model, BaroState.initial(model, rngs[j]), rngs[j], dt=0.01)
        np.testing.assert_array_equal(batch.altitude_m[j], single.altitude_m)


def test_preset_and_nominal():
    m = BaroModel.preset("bmp280")
    nominal = m.nominal(0.0)
    # the data sheet's figures back in metres: 1.6 cm noise, 12 Pa ~ 1 m, 0.16 Pa ~ 1.3 cm
    assert nominal.noise_sigma_m == pytest.approx(0.016, rel=1e-4)
    assert nominal.bias_sigma_m == pytest.approx(1.0, rel=2e-3)
    assert nominal.resolution_m == pytest.approx(0.16 / 12.013, rel=1e-3)
    assert nominal.bias_tau_s == 600.0
    ideal, _ = simulate_baro([12.0, 13.0], BaroModel.preset("ideal"), BaroState(0, 0.0), np.random.default_rng(0),
                             dt=1.0)
    np.testing.assert_allclose(ideal.altitude_m, [12.0, 13.0], atol=1e-9)
    with pytest.raises(ConfigError):
        BaroModel.preset("nope")
    with pytest.raises(ConfigError):
        BaroModel(noise_sigma_pa=-1.0)
    with pytest.raises(ConfigError):
        BaroConfig(overrides={"bias_tau_s": 0.0})
    with pytest.raises(ConfigError):
        BaroConfig(overrides={"unknown": 1.0})


def _short(**baro):
    over = {"timing": {"duration_s": 3.0}}
    if baro:
        over["baro"] = baro
    return load_scenario("paper-2012").with_overrides(over)


def test_scenario_section_is_left_out_at_its_default():
    plain = load_scenario("paper-2012")
    assert "baro" not in plain.to_dict()
    with_baro = plain.with_overrides({"baro": {"enabled": True}})
    assert with_baro.to_dict()["baro"]["enabled"] is True
    assert with_baro.config_hash() != plain.config_hash()
    assert type(with_baro).from_dict(with_baro.to_dict(), base_dir=with_baro.base_dir) == with_baro


def test_simulator_stream_appended_last_leaves_every_other_number():
    off, on = Simulator(_short()), Simulator(_short(enabled=True))
    s_off, s_on = off.reset(5), on.reset(5)
    np.testing.assert_array_equal(s_off.prior.as_action(), s_on.prior.as_action())
    a, b = off.advance(300), on.advance(300)
    assert a.baro is None and b.baro is not None
    for name in ("dtheta_r", "dv_r", "rate_b", "accel_b"):
        np.testing.assert_array_equal(getattr(a.imu, name), getattr(b.imu, name))
    np.testing.assert_array_equal(a.gnss.pseudorange_m, b.gnss.pseudorange_m)
    np.testing.assert_array_equal(a.gnss.valid, b.gnss.valid)
    # the readings are the truth's height plus about a metre of bias
    assert np.all(np.abs(b.baro.altitude_m - b.truth.h) < 6.0)


def test_simulator_chunking_and_batch_give_the_same_readings():
    sc = _short(enabled=True)
    one = Simulator(sc)
    one.reset(2)
    whole = one.advance(300).baro.altitude_m
    parts = Simulator(sc)
    parts.reset(2)
    pieces = [parts.advance(n).baro.altitude_m for n in (1, 7, 92, 200)]
    np.testing.assert_array_equal(np.concatenate(pieces), whole)
    batch = SimulatorBatch(sc, 2)
    batch.reset([2, 3])
    chunk = batch.advance(300)
    np.testing.assert_array_equal(chunk.member(0).baro.altitude_m, whole)
    assert not np.array_equal(chunk.member(1).baro.altitude_m, whole)
