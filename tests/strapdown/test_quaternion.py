"""Seed 001 quaternion algorithms: kinematics, error orders, printed typos, Table 1."""

from __future__ import annotations

import numpy as np
import pytest

from navsim.errors import ConfigError
from navsim.rotations import quat_from_rotvec, quat_multiply, quat_to_rotvec
from navsim.strapdown.quaternion import (
    error_angles,
    error_quaternion,
    matrizant_integrate,
    matrizant_quaternion,
    omega_matrix,
    quat_cumulative_product,
    reversible_integrate,
    rk4_integrate,
)

# three-axis test motion (C_z != 0, so the printed f2 sign matters)
_C = np.array([0.174, 0.174, 0.3])
_F = np.array([0.8, 1.0, 0.6])


def _rates(t):
    return _C * np.sin(2 * np.pi * _F * np.asarray(t)[..., None])


def _increments(t0, t1):
    w = 2 * np.pi * _F
    return _C / w * (np.cos(w * np.asarray(t0)[..., None]) - np.cos(w * np.asarray(t1)[..., None]))


@pytest.fixture(scope="module")
def reference():
    """RK4 at 0.5 ms over 5 s (global error ~1e-13, far below the algorithms tested)."""
    step, duration = 0.0005, 5.0
    return step, rk4_integrate(_rates, [1, 0, 0, 0], 0.0, step, int(round(duration / step)))


def _max_error(q_ref, q):
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    return np.abs(quat_to_rotvec(error_quaternion(q_ref, q))).max()


def _errors(reference, h, kind):
    step, q_ref = reference
    n = int(round(5.0 / h))
    t = h * np.arange(n)
    theta = _increments(t, t + h)
    r = int(round(h / step))
    if kind == "reversible":
        return _max_error(q_ref[::r], reversible_integrate([1, 0, 0, 0], theta))
    return _max_error(q_ref[:: 2 * r], matrizant_integrate([1, 0, 0, 0], theta, variant=kind))


def test_omega_matrix_is_right_multiplication_by_rate():
    rng = np.random.default_rng(1)
    q = rng.standard_normal(4)
    w = rng.standard_normal(3)
    np.testing.assert_allclose(omega_matrix(w) @ q, quat_multiply(q, np.r_[0.0, w]), atol=1e-15)


def test_rk4_reference_against_single_axis_closed_form():
    # single axis: the quaternion of the integrated angle is exact
    rate = lambda t: np.stack([0.5 * np.sin(3 * t), 0 * t, 0 * t], -1)  # noqa: E731
    q = rk4_integrate(rate, [1, 0, 0, 0], 0.0, 0.001, 5000)
    t = 0.001 * np.arange(5001)
    angle = 0.5 / 3 * (1 - np.cos(3 * t))
    exact = quat_from_rotvec(np.stack([angle, 0 * t, 0 * t], -1))
    np.testing.assert_allclose(q, exact, atol=1e-13)


def test_matrizant_constant_rate_matches_exponential():
    # constant rate: Theta_0 = Theta_1, cross term 0; vector part error phi^5 / 3840
    theta = np.array([0.004, -0.003, 0.002])
    f = matrizant_quaternion(theta, theta)
    exact = quat_from_rotvec(2 * theta)
    phi = np.linalg.norm(2 * theta)
    assert np.abs(f - exact).max() < phi**5 / 1000
    assert np.abs(f - exact).max() > 0  # truncated series, not the closed form


@pytest.mark.parametrize(
    "variant, ratio",
    [("corrected", 16.0), ("printed-sign", 4.0), ("printed-f0", 4.0), ("printed-index", 2.0), ("printed", 2.0)],
)
def test_matrizant_error_order_per_variant(reference, variant, ratio):
    # global error ~ h^p: halving h divides it by 2^p
    errors = [_errors(reference, h, variant) for h in (0.01, 0.005)]
    assert errors[0] / errors[1] == pytest.approx(ratio, rel=0.1)


def test_printed_typos_cost_orders_of_magnitude(reference):
    corrected = _errors(reference, 0.005, "corrected")
    for variant in ("printed-sign", "printed-f0", "printed-index"):
        assert _errors(reference, 0.005, variant) > 1e3 * corrected


def test_printed_f2_sign_alone_breaks_the_coning_term():
    # with theta_z = 0 the y component of Theta_0 x Theta_1 vanishes: variants agree in f
    t0, t1 = np.array([1e-3, 2e-3, 0.0]), np.array([3e-3, -1e-3, 0.0])
    f_c, f_p = matrizant_quaternion(t0, t1), matrizant_quaternion(t0, t1, "printed")
    np.testing.assert_allclose(f_c[1:], f_p[1:], atol=1e-18)
    # with theta_z != 0 the corrected vector part equals the two-sample rotation vector
    t0, t1 = np.array([1e-3, 2e-3, 1.5e-3]), np.array([3e-3, -1e-3, 0.5e-3])
    phi = t0 + t1 + 2.0 / 3.0 * np.cross(t0, t1)
    np.testing.assert_allclose(matrizant_quaternion(t0, t1), quat_from_rotvec(phi), atol=1e-13)
    assert np.abs(matrizant_quaternion(t0, t1, "printed")[2] - quat_from_rotvec(phi)[2]) > 1e-7


