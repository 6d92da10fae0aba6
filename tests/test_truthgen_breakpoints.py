"""Fast truth generation across the motion's breakpoints (navsim.truthgen).

References are computed here independently of the generator's fast paths: Gauss-Legendre
with many nodes on each smooth piece of a sample and the Cauchy kernel of eq. (1.14) of
seed 000, with the knot crossing times of a constant-speed profile in closed form.
"""

import math

import numpy as np
import pytest

from navsim.earth import WGS84
from navsim.motion import ConstantSpeed, Oscillation, Station, Timetable, TrueState, body_kinematics
from navsim.trackio import load_bundled_track
from navsim.truthgen import TruthGenerator

R = 4


@pytest.fixture(scope="module")
def urban():
    return load_bundled_track("urban-road", earth=WGS84)


@pytest.fixture(scope="module")
def mountain():
    return load_bundled_track("mountain-railway", earth=WGS84)


def window_error(a, b):
    """max |a - b| over samples and axes, per order relative to max |b| over the window."""
    scale = np.abs(b).max(axis=(0, 2), keepdims=True)
    return float(np.max(np.abs(a - b) / scale))


def reference_integrals(track, profile, osc, h, index, cuts, nodes=24):
    """r-fold integrals (1.14) over samples ``index``, piecewise at absolute times ``cuts``.

    I_r = int_{t_k}^{t_k + h} (t_k + h - tau)^(r-1) / (r-1)! g(tau) dtau, by Gauss-Legendre
    with ``nodes`` nodes on every piece between consecutive cuts inside the sample.
    """
    x, w = np.polynomial.legendre.leggauss(nodes)
    out_w, out_f = np.zeros((len(index), R, 3)), np.zeros((len(index), R, 3))
    for n, k in enumerate(index):
        t0 = k * h
        # pieces in time from the sample start (the kernel needs h - tau to full precision)
        inner = [c - t0 for c in cuts if t0 < c < t0 + h]
        edges = [0.0] + inner + [h]
        for a, b in zip(edges[:-1], edges[1:]):
            tau = 0.5 * (a + b) + 0.5 * (b - a) * x
            omega, force = body_kinematics(track, profile, t0 + tau, osc)
            for r in range(1, R + 1):
                kern = 0.5 * (b - a) * w * (h - tau) ** (r - 1) / math.factorial(r - 1)
                out_w[n, r - 1] += kern @ omega
                out_f[n, r - 1] += kern @ force
    return out_w, out_f


# ------------------------------------------------------------------ accessors
def test_timetable_breakpoints_are_where_the_snap_jumps():
    tt = Timetable((Station(0.0, 3.0), Station(400.0, 2.0)), cruise_speed=12.0, max_accel=1.0,
                   max_decel=1.2, jerk_time=1.5)
    bp = tt.breakpoints
    assert np.all(np.diff(bp) > 0) and bp[0] == pytest.approx(3.0)
    # snap (d^2 a / dt^2) by second differences just left and right of each breakpoint:
    # a raised-cosine ramp of step c starts and ends with snap +-(pi^2 / 2) c / T^2
    d = 1e-3
    def snap(t):
        return (tt.evaluate(t + d)[2] - 2 * tt.evaluate(t)[2] + tt.evaluate(t - d)[2]) / d**2
    jump = snap(bp + 2 * d) - snap(bp - 2 * d)
    assert np.all(np.abs(jump) > 0.5 * (np.pi**2 / 2) * 1.0 / 1.5**2 * 0.9)
    # and between breakpoints the snap is continuous: over the same 4 ms it changes by
    # at most (pi^3 / 2) c / T^3 * 4 ms = 0.02 m/s^4
    mid = 0.5 * (bp[:-1] + bp[1:])
    assert np.all(np.abs(snap(mid + 2 * d) - snap(mid - 2 * d)) < 0.03)
    assert ConstantSpeed(3.0).breakpoints.size == 0


