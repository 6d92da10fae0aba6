"""navsim.paper.seed000.run: the reproduction table and the section-6 conclusions."""

from __future__ import annotations

import numpy as np
import pytest

from navsim.paper import seed000


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    plot_dir = tmp_path_factory.mktemp("seed000")
    return seed000.run(plot_dir=str(plot_dir), quick=True), plot_dir


def test_rows_have_the_contract_keys(result):
    rows, _ = result
    assert rows
    for row in rows:
        assert set(row) == {"ref", "quantity", "paper", "navsim", "unit"}
        assert row["ref"].startswith("000 ")
        assert row["paper"] is None or np.isfinite(row["paper"])
        assert np.isfinite(row["navsim"])


def test_every_printed_test_motion_coefficient_within_one_percent(result):
    rows, _ = result
    checked = [r for r in rows if "coefficient" in r["quantity"] and r["paper"] is not None]
    refs = {r["ref"] for r in checked}
    assert refs >= {"000 (2.6)", "000 (2.7)", "000 (2.12)", "000 (2.13)", "000 (3.10)", "000 (3.11)",
                    "000 (4.11)", "000 (4.12)", "000 (4.14)"}
    for r in checked:
        assert r["navsim"] == pytest.approx(r["paper"], rel=0.01), r["quantity"]


def test_local_error_orders(result):
    rows, _ = result
    for r in rows:
        if "local error order" in r["quantity"] and r["paper"] is not None and "optimized" not in r["quantity"]:
            assert r["navsim"] == pytest.approx(r["paper"], abs=0.1), r["quantity"]


def test_exact_integration_reference_is_one(result):
    rows, _ = result
    checks = [r for r in rows if "exact integration" in r["quantity"]]
    assert len(checks) == 3
    for r in checks:
        assert r["navsim"] == pytest.approx(1.0, rel=1e-6)


def test_one_png_per_experiment(result):
    _, plot_dir = result
    names = sorted(p.name for p in plot_dir.iterdir())
    assert names == sorted([
        "000_coning_drift.png", "000_sculling_error.png", "000_local_error.png", "000_position.png",
        "000_fig1_pseudo_sculling_constant.png", "000_fig2_pseudo_sculling_linear.png",
        "000_fig3_pseudo_coning.png",
    ])
    assert all((plot_dir / n).stat().st_size > 10_000 for n in names)


def _level(rows, fig, name):
    key = f"{name}, geometric mean"
    return next(r["navsim"] for r in rows if r["ref"] == f"000 {fig}" and key in r["quantity"])


def test_section6_new_algorithms_attenuate_better(result):
    # the paper's conclusion: smoothing beats traditional, invariant beats both
    rows, _ = result
    assert _level(rows, "Fig. 1", "invariant-4.5") < 0.1 * _level(rows, "Fig. 1", "first-order")
    linear = [_level(rows, "Fig. 2", n) for n in ("two-sample", "smoothing", "invariant-4.4")]
    assert linear[2] < linear[1] < linear[0]
    quadratic = [_level(rows, "Fig. 3", n) for n in ("three-sample", "smoothing", "invariant")]
    assert quadratic[2] < quadratic[1] < quadratic[0]


def test_pseudo_errors_tend_to_one_at_high_solution_rate():
    # f_h << f: every algorithm integrates the harmonic (nearly) exactly
    for name in ("two-sample", "smoothing", "invariant-4.4"):
        assert seed000.pseudo_sculling_error(name, [0.1], transposed=0.1)[0] == pytest.approx(1.0, abs=0.01)
