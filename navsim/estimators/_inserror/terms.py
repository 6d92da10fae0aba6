"""Body-frame strapdown terms of a batch (:func:`body_terms`, :class:`BodyTerms` with the linear
bias compensation) and of one step (:class:`StepTerms`). Derivation:
:mod:`navsim.estimators._inserror`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ...rotations import quat_from_rotvec
from ...strapdown import ins as _ins
from ...strapdown import onestep as _one
from ...strapdown.ins import Method
from ...strapdown.onestep import Vec
from .model import cross3


@dataclass(frozen=True, slots=True)
class BodyTerms:
    """Raw body-frame strapdown terms of n navigation steps (no bias removed).

    Attributes
    ----------
    phi : (n, 3) rotation vector over each step, rad (coning algorithm).
    dv_b : (n, 3) velocity increment DeltaV + deltaV_s + second-order rotation term, m/s.
    ds_b : (n, 3) or None, body-frame double integral of the exact position forms, m.
    rule : "rectangle", "trapezoid" or None (exact forms).
    dtheta1, dv1 : (n, 3) first-order increments over each step (rad, m/s).
    dt : float, step, s.
    """

    phi: np.ndarray
    dv_b: np.ndarray
    ds_b: np.ndarray | None
    rule: str | None
    dtheta1: np.ndarray
    dv1: np.ndarray
    dt: float

    def __len__(self) -> int:
        return len(self.phi)

    def compensated(self, gyro_bias: ArrayLike, accel_bias: ArrayLike, start: int = 0, stop: int | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
        """Terms of steps start:stop with constant biases removed, to first order in the bias.

        For a constant rate omega and force f over the step the exact terms are
        ``Phi = omega T``, ``dV = f T + (omega x f) T^2/2 + ...`` and
        ``dS = f T^2/2 + (omega x f) T^3/6 + ...``, so replacing omega, f by
        omega - b_g, f - b_a changes them by::

            dPhi = -b_g T
            ddV  = -b_a T - T (b_g x DV + DTheta x b_a) / 2                  (first-order sculling)
            ddS  = -b_a T^2/2 - T^2 (b_g x DV + DTheta x b_a) / 6

        (with ``- T b_g x b_a`` added inside the brackets: the bilinear remainder).

        (DTheta, DV the raw first-order increments). What is left is of order
        ``b x omega' T^3`` per step: for 1e-3 rad/s of bias (consumer MEMS) and a 0.01 s
        step below 1e-10 rad or m/s per step. Compensating the raw increments instead
        (:func:`compensate_increments`, then the strapdown algorithms) agrees to that order
        (tests/estimators/test_ins_only.py); this form lets one batch of body terms serve
        every bias estimate of the batch.

        Returns
        -------
        quat_body (k, 4), dv_body (k, 3), ds_body (k, 3) or None, dv_first (k, 3)
        """
        sl = slice(start, stop)
        T = self.dt
        bg = np.asarray(gyro_bias, dtype=float)
        ba = np.asarray(accel_bias, dtype=float)
        th, dv = self.dtheta1[sl], self.dv1[sl]
        phi = self.phi[sl] - bg * T
        cross = T * (cross3(np.broadcast_to(bg, dv.shape), dv) + cross3(th, np.broadcast_to(ba, th.shape)))
        cross = cross - (T * T) * np.cross(bg, ba)  # the bilinear remainder (b_g T) x (b_a T)
        dv_b = self.dv_b[sl] - ba * T - 0.5 * cross
        ds_b = None if self.ds_b is None else self.ds_b[sl] - ba * (0.5 * T * T) - (T / 6.0) * cross
        return quat_from_rotvec(phi), dv_b, ds_b, dv - ba * T


def body_terms(dtheta_sub: np.ndarray | None = None, dv_sub: np.ndarray | None = None, dtheta_r: np.ndarray | None = None,
               dv_r: np.ndarray | None = None, dt: float = 0.01, coning: Method = None, sculling: Method = None,
               position: Method = None) -> BodyTerms:
    """The body-frame terms of :func:`navsim.strapdown.ins.integrate` for n steps.

    The same computation as the strapdown module's (registry methods chosen by
    :func:`navsim.strapdown.ins.resolve_methods`, plus the second-order rotation terms
    ``Phi x (Phi x DV) / 6`` and ``dt Phi x (Phi x DV) / 24``), but returning the rotation
    vector (not its quaternion) so that biases can be removed linearly afterwards.
    tests/estimators/test_ins_only.py checks that with zero bias
    :meth:`ErrorStateIns.advance` reproduces ``integrate`` exactly.
    """
    t = _ins.body_terms(dtheta_sub, dv_sub, dtheta_r, dv_r, dt, coning, sculling, position)
    return BodyTerms(t.rotvec_body, t.dv_body, t.ds_body, t.rule, t.dtheta_first, t.dv_first, float(dt))


@dataclass(frozen=True, slots=True)
class StepTerms:
    """:class:`BodyTerms` of ONE step as Python floats (3-tuples), for the step-wise path.

    Computed by :func:`navsim.strapdown.onestep.one_step_terms` with the operations of the
    array forms, so :meth:`ErrorStateIns.advance_body` gives the numbers of a
    :class:`BodyTerms` batch of one. ``dtheta1`` is the (1, 3) array view callers index.
    """

    phi: Vec
    dv_b: Vec
    ds_b: Vec | None
    rule: str | None
    theta1: Vec
    dv1: Vec
    dt: float

    def __len__(self) -> int:
        return 1

    @property
    def dtheta1(self) -> np.ndarray:
        """(1, 3) first-order angle increment, rad (as :attr:`BodyTerms.dtheta1`)."""
        return np.array([self.theta1])

    def compensated(self, gyro_bias: Sequence[float], accel_bias: Sequence[float]
                    ) -> tuple[tuple[float, float, float, float], Vec, Vec | None, Vec]:
        """:meth:`BodyTerms.compensated` of the step on floats (the same operations).

        Returns q(Phi) (4-tuple), dV_b, dS_b (or None), DV - b_a T (3-tuples).
        """
        T = self.dt
        g0, g1, g2 = gyro_bias
        a0, a1, a2 = accel_bias
        t0, t1, t2 = self.theta1
        v0, v1, v2 = self.dv1
        phi = self.phi
        phi = (phi[0] - g0 * T, phi[1] - g1 * T, phi[2] - g2 * T)
        TT = T * T
        # T (b_g x DV + DTheta x b_a) - T^2 b_g x b_a, component by component
        c0 = T * ((g1 * v2 - g2 * v1) + (t1 * a2 - t2 * a1)) - TT * (g1 * a2 - g2 * a1)
        c1 = T * ((g2 * v0 - g0 * v2) + (t2 * a0 - t0 * a2)) - TT * (g2 * a0 - g0 * a2)
        c2 = T * ((g0 * v1 - g1 * v0) + (t0 * a1 - t1 * a0)) - TT * (g0 * a1 - g1 * a0)
        d = self.dv_b
        dv_b = (d[0] - a0 * T - 0.5 * c0, d[1] - a1 * T - 0.5 * c1, d[2] - a2 * T - 0.5 * c2)
        ds_b = None
        if self.ds_b is not None:
            d, h2, t6 = self.ds_b, 0.5 * T * T, T / 6.0
            ds_b = (d[0] - a0 * h2 - t6 * c0, d[1] - a1 * h2 - t6 * c1, d[2] - a2 * h2 - t6 * c2)
        return _one.quat_from_rotvec(phi), dv_b, ds_b, (v0 - a0 * T, v1 - a1 * T, v2 - a2 * T)
