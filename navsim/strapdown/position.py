"""Position (apparent displacement) update over one navigation step (seed 000, §5).

Signature of every registered method::

    f(velocity_i_k, mat_ib_k, dtheta_sub, dv_sub, dtheta_r, dv_r, dt) -> displacement_i

``velocity_i_k`` (n, 3) m/s
    Apparent velocity V_i(t_k) in the inertial frame (1.3).
``mat_ib_k`` (n, 3, 3)
    Attitude C_b^i(t_k) (maps body to inertial components).
``dtheta_sub``, ``dv_sub`` (n, m, 3) or None
    Traditional sub-sample increments (only "trapezoid" may use them).
``dtheta_r``, ``dv_r`` (n, R, 3) or None
    Multiple-integral increments (1.14) over the step.
``dt`` float, s
    The navigation step DeltaT.
returns ``displacement_i`` (n, 3) m
    S_i(k+1) - S_i(k).

Methods
-------
rectangle
    (5.1) ``V_i(k) DeltaT``.
trapezoid
    ``DeltaT (V_i(k) + V_i(k+1)) / 2`` with ``V_i(k+1) = V_i(k) + C(k)(DV + dV_s)`` (1.3),
    (1.6); dV_s by the two-sample sculling algorithm (2.3) when two sub-samples are given,
    else by the smoothing algorithm (3.6) on ``dv_r``/``dtheta_r`` (R >= 2), else (2.4).
exact
    The exact discrete form (5.2)-(5.3), ``V_i(k) DeltaT + C(k) (DV^2 + dS_s)``, with the
    partial increment (5.4) ``dS_s = int int DeltaTheta(t_k, tau) x a(tau) dtau dt
    = int_0^T (T - tau) DeltaTheta(tau) x a(tau) dtau`` by the *constant-model* formula
    ``dS_s = T/6 DT1 x DV1`` (constant omega and a; traditional = smoothing for this
    order). Needs ``dtheta_r`` R >= 1 and ``dv_r`` R >= 2. Local error of dS_s
    ``T^4/24 (B_w x A_a) + O(T^5)``.
exact-smoothing
    (5.2) with dS_s for *linear* omega and a models whose coefficients come from (3.5)
    (the smoothing approach, "by analogy" in the paper). Derived here:
    ``dS_s = A_w x A_a T^3/6 + A_w x B_a T^4/12 + B_w x A_a T^4/24 + B_w x B_a T^5/40``
    and with (3.5)
    ``dS_s = T/15 DT1 x DV1 - 3/10 DT1 x DV2 + 1/5 DT2 x DV1 + 3/(5T) DT2 x DV2``.
    Needs ``dtheta_r`` R >= 2 and ``dv_r`` R >= 2. Exact when omega and a are linear;
    local error of dS_s (computed - exact, A..D = omega, a and their derivatives at t_k)
    ``T^5 [A_w x C_a / 360 - C_w x A_a / 720] + O(T^6)``
    (tests/strapdown/test_position.py).
exact-invariant
    (5.2) with the *acceleration-invariant* dS_s (integration by parts against the
    multiple integrals of a, the analogue of (4.1)):
    ``dS_s = DT1 x DV2 - 2 w_k+1 x DV3 + 3 w'_k+1 x DV4 - 4 w''_k+1 x DV5 + ...``
    truncated after the w' term, with the linear omega model (3.5) moved to t_k+1:
    ``w_k+1 = 4/T DT1 - 6/T^2 DT2``, ``w'_k+1 = 6/T^2 DT1 - 12/T^3 DT2``.
    Needs ``dtheta_r`` R >= 2 and ``dv_r`` R >= 4. Exact for *any* a(t) when omega is
    linear (so pure linear vibration costs nothing, the case the paper singles out);
    local error of dS_s ``-T^5/720 (C_w x A_a) + O(T^6)`` for general motion.

With ideal increments and no rotation dS_s = 0 and (5.2) is exact whatever DeltaT,
whereas (5.1) and the trapezoid rule carry a methodical error that grows with DeltaT.

References
----------
.. [000] Litmanovich Yu.A., Izv. RAN, 2002 (seed 000), eqs. (1.3)-(1.6), (3.5), (4.1),
   (5.1)-(5.4).
.. [6] Lesyuchevsky V.M., Litmanovich Yu.A., Gyroscopy and Navigation, 1994, no. 2,
   39-58 (exact velocity integration with double-integral accelerometer outputs).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ConfigError
from .checks import check_dt as _dt
from .checks import check_multi as _multi
from .sculling import first_order, smoothing, two_sample

__all__ = [
    "rectangle",
    "trapezoid",
    "exact",
    "exact_smoothing",
    "exact_invariant",
    "partial_increment_constant",
    "partial_increment_smoothing",
    "partial_increment_invariant",
    "POSITION_METHODS",
    "POSITION_INPUTS",
]

PositionFn = Callable[..., np.ndarray]


def _state(velocity_i_k: ArrayLike | None, mat_ib_k: ArrayLike | None, name: str) -> tuple[np.ndarray, np.ndarray]:
    velocity = np.asarray(velocity_i_k, dtype=float)
    if velocity.ndim != 2 or velocity.shape[1] != 3:
        raise ConfigError(f"{name}.velocity_i_k", "array of shape (n, 3)", velocity.shape)
    if mat_ib_k is None:
        return velocity, None  # type: ignore[return-value]
    mat = np.asarray(mat_ib_k, dtype=float)
    if mat.shape != (velocity.shape[0], 3, 3):
        raise ConfigError(f"{name}.mat_ib_k", f"array of shape ({velocity.shape[0]}, 3, 3)", mat.shape)
    return velocity, mat


# ------------------------------------------------------------------ partial increments (5.4)
def partial_increment_constant(dtheta_r: ArrayLike | None, dv_r: ArrayLike | None, dt: float | None) -> np.ndarray:
    """dS_s (5.4) for constant omega and a: ``T/6 DT1 x DV1``, shape (n, 3)."""
    th = _multi(dtheta_r, 1, "exact")
    dv = _multi(dv_r, 1, "exact", "dv_r")
    t = _dt(dt, "exact")
    return (t / 6.0) * np.cross(th[:, 0], dv[:, 0])


def partial_increment_smoothing(dtheta_r: ArrayLike | None, dv_r: ArrayLike | None, dt: float | None) -> np.ndarray:
    """dS_s (5.4) for linear omega and a models from (3.5) (smoothing class), (n, 3)."""
    th = _multi(dtheta_r, 2, "exact-smoothing")
    dv = _multi(dv_r, 2, "exact-smoothing", "dv_r")
    t = _dt(dt, "exact-smoothing")
    t1, t2 = th[:, 0], th[:, 1]
    v1, v2 = dv[:, 0], dv[:, 1]
    # (5.4) with (3.5) for both factors (derived; see the module docstring)
    return (
        (t / 15.0) * np.cross(t1, v1)
        - 0.3 * np.cross(t1, v2)
        + 0.2 * np.cross(t2, v1)
        + (0.6 / t) * np.cross(t2, v2)
    )


def partial_increment_invariant(dtheta_r: ArrayLike | None, dv_r: ArrayLike | None, dt: float | None) -> np.ndarray:
    """Acceleration-invariant dS_s (5.4) for the linear omega model, shape (n, 3)."""
    th = _multi(dtheta_r, 2, "exact-invariant")
    dv = _multi(dv_r, 4, "exact-invariant", "dv_r")
    t = _dt(dt, "exact-invariant")
    t1, t2 = th[:, 0], th[:, 1]
    rate_end = (4.0 / t) * t1 - (6.0 / t**2) * t2  # omega(t_k+1) from (3.5)
    rate_dot_end = (6.0 / t**2) * t1 - (12.0 / t**3) * t2
    # analogue of (4.1) for (5.4): DT1 x DV2 - 2 w x DV3 + 3 w' x DV4
    return np.cross(t1, dv[:, 1]) - 2.0 * np.cross(rate_end, dv[:, 2]) + 3.0 * np.cross(rate_dot_end, dv[:, 3])


# ------------------------------------------------------------------------------- methods
def rectangle(velocity_i_k: ArrayLike | None, mat_ib_k: ArrayLike | None = None, dtheta_sub: ArrayLike | None = None,
              dv_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None, dv_r: ArrayLike | None = None,
              dt: float | None = None) -> np.ndarray:
    """(5.1) rectangle rule: ``V_i(k) DeltaT``, shape (n, 3)."""
    velocity, _ = _state(velocity_i_k, None, "rectangle")
    return velocity * _dt(dt, "rectangle")


def trapezoid(velocity_i_k: ArrayLike | None, mat_ib_k: ArrayLike | None, dtheta_sub: ArrayLike | None = None,
              dv_sub: ArrayLike | None = None,
              dtheta_r: ArrayLike | None = None, dv_r: ArrayLike | None = None, dt: float | None = None) -> np.ndarray:
    """Trapezoid rule on V_i(k), V_i(k+1) (V_i(k+1) by (1.3), (1.6)), shape (n, 3)."""
    velocity, mat = _state(velocity_i_k, mat_ib_k, "trapezoid")
    t = _dt(dt, "trapezoid")
    if dtheta_sub is not None and dv_sub is not None and np.shape(dtheta_sub)[1] == 2:
        dv_body = two_sample(dtheta_sub, dv_sub)
    elif dtheta_r is not None and dv_r is not None and np.shape(dtheta_r)[1] >= 2 and np.shape(dv_r)[1] >= 2:
        dv_body = smoothing(None, None, dtheta_r, dv_r, t)
    else:
        dv_body = first_order(dtheta_sub, dv_sub, dtheta_r, dv_r)
    velocity_next = velocity + np.einsum("nij,nj->ni", mat, dv_body)  # (1.3), (1.6)
    return 0.5 * t * (velocity + velocity_next)


def _exact_form(velocity_i_k: ArrayLike | None, mat_ib_k: ArrayLike | None, dv_r: ArrayLike | None, dt: float | None,
                partial: np.ndarray,
                name: str) -> np.ndarray:
    velocity, mat = _state(velocity_i_k, mat_ib_k, name)
    t = _dt(dt, name)
    dv = _multi(dv_r, 2, name, "dv_r")
    # (5.2)-(5.3): S(k+1) = S(k) + V(k) T + C(k) (DV^2 + dS_s)
    return velocity * t + np.einsum("nij,nj->ni", mat, dv[:, 1] + partial)


def exact(velocity_i_k: ArrayLike | None, mat_ib_k: ArrayLike | None, dtheta_sub: ArrayLike | None = None,
          dv_sub: ArrayLike | None = None,
          dtheta_r: ArrayLike | None = None, dv_r: ArrayLike | None = None, dt: float | None = None) -> np.ndarray:
    """(5.2) exact form with the constant-model partial increment, shape (n, 3)."""
    partial = partial_increment_constant(dtheta_r, dv_r, dt)
    return _exact_form(velocity_i_k, mat_ib_k, dv_r, dt, partial, "exact")


def exact_smoothing(velocity_i_k: ArrayLike | None, mat_ib_k: ArrayLike | None, dtheta_sub: ArrayLike | None = None,
                    dv_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None, dv_r: ArrayLike | None = None,
                    dt: float | None = None) -> np.ndarray:
    """(5.2) exact form with the smoothing (linear models) partial increment, (n, 3)."""
    partial = partial_increment_smoothing(dtheta_r, dv_r, dt)
    return _exact_form(velocity_i_k, mat_ib_k, dv_r, dt, partial, "exact-smoothing")


def exact_invariant(velocity_i_k: ArrayLike | None, mat_ib_k: ArrayLike | None, dtheta_sub: ArrayLike | None = None,
                    dv_sub: ArrayLike | None = None, dtheta_r: ArrayLike | None = None, dv_r: ArrayLike | None = None,
                    dt: float | None = None) -> np.ndarray:
    """(5.2) exact form with the acceleration-invariant partial increment, (n, 3)."""
    partial = partial_increment_invariant(dtheta_r, dv_r, dt)
    return _exact_form(velocity_i_k, mat_ib_k, dv_r, dt, partial, "exact-invariant")


POSITION_METHODS: dict[str, PositionFn] = {
    "rectangle": rectangle,
    "trapezoid": trapezoid,
    "exact": exact,
    "exact-smoothing": exact_smoothing,
    "exact-invariant": exact_invariant,
}

#: Inputs per method (empty: only velocity and dt).
POSITION_INPUTS: dict[str, dict[str, int]] = {
    "rectangle": {},
    "trapezoid": {"dtheta_r": 2, "dv_r": 2},  # or {"sub": 2}; (2.4) fallback with r = 1
    "exact": {"dtheta_r": 1, "dv_r": 2},
    "exact-smoothing": {"dtheta_r": 2, "dv_r": 2},
    "exact-invariant": {"dtheta_r": 2, "dv_r": 4},
}
