"""A researcher's own estimator, given by import path, everywhere a name is taken.

The example estimator ``examples/smoothed_fix.py:SmoothedFix`` (not registered, not in the
package) runs through ``navsim run``/``bench``, a local campaign, a Dask campaign and an
estimator FMU (the file embedded into the FMU's resources). The same operations run in
the same order on every path (the estimator has no batch path, so every face calls its
``step`` once per navigation step), so the scores are asserted equal bit for bit.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from navsim import estimators
from navsim.cli import main
from navsim.errors import ConfigError
from navsim.metrics import score_episode
from navsim.report import run_one
from navsim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "smoothed_fix.py"
CPU = {"step_time_us", "cpu_total_s", "realtime_factor"}
NAMES = {"estimator"}  # the label differs with the spelling of the path
OVER = {"timing": {"duration_s": 12.0}, "outages": {"windows_s": [[5.0, 8.0]]}}


def _scores(record) -> dict:
    return {k: v for k, v in score_episode(record).to_flat_dict().items() if k not in CPU}


@pytest.fixture()
def example_copy(tmp_path, monkeypatch):
    """The example as a user's own project folder: ``proj/my_filters.py``, cwd = proj."""
    proj = tmp_path / "proj"
    proj.mkdir()
    shutil.copy(EXAMPLE, proj / "my_filters.py")
    monkeypatch.chdir(proj)
    monkeypatch.syspath_prepend(str(proj))  # what the command-line's cwd lookup gives; undone after the test
    return proj


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("paper-2012").with_overrides(OVER)


def test_make_by_dotted_path_and_by_file_give_the_same_numbers(example_copy, scenario):
    a = run_one(scenario, "my_filters:SmoothedFix", 1, {"gain": 0.4})
    b = run_one(scenario, "my_filters.py:SmoothedFix", 1, {"gain": 0.4})
    c = run_one(scenario, str(example_copy / "my_filters.py") + ":SmoothedFix", 1, {"gain": 0.4})
    strip = [{k: v for k, v in _scores(r).items() if k not in NAMES} for r in (a, b, c)]
    assert strip[0] == strip[1] == strip[2]
    np.testing.assert_array_equal(a.est_lat, b.est_lat)
    assert _scores(a)["horizontal_rmse_m"] < 30.0  # a working filter, not NaN


@pytest.mark.parametrize("name, expected", [
    ("nosuchpkg.mod:Thing", "nosuchpkg is not installed"),
    ("my_filters:Nope", "a callable Nope in module my_filters"),
    ("missing_file.py:X", "an existing Python file"),
    ("not a name", "or an import path"),
])
def test_bad_import_paths_are_one_clear_error(example_copy, name, expected, capsys):
    with pytest.raises(ConfigError, match=expected):
        estimators.make(name)
    code = main(["run", "paper-2012", "--set", "timing.duration_s=2", "--estimator", name, "-q"])
    err = capsys.readouterr().err
    assert code == 2 and expected in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_bad_options_of_a_user_estimator_are_a_config_error(example_copy):
    with pytest.raises(ConfigError, match="options"):
        estimators.make("my_filters:SmoothedFix", nonsense=1)


def test_estimators_command_lists_options_and_unavailable_ones(capsys, monkeypatch):
    assert main(["estimators", "--json"]) == 0
    infos = {i["name"]: i for i in json.loads(capsys.readouterr().out)}
    assert set(estimators.available()) <= set(infos)
    assert infos["lc-ekf"]["available"] and "use_velocity" in infos["lc-ekf"]["options"]
    # without filterpy, gnss-cv is listed as unavailable with the install hint, and refused cleanly
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda n, *a: None if n == "filterpy" else real(n, *a))
    assert "gnss-cv" not in estimators.available()
    info = estimators.describe(["gnss-cv"])[0]
    assert not info.available and "navsim-track[filters]" in info.missing
    with pytest.raises(ConfigError, match=r"navsim-track\[filters\]"):
        estimators.make("gnss-cv")


