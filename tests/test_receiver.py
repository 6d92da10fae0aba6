"""The receiver's single-epoch fixes: the compiled per-epoch kernels against the NumPy path.

* the compiled kernels run the same operations for an epoch alone and in a batch: equal
  bit for bit (what makes an estimator's ``step`` equal its ``step_batch``);
* the NumPy path (all epochs at once) and the compiled one sum the normal equations in
  different orders and invert them differently (LU against an eigen-decomposition): they
  agree to the rounding bounds derived in :func:`_position_bound`, :func:`_velocity_bound`
  and :func:`_covariance_bound`;
* each epoch stops on its own ``max |dx| < tol_m``; rank test and missing data as values.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from navsim import receiver
from navsim.earth import WGS84
from navsim.errors import ConfigError
from navsim.sensors import gnss as g
from tolerances import EPS, UNIT_ROUNDOFF, assert_same_arithmetic, gamma

needs_numba = pytest.mark.skipif(not receiver.available(), reason="numba not installed (extra 'fast')")


def _epochs(mask_deg: float, seed: int = 3):
    """60 epochs of a receiver moving near Rostov, paper-2012 errors (15 m pseudorange
    noise, clock), with an elevation mask: 4-12 satellites per epoch at 20 degrees."""
    model = dataclasses.replace(g.GnssErrorModel.preset("paper-2012"), elevation_mask_deg=mask_deg)
    c = g.walker_constellation("gps")
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 6000.0, 100.0)
    p0 = WGS84.geodetic_to_ecef(np.radians(47.2), np.radians(39.7), 80.0)
    v = np.array([-12.0, 15.0, 9.0])
    pos, vel = p0 + t[:, None] * v, np.broadcast_to(v, (len(t), 3)).copy()
    epochs, _ = g.simulate_epochs(t, pos, vel, c, model, g.GnssState.initial(model, c, rng), rng)
    return epochs


@pytest.fixture(scope="module", params=[5.0, 20.0], ids=["mask5", "mask20"])
def epochs(request):
    return _epochs(request.param)


def _position_bound(fix, epochs) -> np.ndarray:
    """Bound (k, 4) on |x_numpy - x_compiled| (position m, clock m) of converged epochs.

    At the solution both paths solve ``H^T H dx = H^T r`` with the residuals
    ``r_j = rho_j - (|r_s - r| + b)`` computed in floating point: about five roundings of
    quantities of the size of the pseudorange (the subtraction, squares and root of the
    range, the two subtractions of the residual), so ``|dr_j| <= 5 u max|rho|`` (~1e-8 m
    for 2e7 m). The solution moves by ``a_i^T dr`` with ``|a_i| = sqrt(C_ii)`` (the row of
    the pseudo-inverse), so ``|dx_i| <= sqrt(C_ii) sqrt(m) 5 u max|rho|``, once per path;
    plus one rounding of the state itself (2 u |x|). The iteration error left after a last
    step below ``tol_m`` is the Gauss-Newton contraction (residual / range, ~1e-6) times
    that step: below 1e-12 m, negligible.
    """
    m = epochs.valid.sum(axis=1)
    rho = np.where(epochs.valid, np.abs(epochs.pseudorange_m), 0.0).max(axis=1)
    sd = np.sqrt(np.diagonal(fix.covariance, axis1=1, axis2=2))
    state = np.concatenate([fix.position_e, fix.clock_bias_m[:, None]], axis=1)
    return 2.0 * (sd * np.sqrt(m)[:, None] * 5.0 * UNIT_ROUNDOFF * rho[:, None]) + 2.0 * EPS * np.abs(state)


def _velocity_bound(vfix, epochs) -> np.ndarray:
    """Bound (k, 4) on the velocity-fix difference, the same position given to both paths.

    ``y_j = rate_j - u . v_s``: the unit vector and the dot product carry about five
    roundings of ``|v_s| + |rate|``; through the pseudo-inverse as in :func:`_position_bound`."""
    m = epochs.valid.sum(axis=1)
    mag = np.where(epochs.valid, np.linalg.norm(epochs.sat_vel_e, axis=-1) + np.abs(epochs.pseudorange_rate_mps),
                   0.0).max(axis=1)
    sd = np.sqrt(np.diagonal(vfix.covariance, axis1=1, axis2=2))
    solution = np.concatenate([vfix.velocity_e, vfix.clock_drift_mps[:, None]], axis=1)
    return 2.0 * (sd * np.sqrt(m)[:, None] * 5.0 * UNIT_ROUNDOFF * mag[:, None]) + 2.0 * EPS * np.abs(solution)


def _covariance_bound(cov: np.ndarray, n_sat: np.ndarray) -> np.ndarray:
    """Bound (k,) on max |C_numpy - C_compiled|, C = (H^T H)^-1.

    The entries of ``N = H^T H`` are m-term sums of products of unit-vector components
    (``|h_i h_j| <= 1``), summed in different orders: ``|dN_ij| <= gamma_m m`` per path,
    ``|dN|_2 <= 4 gamma_m m``; then ``|dC| <= |C|_2^2 |dN|_2`` plus each inversion's own
    backward error, ``~8 u kappa |C|_2`` (``kappa = |N|_2 |C|_2``)."""
    lam = np.linalg.eigvalsh(cov)
    c2 = lam[:, -1]
    kappa = lam[:, -1] / lam[:, 0]
    g_m = np.array([gamma(int(n)) for n in n_sat])
    return 2.0 * (c2**2 * 4.0 * g_m * n_sat + 8.0 * UNIT_ROUNDOFF * kappa * c2)


@needs_numba
def test_compiled_epoch_alone_equals_epoch_in_batch(epochs):
    sat, rho, valid = epochs.sat_pos_e, epochs.pseudorange_m, epochs.valid
    batch = receiver.least_squares_fix(sat, rho, valid, method="compiled")
    vbatch = receiver.velocity_fix(sat, epochs.sat_vel_e, epochs.pseudorange_rate_mps, valid, batch.position_e,
                                   method="compiled")
    assert batch.ok.sum() > 40
    for e in range(len(sat)):
        one = receiver.least_squares_fix(sat[e], rho[e], valid[e], method="compiled")
        for name in receiver.Fix.__slots__:
            assert_same_arithmetic(getattr(one, name), getattr(batch, name)[e], f"{name} epoch {e}")
        vone = receiver.velocity_fix(sat[e], epochs.sat_vel_e[e], epochs.pseudorange_rate_mps[e], valid[e],
                                     batch.position_e[e], method="compiled")
        for name in receiver.VelocityFix.__slots__:
            assert_same_arithmetic(getattr(vone, name), getattr(vbatch, name)[e], f"{name} epoch {e}")


@needs_numba
def test_compiled_agrees_with_numpy_to_rounding(epochs):
    sat, rho, valid = epochs.sat_pos_e, epochs.pseudorange_m, epochs.valid
    fc = receiver.least_squares_fix(sat, rho, valid, method="compiled")
    fn = receiver.least_squares_fix(sat, rho, valid, method="numpy")
    np.testing.assert_array_equal(fc.ok, fn.ok)
    np.testing.assert_array_equal(fc.n_used, fn.n_used)
    ok = fn.ok
    assert ok.sum() > 40
    diff = np.abs(np.concatenate([fc.position_e - fn.position_e, (fc.clock_bias_m - fn.clock_bias_m)[:, None]], 1))
    bound = _position_bound(fn, epochs)
    assert np.all(diff[ok] <= bound[ok]), (diff[ok].max(), bound[ok].min())
    assert np.all(np.isnan(fc.position_e[~ok])) and np.all(np.isnan(fc.covariance[~ok]))
    dcov = np.abs(fc.covariance - fn.covariance).max(axis=(1, 2))
    cbound = _covariance_bound(fn.covariance[ok], fn.n_used[ok])
    assert np.all(dcov[ok] <= cbound), (dcov[ok].max(), cbound.min())
    # velocity: the same position for both, so only the velocity arithmetic differs
    position = np.where(ok[:, None], fn.position_e, 0.0)
    args = (sat, epochs.sat_vel_e, epochs.pseudorange_rate_mps, valid, position)
    vc = receiver.velocity_fix(*args, method="compiled")
    vn = receiver.velocity_fix(*args, method="numpy")
    np.testing.assert_array_equal(vc.ok, vn.ok)
    np.testing.assert_array_equal(vc.n_used, vn.n_used)
    vok = vn.ok & ok
    vdiff = np.abs(np.concatenate([vc.velocity_e - vn.velocity_e, (vc.clock_drift_mps - vn.clock_drift_mps)[:, None]],
                                  1))
    vbound = _velocity_bound(vn, epochs)
    assert np.all(vdiff[vok] <= vbound[vok]), (vdiff[vok].max(), vbound[vok].min())
    dvcov = np.abs(vc.covariance - vn.covariance).max(axis=(1, 2))
    assert np.all(dvcov[vok] <= _covariance_bound(vn.covariance[vok], vn.n_used[vok]))


@pytest.mark.parametrize("method", ["numpy", pytest.param("compiled", marks=needs_numba)])
def test_each_epoch_stops_on_its_own_step(method):
    """A batch of epochs started far apart (the Earth's centre, the truth): each epoch's
    result is its single-epoch result (NumPy: to rounding, the einsum runs over the batch)."""
    ep = _epochs(5.0)
    sat, rho, valid = ep.sat_pos_e[:6], ep.pseudorange_m[:6], ep.valid[:6]
    near = receiver.least_squares_fix(sat, rho, valid, method=method).position_e
    initial = np.where(np.arange(6)[:, None] % 2 == 0, 0.0, near)
    batch = receiver.least_squares_fix(sat, rho, valid, initial=initial, method=method)
    assert batch.ok.all()
    for e in range(6):
        one = receiver.least_squares_fix(sat[e], rho[e], valid[e], initial=initial[e], method=method)
        if method == "compiled":
            assert_same_arithmetic(one.position_e, batch.position_e[e])
        else:
            bound = _position_bound(batch, dataclasses.replace(ep, valid=ep.valid[:6],
                                                               pseudorange_m=ep.pseudorange_m[:6]))[e, :3]
            assert np.all(np.abs(one.position_e - batch.position_e[e]) <= bound)
    # too few iterations from the Earth's centre: not converged is a value, per epoch
    short = receiver.least_squares_fix(sat, rho, valid, initial=initial, max_iter=2, method=method)
    np.testing.assert_array_equal(short.ok, np.arange(6) % 2 == 1)
    assert np.all(np.isnan(short.position_e[::2]))


@pytest.mark.parametrize("method", ["numpy", pytest.param("compiled", marks=needs_numba)])
def test_rank_test_and_missing_data_are_values(method):
    ep = _epochs(5.0)
    sat, rho, valid = ep.sat_pos_e[:4].copy(), ep.pseudorange_m[:4].copy(), ep.valid[:4].copy()
    used = np.flatnonzero(valid[0])
    valid[0, used[3:]] = False  # 3 satellites
    sat[1] = sat[1, np.flatnonzero(valid[1])[0]]  # every satellite at one place: rank 1
    rho[2, np.flatnonzero(valid[2])[:2]] = np.nan  # two valid channels with a NaN: not used
    fix = receiver.least_squares_fix(sat, rho, valid, method=method)
    assert fix.n_used[0] == 3 and fix.n_used[2] == valid[2].sum() - 2
    np.testing.assert_array_equal(fix.ok, [False, False, True, True])
    assert np.all(np.isnan(fix.position_e[:2])) and np.all(np.isnan(fix.covariance[:2]))
    vfix = receiver.velocity_fix(sat, ep.sat_vel_e[:4], ep.pseudorange_rate_mps[:4], valid, fix.position_e,
                                 method=method)
    np.testing.assert_array_equal(vfix.ok, [False, False, True, True])  # NaN position: no channel used
    assert vfix.n_used[0] == 0 and np.all(np.isnan(vfix.velocity_e[:2]))


@needs_numba
def test_symmetric_inverse_and_rank_test():
    rng = np.random.default_rng(0)
    receiver.epoch_kernels()
    inverse = np.empty((4, 4))
    for _ in range(20):
        h = np.concatenate([rng.normal(size=(8, 3)), np.ones((8, 1))], axis=1)
        n = h.T @ h
        assert receiver._sym4_inverse(n, inverse)
        lam = np.linalg.eigvalsh(n)
        # backward-stable inversion: relative error of order kappa * u (a few tens of roundings)
        scale = 64.0 * UNIT_ROUNDOFF * lam[-1] / lam[0] / lam[0]
        assert np.abs(inverse - np.linalg.inv(n)).max() <= scale
    u = rng.normal(size=(6, 3))
    h = np.concatenate([u, np.ones((6, 1))], axis=1)
    h[:, 2] = h[:, 0]  # two equal columns: rank 3
    assert not receiver._sym4_inverse(h.T @ h, inverse)
    assert not receiver._sym4_inverse(np.zeros((4, 4)), inverse)
    bad = np.eye(4)
    bad[1, 2] = bad[2, 1] = np.nan
    assert not receiver._sym4_inverse(bad, inverse)


def test_method_option(monkeypatch):
    ep = _epochs(5.0)
    with pytest.raises(ConfigError):
        receiver.least_squares_fix(ep.sat_pos_e[0], ep.pseudorange_m[0], ep.valid[0], method="fast")  # type: ignore[arg-type]
    monkeypatch.setattr(receiver, "available", lambda: False)
    with pytest.raises(ConfigError):
        receiver.velocity_fix(ep.sat_pos_e[0], ep.sat_vel_e[0], ep.pseudorange_rate_mps[0], ep.valid[0],
                              np.zeros(3), method="compiled")
    auto = receiver.least_squares_fix(ep.sat_pos_e, ep.pseudorange_m, ep.valid)  # falls back to NumPy
    numpy = receiver.least_squares_fix(ep.sat_pos_e, ep.pseudorange_m, ep.valid, method="numpy")
    assert_same_arithmetic(auto.position_e, numpy.position_e)
