"""Compiled white-noise pass of the IMU error model (:func:`navsim.sensors.imu.apply_imu_errors_batch`).

One pass over each member's draws: for every sample, the R white-noise integrals of a
sensor from draw slots 0..R-1 (:mod:`navsim.sensors.imu`: the lower-triangular Cholesky
factor L of the unit covariance times the draws, then times ``sqrt(h) h^(i-1)`` and the
density), added to the noise-free output, and the rate output, the noise-free rate plus
the first integral's noise divided by h. The expressions and their order are those of the
NumPy path of ``apply_imu_errors_batch``, element by element::

    unit_i  = L[i, 0] z_0 + L[i, 1] z_1 + ... + L[i, i] z_i     (left to right)
    out_i   = base_i + unit_i * (sqrt(h) h^(i-1) density)
    rate    = base_rate + noise_1 / h

so the numbers are the same bit for bit (``tests/sensors/test_imu_kernel.py``); numba does
not contract a product and a sum into a fused multiply-add unless asked (no ``fastmath``).
The NumPy path makes a pass over all members and samples per term, the kernel one pass in
all, reading the draws once and writing each output once.

The block of standard normals itself (one row of ``6 (R + 2)`` per sample) is drawn as
:func:`normals_into` does: numba implements NumPy's ziggurat method for
``Generator.standard_normal`` on the same bit generator, so a member's numbers and its
generator's state afterwards are those of ``rng.standard_normal(out=block)``; compiled,
the ziggurat is inlined around the bit generator's calls (NumPy's fill calls a
distribution function per element), and :func:`draw_kernel` draws the blocks of a whole
group of members in one call (:mod:`navsim.sensors.imu._bitgen`). The draws are most of
the model's cost.

:func:`white_noise_into` and :func:`normals_into` are plain Python in the subset numba
compiles; :func:`kernel` and :func:`draw_kernel` return them compiled (numba, optional
extra ``fast``; compiled on the first call and cached on disk) or None without numba.
``navsim.sensors.imu.apply.USE_KERNEL`` switches both off.
"""

from __future__ import annotations

import threading
from typing import Any, Callable

import numpy as np

from navsim.jit import available

__all__ = ["available", "kernel", "draw_kernel", "draws", "white_noise_into", "normals_into"]


def white_noise_into(z: np.ndarray, slot0: int, factor: np.ndarray, scale_density: np.ndarray, h: float,
                     base_r: np.ndarray, base_rate: np.ndarray, out_r: np.ndarray, out_rate: np.ndarray) -> None:
    """Write ``base + white noise`` of one sensor for B members and n samples.

    z : (B, n, W) draws; slots ``slot0 .. slot0 + 3 R - 1`` of a row are the sensor's
    white-noise draws (slot q, axis a at ``slot0 + 3 q + a``). factor : (R, R) lower
    triangular. scale_density : (R, 3), ``sqrt(h) h^(i-1) density[a]``. base_r : (B, n, R, 3)
    and base_rate : (B, n, 3), the noise-free outputs (may be broadcast views). out_r,
    out_rate : outputs like base_r, base_rate (may be strided views).
    """
    members, n = z.shape[0], z.shape[1]
    order = factor.shape[0]
    if order == 4:  # the bundled scenarios' order: the same terms, unrolled
        _white_noise_r4(z, slot0, factor, scale_density, h, base_r, base_rate, out_r, out_rate)
        return
    for b in range(members):
        for k in range(n):
            for a in range(3):
                for i in range(order):
                    unit = factor[i, 0] * z[b, k, slot0 + a]
                    for q in range(1, i + 1):
                        unit += factor[i, q] * z[b, k, slot0 + 3 * q + a]
                    noise = unit * scale_density[i, a]
                    out_r[b, k, i, a] = base_r[b, k, i, a] + noise
                    if i == 0:
                        out_rate[b, k, a] = base_rate[b, k, a] + noise / h


