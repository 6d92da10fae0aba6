"""The compiled strapdown loop (navsim.strapdown.compiled) is the sequential loop bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from navsim.earth import SPHERICAL, WGS84
from navsim.rotations import mat_nb_from_hpr, mat_to_quat
from navsim.strapdown import compiled
from navsim.strapdown.ins import InsState, body_terms, integrate_body_terms

pytestmark = pytest.mark.skipif(not compiled.available(), reason="numba not installed (extra 'fast')")

DT, N = 0.01, 3000


def _moving(rng):
    """A turning, climbing vehicle: body rates and specific force with noise (not at rest)."""
    k = np.arange(N)[:, None]
    dth = 1e-4 * np.sin(0.01 * k + np.array([0.0, 1.0, 2.0])) * DT + 1e-7 * rng.standard_normal((N, 3))
    dv = (np.array([0.3, 0.5, 9.80]) + 0.2 * np.cos(0.02 * k)) * DT
    return dth, dv


@pytest.mark.parametrize("earth", [WGS84, SPHERICAL], ids=["wgs84", "spherical"])
@pytest.mark.parametrize("form", ["rectangle", "trapezoid", "exact"])
def test_compiled_is_sequential_bit_for_bit(earth, form):
    rng = np.random.default_rng(3)
    dth, dv = _moving(rng)
    if form == "exact":
        kern = DT ** np.arange(1, 5) / np.array([1.0, 2.0, 6.0, 24.0])
        terms = body_terms(None, None, dth[:, None, :] * (kern / DT)[None, :, None],
                           dv[:, None, :] * (kern / DT)[None, :, None], DT)
    else:
        terms = body_terms(dth[:, None, :], dv[:, None, :], None, None, DT, coning="one-sample",
                           sculling="first-order", position=form)
    state = InsState(0.9, 0.4, 250.0, np.array([5.0, 20.0, 0.3]), mat_to_quat(mat_nb_from_hpr(0.3, 0.02, -0.01)),
                     (1e-17, -2e-17, 3e-13))
    args = (terms.quat_body, terms.dv_body, terms.ds_body, terms.rule, DT, earth)
    seq = integrate_body_terms(state, *args, method="sequential")
    com = integrate_body_terms(state, *args, method="compiled")
    for field in ("lat", "lon", "h", "velocity_n", "quat_nb"):
        np.testing.assert_array_equal(getattr(com, field), getattr(seq, field), err_msg=field)
    assert com.final_compensation == seq.final_compensation
    # it moved: the comparison is between non-trivial trajectories
    assert abs(seq.lat[-1] - seq.lat[0]) > 1e-6 and abs(seq.h[-1] - seq.h[0]) > 1.0
    # against the loop-free scan: the same solution to rounding (relative to each quantity's scale)
    scan = integrate_body_terms(state, *args, method="scan")
    scale = {"lat": 1.0, "lon": 1.0, "h": 1e3, "velocity_n": 100.0, "quat_nb": 1.0}
    for field, s in scale.items():
        assert np.abs(np.asarray(getattr(scan, field)) - getattr(com, field)).max() <= 1e-12 * s, field


def test_auto_short_runs_use_the_loop_numbers():
    rng = np.random.default_rng(4)
    dth, dv = _moving(rng)
    terms = body_terms(dth[:100, None, :], dv[:100, None, :], None, None, DT, coning="one-sample",
                       sculling="first-order", position="trapezoid")
    state = InsState(0.5, 0.1, 10.0, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))
    args = (terms.quat_body, terms.dv_body, terms.ds_body, terms.rule, DT, WGS84)
    auto = integrate_body_terms(state, *args)
    seq = integrate_body_terms(state, *args, method="sequential")
    np.testing.assert_array_equal(auto.velocity_n, seq.velocity_n)
    np.testing.assert_array_equal(auto.lat, seq.lat)