def test_spline_knot_positions_map_the_spline_knots(urban):
    ks = urban.knot_s
    assert ks.size > 100 and np.all(np.diff(ks) > 0) and 0 < ks[0] and ks[-1] < urban.length
    t = np.unique(urban._spline.t)
    inner = t[(t > urban.waypoint_u[0]) & (t < urban.waypoint_u[-1])]
    assert inner.size == ks.size
    # the geodetic position at knot_s is the spline evaluated at the knot parameter
    pos = urban.geodetic(ks[::50])[0]
    direct = urban._curve(inner[::50], 0)[0]
    np.testing.assert_allclose(pos, direct, rtol=0, atol=1e-12)


def test_knot_crossing_times_of_a_constant_speed_profile(urban):
    v, s0 = 13.0, 200.0
    gen = TruthGenerator(urban, ConstantSpeed(v, s0), (), 0.01, R, 4, 20.0)
    ks = urban.knot_s
    expected = (ks[(ks > s0) & (ks < s0 + v * 22.0)] - s0) / v  # t_lim covers 2 blocks past t_end
    got = gen.breakpoints * 0.01
    assert got.size == expected.size
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-11)


# ------------------------------------------------------------------ accuracy
def test_fits_match_high_order_quadrature_away_from_breakpoints(urban, mountain):
    cases = [
        (urban, Timetable((Station(50.0, 3.0), Station(600.0, 3.0)), cruise_speed=14.0, max_accel=2.0,
                          max_decel=2.5, jerk_time=1.0), (), 0.01, 30.0),
        (mountain, ConstantSpeed(22.0, s0=2000.0),
         (Oscillation("roll", 0.01, 1.3), Oscillation("pitch", 0.004, 0.8, 0.3)), 0.005, 12.0),
    ]
    for track, profile, osc, h, t_end in cases:
        fast_gen = TruthGenerator(track, profile, osc, h, R, 4, t_end)
        ref_gen = TruthGenerator(track, profile, osc, h, R, 12, t_end, block_s=0.0)  # direct only
        n = int(round(t_end / h))
        fast = fast_gen.samples(0, n)
        index = np.arange(n)
        a, b = fast_gen._inside(index, index + 1)
        away = b == a
        # the fast path does the work: most samples come from a Chebyshev fit
        assert fast.used_block.mean() > 0.9
        assert fast_gen.breakpoints.size > 10
        ref = ref_gen._direct(index[away])
        assert window_error(fast.dtheta_r[away], ref.dtheta_r) < 1e-12
        assert window_error(fast.dv_r[away], ref.dv_r) < 1e-12
        np.testing.assert_allclose(fast.truth.position_e[away], ref.truth.position_e, rtol=1e-14, atol=0)
        np.testing.assert_allclose(fast.truth.mat_nb[away], ref.truth.mat_nb, rtol=0, atol=1e-13)
        assert window_error(fast.omega_end[away][:, None], ref.omega_end[:, None]) < 1e-12
        assert window_error(fast.force_end[away][:, None], ref.force_end[:, None]) < 1e-12


def test_straddling_samples_are_integrated_exactly(urban):
    v, s0, h, t_end = 13.0, 200.0, 0.01, 8.0
    profile = ConstantSpeed(v, s0)
    gen = TruthGenerator(urban, profile, (), h, R, 4, t_end)
    n = int(round(t_end / h))
    fast = gen.samples(0, n)
    ks = urban.knot_s
    cuts = ((ks - s0) / v)[(ks > s0) & (ks < s0 + v * t_end)]  # closed-form crossing times
    frac = cuts / h - np.floor(cuts / h)
    inside = (frac > 1e-6) & (frac < 1 - 1e-6)  # not on a sample boundary
    straddle = np.unique(np.floor(cuts[inside] / h).astype(int))
    assert straddle.size > 20
    assert not fast.used_block[straddle].any()
    ref_w, ref_f = reference_integrals(urban, profile, (), h, straddle, cuts)
    err_w = window_error(fast.dtheta_r[straddle], ref_w)
    err_f = window_error(fast.dv_r[straddle], ref_f)
    assert err_w < 1e-12 and err_f < 1e-12
    # the previous behaviour (Gauss-Legendre across the kink) is first-order wrong there
    old = TruthGenerator(urban, profile, (), h, R, 4, t_end, split_at_breakpoints=False)._direct(straddle)
    assert window_error(old.dtheta_r, ref_w) > 100 * max(err_w, 1e-14)


