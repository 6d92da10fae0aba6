"""The frame of a track at arc lengths s: tangent, heading, pitch, curvature and cant
(:func:`track_frame`), segment masks (:func:`segment_mask`) and cant models (:func:`with_cant`).
"""


import math
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ConfigError
from .arclength import ArcLengthTrack
from .base import CantModel, Track, TrackFrame


def track_frame(track: Track, s: ArrayLike) -> TrackFrame:
    """Tangent, heading, pitch, curvature and cant of a track at arc lengths s (m).

    See :class:`TrackFrame` for the definitions; everything is analytic in the track's
    first and second derivatives.
    """
    if isinstance(track, ArcLengthTrack):
        pos, d1, d2, cant, dcant = track._geodetic_and_cant(s)
    else:
        pos, d1, d2 = track.geodetic(s)
        cant, dcant = track.cant(s)
    earth = track.earth
    lat, lon, h = pos[..., 0], pos[..., 1], pos[..., 2]
    lat1, lon1, h1 = d1[..., 0], d1[..., 1], d1[..., 2]
    lat2, lon2, h2 = d2[..., 0], d2[..., 1], d2[..., 2]
    r_n, r_e = earth.radii(lat)
    dr_n, dr_e = earth.radii_derivative(lat)
    sl, cl = np.sin(lat), np.cos(lat)
    t_e = (r_e + h) * cl * lon1
    t_n = (r_n + h) * lat1
    t_u = h1
    dt_e = (dr_e * lat1 + h1) * cl * lon1 - (r_e + h) * sl * lat1 * lon1 + (r_e + h) * cl * lon2
    dt_n = (dr_n * lat1 + h1) * lat1 + (r_n + h) * lat2
    dt_u = h2
    horiz2 = t_e * t_e + t_n * t_n
    horiz = np.sqrt(horiz2)
    heading = np.arctan2(t_e, t_n)
    pitch = np.arcsin(np.clip(t_u, -1.0, 1.0))
    dheading = (t_n * dt_e - t_e * dt_n) / horiz2
    dpitch = dt_u / horiz  # sqrt(1 - t_U^2) = horizontal norm for a unit tangent
    curvature = (dheading - t_e * np.tan(lat) / (r_e + h)) / horiz
    return TrackFrame(
        lat=lat, lon=lon, h=h,
        tangent_n=np.stack([t_e, t_n, t_u], axis=-1),
        dtangent_n_ds=np.stack([dt_e, dt_n, dt_u], axis=-1),
        heading=heading, pitch=pitch, dheading_ds=dheading, dpitch_ds=dpitch,
        cant=cant, dcant_ds=dcant, curvature=curvature,
    )


def segment_mask(track: Track, s: ArrayLike, kind: str | Sequence[str]) -> np.ndarray:
    """True where s lies inside a segment of the given kind(s), shape of s."""
    s = np.asarray(s, dtype=float)
    kinds = {kind} if isinstance(kind, str) else set(kind)
    mask = np.zeros(s.shape, dtype=bool)
    for seg in track.segments:
        if seg.kind in kinds:
            mask |= (s >= seg.s_start) & (s <= seg.s_end)
    return mask


def with_cant(track: Track, mode: str = "none", design_speed: float = 0.0,
              max_cant: float = math.asin(0.150 / 1.500)) -> Track:
    """The track with another cant model: ``mode`` "none" or "design" (design speed m/s,
    maximum cant rad). "track" returns the track unchanged."""
    if mode == "track":
        return track
    model = CantModel() if mode in ("none", "zero") else CantModel(mode, float(design_speed), float(max_cant))
    if not hasattr(track, "with_cant_model"):
        raise ConfigError("track", "a navsim track that supports with_cant_model", type(track).__name__)
    return track.with_cant_model(model)  # type: ignore[attr-defined]
