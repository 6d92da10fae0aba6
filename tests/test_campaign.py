"""navsim.campaign: spec validation, SQLite results, resume, failures, report, Dask with a lost worker."""

from __future__ import annotations

import argparse
import json
import os
import signal
import sqlite3
import time
from pathlib import Path

import numpy as np
import pytest

from navsim import campaign as cp
from navsim.campaign import database as cp_database
from navsim.campaign import executors as cp_executors
from navsim.errors import ConfigError
from navsim.metrics import score_episode
from navsim.report import run_one

SPEC = """
[campaign]
name = "tiny"
seeds = "0:3"
[overrides]
timing = { duration_s = 20.0 }
outages = { windows_s = [[8.0, 14.0]] }
[[scenarios]]
name = "paper-2012"
label = "short"
[[estimators]]
name = "gnss-ls"
[[estimators]]
name = "along-track"
"""


def _spec(tmp_path, text=SPEC, name="camp.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return cp.load_campaign(path)


def _db_rows(spec):
    con = sqlite3.connect(str(spec.database))
    try:
        return con.execute("SELECT scenario_hash, estimator, options, seed, status, scores FROM episodes").fetchall()
    finally:
        con.close()


def _comparable(scores: dict) -> dict:
    return {k: v for k, v in scores.items() if k not in cp.CPU_FIELDS}


# ---------------------------------------------------------------------------- spec
def test_spec_resolves_scenarios_estimators_and_paths(tmp_path):
    spec = _spec(tmp_path)
    assert spec.name == "tiny" and spec.seeds == (0, 1, 2) and spec.size == 6
    sc = spec.scenarios[0]
    assert sc.label == "short" and sc.scenario.timing.duration_s == 20.0
    assert sc.config_hash == sc.scenario.config_hash()
    assert [e.label for e in spec.estimators] == ["gnss-ls", "along-track"]
    assert spec.database == tmp_path / "camp.sqlite" and spec.report_dir == tmp_path / "camp_report"
    keys = [t.key for t in cp.episode_tasks(spec)]
    assert len(set(keys)) == 6


@pytest.mark.parametrize("patch, field", [
    (('seeds = "0:3"', 'seeds = "3:1"'), "campaign.seeds"),
    (('seeds = "0:3"', 'seeds = [1, 1]'), "campaign.seeds"),
    (('name = "gnss-ls"', 'name = "no-such-filter"'), "estimators[0].name"),
    (('label = "short"', 'label = "short"\ncolour = 3'), "scenarios[0].colour"),
    (('name = "paper-2012"', 'name = "no-such-scenario"'), "scenarios[0]: scenario"),
    (("duration_s = 20.0", "duration_s = -1.0"), "scenarios[0]: timing.duration_s"),
    (('name = "along-track"', 'name = "gnss-ls"'), "estimators[1].label"),
    (('name = "tiny"', 'name = "tiny"\ninterval = "bootstrap"'), "campaign.interval"),
])
def test_spec_errors_name_the_field(tmp_path, patch, field):
    with pytest.raises(ConfigError) as info:
        _spec(tmp_path, SPEC.replace(*patch, 1))
    assert info.value.field == field
    assert info.value.source == "camp.toml"


@pytest.mark.parametrize("top, drop, field, expected", [
    ("", "[[estimators]]", "estimators", "a non-empty array of tables [[estimators]]"),
    ("estimators = [1]\n", "[[estimators]]", "estimators[0]", "a table with name, label, options"),
    ('estimators = [{name = "gnss-ls", colour = 1}]\n', "[[estimators]]", "estimators[0].colour", "one of the keys"),
    ("scenarios = []\n", "[[scenarios]]", "scenarios", "a non-empty array of tables [[scenarios]]"),
])
def test_spec_array_of_tables_errors(tmp_path, top, drop, field, expected):
    """[[scenarios]] and [[estimators]]: a non-empty array of tables with known keys."""
    head, tail = SPEC.split(drop, 1)
    rest = "" if drop == "[[estimators]]" else tail[tail.index("[[estimators]]"):]
    with pytest.raises(ConfigError) as info:
        _spec(tmp_path, top + head + rest)
    assert info.value.field == field and expected in info.value.expected


def test_estimator_options_enter_key_and_label(tmp_path):
    text = SPEC.replace('name = "along-track"', 'name = "gnss-ls"\noptions = { }\nlabel = "ls2"', 1)
    with pytest.raises(ConfigError) as info:  # same estimator, same options twice
        _spec(tmp_path, text)
    assert info.value.field == "estimators[1]"
    spec = _spec(tmp_path, text.replace("options = { }", 'options = { "min_satellites" = 5 }'))
    assert [e.options_json for e in spec.estimators] == ["{}", '{"min_satellites":5}']


# ---------------------------------------------------------------------------- running
def test_local_campaign_equals_navsim_run_and_rerun_skips_everything(tmp_path):
    spec = _spec(tmp_path)
    res = cp.run_campaign(spec, workers=2, progress=False)
    assert (res.total, res.skipped, res.ran, res.failed) == (6, 0, 6, 0)
    rows = cp.read_rows(spec.database, spec)
    assert len(rows) == 6 and {r["status"] for r in rows} == {"ok"}
    assert len({r["worker"] for r in rows}) >= 1
    # independent path: navsim run's function on the same resolved scenario
    scenario = spec.scenarios[0].scenario
    for r in rows:
        direct = score_episode(run_one(scenario, r["estimator"], r["seed"])).to_flat_dict()
        assert _comparable(r["scores"]) == _comparable(direct)
    seeds = {(r["estimator"], r["seed"]): r["scores"]["horizontal_rmse_m"] for r in rows}
    assert seeds[("gnss-ls", 0)] != seeds[("gnss-ls", 1)]
    again = cp.run_campaign(spec, workers=2, progress=False)
    assert (again.skipped, again.ran) == (6, 0)
    assert len(_db_rows(spec)) == 6


def test_resume_after_interruption_runs_only_the_missing_episodes(tmp_path):
    spec = _spec(tmp_path)
    seen = []

    def stop_after_two(task, out):
        seen.append(task.key)
        if len(seen) == 2:
            raise KeyboardInterrupt  # as if the user pressed Ctrl-C

    with pytest.raises(KeyboardInterrupt):
        cp.run_campaign(spec, workers=0, progress=False, on_result=stop_after_two)
    first = _db_rows(spec)
    assert len(first) == 2 and {r[:4] for r in first} == set(seen)
    ran = []
    res = cp.run_campaign(spec, workers=0, progress=False, on_result=lambda t, o: ran.append(t.key))
    assert (res.skipped, res.ran) == (2, 4)
    assert set(ran).isdisjoint(seen) and len(ran) == 4
    rows = _db_rows(spec)
    keys = [r[:4] for r in rows]
    assert len(keys) == len(set(keys)) == 6
    assert {t.key for t in cp.episode_tasks(spec)} == set(keys)
    # the rows written before the interruption are untouched and equal a clean run
    clean = _spec(tmp_path, SPEC.replace('name = "tiny"', 'name = "tiny"\ndatabase = "clean.sqlite"'), "clean.toml")
    cp.run_campaign(clean, workers=0, progress=False)
    ref = {r[:4]: _comparable(json.loads(r[5])) for r in _db_rows(clean)}
    assert {r[:4]: _comparable(json.loads(r[5])) for r in rows} == ref


def test_failed_episode_is_recorded_and_the_campaign_goes_on(tmp_path, monkeypatch, capsys):
    import navsim.report

    real = navsim.report.run_one

    def flaky(scenario, name, seed, options=None, **kw):
        if seed == 1 and name == "along-track":
            raise FloatingPointError("synthetic failure")
        return real(scenario, name, seed, options, **kw)

    spec = _spec(tmp_path)
    monkeypatch.setattr(navsim.report, "run_one", flaky)
    res = cp.run_campaign(spec, workers=0, progress=True)
    assert (res.ran, res.failed) == (6, 1)
    bar = capsys.readouterr().err  # the tqdm bar on stderr: count, failures, time left
    assert "6/6" in bar and "failed=1" in bar and "<00:00" in bar
    rows = cp.read_rows(spec.database)
    bad = [r for r in rows if r["status"] == "failed"]
    assert len(bad) == 1 and bad[0]["seed"] == 1 and bad[0]["estimator"] == "along-track"
    assert "FloatingPointError: synthetic failure" in bad[0]["error"] and bad[0]["scores"] is None
    # a plain rerun keeps the failure; retry_failed replaces it by the real outcome
    assert cp.run_campaign(spec, workers=0, progress=False).ran == 0
    monkeypatch.setattr(navsim.report, "run_one", real)
    res = cp.run_campaign(spec, workers=0, progress=False, retry_failed=True)
    assert (res.ran, res.failed) == (1, 0)
    rows = _db_rows(spec)
    assert len(rows) == 6 and {r[4] for r in rows} == {"ok"}


def test_a_finished_row_is_never_overwritten(tmp_path):
    spec = _spec(tmp_path)
    task = cp.episode_tasks(spec)[0]
    con = cp.open_database(spec.database)
    try:
        ok = {"status": "ok", "scores": {"x": 1.0}, "outages": [], "samples": b"", "error": None, "wall_s": 1.0,
              "worker": "a"}
        cp_database.store(con, task, ok)
        cp_database.store(con, task, dict(ok, scores={"x": 2.0}))
        cp_database.store(con, task, dict(ok, status="failed", scores=None, error="late duplicate"))
        rows = con.execute("SELECT status, scores FROM episodes").fetchall()
    finally:
        con.close()
    assert rows == [("ok", json.dumps({"x": 1.0}))]


def test_changing_the_divergence_threshold_is_refused(tmp_path):
    spec = _spec(tmp_path)
    cp.open_database(spec.database, 1000.0).close()
    with pytest.raises(ConfigError) as info:
        cp.open_database(spec.database, 50.0)
    assert info.value.field == "campaign.divergence_threshold_m"


# ---------------------------------------------------------------------------- report and CLI
def test_cli_runs_and_writes_a_report_readable_in_a_browser(tmp_path, capsys):
    path = tmp_path / "camp.toml"
    path.write_text(SPEC, encoding="utf-8")
    parser = argparse.ArgumentParser()
    cp.add_campaign_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["campaign", str(path), "--report-only"])
    with pytest.raises(ConfigError):  # no database yet
        args.func(args)
    args = parser.parse_args(["campaign", str(path), "--workers", "0", "-q"])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "6 episodes, 0 already" in out and "6 run now (0 failed)" in out
    report = tmp_path / "camp_report"
    index = (report / "index.html").read_text(encoding="utf-8")
    assert index.startswith("<!DOCTYPE html>") and index.count("<table>") == 1
    for png in ("short/bench_errors.png", "short/bench_outages.png"):
        assert f'src="{png}"' in index and (report / png).stat().st_size > 5000
    md = (report / "index.md").read_text(encoding="utf-8")
    assert "| runs finished | | 3/3 | 3/3 |" in md
    # the table's mean equals the mean of the stored per-episode scores
    spec = cp.load_campaign(path)
    vals = [r["scores"]["horizontal_rmse_m"] for r in cp.read_rows(spec.database) if r["estimator"] == "gnss-ls"]
    summary = json.loads((report / "short" / "bench.json").read_text())["summary"]["gnss-ls"]["horizontal_rmse_m"]
    assert summary["mean"] == pytest.approx(np.mean(vals), rel=1e-12) and summary["n"] == 3
    args = parser.parse_args(["campaign", str(path), "--report-only", "--no-plots"])
    assert args.func(args) == 0


