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

Each epoch is solved on its own: Gauss-Newton steps ``dx = (H^T H)^-1 H^T r`` until its own
``max |dx| < tol_m`` (converged), a singular normal matrix (smallest singular value
``<= 1e-12`` times the largest: rank test, ``ok`` False) or ``max_iter`` steps (not
converged, ``ok`` False); an epoch's result does not depend on the other epochs of the
call. Two implementations (``method``):

* ``"numpy"``: all epochs of the call at once (einsum, ``numpy.linalg.svd`` for the rank
  test, ``numpy.linalg.inv``), a converged epoch frozen while the others iterate;
* ``"compiled"``: one loop over the epochs compiled by numba (extra ``fast``;
  :func:`epoch_kernels`), the normal matrix summed satellite by satellite and inverted by
  its eigen-decomposition (cyclic Jacobi rotations, [3]_; the eigenvalues' magnitudes are
  the singular values of the symmetric matrix, so the same rank test). The same
  operations run for an epoch whether it comes alone (a step-wise estimator) or in a batch
  of many (``step_batch``): the same numbers bit for bit. The two methods agree to
  rounding (about 1e-8 m in position on ~2e7 m ECEF coordinates,
  ``tests/test_receiver.py``).

``"auto"`` (the default) is ``"compiled"`` with numba installed, else ``"numpy"``.

References
----------
.. [1] Sokolov S.V., Vdovichenko S.S. (2012), seed 003, eqs. (2), (3), (6).
.. [2] Misra P., Enge P., Global Positioning System: Signals, Measurements and
       Performance, 2nd ed., 2006, section 6.1 (linearised pseudorange and Doppler
       least squares, DOP).
.. [3] Golub G.H., Van Loan C.F., Matrix Computations, 4th ed., 2013, section 8.5
       (the cyclic Jacobi method for the symmetric eigenproblem).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Literal, cast

import numpy as np
from numpy.typing import ArrayLike

from .earth import WGS84, EarthModel
from .errors import ConfigError
from .jit import available

__all__ = ["METHODS", "Fix", "VelocityFix", "epoch_kernels", "least_squares_fix", "velocity_fix"]

METHODS = ("auto", "numpy", "compiled")
"""Implementations of :func:`least_squares_fix` and :func:`velocity_fix` (module notes)."""

Method = Literal["auto", "numpy", "compiled"]


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
    return sat, meas, valid, single


