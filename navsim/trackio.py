"""Track files: GeoJSON, GPX, CSV waypoints and the TOML polynomial model.

Readers return :class:`Waypoints` (lat, lon in rad, h in m, plus segments and properties);
:func:`load_track` turns any supported file into a track (:class:`~navsim.track.SplineTrack`
for waypoints, :class:`~navsim.track.PolynomialTrack` for TOML). Writers produce files the
readers read back (round trip to 1e-11 deg and 1e-5 m).

Formats
-------
GeoJSON (RFC 7946)
    A LineString, or a Feature / FeatureCollection holding exactly one LineString.
    Coordinates are ``[lon, lat]`` or ``[lon, lat, h]`` in degrees and metres - longitude
    first. Optional ``properties``: ``name``, ``earth`` (``"wgs84"`` default, RFC 7946's
    datum, or ``"spherical"``), ``smoothing_m``, ``cant`` (see
    :meth:`navsim.track.CantModel.from_dict`) and ``segments``: a list of
    ``{"kind", "s_start_m", "s_end_m", "name"}`` (arc length on the file's Earth) or
    ``{"kind", "start_index", "end_index", "name"}`` (waypoint indices).
GPX 1.1
    ``trkpt`` (or ``rtept``) elements with ``lat``/``lon`` attributes (degrees) and an
    optional ``ele`` child (m); all track segments in document order.
CSV
    A header naming ``lat_deg``, ``lon_deg`` and optionally ``h_m`` in any column order
    (aliases: lat/latitude, lon/lng/longitude, h/ele/elevation/alt/height); other columns
    are ignored; ``#`` comment lines allowed.
TOML (polynomial model, seed 003)
    ``kind = "polynomial"``, ``phi_start_deg``, ``phi_end_deg``, ``phi0_deg``, ``lam0_deg``,
    ``lam_coeffs`` (rad/rad^k, powers of phi - phi0), ``h_coeffs`` (m/rad^j; a list, or a
    list of lists a_ij for powers of (lambda - lam0)^i (phi - phi0)^j), optional ``earth``,
    ``name``, ``[cant]`` and ``[[segments]]``.

Heights are taken as heights above the chosen Earth model (GPX elevations are usually
above mean sea level; the difference, the geoid undulation, is a near-constant offset
over a track and does not matter to the simulation).

Heights are optional in every format (a CSV without a height column, GeoJSON ``[lon,
lat]`` positions, GPX points without ``<ele>``): they are then 0 m above the Earth
model, a track without grade, and the reader warns (:class:`~navsim.errors.NavsimWarning`,
one ``navsim: warning:`` line in the CLI) that the heights were filled in, because a
forgotten column changes the physics (grade, gravity) without an error. Mixing points
with and without a height is refused.

Malformed input raises :class:`~navsim.errors.ConfigError` (a field is wrong: names the
file and the point, line or key) or :class:`~navsim.errors.TrackError` (the geometry is
unusable: too few points, duplicate consecutive points).

References
----------
.. [1] RFC 7946, The GeoJSON Format, 2016 (sec. 3.1.1: position = [longitude, latitude,
       altitude], WGS-84).
.. [2] GPX 1.1 schema, https://www.topografix.com/GPX/1/1/
"""

from __future__ import annotations

import csv
import json
import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
from numpy.typing import ArrayLike

from .earth import EarthModel, earth_model
from .errors import ConfigError, NavsimWarning, TrackError, file_value
from .track import CantModel, PolynomialTrack, SplineTrack, TrackSegment

if TYPE_CHECKING:  # type hints only
    from importlib.resources.abc import Traversable

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib  # type: ignore[no-redef]

__all__ = [
    "Waypoints",
    "read_geojson",
    "read_gpx",
    "read_csv",
    "read_waypoints",
    "write_geojson",
    "write_gpx",
    "write_csv",
    "track_from_waypoints",
    "load_polynomial_toml",
    "load_track",
    "list_bundled_tracks",
    "load_bundled_track",
    "load_track_file",
]


