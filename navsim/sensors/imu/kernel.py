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

:func:`white_noise_into` is plain Python in the subset numba compiles; :func:`kernel`
returns it compiled (numba, optional extra ``fast``; compiled on the first call and cached
on disk) or None without numba. ``navsim.sensors.imu.apply.USE_KERNEL`` switches it off.
"""

from __future__ import annotations

from navsim.jit import available

__all__ = ["available", "kernel", "white_noise_into"]


def white_noise_into(z, slot0, factor, scale_density, h, base_r, base_rate, out_r, out_rate):
    """Write ``base + white noise`` of one sensor for B members and n samples.

    z : (B, n, W) draws; slots ``slot0 .. slot0 + 3 R - 1`` of a row are the sensor's
    white-noise draws (slot q, axis a at ``slot0 + 3 q + a``). factor : (R, R) lower
    triangular. scale_density : (R, 3), ``sqrt(h) h^(i-1) density[a]``. base_r : (B, n, R, 3)
    and base_rate : (B, n, 3), the noise-free outputs (may be broadcast views). out_r,
    out_rate : outputs like base_r, base_rate (may be strided views).
    """
    members, n = z.shape[0], z.shape[1]
    order = factor.shape[0]
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


_compiled: list = []


def kernel():
    """:func:`white_noise_into` compiled by numba, or None without numba."""
    if not available():
        return None
    if not _compiled:
        import numba

        _compiled.append(numba.njit(cache=True, nogil=True)(white_noise_into))
    return _compiled[0]
