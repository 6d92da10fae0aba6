"""The truth generator's compiled sample-end pass and its node channels give the NumPy path's numbers bit for bit.

``navsim.truthgen_kernel`` computes the wrapped heading, mat_nb, the ECEF position and
velocity at the sample ends with the same expressions in the same order as the NumPy
functions (``angle(exp(i psi))``, ``mat_nb_from_hpr``, ``geodetic_to_ecef``, ``mat_en`` +
``einsum``), so equality is exact, not to a tolerance, except for the heading's wrap:
its phase is ``atan2``, NumPy's in the NumPy path and the C library's in the kernel (and
in its source run by the interpreter, through ``cmath``); where the two differ (NumPy's
own SIMD code on AVX-512 CPUs) the wrapped heading agrees to their ulps and mat_nb, a sine
and cosine of it, to that difference plus its own rounding (``tests/tolerances.py``).
``navsim.motion.truth_channels`` returns the same arrays as ``true_state`` without the
ECEF fields.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from tolerances import assert_same_but_elementary

from navsim import truthgen
from navsim import truthgen_kernel as tk
from navsim.earth import SPHERICAL, WGS84, mat_en
from navsim.motion import TrueState, true_state, truth_channels
from navsim.rotations import mat_nb_from_hpr
from navsim.scenario import load_scenario
from navsim.simulator import Simulator

needs_numba = pytest.mark.skipif(not tk.available(), reason="numba not installed (extra 'fast')")


def _numpy_reference(ends, earth):
    """The NumPy path of TruthGenerator._from_channels, written out."""
    lat, lon, hgt, hd, pitch, roll = ends[:, 12], ends[:, 13], ends[:, 14], ends[:, 15], ends[:, 16], ends[:, 17]
    hd = np.angle(np.exp(1j * hd))
    return (hd, mat_nb_from_hpr(hd, pitch, roll), earth.geodetic_to_ecef(lat, lon, hgt),
            np.einsum("nji,nj->ni", mat_en(lat, lon), ends[:, 6:9]))


def _random_ends(n, seed):
    rng = np.random.default_rng(seed)
    ends = rng.standard_normal((n, 18))
    ends[:, 12] = rng.uniform(-1.5, 1.5, n)  # latitude
    ends[:, 13] = rng.uniform(-3.2, 3.2, n)  # longitude
    ends[:, 14] = rng.uniform(-500.0, 5000.0, n)  # height
    ends[:, 15] = rng.uniform(-40.0, 40.0, n)  # unwrapped heading, several turns
    ends[:, 15][:5] = [np.pi, -np.pi, 0.0, 3 * np.pi, -7 * np.pi]
    ends[:, 16:18] = rng.uniform(-0.3, 0.3, (n, 2))  # pitch, roll
    ends[:, 6:9] = 30.0 * rng.standard_normal((n, 3))
    return ends


def _assert_kernel_outputs(got, want):
    """heading (atan2 of the wrap: to the ulps of pi), mat_nb (sine and cosine of that
    heading, derivative <= 1, plus the products' rounding: scale pi + 1), ECEF position
    and velocity (no heading: bit for bit)."""
    assert_same_but_elementary(got[0], want[0], math.pi, what="heading")
    assert_same_but_elementary(got[1], want[1], math.pi + 1.0, what="mat_nb")
    assert np.array_equal(got[2], want[2]) and np.array_equal(got[3], want[3])


def _run(fn, ends, earth):
    n = ends.shape[0]
    out = (np.empty(n), np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3)))
    fn(ends, tk.earth_constants(earth), *out)
    return out


@pytest.mark.parametrize("earth", [SPHERICAL, WGS84], ids=lambda e: e.name)
def test_python_source_equals_numpy_path(earth):
    # the kernel's source run by the interpreter: the expressions themselves (small n)
    ends = _random_ends(300, 1)
    _assert_kernel_outputs(_run(tk.sample_end_state_into, ends, earth), _numpy_reference(ends, earth))


@needs_numba
@pytest.mark.parametrize("earth", [SPHERICAL, WGS84], ids=lambda e: e.name)
def test_compiled_kernel_equals_numpy_path(earth):
    ends = _random_ends(20_000, 2)
    _assert_kernel_outputs(_run(tk.kernel(), ends, earth), _numpy_reference(ends, earth))


def test_truth_channels_are_true_state_fields():
    sim = Simulator(load_scenario("mountain-railway"))  # WGS-84, design cant, oscillations
    t = np.linspace(0.0, 120.0, 777)
    state = true_state(sim.track, sim.profile, t, sim.oscillations)
    names = ("omega_ib_b", "specific_force_b", "velocity_n", "s", "speed", "accel_along", "lat", "lon", "h",
             "heading", "pitch", "roll")
    for name, value in zip(names, truth_channels(sim.track, sim.profile, t, sim.oscillations), strict=True):
        assert np.array_equal(value, getattr(state, name)), name


@needs_numba
@pytest.mark.parametrize("name, overrides", [
    ("paper-2012", {"timing": {"duration_s": 40.0}}),
    ("paper-2012", {"timing": {"tick_s": 1e-3, "imu_period_s": 1e-3, "nav_period_s": 1e-3, "duration_s": 8.0}}),
    ("mountain-railway", {"timing": {"duration_s": 40.0}}),
], ids=["paper-100Hz", "paper-1kHz", "mountain-railway"])
def test_generator_with_and_without_kernel(name, overrides, monkeypatch):
    results = []
    for use in (True, False):
        monkeypatch.setattr(truthgen, "USE_KERNEL", use)
        sim = Simulator(load_scenario(name).with_overrides(overrides))
        gen = sim.truthgen
        results.append(gen.samples(0, int(round(sim.timing.duration_s / gen.h))))
    a, b = results
    assert a.used_block.any()  # the block method (the kernel's path) ran
    for f in ("dtheta_r", "dv_r", "omega_end", "force_end", "used_block"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f
    for f in TrueState.__dataclass_fields__:  # heading and mat_nb: the wrap's atan2 (module notes)
        if f == "heading":
            assert_same_but_elementary(a.truth.heading, b.truth.heading, math.pi, what=f)
        elif f == "mat_nb":
            assert_same_but_elementary(a.truth.mat_nb, b.truth.mat_nb, math.pi + 1.0, what=f)
        else:
            assert np.array_equal(getattr(a.truth, f), getattr(b.truth, f)), f
