"""One-step float forms of the body terms (navsim.strapdown.onestep) and the engine's
one-step path (ErrorStateIns.advance_body with StepTerms) against the array forms."""

from __future__ import annotations

import numpy as np
import pytest

from navsim import rotations
from navsim.strapdown import ins, onestep

DEFAULT = ("invariant", "invariant-4.4", "exact-invariant")


def _increments(rng, n: int, m: int, R: int = 4, dt: float = 0.01, rate: float = 0.05, force: float = 9.8):
    """Multiple integrals of a smooth random motion (magnitudes of one real step) and m
    sub-sample increments: omega ~ rate rad/s, f ~ force m/s^2; r-fold integral ~ x dt^r / r!."""
    scale = np.array([dt**r / np.prod(range(1, r + 1)) for r in range(1, R + 1)])
    th = rate * rng.standard_normal((n, R, 3)) * scale[None, :, None]
    dv = force * rng.standard_normal((n, R, 3)) * scale[None, :, None]
    th_sub = rate * dt / m * rng.standard_normal((n, m, 3))
    dv_sub = force * dt / m * rng.standard_normal((n, m, 3))
    return th_sub, dv_sub, th, dv


@pytest.mark.parametrize("m", [1, 3])
@pytest.mark.parametrize("with_sub", [True, False])
def test_one_step_terms_equal_array_forms_bit_for_bit(m, with_sub):
    """Only +, -, *, / on the same operands in the same order as the array forms (whose
    elementwise ufuncs round every operation the same way): equal bit for bit."""
    rng = np.random.default_rng(11 + m)
    dt = 0.01
    th_sub, dv_sub, th, dv = _increments(rng, 200, m, dt=dt)
    if not with_sub:
        th_sub = dv_sub = None
    ref = ins.body_terms(th_sub, dv_sub, th, dv, dt)
    assert ins.resolve_methods(None, None, None, th_sub, dv_sub, th, dv) == DEFAULT
    assert ref.rule is None
    rows = [onestep.one_step_terms(DEFAULT, th[i].tolist(), dv[i].tolist(),
                                   None if th_sub is None else th_sub[i].tolist(),
                                   None if dv_sub is None else dv_sub[i].tolist(), dt) for i in range(len(th))]
    phi, dv_b, ds_b, th1, dv1 = (np.array([r[k] for r in rows]) for k in range(5))
    np.testing.assert_array_equal(phi, ref.rotvec_body)
    np.testing.assert_array_equal(dv_b, ref.dv_body)
    np.testing.assert_array_equal(ds_b, ref.ds_body)
    np.testing.assert_array_equal(th1, ref.dtheta_first)
    np.testing.assert_array_equal(dv1, ref.dv_first)
    # the terms are not trivial: the coning, sculling and position corrections are present
    assert np.max(np.abs(phi - th[:, 0])) > 1e-12 and np.max(np.abs(ds_b - dv[:, 1])) > 1e-12


def test_one_step_terms_none_for_other_methods():
    rng = np.random.default_rng(3)
    _, _, th, dv = _increments(rng, 1, 1)
    assert onestep.one_step_terms(("invariant-linear", "invariant-4.4", "exact-invariant"), th[0].tolist(),
                                  dv[0].tolist(), None, None, 0.01) is None
    assert onestep.one_step_terms(DEFAULT, th[0, :3].tolist(), dv[0, :3].tolist(), None, None, 0.01) is None


def test_quat_from_rotvec_matches_array_form():
    """Same formula; sin/cos/sqrt come from libm here and from numpy's loops there: numpy
    may use its own SIMD sin/cos (within 1 ulp of libm) on some CPUs, hence 2 ulp of 1."""
    rng = np.random.default_rng(5)
    v = np.concatenate([rng.standard_normal((500, 3)) * 1e-3, rng.standard_normal((200, 3)) * 1e-6])
    ref = rotations.quat_from_rotvec(v)
    got = np.array([onestep.quat_from_rotvec(x) for x in v.tolist()])
    np.testing.assert_allclose(got, ref, rtol=0, atol=4.5e-16)
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, rtol=0, atol=4.5e-16)