def _white_noise_r4(z: np.ndarray, slot0: int, factor: np.ndarray, scale_density: np.ndarray, h: float,
                    base_r: np.ndarray, base_rate: np.ndarray, out_r: np.ndarray, out_rate: np.ndarray) -> None:
    """:func:`white_noise_into` for R = 4, unrolled: the factor and the scales are read once
    (into locals, not reloaded past the output stores), one axis at a time; the same
    expressions in the same order as the general loop."""
    members, n = z.shape[0], z.shape[1]
    f00 = factor[0, 0]
    f10, f11 = factor[1, 0], factor[1, 1]
    f20, f21, f22 = factor[2, 0], factor[2, 1], factor[2, 2]
    f30, f31, f32, f33 = factor[3, 0], factor[3, 1], factor[3, 2], factor[3, 3]
    for a in range(3):
        s0, s1, s2, s3 = scale_density[0, a], scale_density[1, a], scale_density[2, a], scale_density[3, a]
        c0, c1, c2, c3 = slot0 + a, slot0 + 3 + a, slot0 + 6 + a, slot0 + 9 + a
        for b in range(members):
            for k in range(n):
                z0, z1, z2, z3 = z[b, k, c0], z[b, k, c1], z[b, k, c2], z[b, k, c3]
                noise = (f00 * z0) * s0
                out_r[b, k, 0, a] = base_r[b, k, 0, a] + noise
                out_rate[b, k, a] = base_rate[b, k, a] + noise / h
                out_r[b, k, 1, a] = base_r[b, k, 1, a] + (f10 * z0 + f11 * z1) * s1
                out_r[b, k, 2, a] = base_r[b, k, 2, a] + (f20 * z0 + f21 * z1 + f22 * z2) * s2
                out_r[b, k, 3, a] = base_r[b, k, 3, a] + (f30 * z0 + f31 * z1 + f32 * z2 + f33 * z3) * s3


def normals_into(rng: np.random.Generator, out: np.ndarray) -> None:
    """Fill the C-contiguous 2-D array ``out`` row by row with standard normals from ``rng``.

    The numbers and the generator's state afterwards are those of
    ``rng.standard_normal(out=out)``: numba implements NumPy's ziggurat on the same bit
    generator (``tests/sensors/test_imu_kernel.py`` checks it), without NumPy's per-element
    calls through the bit generator's function pointers.
    """
    for k in range(out.shape[0]):
        for c in range(out.shape[1]):
            out[k, c] = rng.standard_normal()


_compiled: dict[str, Callable[..., Any]] = {}
_compile_lock = threading.Lock()


def _compile() -> bool:
    if not available():
        return False
    if "uniform_many" in _compiled:  # the last entry made: all are there
        return True
    with _compile_lock:  # worker threads may reach this at once (SimulatorBatch threads)
        if "uniform_many" not in _compiled:
            _make()
    return True


def _make() -> None:
    """Fill :data:`_compiled` (under ``_compile_lock``)."""
    import numba

    global _white_noise_r4
    _white_noise_r4 = numba.njit(cache=True, nogil=True)(_white_noise_r4)
    _compiled["white_noise_into"] = numba.njit(cache=True, nogil=True)(white_noise_into)
    from . import _bitgen

    def draw_many(rngs: list[np.random.Generator], out: np.ndarray) -> None:
        """``rngs[b].standard_normal(out=out[b])`` for every b, in one compiled call."""
        _bitgen.normals_into_many(*_bitgen.addresses(rngs), out)

    def uniform_many(rngs: list[np.random.Generator], out: np.ndarray) -> None:
        """``rngs[b].random(out=out[b])`` for every b, in one compiled call."""
        _bitgen.uniforms_into_many(*_bitgen.addresses(rngs), out)

    _compiled["draw_many"] = draw_many
    _compiled["uniform_many"] = uniform_many


def draws(kind: str = "normal") -> Callable[..., None] | None:
    """The group draw of ``kind`` ("normal": :func:`draw_kernel`, "uniform": the same for
    ``Generator.random``) when numba is installed, else None (draw with NumPy; the same
    numbers). The callers skip it when ``apply.USE_KERNEL`` is off."""
    if not _compile():
        return None
    return _compiled["draw_many" if kind == "normal" else "uniform_many"]


def kernel() -> Callable[..., None] | None:
    """:func:`white_noise_into` compiled by numba, or None without numba."""
    return _compiled["white_noise_into"] if _compile() else None


def draw_kernel() -> Callable[..., None] | None:
    """``draw(rngs, out)``: :func:`normals_into` of every generator into ``out[b]``
    (C-contiguous (B, n, W)) in one compiled call (:mod:`navsim.sensors.imu._bitgen`), or
    None without numba."""
    return _compiled["draw_many"] if _compile() else None
