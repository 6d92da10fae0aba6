"""The navigation error: one definition used by the metrics and by every reward.

Position error of an estimate against the truth in the local-level (ENU) frame at the
true position, by linearisation about the truth::

    dE = wrap(lon_est - lon) (R_E + h) cos(lat)
    dN = (lat_est - lat) (R_N + h)
    dU = h_est - h

with ``R_N``, ``R_E`` the meridian and prime-vertical radii of curvature of the Earth
model at the true latitude (:meth:`navsim.earth.EarthModel.radii`) and ``h`` the true
height. The relative error of the linearisation against the exact ENU difference is
below 1e-6 for errors under 10 m and of the order (error / Earth radius) beyond.

One angle wrap, :func:`wrap_angle`: ``atan2(sin x, cos x)``, the principal value in
(-pi, pi] (evaluated as ``angle(exp(i x))``); it is used for the longitude difference and
for attitude-angle differences (heading, pitch, roll) of the rewards and the heading
error of the metrics.

Two evaluations of the same operations in the same order: :func:`local_level_error`
over NumPy arrays (metrics, vector env, adaptive env) and
:func:`local_level_error_scalar` over Python floats for a per-step reward (no NumPy
call per step), with the truth factors ``R_N + h``, ``R_E + h``, ``cos(lat)`` of
:func:`local_level_factors` computed once per chunk. Both round identically (the
tests check it bit for bit).
"""

from __future__ import annotations

import cmath
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["wrap_angle", "wrap_angle_scalar", "local_level_factors", "local_level_error",
           "local_level_error_scalar", "position_error_norm"]


def wrap_angle(x: ArrayLike) -> np.ndarray:
    """The principal value of the angle(s) x in (-pi, pi], rad: ``angle(exp(i x))``
    (nan for non-finite x)."""
    with np.errstate(invalid="ignore"):
        return np.angle(np.exp(1j * np.asarray(x, dtype=float)))


def wrap_angle_scalar(x: float) -> float:
    """:func:`wrap_angle` of one Python float (the same complex exponential and phase)."""
    if x - x != 0.0:  # inf or nan (cmath.exp refuses an infinite imaginary part)
        return math.nan
    return cmath.phase(cmath.exp(1j * x))


def local_level_factors(lat: ArrayLike, h: ArrayLike, earth: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(R_N + h, R_E + h, cos(lat))`` at the true positions (m, m, -)."""
    lat = np.asarray(lat, dtype=float)
    h = np.asarray(h, dtype=float)
    r_n, r_e = earth.radii(lat)
    return r_n + h, r_e + h, np.cos(lat)


def local_level_error(est_lat: ArrayLike, est_lon: ArrayLike, est_h: ArrayLike, lat: ArrayLike, lon: ArrayLike,
                      h: ArrayLike, earth: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(dE, dN, dU)`` in metres of the estimates against the truth (module docstring)."""
    k_north, re_h, cos_lat = local_level_factors(lat, h, earth)
    d_e = wrap_angle(np.asarray(est_lon) - lon) * re_h * cos_lat
    d_n = (np.asarray(est_lat) - lat) * k_north
    d_u = np.asarray(est_h) - h
    return d_e, d_n, d_u


def local_level_error_scalar(est_lat: float, est_lon: float, est_h: float, lat: float, lon: float, h: float,
                             k_north: float, re_h: float, cos_lat: float) -> tuple[float, float, float]:
    """:func:`local_level_error` of one step with the factors of :func:`local_level_factors`."""
    d_e = wrap_angle_scalar(est_lon - lon) * re_h * cos_lat
    d_n = (est_lat - lat) * k_north
    d_u = est_h - h
    return d_e, d_n, d_u


def position_error_norm(d_e: Any, d_n: Any, d_u: Any) -> Any:
    """The 3-D position error ``sqrt(dE^2 + dN^2 + dU^2)``, m (arrays or floats)."""
    if isinstance(d_e, float):
        return math.sqrt(d_e * d_e + d_n * d_n + d_u * d_u)
    return np.sqrt(d_e * d_e + d_n * d_n + d_u * d_u)
