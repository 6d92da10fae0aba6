"""filterpy doing the Kalman arithmetic: lc-ekf-filterpy / tc-ekf-filterpy against navsim's engines.

The two differ only in the update's linear algebra (filterpy: S^-1 by ``linalg.inv``;
navsim: Cholesky solves), i.e. by rounding, amplified by nothing: the closed-loop filters
contract. Over a 300-s episode (300 GNSS updates) the tolerances are therefore set at the
precision of the quantities, not at a fit: latitude/longitude to 10 ulp of a radian value
near 0.8 (1.1e-16 * 6.4e6 m = 7e-10 m each), velocity 1e-9 m/s, covariance elements to
1e-9 of sqrt(P_ii P_jj) (the elements' own scale; cross terms near zero make element-wise
relative errors meaningless), NIS 1e-9 relative.
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


@pytest.mark.parametrize("ours, theirs", [("lc-ekf", "lc-ekf-filterpy"), ("tc-ekf", "tc-ekf-filterpy")])
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