# ---------------------------------------------------------------------------- Dask
DASK_SPEC = SPEC.replace('seeds = "0:3"', 'seeds = "0:4"').replace("duration_s = 20.0", "duration_s = 30.0")


def test_dask_cluster_losing_a_worker_gives_every_episode_once_equal_to_local(tmp_path):
    distributed = pytest.importorskip("distributed")
    spec = _spec(tmp_path, DASK_SPEC)
    killed, after_kill = [], []
    cluster = distributed.LocalCluster(host="127.0.0.1", processes=True, n_workers=2, threads_per_worker=1,
                                       dashboard_address=None, silence_logs=50)
    try:
        with distributed.Client(cluster, timeout="30s") as client:
            client.wait_for_workers(2, timeout=30)

            def kill_one(task, out):
                if not killed:
                    pids = client.run(os.getpid)
                    pid = sorted(pids.values())[0]
                    os.kill(pid, signal.SIGKILL)
                    killed.append(pid)
                after_kill.append(task.key)

            # the campaign opens its own client from the address (as `navsim campaign --scheduler`)
            res = cp.run_campaign(spec, scheduler=cluster.scheduler_address, progress=False, on_result=kill_one)
            assert killed and killed[0] not in client.run(os.getpid).values()
    finally:
        cluster.close(timeout=30)
    assert res.ran == spec.size and res.failed == 0
    assert len(after_kill) == spec.size  # the kill came after the first result: the rest finished after it
    by_killed = [r for r in cp.read_rows(spec.database) if r["worker"].endswith(f":{killed[0]}")]
    assert len(by_killed) < spec.size - 1
    rows = cp.read_rows(spec.database)
    keys = [(r["scenario_hash"], r["estimator"], r["options"], r["seed"]) for r in rows]
    assert len(keys) == len(set(keys)) == spec.size
    local = _spec(tmp_path, DASK_SPEC.replace('name = "tiny"', 'name = "tiny"\ndatabase = "local.sqlite"'), "l.toml")
    cp.run_campaign(local, workers=1, progress=False)
    ref = {(r["scenario_hash"], r["estimator"], r["options"], r["seed"]): r for r in cp.read_rows(local.database)}
    for r, k in zip(rows, keys):
        assert _comparable(r["scores"]) == _comparable(ref[k]["scores"])
        assert r["outages"] == ref[k]["outages"]
        np.testing.assert_array_equal(r["samples"], ref[k]["samples"])