def _engine_pair():
    from navsim.episode import make_context
    from navsim.estimators import _inserror as ie
    from navsim.scenario import load_scenario
    from navsim.simulator import Simulator

    sc = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 12.0}})
    sim = Simulator(sc)
    start = sim.reset(2)
    ctx = make_context(sim)
    noise = ie.ImuNoise.from_nominal(ctx.imu)
    engines = [ie.ErrorStateIns(ctx, start.prior, noise), ie.ErrorStateIns(ctx, start.prior, noise)]
    chunk = next(iter(sim.chunks(10_000)))
    return ie, engines, chunk.imu


def test_engine_one_step_path_equals_batch_of_one():
    """ErrorStateIns stepped with StepTerms (floats) against BodyTerms batches of one (arrays),
    with non-zero biases and closed-loop updates every 2.5 s. The arithmetic is the same
    operations in the same order; the transcendental functions (quaternion of the rotation
    vector, heading/pitch/roll) are libm's on one side and numpy's on the other, which may
    differ by 1 ulp on some CPUs. 1 ulp of attitude per step over 1200 steps is < 3e-13
    rad, < 1e-10 m/s of velocity and < 1e-9 m of position after 12 s at g = 9.8 m/s^2.
    The covariance is the interval's polynomial evaluated for all its steps in one
    (100, 9) @ (9, 81) product on the one-step path and in a (1, 9) @ (9, 81) product per
    step here: BLAS rounding of 9-term sums (1e-15 relative), plus the interval start
    following the state (relative 1e-12)."""
    ie, (a, b), imu = _engine_pair()
    for e in (a, b):
        e.gyro_bias = np.array([1e-4, -2e-4, 3e-5])
        e.accel_bias = np.array([0.01, -0.02, 0.005])
    H = np.zeros((3, ie.N_STATES))
    H[:, :3] = np.eye(3)
    ra, rb, ca, cb = [], [], [], []
    n = len(imu.dtheta_r)
    for i in range(n):
        sl = slice(i, i + 1)
        step_terms = a.prepare(imu.dtheta_sample[sl, :, 0], imu.dv_sample[sl, :, 0], imu.dtheta_r[sl], imu.dv_r[sl])
        assert isinstance(step_terms, ie.StepTerms)
        arrays = ie.body_terms(imu.dtheta_sample[sl, :, 0], imu.dv_sample[sl, :, 0], imu.dtheta_r[sl],
                               imu.dv_r[sl], b.dt)
        for e, terms, rows, covs in ((a, step_terms, ra, ca), (b, arrays, rb, cb)):
            r, c = e.advance_body(terms)
            rows.append(r[0])
            covs.append(c[0])
        if i % 250 == 249:
            for e in (a, b):
                e.update(H, np.eye(3), np.array([0.3, -0.2, 0.1]))
    ra, rb, ca, cb = map(np.array, (ra, rb, ca, cb))
    np.testing.assert_allclose(ra[:, :2], rb[:, :2], rtol=0, atol=2e-16)  # rad: 1e-9 m
    np.testing.assert_allclose(ra[:, 2], rb[:, 2], rtol=0, atol=1e-9)
    np.testing.assert_allclose(ra[:, 3:6], rb[:, 3:6], rtol=0, atol=1e-10)
    np.testing.assert_allclose(ra[:, 6:], rb[:, 6:], rtol=0, atol=3e-13)
    np.testing.assert_allclose(ca, cb, rtol=1e-12, atol=0)
    sa, sb = a.state, b.state
    assert (sa.lat, sa.lon) == pytest.approx((sb.lat, sb.lon), abs=2e-16)
    np.testing.assert_allclose(sa.quat_nb, sb.quat_nb, rtol=0, atol=3e-13)
    assert a.steps == b.steps == n and np.max(np.abs(ra[:, 3:6])) > 1.0  # the vehicle moves


