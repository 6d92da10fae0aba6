"""Body-frame strapdown terms of ONE navigation step on Python floats.

:func:`navsim.strapdown.ins.body_terms` evaluates the registered algorithms on arrays of n
steps; for a single step (an estimator driven step by step: the Gymnasium face, the
estimator FMU) the fixed cost of the array operations dominates. This module gives the
same terms of one step for the methods the default choice of
:func:`navsim.strapdown.ins.resolve_methods` picks when multiple integrals of order 4 are
given, written with the same floating-point operations in the same order as the array
forms, so the results are equal bit for bit (``tests/strapdown/test_onestep.py`` checks it
against :func:`~navsim.strapdown.ins.body_terms`):

* coning ``"invariant"``, seed 000 eq. (4.8) with the coefficient 30/T^3 (see
  :func:`navsim.strapdown.coning.invariant`):
  ``Phi = DT1 + 18/T^2 DT1 x DT3 - 3/(2T) DT2 x (44/T^2 DT3 - 3 DT1)
  - 30/T^3 (DT1 - 6/T DT2 + 12/T^2 DT3) x DT4``;
* sculling ``"invariant-4.4"``, eq. (4.4):
  ``dV = DV1 + DT1 x DV1 + 6/T^2 (DT2 - 2T/3 DT1) x DV2 - 12/T^3 (DT2 - T/2 DT1) x DV3``;
* position ``"exact-invariant"``, eq. (5.2)-(5.4) with the acceleration-invariant partial
  increment: ``dS = DV2 + DT1 x DV2 - 2 w x DV3 + 3 w' x DV4``,
  ``w = 4/T DT1 - 6/T^2 DT2``, ``w' = 6/T^2 DT1 - 12/T^3 DT2``;
* the second-order rotation terms ``Phi x (Phi x DV) / 6`` on dV and
  ``T Phi x (Phi x DV) / 24`` on dS (module notes of :mod:`navsim.strapdown.ins`).

``DTr``, ``DVr`` are the r-fold integrals (seed 000 eq. 1.14) of the angular rate and the
specific force over the step, T the step (s); DV is the first-order increment (the sum of
the sub-sample increments when they are given). :func:`one_step_terms` returns None for
other method choices: callers then use the array forms.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["ONE_STEP_METHODS", "one_step_terms", "cross", "quat_from_rotvec"]

Vec = tuple[float, float, float]

#: (coning, sculling, position) method names with a one-step float form.
ONE_STEP_METHODS = (("invariant", "invariant-4.4", "exact-invariant"),)


def cross(a: Sequence[float], b: Sequence[float]) -> Vec:
    """a x b of two 3-vectors, in the operation order of ``numpy.cross``."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def quat_from_rotvec(v: Sequence[float]) -> tuple[float, float, float, float]:
    """:func:`navsim.rotations.quat_from_rotvec` of one rotation vector (same operations)."""
    angle2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    angle = math.sqrt(angle2)
    if angle < 1e-4:  # sin(a/2)/a = 1/2 - a^2/48 + a^4/3840
        half_sinc = 0.5 - angle2 / 48.0 + angle2 * angle2 / 3840.0  # numpy's x ** 2 is x * x
    else:
        half_sinc = math.sin(0.5 * angle) / angle
    return (math.cos(0.5 * angle), half_sinc * v[0], half_sinc * v[1], half_sinc * v[2])


def _first_order(sub: Sequence[Sequence[float]] | None, r: Sequence[Sequence[float]]) -> Vec:
    """The first-order increment: the sum of the sub-sample increments (in time order, as
    numpy sums over that axis), else the 1-fold integral."""
    if sub is None:
        return (r[0][0], r[0][1], r[0][2])
    x, y, z = sub[0]
    for row in sub[1:]:
        x, y, z = x + row[0], y + row[1], z + row[2]
    return (x, y, z)


