"""The track types: annotations (:class:`TrackSegment`), the :class:`Track` protocol, the frame
(:class:`TrackFrame`) and the cant model (:class:`CantModel`, railway design cant
tan(cant) = v_design^2 kappa / g saturated smoothly at ``max_cant``; Lindahl 2001).

Sign conventions: heading clockwise from north, pitch = grade angle (up positive),
curvature positive turning right, positive cant = roll right side down.
"""


import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike

from ..earth import EarthModel
from ..errors import ConfigError

_SOFTCLIP_POWER = 8


@dataclass(frozen=True, slots=True)
class TrackSegment:
    """An annotation of the track between two arc lengths.

    Parameters
    ----------
    kind : str
        ``"tunnel"``, ``"cutting"``, ``"urban"``, ``"bridge"``, ``"station"``, ...
    s_start, s_end : float
        Arc length at the start and the end, m, ``s_start <= s_end``.
    name : str
        Optional label.
    """

    kind: str
    s_start: float
    s_end: float
    name: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.kind, str) or not self.kind:
            raise ConfigError("segment.kind", "a non-empty string", self.kind)
        for fld in ("s_start", "s_end"):
            value = getattr(self, fld)
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise ConfigError(f"segment.{fld}", "a number (m)", value) from None
            if not math.isfinite(number):
                raise ConfigError(f"segment.{fld}", "a finite number (m)", value)
            object.__setattr__(self, fld, number)
        if self.s_end < self.s_start:
            raise ConfigError("segment.s_end", f"s_end >= s_start = {self.s_start}", self.s_end)


