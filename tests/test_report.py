"""``navsim run`` / ``navsim bench``: parsing, identical numbers, outputs, failures.

The estimators used here are written here and registered for the test only: ``echo``
returns truth (through a backdoor of this test) plus an offset that is a function of
the IMU and GNSS measurements, so two runs give the same numbers exactly when they saw
the same simulated episode; ``frozen`` returns the prior forever; ``flaky`` fails on
its second episode.
"""

from __future__ import annotations

import argparse
import csv
import json
import math

import numpy as np
import pytest

import navsim.estimators as estimators
from navsim.errors import ConfigError
from navsim.estimators.base import Estimate, EstimateBatch
from navsim.metrics import score_episode
from navsim.report import (
    add_bench_parser,
    add_run_parser,
    bench,
    parse_options,
    parse_seeds,
    run_one,
)
from navsim.scenario import load_scenario
from navsim.simulator import Simulator

SETS = ["timing.duration_s=30", "outages.windows_s=[[10.0, 20.0]]"]
SCENARIO = load_scenario("paper-2012").with_overrides(
    {"timing": {"duration_s": 30.0}, "outages": {"windows_s": [[10.0, 20.0]]}})
CPU_KEYS = ("step_time_us", "cpu_total_s", "realtime_factor")
BACKDOOR: dict = {}


class Echo:
    """Truth + an east offset of ``gain`` times the running sum of the z gyro increments
    (so it depends on the IMU noise draws) and, at epochs with a fix, the count of valid
    satellites as NIS."""

    def __init__(self, gain: float = 100.0, sigma_m: float = 1.0):
        self.gain = gain
        self.sigma_m = sigma_m

    def reset(self, context, prior):
        self.earth = context.earth
        self.acc = 0.0

    def step_batch(self, batch):
        tr = BACKDOOR["truth_at"](batch.t)
        off_e = self.acc + self.gain * np.cumsum(batch.dtheta_r[:, 0, 2])
        self.acc = float(off_e[-1])
        r_n, r_e = self.earth.radii(tr.lat)
        lon = tr.lon + off_e / ((r_e + tr.h) * np.cos(tr.lat))
        sol = np.column_stack([tr.lat, lon, tr.h, tr.velocity_n, tr.heading, tr.pitch, tr.roll])
        n = len(batch)
        cov = np.broadcast_to(np.diag([self.sigma_m**2] * 3 + [0.01] * 3 + [1e-6] * 3), (n, 9, 9)).copy()
        nis, dof = np.full(n, np.nan), np.zeros(n, int)
        for j, obs in batch.gnss:
            if obs.valid.sum() >= 4:  # an "update" only with a fix
                nis[j], dof[j] = float(obs.valid.sum()), 4
        return EstimateBatch(sol, cov, nis, dof)

    def step(self, m):
        raise AssertionError("the runner uses step_batch")


class Frozen:
    """The prior, forever, with a covariance wide enough to cover the distance travelled
    (1 km, 100 m/s and 1 rad standard deviations: honest, so not diverged)."""

    def reset(self, context, prior):
        self.prior = prior

    def step(self, m):
        p = self.prior
        return Estimate(m.t, p.lat, p.lon, p.h, p.velocity_n, p.heading, p.pitch, p.roll, covariance=WIDE)


WIDE = np.diag([1e6] * 3 + [1e4] * 3 + [1.0] * 3)


class Flaky(Frozen):
    episodes = 0

    def reset(self, context, prior):
        type(self).episodes += 1
        super().reset(context, prior)
        self.n = type(self).episodes

    def step(self, m):
        if self.n == 2 and m.step == 100:
            raise RuntimeError("flaky failure")
        return super().step(m)


@pytest.fixture(autouse=True)
def registry(monkeypatch):
    sim = Simulator(SCENARIO)
    BACKDOOR["truth_at"] = sim.truth_at
    for name, cls in (("echo", "Echo"), ("frozen", "Frozen"), ("flaky", "Flaky")):
        monkeypatch.setitem(estimators._REGISTRY, name, f"{__name__}:{cls}")
    Flaky.episodes = 0
    yield
    BACKDOOR.clear()


def _parser():
    parser = argparse.ArgumentParser(prog="navsim")
    sub = parser.add_subparsers(dest="command", required=True)
    add_run_parser(sub)
    add_bench_parser(sub)
    return parser


def _cli(argv):
    args = _parser().parse_args(argv)
    return args.func(args)


