"""Compiled sample-end truth of the block method (:meth:`navsim.truthgen.TruthGenerator._from_channels`).

From the fitted channel values at each sample end (heading, pitch, roll, latitude,
longitude, height, ENU velocity), one pass per sample computes what the NumPy path builds
with a pass over all samples per term:

* the heading back to (-pi, pi]: ``atan2(sin psi, cos psi)`` (the NumPy path's
  ``angle(exp(i psi))`` gives the same double: the complex exponential of a purely
  imaginary number is ``cos psi + i sin psi``);
* the body-to-ENU matrix ``mat_nb = Rz(-psi) Rx(theta) Ry(rho)`` of
  :func:`navsim.rotations.mat_nb_from_hpr`;
* the ECEF position of :meth:`navsim.earth.EarthModel.geodetic_to_ecef`:
  ``[(R_E + h) cos(lat) cos(lon), (R_E + h) cos(lat) sin(lon), (R_E (1 - e^2) + h) sin(lat)]``
  with ``R_E = a / sqrt(1 - e^2 sin^2(lat))`` (``a`` on the sphere);
* the ECEF velocity ``v_e = B^T v_n`` with the ECEF-to-ENU matrix B of
  :func:`navsim.earth.mat_en` (rows E, N, U), summed over the rows in order E, N, U as the
  NumPy path's ``einsum`` does.

The expressions and their order are those of the NumPy functions named above, element by
element, and ``sin``, ``cos``, ``atan2`` and ``sqrt`` are the C library's in both paths, so
the numbers are the same bit for bit (``tests/test_truthgen_kernel.py``); numba does not
contract a product and a sum into a fused multiply-add unless asked (no ``fastmath``).

:func:`sample_end_state_into` is plain Python in the subset numba compiles; :func:`kernel`
returns it compiled (numba, optional extra ``fast``; compiled on the first call and cached
on disk) or None without numba. ``navsim.truthgen.USE_KERNEL`` switches it off.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from navsim.earth import EarthModel
from navsim.jit import available

__all__ = ["available", "earth_constants", "kernel", "sample_end_state_into"]

# columns of the channel array (navsim.truthgen: omega_ib_b 0-2, specific force 3-5,
# velocity_n 6-8, then s, speed, accel_along, lat, lon, h, heading, pitch, roll)
_VN, _LAT, _LON, _H, _HEADING, _PITCH, _ROLL = 6, 12, 13, 14, 15, 16, 17


def earth_constants(earth: EarthModel) -> np.ndarray:
    """[a, e^2, 1 - e^2, flat] of an Earth model, as :func:`sample_end_state_into` takes them."""
    e2 = earth.e2
    return np.array([earth.a, e2, 1.0 - e2, 1.0 if earth.f == 0.0 else 0.0])


def sample_end_state_into(ends: np.ndarray, c: np.ndarray, heading: np.ndarray, mat_nb: np.ndarray,
                          position_e: np.ndarray, velocity_e: np.ndarray) -> None:
    """Write the wrapped heading (n,), mat_nb (n, 3, 3), position_e and velocity_e (n, 3).

    ends : (n, 18) fitted channel values at the sample ends (columns as in
    :mod:`navsim.truthgen`). c : :func:`earth_constants`.
    """
    a, e2, one_minus_e2, flat = c[0], c[1], c[2], c[3] != 0.0
    for k in range(ends.shape[0]):
        psi = ends[k, _HEADING]
        psi = math.atan2(math.sin(psi), math.cos(psi))
        heading[k] = psi
        theta, rho = ends[k, _PITCH], ends[k, _ROLL]
        sh, ch = math.sin(psi), math.cos(psi)
        sp, cp = math.sin(theta), math.cos(theta)
        sr, cr = math.sin(rho), math.cos(rho)
        mat_nb[k, 0, 0] = ch * cr + sh * sp * sr
        mat_nb[k, 0, 1] = sh * cp
        mat_nb[k, 0, 2] = ch * sr - sh * sp * cr
        mat_nb[k, 1, 0] = -sh * cr + ch * sp * sr
        mat_nb[k, 1, 1] = ch * cp
        mat_nb[k, 1, 2] = -sh * sr - ch * sp * cr
        mat_nb[k, 2, 0] = -cp * sr
        mat_nb[k, 2, 1] = sp
        mat_nb[k, 2, 2] = cp * cr
        lat, lon, hgt = ends[k, _LAT], ends[k, _LON], ends[k, _H]
        sl, cl = math.sin(lat), math.cos(lat)
        so, co = math.sin(lon), math.cos(lon)
        if flat:
            r_e = a
        else:
            r_e = a / math.sqrt(1.0 - e2 * (sl * sl))
        position_e[k, 0] = (r_e + hgt) * cl * co
        position_e[k, 1] = (r_e + hgt) * cl * so
        position_e[k, 2] = (r_e * one_minus_e2 + hgt) * sl
        ve, vn, vu = ends[k, _VN], ends[k, _VN + 1], ends[k, _VN + 2]
        # v_e[i] = sum over the rows E, N, U of B[row, i] v_n[row], from 0 in that order
        velocity_e[k, 0] = ((0.0 + -so * ve) + -sl * co * vn) + cl * co * vu
        velocity_e[k, 1] = ((0.0 + co * ve) + -sl * so * vn) + cl * so * vu
        velocity_e[k, 2] = ((0.0 + 0.0 * ve) + cl * vn) + sl * vu


_compiled: list = []


def kernel() -> Callable[..., None] | None:
    """:func:`sample_end_state_into` compiled by numba, or None without numba."""
    if not available():
        return None
    if not _compiled:
        import numba

        _compiled.append(numba.njit(cache=True, nogil=True)(sample_end_state_into))
    return _compiled[0]
