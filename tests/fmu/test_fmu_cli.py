"""`navsim fmu ...` through add_fmu_parser."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("fmpy")

from navsim.fmu.cli import main  # noqa: E402


def test_build_validate_and_info(tmp_path, capsys):
    out = tmp_path / "p.fmu"
    assert main(["fmu", "build", "paper-2012", "--what", "plant", "--fmi", "3", "-o", str(out),
                 "--set", "timing.duration_s=5"]) == 0
    assert out.exists()
    assert main(["fmu", "validate", str(out)]) == 0
    assert "ok" in capsys.readouterr().out
    assert main(["fmu", "info"]) == 0
    assert "LD_PRELOAD" in capsys.readouterr().out


def test_bad_input_exit_status_2(tmp_path, capsys):
    assert main(["fmu", "build", "paper-2012", "--what", "estimator", "--estimator", "nope",
                 "-o", str(tmp_path / "e.fmu")]) == 2
    assert "--estimator" in capsys.readouterr().err


def test_cosim_and_run_print_scores(plant3, estimator3, train_fmu, capsys):
    assert main(["fmu", "cosim", str(plant3), str(estimator3), "--seed", "1", "--steps", "150"]) == 0
    score = json.loads(capsys.readouterr().out)
    assert score["steps"] == 150 and score["horizontal_rmse_m"] is not None
    assert main(["fmu", "run", "paper-2012", "--set", "timing.duration_s=2", "--motion-fmu", str(train_fmu),
                 "--motion-map", "s=s,speed=v,accel=a,offset=50", "--motion-input", "F_traction=2e5"]) == 0
    score = json.loads(capsys.readouterr().out)
    assert score["steps"] == 200 and score["estimator"] == "ins-only"
