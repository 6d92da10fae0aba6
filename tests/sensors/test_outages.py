"""Tests of navsim.sensors.outages: windows, segments, canyon geometry, Markov statistics."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from navsim.errors import ConfigError
from navsim.sensors import gnss as g
from navsim.sensors import outages as o


@dataclass(frozen=True)
class Segment:
    """Duck-typed stand-in for navsim.track.TrackSegment."""

    kind: str
    s_start: float
    s_end: float
    name: str = ""


def _run(model, t, s=None, heading=None, elevation=None, azimuth=None, segments=(), seed=0, prn=None):
    k = len(t)
    if elevation is None:
        elevation = np.full((k, 4), np.radians(45.0))
        azimuth = np.tile(np.radians([0.0, 90.0, 180.0, 270.0]), (k, 1))
    s = np.zeros(k) if s is None else s
    heading = np.zeros(k) if heading is None else heading
    rng = np.random.default_rng(seed)
    state = o.OutageState.initial(model, elevation.shape[1], rng)
    return o.visibility(t, s, heading, elevation, azimuth, segments, model, state, rng, prn=prn)


def test_paper_window_is_exact():
    t = np.arange(0.0, 1000.0, 0.01)  # the paper's step
    visible, outage, _ = _run(o.OutageModel.preset("paper-2012"), t)
    expected = (t >= 400.0) & (t < 700.0)
    np.testing.assert_array_equal(outage, expected)
    np.testing.assert_array_equal(visible, ~expected[:, None] & np.ones((1, 4), bool))
    assert outage.sum() == 30_000  # 300 s at 0.01 s


def test_tunnel_removes_every_satellite_inside_only():
    t = np.arange(0.0, 100.0)
    s = 20.0 * t  # 0 .. 1980 m
    segments = [Segment("tunnel", 400.0, 700.0, "T1"), Segment("bridge", 800.0, 900.0, "B")]
    visible, outage, _ = _run(o.OutageModel(), t, s=s, segments=segments)
    inside = (s >= 400.0) & (s < 700.0)
    np.testing.assert_array_equal(outage, inside)
    assert not visible[inside].any()
    assert visible[~inside].all()
    # arc-length windows without a segment do the same
    visible2, outage2, _ = _run(o.OutageModel(arc_windows_m=((400.0, 700.0),)), t, s=s)
    np.testing.assert_array_equal(outage2, inside)
    np.testing.assert_array_equal(visible2, visible)


def test_urban_canyon_matches_ray_wall_geometry():
    rng = np.random.default_rng(4)
    k, m = 200, 30
    t = np.arange(k, dtype=float)
    s = np.full(k, 50.0)
    heading = rng.uniform(0.0, 2.0 * np.pi, k)
    elevation = np.arcsin(rng.uniform(0.0, 1.0, (k, m)))
    azimuth = rng.uniform(0.0, 2.0 * np.pi, (k, m))
    cross_deg = 60.0
    model = o.OutageModel(canyon_masks_deg=(("urban", cross_deg),))
    visible, outage, _ = _run(
        model, t, s=s, heading=heading, elevation=elevation, azimuth=azimuth,
        segments=[Segment("urban", 0.0, 100.0)],
    )
    assert not outage.any()
    # independent truth: walls at lateral distance w, height w tan(E_cross); a ray reaches
    # the wall plane at horizontal distance w / |sin(az - heading)|, at height d tan(E)
    w = 10.0
    wall = w * np.tan(np.radians(cross_deg))
    across = np.abs(np.sin(azimuth - heading[:, None]))
    with np.errstate(divide="ignore"):
        distance = np.where(across > 0, w / across, np.inf)
        ray_height = distance * np.tan(elevation)
    clear = ray_height >= wall
    np.testing.assert_array_equal(visible, clear)
    assert 0.2 < visible.mean() < 0.8


def test_urban_canyon_cases_across_and_along_the_street():
    heading = np.radians(30.0)  # street runs 30 deg east of north
    az = np.radians([30.0 + 90.0, 30.0 + 90.0, 30.0, 210.0, 30.0 + 45.0, 30.0 + 45.0])
    el = np.radians([20.0, 70.0, 5.0, 5.0, 45.0, 55.0])
    model = o.OutageModel(canyon_masks_deg=(("urban", 60.0),))
    t = np.array([0.0, 1.0])
    s = np.array([10.0, 200.0])  # in the canyon, then past it
    visible, _, _ = _run(
        model, t, s=s, heading=np.full(2, heading), elevation=np.tile(el, (2, 1)),
        azimuth=np.tile(az, (2, 1)), segments=[Segment("urban", 0.0, 100.0)],
    )
    # across: low blocked, high kept; along the street: kept even at 5 deg;
    # 45 deg off the street the mask is atan(tan 60 sin 45) = 50.77 deg
    np.testing.assert_array_equal(visible[0], [False, True, True, True, False, True])
    assert visible[1].all()
    assert np.degrees(o.canyon_mask_elevation(np.radians(45.0), np.radians(60.0))) == pytest.approx(
        np.degrees(np.arctan(np.sqrt(3.0) / np.sqrt(2.0)))
    )


def test_sky_mask_sector_and_masked_prns():
    model = o.OutageModel(sky_mask_deg=((150.0, 210.0, 40.0), (350.0, 10.0, 20.0)), masked_prns=(7,))
    az = np.radians([[180.0, 180.0, 90.0, 0.0, 355.0, 90.0]])
    el = np.radians([[30.0, 50.0, 10.0, 15.0, 25.0, 60.0]])
    prn = np.array([1, 2, 3, 4, 5, 7])
    visible, _, _ = _run(model, np.array([0.0]), elevation=el, azimuth=az, prn=prn)
    np.testing.assert_array_equal(visible[0], [False, True, True, False, True, False])
    with pytest.raises(ConfigError, match="prn"):
        _run(model, np.array([0.0]), elevation=el, azimuth=az)


def _runs(flags: np.ndarray, value: bool) -> np.ndarray:
    """Lengths of the complete runs of ``value`` (the first and last runs are dropped)."""
    change = np.flatnonzero(np.diff(flags.astype(int))) + 1
    bounds = np.concatenate([[0], change, [flags.size]])
    lengths = np.diff(bounds)
    kinds = flags[bounds[:-1]]
    inner = slice(1, -1)
    return lengths[inner][kinds[inner] == value]


@pytest.mark.parametrize("dt", [1.0, 0.5])
def test_markov_mean_durations(dt):
    mean_out, mean_avail = 20.0, 60.0
    model = o.OutageModel(
        receiver_mean_outage_s=mean_out, receiver_mean_available_s=mean_avail,
        satellite_mean_outage_s=5.0, satellite_mean_available_s=15.0,
    )
    n = 60_000
    t = np.arange(n) * dt
    _, outage, _ = _run(model, t, seed=9)
    elevation = np.full((n, 4), np.radians(45.0))
    for value, mean in ((True, mean_out), (False, mean_avail)):
        lengths = _runs(outage, value) * dt
        # geometric run lengths: p = dt/mean, sd = dt sqrt(1 - p)/p
        p = dt / mean
        sd = dt * np.sqrt(1.0 - p) / p
        se = sd / np.sqrt(lengths.size)
        assert lengths.size > 300
        assert abs(lengths.mean() - mean) < 4.5 * se, (value, lengths.mean(), mean, se)
    # stationary fraction out: mean_out / (mean_out + mean_avail), loose bound (correlated)
    assert abs(outage.mean() - 0.25) < 0.03
    # per-satellite chains: satellites out ~ 5/(5+15) of the time outside receiver outages
    visible, _, _ = _run(model, t, seed=9, elevation=elevation, azimuth=np.zeros((n, 4)))
    sat_out = ~visible[~outage]
    assert abs(sat_out.mean() - 0.25) < 0.03
    lengths = _runs(~visible[:, 0] | outage, True)
    assert lengths.size > 300


def test_chunk_invariance():
    model = o.OutageModel(
        windows_s=((30.0, 40.0),), receiver_mean_outage_s=5.0, receiver_mean_available_s=10.0,
        satellite_mean_outage_s=3.0, satellite_mean_available_s=6.0,
        canyon_masks_deg=(("urban", 45.0),),
    )
    rng = np.random.default_rng(1)
    k, m = 200, 6
    t = np.arange(k) * 0.5
    s = 10.0 * t
    heading = np.linspace(0.0, 3.0, k)
    el = rng.uniform(0.0, 1.5, (k, m))
    az = rng.uniform(0.0, 6.28, (k, m))
    segs = [Segment("urban", 100.0, 600.0), Segment("tunnel", 800.0, 850.0)]

    def fresh():
        r = np.random.default_rng(77)
        return r, o.OutageState.initial(model, m, r)

    r, st = fresh()
    vis_all, out_all, end_all = o.visibility(t, s, heading, el, az, segs, model, st, r)
    r, st = fresh()
    pieces = []
    for sl in (slice(0, 70), slice(70, 71), slice(71, k)):
        vis, out, st = o.visibility(t[sl], s[sl], heading[sl], el[sl], az[sl], segs, model, st, r)
        pieces.append((vis, out))
    np.testing.assert_array_equal(np.concatenate([p[0] for p in pieces]), vis_all)
    np.testing.assert_array_equal(np.concatenate([p[1] for p in pieces]), out_all)
    assert st.receiver_out == end_all.receiver_out
    np.testing.assert_array_equal(st.satellite_out, end_all.satellite_out)
    assert 0 < vis_all.sum() < vis_all.size


def test_switching_outages_off_leaves_gnss_draws_unchanged():
    c = g.walker_constellation("gps")
    model = g.GnssErrorModel.preset("standalone")
    t = np.arange(0.0, 120.0)
    p0 = np.array([4_400_000.0, 3_600_000.0, 3_300_000.0])
    v = np.array([10.0, -5.0, 3.0])
    pos, vel = p0 + t[:, None] * v, np.tile(v, (t.size, 1))
    geometry = g.sky_geometry(t, pos, c)
    outages = o.OutageModel(
        windows_s=((40.0, 60.0),), satellite_mean_outage_s=5.0, satellite_mean_available_s=10.0
    )
    out_rng = np.random.default_rng(2)
    visible, _, _ = o.visibility(
        t, 5.0 * t, np.zeros(t.size), geometry.elevation, geometry.azimuth, [], outages,
        o.OutageState.initial(outages, c.n_satellites, out_rng), out_rng,
    )
    results = []
    for vis in (None, visible):
        rng = np.random.default_rng(3)
        state = g.GnssState.initial(model, c, rng)
        epochs, end = g.simulate_epochs(t, pos, vel, c, model, state, rng, visible=vis, geometry=geometry)
        results.append((epochs, end))
    (free, end_free), (blocked, end_blocked) = results
    both = free.valid & blocked.valid
    assert both.sum() > 300 and (free.valid & ~blocked.valid).sum() > 100
    np.testing.assert_array_equal(free.pseudorange_m[both], blocked.pseudorange_m[both])
    np.testing.assert_array_equal(free.pseudorange_rate_mps[both], blocked.pseudorange_rate_mps[both])
    np.testing.assert_array_equal(free.clock_bias_m, blocked.clock_bias_m)
    np.testing.assert_array_equal(end_free.multipath, end_blocked.multipath)
    assert not blocked.valid[40:60].any()


def test_model_validation_names_the_field():
    with pytest.raises(ConfigError, match="outages.windows_s"):
        o.OutageModel(windows_s=((700.0, 400.0),))
    with pytest.raises(ConfigError, match="outages.receiver_mean_outage_s"):
        o.OutageModel(receiver_mean_outage_s=5.0)
    with pytest.raises(ConfigError, match="outages.canyon_masks_deg"):
        o.OutageModel(canyon_masks_deg=(("urban", 95.0),))
    with pytest.raises(ConfigError, match="outages.preset"):
        o.OutageModel.preset("sometimes")
    model = o.OutageModel()
    rng = np.random.default_rng(0)
    state = o.OutageState.initial(model, 2, rng)
    _, _, state = o.visibility([1.0], [0.0], [0.0], np.zeros((1, 2)), np.zeros((1, 2)), [], model, state, rng)
    with pytest.raises(ConfigError, match="increasing"):
        o.visibility([1.0], [0.0], [0.0], np.zeros((1, 2)), np.zeros((1, 2)), [], model, state, rng)


@pytest.mark.parametrize("first", [True, False])
def test_vectorised_chain_equals_epoch_loop(first):
    rng = np.random.default_rng(12)
    k, n = 500, 5
    u = rng.random((k, n))
    dt = rng.uniform(0.1, 3.0, k)
    initial = rng.random(n) < 0.5
    mean_out, mean_avail = 4.0, 7.0
    states, last = o._markov(u, dt, initial, mean_out, mean_avail, first)
    # reference: the chain stepped epoch by epoch
    current = initial.copy()
    expected = np.zeros((k, n), dtype=bool)
    for j in range(k):
        if not (first and j == 0):
            p_recover = min(1.0, dt[j] / mean_out)
            p_fail = min(1.0, dt[j] / mean_avail)
            current = np.array(
                [(u[j, i] >= p_recover) if current[i] else (u[j, i] < p_fail) for i in range(n)]
            )
        expected[j] = current
    np.testing.assert_array_equal(states, expected)
    np.testing.assert_array_equal(last, expected[-1])