@dataclass(frozen=True, slots=True)
class Waypoints:
    """Waypoints read from a file.

    Attributes
    ----------
    lat, lon, h : ndarray (N,)
        rad, rad (unwrapped across the antimeridian), m.
    segments : tuple of dict
        Raw segment annotations (``kind``, ``name`` and either ``s_start_m``/``s_end_m``
        or ``start_index``/``end_index``).
    properties : dict
        Other file-level properties (name, earth, cant, smoothing_m, ...).
    source : str
        File name, for messages.
    """

    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    segments: tuple = ()
    properties: dict = field(default_factory=dict)
    source: str = ""


# ---------------------------------------------------------------- validation
def _number(value: Any, where: str, source: str, what: str) -> float:
    if isinstance(value, bool):
        raise ConfigError(where, f"a number ({what})", value, source)
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ConfigError(where, f"a number ({what})", file_value(value), source) from None
    if not math.isfinite(number):
        raise ConfigError(where, f"a finite number ({what})", value, source)
    return number


def _finish(lat_deg: ArrayLike, lon_deg: ArrayLike, h: ArrayLike, labels: Sequence[str], source: str,
            segments: Sequence[TrackSegment | dict] = (), properties: dict | None = None) -> Waypoints:
    lat_deg = np.asarray(lat_deg, dtype=float)
    lon_deg = np.asarray(lon_deg, dtype=float)
    h = np.asarray(h, dtype=float)
    if lat_deg.size < 2:
        raise TrackError(f"{source}: a track needs at least 2 points, got {lat_deg.size}")
    for i in range(lat_deg.size):
        if not -90.0 < lat_deg[i] < 90.0:
            raise ConfigError(f"{labels[i]} latitude", "a latitude in (-90, 90) deg", float(lat_deg[i]), source)
        if not -180.0 <= lon_deg[i] <= 180.0:
            raise ConfigError(f"{labels[i]} longitude", "a longitude in [-180, 180] deg", float(lon_deg[i]), source)
    lat = np.radians(lat_deg)
    lon = np.unwrap(np.radians(lon_deg))
    same = np.flatnonzero((np.diff(lat) == 0) & (np.diff(lon) == 0) & (np.diff(h) == 0))
    if same.size:
        i = int(same[0])
        raise TrackError(f"{source}: {labels[i + 1]} duplicates the point before it ({labels[i]}); "
                         "remove duplicate consecutive points")
    return Waypoints(lat, lon, h, tuple(segments), dict(properties or {}), source)


# ---------------------------------------------------------------- GeoJSON
def read_geojson(path: str | os.PathLike) -> Waypoints:
    """Read a GeoJSON LineString (or a Feature / FeatureCollection with one)."""
    source = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as fh:
            doc = json.load(fh)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"line {exc.lineno}", "valid JSON", exc.msg, source) from None
    properties: dict = {}
    geometry = doc
    if isinstance(doc, dict) and doc.get("type") == "FeatureCollection":
        features = [f for f in doc.get("features", []) if isinstance(f, dict)
                    and isinstance(f.get("geometry"), dict) and f["geometry"].get("type") == "LineString"]
        if len(features) != 1:
            raise ConfigError("features", "exactly one Feature with a LineString geometry", len(features), source)
        doc = features[0]
    if isinstance(doc, dict) and doc.get("type") == "Feature":
        properties = doc.get("properties") or {}
        geometry = doc.get("geometry")
    if not isinstance(geometry, dict) or geometry.get("type") != "LineString":
        got = geometry.get("type") if isinstance(geometry, dict) else type(geometry).__name__
        raise ConfigError("geometry.type", "'LineString'", got, source)
    coords = geometry.get("coordinates")
    if not isinstance(coords, list):
        raise ConfigError("geometry.coordinates", "a list of [lon, lat(, h)] positions", type(coords).__name__, source)
    n = len(coords)
    lat, lon, h = np.empty(n), np.empty(n), np.empty(n)
    dims = set()
    labels = [f"coordinates[{i}]" for i in range(n)]
    for i, pos in enumerate(coords):
        if not isinstance(pos, (list, tuple)) or len(pos) not in (2, 3):
            raise ConfigError(labels[i], "[lon, lat] or [lon, lat, h]", file_value(pos), source)
        dims.add(len(pos))
        lon[i] = _number(pos[0], labels[i] + "[0]", source, "longitude, deg")
        lat[i] = _number(pos[1], labels[i] + "[1]", source, "latitude, deg")
        h[i] = _number(pos[2], labels[i] + "[2]", source, "height, m") if len(pos) == 3 else 0.0
    if len(dims) > 1:
        raise ConfigError("geometry.coordinates", "all positions with a height, or none", "a mix", source)
    if dims == {2}:
        _no_heights(source, "[lon, lat] positions without a height")
    if not isinstance(properties, dict):
        raise ConfigError("properties", "an object", file_value(properties), source)
    segments = properties.get("segments", [])
    if not isinstance(segments, list):
        raise ConfigError("properties.segments", "a list of segment objects", file_value(segments), source)
    props = {k: v for k, v in properties.items() if k != "segments"}
    return _finish(lat, lon, h, labels, source, segments, props)


