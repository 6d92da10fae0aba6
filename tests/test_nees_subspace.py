"""NEES on the error subspace a filter's covariance claims (closed-form cases and the along-track filter)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from navsim.metrics import claimed_rank, nees, nees_series, nees_subspace, nees_summary


def _mapped(n: int, r: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """Errors e = J x, x ~ N(0, P_r), and the covariance J P_r J^T (rank r), with mixed units
    (rows scaled 1 m ... 1e-4 rad) and a time-varying J."""
    scale = np.array([1.0, 1.0, 1.0, 0.1, 0.1, 0.1, 1e-4, 1e-4, 1e-4])
    j = rng.standard_normal((n, 9, r)) * scale[None, :, None]
    a = rng.standard_normal((r, r))
    p_r = a @ a.T + r * np.eye(r)
    x = rng.multivariate_normal(np.zeros(r), p_r, size=n)
    return np.einsum("nij,nj->ni", j, x), j @ p_r @ np.swapaxes(j, 1, 2)


@pytest.mark.parametrize("r", [1, 2, 5])
def test_a_mapped_covariance_claims_its_rank_and_nees_is_chi2_r(r):
    rng = np.random.default_rng(7)
    e, cov = _mapped(4000, r, rng)
    comps = np.arange(9)
    assert claimed_rank(cov, comps) == r
    series, d = nees_series(e, cov, comps)
    assert d == r
    # mean of 4000 chi2(r) draws: within 4 standard errors of r
    assert abs(series.mean() - r) < 4 * np.sqrt(2 * r / len(series))
    # and the distribution: Kolmogorov-Smirnov against chi2(r)
    assert stats.kstest(series, stats.chi2(r).cdf).pvalue > 1e-3
    summary = nees_summary(e, cov)
    assert summary.dof == r and summary.lower < summary.anees < summary.upper


def test_inside_the_subspace_it_is_the_pseudo_inverse_form():
    rng = np.random.default_rng(3)
    e, cov = _mapped(50, 2, rng)
    comps = np.arange(9)
    got = nees_subspace(e, cov, comps, 2)
    want = np.einsum("ni,nij,nj->n", e, np.linalg.pinv(cov, hermitian=True, rcond=1e-12), e)
    np.testing.assert_allclose(got, want, rtol=1e-6)  # two factorisations of an ill-scaled matrix


def test_full_rank_covariance_keeps_the_plain_nees_bit_for_bit():
    rng = np.random.default_rng(5)
    a = rng.standard_normal((300, 9, 9))
    cov = a @ np.swapaxes(a, 1, 2) + 0.1 * np.eye(9)
    e = rng.standard_normal((300, 9))
    comps = np.arange(9)
    series, d = nees_series(e, cov, comps)
    assert d == 9
    np.testing.assert_array_equal(series, nees(e, cov, comps))


def test_highly_correlated_full_rank_filter_is_not_taken_as_singular():
    # position and velocity correlated at 0.9999 (a steady-state filter): still rank 6
    rho = 0.9999
    block = np.array([[1.0, rho], [rho, 1.0]])
    cov = np.kron(block, np.eye(3)) * np.array([100.0] * 3 + [1e-2] * 3)[:, None] ** 0.5 \
        * np.array([100.0] * 3 + [1e-2] * 3)[None, :] ** 0.5
    cov = np.broadcast_to(cov, (10, 6, 6))
    assert claimed_rank(cov, np.arange(6)) == 6


def test_along_track_is_scored_on_its_two_dimensional_subspace():
    from navsim import estimators
    from navsim.episode import run_episode
    from navsim.metrics import score_episode
    from navsim.scenario import load_scenario

    sc = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 60.0}})
    rec = run_episode(sc, estimators.make("along-track"), seed=0)
    score = score_episode(rec)
    assert score.nees_dof == 2 and score.nees_components == "dE,dN,dU,dvE,dvN,dvU"
    floored = score_episode(run_episode(sc, estimators.make("along-track", position_floor_m=1e-3,
                                                            velocity_floor_mps=1e-3), seed=0))
    assert floored.nees_dof == 6  # floors make it full rank: the old scoring
