"""Whether the optional compiled kernels can be used: numba (extra ``fast``) is installed.

The compiled kernels (``navsim.sensors.imu.kernel``, ``navsim.strapdown.compiled``,
``navsim.estimators.paper_ekf.kernel``, ``navsim.receiver.epoch_kernels``) compile their
float functions with numba on first use and keep the pure-NumPy/Python paths as the
reference; this module answers, once per process and without importing numba, whether they
may.
"""

from __future__ import annotations

import functools
import importlib.util


@functools.cache
def available() -> bool:
    """True when numba is installed (it is not imported here)."""
    return importlib.util.find_spec("numba") is not None