def test_bench_and_a_local_campaign_take_the_import_path(example_copy, scenario, tmp_path):
    from navsim import campaign as cp

    ref = {s: _scores(run_one(scenario, "my_filters:SmoothedFix", s)) for s in (0, 1)}
    out = tmp_path / "bench"
    assert main(["bench", "paper-2012", "--set", "timing.duration_s=12", "--set", "outages.windows_s=[[5.0, 8.0]]",
                 "--estimators", "lc-ekf,my_filters:SmoothedFix", "--seeds", "0:2", "--out", str(out),
                 "--no-plots", "-q"]) == 0
    runs = (out / "runs.csv").read_text().splitlines()
    assert sum("my_filters:SmoothedFix" in line for line in runs) == 2
    spec_text = f"""
[campaign]
seeds = "0:2"
[overrides]
timing = {{ duration_s = 12.0 }}
outages = {{ windows_s = [[5.0, 8.0]] }}
[[scenarios]]
name = "paper-2012"
[[estimators]]
name = "my_filters.py:SmoothedFix"
"""
    spec_path = example_copy / "study.toml"
    spec_path.write_text(spec_text, encoding="utf-8")
    spec = cp.load_campaign(spec_path)
    res = cp.run_campaign(spec, workers=1, progress=False)  # a spawned worker process imports the file
    assert res.ran == 2 and res.failed == 0
    for row in cp.read_rows(spec.database):
        assert {k: v for k, v in row["scores"].items() if k not in set(cp.CPU_FIELDS) | NAMES} == \
            {k: v for k, v in ref[row["seed"]].items() if k not in set(cp.CPU_FIELDS) | NAMES}


def test_dask_campaign_takes_the_import_path(example_copy, scenario):
    distributed = pytest.importorskip("distributed")
    from navsim import campaign as cp

    ref = {s: _scores(run_one(scenario, "my_filters:SmoothedFix", s)) for s in (0, 1)}
    (example_copy / "study.toml").write_text("""
[campaign]
seeds = "0:2"
[overrides]
timing = { duration_s = 12.0 }
outages = { windows_s = [[5.0, 8.0]] }
[[scenarios]]
name = "paper-2012"
[[estimators]]
name = "my_filters.py:SmoothedFix"
""", encoding="utf-8")
    spec = cp.load_campaign(example_copy / "study.toml")
    cluster = distributed.LocalCluster(host="127.0.0.1", processes=True, n_workers=1, threads_per_worker=1,
                                       dashboard_address=None, silence_logs=50)
    try:
        res = cp.run_campaign(spec, scheduler=cluster.scheduler_address, progress=False)
    finally:
        cluster.close(timeout=30)
    assert res.ran == 2 and res.failed == 0
    for row in cp.read_rows(spec.database):
        assert {k: v for k, v in row["scores"].items() if k not in set(cp.CPU_FIELDS) | NAMES} == \
            {k: v for k, v in ref[row["seed"]].items() if k not in set(cp.CPU_FIELDS) | NAMES}


def test_estimator_fmu_embeds_the_users_file(example_copy, tmp_path):
    pytest.importorskip("pythonfmu")
    pytest.importorskip("fmpy")
    from navsim.episode import run_episode
    from navsim.fmu.build import build_fmu
    from navsim.fmu.master import cosimulate

    short = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 6.0},
                                                         "outages": {"windows_s": [[2.0, 4.0]]}})
    plant = build_fmu(short, "plant", 2, tmp_path / "plant.fmu")
    est = build_fmu(short, "estimator", 2, tmp_path / "est.fmu", estimator="my_filters.py:SmoothedFix",
                    estimator_options="gain = 0.7")
    reference = run_episode(short, estimators.make("my_filters:SmoothedFix", gain=0.7), seed=3)
    (example_copy / "my_filters.py").unlink()  # the FMU carries its own copy
    record = cosimulate(plant, est, seed=3)
    for field in ("est_lat", "est_lon", "est_h", "est_velocity_n", "est_cov"):
        np.testing.assert_array_equal(getattr(record, field), getattr(reference, field), err_msg=field)
