"""Rotations: direction cosine matrices, quaternions, rotation vectors and angles.

Conventions (see the package docstring):

* A DCM ``mat_ab`` maps components in frame b to frame a: ``v_a = mat_ab @ v_b``.
* Quaternions are scalar first, ``q = [q0, q1, q2, q3]`` (Rodrigues-Hamilton parameters
  lambda_0..lambda_3 of seed 001), Hamilton product; ``q_ab`` rotates b-components into
  a-components, ``v_a = q_ab * v_b * conj(q_ab)``, and ``quat_to_mat(q_ab) = mat_ab``.
* Vehicle attitude angles in the ENU navigation frame with body axes x right, y forward,
  z up: heading psi (clockwise from north, toward east), pitch theta (forward axis up
  positive), roll rho (right side down positive);
  ``mat_nb = Rz(-psi) @ Rx(theta) @ Ry(rho)`` with active elementary rotations.
* Euler-Krylov angles alpha, beta, gamma of seed 003, Appendix 1: the matrix
  ``D(alpha, beta, gamma) = Rz'(gamma) Rx'(alpha) Ry'(beta)`` of *passive* elementary
  rotations (it maps reference components to body components), exactly as printed.

All functions are vectorised over leading dimensions and use radians.

Notes
-----
Seed 003 has two inconsistencies that navsim resolves as follows (checked numerically in
``tests/test_rotations.py``):

* The ENU-to-Greenwich matrix is written ``B = D(lambda + Omega t, -phi, 0)`` in one place
  and ``B = D(-phi, lambda, 0)`` in another. With Appendix 1 as printed only the second is
  the ENU frame; navsim uses ``D(-phi, lambda, 0)`` (and ``D(-phi, lambda + Omega t, 0)``
  relative to the inertial frame).
* The printed kinematic matrix Phi(beta, gamma) of eq. (1) is the kinematic matrix of
  ``D`` with alpha and beta interchanged. For ``D`` as printed, the angle rates are
  ``[alpha', beta', gamma'] = Phi(alpha, gamma) omega_b`` with
  ``Phi = [[cos g, -sin g, 0], [sin g / cos a, cos g / cos a, 0],
  [sin g tan a, cos g tan a, 1]]`` (:func:`euler_krylov_rate_matrix`); its singularity
  is at alpha = +-90 deg, where Appendix 1 loses a degree of freedom.

References
----------
.. [1] Sokolov S.V., Vdovichenko S.S. (2012), seed 003, eq. (1) and Appendix 1.
.. [2] Kononenko V.A. (2007), seed 001: Rodrigues-Hamilton parameters.
.. [3] Ishlinsky A.Yu., Orientation, Gyroscopes and Inertial Navigation, 1976.
.. [4] Savage P.G., Strapdown Analytics, 2nd ed., 2007, ch. 3 (rotation vector).
"""

from __future__ import annotations

import numpy as np

from .types import FloatOrArray

__all__ = [
    "skew",
    "quat_multiply",
    "quat_conjugate",
    "quat_normalize",
    "quat_from_rotvec",
    "quat_to_rotvec",
    "quat_to_mat",
    "mat_to_quat",
    "mat_from_rotvec",
    "mat_nb_from_hpr",
    "hpr_from_mat_nb",
    "body_rate_from_hpr_rates",
    "euler_krylov_matrix",
    "euler_krylov_from_matrix",
    "euler_krylov_rate_matrix",
]


def skew(vector: FloatOrArray) -> np.ndarray:
    """Cross-product matrix ``[v x]`` with ``skew(a) @ b == cross(a, b)``, shape (..., 3, 3)."""
    v = np.asarray(vector, dtype=float)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    zero = np.zeros_like(x)
    return np.stack(
        [
            np.stack([zero, -z, y], axis=-1),
            np.stack([z, zero, -x], axis=-1),
            np.stack([-y, x, zero], axis=-1),
        ],
        axis=-2,
    )


