"""Wheel odometer (navsim.sensors.odometer): closed forms, quantisation carry, slip,
chunk invariance, batch = single."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from navsim.errors import ConfigError
from navsim.sensors import odometer as odo
from navsim.sensors.odometer import OdometerModel, OdometerState, simulate_odometer, simulate_odometer_batch

DT = 0.01


def _run(model, ds, accel, seed=0, chunks=None):
    rng = np.random.default_rng(seed)
    state = OdometerState.initial(model, rng)
    if chunks is None:
        return simulate_odometer(ds, accel, model, state, rng, dt=DT) + (state,)
    outs = []
    i = 0
    for c in chunks:
        out, state = simulate_odometer(ds[i:i + c], accel[i:i + c], model, state, rng, dt=DT)
        outs.append(out)
        i += c
    return outs, state


def test_ideal_is_exact():
    ds = np.linspace(0.0, 0.3, 500)
    out, _, _ = _run(OdometerModel.preset("ideal"), ds, np.zeros_like(ds))
    assert np.array_equal(out.ds_m, ds)
    assert not out.pulses.any()


def test_mean_scale_factor_and_noise_variance_closed_forms():
    """Turn-on scale factor only + white noise: d = ds (1 + c) + q sqrt(dt) z. Over many
    episodes c has sigma_c; within one, the residual d - ds (1 + c) is white with
    variance q^2 dt (chi-square bounds on the sample variance)."""
    q, sigma_c = 0.02, 5e-3
    model = OdometerModel(scale_factor_sigma=sigma_c, noise_density_m_per_sqrt_s=q)
    n = 4000
    ds = np.full(n, 0.2)
    out, state, s0 = _run(model, ds, np.zeros(n), seed=1)
    c = s0.scale_factor_turn_on
    assert np.all(out.scale_factor == c)
    resid = out.ds_m - ds * (1.0 + c)
    var = resid.var(ddof=0) * n / (n - 1)
    lo, hi = chi2.ppf([0.001, 0.999], n - 1) / (n - 1)
    assert lo < var / (q * q * DT) < hi
    assert abs(resid.mean()) < 4 * q * math.sqrt(DT / n)
    # turn-on draw over episodes: sample variance of c inside chi-square bounds
    cs = np.array([OdometerState.initial(model, np.random.default_rng(k)).scale_factor_turn_on for k in range(400)])
    lo, hi = chi2.ppf([0.001, 0.999], 400) / 400
    assert lo < np.mean(cs**2) / sigma_c**2 < hi


def test_gauss_markov_scale_factor_statistics():
    """g stationary with variance sigma_g^2 and lag-one correlation exp(-dt/tau)."""
    sigma_g, tau = 2e-3, 0.5
    model = OdometerModel(scale_factor_gm_sigma=sigma_g, scale_factor_gm_tau_s=tau)
    n = 20000
    out, _, _ = _run(model, np.ones(n), np.zeros(n), seed=3)
    g = out.scale_factor
    phi = math.exp(-DT / tau)
    # innovations g_k+1 - phi g_k are white with variance sigma^2 (1 - phi^2)
    w = (g[1:] - phi * g[:-1]) / (sigma_g * math.sqrt(1 - phi * phi))
    lo, hi = chi2.ppf([0.001, 0.999], n - 1) / (n - 1)
    assert lo < np.mean(w * w) < hi
    assert abs(np.corrcoef(w[1:], w[:-1])[0, 1]) < 4 / math.sqrt(n)


@pytest.mark.parametrize("preset", ["rail-tachometer", "car-wheel-speed"])
def test_quantisation_carry_keeps_running_distance_within_one_pulse(preset):
    """0 <= sum d - sum ds_m < p at every step, with d the unquantised distance (the
    same model without quantiser and the same draws)."""
    model = OdometerModel.preset(preset)
    p = model.pulse_length_m
    rng = np.random.default_rng(7)
    n = 5000
    ds = np.abs(rng.normal(0.15, 0.1, n))
    accel = rng.normal(0.0, 1.0, n)
    out, _, _ = _run(model, ds, accel, seed=11)
    import dataclasses

    raw, _, _ = _run(dataclasses.replace(model, pulses_per_revolution=0), ds, accel, seed=11)
    assert np.all(out.pulses == np.rint(out.ds_m / p))
    gap = np.cumsum(raw.ds_m) - np.cumsum(out.ds_m)
    assert gap.min() >= -1e-9 and gap.max() < p + 1e-9
    assert gap.max() > 0.5 * p  # the carry is used, not trivially zero


def test_slip_only_above_the_threshold():
    model = OdometerModel(slip_fraction=0.03, slide_fraction=0.05, slip_accel_threshold_mps2=0.5)
    accel = np.array([-1.0, -0.5, -0.49, 0.0, 0.49, 0.5, 0.51, 2.0])
    ds = np.full(len(accel), 0.2)
    out, _, _ = _run(model, ds, accel)
    expected = ds * (1.0 + np.array([-0.05, 0, 0, 0, 0, 0, 0.03, 0.03]))
    np.testing.assert_allclose(out.ds_m, expected, rtol=0, atol=1e-15)
    assert np.array_equal(odo.slip_factor(accel, model) != 0, np.abs(accel) > 0.5)


@pytest.mark.parametrize("preset", ["rail-tachometer", "car-wheel-speed"])
def test_chunk_invariance(preset):
    model = OdometerModel.preset(preset)
    rng = np.random.default_rng(5)
    n = 3000
    ds = np.abs(rng.normal(0.2, 0.1, n))
    accel = rng.normal(0.0, 1.5, n)
    whole, end_whole, _ = _run(model, ds, accel, seed=2)
    parts, end_parts = _run(model, ds, accel, seed=2, chunks=[1, 5, 1018, 1, 1024, 700, 251])
    for name in ("ds_m", "pulses", "scale_factor"):
        assert np.array_equal(np.concatenate([getattr(o, name) for o in parts]), getattr(whole, name)), name
    assert end_parts == end_whole


def test_batch_equals_single():
    model = OdometerModel.preset("rail-tachometer")
    rng = np.random.default_rng(9)
    ds = np.abs(rng.normal(0.2, 0.05, 700))
    accel = rng.normal(0.0, 0.6, 700)
    seeds = [4, 5, 6]
    rngs = [np.random.default_rng(s) for s in seeds]
    states = [OdometerState.initial(model, r) for r in rngs]
    batch, new = simulate_odometer_batch(ds, accel, model, states, rngs, dt=DT)
    for j, seed in enumerate(seeds):
        single, s_end, _ = _run(model, ds, accel, seed=seed)
        assert np.array_equal(batch.ds_m[j], single.ds_m)
        assert np.array_equal(batch.pulses[j], single.pulses)
        assert new[j] == s_end


def test_fixed_width_draws_whatever_is_switched_on():
    """Every model consumes the same numbers: the generator ends in the same state."""
    ds = np.full(37, 0.1)
    ends = []
    for model in (OdometerModel(), OdometerModel.preset("car-wheel-speed")):
        rng = np.random.default_rng(0)
        state = OdometerState.initial(model, rng)
        simulate_odometer(ds, np.zeros(37), model, state, rng, dt=DT)
        ends.append(rng.standard_normal())
    assert ends[0] == ends[1]


def test_validation():
    with pytest.raises(ConfigError, match="odometer.pulses_per_revolution"):
        OdometerModel(pulses_per_revolution=-1)
    with pytest.raises(ConfigError, match="odometer.slip_fraction"):
        OdometerModel(slip_fraction=1.5)
    with pytest.raises(ConfigError, match="odometer.wheel_circumference_m"):
        OdometerModel(wheel_circumference_m=0.0)
    with pytest.raises(ConfigError, match="odometer.preset"):
        OdometerModel.preset("bicycle")
    model = OdometerModel()
    rng = np.random.default_rng(0)
    a = OdometerState.initial(model, rng)
    b = OdometerState(3, 0.0, 0.0)
    with pytest.raises(ConfigError, match="lockstep"):
        simulate_odometer_batch(np.ones(2), np.zeros(2), model, [a, b], [rng, rng], dt=DT)
    with pytest.raises(ConfigError, match="accel"):
        simulate_odometer(np.ones(3), np.zeros(2), model, a, rng, dt=DT)