def test_printed_f0_loses_norm_three_eighths_phi_squared_per_step():
    theta = np.tile([0.002, 0.001, 0.0], (200, 1))
    p = matrizant_integrate([1, 0, 0, 0], theta, variant="printed")
    phi2 = np.sum((2 * theta[0]) ** 2)
    expected = (1 - 0.375 * phi2) ** 100
    assert abs(np.linalg.norm(p[-1]) - expected) < 1e-3 * (1 - expected)
    p_c = matrizant_integrate([1, 0, 0, 0], theta)
    assert abs(np.linalg.norm(p_c[-1]) - 1) < 1e-12


def test_reversible_is_first_order(reference):
    errors = [_errors(reference, h, "reversible") for h in (0.01, 0.005, 0.0025)]
    assert 1.7 < errors[0] / errors[1] < 2.3
    assert 1.7 < errors[1] / errors[2] < 2.3


def test_reversible_keeps_unit_norm_and_alternates_order():
    theta = np.tile([0.01, -0.02, 0.015], (6, 1))
    m = reversible_integrate([1, 0, 0, 0], theta)
    np.testing.assert_allclose(np.linalg.norm(m, axis=1), 1, atol=1e-15)
    # first step "odd": mu1 from old values, mu2 uses the new mu1
    x, y, z = 0.5 * theta[0]
    mu1 = x
    mu2 = y - z * mu1
    assert m[1, 1] == pytest.approx(mu1) and m[1, 2] == pytest.approx(mu2)
    m_even = reversible_integrate([1, 0, 0, 0], theta, first_step_odd=False)
    assert m_even[1, 3] == pytest.approx(z) and m_even[1, 2] == pytest.approx(y + x * z)


def test_error_angles_recover_a_small_rotation():
    q_ref = quat_from_rotvec([0.3, -0.2, 0.5])
    delta = np.array([1e-5, -2e-5, 3e-5])  # x (roll), y (pitch), z (heading)
    q = quat_multiply(q_ref, quat_from_rotvec(delta))
    heading, pitch, roll = error_angles(q_ref, q)
    np.testing.assert_allclose([roll, pitch, heading], delta, rtol=1e-8)


def test_cumulative_product_matches_pairwise_products():
    rng = np.random.default_rng(2)
    dq = quat_from_rotvec(0.1 * rng.standard_normal((5, 3)))
    out = quat_cumulative_product([1, 0, 0, 0], dq)
    q = np.array([1.0, 0, 0, 0])
    for k in range(5):
        q = quat_multiply(q, dq[k])
        np.testing.assert_allclose(out[k + 1], q, atol=1e-15)


def test_bad_inputs_name_the_field():
    with pytest.raises(ConfigError, match="variant"):
        matrizant_quaternion(np.zeros(3), np.zeros(3), variant="typo")
    with pytest.raises(ConfigError, match="dtheta"):
        matrizant_integrate([1, 0, 0, 0], np.zeros((3, 3)))  # odd count
    with pytest.raises(ConfigError, match="dtheta"):
        reversible_integrate([1, 0, 0, 0], np.zeros((3, 2)))


def test_seed001_quick_run_reproduces_table1_magnitudes(tmp_path):
    from navsim.paper import seed001

    rows = seed001.run(plot_dir=str(tmp_path), quick=True)
    assert (tmp_path / "seed001_fig2.png").exists()
    table = {r["quantity"]: r for r in rows}
    for angle in ("pitch", "roll"):
        m_mean = table[f"mean {angle} error, reversible (11)"]
        m_std = table[f"std {angle} error, reversible (11)"]
        # linear drift: std / mean = 1/sqrt(3); the printed table has 0.59-0.62
        assert m_std["navsim"] / abs(m_mean["navsim"]) == pytest.approx(3**-0.5, rel=0.05)
        # 20 s is a tenth of the 200 s run: means a tenth of the printed values (factor 2)
        assert 0.05 < abs(m_mean["navsim"]) / abs(m_mean["paper"]) < 0.2
        # the correct matrizant algorithm is far more accurate than the reversible one
        p_mean = table[f"mean {angle} error, matrizant (8)-(9)"]
        assert abs(p_mean["navsim"]) < 1e-4 * abs(m_mean["navsim"])
    assert all(set(r) == {"ref", "quantity", "paper", "navsim", "unit"} for r in rows)