# ---------------------------------------------------------------------------- quaternions
def quat_multiply(p: FloatOrArray, q: FloatOrArray) -> np.ndarray:
    """Hamilton product ``p * q`` of scalar-first quaternions, shape (..., 4)."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    p0, p1, p2, p3 = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    q0, q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
            p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
            p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
            p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0,
        ],
        axis=-1,
    )


def quat_conjugate(q: FloatOrArray) -> np.ndarray:
    """Conjugate (inverse of a unit quaternion), shape (..., 4)."""
    q = np.array(q, dtype=float)
    q[..., 1:] *= -1.0
    return q


def quat_normalize(q: FloatOrArray) -> np.ndarray:
    """Scale to unit norm, shape (..., 4)."""
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_from_rotvec(rotvec: FloatOrArray) -> np.ndarray:
    """Quaternion of the rotation vector phi: ``[cos(|phi|/2), sin(|phi|/2) phi/|phi|]``.

    Uses the Taylor series of sin(x/2)/x below |phi| = 1e-4 rad, so it is accurate to
    machine precision for the tiny rotations of one strapdown step.
    """
    v = np.asarray(rotvec, dtype=float)
    angle2 = np.sum(v * v, axis=-1)
    angle = np.sqrt(angle2)
    small = angle < 1e-4
    safe = np.where(small, 1.0, angle)
    # sin(a/2)/a = 1/2 - a^2/48 + a^4/3840
    half_sinc = np.where(small, 0.5 - angle2 / 48.0 + angle2**2 / 3840.0, np.sin(0.5 * safe) / safe)
    return np.concatenate([np.cos(0.5 * angle)[..., None], half_sinc[..., None] * v], axis=-1)


def quat_to_rotvec(q: FloatOrArray) -> np.ndarray:
    """Rotation vector of a unit quaternion, angle in [0, pi], shape (..., 3)."""
    q = np.asarray(q, dtype=float)
    q = np.where(q[..., :1] < 0.0, -q, q)
    vec_norm = np.linalg.norm(q[..., 1:], axis=-1)
    angle = 2.0 * np.arctan2(vec_norm, q[..., 0])
    small = vec_norm < 1e-8
    scale = np.where(small, 2.0 / np.where(small, q[..., 0], 1.0), angle / np.where(small, 1.0, vec_norm))
    return scale[..., None] * q[..., 1:]


def quat_to_mat(q: FloatOrArray) -> np.ndarray:
    """DCM of a unit quaternion: ``quat_to_mat(q_ab) = mat_ab``, shape (..., 3, 3)."""
    q = np.asarray(q, dtype=float)
    q0, q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)], -1),
            np.stack([2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 - q0 * q1)], -1),
            np.stack([2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3], -1),
        ],
        axis=-2,
    )


def mat_to_quat(mat: FloatOrArray) -> np.ndarray:
    """Unit quaternion (scalar first, q0 >= 0) of a DCM, shape (..., 4).

    Delegates to :class:`scipy.spatial.transform.Rotation`, whose conversion is robust
    near 180 deg rotations.
    """
    from scipy.spatial.transform import Rotation

    mat = np.asarray(mat, dtype=float)
    shape = mat.shape[:-2]
    quat = Rotation.from_matrix(mat.reshape(-1, 3, 3)).as_quat()  # scalar last
    quat = np.concatenate([quat[:, 3:], quat[:, :3]], axis=1)
    quat = np.where(quat[:, :1] < 0.0, -quat, quat)
    return quat.reshape(shape + (4,))


def mat_from_rotvec(rotvec: FloatOrArray) -> np.ndarray:
    """DCM of a rotation vector (Rodrigues' formula), shape (..., 3, 3)."""
    return quat_to_mat(quat_from_rotvec(rotvec))


# ----------------------------------------------------------- vehicle heading/pitch/roll
def mat_nb_from_hpr(heading: FloatOrArray, pitch: FloatOrArray, roll: FloatOrArray) -> np.ndarray:
    """Body-to-ENU DCM from heading, pitch and roll (rad), shape (..., 3, 3).

    ``mat_nb = Rz(-heading) Rx(pitch) Ry(roll)``; the body y (forward) axis in ENU is
    ``[sin(psi) cos(theta), cos(psi) cos(theta), sin(theta)]``.
    """
    heading, pitch, roll = np.broadcast_arrays(
        *(np.asarray(x, dtype=float) for x in (heading, pitch, roll))
    )
    sh, ch = np.sin(heading), np.cos(heading)
    sp, cp = np.sin(pitch), np.cos(pitch)
    sr, cr = np.sin(roll), np.cos(roll)
    return np.stack(
        [
            np.stack([ch * cr + sh * sp * sr, sh * cp, ch * sr - sh * sp * cr], -1),
            np.stack([-sh * cr + ch * sp * sr, ch * cp, -sh * sr - ch * sp * cr], -1),
            np.stack([-cp * sr, sp, cp * cr], -1),
        ],
        axis=-2,
    )


def hpr_from_mat_nb(mat_nb: FloatOrArray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`mat_nb_from_hpr`: heading in (-pi, pi], pitch, roll (rad)."""
    m = np.asarray(mat_nb, dtype=float)
    pitch = np.arcsin(np.clip(m[..., 2, 1], -1.0, 1.0))
    heading = np.arctan2(m[..., 0, 1], m[..., 1, 1])
    roll = np.arctan2(-m[..., 2, 0], m[..., 2, 2])
    return heading, pitch, roll


def body_rate_from_hpr_rates(heading: FloatOrArray, pitch: FloatOrArray, roll: FloatOrArray, heading_rate: FloatOrArray,
                             pitch_rate: FloatOrArray, roll_rate: FloatOrArray) -> np.ndarray:
    """omega_nb_b, the body rate relative to ENU in body axes, from angle rates (rad/s).

    Differentiating ``mat_nb = Rz(-psi) Rx(theta) Ry(rho)`` gives
    ``omega_nb_b = [psi' sin(rho) cos(theta) + theta' cos(rho),
    rho' - psi' sin(theta), theta' sin(rho) - psi' cos(rho) cos(theta)]``.
    """
    del heading  # the body rate does not depend on the heading itself
    sp, cp = np.sin(pitch), np.cos(pitch)
    sr, cr = np.sin(roll), np.cos(roll)
    return np.stack(
        [
            heading_rate * sr * cp + pitch_rate * cr,
            roll_rate - heading_rate * sp,
            pitch_rate * sr - heading_rate * cr * cp,
        ],
        axis=-1,
    )


# ------------------------------------------------------------- Euler-Krylov angles (003)
def euler_krylov_matrix(alpha: FloatOrArray, beta: FloatOrArray, gamma: FloatOrArray) -> np.ndarray:
    """The matrix D(alpha, beta, gamma) of seed 003, Appendix 1, shape (..., 3, 3).

    It maps reference-frame components to body components (a passive rotation):
    ``D = Rz'(gamma) Rx'(alpha) Ry'(beta)``.
    """
    alpha, beta, gamma = np.broadcast_arrays(
        *(np.asarray(x, dtype=float) for x in (alpha, beta, gamma))
    )
    sa, ca = np.sin(alpha), np.cos(alpha)
    sb, cb = np.sin(beta), np.cos(beta)
    sg, cg = np.sin(gamma), np.cos(gamma)
    # Appendix 1, row by row as printed
    return np.stack(
        [
            np.stack([sb * sa * sg + cb * cg, ca * sg, cb * sa * sg - sb * cg], -1),
            np.stack([sb * sa * cg - cb * sg, ca * cg, cb * sa * cg + sb * sg], -1),
            np.stack([sb * ca, -sa, cb * ca], -1),
        ],
        axis=-2,
    )


def euler_krylov_from_matrix(mat: FloatOrArray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`euler_krylov_matrix`: alpha in [-pi/2, pi/2], beta, gamma."""
    m = np.asarray(mat, dtype=float)
    alpha = np.arcsin(np.clip(-m[..., 2, 1], -1.0, 1.0))
    beta = np.arctan2(m[..., 2, 0], m[..., 2, 2])
    gamma = np.arctan2(m[..., 0, 1], m[..., 1, 1])
    return alpha, beta, gamma


def euler_krylov_rate_matrix(alpha: FloatOrArray, gamma: FloatOrArray) -> np.ndarray:
    """Kinematic matrix Phi with ``[alpha', beta', gamma'] = Phi @ omega_b``, (..., 3, 3).

    ``omega_b`` is the body rate relative to the reference frame of D, in body axes.
    This is the corrected form of 003 eq. (1); see the module notes.
    """
    alpha, gamma = np.broadcast_arrays(np.asarray(alpha, dtype=float), np.asarray(gamma, dtype=float))
    sg, cg = np.sin(gamma), np.cos(gamma)
    ca, ta = np.cos(alpha), np.tan(alpha)
    zero, one = np.zeros_like(alpha), np.ones_like(alpha)
    return np.stack(
        [
            np.stack([cg, -sg, zero], -1),
            np.stack([sg / ca, cg / ca, zero], -1),
            np.stack([sg * ta, cg * ta, one], -1),
        ],
        axis=-2,
    )