def test_scenario_file_relative_to_the_spec(tmp_path):
    from navsim.scenario import load_scenario

    sub = tmp_path / "scen"
    sub.mkdir()
    base = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 20.0}})
    (sub / "mine.toml").write_text(base.to_toml(), encoding="utf-8")
    text = SPEC.replace('name = "paper-2012"\nlabel = "short"', 'name = "scen/mine.toml"')
    spec = _spec(tmp_path, text)
    sc = spec.scenarios[0]
    assert sc.label == "mine"
    # the campaign overrides (same duration, outage window) on top of the file's scenario
    expected = base.with_overrides({"outages": {"windows_s": [[8.0, 14.0]]}})
    assert sc.config_hash == expected.config_hash()


def test_sigkill_of_the_campaign_process_loses_no_finished_row(tmp_path):
    import subprocess
    import sys

    path = tmp_path / "camp.toml"
    path.write_text(SPEC, encoding="utf-8")
    code = (
        "import os, signal, sys\n"
        "from navsim import campaign as cp\n"
        "n = []\n"
        "def hook(task, out):\n"
        "    n.append(task.seed)\n"
        "    if len(n) == 3:\n"
        "        os.kill(os.getpid(), signal.SIGKILL)\n"
        "cp.run_campaign(cp.load_campaign(sys.argv[1]), workers=0, progress=False, on_result=hook)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code, str(path)], timeout=120, capture_output=True)
    assert proc.returncode == -signal.SIGKILL
    spec = cp.load_campaign(path)
    con = sqlite3.connect(str(spec.database))
    try:
        assert con.execute("PRAGMA integrity_check").fetchone() == ("ok",)
    finally:
        con.close()
    assert len(_db_rows(spec)) == 3  # every row committed before the kill is there
    res = cp.run_campaign(spec, workers=0, progress=False)
    assert (res.skipped, res.ran) == (3, 3)
    keys = [r[:4] for r in _db_rows(spec)]
    assert len(keys) == len(set(keys)) == 6


def test_an_unreachable_scheduler_is_a_clear_error_within_the_timeout():
    pytest.importorskip("distributed")
    t0 = time.perf_counter()
    with pytest.raises(cp.CampaignInterrupted, match="no Dask scheduler answered at tcp://127.0.0.1:9"):
        cp_executors._run_dask([], "tcp://127.0.0.1:9", lambda t, o: None, timeout_s=1.0)
    assert time.perf_counter() - t0 < 15


def test_dask_result_lost_after_completion_is_resubmitted_then_stored_as_failed(monkeypatch):
    """A finished future whose result cannot be fetched any more (its worker died between
    completion and fetch: CancelledError, OSError, ...) is resubmitted, at most
    DASK_RESUBMITS times, and then stored as a failed episode; nothing escapes _run_dask."""
    distributed = pytest.importorskip("distributed")

    class Future:
        def __init__(self, key, outcome):
            self.key, self.outcome, self.status = key, outcome, "finished"

        def result(self):
            if isinstance(self.outcome, BaseException):
                raise self.outcome
            return self.outcome

        def release(self):
            pass

        def cancel(self):
            pass

    class Client:
        def __init__(self, plan):
            self.plan, self.submitted = plan, []

        def submit(self, fn, task, pure=False):
            self.submitted.append(task)
            outcome = self.plan[task].pop(0)
            return Future(f"{task}-{len(self.submitted)}", outcome)

    class AsCompleted:
        def __init__(self, futures):
            self.queue = list(futures)

        def __iter__(self):
            while self.queue:
                yield self.queue.pop(0)

        def add(self, fut):
            self.queue.append(fut)

    monkeypatch.setattr(distributed, "as_completed", AsCompleted)
    ok = {"status": "ok"}
    lost = OSError("connection to the worker closed")
    plan = {"a": [lost, ok], "b": [ok], "c": [lost] * (cp.DASK_RESUBMITS + 1)}
    client = Client(plan)
    got = {}
    cp_executors._run_dask(["a", "b", "c"], client, lambda task, out: got.setdefault(task, []).append(out))
    assert got["a"] == [ok] and got["b"] == [ok]
    assert len(got["c"]) == 1 and got["c"][0]["status"] == "failed" and "OSError" in got["c"][0]["error"]
    assert client.submitted.count("a") == 2 and client.submitted.count("c") == cp.DASK_RESUBMITS + 1


def test_sigkill_of_the_campaign_parent_leaves_no_worker_process(tmp_path):
    """Local pool workers die with their parent: after SIGKILL of the campaign process
    no worker is left running (they carry PR_SET_PDEATHSIG / a parent watcher)."""
    import subprocess
    import sys

    spec_file = tmp_path / "orphans.toml"
    spec_file.write_text(SPEC.replace("duration_s = 20.0", "duration_s = 200.0"), encoding="utf-8")
    code = (
        "import os, sys, time, threading\n"
        "import navsim.campaign as cp\n"
        "spec = cp.load_campaign(sys.argv[1])\n"
        "cp.run_campaign(spec, workers=2, progress=False)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code, str(spec_file)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    def descendants(pid):
        try:
            kids = [int(p) for p in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
        except FileNotFoundError:
            return []
        return kids + [d for k in kids for d in descendants(k)]

    def command(pid):
        try:
            return Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace")
        except OSError:
            return ""

    if not Path(f"/proc/{proc.pid}/task/{proc.pid}/children").exists():
        pytest.skip("no /proc children listing on this system")
    # the workers: children of the campaign process (spawn) or of its fork server (forkserver,
    # forked without exec: they show the server's command line); the fork server counts too
    children = []
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(children) < 3:
        time.sleep(0.5)
        children = [c for c in descendants(proc.pid) if "spawn_main" in command(c) or "forkserver" in command(c)]
        if children and all("spawn_main" in command(c) for c in children) and len(children) >= 2:
            break
    assert len(children) >= 2, f"no worker process started: {children}"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    alive = set(children)
    deadline = time.monotonic() + 30
    while alive and time.monotonic() < deadline:
        time.sleep(0.2)
        alive = {c for c in alive if Path(f"/proc/{c}").exists() and
                 Path(f"/proc/{c}/stat").read_text().split()[2] != "Z"}
    assert not alive, f"orphaned workers still running: {sorted(alive)}"