def one_step_terms(methods: tuple, dtheta_r: Sequence[Sequence[float]], dv_r: Sequence[Sequence[float]],
                   dtheta_sub: Sequence[Sequence[float]] | None, dv_sub: Sequence[Sequence[float]] | None,
                   dt: float) -> tuple[Vec, Vec, Vec, Vec, Vec] | None:
    """``(Phi, dV_b, dS_b, DTheta, DV)`` of one step, or None without a float form.

    Parameters
    ----------
    methods : (coning, sculling, position) names as resolved by
        :func:`navsim.strapdown.ins.resolve_methods`.
    dtheta_r, dv_r : (R, 3) nested sequences, R >= 4 (rad, m/s times s^(r-1)).
    dtheta_sub, dv_sub : (m, 3) nested sequences or None (rad, m/s).
    dt : float, the navigation step T, s.

    Returns
    -------
    Phi (rad), dV_b (m/s), dS_b (m), DTheta (rad), DV (m/s): 3-tuples, the rows of
    :class:`navsim.strapdown.ins.BodyTerms` ``rotvec_body, dv_body, ds_body,
    dtheta_first, dv_first``.
    """
    if tuple(methods) not in ONE_STEP_METHODS or len(dtheta_r) < 4 or len(dv_r) < 4:
        return None
    t = float(dt)
    (a1, b1, c1), (a2, b2, c2), (a3, b3, c3), (a4, b4, c4) = dtheta_r[0], dtheta_r[1], dtheta_r[2], dtheta_r[3]
    (e1, f1, g1), (e2, f2, g2), (e3, f3, g3), (e4, f4, g4) = dv_r[0], dv_r[1], dv_r[2], dv_r[3]
    # unrolled 3-vector algebra: x = (a, b, c) components of the DT_r, (e, f, g) of the DV_r;
    # each line is one array expression of the vector forms, component by component
    # coning (4.8): DT1 + [c18 DT1 x DT3 - c15 DT2 x (c44 DT3 - 3 DT1) - c30 (DT1 - c6 DT2 + c12 DT3) x DT4]
    c44, c6, c12 = 44.0 / t**2, 6.0 / t, 12.0 / t**2
    c18, c15, c30 = 18.0 / t**2, 1.5 / t, 30.0 / t**3
    ux, uy, uz = c44 * a3 - 3.0 * a1, c44 * b3 - 3.0 * b1, c44 * c3 - 3.0 * c1
    wx, wy, wz = a1 - c6 * a2 + c12 * a3, b1 - c6 * b2 + c12 * b3, c1 - c6 * c2 + c12 * c3
    p0 = a1 + (c18 * (b1 * c3 - c1 * b3) - c15 * (b2 * uz - c2 * uy) - c30 * (wy * c4 - wz * b4))
    p1 = b1 + (c18 * (c1 * a3 - a1 * c3) - c15 * (c2 * ux - a2 * uz) - c30 * (wz * a4 - wx * c4))
    p2 = c1 + (c18 * (a1 * b3 - b1 * a3) - c15 * (a2 * uy - b2 * ux) - c30 * (wx * b4 - wy * a4))
    # sculling (4.4): DV1 + [DT1 x DV1 + s6 (DT2 - k23 DT1) x DV2 - s12 (DT2 - k12 DT1) x DV3]
    k23, k12 = 2.0 * t / 3.0, 0.5 * t
    s6, s12 = 6.0 / t**2, 12.0 / t**3
    ux, uy, uz = a2 - k23 * a1, b2 - k23 * b1, c2 - k23 * c1
    wx, wy, wz = a2 - k12 * a1, b2 - k12 * b1, c2 - k12 * c1
    v0 = e1 + ((b1 * g1 - c1 * f1) + s6 * (uy * g2 - uz * f2) - s12 * (wy * g3 - wz * f3))
    v1 = f1 + ((c1 * e1 - a1 * g1) + s6 * (uz * e2 - ux * g2) - s12 * (wz * e3 - wx * g3))
    v2 = g1 + ((a1 * f1 - b1 * e1) + s6 * (ux * f2 - uy * e2) - s12 * (wx * f3 - wy * e3))
    # position (5.2)-(5.4): DV2 + [DT1 x DV2 - 2 w x DV3 + 3 w' x DV4] (V = 0, C = I)
    r4, r6, r12 = 4.0 / t, 6.0 / t**2, 12.0 / t**3
    ux, uy, uz = r4 * a1 - r6 * a2, r4 * b1 - r6 * b2, r4 * c1 - r6 * c2  # w
    wx, wy, wz = r6 * a1 - r12 * a2, r6 * b1 - r12 * b2, r6 * c1 - r12 * c2  # w'
    s0 = e2 + ((b1 * g2 - c1 * f2) - 2.0 * (uy * g3 - uz * f3) + 3.0 * (wy * g4 - wz * f4))
    s1 = f2 + ((c1 * e2 - a1 * g2) - 2.0 * (uz * e3 - ux * g3) + 3.0 * (wz * e4 - wx * g4))
    s2 = g2 + ((a1 * f2 - b1 * e2) - 2.0 * (ux * f3 - uy * e3) + 3.0 * (wx * f4 - wy * e4))
    # second-order rotation terms: Phi x (Phi x DV) / 6 on dV, T Phi x (Phi x DV) / 24 on dS
    th = _first_order(dtheta_sub, dtheta_r)
    dv = _first_order(dv_sub, dv_r)
    x0, x1, x2 = p1 * dv[2] - p2 * dv[1], p2 * dv[0] - p0 * dv[2], p0 * dv[1] - p1 * dv[0]
    n0, n1, n2 = p1 * x2 - p2 * x1, p2 * x0 - p0 * x2, p0 * x1 - p1 * x0
    q24 = t / 24.0
    dv_b = (v0 + n0 / 6.0, v1 + n1 / 6.0, v2 + n2 / 6.0)
    ds_b = (s0 + q24 * n0, s1 + q24 * n1, s2 + q24 * n2)
    return (p0, p1, p2), dv_b, ds_b, th, dv
