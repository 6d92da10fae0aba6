"""Generate the bundled tracks in navsim/data/tracks/ from geometric design elements.

Deterministic (no randomness): running it again rewrites byte-identical files.

    python tools/make_tracks.py            # writes navsim/data/tracks/*
    python tools/make_tracks.py --check    # exit 1 if the committed files differ

Tracks (all geometry invented for simulation; nothing is surveyed or downloaded):

paper-2012.toml
    The worked example of seed 003 (Sokolov & Vdovichenko 2012): second-order polynomials
    lambda(phi), h(phi) near Rostov-on-Don (the authors' university, ~47.2 N, 39.7 E),
    running north for 24 km (1000 s at up to 24 m/s). Plan: east offset
    e = c1 n + c2 n^2 of the north distance n with c1 = tan(8 deg) (heading 8 deg east of
    north at the start) and c2 = -6e-6 1/m (a gentle left-hand curve, radius ~ 1/(2 c2)
    = 83 km, heading -7.4 deg at the end). Profile: grade +3 per mille at the start,
    -2 per mille at the end (a crest vertical curve, radius 4.8e6 m), h = 75 m at the start.
    On the sphere of 003 (r = 6371 km) with x = phi - phi0 (rad):
    lambda - lam0 = (c1 / cos phi0) x + (c2 r / cos phi0) x^2,
    h = h0 + g0 r x + (dg r^2 / (2 L)) x^2.
mountain-railway.geojson
    A 35 km single-track mountain railway in the western Caucasus (fictional alignment):
    straights, clothoid transitions (length 60 + 30000/R m), circular curves of radius
    300-1000 m, grades up to 25 per mille joined by parabolic vertical curves of radius
    10 km, three tunnels, a viaduct, a cutting and two stations. Design cant for 70 km/h
    limited to 150 mm. Sampled every 10 m of plan length.
urban-road.geojson
    A 6.3 km drive through a street grid in Rostov-on-Don (fictional route): straights
    with 90-degree turns of radius 15-50 m entered by short clothoids (length R / 2),
    grades up to 4 % with vertical curves of radius 800 m, "urban" canyon segments.
    No cant. Sampled every 2 m of plan length.

The plan is built in a local tangent plane (east, north) at the start point and mapped
to the WGS-84 ellipsoid along the normal (scale distortion < 1e-5 over 20 km); heights are
the designed profile. Segment arc lengths are 3-D arc lengths, s = int sqrt(1 + grade^2) dl.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from navsim.earth import SPHERICAL, WGS84, mat_en  # noqa: E402
from navsim.trackio import write_geojson  # noqa: E402

OUT = ROOT / "navsim" / "data" / "tracks"
_GL_X, _GL_W = np.polynomial.legendre.leggauss(6)


# ---------------------------------------------------------------- design elements
class PiecewiseLinearRate:
    """A rate r(l) piecewise linear in l (curvature, or grade) and its exact integral."""

    def __init__(self, start_value: float = 0.0):
        self.l = [0.0]
        self.r = [start_value]

    def ramp(self, length: float, end_value: float) -> None:
        self.l.append(self.l[-1] + length)
        self.r.append(end_value)

    def hold(self, length: float) -> None:
        self.ramp(length, self.r[-1])

    @property
    def total(self) -> float:
        return self.l[-1]

    def integral(self, x: np.ndarray, x0: float = 0.0) -> np.ndarray:
        """x0 + int_0^x r dl, exact for piecewise-linear r."""
        lb, rb = np.array(self.l), np.array(self.r)
        seg = np.diff(lb)
        area = 0.5 * (rb[:-1] + rb[1:]) * seg
        cum = np.concatenate([[0.0], np.cumsum(area)])
        k = np.clip(np.searchsorted(lb, x, side="right") - 1, 0, lb.size - 2)
        d = x - lb[k]
        slope = np.where(seg[k] > 0, (rb[k + 1] - rb[k]) / np.where(seg[k] > 0, seg[k], 1.0), 0.0)
        return x0 + cum[k] + rb[k] * d + 0.5 * slope * d * d

    def value(self, x: np.ndarray) -> np.ndarray:
        return np.interp(x, self.l, self.r)


def curve(plan: PiecewiseLinearRate, radius: float, deflection_deg: float, transition: float) -> None:
    """Clothoid in, circular arc, clothoid out; deflection > 0 turns right."""
    kappa = math.copysign(1.0 / radius, deflection_deg)
    arc = radius * math.radians(abs(deflection_deg)) - transition
    if arc < 0:
        raise ValueError(f"deflection {deflection_deg} too small for transition {transition} at R {radius}")
    plan.ramp(transition, kappa)
    plan.hold(arc)
    plan.ramp(transition, 0.0)


def profile_from_grades(grades: list[tuple[float, float]], vertical_radius: float, total: float) -> PiecewiseLinearRate:
    """Grade function from (start_l, grade) breakpoints, each change made by a parabolic
    vertical curve of the given radius centred on the breakpoint."""
    prof = PiecewiseLinearRate(grades[0][1])
    for (l_prev, g_prev), (l_pvi, g_next) in zip(grades[:-1], grades[1:]):
        lv = vertical_radius * abs(g_next - g_prev)
        prof.hold(l_pvi - lv / 2 - prof.total)
        prof.ramp(lv, g_next)
    prof.hold(total - prof.total)
    return prof


def plan_points(plan: PiecewiseLinearRate, heading0_deg: float, step: float):
    """Plan positions (east, north) every ``step`` m of plan length, exact heading and
    Gauss-Legendre integration of (sin, cos) of heading between samples."""
    n = int(round(plan.total / step))
    l = np.linspace(0.0, plan.total, n + 1)
    a, b = l[:-1], l[1:]
    nodes = 0.5 * (a + b)[:, None] + 0.5 * (b - a)[:, None] * _GL_X
    psi = plan.integral(nodes, math.radians(heading0_deg))
    de = 0.5 * (b - a) * (np.sin(psi) @ _GL_W)
    dn = 0.5 * (b - a) * (np.cos(psi) @ _GL_W)
    east = np.concatenate([[0.0], np.cumsum(de)])
    north = np.concatenate([[0.0], np.cumsum(dn)])
    return l, east, north


def to_geodetic(lat0_deg: float, lon0_deg: float, east: np.ndarray, north: np.ndarray):
    """Tangent-plane (east, north) at (lat0, lon0) to WGS-84 lat, lon along the normal."""
    lat0, lon0 = math.radians(lat0_deg), math.radians(lon0_deg)
    origin = WGS84.geodetic_to_ecef(lat0, lon0, 0.0)
    rows = mat_en(lat0, lon0)  # rows E, N, U in ECEF
    xyz = origin + east[:, None] * rows[0] + north[:, None] * rows[1]
    lat, lon, _ = WGS84.ecef_to_geodetic(xyz)
    return lat, lon


def arc_length_3d(grade: PiecewiseLinearRate, l: np.ndarray) -> np.ndarray:
    """s(l) = int sqrt(1 + grade^2) dl at the sample points (fine Gauss-Legendre)."""
    a, b = l[:-1], l[1:]
    nodes = 0.5 * (a + b)[:, None] + 0.5 * (b - a)[:, None] * _GL_X
    ds = 0.5 * (b - a) * (np.sqrt(1.0 + grade.value(nodes) ** 2) @ _GL_W)
    return np.concatenate([[0.0], np.cumsum(ds)])


def segments_at(l: np.ndarray, s: np.ndarray, spec: list[tuple[str, str, float, float]]):
    out = []
    for kind, name, l0, l1 in spec:
        out.append({"kind": kind, "name": name,
                    "s_start_m": round(float(np.interp(l0, l, s)), 3),
                    "s_end_m": round(float(np.interp(l1, l, s)), 3)})
    return out


# ---------------------------------------------------------------- paper-2012
def paper_2012() -> str:
    r = SPHERICAL.a
    phi0_deg, lam0_deg = 47.2, 39.7
    phi0 = math.radians(phi0_deg)
    length_north = 24_000.0
    c1, c2 = math.tan(math.radians(8.0)), -6.0e-6
    g0, g1, h0 = 0.003, -0.002, 75.0
    p1 = c1 / math.cos(phi0)
    p2 = c2 * r / math.cos(phi0)
    b1 = g0 * r
    b2 = (g1 - g0) * r * r / (2.0 * length_north)
    phi_end_deg = phi0_deg + math.degrees(length_north / r)
    return f"""# Seed 003 worked example (Sokolov & Vdovichenko 2012): "the models of longitude and