def _no_cpu(flat):
    return {k: v for k, v in flat.items() if k not in CPU_KEYS}


# ------------------------------------------------------------------ parsing
def test_parse_seeds():
    assert parse_seeds("0:20") == list(range(20))
    assert parse_seeds("3") == [3] and parse_seeds("1,4,7") == [1, 4, 7] and parse_seeds("0:10:5") == [0, 5]
    for bad in ("a:b", "5:5", "1,1", "-1", "1:2:3:4"):
        with pytest.raises(ConfigError):
            parse_seeds(bad)


def test_parse_options():
    got = parse_options(["gain=2.5", "echo.sigma_m=3", "frozen.tag=hello"], ["echo", "frozen"])
    assert got == {None: {"gain": 2.5}, "echo": {"sigma_m": 3}, "frozen": {"tag": "hello"}}
    with pytest.raises(ConfigError):
        parse_options(["novalue"])
    with pytest.raises(ConfigError):
        parse_options(["other.k=1"], ["echo"])


# ------------------------------------------------------------------ run
def test_run_json_is_one_flat_object_with_the_expected_numbers(capsys):
    assert _cli(["run", "paper-2012", "--estimator", "echo", "--seed", "2", "--json", "-q",
                 "--option", "gain=50", *sum((["--set", s] for s in SETS), [])]) == 0
    out = capsys.readouterr().out
    flat = json.loads(out)
    assert out.count("\n") == 1 and isinstance(flat, dict)
    assert all(not isinstance(v, (dict, list)) for v in flat.values())
    assert flat["estimator"] == "echo" and flat["seed"] == 2 and flat["steps"] == 3000
    # independently: the same episode through the library
    record = run_one(SCENARIO, "echo", 2, {"gain": 50.0})
    score = score_episode(record)
    provenance = {"navsim_version", "command", "scenario_hash", "date_utc"}  # tests/test_provenance.py
    assert provenance <= set(flat) and flat["scenario_hash"] == SCENARIO.config_hash()
    assert _no_cpu({k: v for k, v in flat.items() if k not in provenance}) == \
        _no_cpu(json.loads(json.dumps(score.to_flat_dict())))
    # the offset we put in is what the metric sees: final horizontal error = |gain * sum dtheta_z|
    sim = Simulator(SCENARIO)
    sim.reset(2)
    dz = np.concatenate([c.imu.dtheta_r[:, 0, 2] for c in sim.chunks(1000)])
    assert flat["horizontal_final_m"] == pytest.approx(abs(50.0 * dz.sum()), rel=1e-6)
    assert flat["outage_count"] == 1 and flat["nees_dof"] == 9 and flat["nis_updates"] == 20


def test_run_table_and_plot(tmp_path, capsys):
    png = tmp_path / "errors.png"
    assert _cli(["run", "paper-2012", "--estimator", "frozen", "-q", "--plot", str(png),
                 *sum((["--set", s] for s in SETS), [])]) == 0
    out = capsys.readouterr().out
    assert "horizontal_rmse_m" in out and "outage 1: GNSS epochs 10-19 s" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000


def test_run_rejects_unknown_estimators_and_options():
    with pytest.raises(ConfigError, match="--estimator"):
        _cli(["run", "paper-2012", "--estimator", "no-such-filter", "-q"])
    with pytest.raises(ConfigError, match="options"):
        _cli(["run", "paper-2012", "--estimator", "echo", "--option", "bogus=1", "-q", "--set", SETS[0]])


# ------------------------------------------------------------------ bench
def test_bench_numbers_equal_run_and_seeds_differ():
    result = bench(SCENARIO, ["echo", "frozen"], [0, 1, 2])
    assert not result.failures
    for seed in (0, 2):
        alone = score_episode(run_one(SCENARIO, "echo", seed))
        assert _no_cpu(result.scores["echo"][seed].to_flat_dict()) == _no_cpu(alone.to_flat_dict())
    finals = {result.scores["echo"][s].horizontal_final_m for s in (0, 1, 2)}
    assert len(finals) == 3  # the IMU noise differs between seeds
    summary = result.summary["echo"]["horizontal_rmse_m"]
    values = [result.scores["echo"][s].horizontal_rmse_m for s in (0, 1, 2)]
    assert summary.n == 3 and summary.mean == pytest.approx(np.mean(values))
    assert summary.low < summary.mean < summary.high
    assert result.mc_nees["echo"].dof == 9 and result.mc_nees["echo"].runs.max() == 3


