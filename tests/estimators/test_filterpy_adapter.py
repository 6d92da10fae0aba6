"""A user's own filterpy filter as a navsim estimator (navsim.estimators.filterpy_adapter).

Independent truth: the bundled ``gnss-cv`` is a filterpy ``KalmanFilter`` with the same
white-acceleration model and the same least-squares fixes, in ECEF; the example
``examples/filterpy_cv.py`` runs it in a tangent plane through the adapter. The model's
Q is isotropic per axis and the fix covariances are rotated with the coordinates, so the
two are the same filter in rotated coordinates and differ by the rounding of the
rotation: coordinates ~6.4e6 m carry ulp(6.4e6) = 9.3e-10 m, a few ulp per rotation and
fix; the filter contracts, so 16 ulp (1.5e-8 m) bounds the positions, 1e-9 of the scale
the covariances (relative to sqrt(P_ii P_jj), as in test_filterpy_based). The three kinds
(KalmanFilter, ExtendedKalmanFilter, UnscentedKalmanFilter) are one filter on a linear
model (the unscented transform of a linear map is exact): the same bounds.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("filterpy")

from navsim import estimators  # noqa: E402
from navsim.cli import main  # noqa: E402
from navsim.episode import run_episode  # noqa: E402
from navsim.errors import ConfigError  # noqa: E402
from navsim.estimators.filterpy_adapter import from_filterpy  # noqa: E402
from navsim.metrics import score_episode  # noqa: E402
from navsim.scenario import load_scenario  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "filterpy_cv.py"
NAME = f"{EXAMPLE}:make"
POS_TOL_M = 16 * np.spacing(6.4e6)
OVER = {"timing": {"duration_s": 40.0}, "outages": {"windows_s": [[15.0, 22.0]]}}


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("paper-2012").with_overrides(OVER)


def _same_filter(a, b):
    assert np.max(np.abs(a.est_lat - b.est_lat)) * 6.4e6 <= POS_TOL_M
    assert np.max(np.abs(a.est_lon - b.est_lon)) * 6.4e6 <= POS_TOL_M
    assert np.max(np.abs(a.est_h - b.est_h)) <= POS_TOL_M
    assert np.max(np.abs(a.est_velocity_n - b.est_velocity_n)) <= 1e-9
    sl = np.s_[:, :6, :6]
    d = np.sqrt(np.diagonal(a.est_cov[sl], axis1=1, axis2=2))
    assert np.max(np.abs(a.est_cov[sl] - b.est_cov[sl]) / (d[:, :, None] * d[:, None, :])) <= 1e-9
    ok = np.isfinite(a.nis)
    assert np.array_equal(ok, np.isfinite(b.nis)) and ok.sum() >= 30
    np.testing.assert_allclose(b.nis[ok], a.nis[ok], rtol=1e-9)


def test_the_adapted_kalman_filter_is_gnss_cv(scenario):
    ours = run_episode(scenario, estimators.make("gnss-cv", accel_psd=0.1), seed=2)
    theirs = run_episode(scenario, estimators.make(NAME, kind="kf", accel_psd=0.1), seed=2)
    _same_filter(ours, theirs)
    assert np.all(np.isnan(theirs.est_hpr)) and np.all(np.isnan(theirs.est_cov[:, 6:, 6:]))


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_ekf_and_ukf_kinds_equal_the_kalman_filter_on_a_linear_model(scenario, kind):
    kf = run_episode(scenario, estimators.make(NAME, kind="kf"), seed=3)
    other = run_episode(scenario, estimators.make(NAME, kind=kind), seed=3)
    _same_filter(kf, other)


def test_filterpys_predict_and_update_run_once_per_step_and_epoch(monkeypatch, scenario):
    from filterpy.kalman import UnscentedKalmanFilter

    calls = {"predict": 0, "update": 0}
    predict, update = UnscentedKalmanFilter.predict, UnscentedKalmanFilter.update

    def counted(name, real):
        def wrapper(self, *a, **k):
            calls[name] += 1
            return real(self, *a, **k)
        return wrapper

    monkeypatch.setattr(UnscentedKalmanFilter, "predict", counted("predict", predict))
    monkeypatch.setattr(UnscentedKalmanFilter, "update", counted("update", update))
    short = scenario.with_overrides({"timing": {"duration_s": 5.0}})
    rec = run_episode(short, estimators.make(NAME, kind="ukf"), seed=0)
    assert calls["predict"] == len(rec.t) and calls["update"] == np.count_nonzero(np.isfinite(rec.nis)) == 5


def test_episodes_do_not_share_the_filter(scenario):
    est = estimators.make(NAME)
    short = scenario.with_overrides({"timing": {"duration_s": 5.0}})
    a = run_episode(short, est, seed=0)
    run_episode(short, est, seed=1)
    c = run_episode(short, est, seed=0)
    np.testing.assert_array_equal(a.est_lat, c.est_lat)
    np.testing.assert_array_equal(a.est_cov, c.est_cov)


def test_navsim_bench_runs_it_by_import_path(scenario, tmp_path):
    out = tmp_path / "bench"
    assert main(["bench", "paper-2012", "--set", "timing.duration_s=40", "--set", "outages.windows_s=[[15.0, 22.0]]",
                 "--estimators", f"gnss-cv,{NAME}", "--option", "gnss-cv.accel_psd=0.1", "--seeds", "0:2",
                 "--out", str(out), "--no-plots", "-q"]) == 0
    rows = json.loads((out / "bench.json").read_text())
    text = json.dumps(rows)
    assert NAME in text
    direct = {s: score_episode(run_episode(scenario, estimators.make(NAME), seed=s)).horizontal_rmse_m
              for s in (0, 1)}
    runs = (out / "runs.csv").read_text().splitlines()
    header = runs[0].split(",")
    col = header.index("horizontal_rmse_m")
    got = {int(r.split(",")[2]): float(r.split(",")[col]) for r in runs[1:] if NAME in r}
    assert got.keys() == direct.keys()
    for s in got:  # the same operations in the same order: the same numbers
        assert got[s] == direct[s]


def test_bad_input_is_a_config_error():
    with pytest.raises(ConfigError, match="KalmanFilter"):
        from_filterpy(object())
    from filterpy.kalman import KalmanFilter

    with pytest.raises(ConfigError, match="measure"):
        from_filterpy(KalmanFilter(6, 6), measure="pseudoranges")
    with pytest.raises(ConfigError, match="ExtendedKalmanFilter"):
        from_filterpy(KalmanFilter(6, 6), hx_jacobian=lambda x: np.eye(6))
    from navsim.episode import make_context
    from navsim.simulator import Simulator

    sc = load_scenario("paper-2012")
    est = from_filterpy(KalmanFilter(4, 4))
    with pytest.raises(ConfigError, match="6 states"):
        est.reset(make_context(sc), Simulator(sc).reset(0).prior)