def write_geojson(path: str | os.PathLike, lat: ArrayLike, lon: ArrayLike, h: ArrayLike, *, properties: dict | None = None,
                  segments: Sequence[TrackSegment | dict] = ()) -> None:
    """Write a GeoJSON Feature with a LineString (lat, lon in rad, h in m)."""
    lat_deg, lon_deg = np.degrees(np.asarray(lat, float)), np.degrees(np.asarray(lon, float))
    lon_deg = (lon_deg + 180.0) % 360.0 - 180.0
    coords = [[round(float(a), 11), round(float(b), 11), round(float(c), 5)]
              for a, b, c in zip(lon_deg, lat_deg, np.asarray(h, float))]
    props = dict(properties or {})
    if segments:
        props["segments"] = [_segment_dict(g) for g in segments]
    lines = ",\n".join(json.dumps(c, separators=(",", ":")) for c in coords)
    text = ('{"type": "Feature",\n"properties": ' + json.dumps(props, indent=1, sort_keys=False)
            + ',\n"geometry": {"type": "LineString", "coordinates": [\n' + lines + "\n]}}\n")
    from .io import write_text_atomic

    write_text_atomic(path, text)


def _segment_dict(g: TrackSegment | dict) -> dict:
    if isinstance(g, TrackSegment):
        return {"kind": g.kind, "name": g.name, "s_start_m": round(g.s_start, 3), "s_end_m": round(g.s_end, 3)}
    return dict(g)


# ---------------------------------------------------------------- GPX
def read_gpx(path: str | os.PathLike) -> Waypoints:
    """Read the track points (``trkpt``; else route points ``rtept``) of a GPX file."""
    source = os.fspath(path)
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        line, col = exc.position
        raise ConfigError(f"line {line}, column {col}", "well-formed GPX XML", str(exc), source) from None
    points = [el for el in root.iter() if el.tag.rsplit("}", 1)[-1] == "trkpt"]
    kind = "trkpt"
    if not points:
        points = [el for el in root.iter() if el.tag.rsplit("}", 1)[-1] == "rtept"]
        kind = "rtept"
    n = len(points)
    lat, lon, h = np.empty(n), np.empty(n), np.empty(n)
    labels = [f"{kind} #{i + 1}" for i in range(n)]
    has_ele = []
    for i, el in enumerate(points):
        for attr in ("lat", "lon"):
            if el.get(attr) is None:
                raise ConfigError(f"{labels[i]} @{attr}", "an attribute in degrees", None, source)
        lat[i] = _number(el.get("lat"), f"{labels[i]} @lat", source, "latitude, deg")
        lon[i] = _number(el.get("lon"), f"{labels[i]} @lon", source, "longitude, deg")
        ele = [c for c in el if c.tag.rsplit("}", 1)[-1] == "ele"]
        has_ele.append(bool(ele))
        h[i] = _number(ele[0].text, f"{labels[i]} <ele>", source, "elevation, m") if ele else 0.0
    if any(has_ele) and not all(has_ele):
        i = has_ele.index(False)
        raise ConfigError(f"{labels[i]} <ele>", "an elevation on every point, or on none", None, source)
    if n and not any(has_ele):
        _no_heights(source, "no <ele> on its points")
    names = [el.text for el in root.iter() if el.tag.rsplit("}", 1)[-1] == "name" and el.text]
    props = {"name": names[0]} if names else {}
    return _finish(lat, lon, h, labels, source, (), props)


