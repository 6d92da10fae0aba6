"""Constants of the GNSS models: the speed of light, IS-GPS-200's Earth rate, WGS-84's J2, the
GPS week and the packaged almanac's file name.
"""

from __future__ import annotations

C_LIGHT = 299_792_458.0
"""Speed of light in vacuum, m/s."""

OMEGA_E_GPS = 7.2921151467e-5
"""Earth rotation rate of IS-GPS-200, rad/s (used only to read/write YUMA node angles)."""

J2_WGS84 = 1.08262668e-3
"""Second zonal harmonic (WGS-84 / EGM96, NIMA TR8350.2), for the Walker node rate."""

SECONDS_PER_WEEK = 604_800.0

REFERENCE_ALMANAC = "gps_walker_24_6_1.alm"
"""File name of the packaged YUMA almanac (navsim/data/almanac)."""