# ------------------------------------------------------------------ chunking
def test_chunk_invariance_across_blocks_and_knots(urban):
    profile = Timetable((Station(50.0, 1.0), Station(400.0, 2.0)), cruise_speed=14.0, max_accel=2.0,
                        max_decel=2.5, jerk_time=1.0)
    h, t_end = 0.01, 12.0
    n = int(round(t_end / h))

    def make():
        return TruthGenerator(urban, profile, (), h, R, 4, t_end)

    whole = make().samples(0, n)
    gen = make()
    sizes = [1, 37, 62, 113, 7, 250, 99, 2, 201, 128, 100]
    parts, i0 = [], 0
    for size in sizes:
        size = min(size, n - i0)
        parts.append(gen.samples(i0, size))
        i0 += size
    parts.append(gen.samples(i0, n - i0))
    assert gen.breakpoints.size > 20  # knots and ramp ends inside the chunks
    for f in ("dtheta_r", "dv_r", "omega_end", "force_end", "used_block"):
        assert np.array_equal(np.concatenate([getattr(p, f) for p in parts]), getattr(whole, f)), f
    for f in TrueState.__dataclass_fields__:
        assert np.array_equal(np.concatenate([getattr(p.truth, f) for p in parts]), getattr(whole.truth, f)), f
    # a range starting in the middle, from a fresh generator, is the same too
    mid = make().samples(333, 404)
    assert np.array_equal(mid.dtheta_r, whole.dtheta_r[333:737])
    assert np.array_equal(mid.truth.position_e, whole.truth.position_e[333:737])


def test_mixed_blocks_and_breakpoints_on_sample_boundaries(mountain):
    """Slow running over 10-30 m knots leaves some 1-s blocks without a knot (plain fits
    between split ones, in one call); a timetable whose dwell ends on a sample boundary
    inside a block splits runs there without a straddling sample."""
    h, t_end = 0.005, 8.0
    n = int(round(t_end / h))
    cases = [ConstantSpeed(7.0, s0=2000.0),
             Timetable((Station(2000.0, 1.5), Station(2400.0, 1.0)), cruise_speed=10.0, max_accel=1.0,
                       max_decel=1.0, jerk_time=2.0)]
    for profile in cases:
        gen = TruthGenerator(mountain, profile, (), h, R, 4, t_end)
        fast = gen.samples(0, n)
        b = gen.block
        ks = np.arange(n // b)
        lo, hi = gen._inside(ks * b, (ks + 1) * b)
        cut = hi > lo
        ref = TruthGenerator(mountain, profile, (), h, R, 12, t_end, block_s=0.0)._direct(np.arange(n))
        assert window_error(fast.dtheta_r, ref.dtheta_r) < 1e-12
        assert window_error(fast.dv_r, ref.dv_r) < 1e-12
        np.testing.assert_allclose(fast.truth.position_e, ref.truth.position_e, rtol=1e-14, atol=0)
        if isinstance(profile, ConstantSpeed):
            assert cut.any() and (~cut).any()  # both kinds of block in one call
            assert fast.used_block.mean() > 0.95
        else:
            # the dwell ends at 1.5 s = sample 300 (inside block 1), the ramp at 3.5 s = 700
            assert 300.0 in gen.breakpoints and 700.0 in gen.breakpoints
            assert fast.used_block[290:310].all() and fast.used_block[690:710].all()
