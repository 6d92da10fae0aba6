"""The antenna at a lever arm from the IMU (:func:`antenna_state`), Groves 2013 sec. 14.2.3 and
14.3.3: ``r_a = r + C_eb l`` (LA.1), ``v_a = v + C_eb (omega_ib_b x l) - omega_ie x C_eb l`` (LA.2).
"""

from __future__ import annotations

import numpy as np

from ...earth import WGS84, EarthModel


def antenna_state(position_e: np.ndarray, velocity_e: np.ndarray, mat_eb: np.ndarray, omega_ib_b: np.ndarray,
                  lever_arm_b: np.ndarray, earth: EarthModel = WGS84) -> tuple[np.ndarray, np.ndarray]:
    """ECEF position and ECEF-frame velocity of an antenna at a lever arm from the IMU.

    Parameters
    ----------
    position_e, velocity_e : array_like (..., 3)
        ECEF position (m) and velocity relative to the Earth (m/s) of the IMU.
    mat_eb : array_like (..., 3, 3)
        Body-to-ECEF attitude matrix (``mat_en(lat, lon).T @ mat_nb``).
    omega_ib_b : array_like (..., 3)
        Body rate relative to inertial space in body axes, rad/s.
    lever_arm_b : array_like (3,) or (..., 3)
        Antenna phase centre relative to the IMU in body axes (x right, y forward,
        z up), m.
    earth : EarthModel
        Its rotation rate Omega gives ``omega_ie_e = [0, 0, Omega]``.

    Returns
    -------
    position_e, velocity_e : ndarray (..., 3)
        Of the antenna::

            r_a = r + C_eb l                                               (LA.1)
            v_a = v + C_eb (omega_ib_b x l) - omega_ie_e x (C_eb l)       (LA.2)

    (LA.2) is the time derivative of (LA.1) in the ECEF frame, ``dC_eb/dt = C_eb
    [omega_eb_b x]`` with ``omega_eb_b = omega_ib_b - C_be omega_ie_e``; the ECEF form of
    the lever-arm relations of Groves (2013), sections 14.2.3 and 14.3.3. tests/sensors/test_lever_arm.py checks
    (LA.2) against finite differences of (LA.1) along a true trajectory.
    """
    position_e = np.asarray(position_e, dtype=float)
    velocity_e = np.asarray(velocity_e, dtype=float)
    mat_eb = np.asarray(mat_eb, dtype=float)
    lever = np.asarray(lever_arm_b, dtype=float)
    omega = np.asarray(omega_ib_b, dtype=float)
    arm_e = np.einsum("...ij,...j->...i", mat_eb, lever)  # C_eb l
    turn_b = np.cross(omega, lever)  # omega_ib_b x l
    rate = earth.rate
    # omega_ie_e x (C_eb l) with omega_ie_e = [0, 0, Omega]
    earth_turn = np.stack([-rate * arm_e[..., 1], rate * arm_e[..., 0], np.zeros_like(arm_e[..., 0])], axis=-1)
    position_a = position_e + arm_e  # (LA.1)
    velocity_a = velocity_e + np.einsum("...ij,...j->...i", mat_eb, turn_b) - earth_turn  # (LA.2)
    return position_a, velocity_a
