"""filterpy doing the Kalman arithmetic: lc-ekf-, tc-ekf-, tc-ukf-filterpy against navsim's engines.

The two differ only in the update's linear algebra (filterpy: S^-1 by ``linalg.inv``;
navsim: Cholesky solves), i.e. by rounding, amplified by nothing: the closed-loop filters
contract. Over a 300-s episode (300 GNSS updates) the tolerances are therefore set at the
precision of the quantities, not at a fit: latitude/longitude to 10 ulp of a radian value
near 0.8 (1.1e-16 * 6.4e6 m = 7e-10 m each), velocity 1e-9 m/s, covariance elements to
1e-9 of sqrt(P_ii P_jj) (the elements' own scale; cross terms near zero make element-wise
relative errors meaningless), NIS 1e-9 relative.

tc-ukf-filterpy draws filterpy's Merwe sigma points (the same scheme and weights as
navsim's, scipy's Cholesky instead of numpy's), evaluates h one point at a time (navsim:
all points in one array call) and uses inv(S); on paper-2012 (compensated clock) the
update is well conditioned and the same tolerances hold. With a standalone receiver the
clock prior is 3 km against metre-level pseudoranges: cond(S) ~ 2e10 at the first update
and P - K S K^T cancels the clock variance by ~5e5, so two correct implementations differ
there by up to eps cond(S) shrink (the forward error of a solve with S, Higham ch. 7,
amplified by the cancellation); that is the bound of the per-update test on identical
inputs, and why the standalone episodes are not compared end to end.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("filterpy")

from navsim import estimators  # noqa: E402
from navsim.episode import run_episode  # noqa: E402
from navsim.scenario import load_scenario  # noqa: E402

R_EARTH = 6.4e6
ULP_M = np.spacing(0.8) * R_EARTH


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 300.0}})


@pytest.mark.parametrize("ours, theirs", [("lc-ekf", "lc-ekf-filterpy"), ("tc-ekf", "tc-ekf-filterpy"),
                                         ("tc-ukf", "tc-ukf-filterpy")])
def test_filterpy_update_gives_navsims_numbers(scenario, ours, theirs):
    a = run_episode(scenario, estimators.make(ours), seed=1)
    b = run_episode(scenario, estimators.make(theirs), seed=1)
    assert np.count_nonzero(np.isfinite(a.nis)) >= 250  # the updates happened
    assert np.max(np.abs(a.est_lat - b.est_lat)) * R_EARTH <= 10 * ULP_M
    assert np.max(np.abs(a.est_lon - b.est_lon)) * R_EARTH <= 10 * ULP_M
    assert np.max(np.abs(a.est_h - b.est_h)) <= 1e-8
    assert np.max(np.abs(a.est_velocity_n - b.est_velocity_n)) <= 1e-9
    d = np.sqrt(np.abs(np.diagonal(a.est_cov, axis1=1, axis2=2)))
    scale = d[:, :, None] * d[:, None, :]
    assert np.nanmax(np.abs(a.est_cov - b.est_cov) / scale) <= 1e-9
    np.testing.assert_allclose(b.nis, a.nis, rtol=1e-9)
    np.testing.assert_array_equal(np.isnan(a.nis), np.isnan(b.nis))


def test_the_update_is_filterpys(monkeypatch, scenario):
    """Not a copy of navsim's: the filterpy filter's update is what runs."""
    from filterpy.kalman import ExtendedKalmanFilter

    calls = []
    real = ExtendedKalmanFilter.update
    monkeypatch.setattr(ExtendedKalmanFilter, "update", lambda self, *a, **k: (calls.append(1), real(self, *a, **k)))
    short = scenario.with_overrides({"timing": {"duration_s": 20.0}})
    rec = run_episode(short, estimators.make("lc-ekf-filterpy"), seed=0)
    assert len(calls) == np.count_nonzero(np.isfinite(rec.nis)) > 0


def test_the_unscented_update_and_sigma_points_are_filterpys(monkeypatch, scenario):
    from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

    calls = {"update": 0, "points": 0}
    update, points = UnscentedKalmanFilter.update, MerweScaledSigmaPoints.sigma_points

    def counted_update(self, *a, **k):
        calls["update"] += 1
        return update(self, *a, **k)

    def counted_points(self, *a, **k):
        calls["points"] += 1
        return points(self, *a, **k)

    monkeypatch.setattr(UnscentedKalmanFilter, "update", counted_update)
    monkeypatch.setattr(MerweScaledSigmaPoints, "sigma_points", counted_points)
    short = scenario.with_overrides({"timing": {"duration_s": 20.0}})
    est = estimators.make("tc-ukf-filterpy", alpha=0.8, kappa=1.0)
    rec = run_episode(short, est, seed=0)
    n = np.count_nonzero(np.isfinite(rec.nis))
    assert calls["update"] == calls["points"] == n > 0
    (kf,) = est.unscented_update._filters.values()
    assert (kf.points_fn.alpha, kf.points_fn.beta, kf.points_fn.kappa) == (0.8, 2.0, 1.0)


def test_unscented_update_matches_navsims_to_the_conditioning():
    """Standalone receiver (clock and atmosphere states, lever arm), both updates on the
    same inputs at every epoch: differences within eps cond(S) shrink (module notes),
    P relative to sqrt(P_ii P_jj), dx relative to the posterior sigmas."""
    from navsim.estimators import filterpy_based, tightly

    sc = load_scenario("paper-2012").with_overrides({
        "timing": {"duration_s": 20.0},
        "gnss": {"preset": "standalone", "overrides": {"multipath_sigma_m": 0.0}, "lever_arm_m": [0.4, 1.5, 3.0]}})
    inputs = []
    ours = tightly.unscented_update

    def spy(mean, P, hx, z, R, alpha, beta, kappa):
        inputs.append((mean.copy(), P.copy(), hx, z.copy(), np.array(R)))
        return ours(mean, P, hx, z, R, alpha, beta, kappa)

    est = estimators.make("tc-ukf")
    est.unscented_update = spy
    run_episode(sc, est, seed=1)
    theirs = filterpy_based.FilterpyUnscentedUpdate()
    eps = np.finfo(float).eps
    assert len(inputs) == 20 and inputs[0][1].shape == (19, 19)  # clock and atmosphere states
    for mean, P, hx, z, R in inputs:
        a, b = ours(mean, P, hx, z, R), theirs(mean, P, hx, z, R)
        X, Wm, Wc, _ = tightly.sigma_points(mean, P)
        dZ = hx(X) - Wm @ hx(X)
        S = (dZ.T * Wc) @ dZ + np.diag(R)
        active = np.diag(P) > 0.0
        prior, post = np.diag(P)[active], np.diag(a[1])[active]
        bound = eps * np.linalg.cond(S) * np.max(prior / post)
        sd = np.sqrt(np.where(np.diag(P) > 0.0, np.diag(a[1]), 1.0))
        assert np.max(np.abs(a[1] - b[1]) / np.outer(sd, sd)) <= bound
        assert np.max(np.abs(a[0] - b[0]) / sd) <= bound
        assert abs(a[2] - b[2]) <= bound * a[2]
