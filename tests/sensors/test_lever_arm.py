"""The GNSS antenna lever arm on the truth side: scenario field, antenna state, simulator.

Checks: (LA.2) of navsim.sensors.gnss.antenna_state is the time derivative of (LA.1)
along true trajectories (finite differences); the simulator's pseudoranges and rates
with a lever arm differ from those without by exactly the range change to the antenna
(same seed, white noise: the noise cancels); a zero lever arm reproduces the measurements
made at the IMU bit for bit; chunk invariance; the scenario field's validation, TOML
round trip and hash.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import sys

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10
    import tomli as tomllib

import numpy as np
import pytest

from navsim.earth import SPHERICAL, WGS84, mat_en
from navsim.episode import make_context
from navsim.errors import ConfigError
from navsim.rotations import mat_nb_from_hpr
from navsim.scenario import _HASH_OMIT_IF_DEFAULT, GnssConfig, Scenario, load_scenario
from navsim.sensors import gnss as gnss_mod
from navsim.simulator import STREAMS, Simulator

ARM = (0.4, 1.5, 3.0)


def _mat_eb(truth):
    return np.swapaxes(mat_en(truth.lat, truth.lon), -1, -2) @ mat_nb_from_hpr(truth.heading, truth.pitch, truth.roll)


def _antenna_position(sim, t, arm):
    tr = sim.truth_at(np.atleast_1d(t))
    return tr.position_e + np.einsum("nij,j->ni", _mat_eb(tr), np.asarray(arm, dtype=float))


# ------------------------------------------------------------------------ antenna_state
@pytest.mark.parametrize("name,t0", [("mountain-railway", 300.0), ("urban-road", 150.0), ("paper-2012", 500.0)])
def test_antenna_velocity_is_the_derivative_of_the_antenna_position(name, t0):
    """(LA.2) against a 4th-order central difference of (LA.1) along the true motion
    (curves, cant, timetable accelerations and the body oscillations of the scenario)."""
    sim = Simulator(load_scenario(name))
    t = t0 + np.arange(5) * 7.3
    truth = sim.truth_at(t)
    pos_a, vel_a = gnss_mod.antenna_state(truth.position_e, truth.velocity_e, _mat_eb(truth), truth.omega_ib_b,
                                          ARM, sim.earth)
    np.testing.assert_allclose(pos_a, _antenna_position(sim, t, ARM), rtol=0, atol=1e-8)
    h = 0.01
    fd = np.array([(-_antenna_position(sim, ti + 2 * h, ARM) + 8 * _antenna_position(sim, ti + h, ARM)
                    - 8 * _antenna_position(sim, ti - h, ARM) + _antenna_position(sim, ti - 2 * h, ARM))[0] / (12 * h)
                   for ti in t])
    np.testing.assert_allclose(vel_a, fd, rtol=0, atol=2e-6)
    # the lever-arm part is really there (at least the Earth-rate term, ~2.5e-4 m/s)
    assert np.max(np.linalg.norm(vel_a - truth.velocity_e, axis=1)) > 1e-4


def test_antenna_state_closed_forms():
    """Level body heading north at the equator, lon 0 (ENU = (y_e, z_e, x_e)): pure yaw
    rate and the Earth rate give the velocity of the antenna by hand."""
    for earth in (WGS84, SPHERICAL):
        r = np.array([earth.a, 0.0, 0.0])
        v = np.array([0.0, 0.0, 20.0])  # north
        mat_eb = mat_en(0.0, 0.0).T  # body = ENU axes (heading north, level)
        omega_ib_b = np.array([0.0, 0.0, 0.1])  # yaw left 0.1 rad/s (inertial)
        lever = np.array([0.0, 2.0, 1.0])  # 2 m forward, 1 m up
        pos, vel = gnss_mod.antenna_state(r, v, mat_eb, omega_ib_b, lever, earth)
        np.testing.assert_allclose(pos, [earth.a + 1.0, 0.0, 2.0], atol=1e-9)
        # omega x l = (0,0,0.1) x (0,2,1) = (-0.2, 0, 0) east -> ECEF -0.2 y_e; Earth rate
        # Omega z_e x (C l = (1, 0, 2) in ECEF) = (0, Omega, 0)
        np.testing.assert_allclose(vel, [0.0, -0.2 - earth.rate, 20.0], atol=1e-15)


def test_zero_lever_arm_is_the_identity():
    rng = np.random.default_rng(1)
    pos, vel = rng.standard_normal((4, 3)) * 6e6, rng.standard_normal((4, 3))
    mat = np.broadcast_to(np.eye(3), (4, 3, 3))
    a, b = gnss_mod.antenna_state(pos, vel, mat, rng.standard_normal((4, 3)), (0.0, 0.0, 0.0))
    assert np.array_equal(a, pos) and np.array_equal(b, vel)


# ------------------------------------------------------------------------ simulator
def _short(name="mountain-railway", arm=None, duration=12.0, preset="paper-2012"):
    over = {"timing": {"duration_s": duration}, "gnss": {"preset": preset}, "outages": {"tunnel_kinds": []}}
    if arm is not None:
        over["gnss"]["lever_arm_m"] = list(arm)
    return load_scenario(name).with_overrides(over)


def test_simulator_measures_at_the_antenna():
    """Same seed, white noise only: the difference of the observables with and without the
    lever arm is the geometric range (rate) change to the antenna, computed here from the
    true attitude by rotation matrices and from finite differences of the antenna track."""
    seed = 5
    sims = {arm: Simulator(_short(arm=arm)) for arm in (None, ARM)}
    chunks = {}
    for arm, sim in sims.items():
        sim.reset(seed)
        chunks[arm] = sim.advance(10_000)
    base, moved = chunks[None], chunks[ARM]
    g0, g1 = base.gnss, moved.gnss
    assert np.array_equal(g0.valid, g1.valid) and g0.valid.sum() > 20
    sim = sims[ARM]
    truth = sim.truth_at(g1.t)
    r_imu = truth.position_e
    r_ant = _antenna_position(sim, g1.t, ARM)
    h = 0.01  # 4th-order central difference (the body oscillations make a 2nd-order one too coarse)
    v_ant = (8 * (_antenna_position(sim, g1.t + h, ARM) - _antenna_position(sim, g1.t - h, ARM))
             - (_antenna_position(sim, g1.t + 2 * h, ARM) - _antenna_position(sim, g1.t - 2 * h, ARM))) / (12 * h)
    for k in range(len(g1.t)):
        ok = g1.valid[k]
        sat = g1.sat_pos_e[k][ok]
        rho0 = np.linalg.norm(sat - r_imu[k], axis=1)
        rho1 = np.linalg.norm(sat - r_ant[k], axis=1)
        np.testing.assert_allclose(g1.pseudorange_m[k][ok] - g0.pseudorange_m[k][ok], rho1 - rho0, rtol=0, atol=1e-6)
        u1 = (sat - r_ant[k]) / rho1[:, None]
        u0 = (sat - r_imu[k]) / rho0[:, None]
        vs = g1.sat_vel_e[k][ok]
        rate_change = np.einsum("mi,mi->m", u1, vs - v_ant[k]) - np.einsum("mi,mi->m", u0, vs - truth.velocity_e[k])
        np.testing.assert_allclose(g1.pseudorange_rate_mps[k][ok] - g0.pseudorange_rate_mps[k][ok], rate_change,
                                   rtol=0, atol=1e-5)
    # the IMU data do not move with the antenna
    assert np.array_equal(base.imu.dtheta_r, moved.imu.dtheta_r)


def test_zero_lever_arm_reproduces_the_measurements_at_the_imu():
    """An explicit [0, 0, 0] builds the epochs from the IMU's position exactly as before
    the lever arm existed: rebuilt here from the chunk's truth with fresh streams."""
    sc = _short(arm=(0.0, 0.0, 0.0), preset="standalone")
    assert sc == _short(preset="standalone") and not sc.gnss.has_lever_arm
    sim = Simulator(sc)
    sim.reset(11)
    chunk = sim.advance(10_000)
    idx = chunk.gnss_step
    rngs = dict(zip(STREAMS, (np.random.Generator(np.random.PCG64(s))
                              for s in np.random.SeedSequence(11).spawn(len(STREAMS)))))
    state = gnss_mod.GnssState.initial(sim.gnss_model, sim.constellation, rngs["gnss"])
    epochs, _ = gnss_mod.simulate_epochs(chunk.t[idx], chunk.truth.position_e[idx], chunk.truth.velocity_e[idx],
                                         sim.constellation, sim.gnss_model, state, rngs["gnss"], sim.earth)
    for f in ("pseudorange_m", "pseudorange_rate_mps", "elevation", "clock_bias_m"):
        assert np.array_equal(getattr(chunk.gnss, f), getattr(epochs, f)), f
    assert np.array_equal(chunk.gnss.valid, epochs.valid)  # no outages in this scenario


