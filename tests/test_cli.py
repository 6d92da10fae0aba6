"""The navsim command: simulate to NPZ/CSV with the documented layout, show, errors."""

import csv

import numpy as np
import pytest

from navsim.cli import main
from navsim.io import GNSS_KEYS, STEP_KEYS


def test_simulate_npz_layout_and_plot(tmp_path, capsys):
    out = tmp_path / "ep.npz"
    png = tmp_path / "ep.png"
    assert main(["simulate", "paper-2012", "--seed", "3", "-o", str(out), "--set", "timing.duration_s=5", "-q",
                 "--plot", str(png), "--chunk", "123"]) == 0
    with np.load(out) as data:
        assert set(STEP_KEYS) | set(GNSS_KEYS) <= set(data.files)
        assert data["t"].shape == (500,) and data["dtheta_r"].shape == (500, 4, 3)
        assert data["gnss_pseudorange_m"].shape[0] == 5
        assert int(data["seed"]) == 3 and "duration_s = 5.0" in str(data["scenario_toml"])
        np.testing.assert_allclose(data["t"], (np.arange(500) + 1) * 0.01)
    assert png.stat().st_size > 10_000


def test_simulate_csv_matches_npz(tmp_path):
    main(["simulate", "paper-2012", "-o", str(tmp_path / "a.npz"), "--set", "timing.duration_s=3", "-q"])
    main(["simulate", "paper-2012", "-o", str(tmp_path / "a.csv"), "--set", "timing.duration_s=3", "-q"])
    with open(tmp_path / "a.csv") as f:
        rows = list(csv.DictReader(f))
    with np.load(tmp_path / "a.npz") as data:
        assert len(rows) == 300
        np.testing.assert_allclose([float(r["lat"]) for r in rows], data["lat"], rtol=1e-15)
        np.testing.assert_allclose([float(r["dv_r1_2"]) for r in rows], data["dv_r"][:, 0, 2], rtol=1e-15)
    with open(tmp_path / "a_gnss.csv") as f:
        gnss = list(csv.DictReader(f))
    assert len(gnss) == 3 * 24 and {"prn", "valid", "pseudorange_m"} <= set(gnss[0])


def test_show_and_scenarios(capsys):
    assert main(["show", "paper-2012", "--set", "motion.speed_mps=10"]) == 0
    assert "speed_mps = 10.0" in capsys.readouterr().out
    assert main(["scenarios"]) == 0
    assert "mountain-railway" in capsys.readouterr().out


def test_bad_input_exits_2_with_the_field(tmp_path, capsys):
    assert main(["simulate", "paper-2012", "-o", str(tmp_path / "x.npz"), "--set", "timing.nav_period_s=0.013"]) == 2
    err = capsys.readouterr().err
    assert "timing.nav_period_s" in err and "expected" in err
    assert not (tmp_path / "x.npz").exists()


@pytest.mark.parametrize("option, value, message", [
    ("--seed", "-1", "expected an integer >= 0, got '-1'"),
    ("--seed", "x", "expected an integer >= 0, got 'x'"),
    ("--chunk", "0", "expected a whole number >= 1, got '0'"),
    ("--chunk", "1.5", "expected a whole number >= 1, got '1.5'"),
])
def test_integer_options_refused_in_one_line(tmp_path, capsys, option, value, message):
    assert main(["simulate", "paper-2012", "-o", str(tmp_path / "x.npz"), option, value]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_a_reader_that_leaves_the_pipe_early_gets_a_quiet_stop():
    """`navsim run --json | head -c 10`: the reader closes the pipe before navsim writes; no
    'Broken pipe' error line and no traceback, the exit status a shell gives SIGPIPE."""
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "navsim.cli", "run", "paper-2012", "--estimator", "ins-only",
                             "--seed", "0", "--set", "timing.duration_s=2", "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader is gone before the first byte is written
    err = proc.stderr.read().decode()
    proc.wait(timeout=120)
    proc.stderr.close()
    assert proc.returncode == 141, (proc.returncode, err)
    assert "Broken pipe" not in err and "Traceback" not in err, err
