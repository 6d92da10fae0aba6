"""Tests of navsim.trackio: GeoJSON / GPX / CSV / TOML round trips and error messages."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from navsim.earth import SPHERICAL, WGS84
from navsim.errors import ConfigError, TrackError
from navsim.track import CantModel, PolynomialTrack, SplineTrack, TrackSegment
from navsim.trackio import load_track_file
from navsim.trackio import (
    load_track,
    read_csv,
    read_geojson,
    read_gpx,
    write_csv,
    write_geojson,
    write_gpx,
)


def sample_waypoints(n=60):
    """A gently curving, climbing line near Rostov-on-Don, every ~50 m."""
    k = np.arange(n)
    lat = math.radians(47.22) + 50.0 * k / 6.37e6
    lon = math.radians(39.71) + 1e-6 * k**1.5
    h = 60.0 + 0.3 * k + 2.0 * np.sin(k / 7.0)
    return lat, lon, h


@pytest.mark.parametrize("suffix, writer, reader", [
    (".geojson", write_geojson, read_geojson),
    (".gpx", write_gpx, read_gpx),
    (".csv", write_csv, read_csv),
])
def test_round_trip(tmp_path, suffix, writer, reader):
    lat, lon, h = sample_waypoints()
    path = tmp_path / f"track{suffix}"
    writer(path, lat, lon, h)
    wp = reader(path)
    # files keep 11 decimals of degrees (1e-11 deg ~ 1 micrometre) and 1e-5 m of height
    assert np.max(np.abs(np.degrees(wp.lat - lat))) < 1e-11
    assert np.max(np.abs(np.degrees(wp.lon - lon))) < 1e-11
    assert np.max(np.abs(wp.h - h)) < 1e-5
    # the track from the file is the track from the arrays
    from_file = load_track(path)
    direct = SplineTrack(lat, lon, h)
    assert isinstance(from_file, SplineTrack)
    assert from_file.length == pytest.approx(direct.length, abs=1e-4)
    s = np.linspace(0, direct.length, 101)
    p_file, p_direct = from_file.geodetic(s)[0], direct.geodetic(s)[0]
    r_n, r_e = WGS84.radii(p_direct[:, 0])
    # file rounding (~1e-6 m horizontally, 5e-6 m in height) through the interpolant
    assert np.max(np.abs(p_file[:, 0] - p_direct[:, 0]) * r_n) < 1e-5
    assert np.max(np.abs(p_file[:, 1] - p_direct[:, 1]) * r_e * np.cos(p_direct[:, 0])) < 1e-5
    assert np.max(np.abs(p_file[:, 2] - p_direct[:, 2])) < 3e-5


def test_geojson_lon_lat_order_feature_collection_and_segments(tmp_path):
    lat, lon, h = sample_waypoints()
    coords = [[math.degrees(b), math.degrees(a), c] for a, b, c in zip(lat, lon, h)]
    doc = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "geometry": {"type": "Point", "coordinates": coords[0]}, "properties": {}},
        {"type": "Feature", "geometry": {"type": "LineString", "coordinates": coords},
         "properties": {"name": "demo", "earth": "spherical",
                        "cant": {"mode": "design", "design_speed_mps": 20.0, "max_cant_deg": 5.0},
                        "segments": [{"kind": "tunnel", "name": "T1", "s_start_m": 100.0, "s_end_m": 400.0},
                                     {"kind": "station", "start_index": 0, "end_index": 10}]}},
    ]}
    path = tmp_path / "fc.json"
    path.write_text(json.dumps(doc))
    track = load_track(path)
    assert track.name == "demo" and track.earth is SPHERICAL
    assert track.cant_model == CantModel("design", 20.0, math.radians(5.0))
    assert math.degrees(track.geodetic(0.0)[0][0]) == pytest.approx(47.22)  # latitude second in GeoJSON
    assert math.degrees(track.geodetic(0.0)[0][1]) == pytest.approx(39.71)
    kinds = {g.kind: g for g in track.segments}
    assert kinds["tunnel"] == TrackSegment("tunnel", 100.0, 400.0, "T1")
    assert kinds["station"].s_start == 0.0
    assert kinds["station"].s_end == pytest.approx(track.waypoint_s[10], abs=1e-9)
    xyz = SPHERICAL.geodetic_to_ecef(lat[:11], lon[:11], h[:11])
    chords = np.sum(np.linalg.norm(np.diff(xyz, axis=0), axis=1))
    assert track.waypoint_s[10] == pytest.approx(chords, rel=1e-4)  # smooth: arc ~ chord sum
    # bare LineString geometry, 2-D positions: height 0
    bare = tmp_path / "bare.geojson"
    bare.write_text(json.dumps({"type": "LineString", "coordinates": [c[:2] for c in coords]}))
    assert np.all(read_geojson(bare).h == 0.0)
    # earth override moves segment ends to the same points
    wgs = load_track(path, earth=WGS84)
    p_sph = track.geodetic(np.array([100.0, 400.0]))[0]
    tunnel = next(g for g in wgs.segments if g.kind == "tunnel")
    p_wgs = wgs.geodetic(np.array([tunnel.s_start, tunnel.s_end]))[0]
    assert np.allclose(p_sph, p_wgs, atol=1e-12)


def test_csv_columns_by_name_in_any_order(tmp_path):
    lat, lon, h = sample_waypoints(8)
    lines = ["# exported by hand", "time_s,h_m,lon_deg,lat_deg"]
    for i, (a, b, c) in enumerate(zip(lat, lon, h)):
        lines.append(f"{i},{c:.5f},{math.degrees(b):.11f},{math.degrees(a):.11f}")
    path = tmp_path / "t.csv"
    path.write_text("\n".join(lines) + "\n")
    wp = read_csv(path)
    assert np.allclose(wp.lat, lat, atol=1e-13) and np.allclose(wp.h, h, atol=1e-5)


def test_smoothing_spline_stays_near_noisy_waypoints(tmp_path):
    rng = np.random.default_rng(3)
    n = 400
    north = np.arange(n) * 10.0
    lat = math.radians(47.0) + north / 6.37e6
    lon = math.radians(39.0) + rng.normal(0.0, 0.5, n) / (6.39e6 * math.cos(math.radians(47.0)))
    h = 100.0 + rng.normal(0.0, 0.5, n)
    path = tmp_path / "noisy.csv"
    write_csv(path, lat, lon, h)
    smooth = load_track_file(path, smoothing_m=0.7)  # noise 0.5 m in 2 axes: RMS 0.71 m
    interp = load_track_file(path)
    s = np.linspace(100.0, smooth.length - 100.0, 2001)
    # the smoothed track is much straighter than the interpolant through the noise
    from navsim.track import track_frame
    assert np.max(np.abs(track_frame(smooth, s).curvature)) < 0.01 * np.max(np.abs(track_frame(interp, s).curvature))
    pos = smooth.geodetic(smooth.waypoint_s)[0]
    r_n, r_e = WGS84.radii(lat)
    dist = np.hypot((pos[:, 0] - lat) * r_n, (pos[:, 1] - lon) * r_e * np.cos(lat))
    assert np.sqrt(np.mean(dist**2 + (pos[:, 2] - h) ** 2)) == pytest.approx(0.7, rel=0.05)


def test_polynomial_toml(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text(
        'kind = "polynomial"\nname = "p"\nearth = "wgs84"\nphi_start_deg = 47.3\nphi_end_deg = 47.2\n'
        'phi0_deg = 47.2\nlam0_deg = 39.7\nlam_coeffs = [0.0, 0.1, 20.0]\nh_coeffs = [[50.0, 1000.0], [300.0, 0.0]]\n'
        '[[segments]]\nkind = "bridge"\ns_start_m = 10.0\ns_end_m = 90.0\n'
    )
    track = load_track(path)
    assert isinstance(track, PolynomialTrack) and track.direction == -1 and track.earth is WGS84
    phi = np.radians([47.2, 47.25])
    lam = np.radians(39.7) + 0.1 * (phi - np.radians(47.2)) + 20.0 * (phi - np.radians(47.2)) ** 2
    x = phi - np.radians(47.2)
    assert np.allclose(track.height(phi), 50.0 + 1000.0 * x + 300.0 * (lam - np.radians(39.7)), atol=1e-9)
    assert track.segments == (TrackSegment("bridge", 10.0, 90.0),)
    bad = tmp_path / "bad.toml"
    bad.write_text('kind = "polynomial"\nphi_start_deg = 47.3\nphi_end_deg = 47.2\nlam_coeffs = [0.0]\nh_coeffs = "x"\n')
    with pytest.raises(ConfigError, match=r"bad\.toml: h_coeffs"):
        load_track(bad)


# ------------------------------------------------------------------ malformed input
def _geojson(tmp_path, coords, name="bad.geojson"):
    path = tmp_path / name
    path.write_text(json.dumps({"type": "LineString", "coordinates": coords}))
    return path


def test_malformed_geojson_messages(tmp_path):
    with pytest.raises(TrackError, match="at least 2 points"):
        load_track(_geojson(tmp_path, [[39.0, 47.0, 0.0]]))
    with pytest.raises(TrackError, match=r"coordinates\[2\] duplicates"):
        load_track(_geojson(tmp_path, [[39.0, 47.0, 0.0], [39.0, 47.001, 0.0], [39.0, 47.001, 0.0]]))
    with pytest.raises(ConfigError, match=r"coordinates\[1\] latitude: expected a latitude"):
        load_track(_geojson(tmp_path, [[39.0, 47.0], [39.0, 95.0]]))
    with pytest.raises(ConfigError, match=r"coordinates\[1\]\[1\]: expected a number"):
        load_track(_geojson(tmp_path, [[39.0, 47.0], [39.0, "north"]]))
    path = tmp_path / "nan.geojson"
    path.write_text('{"type": "LineString", "coordinates": [[39.0, 47.0], [39.0, NaN]]}')
    with pytest.raises(ConfigError, match=r"nan\.geojson: coordinates\[1\]\[1\]: expected a finite number"):
        load_track(path)
    path = tmp_path / "poly.geojson"
    path.write_text('{"type": "Polygon", "coordinates": []}')
    with pytest.raises(ConfigError, match="LineString"):
        load_track(path)
    path = tmp_path / "broken.geojson"
    path.write_text('{"type": "LineString",\n "coordinates": [[39.0, 47.0]')
    with pytest.raises(ConfigError, match=r"broken\.geojson: line 2"):
        load_track(path)


def test_malformed_gpx_and_csv_messages(tmp_path):
    gpx = tmp_path / "bad.gpx"
    gpx.write_text('<?xml version="1.0"?><gpx xmlns="http://www.topografix.com/GPX/1/1"><trk><trkseg>'
                   '<trkpt lat="47.0" lon="39.0"><ele>10</ele></trkpt>'
                   '<trkpt lat="47.001" lon="abc"><ele>11</ele></trkpt></trkseg></trk></gpx>')
    with pytest.raises(ConfigError, match=r"bad\.gpx: trkpt #2 @lon: expected a number"):
        load_track(gpx)
    gpx.write_text('<gpx><trk><trkseg><trkpt lat="47.0" lon="39.0"><ele>10</ele></trkpt>'
                   '<trkpt lat="47.001" lon="39.0"></trkpt></trkseg></trk></gpx>')
    with pytest.raises(ConfigError, match=r"trkpt #2 <ele>: expected an elevation on every point"):
        load_track(gpx)
    gpx.write_text('<gpx><trk><trkseg><trkpt lat="47.0" lon="39.0"></trk></gpx>')
    with pytest.raises(ConfigError, match=r"bad\.gpx: line 1, column"):
        load_track(gpx)
    csv_path = tmp_path / "bad.csv"
    csv_path.write_text("lat_deg,lon_deg,h_m\n47.0,39.0,1\n47.001,39.0,nan\n")
    with pytest.raises(ConfigError, match=r"bad\.csv: line 3, column h_m: expected a finite number"):
        load_track(csv_path)
    csv_path.write_text("latitude,x,h_m\n47.0,39.0,1\n")
    with pytest.raises(ConfigError, match=r"line 1 \(header\)"):
        load_track(csv_path)
    csv_path.write_text("lat_deg,lon_deg\n47.0,39.0\n47.0,39.0\n")
    with pytest.raises(TrackError, match="line 3 duplicates"):
        load_track(csv_path)
    with pytest.raises(ConfigError, match="ending in one of"):
        load_track(tmp_path / "track.kml")
    with pytest.raises(ConfigError, match="existing file"):
        load_track(tmp_path / "missing.csv")


def test_near_duplicate_points_are_rejected_by_the_spline():
    lat = np.radians([47.0, 47.001, 47.001 + 1e-12])
    with pytest.raises(TrackError, match="waypoints 1 and 2 coincide"):
        SplineTrack(lat, np.radians([39.0, 39.0, 39.0]), np.zeros(3))
