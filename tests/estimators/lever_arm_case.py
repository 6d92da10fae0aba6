"""The shared test case of the antenna lever-arm tests (not a test module).

A roof antenna 1.5 m forward of and 3 m above the IMU on the curvy part of the
mountain railway (curves of 300-500 m radius with design cant from s = 2300 m), at a
constant 19.4 m/s without body oscillations. The truth matches the filters' models:
a tactical IMU without the error terms the filters do not estimate (fixed biases,
scale factors, misalignments, quantisation; as in test_loosely.py), and white GNSS
noise (the paper-2012 preset) with small sigmas (1 m, 0.05 m/s) so that the lever arm
is large against the noise.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from navsim.metrics import error_vector, nees
from navsim.scenario import load_scenario

LEVER_ARM_M = (0.0, 1.5, 3.0)
_MATCHED = {"bias": 0.0, "scale_factor": 0.0, "misalignment": 0.0, "quantization_lsb": 0.0}


def lever_scenario(duration_s: float = 60.0, lever_arm_m=LEVER_ARM_M, name: str = "mountain-railway"):
    over = {
        "timing": {"duration_s": duration_s},
        "motion": {"profile": "constant", "speed_mps": 19.4, "start_s_m": 2300.0, "stations": [],
                   "oscillations": []},
        "imu": {"preset": "tactical", "gyro": _MATCHED, "accel": _MATCHED},
        "gnss": {"preset": "paper-2012", "lever_arm_m": list(lever_arm_m),
                 "overrides": {"pseudorange_sigma_m": 1.0, "doppler_sigma_mps": 0.05}},
        "initial": {"position_m": 3.0, "velocity_mps": 0.1, "attitude_deg": 0.2},
    }
    if name == "urban-road":
        over["motion"].update(speed_mps=10.0, start_s_m=150.0)
    return load_scenario(name).with_overrides(over)


def zero_lever_context(context):
    """The same context with the antenna told to be at the IMU (an uncompensated filter)."""
    return dataclasses.replace(context, gnss=dataclasses.replace(context.gnss, lever_arm_b_m=(0.0, 0.0, 0.0)))


def figures(record, skip_s: float = 20.0, components=slice(0, 9)):
    """Horizontal RMS / max error (m), vertical RMS (m) and mean NEES after skip_s."""
    e = error_vector(record)
    k = record.t > skip_s
    horizontal = np.hypot(e[k, 0], e[k, 1])
    idx = np.arange(9)[components]
    return {"h_rms": float(np.sqrt(np.mean(horizontal**2))), "h_max": float(horizontal.max()),
            "up_rms": float(np.sqrt(np.mean(e[k, 2] ** 2))),
            "nees": nees(e, record.est_cov, idx)[k], "dof": len(idx)}