# height were given by second-order polynomials". The paper prints no coefficients; these
# are invented, plausible ones near Rostov-on-Don (Rostov State Transport University,
# ~47.2 N 39.7 E), generated by tools/make_tracks.py:
#   plan: east offset e = c1 n + c2 n^2 of the north distance n, c1 = tan(8 deg),
#         c2 = -6e-6 1/m (gentle left curve, radius ~83 km; heading +8 deg -> -7.4 deg);
#   profile: grade +3 per mille at the start, -2 per mille at the end, h = 75 m at start.
# lambda(phi) = lam0 + sum_k lam_coeffs[k] (phi - phi0)^k   (rad)
# h(phi)      = sum_j h_coeffs[j] (phi - phi0)^j            (m)
# This is the printed form lambda(P, phi), h(A, P, phi) re-expanded about phi0, lam0.
kind = "polynomial"
name = "paper-2012"
description = "Seed 003 example: 2nd-order polynomial track near Rostov-on-Don, 24 km northbound"
earth = "spherical"
phi_start_deg = {phi0_deg!r}
phi_end_deg = {phi_end_deg!r}
phi0_deg = {phi0_deg!r}
lam0_deg = {lam0_deg!r}
lam_coeffs = [0.0, {p1!r}, {p2!r}]
h_coeffs = [{h0!r}, {b1!r}, {b2!r}]

