"""What a GNSS receiver computes from its own observables: single-epoch least-squares fixes.

Receiver-side code: it takes the channels of an epoch (satellite positions and
velocities, pseudoranges, pseudorange rates, validity) and nothing of the simulator's
error draws, so the truth side (:mod:`navsim.sensors.gnss`, which re-exports it) and the
estimators (:mod:`navsim.estimators.loosely`, :mod:`navsim.estimators.along_track`,
:mod:`navsim.estimators.gnss_only`) share it without the estimators importing a sensor
model.

* :func:`least_squares_fix`: position and clock bias by Gauss-Newton on the
  pseudorange model of seed 003 eq. (2) with a clock bias,
  ``rho = |r_s - r| + b``, all satellites weighted equally; covariance
  ``(H^T H)^-1`` in units of the pseudorange variance (GDOP = sqrt(trace)).
* :func:`velocity_fix`: velocity and clock drift by linear least squares on the
  pseudorange-rate model of seed 003 eq. (3) with a drift,
  ``rate = u . (v_s - v) + d``, ``u = (r_s - r) / |r_s - r|``.

Missing data is a value: with fewer than 4 valid satellites, a singular geometry or no
convergence ``ok`` is False and the solution NaN. Geometric ranges are taken at the
reception instant in ECEF (no light time, no Sagnac term), as in seed 003 eq. (2).

References
----------
.. [1] Sokolov S.V., Vdovichenko S.S. (2012), seed 003, eqs. (2), (3), (6).
.. [2] Misra P., Enge P., Global Positioning System: Signals, Measurements and
       Performance, 2nd ed., 2006, section 6.1 (linearised pseudorange and Doppler
       least squares, DOP).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
from numpy.typing import ArrayLike

from .earth import WGS84, EarthModel
from .errors import ConfigError

__all__ = ["Fix", "VelocityFix", "least_squares_fix", "velocity_fix"]


@dataclass(frozen=True, slots=True, eq=False)
class Fix:
    """Single-epoch point solutions (NaN where ``ok`` is False).

    Attributes
    ----------
    position_e : (k, 3) m
    clock_bias_m : (k,) m
    covariance : (k, 4, 4)
        (H^T H)^-1 for the state [x, y, z, c dt], in units of the pseudorange variance
        sigma^2 (multiply by sigma^2 for m^2); GDOP = sqrt(trace).
    n_used : (k,) int
    ok : (k,) bool
    """

    position_e: np.ndarray
    clock_bias_m: np.ndarray
    covariance: np.ndarray
    n_used: np.ndarray
    ok: np.ndarray


@dataclass(frozen=True, slots=True, eq=False)
class VelocityFix:
    """Single-epoch velocity solutions (NaN where ``ok`` is False).

    Attributes
    ----------
    velocity_e : (k, 3) m/s, ECEF-frame velocity
    clock_drift_mps : (k,) m/s
    covariance : (k, 4, 4) in units of the pseudorange-rate variance
    n_used : (k,) int
    ok : (k,) bool
    """

    velocity_e: np.ndarray
    clock_drift_mps: np.ndarray
    covariance: np.ndarray
    n_used: np.ndarray
    ok: np.ndarray


def _as_epochs(sat_in: ArrayLike, meas_in: ArrayLike,
               valid_in: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    sat: np.ndarray = np.asarray(sat_in, dtype=float)
    single = sat.ndim == 2
    if single:
        sat = sat[None]
    if sat.ndim != 3 or sat.shape[-1] != 3:
        raise ConfigError("sat_pos_e", "shape (k, m, 3) or (m, 3)", sat.shape)
    meas = np.asarray(meas_in, dtype=float).reshape(sat.shape[:2])
    valid = np.asarray(valid_in, dtype=bool).reshape(sat.shape[:2])
    valid = valid & np.isfinite(meas) & np.all(np.isfinite(sat), axis=-1)
    return sat, np.where(valid, meas, 0.0), valid, single


_EYE4 = np.eye(4)
_EYE4.setflags(write=False)


def _normal_solve(h: np.ndarray, w: np.ndarray,
                  residual: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Batched weighted normal equations; returns dx (k,4), inverse (k,4,4), rank_ok (k,).

    A singular epoch gets the identity in place of its normal matrix and a zero right-hand
    side (its solution is discarded); when every epoch has full rank the replacements are
    skipped (the same numbers, fewer array operations for a single epoch)."""
    normal = np.einsum("kmi,km,kmj->kij", h, w, h)
    rhs = np.einsum("kmi,km,km->ki", h, w, residual)
    singular = np.linalg.svd(normal, compute_uv=False)
    rank_ok = singular[:, -1] > 1e-12 * np.maximum(singular[:, 0], 1e-300)
    if not rank_ok.all():
        normal = np.where(rank_ok[:, None, None], normal, _EYE4)
        rhs = np.where(rank_ok[:, None], rhs, 0.0)
    inverse = np.linalg.inv(normal)
    dx = np.einsum("kij,kj->ki", inverse, rhs)
    return dx, inverse, rank_ok