def test_chunk_invariance_with_a_lever_arm():
    sc = _short("urban-road", arm=ARM, duration=9.0, preset="standalone")
    a, b = Simulator(sc), Simulator(sc)
    a.reset(2)
    b.reset(2)
    whole = a.advance(900)
    parts = [b.advance(n) for n in (133, 250, 517)]
    for f in ("pseudorange_m", "pseudorange_rate_mps", "valid"):
        assert np.array_equal(getattr(whole.gnss, f), np.concatenate([getattr(p.gnss, f) for p in parts]))


def test_context_tells_the_lever_arm():
    sim = Simulator(_short(arm=ARM, duration=2.0))
    sim.reset(0)
    assert make_context(sim).gnss.lever_arm_b_m == ARM
    sim0 = Simulator(_short(duration=2.0))
    sim0.reset(0)
    assert make_context(sim0).gnss.lever_arm_b_m == (0.0, 0.0, 0.0)


# ------------------------------------------------------------------------ scenario
@pytest.mark.parametrize("bad", [[0.0, 1.0], [0.0, 0.0, 0.0, 0.0], "roof", [0.0, True, 3.0], [0.0, 0.0, 150.0],
                                 [0.0, -101.0, 0.0], [0.0, 0.0, math.inf]])
def test_bad_lever_arms_name_the_field(bad):
    with pytest.raises(ConfigError) as info:
        load_scenario("paper-2012").with_overrides({"gnss": {"lever_arm_m": bad}})
    assert "gnss.lever_arm_m" in str(info.value)
    with pytest.raises(ConfigError, match=r"gnss\.lever_arm_m"):
        GnssConfig(lever_arm_m=bad)


