"""navsim: inertial-satellite navigation of a vehicle on a known track.

One core simulator produces true motion and sensor data; plug-in estimators turn sensor
data into a navigation solution; metrics score each episode. The Gymnasium environment
(``navsim.envs``) and the FMU (``navsim.fmu``) are thin faces of the same core.

Conventions (stated once, here)
-------------------------------
Units
    SI inside, radians inside. Degrees appear only at the edges (scenario files, reports),
    always in fields whose names end in ``_deg``.
Frames
    ``i``  inertial: coincides with ``e`` at t = 0 (seed 003).
    ``e``  ECEF: x through lat 0 / lon 0, z to the north pole. Seed 003 writes its
           Greenwich axes as (xi, eta, zeta) = (y_e, z_e, x_e).
    ``n``  local level East-North-Up: the "accompanying frame" S of seed 003
           (X east, Y north, Z up).
    ``b``  body = IMU axes: x right, y forward, z up. A vehicle heading north on a level
           track has ``b`` aligned with ``n`` (the initial condition of seed 003).
Attitude
    ``mat_ab`` maps b-components to a-components (``v_a = mat_ab @ v_b``). Quaternions
    are scalar first (Rodrigues-Hamilton, seed 001). Vehicle angles: heading clockwise
    from north, pitch forward-axis up, roll right side down; Euler-Krylov angles of seed
    003 in :mod:`navsim.rotations`.
Position
    Geodetic latitude, longitude (rad) and height (m) on the scenario's Earth model
    (:mod:`navsim.earth`): the spherical Earth of seed 003 or WGS-84.
Names
    By physics with a frame suffix: ``velocity_n``, ``omega_ib_b`` (rate of b relative
    to i, in b axes), ``specific_force_b``, ``mat_nb``. Increments: ``dtheta``, ``dv``
    (r = 1) and the multiple integrals ``dtheta_r``, ``dv_r`` of seed 000 eq. (1.14),
    ``dtheta_r[..., r-1, :]`` being the r-fold integral over one sample.
Time
    An integer tick count; ``t = t0 + tick * tick_s``, never a float accumulator. The IMU
    sample, navigation step, GNSS epoch, env step and FMU step are whole multiples of the
    tick; anything else is rejected when the scenario is built.
Randomness
    ``Simulator.reset(seed)`` makes one :class:`numpy.random.SeedSequence` and spawns
    named child streams (motion, imu, gnss, outages, initial_error, odometer). Turning a source off
    changes no other stream; generation is chunk-invariant (the same numbers whatever
    the chunk size). The global NumPy RNG is never used.
Missing data
    A GNSS outage or a satellite below the mask is a value with a validity mask, not an
    exception. Errors on bad input derive from :class:`navsim.errors.NavsimError`.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version
from typing import TYPE_CHECKING

from . import _gymhook, earth, errors, rotations

if TYPE_CHECKING:  # type hints only
    from typing import Any

try:
    __version__ = version("navsim-track")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"

__all__ = ["earth", "errors", "rotations", "evaluate", "__version__"]

# The core never imports Gymnasium. The navsim env ids are registered now if it is
# imported already (``import gymnasium as gym, navsim``), else as soon as it is
# (``import navsim, gymnasium``); ``import navsim.envs`` registers them too.
_gymhook.install()


def __getattr__(name: str) -> Any:
    if name == "evaluate":  # lazily: it lives in the Gymnasium face
        from .envs import evaluate

        return evaluate
    raise AttributeError(f"module 'navsim' has no attribute {name!r}")