def least_squares_fix(
    sat_pos_e: ArrayLike,
    pseudorange_m: ArrayLike,
    valid: ArrayLike,
    earth: EarthModel = WGS84,
    initial: ArrayLike | None = None,
    *,
    max_iter: int = 20,
    tol_m: float = 1e-6,
) -> Fix:
    """Point position and clock bias from pseudoranges by Gauss-Newton.

    Model: pseudorange = |r_s - r| + b (003 eq. (2) with a clock bias), all satellites
    weighted equally.

    Parameters
    ----------
    sat_pos_e : array_like (k, m, 3) or (m, 3)
    pseudorange_m, valid : array_like (k, m) or (m,)
    earth : EarthModel
        Unused by the algebra (kept for a uniform signature and future use).
    initial : array_like (k, 3), (3,) or (k, 4), (4,), optional
        Starting position (and clock bias); the Earth's centre by default, from which
        Gauss-Newton converges for GNSS geometry.

    Returns
    -------
    Fix
        With shapes (3,), (), (4, 4), (), () for single-epoch input. ``ok`` is False
        (and the solution NaN) with fewer than 4 valid satellites, a singular geometry
        or no convergence: missing data is a value, not an exception.
    """
    del earth
    sat, rho, valid, single = _as_epochs(sat_pos_e, pseudorange_m, valid)
    k = sat.shape[0]
    state = np.zeros((k, 4))
    if initial is not None:
        init = np.asarray(initial, dtype=float)
        init = np.broadcast_to(init, (k, init.shape[-1]))
        state[:, : init.shape[-1]] = init
    w = valid.astype(float)
    n_used = valid.sum(axis=1)
    converged = np.zeros(k, dtype=bool)
    h = np.ones(sat.shape[:2] + (4,))  # [-unit, 1]: the unit vectors are written in place each iteration
    for _ in range(max_iter):
        los = sat - state[:, None, :3]
        dist = np.linalg.norm(los, axis=-1)
        dist = np.where(valid & (dist > 0.0), dist, 1.0)
        np.negative(los / dist[..., None], out=h[..., :3])
        residual = np.where(valid, rho - (dist + state[:, 3:4]), 0.0)
        dx, inverse, rank_ok = _normal_solve(h, w, residual)
        state = state + dx
        converged = rank_ok & (np.abs(dx).max(axis=1) < tol_m)
        if (converged | ~rank_ok).all():
            break
    # covariance at the solution
    los = sat - state[:, None, :3]
    dist = np.where(valid, np.linalg.norm(los, axis=-1), 1.0)
    h = np.concatenate([-los / dist[..., None], np.ones(dist.shape + (1,))], axis=-1)
    _, covariance, rank_ok = _normal_solve(h, w, np.zeros_like(dist))
    ok = converged & rank_ok & (n_used >= 4) & np.all(np.isfinite(state), axis=1)
    state = np.where(ok[:, None], state, np.nan)
    covariance = np.where(ok[:, None, None], covariance, np.nan)
    fix = Fix(state[:, :3], state[:, 3], covariance, n_used, ok)
    if single:
        fix = Fix(*(getattr(fix, name)[0] for name in Fix.__slots__))
    return fix


def velocity_fix(sat_pos_e: ArrayLike, sat_vel_e: ArrayLike, pseudorange_rate_mps: ArrayLike, valid: ArrayLike,
                 position_e: ArrayLike) -> VelocityFix:
    """Receiver velocity and clock drift from pseudorange rates (linear least squares).

    Model (003 eq. (3) plus drift): rate = u . (v_s - v) + d, u = (r_s - r)/|r_s - r|, so
    rate - u . v_s = -u . v + d.

    Parameters
    ----------
    sat_pos_e, sat_vel_e : array_like (k, m, 3) or (m, 3)
    pseudorange_rate_mps, valid : array_like (k, m) or (m,)
    position_e : array_like (k, 3) or (3,)
        Receiver position (e.g. from :func:`least_squares_fix`).
    """
    sat, rate, valid, single = _as_epochs(sat_pos_e, pseudorange_rate_mps, valid)
    vel = np.asarray(sat_vel_e, dtype=float).reshape(sat.shape)
    k = sat.shape[0]
    position = np.broadcast_to(np.asarray(position_e, dtype=float).reshape(-1, 3), (k, 3))
    finite = np.all(np.isfinite(vel), axis=-1) & np.all(np.isfinite(position), axis=1)[:, None]
    valid = cast(np.ndarray, valid & finite)
    los = sat - position[:, None, :]
    dist = np.linalg.norm(los, axis=-1)
    dist = np.where(valid & (dist > 0.0), dist, 1.0)
    unit = np.where(valid[..., None], los / dist[..., None], 0.0)
    vel = np.where(valid[..., None], vel, 0.0)
    h = np.concatenate([-unit, np.ones(unit.shape[:2] + (1,))], axis=-1)
    y = np.where(valid, rate - np.einsum("kmi,kmi->km", unit, vel), 0.0)
    solution, covariance, rank_ok = _normal_solve(h, valid.astype(float), y)
    n_used = valid.sum(axis=1)
    ok = rank_ok & (n_used >= 4)
    solution = np.where(ok[:, None], solution, np.nan)
    covariance = np.where(ok[:, None, None], covariance, np.nan)
    result = VelocityFix(solution[:, :3], solution[:, 3], covariance, n_used, ok)
    if single:
        result = VelocityFix(*(getattr(result, name)[0] for name in VelocityFix.__slots__))
    return result