def write_gpx(path: str | os.PathLike, lat: ArrayLike, lon: ArrayLike, h: ArrayLike, *, name: str = "") -> None:
    """Write a GPX 1.1 file with one track (lat, lon in rad, h in m)."""
    ns = "http://www.topografix.com/GPX/1/1"
    ET.register_namespace("", ns)
    gpx = ET.Element(f"{{{ns}}}gpx", {"version": "1.1", "creator": "navsim"})
    trk = ET.SubElement(gpx, f"{{{ns}}}trk")
    if name:
        ET.SubElement(trk, f"{{{ns}}}name").text = name
    seg = ET.SubElement(trk, f"{{{ns}}}trkseg")
    lon_deg = (np.degrees(np.asarray(lon, float)) + 180.0) % 360.0 - 180.0
    for a, b, c in zip(np.degrees(np.asarray(lat, float)), lon_deg, np.asarray(h, float)):
        pt = ET.SubElement(seg, f"{{{ns}}}trkpt", {"lat": f"{a:.11f}", "lon": f"{b:.11f}"})
        ET.SubElement(pt, f"{{{ns}}}ele").text = f"{c:.5f}"
    ET.ElementTree(gpx).write(path, encoding="utf-8", xml_declaration=True)


def _no_heights(source: str, what: str) -> None:
    """The warning of a track file without heights (the documented default: 0 m)."""
    import warnings

    warnings.warn(f"track file {Path(source).name}: {what}; heights taken as 0 m above the Earth model "
                  "(a track without grade)", NavsimWarning, stacklevel=3)


# ---------------------------------------------------------------- CSV
_ALIASES = {
    "lat": ("lat_deg", "lat", "latitude", "latitude_deg"),
    "lon": ("lon_deg", "lon", "lng", "long", "longitude", "longitude_deg"),
    "h": ("h_m", "h", "ele", "elevation", "elevation_m", "alt", "alt_m", "altitude", "height", "height_m"),
}