@runtime_checkable
class Track(Protocol):
    """What the motion module needs from a track (all tracks here satisfy it)."""

    earth: EarthModel
    length: float
    segments: tuple[TrackSegment, ...]

    def geodetic(self, s: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """pos, d1, d2, each ``np.shape(s) + (3,)``: [lat, lon, h] (rad, rad, m) and
        their first and second derivatives with respect to true arc length s."""
        ...

    def cant(self, s: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Cant as a roll angle (rad, right side down positive) and d cant / ds (rad/m)."""
        ...


@dataclass(frozen=True, slots=True)
class TrackFrame:
    """Geometry of a track at arc lengths s (every array has the shape of s, or + (3,)).

    Attributes
    ----------
    lat, lon, h : ndarray
        Geodetic position, rad, rad, m.
    tangent_n : ndarray (..., 3)
        Unit tangent in ENU, t = [(R_E+h) cos(lat) lon', (R_N+h) lat', h'].
    dtangent_n_ds : ndarray (..., 3)
        d/ds of the ENU components of the unit tangent, 1/m (product rule with the radii
        derivatives; it includes the rotation of the ENU frame along the track).
    heading, pitch : ndarray
        atan2(t_E, t_N) clockwise from north, and asin(t_U) (grade angle, up positive), rad.
    dheading_ds, dpitch_ds : ndarray
        Their derivatives, rad/m: (t_N t'_E - t_E t'_N) / (t_E^2 + t_N^2), t'_U / sqrt(1 - t_U^2).
    cant, dcant_ds : ndarray
        Cant (roll, right side down positive), rad, and its derivative, rad/m.
    curvature : ndarray
        Signed geodesic curvature of the horizontal projection, 1/m, positive turning
        right: (dheading_ds - t_E tan(lat) / (R_E + h)) / cos(pitch). The second term
        removes the rotation of the ENU frame about Up (meridian convergence) so that a
        geodesic has zero curvature and a small circle of radius r has ~1/r.
    """

    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    tangent_n: np.ndarray
    dtangent_n_ds: np.ndarray
    heading: np.ndarray
    pitch: np.ndarray
    dheading_ds: np.ndarray
    dpitch_ds: np.ndarray
    cant: np.ndarray
    dcant_ds: np.ndarray
    curvature: np.ndarray


@dataclass(frozen=True, slots=True)
class CantModel:
    """How a track's cant (superelevation, a roll angle) is made.

    Parameters
    ----------
    mode : str
        ``"none"`` (zero cant) or ``"design"``: tan(cant) = v_design^2 kappa / g with kappa
        the horizontal curvature, smoothly limited to ``max_cant``.
    design_speed_mps : float
        Design speed v_design, m/s (mode ``"design"``).
    max_cant : float
        Largest cant angle, rad. 150 mm of cant on standard gauge (1435 mm; 1500 mm between
        rail-head centres) is asin(0.150 / 1.500) = 0.1002 rad; see :meth:`from_mm`.
    gravity_mps2 : float
        g in the design formula, m/s^2.
    """

    mode: str = "none"
    design_speed_mps: float = 0.0
    max_cant: float = math.asin(0.150 / 1.500)
    gravity_mps2: float = 9.81

    def __post_init__(self) -> None:
        if self.mode == "zero":
            object.__setattr__(self, "mode", "none")
        if self.mode not in ("none", "design"):
            raise ConfigError("cant.mode", "'none' or 'design'", self.mode)
        if self.mode == "design":
            for fld in ("design_speed_mps", "max_cant", "gravity_mps2"):
                value = getattr(self, fld)
                if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                    raise ConfigError(f"cant.{fld}", "a positive finite number", value)
            if self.max_cant >= math.pi / 4:
                raise ConfigError("cant.max_cant", "an angle below pi/4 rad", self.max_cant)

    @classmethod
    def from_mm(cls, design_speed_mps: float, max_cant_mm: float = 150.0,
                rail_spacing_mm: float = 1500.0) -> "CantModel":
        """Design cant with the limit given as rail-height difference over rail spacing."""
        if not 0 < max_cant_mm < rail_spacing_mm:
            raise ConfigError("cant.max_cant_mm", f"in (0, {rail_spacing_mm}) mm", max_cant_mm)
        return cls("design", design_speed_mps, math.asin(max_cant_mm / rail_spacing_mm))

    @classmethod
    def from_dict(cls, data: dict[str, Any] | None, source: str | None = None) -> "CantModel":
        """From a file's ``cant`` table: ``mode``, ``design_speed_mps`` and either
        ``max_cant_deg`` or ``max_cant_mm`` (with optional ``rail_spacing_mm``)."""
        if not data:
            return cls()
        if not isinstance(data, dict):
            raise ConfigError("cant", "a table/object", data, source)
        known = {"mode", "design_speed_mps", "max_cant_deg", "max_cant_mm", "rail_spacing_mm",
                 "gravity_mps2"}
        extra = set(data) - known
        if extra:
            raise ConfigError("cant", f"only keys {sorted(known)}", sorted(extra), source)
        mode = data.get("mode", "none")
        if mode in ("none", "zero"):
            return cls()
        try:
            speed = float(data["design_speed_mps"])
            if "max_cant_deg" in data:
                max_cant = math.radians(float(data["max_cant_deg"]))
            else:
                spacing = float(data.get("rail_spacing_mm", 1500.0))
                max_cant = math.asin(float(data.get("max_cant_mm", 150.0)) / spacing)
            return cls(mode, speed, max_cant, float(data.get("gravity_mps2", 9.81)))
        except KeyError as exc:
            raise ConfigError(f"cant.{exc.args[0]}", "present for mode 'design'", None, source) from None
        except (TypeError, ValueError) as exc:
            if isinstance(exc, ConfigError):
                raise ConfigError(exc.field, exc.expected, exc.got, source) from None
            raise ConfigError("cant", "numbers for design_speed_mps / max_cant_*", data, source) from None

    def to_dict(self) -> dict[str, Any]:
        if self.mode == "none":
            return {"mode": "none"}
        return {"mode": "design", "design_speed_mps": self.design_speed_mps,
                "max_cant_deg": math.degrees(self.max_cant), "gravity_mps2": self.gravity_mps2}

    def evaluate(self, kappa: np.ndarray, dkappa_ds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cant and d cant / ds from curvature (1/m) and its derivative (1/m^2)."""
        kappa = np.asarray(kappa, dtype=float)
        if self.mode == "none":
            return np.zeros_like(kappa), np.zeros_like(kappa)
        gain = self.design_speed_mps**2 / self.gravity_mps2
        x = gain * kappa
        raw = np.arctan(x)  # tan(cant) = v^2 kappa / g
        draw = gain * np.asarray(dkappa_ds, dtype=float) / (1.0 + x * x)
        q = (raw / self.max_cant) ** _SOFTCLIP_POWER
        p = 1.0 / _SOFTCLIP_POWER
        return raw * (1.0 + q) ** (-p), draw * (1.0 + q) ** (-p - 1.0)
