"""The one navigation-error function (navsim.naverror) and make_context from a scenario."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from tolerances import assert_same_but_elementary

from navsim.earth import WGS84, mat_en
from navsim.episode import make_context
from navsim.naverror import (
    local_level_error,
    local_level_error_scalar,
    local_level_factors,
    wrap_angle,
    wrap_angle_scalar,
)
from navsim.scenario import list_scenarios, load_scenario
from navsim.simulator import Simulator


def test_wrap_is_the_principal_value_and_scalar_equals_array():
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.standard_normal(20000) * s for s in (1e-9, 1e-4, 1.0, 10.0, 1e3)])
    w = wrap_angle(x)
    assert np.all(w > -math.pi) and np.all(w <= math.pi)
    # the same angle: x - w is a whole number of turns (to the rounding of x)
    turns = (x - w) / (2 * math.pi)
    assert np.allclose(turns, np.round(turns), rtol=0, atol=1e-9 * np.maximum(1.0, np.abs(x)).max())
    assert np.allclose(w[np.abs(x) < 3.0], x[np.abs(x) < 3.0], rtol=4e-16, atol=0)  # inside: x itself to 1 ulp
    # the same complex exponential and phase; the phase is atan2, NumPy's or the C
    # library's (cmath): bit for bit where they agree, else to their ulps (tests/tolerances.py)
    assert_same_but_elementary([wrap_angle_scalar(float(v)) for v in x], w, math.pi, what="wrap")
    assert math.isnan(wrap_angle_scalar(math.inf)) and math.isnan(wrap_angle_scalar(math.nan))
    assert np.isnan(wrap_angle(np.array([np.inf, np.nan]))).all()


def test_local_level_error_against_the_exact_enu_difference():
    """Independent truth: ECEF difference rotated into ENU at the true position. The
    linearisation's relative error is of the order error / Earth radius."""
    rng = np.random.default_rng(1)
    n = 2000
    lat = rng.uniform(-1.4, 1.4, n)
    lon = rng.uniform(-math.pi, math.pi, n)
    h = rng.uniform(-100.0, 3000.0, n)
    d = rng.standard_normal((n, 3)) * 10.0  # metres
    k_north, re_h, cos_lat = local_level_factors(lat, h, WGS84)
    est_lat = lat + d[:, 1] / k_north
    est_lon = lon + d[:, 0] / (re_h * cos_lat)
    est_lon = np.where(est_lon > math.pi, est_lon - 2 * math.pi, est_lon)  # crossing the date line: wrapped
    est_h = h + d[:, 2]
    d_e, d_n, d_u = local_level_error(est_lat, est_lon, est_h, lat, lon, h, WGS84)
    assert np.allclose(np.column_stack([d_e, d_n, d_u]), d, rtol=0, atol=1e-7)  # the inverse of its own definition
    exact = np.einsum("kij,kj->ki", mat_en(lat, lon), WGS84.geodetic_to_ecef(est_lat, est_lon, est_h)
                      - WGS84.geodetic_to_ecef(lat, lon, h))
    err = np.linalg.norm(np.column_stack([d_e, d_n, d_u]) - exact, axis=1)
    assert np.all(err <= 10.0 * np.linalg.norm(d, axis=1) ** 2 / 6.3e6 + 1e-6)
    rows = [local_level_error_scalar(*map(float, (est_lat[i], est_lon[i], est_h[i], lat[i], lon[i], h[i],
                                                  k_north[i], re_h[i], cos_lat[i]))) for i in range(n)]
    assert np.array_equal(np.array(rows), np.column_stack([d_e, d_n, d_u]))  # scalar form: bit for bit


@pytest.mark.parametrize("name", list_scenarios())
def test_make_context_from_the_scenario_equals_the_simulators(name):
    over = {"odometer": {"enabled": True, "preset": "car-wheel-speed"}, "gnss": {"preset": "standalone"},
            "imu": {"preset": "consumer-mems"}}
    for sc in (load_scenario(name), load_scenario(name).with_overrides(over)):
        a, b = make_context(sc), make_context(Simulator(sc))
        for f in dataclasses.fields(a):
            if f.name != "track":
                assert getattr(a, f.name) == getattr(b, f.name), f.name
        s = np.linspace(0.0, 0.9 * b.track.length, 7)
        for x, y in zip(a.track.geodetic(s), b.track.geodetic(s)):
            assert np.array_equal(x, y)
    assert b.odometer is not None and b.gnss.clock_modelled and b.gnss.atmosphere_modelled