[cant]
mode = "none"
"""


# ---------------------------------------------------------------- mountain railway
def mountain_railway():
    plan = PiecewiseLinearRate(0.0)
    plan.hold(1500.0)  # station and approach
    radii = [600, 400, 300, 800, 1000, 450, 350, 700, 500, 300, 900, 400]
    deflections = [25, -40, 60, -35, 20, -55, 45, -30, 38, -62, 22, 48]
    straights = [420, 300, 650, 250, 800, 380, 270, 540, 310, 460, 700, 350]
    i = 0
    while plan.total < 33_000.0:
        j = i % len(radii)
        sign = -1 if (i // len(radii)) % 2 else 1  # mirror the pattern every cycle
        r = float(radii[j])
        curve(plan, r, sign * deflections[j], 60.0 + 30_000.0 / r)
        plan.hold(float(straights[j]))
        i += 1
    plan.hold(35_000.0 - plan.total)  # final straight into the terminus
    total = plan.total
    grades = [(0.0, 0.0), (1500.0, 0.012), (6000.0, 0.025), (14000.0, 0.018), (16000.0, 0.003),
              (19500.0, -0.024), (27000.0, -0.015), (33000.0, 0.0)]
    grade = profile_from_grades(grades, 10_000.0, total)
    l, east, north = plan_points(plan, 150.0, 10.0)
    h = grade.integral(l, 120.0)
    lat, lon = to_geodetic(44.40, 39.45, east, north)
    s = arc_length_3d(grade, l)
    spec = [
        ("station", "Upper Valley", 0.0, 800.0),
        ("bridge", "Viaduct", 4000.0, 4250.0),
        ("tunnel", "Tunnel 1", 9800.0, 10400.0),
        ("cutting", "Deep cutting", 12000.0, 12600.0),
        ("tunnel", "Summit tunnel", 16200.0, 19200.0),
        ("tunnel", "Tunnel 3", 24500.0, 25400.0),
        ("station", "Lower Valley", total - 800.0, total),
    ]
    props = {
        "name": "mountain-railway",
        "description": ("Fictional 35 km mountain railway, western Caucasus: curves R 300-1000 m with clothoid "
                        "transitions, grades up to 25 per mille, 3 tunnels. Generated by tools/make_tracks.py."),
        "earth": "wgs84",
        "cant": {"mode": "design", "design_speed_mps": round(70 / 3.6, 4), "max_cant_mm": 150.0,
                 "rail_spacing_mm": 1500.0},
        "design": {"plan_length_m": total, "sample_step_m": 10.0, "start_heading_deg": 150.0,
                   "radii_m": radii, "deflections_deg": deflections, "transition_m": "60 + 30000 / R",
                   "grades": [[a, b] for a, b in grades], "vertical_curve_radius_m": 10000.0,
                   "start_height_m": 120.0},
    }
    return lat, lon, h, segments_at(l, s, spec), props


# ---------------------------------------------------------------- urban road
def urban_road():
    plan = PiecewiseLinearRate(0.0)
    legs = [  # (straight before the turn m, turn radius m, +90 right / -90 left)
        (420, 20, 90), (380, 15, -90), (560, 30, 90), (300, 50, 90), (450, 25, -90),
        (520, 15, -90), (340, 40, 90), (610, 20, 90), (280, 35, -90), (470, 15, -90),
        (390, 45, 90), (500, 20, -90),
    ]
    for straight, radius, turn in legs:
        plan.hold(float(straight))
        curve(plan, float(radius), float(turn), radius / 2.0)
    plan.hold(6300.0 - plan.total)
    total = plan.total
    grades = [(0.0, 0.01), (900.0, 0.04), (1700.0, -0.02), (2600.0, -0.035), (3500.0, 0.0),
              (4300.0, 0.025), (5200.0, -0.01)]
    grade = profile_from_grades(grades, 800.0, total)
    l, east, north = plan_points(plan, 0.0, 2.0)
    h = grade.integral(l, 60.0)
    lat, lon = to_geodetic(47.2220, 39.7100, east, north)
    s = arc_length_3d(grade, l)
    spec = [
        ("urban", "Canyon A", 300.0, 1250.0),
        ("urban", "Canyon B", 2100.0, 2900.0),
        ("bridge", "Overpass", 3300.0, 3420.0),
        ("urban", "Canyon C", 3900.0, 4800.0),
        ("tunnel", "Underpass", 5350.0, 5520.0),
    ]
    props = {
        "name": "urban-road",
        "description": ("Fictional 6.3 km urban drive, Rostov-on-Don street grid: 90-degree turns R 15-50 m "
                        "with clothoids R/2, grades up to 4 %, urban canyons. Generated by tools/make_tracks.py."),
        "earth": "wgs84",
        "cant": {"mode": "none"},
        "design": {"plan_length_m": total, "sample_step_m": 2.0, "start_heading_deg": 0.0,
                   "legs_straight_radius_turn": [list(x) for x in legs], "transition_m": "R / 2",
                   "grades": [[a, b] for a, b in grades], "vertical_curve_radius_m": 800.0,
                   "start_height_m": 60.0},
    }
    return lat, lon, h, segments_at(l, s, spec), props


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare with the committed files instead of writing")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    tmp = out if not args.check else Path(__import__("tempfile").mkdtemp())
    (tmp / "paper-2012.toml").write_text(paper_2012(), encoding="utf-8")
    for name, make in (("mountain-railway", mountain_railway), ("urban-road", urban_road)):
        lat, lon, h, segments, props = make()
        write_geojson(tmp / f"{name}.geojson", lat, lon, h, properties=props, segments=segments)
    if args.check:
        bad = [p.name for p in tmp.iterdir() if (out / p.name).read_bytes() != p.read_bytes()]
        if bad:
            print("differ:", ", ".join(sorted(bad)))
            return 1
        print("bundled tracks are up to date")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
