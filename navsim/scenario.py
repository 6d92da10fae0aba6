"""Scenarios: frozen, typed configuration that round-trips to TOML.

A scenario is track + motion + IMU + GNSS + outages + duration + rates + initial
uncertainty (+ an optional wheel odometer, ``[odometer]``, and barometric altimeter, ``[baro]``
(:class:`navsim.sensors.baro.BaroConfig`), both off by default). The ``[outages]`` table holds the fields of
:class:`navsim.sensors.outages.OutageModel` directly. Bundled scenarios live in ``navsim/scenarios/*.toml``; :func:`load_scenario`
takes a bundled name or a path. Every value is checked when the scenario is built, and a
bad one raises :class:`~navsim.errors.ConfigError` naming the field (dotted path), the
expectation and the value: unknown keys, wrong types, negative or non-multiple rates,
malformed files, impossible tracks and motions.

Degrees appear only here, at the edge, in fields whose names end in ``_deg``.

Examples
--------
>>> from navsim.scenario import load_scenario
>>> sc = load_scenario("paper-2012")
>>> sc.timing.nav_period_s, sc.timing.steps
(0.01, 100000)
>>> sc2 = sc.with_overrides({"timing": {"duration_s": 10.0}})
>>> sc2.timing.steps
1000
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import sys
import types
import typing
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from .errors import ConfigError, check_multiple, check_positive
from .sensors.baro import BaroConfig
from .sensors.odometer import PRESET_NAMES as _ODOMETER_PRESETS
from .sensors.odometer import OdometerModel
from .sensors.outages import OutageModel

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "TimingConfig",
    "TrackConfig",
    "StationConfig",
    "OscillationConfig",
    "MotionConfig",
    "ImuConfig",
    "GnssConfig",
    "InitialUncertainty",
    "OdometerConfig",
    "BaroConfig",
    "Scenario",
    "load_scenario",
    "list_scenarios",
]


# ============================================================================ sections
@dataclass(frozen=True, slots=True)
class TimingConfig:
    """The time base. Every period is a whole multiple of ``tick_s``.

    Attributes
    ----------
    tick_s : base tick, s. imu_period_s : IMU sample period h, s (a multiple of the
    tick). nav_period_s : navigation step, s (a multiple of the IMU period: the step
    over which the multiple integrals of seed 000 are formed). gnss_period_s : GNSS
    epoch period, s (a multiple of the navigation step). duration_s : episode length, s
    (a multiple of the navigation step).
    """

    tick_s: float = 0.01
    imu_period_s: float = 0.01
    nav_period_s: float = 0.01
    gnss_period_s: float = 1.0
    duration_s: float = 1000.0

    def __post_init__(self) -> None:
        check_positive("timing.tick_s", self.tick_s)
        check_multiple("timing.imu_period_s", self.imu_period_s, self.tick_s, "timing.tick_s")
        check_multiple("timing.nav_period_s", self.nav_period_s, self.imu_period_s, "timing.imu_period_s")
        check_multiple("timing.gnss_period_s", self.gnss_period_s, self.nav_period_s, "timing.nav_period_s")
        check_multiple("timing.duration_s", self.duration_s, self.nav_period_s, "timing.nav_period_s")

    @property
    def imu_ticks(self) -> int:
        """Ticks per IMU sample."""
        return round(self.imu_period_s / self.tick_s)

    @property
    def samples_per_step(self) -> int:
        """IMU samples per navigation step (m)."""
        return round(self.nav_period_s / self.imu_period_s)

    @property
    def nav_ticks(self) -> int:
        return self.imu_ticks * self.samples_per_step

    @property
    def steps_per_epoch(self) -> int:
        """Navigation steps per GNSS epoch."""
        return round(self.gnss_period_s / self.nav_period_s)

    @property
    def steps(self) -> int:
        """Navigation steps in the episode."""
        return round(self.duration_s / self.nav_period_s)


@dataclass(frozen=True, slots=True)
class TrackConfig:
    """Which track: a bundled one by name, or a file (GeoJSON, GPX, CSV).

    ``file`` is relative to the scenario file's folder. ``cant`` is ``"track"`` (the
    track's own cant), ``"none"``, or ``"design"`` (railway design cant from curvature
    at ``cant_design_speed_mps``, limited to ``cant_max_deg``).
    """

    bundled: str = ""
    file: str = ""
    cant: str = "track"
    cant_design_speed_mps: float = 25.0
    cant_max_deg: float = 6.0
    smoothing_m: float = 0.0

    def __post_init__(self) -> None:
        if bool(self.bundled) == bool(self.file):
            raise ConfigError("track", "exactly one of track.bundled or track.file", {"bundled": self.bundled, "file": self.file})
        if self.bundled and (any(c in self.bundled for c in "/\\:") or self.bundled.startswith(".")):
            raise ConfigError("track.bundled", "the name of a bundled track, without separators (files go in track.file)",
                              self.bundled)
        if self.cant not in ("track", "none", "design"):
            raise ConfigError("track.cant", "one of 'track', 'none', 'design'", self.cant)


@dataclass(frozen=True, slots=True)
class StationConfig:
    """A timetable stop: platform mark (arc length, m) and dwell time (s)."""

    s_m: float
    dwell_s: float = 30.0


@dataclass(frozen=True, slots=True)
class OscillationConfig:
    """A harmonic body oscillation on one angle ("heading", "pitch" or "roll").

    Give either ``amplitude_deg`` (angle amplitude) or ``rate_amplitude_deg_s`` (rate
    amplitude = angle amplitude * 2 pi f, as seed 001 specifies its test motion).
    """

    angle: str
    frequency_hz: float
    amplitude_deg: float = 0.0
    rate_amplitude_deg_s: float = 0.0
    phase_deg: float = 0.0

    def amplitude_rad(self) -> float:
        if self.rate_amplitude_deg_s:
            return math.radians(self.rate_amplitude_deg_s) / (2.0 * math.pi * self.frequency_hz)
        return math.radians(self.amplitude_deg)


@dataclass(frozen=True, slots=True)
class MotionConfig:
    """Along-track motion.

    ``profile``: ``"constant"`` (``speed_mps`` from ``start_s_m``, plus the harmonic
    variation ``speed_amplitude_mps * sin(2 pi t / speed_period_s)`` when the amplitude is
    non-zero), ``"timetable"``
    (``stations`` with ``cruise_speed_mps``, ``max_accel_mps2``, ``max_decel_mps2``,
    ``jerk_time_s``) or ``"external"`` (samples pushed step by step; ``start_s_m`` and
    ``speed_mps`` give the initial state).
    """

    profile: str = "constant"
    speed_mps: float = 20.0
    speed_amplitude_mps: float = 0.0
    speed_period_s: float = 300.0
    start_s_m: float = 0.0
    stations: tuple[StationConfig, ...] = ()
    cruise_speed_mps: float = 25.0
    max_accel_mps2: float = 0.8
    max_decel_mps2: float = 0.8
    jerk_time_s: float = 2.0
    oscillations: tuple[OscillationConfig, ...] = ()

    def __post_init__(self) -> None:
        if self.profile not in ("constant", "timetable", "external"):
            raise ConfigError("motion.profile", "one of 'constant', 'timetable', 'external'", self.profile)
        if self.profile == "timetable" and len(self.stations) < 2:
            raise ConfigError("motion.stations", "at least two stations for a timetable", len(self.stations))
        if self.start_s_m < 0:
            raise ConfigError("motion.start_s_m", "an arc length >= 0", self.start_s_m)
        if not (self.speed_period_s > 0 and math.isfinite(self.speed_period_s)):
            raise ConfigError("motion.speed_period_s", "a positive period (s)", self.speed_period_s)
        if not (math.isfinite(self.speed_amplitude_mps) and abs(self.speed_amplitude_mps) < abs(self.speed_mps)
                or self.speed_amplitude_mps == 0.0):
            raise ConfigError("motion.speed_amplitude_mps", "a finite amplitude below |speed_mps| (no reversal)",
                              self.speed_amplitude_mps)


@dataclass(frozen=True, slots=True)
class ImuConfig:
    """IMU: a preset of :func:`navsim.sensors.imu.imu_preset` plus per-field overrides.

    ``orders``: how many multiple-integral orders r = 1..orders are produced (seed 000
    uses up to 4). ``quadrature_nodes``: Gauss-Legendre nodes per sample used to
    integrate the true motion. ``gyro`` / ``accel``: overrides of the preset's fields.
    """

    preset: str = "ideal"
    orders: int = 4
    quadrature_nodes: int = 4
    gyro: dict = field(default_factory=dict)
    accel: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not 1 <= self.orders <= 6:
            raise ConfigError("imu.orders", "an integer in 1..6", self.orders)
        if not 1 <= self.quadrature_nodes <= 16:
            raise ConfigError("imu.quadrature_nodes", "an integer in 1..16", self.quadrature_nodes)


@dataclass(frozen=True, slots=True)
class GnssConfig:
    """GNSS receiver: constellation, error preset and overrides.

    ``constellation``: ``"gps"``, ``"glonass"`` or ``"yuma:<file>"`` (relative to the
    scenario file). ``epoch_phase_deg`` rotates the constellation in time (changes the
    geometry). ``overrides``: fields of the preset's error model.

    ``lever_arm_m``: position of the antenna phase centre relative to the IMU in body
    axes (x right, y forward, z up), m; at most ``MAX_LEVER_ARM_M`` per component. The
    measurements are made at the antenna (Groves 2013, section 14.2.3); the default
    ``[0, 0, 0]`` puts the antenna at the IMU and changes no number.
    """

    MAX_LEVER_ARM_M = 100.0

    enabled: bool = True
    constellation: str = "gps"
    preset: str = "paper-2012"
    epoch_phase_deg: float = 0.0
    overrides: dict = field(default_factory=dict)
    lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        arm = self.lever_arm_m
        if isinstance(arm, (str, bytes)) or not hasattr(arm, "__len__") or len(arm) != 3:
            raise ConfigError("gnss.lever_arm_m", "three numbers [x right, y forward, z up], m", arm)
        values = []
        for value in arm:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or abs(value) > self.MAX_LEVER_ARM_M:
                raise ConfigError("gnss.lever_arm_m",
                                  f"three finite numbers of at most {self.MAX_LEVER_ARM_M:g} m in magnitude", list(arm))
            values.append(float(value))
        object.__setattr__(self, "lever_arm_m", tuple(values))

    @property
    def has_lever_arm(self) -> bool:
        """True when the antenna is not at the IMU."""
        return any(v != 0.0 for v in self.lever_arm_m)


@dataclass(frozen=True, slots=True)
class OdometerConfig:
    """Wheel odometer (:mod:`navsim.sensors.odometer`): off by default.

    ``preset``: one of :meth:`navsim.sensors.odometer.OdometerModel.preset`
    (``"ideal"``, ``"rail-tachometer"``, ``"car-wheel-speed"``); ``overrides``: fields of
    the preset's :class:`~navsim.sensors.odometer.OdometerModel`. The table is left out
    of :meth:`Scenario.to_dict` (and so of the TOML text and the config hash) while it
    holds its defaults, so scenarios without an odometer are unchanged.
    """

    enabled: bool = False
    preset: str = "rail-tachometer"
    overrides: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.preset not in _ODOMETER_PRESETS:
            raise ConfigError("odometer.preset", f"one of {_ODOMETER_PRESETS}", self.preset)
        self.model()  # validates the overrides

    def model(self) -> OdometerModel:
        """The truth-side odometer model: the preset with the overrides applied."""
        from .sensors.models import replace_checked  # the sensor package imports this module

        base = OdometerModel.preset(self.preset)
        return replace_checked(base, self.overrides, "odometer.overrides") if self.overrides else base


@dataclass(frozen=True, slots=True)
class InitialUncertainty:
    """1-sigma of the initial estimate handed to estimators (per axis).

    The simulator draws the prior's error from these (stream ``initial_error``).
    """

    position_m: float = 10.0
    velocity_mps: float = 0.1
    attitude_deg: float = 0.1

    def __post_init__(self) -> None:
        for name in ("position_m", "velocity_mps", "attitude_deg"):
            value = getattr(self, name)
            if not (value >= 0 and math.isfinite(value)):
                raise ConfigError(f"initial.{name}", "a finite sigma >= 0", value)

    def covariance(self) -> Any:
        """The prior's 9 x 9 covariance over :data:`navsim.types.STATE_LABELS`: diagonal,
        ``position_m^2`` (m^2), ``velocity_mps^2`` (m^2/s^2), ``radians(attitude_deg)^2``
        (rad^2), three axes each."""
        import numpy as np

        sig_att = math.radians(self.attitude_deg)
        return np.diag(np.repeat([self.position_m**2, self.velocity_mps**2, sig_att**2], 3))


@dataclass(frozen=True, slots=True)
class Scenario:
    """A complete scenario. Build with :func:`load_scenario` or :meth:`from_dict`."""

    name: str
    description: str = ""
    earth: str = "wgs84"
    timing: TimingConfig = TimingConfig()
    track: TrackConfig = TrackConfig(bundled="paper-2012")
    motion: MotionConfig = MotionConfig()
    imu: ImuConfig = ImuConfig()
    gnss: GnssConfig = GnssConfig()
    outages: OutageModel = OutageModel()
    initial: InitialUncertainty = InitialUncertainty()
    odometer: OdometerConfig = OdometerConfig()
    baro: BaroConfig = BaroConfig()
    base_dir: str = ""  # folder that relative file names refer to (not serialised)

    def __post_init__(self) -> None:
        if self.earth not in ("spherical", "wgs84"):
            raise ConfigError("earth", "one of 'spherical', 'wgs84'", self.earth)

    # -- (de)serialisation -------------------------------------------------------------
    @classmethod
    def from_dict(cls, data: dict, source: str | None = None, base_dir: str = "") -> "Scenario":
        """Build from a nested dict (as read from TOML); errors name the dotted field."""
        try:
            scenario = _from_dict(cls, data, "", exclude=("base_dir",))
        except ConfigError as exc:
            if source and not exc.source:
                raise ConfigError(exc.field, exc.expected, exc.got, source=source) from None
            raise
        from .validation import validate_scenario

        scenario = dataclasses.replace(scenario, base_dir=base_dir)
        try:
            validate_scenario(scenario)  # the cross-section and physical checks
        except ConfigError as exc:
            if source and not exc.source:
                raise ConfigError(exc.field, exc.expected, exc.got, source=source) from None
            raise
        return scenario

    def to_dict(self) -> dict:
        """Nested dict of plain values (TOML-ready); ``from_dict(to_dict())`` round-trips."""
        data = _to_dict(self)
        data.pop("base_dir", None)
        for section, default in _OMIT_SECTION_IF_DEFAULT:
            if data.get(section) == _to_dict(default):
                del data[section]
        return data

    def to_toml(self) -> str:
        import tomli_w

        return tomli_w.dumps(self.to_dict())

    def with_overrides(self, overrides: dict) -> "Scenario":
        """A copy with nested overrides merged in, e.g. ``{"timing": {"duration_s": 60}}``."""
        return Scenario.from_dict(_deep_merge(self.to_dict(), overrides), base_dir=self.base_dir)

    def config_hash(self) -> str:
        """SHA-256 (16 hex digits) of the canonical JSON of :meth:`to_dict` plus the contents
        digest of every user file the scenario reads (:meth:`file_digests`).

        Fields added after hashes were first published (:data:`_HASH_OMIT_IF_DEFAULT`)
        are left out while they hold their default, so every earlier scenario keeps its
        hash; any other value enters the hash.
        """
        data = self.to_dict()
        for section, name, default in _HASH_OMIT_IF_DEFAULT:
            if data.get(section, {}).get(name) == default:
                data[section] = {k: v for k, v in data[section].items() if k != name}
        files = self.file_digests()
        if files:  # user files enter by their contents: an edited track is another scenario
            data["files"] = files
        blob = json.dumps(data, sort_keys=True, separators=(",", ":"), default=str)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]

    def file_dependencies(self) -> dict[str, Path]:
        """The user files the scenario reads, by field: ``track.file`` and a YUMA almanac
        (``gnss.constellation = "yuma:<file>"``), resolved as :meth:`resolve_path` does.
        Bundled data (``track.bundled``, the scenario presets) is versioned with navsim."""
        deps = {}
        if self.track.file:
            deps["track.file"] = self.file_candidates(self.track.file, "track")[0]
        if self.gnss.constellation.startswith("yuma:"):
            deps["gnss.constellation"] = self.file_candidates(self.gnss.constellation[5:], "almanac")[0]
        return deps

    def file_digests(self) -> dict[str, str]:
        """SHA-256 (16 hex digits) of the contents of each :meth:`file_dependencies` file
        (``"missing"`` for a file that cannot be read: loading it reports the error)."""
        out = {}
        for name, path in self.file_dependencies().items():
            try:
                out[name] = hashlib.sha256(path.read_bytes()).hexdigest()[:16]
            except OSError:
                out[name] = "missing"
        return out

    def file_candidates(self, name: str, kind: str = "track") -> list[Path]:
        """Where a file name of the scenario is looked for, in order; the first existing one
        is used (the first one when none exists).

        1. an absolute path: itself only;
        2. relative to the scenario file's folder (``base_dir``; a scenario not read from
           a file has none);
        3. relative to the current directory;
        4. a bare name (no folder separators, not ``..``): navsim's bundled data,
           ``navsim/data/tracks`` for ``kind="track"``, ``navsim/data/almanac`` for
           ``kind="almanac"``.
        """
        path = Path(name)
        if path.is_absolute():
            return [path]
        found = [Path(self.base_dir) / path] if self.base_dir else []
        found.append(Path.cwd() / path)
        if "/" not in name and "\\" not in name and name not in ("", ".", ".."):
            folder = {"track": "tracks", "almanac": "almanac"}.get(kind)
            if folder is None:
                raise ConfigError("kind", "'track' or 'almanac'", kind)
            found.append(Path(str(resources.files("navsim") / "data" / folder / name)))
        for p in found:
            if p.is_file():
                return [p] + [q for q in found if q != p]
        return found

    def resolve_path(self, name: str, kind: str = "track", field: str | None = None) -> Path:
        """The file a scenario names (``track.file``, a YUMA almanac): the first existing
        place of :meth:`file_candidates` (scenario folder, current directory, bundled
        data). Raises :class:`ConfigError` naming the field and every place tried
        (never the file's contents) when none exists."""
        candidates = self.file_candidates(name, kind)
        if candidates[0].is_file():
            return candidates[0]
        field = field or ("track.file" if kind == "track" else "gnss.constellation")
        raise ConfigError(field, f"an existing file (looked in: {', '.join(str(p) for p in candidates)})", name)


_HASH_OMIT_IF_DEFAULT = (("gnss", "lever_arm_m", [0.0, 0.0, 0.0]), ("motion", "speed_amplitude_mps", 0.0),
                         ("motion", "speed_period_s", 300.0))

_OMIT_SECTION_IF_DEFAULT = (("odometer", OdometerConfig()), ("baro", BaroConfig()))
"""Sections added after scenarios were first published, left out of :meth:`Scenario.to_dict`
(so of the TOML text and the hash) while they hold their defaults."""
"""(section, field, default as in :meth:`Scenario.to_dict`) left out of the hash at the default."""


# ============================================================================ loading
def list_scenarios() -> list[str]:
    """Names of the bundled scenarios."""
    folder = resources.files("navsim") / "scenarios"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load a bundled scenario by name (``"paper-2012"``) or a TOML file by path."""
    text_path = Path(name_or_path)
    if text_path.suffix == ".toml" or text_path.exists():
        path = text_path
        if not path.exists():
            raise ConfigError("scenario", "an existing TOML file", str(name_or_path))
    else:
        path = Path(str(resources.files("navsim") / "scenarios" / f"{name_or_path}.toml"))
        if not path.exists():
            raise ConfigError("scenario", f"a bundled scenario {list_scenarios()} or a .toml path", str(name_or_path))
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise ConfigError("scenario", "a UTF-8 text file", f"byte 0x{exc.object[exc.start]:02x} at offset {exc.start}",
                          source=path.name) from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("scenario", "valid TOML", f"{exc}", source=str(path)) from None
    return Scenario.from_dict(data, source=path.name, base_dir=str(path.parent))


# ============================================================================ machinery
def _deep_merge(base: dict, overrides: dict) -> dict:
    merged = dict(base)
    for key, value in overrides.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict) and key not in ("gyro", "accel", "overrides"):
            merged[key] = _deep_merge(merged[key], value)
        else:
            merged[key] = value
    return merged


def _type_name(tp: Any) -> str:
    return getattr(tp, "__name__", str(tp))


def _convert(tp: Any, value: Any, path: str) -> Any:
    origin = typing.get_origin(tp)
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise ConfigError(path, "a table", value)
        return _from_dict(tp, value, f"{path}.")
    if origin is tuple:
        args = typing.get_args(tp)
        if not isinstance(value, (list, tuple)):
            raise ConfigError(path, "an array", value)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, f"{path}[{i}]") for i, v in enumerate(value))
        if len(args) != len(value):
            raise ConfigError(path, f"an array of {len(args)} values", list(value))
        return tuple(_convert(a, v, f"{path}[{i}]") for i, (a, v) in enumerate(zip(args, value)))
    if origin in (typing.Union, types.UnionType):
        errors = []
        for arg in typing.get_args(tp):
            try:
                return _convert(arg, value, path)
            except ConfigError as exc:
                errors.append(exc)
        raise errors[0]
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(path, "a number", value)
        if not math.isfinite(value):
            raise ConfigError(path, "a finite number", value)
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not (isinstance(value, int) or (isinstance(value, float) and value.is_integer())):
            raise ConfigError(path, "an integer", value)
        return int(value)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(path, "true or false", value)
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(path, "a string", value)
        return value
    if tp is dict or origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(path, "a table", value)
        return dict(value)
    raise TypeError(f"unsupported config type {tp!r} at {path}")  # programming error


def _from_dict(cls: Any, data: dict, prefix: str, exclude: tuple[str, ...] = ()) -> Any:
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls) if f.init and f.name not in exclude]
    for key in data:
        if key not in names:
            raise ConfigError(f"{prefix}{key}", f"a known key of [{prefix.rstrip('.') or 'scenario'}]: {names}", key)
    kwargs = {}
    for f in dataclasses.fields(cls):
        if f.name in data:
            kwargs[f.name] = _convert(hints[f.name], data[f.name], f"{prefix}{f.name}")
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING and f.init:
            raise ConfigError(f"{prefix}{f.name}", "a value (this field is required)", None)
    return cls(**kwargs)


def _to_dict(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj):
        return {f.name: _to_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj) if f.init}
    if isinstance(obj, (tuple, list)):
        return [_to_dict(v) for v in obj]
    if isinstance(obj, dict):
        return {k: _to_dict(v) for k, v in obj.items()}
    return obj