def test_bench_without_the_episode_cache_gives_the_same_numbers(monkeypatch):
    cached = bench(SCENARIO, ["echo"], [1])
    monkeypatch.setattr("navsim.report._CACHE_LIMIT_BYTES", 0.0)
    fresh = bench(SCENARIO, ["echo"], [1])
    assert _no_cpu(cached.scores["echo"][1].to_flat_dict()) == _no_cpu(fresh.scores["echo"][1].to_flat_dict())


def test_a_failing_estimator_is_recorded_and_the_bench_goes_on():
    result = bench(SCENARIO, ["flaky", "echo"], [0, 1, 2])
    assert [(f["estimator"], f["seed"]) for f in result.failures] == [("flaky", 1)]
    assert "RuntimeError: flaky failure" in result.failures[0]["error"]
    assert sorted(result.scores["flaky"]) == [0, 2] and sorted(result.scores["echo"]) == [0, 1, 2]
    assert result.summary["flaky"]["horizontal_rmse_m"].n == 2


def test_bench_cli_writes_tables_and_plots(tmp_path, capsys):
    out_dir = tmp_path / "bench"
    assert _cli(["bench", "paper-2012", "--estimators", "echo,frozen,flaky", "--seeds", "0:2", "-q",
                 "--out", str(out_dir), "--option", "echo.gain=10", *sum((["--set", s] for s in SETS), [])]) == 0
    text = capsys.readouterr().out
    assert "| horizontal_rmse_m | m |" in text and "flaky seed 1: RuntimeError" in text
    for name in ("bench.md", "bench.csv", "runs.csv", "bench.json", "bench_errors.png", "bench_outages.png",
                 "bench_nees.png"):
        assert (out_dir / name).stat().st_size > 100, name
    data = json.loads((out_dir / "bench.json").read_text())
    assert data["seeds"] == [0, 1] and data["failures"][0]["seed"] == 1
    rows = list(csv.DictReader((out_dir / "runs.csv").open()))
    assert len(rows) == 6 and sum(bool(r["error"]) for r in rows) == 1
    echo_rmse = [float(r["horizontal_rmse_m"]) for r in rows if r["estimator"] == "echo"]
    summary = list(csv.DictReader((out_dir / "bench.csv").open()))
    echo = next(r for r in summary if r["estimator"] == "echo")
    assert float(echo["horizontal_rmse_m.mean"]) == pytest.approx(np.mean(echo_rmse))
    assert data["summary"]["echo"]["horizontal_rmse_m"]["mean"] == pytest.approx(np.mean(echo_rmse))
    # the per-run JSON rows carry the outages
    run = next(r for r in data["runs"] if r["estimator"] == "frozen")
    assert run["outages"][0]["n_epochs"] == 10 and math.isfinite(run["outages"][0]["max_drift_m"])


def test_bench_json_to_stdout(capsys):
    assert _cli(["bench", "paper-2012", "--estimators", "frozen", "--seeds", "0:2", "-q", "--json",
                 "--interval", "percentile", *sum((["--set", s] for s in SETS), [])]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["interval"]["method"] == "percentile" and len(data["runs"]) == 2


def test_bench_rejects_unknown_estimators():
    with pytest.raises(ConfigError, match="nope"):
        _cli(["bench", "paper-2012", "--estimators", "frozen,nope", "--seeds", "0:2", "-q"])


def test_cli_main_exits_2_on_bad_input_when_wired(capsys):
    from navsim import cli

    parser = cli.build_parser()
    choices = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices
    if "run" not in choices:
        pytest.skip("navsim.cli does not register `run` yet")
    assert cli.main(["run", "paper-2012", "--estimator", "no-such-filter", "-q"]) == 2
    assert "--estimator" in capsys.readouterr().err


# ------------------------------------------------------------------ bundled estimators
def test_bundled_estimators_score_on_a_short_episode():
    bundled = [n for n in estimators.available() if n not in ("echo", "frozen", "flaky")]
    if not bundled:
        pytest.skip("no bundled estimator installed yet")
    short = SCENARIO.with_overrides({"timing": {"duration_s": 10.0}, "outages": {"windows_s": []}})
    for name in bundled[:2]:
        score = score_episode(run_one(short, name, 0))
        assert score.steps == 1000 and score.step_time_us > 0
        assert math.isfinite(score.horizontal_rmse_m) or score.diverged
