"""Tests of navsim.track: arc length, derivatives, the 003 polynomial model, fitting,
track_frame and the bundled tracks."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from navsim.earth import SPHERICAL, WGS84
from navsim.errors import ConfigError, TrackError
from navsim.track import (
    CantModel,
    PiecewisePolynomialTrack,
    PolynomialTrack,
    SplineTrack,
    Track,
    TrackSegment,
    fit_polynomial_track,
    segment_mask,
    track_frame,
    with_cant,
)
from navsim.trackio import list_bundled_tracks, load_bundled_track

ROOT = Path(__file__).resolve().parents[1]
R_SPH = SPHERICAL.a
PHI0 = math.radians(47.2)
LAM0 = math.radians(39.7)


def metric_scale(track, pos):
    """[R_N + h, (R_E + h) cos(lat), 1]: turns [lat, lon, h] increments into metres."""
    r_n, r_e = track.earth.radii(pos[..., 0])
    h = pos[..., 2]
    return np.stack([r_n + h, (r_e + h) * np.cos(pos[..., 0]), np.ones_like(h)], axis=-1)


def five_point(f, s, d):
    """First and second derivatives by the 5-point central stencils (truncation d^4)."""
    p2, p1, p0, m1, m2 = f(s + 2 * d), f(s + d), f(s), f(s - d), f(s - 2 * d)
    return (-p2 + 8 * p1 - 8 * m1 + m2) / (12 * d), (-p2 + 16 * p1 - 30 * p0 + 16 * m1 - m2) / (12 * d * d)


def gentle_polynomial(**kwargs) -> PolynomialTrack:
    """lambda: heading ~8 deg east of north, curving left; h: crest, grades +3 / -2 per mille."""
    length = 24_000.0
    return PolynomialTrack(
        [0.0, math.tan(math.radians(8)) / math.cos(PHI0), -6e-6 * R_SPH / math.cos(PHI0)],
        [75.0, 0.003 * R_SPH, -0.005 * R_SPH**2 / (2 * length)],
        PHI0, PHI0 + length / R_SPH, lam0=LAM0, **kwargs,
    )


def circle_track(radius, *, right=True, earth=SPHERICAL, span_deg=300.0, step_deg=1.0, h=0.0, **kwargs):
    """Waypoints on a small circle of geodesic radius ``radius`` (sphere formulas)."""
    lat_c, lon_c = math.radians(47.0), math.radians(39.0)
    d = radius / earth.a
    az = np.radians(np.arange(0.0, span_deg + 1e-9, step_deg))
    if not right:
        az = -az
    lat = np.arcsin(np.sin(lat_c) * np.cos(d) + np.cos(lat_c) * np.sin(d) * np.cos(az))
    lon = lon_c + np.arctan2(np.sin(az) * np.sin(d) * np.cos(lat_c), np.cos(d) - np.sin(lat_c) * np.sin(lat))
    return SplineTrack(lat, lon, np.full_like(lat, h), earth=earth, **kwargs), d


# ------------------------------------------------------------------ arc length
@pytest.mark.parametrize("name", ["paper-2012", "mountain-railway", "urban-road"])
def test_metric_norm_of_d1_is_one(name):
    track = load_bundled_track(name)
    s = np.linspace(0.0, track.length, 5001)
    pos, d1, _ = track.geodetic(s)
    norm = np.linalg.norm(metric_scale(track, pos) * d1, axis=-1)
    assert np.max(np.abs(norm - 1.0)) < 1e-12


def test_arc_length_of_a_meridian_equals_the_meridian_arc():
    # lambda = const, h = const on WGS-84: s = int R_N(phi) + h dphi (independent quadrature)
    a, b, h = math.radians(44.0), math.radians(44.3), 250.0
    track = PolynomialTrack([0.0], [h], a, b, lam0=LAM0, earth=WGS84)
    expected = quad(lambda p: WGS84.radii(p)[0] + h, a, b, epsabs=0, epsrel=1e-13)[0]
    assert track.length == pytest.approx(expected, rel=1e-13)
    # southbound version: the same length, s = 0 at the northern end
    south = PolynomialTrack([0.0], [h], b, a, lam0=LAM0, earth=WGS84)
    assert south.length == pytest.approx(expected, rel=1e-13)
    assert south.geodetic(0.0)[0][0] == pytest.approx(b, abs=1e-15)
    assert south.geodetic(0.0)[1][0] < 0


def test_arc_length_inverse_is_exact_and_points_are_consistent():
    track = load_bundled_track("mountain-railway")
    s = np.linspace(0.0, track.length, 20001)
    u = track._u_of_s(s)
    assert np.max(np.abs(track._s_of_u(u) - s)) < 1e-9  # m, on a 35 km track
    # metric distance between neighbouring points ~ their arc-length difference
    ds = 0.05
    p0, p1 = track.geodetic(s[:-1])[0], track.geodetic(s[:-1] + ds)[0]
    xyz0 = track.earth.geodetic_to_ecef(p0[:, 0], p0[:, 1], p0[:, 2])
    xyz1 = track.earth.geodetic_to_ecef(p1[:, 0], p1[:, 1], p1[:, 2])
    chord = np.linalg.norm(xyz1 - xyz0, axis=-1)
    # chord = ds (1 - kappa^2 ds^2 / 24): kappa <= 1/290 m gives < 1.3e-9 m, rounding ~2e-9 m
    assert np.max(np.abs(chord - ds)) < 5e-9


@pytest.mark.parametrize(
    "name, step, tol1, tol2",
    [
        # error ~ rounding (|lat| eps R ~ 7e-10 m) / step + stencil truncation
        ("paper-2012", 2.0, 2e-9, 5e-9),
        ("mountain-railway", 0.5, 1e-8, 5e-8),
        # 2 m knot spacing around 15 m radius turns: truncation dominates
        ("urban-road", 0.25, 3e-6, 3e-6),
    ],
)
def test_d1_d2_against_finite_differences(name, step, tol1, tol2):
    track = load_bundled_track(name)
    s = np.linspace(2 * step, track.length - 2 * step, 3001)
    pos, d1, d2 = track.geodetic(s)
    fd1, fd2 = five_point(lambda x: track.geodetic(x)[0], s, step)
    scale = metric_scale(track, pos)
    assert np.max(np.abs(scale * (fd1 - d1))) < tol1  # m/m
    assert np.max(np.abs(scale * (fd2 - d2))) < tol2  # 1/m


def test_shapes_scalar_and_range_errors():
    track = gentle_polynomial()
    pos, d1, d2 = track.geodetic(100.0)
    assert pos.shape == d1.shape == d2.shape == (3,)
    pos, d1, d2 = track.geodetic(np.zeros((4, 5)))
    assert pos.shape == (4, 5, 3)
    c, dc = track.cant(np.zeros(7))
    assert c.shape == dc.shape == (7,)
    assert isinstance(track, Track)
    with pytest.raises(TrackError, match="arc length"):
        track.geodetic(track.length + 1.0)
    with pytest.raises(TrackError):
        track.geodetic(-1.0)


# ------------------------------------------------------------------ polynomial model (003)
def test_polynomial_derivatives_against_finite_differences():
    track = gentle_polynomial()
    phi = np.linspace(track.phi_start, track.phi_end, 11)
    d = 1e-4  # rad
    for fn in (track.lam, track.height):
        for nu in (0, 1, 2):
            f = lambda x: fn(x, nu)  # noqa: E731
            exact = fn(phi, nu + 1)
            approx = (-f(phi + 2 * d) + 8 * f(phi + d) - 8 * f(phi - d) + f(phi - 2 * d)) / (12 * d)
            # rounding of the stencil ~ eps |f| / d
            rounding = 1e-15 * np.max(np.abs(f(phi))) / d
            assert np.allclose(approx, exact, rtol=1e-8, atol=rounding)


def test_two_dimensional_height_is_composed_and_matches_the_printed_form():
    # h(A, lambda, phi) = sum a_ij (lambda - lam0)^i (phi - phi0)^j, 2-D as printed in 003
    lam_c = [0.0, 0.2, -50.0]
    a = np.array([[80.0, 1.5e4, -3e6], [2.0e5, 1.0e6, 0.0], [-4.0e7, 0.0, 0.0]])
    track = PolynomialTrack(lam_c, a, PHI0, PHI0 + 3e-3, lam0=LAM0)
    phi = np.linspace(PHI0, PHI0 + 3e-3, 7)
    lam = LAM0 + np.polynomial.polynomial.polyval(phi - PHI0, lam_c)
    direct = sum(a[i, j] * (lam - LAM0) ** i * (phi - PHI0) ** j for i in range(3) for j in range(3))
    assert np.allclose(track.height(phi), direct, rtol=0, atol=1e-9)
    # dh/dphi of the composed h(A, P, phi) = h_lambda lambda' + h_phi (chain rule)
    dlam = np.polynomial.polynomial.polyval(phi - PHI0, np.polynomial.polynomial.polyder(lam_c))
    h_lam = sum(i * a[i, j] * (lam - LAM0) ** (i - 1) * (phi - PHI0) ** j for i in range(1, 3) for j in range(3))
    h_phi = sum(j * a[i, j] * (lam - LAM0) ** i * (phi - PHI0) ** (j - 1) for i in range(3) for j in range(1, 3))
    assert np.allclose(track.height(phi, 1), h_lam * dlam + h_phi, rtol=1e-12)
    # the printed coefficients (about phi = lambda = 0) evaluated literally give the same
    P, A = track.printed_coefficients()
    lam_printed = sum(P[k] * phi**k for k in range(P.size))
    h_printed = sum(A[i, j] * lam_printed**i * phi**j for i in range(A.shape[0]) for j in range(A.shape[1]))
    assert np.allclose(lam_printed, track.lam(phi), rtol=0, atol=1e-12)  # rad; terms ~1e2 cancel
    # terms reach |a_20| lam^2 ~ 6e7 m: cancellation leaves ~1e-8 relative of that
    assert np.allclose(h_printed, track.height(phi), rtol=0, atol=5e-5)
    # and from_printed re-expands back to the same model
    again = PolynomialTrack.from_printed(P, A, PHI0, PHI0 + 3e-3)
    assert np.allclose(again.lam(phi), track.lam(phi), rtol=0, atol=1e-13)
    assert np.allclose(again.height(phi), track.height(phi), rtol=0, atol=5e-5)
    assert again.length == pytest.approx(track.length, rel=1e-9)


def test_paper_velocity_relations_hold_along_the_track():
    # 003: V_X = dlambda/dphi V_Y cos(phi) and V_Z = dh/dphi V_Y / (r + h) on the sphere
    track = gentle_polynomial()
    s = np.linspace(0.0, track.length, 50)
    frame = track_frame(track, s)
    t_e, t_n, t_u = frame.tangent_n[:, 0], frame.tangent_n[:, 1], frame.tangent_n[:, 2]
    phi = frame.lat
    assert np.allclose(t_e, track.lam(phi, 1) * t_n * np.cos(phi), atol=1e-14)
    assert np.allclose(t_u, track.height(phi, 1) * t_n / (R_SPH + frame.h), atol=1e-15)
    assert np.allclose(track.phi_at(s), phi, atol=1e-15)
    assert np.allclose(track.arc_length_at(phi), s, atol=1e-9)


def test_polynomial_config_errors():
    with pytest.raises(ConfigError, match="phi_end"):
        PolynomialTrack([0.0], [0.0], PHI0, PHI0)
    with pytest.raises(ConfigError, match="lam_coeffs"):
        PolynomialTrack(["a"], [0.0], PHI0, PHI0 + 1e-3)
    with pytest.raises(ConfigError, match="h_coeffs"):
        PolynomialTrack([0.0], [np.nan], PHI0, PHI0 + 1e-3)
    with pytest.raises(ConfigError, match="nu"):
        gentle_polynomial().lam(PHI0, 4)


# ------------------------------------------------------------------ fitting
def test_fit_recovers_a_known_polynomial():
    truth = gentle_polynomial()
    fit = fit_polynomial_track(truth, degree=2, max_error_m=0.01)
    assert isinstance(fit.track, PolynomialTrack) and fit.n_pieces == 1
    phi = np.linspace(truth.phi_start, truth.phi_end, 101)
    assert np.max(np.abs(fit.track.lam(phi) - truth.lam(phi))) * R_SPH < 1e-6  # m
    assert np.max(np.abs(fit.track.height(phi) - truth.height(phi))) < 1e-6
    assert fit.max_cross_track_m < 1e-6 and fit.max_height_m < 1e-6
    assert fit.track.length == pytest.approx(truth.length, rel=1e-10)
    # same physics regardless of the expansion point: coefficient about phi_start
    assert np.allclose(fit.track.lam_coeffs, truth.lam_coeffs, rtol=1e-6, atol=1e-12)


def test_fit_from_waypoint_array_southbound():
    truth = PolynomialTrack([0.0, 0.1, 30.0], [50.0, -2e4], PHI0 + 2e-3, PHI0, lam0=LAM0)
    pos = truth.geodetic(np.linspace(0, truth.length, 300))[0]
    fit = fit_polynomial_track(pos, degree=2, max_error_m=0.01, earth=SPHERICAL)
    assert fit.track.phi_range == pytest.approx(truth.phi_range, abs=1e-15)
    assert fit.track.direction == -1
    assert fit.max_error_m < 1e-6


def test_piecewise_fit_where_one_polynomial_cannot():
    # a wavy northbound line: east offset 40 m sin(2 pi n / 4 km) over 20 km
    n = np.linspace(0.0, 20_000.0, 2001)
    phi = PHI0 + n / R_SPH
    lam = LAM0 + 40.0 * np.sin(2 * np.pi * n / 4000.0) / (R_SPH * np.cos(phi))
    h = 100.0 + 5.0 * np.cos(2 * np.pi * n / 5000.0)
    single = fit_polynomial_track((phi, lam, h), degree=2, max_error_m=1e3, earth=SPHERICAL)
    assert single.n_pieces == 1 and single.max_cross_track_m > 20.0  # one parabola is far off
    fit = fit_polynomial_track((phi, lam, h), degree=3, max_error_m=0.5, earth=SPHERICAL)
    assert isinstance(fit.track, PiecewisePolynomialTrack) and fit.n_pieces > 1
    assert fit.max_cross_track_m <= 0.5 and fit.max_height_m <= 0.5
    assert fit.rms_cross_track_m <= fit.max_cross_track_m
    # independent check of the reported error at the data points
    east = (lam - fit.track.lam(phi)) * R_SPH * np.cos(phi)
    assert np.max(np.abs(east)) < 0.51  # cross-track ~ east error (heading < 4 deg)
    # cubic pieces join C^2: value, slope and curvature continuous at the breakpoints
    for pp in (fit.track._lam_pp, fit.track._h_pp):
        for nu in (0, 1, 2):
            d = pp.derivative(nu) if nu else pp
            dx = np.diff(d.x)[:-1]
            left = sum(d.c[m, :-1] * dx ** (d.c.shape[0] - 1 - m) for m in range(d.c.shape[0]))
            right = d.c[-1, 1:]  # value of the next piece at its start
            assert np.allclose(left, right, rtol=1e-9, atol=1e-9 * np.max(np.abs(d.c[-1])))
    assert fit.track.degree == 3
    # and it is a valid track
    s = np.linspace(0, fit.track.length, 1001)
    pos, d1, _ = fit.track.geodetic(s)
    assert np.max(np.abs(np.linalg.norm(metric_scale(fit.track, pos) * d1, axis=-1) - 1)) < 1e-12


def test_fit_rejects_a_track_that_turns_back_in_latitude():
    n = np.linspace(0.0, 2000.0, 201)
    north = np.where(n < 1200.0, n, 2400.0 - n)  # goes north 1200 m, then back south
    east = 0.2 * n
    phi = PHI0 + north / R_SPH
    lam = LAM0 + east / (R_SPH * np.cos(PHI0))
    with pytest.raises(TrackError, match=r"turns back at point 120\b"):
        fit_polynomial_track((phi, lam, np.zeros_like(phi)), earth=SPHERICAL)
    # also for a real track: the urban road runs north, east, then south
    with pytest.raises(TrackError, match="not monotonic"):
        fit_polynomial_track(load_bundled_track("urban-road"))


# ------------------------------------------------------------------ track_frame
@pytest.mark.parametrize("right", [True, False])
def test_track_frame_on_a_circle(right):
    radius = 200.0
    track, d = circle_track(radius, right=right)
    s = np.linspace(50.0, track.length - 50.0, 400)
    frame = track_frame(track, s)
    # geodesic curvature of a small circle on the sphere: cot(r / R) / R ~ 1 / r
    expected = 1.0 / (R_SPH * math.tan(d))
    sign = 1.0 if right else -1.0
    assert np.max(np.abs(frame.curvature - sign * expected)) < 1e-7 * expected
    # heading = azimuth from the centre + 90 deg (right / clockwise) or - 90 deg (left)
    lat_c, lon_c = math.radians(47.0), math.radians(39.0)
    lat, lon = frame.lat, frame.lon
    az = np.arctan2(np.sin(lon - lon_c) * np.cos(lat),
                    np.cos(lat_c) * np.sin(lat) - np.sin(lat_c) * np.cos(lat) * np.cos(lon - lon_c))
    # back-azimuth at the point toward the centre, then turn +-90 deg
    az_to_c = np.arctan2(np.sin(lon_c - lon) * np.cos(lat_c),
                         np.cos(lat) * np.sin(lat_c) - np.sin(lat) * np.cos(lat_c) * np.cos(lon_c - lon))
    want = az_to_c - sign * np.pi / 2
    err = np.angle(np.exp(1j * (frame.heading - want)))
    assert np.max(np.abs(err)) < 1e-6  # rad; spline interpolation of 1-deg waypoints
    del az
    assert np.allclose(frame.pitch, 0.0, atol=1e-9)
    # heading rate: curvature plus meridian convergence (t_E tan(lat) / R)
    conv = frame.tangent_n[:, 0] * np.tan(lat) / R_SPH
    assert np.allclose(frame.dheading_ds, frame.curvature + conv, rtol=0, atol=1e-12)


def test_track_frame_on_a_meridian_is_straight():
    track = PolynomialTrack([0.0], [10.0, 1e4], PHI0, PHI0 + 1e-3, lam0=LAM0, earth=WGS84)
    frame = track_frame(track, np.linspace(0, track.length, 11))
    assert np.allclose(frame.heading, 0.0, atol=1e-15)
    assert np.allclose(frame.curvature, 0.0, atol=1e-15)
    r_n, _ = WGS84.radii(frame.lat)
    # grade dh/dn = 1e4 / (R_N + h): pitch = atan of it
    assert np.allclose(np.tan(frame.pitch), 1e4 / (r_n + frame.h), rtol=1e-9)


@pytest.mark.parametrize(
    "name, step, rtol",
    # the stencil's d^4 truncation sees the jumps of the 5th derivative at the quintic
    # spline's knots (every 10 m) on the mountain railway; the polynomial track is smooth
    [("paper-2012", 5.0, 1e-6), ("mountain-railway", 0.5, 2e-5)],
)
def test_track_frame_rates_against_finite_differences(name, step, rtol):
    track = with_cant(load_bundled_track(name), mode="design", design_speed=25.0, max_cant=0.1)
    s = np.linspace(10.0, track.length - 10.0, 1501)
    frame = track_frame(track, s)
    f = lambda x: track_frame(track, x)  # noqa: E731
    fp, fm = f(s + step), f(s - step)
    fp2, fm2 = f(s + 2 * step), f(s - 2 * step)

    def deriv(attr):
        a2, a1, b1, b2 = (getattr(g, attr) for g in (fp2, fp, fm, fm2))
        diff1, diff2 = a1 - b1, a2 - b2
        if attr == "heading":  # wrap at +-pi
            diff1, diff2 = np.angle(np.exp(1j * diff1)), np.angle(np.exp(1j * diff2))
        return (8 * diff1 - diff2) / (12 * step)

    scale = np.max(np.abs(frame.dtangent_n_ds)) + 1e-12
    assert np.max(np.abs(deriv("tangent_n") - frame.dtangent_n_ds)) < rtol * scale + 1e-11
    for attr, rate in (("heading", "dheading_ds"), ("pitch", "dpitch_ds")):
        exact = getattr(frame, rate)
        tol = rtol * (np.max(np.abs(exact)) + 1e-9) + 1e-11
        assert np.max(np.abs(deriv(attr) - exact)) < tol, attr
    # cant is a function of curvature (third derivatives): the knot jumps of the spline's
    # fifth derivative make the stencil error O(step^2) there, so a finer step; cant
    # rounding is only eps |cant| / step
    fine = step / 25.0
    fd_cant = (8 * (track.cant(s + fine)[0] - track.cant(s - fine)[0])
               - (track.cant(s + 2 * fine)[0] - track.cant(s - 2 * fine)[0])) / (12 * fine)
    tol = rtol * np.max(np.abs(frame.dcant_ds)) + 1e-13
    assert np.max(np.abs(fd_cant - frame.dcant_ds)) < tol
    # the unit tangent is unit
    assert np.allclose(np.linalg.norm(frame.tangent_n, axis=-1), 1.0, atol=1e-13)


def test_design_cant_from_curvature():
    radius, v = 400.0, 20.0
    track, d = circle_track(radius, step_deg=0.5, earth=SPHERICAL, cant_model=CantModel("design", v, 0.25))
    s = np.linspace(50.0, track.length - 50.0, 50)
    cant, dcant = track.cant(s)
    kappa = 1.0 / (R_SPH * math.tan(d))
    raw = math.atan(v * v * kappa / 9.81)  # tan(cant) = v^2 kappa / g = 0.1, below the 0.25 limit
    assert np.allclose(cant, raw * (1 + (raw / 0.25) ** 8) ** (-1 / 8), rtol=1e-6)
    assert abs(cant[0] - raw) < 5e-4 * raw  # the soft limit: within 0.05 % below half the limit
    assert np.max(np.abs(dcant)) < 1e-8  # constant curvature
    # saturation: far above the limit the cant approaches max_cant and never exceeds it
    sharp = with_cant(track, mode="design", design_speed=60.0, max_cant=0.1)
    c_sharp, _ = sharp.cant(s)
    assert np.all(c_sharp < 0.1) and np.all(c_sharp > 0.095)
    # left-hand curve: negative cant (left side down)
    left, _ = circle_track(radius, right=False, step_deg=0.5, cant_model=CantModel("design", v, 0.25))
    assert np.allclose(left.cant(s)[0], -cant, rtol=1e-6)
    assert np.all(with_cant(track, mode="none").cant(s)[0] == 0.0)


def test_plan_curvature_agrees_with_the_exact_curvature():
    track = load_bundled_track("mountain-railway")
    s = np.linspace(0.0, track.length, 4001)
    kappa, _ = track.plan_curvature(s)
    exact = track_frame(track, s).curvature
    assert np.max(np.abs(kappa - exact)) < 1e-4 * np.max(np.abs(exact))


# ------------------------------------------------------------------ bundled tracks
def test_bundled_tracks_are_listed_and_documented():
    assert list_bundled_tracks() == ["mountain-railway", "paper-2012", "urban-road"]
    with pytest.raises(ConfigError, match="one of"):
        load_bundled_track("no-such-track")


def test_bundled_paper_2012():
    track = load_bundled_track("paper-2012")
    assert isinstance(track, PolynomialTrack) and track.earth is SPHERICAL
    assert track.lam_coeffs.size == 3 and track.h_coeffs.shape == (3,)  # second-order polynomials
    assert math.degrees(track.phi_start) == pytest.approx(47.2)
    assert math.degrees(track.lam(track.phi_start)) == pytest.approx(39.7)
    assert 22_500.0 < track.length < 25_000.0  # 1000 s at 22.5-25 m/s
    frame = track_frame(track, np.linspace(0, track.length, 201))
    assert np.all(np.abs(frame.heading) < math.radians(10))  # roughly north
    assert np.max(np.abs(np.tan(frame.pitch))) < 0.004  # a few per mille
    assert track.segments == ()


def test_bundled_mountain_railway():
    track = load_bundled_track("mountain-railway")
    assert isinstance(track, SplineTrack) and track.earth is WGS84
    assert 30_000.0 < track.length < 40_000.0
    kinds = [g.kind for g in track.segments]
    assert kinds.count("tunnel") == 3 and kinds.count("station") == 2
    assert {g.name for g in track.segments if g.kind == "tunnel"} == {"Tunnel 1", "Summit tunnel", "Tunnel 3"}
    summit = next(g for g in track.segments if g.name == "Summit tunnel")
    assert summit.s_end - summit.s_start == pytest.approx(3000.0, abs=1.0)
    s = np.linspace(0.0, track.length, 20001)
    frame = track_frame(track, s)
    radius = 1.0 / np.max(np.abs(frame.curvature))
    assert 290.0 < radius < 310.0  # sharpest design curve 300 m
    assert 0.024 < np.max(np.abs(np.tan(frame.pitch))) < 0.0255  # ruling grade 25 per mille
    assert track.cant_model.mode == "design"
    assert 0.0 < np.max(np.abs(frame.cant)) < track.cant_model.max_cant
    # tunnels: the summit tunnel is at the top of the line
    mask = segment_mask(track, s, "tunnel")
    assert np.max(frame.h[mask]) == pytest.approx(np.max(frame.h), abs=20.0)


def test_bundled_urban_road():
    track = load_bundled_track("urban-road")
    assert 5_000.0 < track.length < 8_000.0
    urban = [g for g in track.segments if g.kind == "urban"]
    assert len(urban) == 3
    s = np.linspace(0.0, track.length, 20001)
    frame = track_frame(track, s)
    assert 14.0 < 1.0 / np.max(np.abs(frame.curvature)) < 16.0  # tightest turn 15 m
    # twelve 90-degree turns: total absolute heading change 12 * 90 deg
    turning = np.sum(np.abs(np.diff(np.unwrap(frame.heading))))
    assert turning == pytest.approx(math.radians(12 * 90), rel=0.01)
    assert np.all(frame.cant == 0.0)


def test_with_earth_moves_segments_to_the_same_points():
    track = load_bundled_track("mountain-railway")
    sph = load_bundled_track("mountain-railway", earth=SPHERICAL)
    assert sph.earth is SPHERICAL and abs(sph.length - track.length) > 1.0
    for a, b in zip(track.segments, sph.segments):
        pa = track.geodetic(np.array([a.s_start, a.s_end]))[0]
        pb = sph.geodetic(np.array([b.s_start, b.s_end]))[0]
        assert np.allclose(pa, pb, rtol=0, atol=1e-12)


def test_generator_reproduces_the_committed_files(tmp_path):
    out = subprocess.run([sys.executable, str(ROOT / "tools" / "make_tracks.py"), "--check"],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stdout + out.stderr


def test_segments_validation():
    with pytest.raises(ConfigError, match="s_end"):
        TrackSegment("tunnel", 10.0, 5.0)
    with pytest.raises(ConfigError, match="kind"):
        TrackSegment("", 0.0, 5.0)
    track = gentle_polynomial()
    with pytest.raises(TrackError, match="outside the track"):
        track.with_segments([TrackSegment("tunnel", 0.0, track.length + 100.0)])
    moved = track.with_segments([TrackSegment("tunnel", 100.0, 200.0, "T")])
    assert segment_mask(moved, np.array([50.0, 150.0, 250.0]), "tunnel").tolist() == [False, True, False]