def read_csv(path: str | os.PathLike) -> Waypoints:
    """Read waypoints from a CSV file with a header (columns found by name)."""
    source = os.fspath(path)
    with open(path, newline="", encoding="utf-8") as fh:
        lines = [(i + 1, line) for i, line in enumerate(fh) if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise ConfigError("header", "a header line with lat_deg, lon_deg (, h_m)", "an empty file", source)
    rows = list(csv.reader([line for _, line in lines]))
    header = [c.strip().lower() for c in rows[0]]
    cols = {}
    for key, names in _ALIASES.items():
        found = [header.index(nm) for nm in names if nm in header]
        if found:
            cols[key] = found[0]
        elif key != "h":
            raise ConfigError(f"line {lines[0][0]} (header)", f"a column named one of {list(names)}", file_value(rows[0]), source)
    if "h" not in cols:
        _no_heights(source, f"no height column (one of {list(_ALIASES['h'])})")
    n = len(rows) - 1
    lat, lon, h = np.empty(n), np.empty(n), np.zeros(n)
    labels = []
    for j, row in enumerate(rows[1:]):
        lineno = lines[j + 1][0]
        labels.append(f"line {lineno}")
        for key, arr, what in (("lat", lat, "latitude, deg"), ("lon", lon, "longitude, deg"), ("h", h, "height, m")):
            if key not in cols:
                continue
            c = cols[key]
            if c >= len(row):
                raise ConfigError(f"line {lineno}, column {header[c]}", "a value", "a missing field", source)
            arr[j] = _number(row[c].strip(), f"line {lineno}, column {header[c]}", source, what)
    return _finish(lat, lon, h, labels, source, (), {})


def write_csv(path: str | os.PathLike, lat: ArrayLike, lon: ArrayLike, h: ArrayLike) -> None:
    """Write waypoints as CSV with the header ``lat_deg,lon_deg,h_m``."""
    from .io import atomic_output

    with atomic_output(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["lat_deg", "lon_deg", "h_m"])
        lon_deg = (np.degrees(np.asarray(lon, float)) + 180.0) % 360.0 - 180.0
        for a, b, c in zip(np.degrees(np.asarray(lat, float)), lon_deg, np.asarray(h, float)):
            w.writerow([f"{a:.11f}", f"{b:.11f}", f"{c:.5f}"])


# ---------------------------------------------------------------- to tracks
def read_waypoints(path: str | os.PathLike) -> Waypoints:
    """Dispatch on the suffix: .geojson / .json, .gpx, .csv."""
    suffix = Path(path).suffix.lower()
    readers = {".geojson": read_geojson, ".json": read_geojson, ".gpx": read_gpx, ".csv": read_csv}
    if suffix not in readers:
        raise ConfigError("track.file", f"a file ending in one of {sorted(readers)} or .toml", os.fspath(path))
    if not Path(path).is_file():
        raise ConfigError("track.file", "an existing file", os.fspath(path))
    return readers[suffix](path)


def _earth_from(props: dict, source: str) -> EarthModel:
    name = props.get("earth", "wgs84")
    try:
        return earth_model(name)
    except ConfigError:
        raise ConfigError("earth", "'wgs84' or 'spherical'", name, source) from None


def track_from_waypoints(wp: Waypoints, *, earth: EarthModel | None = None, smoothing_m: float | None = None,
                         cant_model: CantModel | None = None) -> SplineTrack:
    """A :class:`~navsim.track.SplineTrack` from waypoints and their file properties.

    Segments given by arc length refer to the Earth the file declares; when ``earth``
    differs, they are moved to the same points on the new Earth.
    """
    props = wp.properties
    file_earth = _earth_from(props, wp.source)
    if smoothing_m is None or smoothing_m == 0.0:
        smoothing_m = _number(props.get("smoothing_m", 0.0), "properties.smoothing_m", wp.source, "m")
    if cant_model is None:
        cant_model = CantModel.from_dict(props.get("cant"), wp.source)
    name = str(props.get("name") or Path(wp.source).stem or "track")
    track = SplineTrack(wp.lat, wp.lon, wp.h, earth=file_earth, cant_model=cant_model,
                        smoothing_m=smoothing_m, name=name)
    segments = []
    waypoint_s = None
    for i, g in enumerate(wp.segments):
        where = f"segments[{i}]"
        if not isinstance(g, dict):
            raise ConfigError(where, "an object with kind and s_start_m/s_end_m or start_index/end_index", file_value(g),
                              wp.source)
        kind = g.get("kind")
        if not isinstance(kind, str) or not kind:
            raise ConfigError(where + ".kind", "a non-empty string", file_value(kind), wp.source)
        if "start_index" in g or "end_index" in g:
            if waypoint_s is None:
                waypoint_s = track.waypoint_s
            idx = []
            for key in ("start_index", "end_index"):
                v = g.get(key)
                if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v < wp.lat.size:
                    raise ConfigError(f"{where}.{key}", f"a waypoint index in [0, {wp.lat.size - 1}]", v, wp.source)
                idx.append(v)
            a, b = float(waypoint_s[idx[0]]), float(waypoint_s[idx[1]])
        else:
            a = _number(g.get("s_start_m"), where + ".s_start_m", wp.source, "arc length, m")
            b = _number(g.get("s_end_m"), where + ".s_end_m", wp.source, "arc length, m")
        if b < a:
            raise ConfigError(where + ".s_end_m", f">= start {a}", b, wp.source)
        segments.append(TrackSegment(kind, a, b, str(g.get("name", ""))))
    try:
        track = track.with_segments(segments)
    except TrackError as exc:
        raise TrackError(f"{wp.source}: {exc}") from None
    if earth is not None:
        track = track.with_earth(earth)
    return track


def load_polynomial_toml(path: str | os.PathLike, *, earth: EarthModel | None = None,
                         cant_model: CantModel | None = None) -> PolynomialTrack:
    """A :class:`~navsim.track.PolynomialTrack` from a TOML file (see the module docstring)."""
    source = os.fspath(path)
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("toml", "valid TOML", str(exc), source) from None
    if doc.get("kind") != "polynomial":
        raise ConfigError("kind", "'polynomial'", doc.get("kind"), source)
    known = {"kind", "name", "description", "earth", "phi_start_deg", "phi_end_deg", "phi0_deg", "lam0_deg",
             "lam_coeffs", "h_coeffs", "cant", "segments"}
    extra = set(doc) - known
    if extra:
        raise ConfigError("toml", f"only keys {sorted(known)}", sorted(extra), source)
    vals = {}
    for key in ("phi_start_deg", "phi_end_deg"):
        if key not in doc:
            raise ConfigError(key, "a latitude in degrees", None, source)
        vals[key] = _number(doc[key], key, source, "deg")
    phi0 = _number(doc.get("phi0_deg", vals["phi_start_deg"]), "phi0_deg", source, "deg")
    lam0 = _number(doc.get("lam0_deg", 0.0), "lam0_deg", source, "deg")
    if cant_model is None:
        cant_model = CantModel.from_dict(doc.get("cant"), source)
    segments = []
    for i, g in enumerate(doc.get("segments", [])):
        try:
            segments.append(TrackSegment(g["kind"], g["s_start_m"], g["s_end_m"], g.get("name", "")))
        except (KeyError, TypeError):
            raise ConfigError(f"segments[{i}]", "a table with kind, s_start_m, s_end_m", g, source) from None
    file_earth = _earth_from(doc, source)
    try:
        track = PolynomialTrack(
            doc.get("lam_coeffs"), doc.get("h_coeffs"),
            math.radians(vals["phi_start_deg"]), math.radians(vals["phi_end_deg"]),
            phi0=math.radians(phi0), lam0=math.radians(lam0), earth=file_earth,
            segments=segments, cant_model=cant_model, name=str(doc.get("name", Path(source).stem)),
        )
    except ConfigError as exc:
        raise ConfigError(exc.field, exc.expected, exc.got, source) from None
    if earth is not None:
        track = track.with_earth(earth)
    return track


def load_track(path: str | os.PathLike, *, earth: EarthModel | None = None, smoothing_m: float = 0.0,
               cant_model: CantModel | None = None) -> PolynomialTrack | SplineTrack:
    """Any supported track file as a track; ``earth`` overrides the file's Earth model."""
    if Path(path).suffix.lower() == ".toml":
        if not Path(path).is_file():
            raise ConfigError("track.file", "an existing file", os.fspath(path))
        return load_polynomial_toml(path, earth=earth, cant_model=cant_model)
    return track_from_waypoints(read_waypoints(path), earth=earth, smoothing_m=smoothing_m, cant_model=cant_model)


# ======================================================================== bundled tracks
_BUNDLED_SUFFIXES = (".toml", ".geojson")


def _bundled_dir() -> Traversable:
    return resources.files("navsim").joinpath("data", "tracks")  # type: ignore[call-arg]  # the 3.10 stub takes one segment; a package folder is a Path


def list_bundled_tracks() -> list[str]:
    """Names of the bundled tracks (``"paper-2012"``, ``"mountain-railway"``, ``"urban-road"``)."""
    names = []
    for entry in _bundled_dir().iterdir():
        for suffix in _BUNDLED_SUFFIXES:
            if entry.name.endswith(suffix):
                names.append(entry.name[: -len(suffix)])
    return sorted(names)


def load_bundled_track(name: str, *, earth: EarthModel | None = None) -> PolynomialTrack | SplineTrack:
    """A bundled track by name; ``earth`` overrides the Earth model the file declares.

    The polynomial track's coefficients are angles and heights, valid on either Earth;
    waypoint tracks keep their lat/lon/h and re-measure arc length on the given Earth.
    """
    if name not in list_bundled_tracks():  # a name only: no separators, no paths outside the package
        raise ConfigError("track.bundled", f"the name of a bundled track, one of {list_bundled_tracks()} "
                                           "(files go in track.file)", name)
    for suffix in _BUNDLED_SUFFIXES:
        entry = _bundled_dir().joinpath(name + suffix)
        if entry.is_file():
            with resources.as_file(entry) as path:
                return load_track(path, earth=earth)
    raise ConfigError("track.bundled", f"one of {list_bundled_tracks()}", name)


def load_track_file(path: str | os.PathLike, *, earth: EarthModel | None = None, smoothing_m: float = 0.0,
                    cant_model: CantModel | None = None) -> PolynomialTrack | SplineTrack:
    """A track from a file (.geojson/.json, .gpx, .csv, .toml); see :mod:`navsim.trackio`."""
    return load_track(path, earth=earth, smoothing_m=smoothing_m, cant_model=cant_model)