def _checked(sat: np.ndarray, meas: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # the NumPy path's channel screening (the compiled kernels screen channel by channel)
    valid = valid & np.isfinite(meas) & np.all(np.isfinite(sat), axis=-1)
    return np.where(valid, meas, 0.0), valid


def _use_compiled(method: str) -> bool:
    if method not in METHODS:
        raise ConfigError("method", f"one of {METHODS}", method)
    if method == "numpy":
        return False
    if available():
        return True
    if method == "compiled":
        raise ConfigError("method", "'compiled' with numba installed (extra 'fast'), or 'auto'/'numpy'", method)
    return False


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


# ============================================================================ compiled kernels
# Plain Python in the subset numba compiles (epoch_kernels compiles them; they also run,
# slowly, as Python). One epoch: m channels, state [x, y, z, b].

def _sym4_inverse(a: np.ndarray, inverse: np.ndarray) -> bool:
    """Inverse of the symmetric 4 x 4 matrix ``a`` into ``inverse`` by its eigen-decomposition;
    returns the rank test (False: singular, or not finite; ``inverse`` then undefined).

    Cyclic Jacobi rotations (Golub & Van Loan section 8.5): ``a = V diag(lam) V^T``, so the
    singular values are ``|lam|``; rank test ``min |lam| > 1e-12 max(max |lam|, 1e-300)`` (that
    of the NumPy path on ``numpy.linalg.svd``) and ``a^-1 = V diag(1 / lam) V^T``.
    """
    d = np.empty((4, 4))
    v = np.zeros((4, 4))
    for i in range(4):
        v[i, i] = 1.0
        for j in range(4):
            x = a[i, j]
            if not math.isfinite(x):
                return False
            d[i, j] = x
    for sweep in range(50):
        off = 0.0
        for p in range(3):
            for q in range(p + 1, 4):
                off += abs(d[p, q])
        if off == 0.0:
            break
        for p in range(3):
            for q in range(p + 1, 4):
                apq = d[p, q]
                if apq == 0.0:
                    continue
                g = 100.0 * abs(apq)
                if sweep > 3 and abs(d[p, p]) + g == abs(d[p, p]) and abs(d[q, q]) + g == abs(d[q, q]):
                    d[p, q] = 0.0  # below the rounding of both diagonal entries
                    d[q, p] = 0.0
                    continue
                theta = (d[q, q] - d[p, p]) / (2.0 * apq)
                if abs(theta) > 1e150:
                    t = 0.5 / theta
                else:
                    t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
                    if theta < 0.0:
                        t = -t
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for r in range(4):  # d <- d J
                    x, y = d[r, p], d[r, q]
                    d[r, p] = c * x - s * y
                    d[r, q] = s * x + c * y
                for r in range(4):  # d <- J^T d
                    x, y = d[p, r], d[q, r]
                    d[p, r] = c * x - s * y
                    d[q, r] = s * x + c * y
                d[p, q] = 0.0  # annihilated by the rotation (its computed value is rounding)
                d[q, p] = 0.0
                for r in range(4):  # v <- v J
                    x, y = v[r, p], v[r, q]
                    v[r, p] = c * x - s * y
                    v[r, q] = s * x + c * y
    s_max = 0.0
    s_min = math.inf
    for i in range(4):
        x = abs(d[i, i])
        s_max = max(s_max, x)
        s_min = min(s_min, x)
    if not s_min > 1e-12 * max(s_max, 1e-300):
        return False
    for i in range(4):
        for j in range(i, 4):
            x = 0.0
            for k in range(4):
                x += v[i, k] * v[j, k] / d[k, k]
            inverse[i, j] = x
            inverse[j, i] = x
    return True


def _add_row(normal: np.ndarray, rhs: np.ndarray, h0: float, h1: float, h2: float, y: float) -> None:
    """Add one channel's row ``h = [h0, h1, h2, 1]`` with residual ``y`` to the normal
    equations: the upper triangle of ``H^T H`` and ``H^T y`` (the caller mirrors the triangle)."""
    normal[0, 0] += h0 * h0
    normal[0, 1] += h0 * h1
    normal[0, 2] += h0 * h2
    normal[0, 3] += h0
    normal[1, 1] += h1 * h1
    normal[1, 2] += h1 * h2
    normal[1, 3] += h1
    normal[2, 2] += h2 * h2
    normal[2, 3] += h2
    normal[3, 3] += 1.0
    rhs[0] += h0 * y
    rhs[1] += h1 * y
    rhs[2] += h2 * y
    rhs[3] += y


def _position_normal(sat: np.ndarray, rho: np.ndarray, use: np.ndarray, state: np.ndarray, guard: bool,
                     normal: np.ndarray, rhs: np.ndarray) -> None:
    """Normal matrix ``H^T H`` and right-hand side ``H^T r`` of one epoch at ``state``:
    rows ``h = [-u, 1]``, ``u = (r_s - r) / |r_s - r|``, ``r = rho - (|r_s - r| + b)``
    over the channels in ``use`` (``guard``: a zero range counts as 1, as in the iteration)."""
    for i in range(4):
        rhs[i] = 0.0
        for j in range(4):
            normal[i, j] = 0.0
    for j in range(sat.shape[0]):
        if not use[j]:
            continue
        lx, ly, lz = sat[j, 0] - state[0], sat[j, 1] - state[1], sat[j, 2] - state[2]
        dist = math.sqrt(lx * lx + ly * ly + lz * lz)
        if guard and not dist > 0.0:
            dist = 1.0
        h0, h1, h2 = -(lx / dist), -(ly / dist), -(lz / dist)
        res = rho[j] - (dist + state[3])
        _add_row(normal, rhs, h0, h1, h2, res)
    for i in range(4):
        for j in range(i):
            normal[i, j] = normal[j, i]


def fix_epochs(sat: np.ndarray, rho: np.ndarray, valid: np.ndarray, init: np.ndarray, max_iter: int, tol_m: float,
               state: np.ndarray, covariance: np.ndarray, n_used: np.ndarray, ok: np.ndarray) -> None:
    """The position fix of k epochs, one after the other (the compiled path of :func:`least_squares_fix`).

    ``sat`` (k, m, 3), ``rho`` (k, m), ``valid`` (k, m) bool, ``init`` (k, 4) starting
    states; fills ``state`` (k, 4), ``covariance`` (k, 4, 4) (NaN where not ok), ``n_used``
    (k,) int and ``ok`` (k,) bool. A channel is used if valid and its pseudorange and
    satellite position are finite.
    """
    m = sat.shape[1]
    use = np.empty(m, dtype=np.bool_)
    normal = np.empty((4, 4))
    rhs = np.empty(4)
    inverse = np.empty((4, 4))
    x = np.empty(4)
    dx = np.empty(4)
    for e in range(sat.shape[0]):
        count = 0
        for j in range(m):
            u = valid[e, j] and math.isfinite(rho[e, j])
            for c in range(3):
                u = u and math.isfinite(sat[e, j, c])
            use[j] = u
            if u:
                count += 1
        n_used[e] = count
        for i in range(4):
            x[i] = init[e, i]
        converged = False
        for _ in range(max_iter):
            _position_normal(sat[e], rho[e], use, x, True, normal, rhs)
            if not _sym4_inverse(normal, inverse):
                break
            step = 0.0
            for i in range(4):
                dx[i] = inverse[i, 0] * rhs[0] + inverse[i, 1] * rhs[1] + inverse[i, 2] * rhs[2] + inverse[i, 3] * rhs[3]
            for i in range(4):
                x[i] = x[i] + dx[i]
                step = max(step, abs(dx[i]))
            if step < tol_m:
                converged = True
                break
        good = converged and count >= 4
        for i in range(4):
            good = good and math.isfinite(x[i])
        if good:  # covariance at the solution
            _position_normal(sat[e], rho[e], use, x, False, normal, rhs)
            good = _sym4_inverse(normal, inverse)
        ok[e] = good
        for i in range(4):
            state[e, i] = x[i] if good else math.nan
            for j in range(4):
                covariance[e, i, j] = inverse[i, j] if good else math.nan


def velocity_epochs(sat: np.ndarray, vel: np.ndarray, rate: np.ndarray, valid: np.ndarray, position: np.ndarray,
                    solution: np.ndarray, covariance: np.ndarray, n_used: np.ndarray, ok: np.ndarray) -> None:
    """The velocity fix of k epochs, one after the other (the compiled path of :func:`velocity_fix`).

    ``sat``, ``vel`` (k, m, 3), ``rate`` (k, m), ``valid`` (k, m) bool, ``position`` (k, 3);
    fills ``solution`` (k, 4) = (v, d), ``covariance`` (k, 4, 4), ``n_used``, ``ok``.
    """
    m = sat.shape[1]
    normal = np.empty((4, 4))
    rhs = np.empty(4)
    inverse = np.empty((4, 4))
    for e in range(sat.shape[0]):
        px, py, pz = position[e, 0], position[e, 1], position[e, 2]
        here = math.isfinite(px) and math.isfinite(py) and math.isfinite(pz)
        for i in range(4):
            rhs[i] = 0.0
            for j in range(4):
                normal[i, j] = 0.0
        count = 0
        for j in range(m):
            u = here and valid[e, j] and math.isfinite(rate[e, j])
            for c in range(3):
                u = u and math.isfinite(sat[e, j, c]) and math.isfinite(vel[e, j, c])
            if not u:
                continue
            count += 1
            lx, ly, lz = sat[e, j, 0] - px, sat[e, j, 1] - py, sat[e, j, 2] - pz
            dist = math.sqrt(lx * lx + ly * ly + lz * lz)
            if not dist > 0.0:
                dist = 1.0
            u0, u1, u2 = lx / dist, ly / dist, lz / dist
            y = rate[e, j] - (u0 * vel[e, j, 0] + u1 * vel[e, j, 1] + u2 * vel[e, j, 2])
            h0, h1, h2 = -u0, -u1, -u2
            _add_row(normal, rhs, h0, h1, h2, y)
        for i in range(4):
            for j in range(i):
                normal[i, j] = normal[j, i]
        n_used[e] = count
        good = count >= 4 and _sym4_inverse(normal, inverse)
        ok[e] = good
        for i in range(4):
            x = inverse[i, 0] * rhs[0] + inverse[i, 1] * rhs[1] + inverse[i, 2] * rhs[2] + inverse[i, 3] * rhs[3]
            solution[e, i] = x if good else math.nan
            for j in range(4):
                covariance[e, i, j] = inverse[i, j] if good else math.nan


_kernels: list[tuple[Callable[..., None], Callable[..., None]]] = []


def epoch_kernels() -> tuple[Callable[..., None], Callable[..., None]] | None:
    """(:func:`fix_epochs`, :func:`velocity_epochs`) compiled by numba (on the first call,
    cached on disk), or None without numba."""
    if not available():
        return None
    if not _kernels:
        import numba

        global _sym4_inverse, _position_normal, _add_row
        _add_row = numba.njit(cache=True, nogil=True)(_add_row)
        _sym4_inverse = numba.njit(cache=True, nogil=True)(_sym4_inverse)
        _position_normal = numba.njit(cache=True, nogil=True)(_position_normal)
        _kernels.append((numba.njit(cache=True, nogil=True)(fix_epochs),
                         numba.njit(cache=True, nogil=True)(velocity_epochs)))
    return _kernels[0]


def _squeezed(result: Any, single: bool) -> Any:
    return type(result)(*(getattr(result, name)[0] for name in type(result).__slots__)) if single else result


def least_squares_fix(
    sat_pos_e: ArrayLike,
    pseudorange_m: ArrayLike,
    valid: ArrayLike,
    earth: EarthModel = WGS84,
    initial: ArrayLike | None = None,
    *,
    max_iter: int = 20,
    tol_m: float = 1e-6,
    method: Method = "auto",
) -> Fix:
    """Point position and clock bias from pseudoranges by Gauss-Newton.

    Model: pseudorange = |r_s - r| + b (003 eq. (2) with a clock bias), all satellites
    weighted equally. Each epoch iterates ``x <- x + (H^T H)^-1 H^T (rho - rho(x))`` until
    its own ``max |dx| < tol_m`` (module notes).

    Parameters
    ----------
    sat_pos_e : array_like (k, m, 3) or (m, 3)
    pseudorange_m, valid : array_like (k, m) or (m,)
    earth : EarthModel
        Unused by the algebra (kept for a uniform signature and future use).
    initial : array_like (k, 3), (3,) or (k, 4), (4,), optional
        Starting position (and clock bias); the Earth's centre by default, from which
        Gauss-Newton converges for GNSS geometry.
    max_iter : int
        Gauss-Newton steps at most per epoch.
    tol_m : float
        Convergence threshold on the largest component of an epoch's step, m.
    method : {"auto", "numpy", "compiled"}
        Implementation (module notes); "compiled" needs numba (extra ``fast``).

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
        state[:, : init.shape[-1]] = init  # (3,)/(4,) broadcast over the epochs
    if _use_compiled(method):
        fix_kernel = cast(tuple, epoch_kernels())[0]
        out, covariance = np.empty((k, 4)), np.empty((k, 4, 4))
        n_used, ok = np.empty(k, dtype=np.int64), np.empty(k, dtype=bool)
        fix_kernel(np.ascontiguousarray(sat), np.ascontiguousarray(rho), np.ascontiguousarray(valid), state,
                   int(max_iter), float(tol_m), out, covariance, n_used, ok)
        return cast(Fix, _squeezed(Fix(out[:, :3], out[:, 3], covariance, n_used, ok), single))
    rho, valid = _checked(sat, rho, valid)
    w = valid.astype(float)
    n_used = valid.sum(axis=1)
    converged = np.zeros(k, dtype=bool)
    active = np.ones(k, dtype=bool)  # not yet converged, full rank so far
    h = np.ones(sat.shape[:2] + (4,))  # [-unit, 1]: the unit vectors are written in place each iteration
    for _ in range(max_iter):
        los = sat - state[:, None, :3]
        dist = np.linalg.norm(los, axis=-1)
        dist = np.where(valid & (dist > 0.0), dist, 1.0)
        np.negative(los / dist[..., None], out=h[..., :3])
        residual = np.where(valid, rho - (dist + state[:, 3:4]), 0.0)
        dx, inverse, rank_ok = _normal_solve(h, w, residual)
        step = active & rank_ok  # a converged or singular epoch keeps its state
        state = np.where(step[:, None], state + dx, state)
        converged |= step & (np.abs(dx).max(axis=1) < tol_m)
        active &= rank_ok & ~converged
        if not active.any():
            break
    # covariance at the solution
    los = sat - state[:, None, :3]
    dist = np.where(valid, np.linalg.norm(los, axis=-1), 1.0)
    h = np.concatenate([-los / dist[..., None], np.ones(dist.shape + (1,))], axis=-1)
    _, covariance, rank_ok = _normal_solve(h, w, np.zeros_like(dist))
    ok = converged & rank_ok & (n_used >= 4) & np.all(np.isfinite(state), axis=1)
    state = np.where(ok[:, None], state, np.nan)
    covariance = np.where(ok[:, None, None], covariance, np.nan)
    return cast(Fix, _squeezed(Fix(state[:, :3], state[:, 3], covariance, n_used, ok), single))


def velocity_fix(sat_pos_e: ArrayLike, sat_vel_e: ArrayLike, pseudorange_rate_mps: ArrayLike, valid: ArrayLike,
                 position_e: ArrayLike, *, method: Method = "auto") -> VelocityFix:
    """Receiver velocity and clock drift from pseudorange rates (linear least squares).

    Model (003 eq. (3) plus drift): rate = u . (v_s - v) + d, u = (r_s - r)/|r_s - r|, so
    rate - u . v_s = -u . v + d.

    Parameters
    ----------
    sat_pos_e, sat_vel_e : array_like (k, m, 3) or (m, 3)
    pseudorange_rate_mps, valid : array_like (k, m) or (m,)
    position_e : array_like (k, 3) or (3,)
        Receiver position (e.g. from :func:`least_squares_fix`).
    method : {"auto", "numpy", "compiled"}
        Implementation (module notes); "compiled" needs numba (extra ``fast``).
    """
    sat, rate, valid, single = _as_epochs(sat_pos_e, pseudorange_rate_mps, valid)
    vel = np.asarray(sat_vel_e, dtype=float).reshape(sat.shape)
    k = sat.shape[0]
    if _use_compiled(method):
        position = np.empty((k, 3))
        position[:] = np.asarray(position_e, dtype=float).reshape(-1, 3)
        velocity_kernel = cast(tuple, epoch_kernels())[1]
        out, covariance = np.empty((k, 4)), np.empty((k, 4, 4))
        n_used, ok = np.empty(k, dtype=np.int64), np.empty(k, dtype=bool)
        velocity_kernel(np.ascontiguousarray(sat), np.ascontiguousarray(vel), np.ascontiguousarray(rate),
                        np.ascontiguousarray(valid), position, out, covariance, n_used, ok)
        return cast(VelocityFix, _squeezed(VelocityFix(out[:, :3], out[:, 3], covariance, n_used, ok), single))
    position = np.broadcast_to(np.asarray(position_e, dtype=float).reshape(-1, 3), (k, 3))
    rate, valid = _checked(sat, rate, valid)
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
    return cast(VelocityFix, _squeezed(VelocityFix(solution[:, :3], solution[:, 3], covariance, n_used, ok), single))
