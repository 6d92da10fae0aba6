"""Sensors: IMU (:mod:`navsim.sensors.imu`), GNSS (:mod:`navsim.sensors.gnss`), GNSS
signal outages (:mod:`navsim.sensors.outages`), the wheel odometer
(:mod:`navsim.sensors.odometer`) and the barometric altimeter (:mod:`navsim.sensors.baro`);
:mod:`navsim.sensors.models` builds a scenario's IMU and GNSS error models (preset plus
checked overrides).

All of them are truth-side models: they turn the true motion into measurements with
errors drawn from explicit ``numpy.random.Generator`` streams and carry their recursive
error states in frozen state objects (chunk-invariant generation).
"""

from __future__ import annotations

from . import gnss, imu, odometer, outages
from .gnss import (
    C_LIGHT,
    Constellation,
    Fix,
    GnssEpochs,
    GnssErrorModel,
    GnssState,
    SkyGeometry,
    VelocityFix,
    elevation_azimuth,
    least_squares_fix,
    load_yuma,
    reference_almanac,
    satellite_states,
    simulate_epochs,
    sky_geometry,
    solve_kepler,
    velocity_fix,
    walker_constellation,
    write_yuma,
)
from .odometer import (
    OdometerModel,
    OdometerOutput,
    OdometerState,
    simulate_odometer,
    simulate_odometer_batch,
)
from .outages import OutageModel, OutageState, canyon_mask_elevation, visibility

__all__ = [
    "gnss",
    "imu",
    "odometer",
    "outages",
    "C_LIGHT",
    "Constellation",
    "Fix",
    "GnssEpochs",
    "GnssErrorModel",
    "GnssState",
    "SkyGeometry",
    "VelocityFix",
    "elevation_azimuth",
    "least_squares_fix",
    "load_yuma",
    "reference_almanac",
    "satellite_states",
    "simulate_epochs",
    "sky_geometry",
    "solve_kepler",
    "velocity_fix",
    "walker_constellation",
    "write_yuma",
    "OdometerModel",
    "OdometerOutput",
    "OdometerState",
    "simulate_odometer",
    "simulate_odometer_batch",
    "OutageModel",
    "OutageState",
    "canyon_mask_elevation",
    "visibility",
]
