"""Tests of navsim.sensors.gnss against closed forms, finite differences and statistics."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import stats

from navsim.earth import SPHERICAL, WGS84
from navsim.errors import ConfigError
from navsim.sensors import gnss as g

GM = WGS84.gm


def _test_constellation(raan_rate: float = 0.0) -> g.Constellation:
    """Eccentric orbits of assorted shapes (not a navigation constellation)."""
    return g.Constellation(
        name="test",
        prn=np.arange(1, 6),
        semi_major_axis_m=np.array([26_559_700.0, 25_510_000.0, 42_164_000.0, 7_000_000.0, 26_560_000.0]),
        eccentricity=np.array([0.0, 0.01, 0.2, 0.05, 0.7]),
        inclination_rad=np.radians([55.0, 64.8, 10.0, 98.0, 63.4]),
        raan_rad=np.array([0.3, -2.0, 1.0, 3.0, -0.5]),
        arg_perigee_rad=np.array([0.0, 1.0, -2.0, 0.5, 4.0]),
        mean_anomaly_rad=np.array([0.1, 2.0, -3.0, 5.0, 0.0]),
        raan_rate_rps=np.full(5, raan_rate),
        epoch_offset_s=-1234.0,
    )


def _to_inertial(pos_e, vel_e, t, rate):
    """ECEF -> inertial frame coinciding with ECEF at t = 0 (rotation about z by rate t)."""
    t = np.asarray(t, dtype=float)
    ang = rate * t.reshape(t.shape + (1,) * (pos_e.ndim - 2))
    c, s = np.cos(ang), np.sin(ang)
    vel_rot = vel_e + rate * np.stack([-pos_e[..., 1], pos_e[..., 0], np.zeros_like(pos_e[..., 0])], -1)

    def rot(v):
        return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1], v[..., 2]], -1)

    return rot(pos_e), rot(vel_rot)


def _receiver(lat_deg=47.2, lon_deg=39.7, h=120.0, earth=WGS84):
    return earth.geodetic_to_ecef(np.radians(lat_deg), np.radians(lon_deg), h)


# ============================================================== orbits
def test_solve_kepler_satisfies_keplers_equation():
    rng = np.random.default_rng(1)
    mean_anomaly = rng.uniform(-30.0, 30.0, 2000)
    ecc = rng.uniform(0.0, 0.95, 2000)
    anomaly = g.solve_kepler(mean_anomaly, ecc)
    assert np.max(np.abs(anomaly - ecc * np.sin(anomaly) - mean_anomaly)) < 1e-12


def test_radius_is_conic_radius():
    c = _test_constellation(raan_rate=-8e-9)
    t = np.linspace(-5000.0, 90_000.0, 97)
    pos, _ = g.satellite_states(c, t, WGS84)
    n = np.sqrt(GM / c.semi_major_axis_m**3)
    anomaly = g.solve_kepler(c.mean_anomaly_rad + n * (t[:, None] - c.epoch_offset_s), c.eccentricity)
    expected = c.semi_major_axis_m * (1.0 - c.eccentricity * np.cos(anomaly))  # r = a (1 - e cos E)
    np.testing.assert_allclose(np.linalg.norm(pos, axis=-1), expected, rtol=1e-13)


def test_orbital_period_in_inertial_frame():
    c = _test_constellation()
    period = 2.0 * np.pi * np.sqrt(c.semi_major_axis_m**3 / GM)
    t0 = 777.0
    for j in range(c.n_satellites):
        times = np.array([t0, t0 + period[j], t0 + period[j] / 4.0])
        pos_e, vel_e = g.satellite_states(c, times, WGS84)
        pos_i, vel_i = _to_inertial(pos_e[:, j], vel_e[:, j], times, WGS84.rate)
        assert np.linalg.norm(pos_i[1] - pos_i[0]) < 1e-4  # m
        assert np.linalg.norm(vel_i[1] - vel_i[0]) < 1e-8  # m/s
        # a quarter period later the satellite is elsewhere (the check above is not vacuous)
        assert np.linalg.norm(pos_i[2] - pos_i[0]) > 0.5 * c.semi_major_axis_m[j] * (1 - c.eccentricity[j])


def test_velocity_matches_finite_differences_of_position():
    c = _test_constellation(raan_rate=-8e-9)
    t = np.linspace(0.0, 40_000.0, 41)
    h = 0.5
    pos_p, _ = g.satellite_states(c, t + h, WGS84)
    pos_m, _ = g.satellite_states(c, t - h, WGS84)
    _, vel = g.satellite_states(c, t, WGS84)
    numeric = (pos_p - pos_m) / (2.0 * h)
    # truncation h^2/6 |jerk| < 1e-3 m/s even for the 7000 km, e = 0.7 orbits
    assert np.max(np.abs(numeric - vel)) < 2e-3
    # GPS-like orbits: tighter
    assert np.max(np.abs(numeric - vel)[:, :2]) < 1e-4
    # the -omega x r term matters: without it the error would be ~ omega r ~ 2 km/s
    omega_cross_r = WGS84.rate * np.linalg.norm(pos_p[:, :2, :2], axis=-1)
    assert np.min(omega_cross_r) > 100.0


def test_inertial_speed_follows_vis_viva():
    c = _test_constellation(raan_rate=0.0)
    t = np.linspace(0.0, 86_400.0, 49)
    pos_e, vel_e = g.satellite_states(c, t, WGS84)
    _, vel_i = _to_inertial(pos_e, vel_e, t, WGS84.rate)
    r = np.linalg.norm(pos_e, axis=-1)
    speed2 = GM * (2.0 / r - 1.0 / c.semi_major_axis_m)  # vis-viva
    np.testing.assert_allclose(np.sum(vel_i**2, axis=-1), speed2, rtol=1e-12)


def _argument_of_latitude_and_node(pos_i, vel_i):
    h = np.cross(pos_i, vel_i)
    inc = np.arccos(h[..., 2] / np.linalg.norm(h, axis=-1))
    node = np.cross([0.0, 0.0, 1.0], h)
    raan = np.arctan2(node[..., 1], node[..., 0])
    node_unit = node / np.linalg.norm(node, axis=-1, keepdims=True)
    h_unit = h / np.linalg.norm(h, axis=-1, keepdims=True)
    u = np.arctan2(np.sum(np.cross(node_unit, pos_i) * h_unit, -1), np.sum(node_unit * pos_i, -1))
    return inc, raan, u


@pytest.mark.parametrize(
    "kind, planes, inc_deg, a, shift_deg",
    [("gps", 6, 55.0, 26_559_700.0, 15.0), ("glonass", 3, 64.8, 25_510_000.0, 15.0)],
)
def test_walker_geometry(kind, planes, inc_deg, a, shift_deg):
    c = g.walker_constellation(kind, node_precession=False)
    assert c.n_satellites == 24
    pos_e, vel_e = g.satellite_states(c, [0.0], WGS84)
    pos_i, vel_i = _to_inertial(pos_e, vel_e, np.array([0.0]), WGS84.rate)
    inc, raan, u = _argument_of_latitude_and_node(pos_i[0], vel_i[0])
    np.testing.assert_allclose(np.degrees(inc), inc_deg, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(pos_e[0], axis=-1), a, rtol=1e-12)
    per_plane = 24 // planes
    raan_deg = np.degrees(raan).reshape(planes, per_plane)
    # each plane's satellites share one node; planes are 360/P apart
    assert np.ptp(np.degrees(np.angle(np.exp(1j * np.radians(raan_deg - raan_deg[:, :1])))), axis=1).max() < 1e-9
    step = np.remainder(np.diff(raan_deg[:, 0]), 360.0)
    np.testing.assert_allclose(step, 360.0 / planes, atol=1e-9)
    # in-plane spacing 360/S and Walker F=1 shift of 360/T per plane
    u_deg = np.degrees(u).reshape(planes, per_plane)
    np.testing.assert_allclose(np.remainder(np.diff(u_deg, axis=1), 360.0), 360.0 / per_plane, atol=1e-9)
    np.testing.assert_allclose(np.remainder(u_deg[1:, 0] - u_deg[:-1, 0], 360.0), shift_deg, atol=1e-9)


def test_walker_phase_rotates_constellation_and_j2_rate():
    base = g.walker_constellation("gps")
    turned = g.walker_constellation("gps", phase_rad=0.4)
    p0, _ = g.satellite_states(base, [100.0])
    p1, _ = g.satellite_states(turned, [100.0])
    c, s = np.cos(0.4), np.sin(0.4)
    rotated = np.stack([c * p0[..., 0] - s * p0[..., 1], s * p0[..., 0] + c * p0[..., 1], p0[..., 2]], -1)
    np.testing.assert_allclose(p1, rotated, atol=1e-6)
    # published GPS almanacs list node rates around -8e-9 rad/s (e.g. -7.8e-9..-8.1e-9)
    assert -8.5e-9 < base.raan_rate_rps[0] < -7.5e-9


def test_constellation_validation_names_the_field():
    with pytest.raises(ConfigError, match="eccentricity"):
        dataclasses.replace(_test_constellation(), eccentricity=np.full(5, 1.2))
    with pytest.raises(ConfigError, match="prn"):
        dataclasses.replace(_test_constellation(), prn=np.array([1, 1, 2, 3, 4]))
    with pytest.raises(ConfigError, match="kind"):
        g.walker_constellation("galileo-ish")


# ============================================================== YUMA
def test_yuma_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    c = g.walker_constellation(
        "gps", eccentricity=rng.uniform(0.001, 0.02, 24), arg_perigee_rad=rng.uniform(-3, 3, 24)
    )
    path = tmp_path / "a.alm"
    g.write_yuma(c, path, week=100, toa_s=319_488.0)
    back = g.load_yuma(path)
    np.testing.assert_array_equal(back.prn, c.prn)
    t = np.linspace(0.0, 86_400.0, 7)
    p0, v0 = g.satellite_states(c, t)
    p1, v1 = g.satellite_states(back, t)
    assert np.max(np.abs(p1 - p0)) < 1.0  # 10 printed digits: sub-metre over a day
    assert np.max(np.abs(v1 - v0)) < 1e-3


def test_yuma_records_with_different_epochs_are_propagated(tmp_path):
    c = g.walker_constellation("gps", eccentricity=0.01, arg_perigee_rad=0.7)
    first, second = c.select(np.arange(12)), c.select(np.arange(12, 24))
    g.write_yuma(first, tmp_path / "a.alm", week=10, toa_s=0.0)
    g.write_yuma(second, tmp_path / "b.alm", week=10, toa_s=7200.0)
    text = (tmp_path / "a.alm").read_text() + "\n" + (tmp_path / "b.alm").read_text()
    (tmp_path / "mixed.alm").write_text(text)
    mixed = g.load_yuma(tmp_path / "mixed.alm", epoch_offset_s=50.0)
    t = np.array([0.0, 5000.0, 20_000.0])
    # the second half's elements hold 7200 s after the first record's epoch (scenario 50 s)
    expected_first, _ = g.satellite_states(first, t - 50.0)
    expected_second, _ = g.satellite_states(second, t - 50.0 - 7200.0)
    got, _ = g.satellite_states(mixed, t)
    assert np.max(np.abs(got[:, :12] - expected_first)) < 1.0
    assert np.max(np.abs(got[:, 12:] - expected_second)) < 1.0


def test_reference_almanac_is_gps_like():
    c = g.reference_almanac()
    assert c.n_satellites == 24
    assert np.all((c.eccentricity > 0.0) & (c.eccentricity < 0.02))
    np.testing.assert_allclose(np.sqrt(c.semi_major_axis_m), np.sqrt(26_559_700.0), atol=1e-5)
    np.testing.assert_allclose(np.degrees(c.inclination_rad), 55.0, atol=1e-7)


@pytest.mark.parametrize(
    "mutate, where",
    [
        (lambda lines: lines.__setitem__(3, "Eccentricity:   abc"), "line 4"),
        (lambda lines: lines.insert(0, "garbage before any header"), "line 1"),
        (lambda lines: lines.__setitem__(7, "Not A Field:  3.0"), "line 8"),
        (lambda lines: lines.pop(8), "record at line 1"),
    ],
)
def test_yuma_malformed_names_the_line(tmp_path, mutate, where):
    path = tmp_path / "ok.alm"
    g.write_yuma(g.walker_constellation("gps"), path)
    lines = path.read_text().splitlines()
    mutate(lines)
    bad = tmp_path / "bad.alm"
    bad.write_text("\n".join(lines))
    with pytest.raises(ConfigError, match=where) as info:
        g.load_yuma(bad)
    assert "bad.alm" in str(info.value)


# ============================================================== line of sight
def test_elevation_azimuth_constructed_directions():
    a = WGS84.a
    receiver = np.array([[a, 0.0, 0.0]])  # lat 0, lon 0: up = +x, east = +y, north = +z
    sats = np.array([[[a + 2e7, 0, 0], [a, 1e7, 0], [a, 0, 1e7], [a + 1e7, 0, -1e7], [a, -1e7, 0]]])
    el, az, rng = g.elevation_azimuth(receiver, sats, WGS84)
    np.testing.assert_allclose(np.degrees(el[0]), [90, 0, 0, 45, 0], atol=1e-9)
    np.testing.assert_allclose(np.degrees(az[0, 1:]), [90, 0, 180, 270], atol=1e-9)
    np.testing.assert_allclose(rng[0], [2e7, 1e7, 1e7, np.sqrt(2) * 1e7, 1e7])


def test_elevation_on_sphere_by_law_of_cosines():
    c = g.walker_constellation("gps")
    receiver = _receiver(earth=SPHERICAL, h=0.0)[None]
    pos, _ = g.satellite_states(c, [0.0, 3000.0], SPHERICAL)
    receiver = np.repeat(receiver, 2, axis=0)
    el, _, _ = g.elevation_azimuth(receiver, pos, SPHERICAL)
    r_rx = np.linalg.norm(receiver, axis=-1)[:, None]
    r_sv = np.linalg.norm(pos, axis=-1)
    gamma = np.arccos(np.einsum("ki,kmi->km", receiver, pos) / (r_rx * r_sv))
    expected = np.arctan2(r_sv * np.cos(gamma) - r_rx, r_sv * np.sin(gamma))
    np.testing.assert_allclose(el, expected, atol=1e-12)


# ============================================================== measurements
def _track(t, earth=WGS84):
    """A receiver moving east-north at ~20 m/s near Rostov (ECEF straight line)."""
    p0 = _receiver(earth=earth)
    v = np.array([-12.0, 15.0, 9.0])
    return p0 + np.asarray(t)[:, None] * v, np.broadcast_to(v, (len(t), 3)).copy()


def _simulate(model, t, seed=0, constellation=None, visible=None, earth=WGS84):
    c = constellation or g.walker_constellation("gps")
    rng = np.random.default_rng(seed)
    state = g.GnssState.initial(model, c, rng)
    pos, vel = _track(t, earth)
    epochs, new = g.simulate_epochs(t, pos, vel, c, model, state, rng, earth, visible=visible)
    return epochs, new, pos, vel


def test_zero_noise_fix_recovers_position_clock_velocity_and_drift():
    model = g.GnssErrorModel(
        pseudorange_sigma_m=0.0,
        doppler_sigma_mps=0.0,
        elevation_mask_deg=5.0,
        clock_enabled=True,
        clock_bias_m=123_456.0,
        clock_drift_mps=-45.0,
        clock_h0=0.0,
        clock_h_2=0.0,
    )
    t = np.arange(0.0, 3600.0, 60.0)
    epochs, _, pos, vel = _simulate(model, t)
    assert np.all(epochs.n_valid >= 5)
    fix = g.least_squares_fix(epochs.sat_pos_e, epochs.pseudorange_m, epochs.valid)
    assert np.all(fix.ok)
    assert np.max(np.linalg.norm(fix.position_e - pos, axis=1)) < 1e-3
    np.testing.assert_allclose(fix.clock_bias_m, epochs.clock_bias_m, atol=1e-3)
    np.testing.assert_allclose(epochs.clock_bias_m, 123_456.0 - 45.0 * t, rtol=1e-12)
    vfix = g.velocity_fix(epochs.sat_pos_e, epochs.sat_vel_e, epochs.pseudorange_rate_mps, epochs.valid, fix.position_e)
    assert np.all(vfix.ok)
    assert np.max(np.abs(vfix.velocity_e - vel)) < 1e-6
    np.testing.assert_allclose(vfix.clock_drift_mps, -45.0, atol=1e-6)
    # single-epoch call gives the same numbers with squeezed shapes
    one = g.least_squares_fix(epochs.sat_pos_e[3], epochs.pseudorange_m[3], epochs.valid[3])
    assert one.position_e.shape == (3,) and one.covariance.shape == (4, 4) and bool(one.ok)
    np.testing.assert_allclose(one.position_e, fix.position_e[3], atol=1e-6)


def test_fix_error_is_consistent_with_covariance_nees():
    model = g.GnssErrorModel.preset("paper-2012")
    t = np.arange(0.0, 6000.0, 10.0)
    epochs, _, pos, vel = _simulate(model, t, seed=11)
    fix = g.least_squares_fix(epochs.sat_pos_e, epochs.pseudorange_m, epochs.valid)
    assert np.all(fix.ok)
    err = np.concatenate([fix.position_e - pos, fix.clock_bias_m[:, None] - 0.0], axis=1)
    cov = fix.covariance * model.pseudorange_sigma_m**2
    nees = np.einsum("ki,kij,kj->k", err, np.linalg.inv(cov), err)
    n = len(t)
    low, high = stats.chi2.ppf([0.0005, 0.9995], 4 * n) / n
    assert low < nees.mean() < high, (low, nees.mean(), high)
    vfix = g.velocity_fix(epochs.sat_pos_e, epochs.sat_vel_e, epochs.pseudorange_rate_mps, epochs.valid, fix.position_e)
    verr = np.concatenate([vfix.velocity_e - vel, vfix.clock_drift_mps[:, None]], axis=1)
    vcov = vfix.covariance * model.doppler_sigma_mps**2
    vnees = np.einsum("ki,kij,kj->k", verr, np.linalg.inv(vcov), verr)
    assert low < vnees.mean() < high, (low, vnees.mean(), high)


def test_doppler_is_time_derivative_of_range():
    model = g.GnssErrorModel.preset("ideal")
    t = np.arange(0.0, 2000.0, 100.0)
    h = 0.05
    mid, _, _, _ = _simulate(model, t)
    plus, _, _, _ = _simulate(model, t + h)
    minus, _, _, _ = _simulate(model, t - h)
    both = mid.valid & plus.valid & minus.valid
    assert both.sum() > 100
    numeric = (plus.pseudorange_m - minus.pseudorange_m) / (2.0 * h)
    err = np.abs(numeric - mid.pseudorange_rate_mps)[both]
    assert err.max() < 1e-4
    assert np.abs(mid.pseudorange_rate_mps[both]).max() > 100.0  # not a trivial zero


def test_elevation_mask_and_invalid_entries():
    model = dataclasses.replace(g.GnssErrorModel.preset("paper-2012"), elevation_mask_deg=20.0)
    t = np.arange(0.0, 7200.0, 300.0)
    epochs, _, pos, _ = _simulate(model, t)
    el, _, _ = g.elevation_azimuth(pos, epochs.sat_pos_e, WGS84)
    np.testing.assert_array_equal(epochs.valid, el >= np.radians(20.0))
    assert (~epochs.valid).sum() > 0 and epochs.valid.sum() > 0
    assert np.all(epochs.pseudorange_m[~epochs.valid] == 0.0)
    assert np.all(epochs.pseudorange_rate_mps[~epochs.valid] == 0.0)


def test_nan_position_and_outage_mask_are_values_not_errors():
    model = g.GnssErrorModel.preset("standalone")
    t = np.arange(0.0, 10.0)
    c = g.walker_constellation("gps")
    rng = np.random.default_rng(5)
    pos, vel = _track(t)
    pos[3] = np.nan
    visible = np.ones((10, 24), dtype=bool)
    visible[6:] = False
    epochs, _ = g.simulate_epochs(t, pos, vel, c, model, g.GnssState.initial(model, c, rng), rng, visible=visible)
    assert not epochs.valid[3].any() and not epochs.valid[6:].any()
    for name in ("pseudorange_m", "pseudorange_rate_mps", "elevation", "azimuth"):
        assert np.all(np.isfinite(getattr(epochs, name)))
    fix = g.least_squares_fix(epochs.sat_pos_e, epochs.pseudorange_m, epochs.valid)
    assert fix.ok[:3].all() and not fix.ok[3] and not fix.ok[6:].any()
    assert np.all(np.isnan(fix.position_e[6:]))
    few = epochs.valid.copy()
    few[0, np.flatnonzero(few[0])[3:]] = False  # 3 satellites only
    fix3 = g.least_squares_fix(epochs.sat_pos_e[:1], epochs.pseudorange_m[:1], few[:1])
    assert fix3.n_used[0] == 3 and not fix3.ok[0]


def test_atmosphere_and_multipath_terms():
    model = g.GnssErrorModel(
        pseudorange_sigma_m=0.0, doppler_sigma_mps=0.0, elevation_mask_deg=0.0,
        ionosphere_zenith_m=5.0, troposphere_zenith_m=2.4,
    )
    # thin shell: factor 1 at zenith, 1/sqrt(1 - (R/(R+350 km))^2) at the horizon
    np.testing.assert_allclose(model.ionosphere_delay_m(np.pi / 2), 5.0)
    np.testing.assert_allclose(
        model.ionosphere_delay_m(0.0), 5.0 / np.sqrt(1.0 - (WGS84.a / (WGS84.a + 350e3)) ** 2)
    )
    np.testing.assert_allclose(model.troposphere_delay_m(np.pi / 2, 0.0), 2.4, rtol=1e-6)
    np.testing.assert_allclose(model.troposphere_delay_m(np.radians(30.0), 0.0), 2.4 * 1.001 / np.sqrt(0.252001))
    t = np.arange(0.0, 600.0, 60.0)
    epochs, _, pos, _ = _simulate(model, t)
    el, _, rng = g.elevation_azimuth(pos, epochs.sat_pos_e, WGS84)
    _, _, height = WGS84.ecef_to_geodetic(pos)
    extra = (epochs.pseudorange_m - rng)[epochs.valid]
    expected = (model.ionosphere_delay_m(el) + model.troposphere_delay_m(el, height[:, None]))[epochs.valid]
    np.testing.assert_allclose(extra, expected, atol=1e-6)
    assert extra.min() > 5.0 + 2.4 * np.exp(-height.max() / 8000.0) - 1e-6
    # multipath sigma falls with elevation
    mp = g.GnssErrorModel(multipath_sigma_m=3.0)
    assert mp.multipath_sigma(0.0) == pytest.approx(3.0)
    assert mp.multipath_sigma(np.radians(10.0)) == pytest.approx(3.0 / np.e)


def test_clock_allan_variance_matches_h_coefficients():
    model = g.GnssErrorModel(
        pseudorange_sigma_m=0.0, doppler_sigma_mps=0.0, clock_enabled=True,
        clock_h0=2e-19, clock_h_2=2e-20,
    )
    c = g.walker_constellation("gps").select([0])
    n, dt = 30_000, 1.0
    t = np.arange(n) * dt
    rng = np.random.default_rng(8)
    state = g.GnssState.initial(model, c, rng)
    epochs, _ = g.simulate_epochs(t, np.full((n, 3), 6.4e6), np.zeros((n, 3)), c, model, state, rng)
    phase_s = epochs.clock_bias_m / g.C_LIGHT
    for m_tau in (1, 10):
        tau = m_tau * dt
        # second differences over non-overlapping windows (spacing 3 tau > 2 tau): independent
        starts = np.arange(0, n - 2 * m_tau, 3 * m_tau)
        second = phase_s[starts + 2 * m_tau] - 2 * phase_s[starts + m_tau] + phase_s[starts]
        estimate = np.mean(second**2) / (2.0 * tau**2)
        truth = model.clock_allan_variance(tau)  # h0/(2 tau) + 2 pi^2 h_-2 tau / 3
        k = starts.size
        low, high = stats.chi2.ppf([0.0005, 0.9995], k) / k * truth
        assert low < estimate < high, (tau, low, estimate, high)
    # drift increments: variance S_g dt (the random-walk part)
    s_f, s_g = model.clock_psd
    inc = np.diff(epochs.clock_drift_mps)
    low, high = stats.chi2.ppf([0.0005, 0.9995], inc.size) / inc.size * s_g * dt
    assert low < np.mean(inc**2) < high


def test_chunk_invariance_with_every_error_on():
    model = g.GnssErrorModel.preset("standalone")
    c = g.walker_constellation("gps")
    t = np.arange(0.0, 60.0)
    pos, vel = _track(t)
    rng = np.random.default_rng(42)
    state = g.GnssState.initial(model, c, rng)
    whole, end_whole = g.simulate_epochs(t, pos, vel, c, model, state, rng)
    rng = np.random.default_rng(42)
    state = g.GnssState.initial(model, c, rng)
    parts = []
    for sl in (slice(0, 25), slice(25, 26), slice(26, 60)):
        part, state = g.simulate_epochs(t[sl], pos[sl], vel[sl], c, model, state, rng)
        parts.append(part)
    joined = g.GnssEpochs.concatenate(parts)
    for name in g.GnssEpochs.__slots__:
        np.testing.assert_array_equal(getattr(joined, name), getattr(whole, name), err_msg=name)
    assert state.clock_bias_m == end_whole.clock_bias_m
    np.testing.assert_array_equal(state.multipath, end_whole.multipath)
    # the errors are really on: bias moves, multipath is not constant
    assert np.std(np.diff(whole.clock_bias_m)) > 0.0


def test_time_must_increase_and_model_validation():
    model = g.GnssErrorModel()
    c = g.walker_constellation("gps")
    rng = np.random.default_rng(0)
    state = g.GnssState.initial(model, c, rng)
    pos, vel = _track(np.arange(3.0))
    _, state = g.simulate_epochs(np.arange(3.0), pos, vel, c, model, state, rng)
    with pytest.raises(ConfigError, match="increasing"):
        g.simulate_epochs(np.array([2.0]), pos[:1], vel[:1], c, model, state, rng)
    with pytest.raises(ConfigError, match="gnss.pseudorange_sigma_m"):
        g.GnssErrorModel(pseudorange_sigma_m=-1.0)
    with pytest.raises(ConfigError, match="gnss.elevation_mask_deg"):
        g.GnssErrorModel(elevation_mask_deg=95.0)
    with pytest.raises(ConfigError, match="gnss.preset"):
        g.GnssErrorModel.preset("nope")
