"""The compiled white-noise pass of the IMU error model gives the NumPy path's numbers bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from navsim.sensors import imu as imu_mod
from navsim.sensors.imu import ImuErrorModel, ImuState, SensorErrors, VibrationHarmonic, apply_imu_errors_batch
from navsim.sensors.imu import apply as imu_apply
from navsim.sensors.imu import kernel as _imu_kernel

pytestmark = pytest.mark.skipif(not _imu_kernel.available(), reason="numba not installed (extra 'fast')")

H, N, R, B = 0.01, 150, 4, 3


def _truth(rng):
    t = np.arange(N) * H
    omega = 1e-3 * np.sin(t)[:, None] * np.array([1.0, -2.0, 0.5]) + 7e-5
    force = np.array([0.1, 0.2, 9.81]) + 0.01 * np.cos(3 * t)[:, None]
    kern = H ** np.arange(1, R + 1) / np.array([1.0, 2.0, 6.0, 24.0])
    dtheta_r = omega[:, None, :] * kern[None, :, None] + 1e-12 * rng.standard_normal((N, R, 3))
    dv_r = force[:, None, :] * kern[None, :, None]
    return t, dtheta_r, dv_r, omega, force


def _models():
    white = SensorErrors(white_noise_density=np.array([1e-6, 2e-6, 3e-6]))
    full_gyro = SensorErrors(bias=np.array([1e-6, -2e-6, 3e-7]), turn_on_bias_sigma=np.full(3, 1e-6),
                             bias_instability_sigma=np.full(3, 2e-6), bias_correlation_time_s=np.full(3, 300.0),
                             white_noise_density=np.full(3, 5e-7), rate_random_walk=np.full(3, 1e-8),
                             scale_factor=np.array([1e-4, -2e-4, 3e-5]),
                             misalignment=np.array([[0.0, 1e-4, 0.0], [2e-4, 0.0, -1e-4], [0.0, 3e-5, 0.0]]),
                             vibration=(VibrationHarmonic(np.array([1e-4, 0.0, 2e-4]), 13.0, 0.3),))
    full_accel = SensorErrors(bias=np.array([1e-3, 0.0, -2e-3]), white_noise_density=np.full(3, 1e-5),
                              vibration=(VibrationHarmonic(np.array([0.01, 0.02, 0.0]), 7.0),
                                         VibrationHarmonic(np.array([0.0, 0.01, 0.03]), 21.0, 1.0)))
    return {
        "paper-2012 preset": imu_mod.imu_preset("paper-2012"),
        "white noise on the gyro only": ImuErrorModel(gyro=white, accel=SensorErrors()),
        "every error but quantization": ImuErrorModel(gyro=full_gyro, accel=full_accel,
                                                      g_sensitivity=np.full((3, 3), 1e-6)),
    }


@pytest.mark.parametrize("name", list(_models()))
def test_kernel_equals_numpy_path(name, monkeypatch):
    model = _models()[name]
    t, dtheta_r, dv_r, omega, force = _truth(np.random.default_rng(5))
    results = {}
    for use in (True, False):
        monkeypatch.setattr(imu_apply, "USE_KERNEL", use)
        rngs = [np.random.default_rng(100 + j) for j in range(B)]
        states = [ImuState.initial(model, r) for r in rngs]
        outs = []
        for a, b in ((0, 70), (70, N)):  # two calls: the carried states too
            out, states = apply_imu_errors_batch(t[a:b], H, dtheta_r[a:b], dv_r[a:b], omega[a:b], force[a:b],
                                                 model, states, rngs)
            outs.append(out)
        results[use] = outs
    for fast, ref in zip(results[True], results[False]):
        for field in ("dtheta_r", "dv_r", "rate_b", "accel_b"):
            np.testing.assert_array_equal(getattr(fast, field), getattr(ref, field), err_msg=field)
    # written into caller's buffers (out=, as the simulator does): the same numbers
    monkeypatch.setattr(imu_apply, "USE_KERNEL", True)
    rngs = [np.random.default_rng(100 + j) for j in range(B)]
    states = [ImuState.initial(model, r) for r in rngs]
    big = imu_mod.ImuOutput(np.full((B, N, R, 3), np.nan), np.full((B, N, R, 3), np.nan), np.full((B, N, 3), np.nan),
                            np.full((B, N, 3), np.nan))
    for a, b in ((0, 70), (70, N)):
        dest = imu_mod.ImuOutput(big.dtheta_r[:, a:b], big.dv_r[:, a:b], big.rate_b[:, a:b], big.accel_b[:, a:b])
        got, states = apply_imu_errors_batch(t[a:b], H, dtheta_r[a:b], dv_r[a:b], omega[a:b], force[a:b],
                                             model, states, rngs, out=dest)
        assert got is dest
    for field in ("dtheta_r", "dv_r", "rate_b", "accel_b"):
        ref = np.concatenate([getattr(o, field) for o in results[False]], axis=1)
        np.testing.assert_array_equal(getattr(big, field), ref, err_msg=field)
    # the noise is really there (the comparison is not between two noise-free outputs)
    assert np.abs(results[True][0].dtheta_r - dtheta_r[None, :70]).max() > 0


def test_compiled_equals_plain_python():
    """The compiled function and its source run as plain Python agree bit for bit."""
    rng = np.random.default_rng(1)
    z = rng.standard_normal((2, 5, 36))
    factor = np.tril(rng.random((R, R)))
    sd = rng.random((R, 3))
    base_r, base_rate = rng.random((2, 5, R, 3)), rng.random((2, 5, 3))
    outs = []
    for fn in (_imu_kernel.kernel(), _imu_kernel.white_noise_into):
        o_r, o_rate = np.empty((2, 5, R, 3)), np.empty((2, 5, 3))
        fn(z, 18, factor, sd, H, base_r, base_rate, o_r, o_rate)
        outs.append((o_r, o_rate))
    np.testing.assert_array_equal(outs[0][0], outs[1][0])
    np.testing.assert_array_equal(outs[0][1], outs[1][1])
    # first order, axis 1, sample (1, 2): base + factor[0, 0] z * sd, from the draws of slot 0
    assert outs[0][0][1, 2, 0, 1] == base_r[1, 2, 0, 1] + (factor[0, 0] * z[1, 2, 19]) * sd[0, 1]


@pytest.mark.parametrize("order", [2, 4, 6])
def test_kernel_equals_numpy_path_at_other_orders(order, monkeypatch):
    """R = 4 takes the unrolled loop, other orders the general one: both the NumPy path's numbers."""
    rng = np.random.default_rng(order)
    n = 40
    t = np.arange(n) * H
    kern = H ** np.arange(1, order + 1) / np.cumprod(np.arange(1, order + 1))
    dtheta_r = 1e-3 * kern[None, :, None] * (1.0 + rng.random((n, order, 3)))
    dv_r = 9.8 * kern[None, :, None] * (1.0 + rng.random((n, order, 3)))
    omega, force = 1e-3 * rng.random((n, 3)), 9.8 + rng.random((n, 3))
    model = imu_mod.imu_preset("paper-2012")
    results = []
    for use in (True, False):
        monkeypatch.setattr(imu_apply, "USE_KERNEL", use)
        rngs = [np.random.default_rng(7 + j) for j in range(B)]
        states = [ImuState.initial(model, r) for r in rngs]
        results.append(apply_imu_errors_batch(t, H, dtheta_r, dv_r, omega, force, model, states, rngs)[0])
    for field in ("dtheta_r", "dv_r", "rate_b", "accel_b"):
        np.testing.assert_array_equal(getattr(results[0], field), getattr(results[1], field), err_msg=field)
    assert np.abs(results[0].dtheta_r - dtheta_r[None]).max() > 0  # the noise is there


def test_compiled_draws_equal_numpy_fill():
    """The compiled draw loop gives NumPy's ``standard_normal(out=)`` numbers for each
    generator of a group and leaves each where NumPy's fill leaves it (2e6 draws: the
    ziggurat's tail branch, about one draw in 4000, is taken hundreds of times)."""
    block = np.empty((4, 5000, 100))
    fast = [np.random.default_rng(42 + j) for j in range(4)]
    ref = [np.random.default_rng(42 + j) for j in range(4)]
    _imu_kernel.draw_kernel()(fast, block)
    expected = np.stack([r.standard_normal((5000, 100)) for r in ref])
    np.testing.assert_array_equal(block, expected)
    assert np.abs(expected).max() > 3.6541528853610088  # the ziggurat's tail (NumPy's r) was drawn
    for a, b in zip(fast, ref):
        np.testing.assert_array_equal(a.standard_normal(10), b.standard_normal(10))
    # the plain-Python source (one scalar draw at a time) too
    small, plain_rng = np.empty((3, 36)), np.random.default_rng(7)
    _imu_kernel.normals_into(plain_rng, small)
    np.testing.assert_array_equal(small, np.random.default_rng(7).standard_normal((3, 36)))