def test_lever_arm_round_trips_and_enters_the_hash():
    sc = load_scenario("mountain-railway")
    moved = sc.with_overrides({"gnss": {"lever_arm_m": [0, 1.5, 3]}})
    assert moved.gnss.lever_arm_m == (0.0, 1.5, 3.0) and moved.gnss.has_lever_arm
    again = Scenario.from_dict(tomllib.loads(moved.to_toml()), base_dir=moved.base_dir)
    assert again == moved and again.config_hash() == moved.config_hash()
    assert moved.config_hash() != sc.config_hash()
    # at the default the field is left out of the hash: the hash of every scenario written
    # before the field existed is unchanged (recomputed here from the definition)
    data = sc.to_dict()
    assert data["gnss"]["lever_arm_m"] == [0.0, 0.0, 0.0]
    del data["gnss"]["lever_arm_m"]
    for section, name, default in _HASH_OMIT_IF_DEFAULT:  # later fields left out the same way
        if data.get(section, {}).get(name) == default:
            del data[section][name]
    blob = json.dumps(data, sort_keys=True, separators=(",", ":"), default=str)
    assert sc.config_hash() == hashlib.sha256(blob.encode()).hexdigest()[:16]
    assert dataclasses.replace(sc.gnss, lever_arm_m=(0.0, 0.0, 0.0)) == sc.gnss


def test_simulator_batch_member_equals_the_single_simulator_with_a_lever_arm():
    from navsim.simulator import SimulatorBatch

    sc = _short("urban-road", arm=ARM, duration=4.0, preset="standalone")
    batch = SimulatorBatch(sc, 2)
    batch.reset([3, 4])
    chunk = batch.advance(400)
    single = Simulator(sc)
    single.reset(4)
    alone = single.advance(400)
    for f in ("pseudorange_m", "pseudorange_rate_mps", "valid"):
        assert np.array_equal(getattr(chunk.member(1).gnss, f), getattr(alone.gnss, f))


def test_nominal_specification_takes_the_lever_arm_as_three_numbers():
    """The nominal GNSS specification carries the surveyed lever arm as 3 floats; any other
    length is refused by name (it used to become a tuple of the wrong length)."""
    model = gnss_mod.GnssErrorModel()
    assert model.nominal(ARM).lever_arm_b_m == tuple(float(x) for x in ARM)
    assert model.nominal(np.array(ARM)).lever_arm_b_m == tuple(float(x) for x in ARM)
    for bad in ((1.0, 2.0), (1.0, 2.0, 3.0, 4.0), ()):
        with pytest.raises(ConfigError, match="lever_arm_b_m"):
            model.nominal(bad)
