"""Metrics: pure functions over arrays of an episode record.

Errors follow the estimator covariance convention of :mod:`navsim.estimators.base`:
``[dE, dN, dU, dvE, dvN, dvU, psiE, psiN, psiU]`` with position errors in metres in the
true position's ENU frame and psi the small rotation of the estimated attitude relative
to the true one about ENU axes (``mat_nb_est = exp([psi x]) mat_nb_true``).

References
----------
.. [1] Bar-Shalom Y., Li X.R., Kirubarajan T., Estimation with Applications to Tracking
       and Navigation, Wiley 2001, section 5.4 (NEES, NIS and their chi-square tests).
"""

from __future__ import annotations

import numpy as np

from .rotations import mat_nb_from_hpr, mat_to_quat, quat_to_rotvec

__all__ = ["error_vector", "nees"]


def error_vector(record) -> np.ndarray:
    """Estimation error (n, 9) = estimate - truth in the convention above."""
    earth = record.earth
    r_n, r_e = earth.radii(record.truth_lat)
    d_e = np.angle(np.exp(1j * (record.est_lon - record.truth_lon))) * (r_e + record.truth_h) * np.cos(record.truth_lat)
    d_n = (record.est_lat - record.truth_lat) * (r_n + record.truth_h)
    d_u = record.est_h - record.truth_h
    dv = record.est_velocity_n - record.truth_velocity_n
    mat_est = mat_nb_from_hpr(*record.est_hpr.T)
    mat_true = mat_nb_from_hpr(*record.truth_hpr.T)
    finite = np.all(np.isfinite(record.est_hpr), axis=1)
    psi = np.full((len(d_e), 3), np.nan)
    if finite.any():
        rel = mat_est[finite] @ np.swapaxes(mat_true[finite], -1, -2)
        psi[finite] = quat_to_rotvec(mat_to_quat(rel))
    return np.column_stack([d_e, d_n, d_u, dv, psi])


def nees(errors: np.ndarray, covariance: np.ndarray, components=slice(None)) -> np.ndarray:
    """Normalised estimation error squared e^T P^-1 e per step over the chosen components.

    Steps whose covariance block has a non-finite entry give nan.
    """
    e = errors[:, components]
    p = covariance[:, components, components]
    out = np.full(len(e), np.nan)
    ok = np.all(np.isfinite(p.reshape(len(p), -1)), axis=1) & np.all(np.isfinite(e), axis=1)
    if ok.any():
        sol = np.linalg.solve(p[ok], e[ok][..., None])[..., 0]
        out[ok] = np.einsum("ni,ni->n", e[ok], sol)
    return out