def test_engine_compiled_step_equals_float_step_bit_for_bit():
    """ErrorStateIns.advance_step (one compiled call with numba) against the float one-step
    path (advance_body of StepTerms), with non-zero biases and closed-loop updates every
    2.5 s: the kernel is the float path's +, -, *, / in the same order and the same libm
    sin/cos/atan2/asin/sqrt (numba calls the C library as Python's math does), its
    coefficients computed by Python as in one_step_terms, so every row, covariance and
    the final state are equal bit for bit."""
    pytest.importorskip("numba")
    ie, (a, b), imu = _engine_pair()
    for e in (a, b):
        e.gyro_bias = np.array([1e-4, -2e-4, 3e-5])
        e.accel_bias = np.array([0.01, -0.02, 0.005])
    H = np.zeros((3, ie.N_STATES))
    H[:, :3] = np.eye(3)
    ra, rb, ca, cb = [], [], [], []
    n = len(imu.dtheta_r)
    for i in range(n):
        args = (imu.dtheta_sample[i, :, 0], imu.dv_sample[i, :, 0], imu.dtheta_r[i], imu.dv_r[i])
        r, c = a.advance_step(*args)
        ra.append(r[0])
        ca.append(c[0])
        r, c = b.advance_body(b.prepare_step(*args))
        rb.append(r[0])
        cb.append(c[0])
        if i % 250 == 249:
            for e in (a, b):
                e.update(H, np.eye(3), np.array([0.3, -0.2, 0.1]))
    assert a._in_w  # the compiled path ran (after the first step resolved the methods)
    np.testing.assert_array_equal(np.array(ra), np.array(rb))
    np.testing.assert_array_equal(np.array(ca), np.array(cb))
    sa, sb = a.state, b.state
    assert (sa.lat, sa.lon, sa.h, sa.compensation) == (sb.lat, sb.lon, sb.h, sb.compensation)
    np.testing.assert_array_equal(sa.velocity_n, sb.velocity_n)
    np.testing.assert_array_equal(sa.quat_nb, sb.quat_nb)
    assert a._f_sum == b._f_sum and a.steps == b.steps == n


def test_engine_falls_back_to_arrays_without_a_float_form():
    """Methods without a float form keep the array path (a BodyTerms batch of one)."""
    ie, (eng, ref), imu = _engine_pair()
    eng.methods["coning"] = ref.methods["coning"] = "invariant-linear"
    terms = eng.prepare_step(imu.dtheta_sample[0, :, 0], imu.dv_sample[0, :, 0], imu.dtheta_r[0], imu.dv_r[0])
    assert isinstance(terms, ie.BodyTerms) and len(terms) == 1
    expected = ref.prepare(imu.dtheta_sample[:1, :, 0], imu.dv_sample[:1, :, 0], imu.dtheta_r[:1], imu.dv_r[:1])
    np.testing.assert_array_equal(eng.advance_body(terms)[0], ref.advance_body(expected)[0])


def test_engine_compiled_step_across_layouts_and_copies_bit_for_bit():
    """The compiled step keeps its constants, biases, state and specific-force sum in one
    work array and checks the input layout on every call: steps alternating between
    sub-sample increments given and not given (a new layout takes the float path once,
    then the compiled one), bias changes by assignment, and a deep copy taken mid-run
    (which must not share the work array), all against the float one-step path: equal
    bit for bit (the same operations in the same order, see the test above)."""
    import copy

    pytest.importorskip("numba")
    ie, (a, b), imu = _engine_pair()
    n = 600
    ra, rb, ca, cb = [], [], [], []
    for i in range(n):
        sub = (i // 150) % 2 == 0
        args = (imu.dtheta_sample[i, :, 0] if sub else None, imu.dv_sample[i, :, 0] if sub else None,
                imu.dtheta_r[i], imu.dv_r[i])
        if i == 333:
            for e in (a, b):
                e.gyro_bias = np.array([2e-5, 1e-5, -4e-5])
                e.accel_bias = np.array([-0.003, 0.004, 0.002])
        if i == 400:
            a = copy.deepcopy(a)
            assert a._w is not b._w
        r, c = a.advance_row(*args)
        ra.append(r)
        ca.append(c)
        r, c = b.advance_body(b.prepare_step(*args))
        rb.append(r[0])
        cb.append(c[0])
        if i % 250 == 249:
            for e in (a, b):
                e.update(np.eye(3, ie.N_STATES), np.eye(3), np.array([0.3, -0.2, 0.1]))
    assert a._row_kernel is not None and a._in_w
    np.testing.assert_array_equal(np.array(ra), np.array(rb))
    np.testing.assert_array_equal(np.array(ca), np.array(cb))
    sa, sb = a.state, b.state
    assert (sa.lat, sa.lon, sa.h, sa.compensation) == (sb.lat, sb.lon, sb.h, sb.compensation)
    np.testing.assert_array_equal(sa.quat_nb, sb.quat_nb)
    assert a._f_sum == b._f_sum and a.steps == b.steps == n
