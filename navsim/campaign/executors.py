"""Monte Carlo campaigns: scenarios x estimators x seeds, locally or on a Dask cluster.

``navsim campaign SPEC.toml [--scheduler tcp://HOST:PORT] [--workers N] [--report-only]``

A campaign is declared in TOML::

    [campaign]
    name = "outage study"            # optional, default: the file's stem
    seeds = "0:100"                  # "A:B", "A:B:STEP", "1,4,7" or a list of ints
    divergence_threshold_m = 1000.0  # optional
    interval = "t"                   # "t" (interval of the mean) or "percentile"
    database = "study.sqlite"        # optional, default SPEC stem + ".sqlite", beside the spec
    report = "study_report"          # optional report folder, default SPEC stem + "_report"

    [overrides]                      # optional, applied to every scenario first
    timing = { duration_s = 200.0 }

    [[scenarios]]
    name = "paper-2012"              # bundled name or a .toml path relative to the spec
    label = "paper-short"            # optional, default: name (labels must differ)
    overrides = { outages = { windows_s = [[80.0, 140.0]] } }

    [[estimators]]
    name = "lc-ekf"
    label = "lc-ekf"                 # optional, default: name, or name(k=v,...) with options
    options = { }                    # keyword options of navsim.estimators.make

Every episode (one scenario, one estimator with its options, one seed) is one task:
the worker builds the scenario from its resolved dictionary, runs
:func:`navsim.report.run_one` and scores it with :func:`navsim.metrics.score_episode`
(so a campaign episode has exactly the numbers of ``navsim run`` with the same
settings). Executors:

- local (default): :class:`concurrent.futures.ProcessPoolExecutor` with every core
  (``--workers N`` to choose), processes forked from a fork server that imported the
  episode code once (``forkserver``, where the platform has it: no fork of the campaign
  process, which may run threads; elsewhere ``spawn``, a fresh interpreter per worker),
  with one BLAS / OpenMP thread each unless the environment says otherwise; every
  worker dies with the campaign process (:func:`_die_with_parent`); ``workers=0`` runs
  the episodes in this process;
- Dask: ``--scheduler tcp://HOST:PORT`` submits the same tasks to an existing
  ``distributed`` cluster (``pip install 'navsim-track[campaign]'``), one future per
  episode, collected with ``distributed.as_completed``. When a worker dies the
  scheduler reruns its tasks elsewhere (Dask's own ``allowed-failures`` policy); the
  parent sees each future finish once.

Results go into an SQLite database beside the spec (stdlib :mod:`sqlite3`), table
``episodes``: one row per episode, unique on ``(scenario_hash, estimator, options,
seed)`` where ``scenario_hash`` is :meth:`navsim.scenario.Scenario.config_hash` of the
resolved scenario and ``options`` the canonical JSON of the estimator options. Only
the parent process writes, one transaction per finished episode, as results arrive: a
killed campaign loses at most the episodes still running, and a rerun skips every
episode already in the table (a finished row is never overwritten; failed episodes
are recorded with their error text and are retried only with ``retry_failed``). The
row holds the flat scores (JSON, keys carry units), the per-outage drifts (JSON) and
an evenly subsampled series of the horizontal error (float32 blob) for the
distribution plots.

The report (:func:`write_report`) groups the rows per scenario: for every estimator
the mean and 95 % interval of every metric (:func:`navsim.metrics.aggregate`), written
with :func:`navsim.report.write_bench` (``bench.md``, CSV, JSON, error-distribution and
drift-per-outage plots) into one folder per scenario, and an ``index.md`` and a static
``index.html`` (tables and the PNGs) at the top of the report folder.

References
----------
Dask distributed, https://distributed.dask.org (Client.submit, as_completed,
LocalCluster). SQLite UPSERT, https://sqlite.org/lang_upsert.html.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import contextlib
import html
import json
import math
import multiprocessing
import os
import socket
import sqlite3
import sys
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Iterable, Sequence

import numpy as np

from ..errors import ConfigError, DependencyNotInstalled, NavsimError

__all__ = [
    "ScenarioEntry",
    "EstimatorEntry",
    "CampaignSpec",
    "EpisodeTask",
    "CampaignResult",
    "load_campaign",
    "campaign_from_dict",
    "episode_tasks",
    "run_episode_task",
    "open_database",
    "finished_keys",
    "run_campaign",
    "read_rows",
    "build_results",
    "write_report",
    "add_campaign_parser",
    "cmd_campaign",
    "CampaignInterrupted",
]

SAMPLES_PER_EPISODE = 500
"""Horizontal-error samples kept per episode (evenly in time) for the distribution plots."""

CPU_FIELDS = ("step_time_us", "cpu_total_s", "realtime_factor")
"""Score fields that depend on the machine (CPU time), not on the numbers."""


class CampaignInterrupted(NavsimError):
    """The campaign cannot go on: the local process pool broke (a worker process died)
    or the Dask scheduler does not answer. The finished rows are kept."""


# ============================================================================ specification
def _canonical_json(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


@dataclass(frozen=True, slots=True)
class ScenarioEntry:
    """One scenario of the campaign: ``label`` (unique), the resolved
    :class:`~navsim.scenario.Scenario` and its configuration hash."""

    label: str
    scenario: object
    config_hash: str


@dataclass(frozen=True, slots=True)
class EstimatorEntry:
    """One estimator: registry ``name``, keyword ``options``, unique ``label``;
    ``options_json`` is the canonical JSON that enters the database key."""

    label: str
    name: str
    options: dict
    options_json: str


@dataclass(frozen=True, slots=True)
class CampaignSpec:
    """A validated campaign (see the module docstring for the TOML form).

    database, report_dir : paths (absolute or relative to the working directory).
    """

    name: str
    scenarios: tuple[ScenarioEntry, ...]
    estimators: tuple[EstimatorEntry, ...]
    seeds: tuple[int, ...]
    database: Path
    report_dir: Path
    divergence_threshold_m: float = 1000.0
    interval: str = "t"

    def __post_init__(self):
        if not self.scenarios:
            raise ConfigError("scenarios", "at least one [[scenarios]] entry", [])
        if not self.estimators:
            raise ConfigError("estimators", "at least one [[estimators]] entry", [])
        if not self.seeds:
            raise ConfigError("campaign.seeds", "at least one seed", list(self.seeds))
        if self.interval not in ("t", "percentile"):
            raise ConfigError("campaign.interval", "'t' or 'percentile'", self.interval)
        if not (self.divergence_threshold_m > 0 and math.isfinite(self.divergence_threshold_m)):
            raise ConfigError("campaign.divergence_threshold_m", "a positive finite number", self.divergence_threshold_m)

    @property
    def size(self) -> int:
        """Number of episodes."""
        return len(self.scenarios) * len(self.estimators) * len(self.seeds)


def _check_keys(table: dict, allowed: Iterable[str], where: str, source: str | None) -> None:
    extra = sorted(set(table) - set(allowed))
    if extra:
        raise ConfigError(f"{where}.{extra[0]}" if where else extra[0], f"one of the keys {sorted(allowed)}",
                          table[extra[0]], source=source)


def _seeds(value, source) -> tuple[int, ...]:
    from ..report import parse_seeds

    if isinstance(value, list):
        if not value or not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in value):
            raise ConfigError("campaign.seeds", "a non-empty list of non-negative integers", value, source=source)
        if len(set(value)) != len(value):
            raise ConfigError("campaign.seeds", "distinct seeds", value, source=source)
        return tuple(value)
    if isinstance(value, int) and not isinstance(value, bool):
        value = str(value)
    if not isinstance(value, str):
        raise ConfigError("campaign.seeds", "a string 'A:B' / 'A:B:STEP' / '1,4,7' or a list of ints", value,
                          source=source)
    try:
        return tuple(parse_seeds(value))
    except ConfigError as exc:
        raise ConfigError("campaign.seeds", exc.expected, exc.got, source=source) from None


def campaign_from_dict(data: dict, base_dir: str | Path = ".", stem: str = "campaign",
                       source: str | None = None) -> CampaignSpec:
    """Validate a campaign dictionary (as read from TOML) and resolve its scenarios.

    base_dir : folder of the spec (scenario paths, database and report are relative
    to it). stem : default name and file stem. Errors are
    :class:`~navsim.errors.ConfigError` naming the field (e.g. ``scenarios[1].overrides``).
    """
    from ..estimators import available, make
    from ..estimators import check as check_estimator
    from ..scenario import load_scenario

    base = Path(base_dir)
    if not isinstance(data, dict):
        raise ConfigError("campaign", "a TOML table", data, source=source)
    _check_keys(data, ("campaign", "overrides", "scenarios", "estimators"), "", source)
    camp = data.get("campaign", {})
    if not isinstance(camp, dict):
        raise ConfigError("campaign", "a table [campaign]", camp, source=source)
    _check_keys(camp, ("name", "seeds", "divergence_threshold_m", "interval", "database", "report"), "campaign", source)
    if "seeds" not in camp:
        raise ConfigError("campaign.seeds", "seeds of the campaign, e.g. \"0:20\"", None, source=source)
    seeds = _seeds(camp["seeds"], source)
    common = data.get("overrides", {})
    if not isinstance(common, dict):
        raise ConfigError("overrides", "a table of scenario overrides", common, source=source)

    raw_scen = data.get("scenarios")
    if not isinstance(raw_scen, list) or not raw_scen:
        raise ConfigError("scenarios", "a non-empty array of tables [[scenarios]]", raw_scen, source=source)
    scenarios = []
    for i, entry in enumerate(raw_scen):
        where = f"scenarios[{i}]"
        if not isinstance(entry, dict):
            raise ConfigError(where, "a table with name, label, overrides", entry, source=source)
        _check_keys(entry, ("name", "label", "overrides"), where, source)
        name = entry.get("name")
        if not isinstance(name, str) or not name:
            raise ConfigError(f"{where}.name", "a bundled scenario name or a .toml path", name, source=source)
        overrides = entry.get("overrides", {})
        if not isinstance(overrides, dict):
            raise ConfigError(f"{where}.overrides", "a table of scenario overrides", overrides, source=source)
        target = name
        if name.endswith(".toml") and not Path(name).is_absolute():
            target = str(base / name)
        try:
            scenario = load_scenario(target)
            if common:
                scenario = scenario.with_overrides(common)
            if overrides:
                scenario = scenario.with_overrides(overrides)
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc.field}", exc.expected, exc.got, source=source) from None
        label = entry.get("label", name if not name.endswith(".toml") else Path(name).stem)
        if not isinstance(label, str) or not label or "/" in label or label in {s.label for s in scenarios}:
            raise ConfigError(f"{where}.label", "a unique non-empty label without '/'", label, source=source)
        scenarios.append(ScenarioEntry(label, scenario, scenario.config_hash()))

    raw_est = data.get("estimators")
    if not isinstance(raw_est, list) or not raw_est:
        raise ConfigError("estimators", "a non-empty array of tables [[estimators]]", raw_est, source=source)
    have = available()
    estimators = []
    for i, entry in enumerate(raw_est):
        where = f"estimators[{i}]"
        if not isinstance(entry, dict):
            raise ConfigError(where, "a table with name, label, options", entry, source=source)
        _check_keys(entry, ("name", "label", "options"), where, source)
        name = entry.get("name")
        if not isinstance(name, str):
            raise ConfigError(f"{where}.name", f"one of {', '.join(have)} or an import path package.module:Factory",
                              name, source=source)
        module_part = name.rsplit(":", 1)[0]
        if module_part.endswith(".py") and not Path(module_part).expanduser().is_absolute():
            # a user's estimator file, relative to the spec like its scenario paths
            name = str((base / module_part).resolve()) + ":" + name.rsplit(":", 1)[1]
        try:
            check_estimator(name)
        except ConfigError as exc:
            raise ConfigError(f"{where}.name", exc.expected, name, source=source) from None
        options = entry.get("options", {})
        if not isinstance(options, dict):
            raise ConfigError(f"{where}.options", "a table of keyword options", options, source=source)
        try:
            make(name, **options)
        except Exception as exc:  # noqa: BLE001 - any refusal of the options is a configuration error
            raise ConfigError(f"{where}.options", f"options accepted by {name} ({exc})", options,
                              source=source) from None
        default = name if not options else name + "(" + ",".join(f"{k}={options[k]}" for k in sorted(options)) + ")"
        label = entry.get("label", default)
        if not isinstance(label, str) or not label or label in {e.label for e in estimators}:
            raise ConfigError(f"{where}.label", "a unique non-empty label", label, source=source)
        opt_json = _canonical_json(options)
        if any(e.name == name and e.options_json == opt_json for e in estimators):
            raise ConfigError(f"{where}", "an estimator and options not already in the campaign", name, source=source)
        estimators.append(EstimatorEntry(label, name, dict(options), opt_json))

    cname = camp.get("name", stem)
    if not isinstance(cname, str):
        raise ConfigError("campaign.name", "a string", cname, source=source)
    database = camp.get("database", f"{stem}.sqlite")
    report = camp.get("report", f"{stem}_report")
    for key, value in (("database", database), ("report", report)):
        if not isinstance(value, str) or not value:
            raise ConfigError(f"campaign.{key}", "a file name", value, source=source)
    threshold = camp.get("divergence_threshold_m", 1000.0)
    if isinstance(threshold, bool) or not isinstance(threshold, (int, float)):
        raise ConfigError("campaign.divergence_threshold_m", "a positive number", threshold, source=source)
    try:
        return CampaignSpec(cname, tuple(scenarios), tuple(estimators), seeds, base / database, base / report,
                            float(threshold), camp.get("interval", "t"))
    except ConfigError as exc:
        raise ConfigError(exc.field, exc.expected, exc.got, source=source) from None


def load_campaign(path: str | Path) -> CampaignSpec:
    """Read and validate a campaign TOML file (see the module docstring)."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        import tomli as tomllib

    path = Path(path)
    if not path.is_file():
        raise ConfigError("campaign", "an existing TOML file", str(path))
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("campaign", "valid TOML", str(exc), source=path.name) from None
    return campaign_from_dict(data, base_dir=path.parent, stem=path.stem, source=path.name)


# ============================================================================ tasks
@dataclass(frozen=True, slots=True)
class EpisodeTask:
    """Everything a worker needs for one episode (plain data, cheap to pickle)."""

    scenario_label: str
    scenario_hash: str
    scenario_dict: dict
    scenario_base_dir: str
    estimator_label: str
    estimator: str
    options_json: str
    seed: int
    divergence_threshold_m: float

    @property
    def key(self) -> tuple[str, str, str, int]:
        """The database key (scenario_hash, estimator, options, seed)."""
        return (self.scenario_hash, self.estimator, self.options_json, self.seed)


def episode_tasks(spec: CampaignSpec) -> list[EpisodeTask]:
    """Every episode of the campaign, ordered scenario, seed, estimator."""
    out = []
    for sc in spec.scenarios:
        data = sc.scenario.to_dict()
        for seed in spec.seeds:
            for est in spec.estimators:
                out.append(EpisodeTask(sc.label, sc.config_hash, data, sc.scenario.base_dir, est.label, est.name,
                                       est.options_json, int(seed), spec.divergence_threshold_m))
    return out


def run_episode_task(task: EpisodeTask) -> dict:
    """Run and score one episode (in a worker). Never raises for a failing episode.

    Returns
    -------
    dict with ``status`` ("ok" or "failed"), ``scores`` (flat dict) , ``outages``
    (list of dicts), ``samples`` (float32 bytes of the horizontal error, m, at most
    :data:`SAMPLES_PER_EPISODE` values), ``error`` (text), ``wall_s`` and ``worker``
    (host:pid).
    """
    from ..metrics import error_series, score_episode
    from ..report import run_one
    from ..scenario import Scenario

    t0 = time.perf_counter()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    try:
        scenario = Scenario.from_dict(task.scenario_dict, base_dir=task.scenario_base_dir)
        if scenario.config_hash() != task.scenario_hash:
            raise RuntimeError(f"scenario hash {scenario.config_hash()} on the worker, {task.scenario_hash} expected "
                               "(different navsim versions?)")
        record = run_one(scenario, task.estimator, task.seed, json.loads(task.options_json))
        series = error_series(record)
        score = score_episode(record, series=series, divergence_threshold_m=task.divergence_threshold_m)
        h = np.asarray(series.horizontal_m, dtype=float)
        stride = max(1, len(h) // SAMPLES_PER_EPISODE)
        return {"status": "ok", "scores": score.to_flat_dict(), "outages": [o.as_dict() for o in score.outages],
                "samples": h[stride - 1::stride].astype(np.float32).tobytes(), "error": None,
                "wall_s": time.perf_counter() - t0, "worker": worker}
    except Exception as exc:  # noqa: BLE001 - a failing episode is a result
        return {"status": "failed", "scores": None, "outages": None, "samples": None,
                "error": f"{type(exc).__name__}: {exc}", "wall_s": time.perf_counter() - t0, "worker": worker}


# ============================================================================ database
_SCHEMA = """
CREATE TABLE IF NOT EXISTS episodes (
    id INTEGER PRIMARY KEY,
    scenario_hash TEXT NOT NULL,
    estimator TEXT NOT NULL,
    options TEXT NOT NULL,
    seed INTEGER NOT NULL,
    scenario TEXT NOT NULL,
    estimator_label TEXT NOT NULL,
    status TEXT NOT NULL CHECK (status IN ('ok', 'failed')),
    scores TEXT,
    outages TEXT,
    samples BLOB,
    error TEXT,
    wall_s REAL,
    worker TEXT,
    finished_utc TEXT NOT NULL,
    UNIQUE (scenario_hash, estimator, options, seed)
);
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
"""

# A finished row is never overwritten; a failed one is replaced by a new outcome (retry).
_UPSERT = """
INSERT INTO episodes (scenario_hash, estimator, options, seed, scenario, estimator_label, status, scores,
                      outages, samples, error, wall_s, worker, finished_utc)
VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)
ON CONFLICT (scenario_hash, estimator, options, seed) DO UPDATE SET
    scenario = excluded.scenario, estimator_label = excluded.estimator_label, status = excluded.status,
    scores = excluded.scores, outages = excluded.outages, samples = excluded.samples, error = excluded.error,
    wall_s = excluded.wall_s, worker = excluded.worker, finished_utc = excluded.finished_utc
WHERE episodes.status = 'failed'
"""


def _corrupt_database(path: Path, exc: Exception) -> NavsimError:
    """The one error for a campaign database SQLite cannot use, with the recovery hint."""
    return NavsimError(
        f"campaign database {path.name}: not a usable navsim campaign database ({type(exc).__name__}: {exc}); "
        f"move it aside (e.g. rename it to {path.name}.corrupt) and run the campaign again to start a new one, "
        f"or try `sqlite3 {path.name} .recover` to salvage its rows")


def open_database(path: str | Path, divergence_threshold_m: float | None = None) -> sqlite3.Connection:
    """Open (create) the campaign database; WAL journal, so a reader never blocks the writer.

    With ``divergence_threshold_m`` the value is stored on first use and a different
    value later is refused (the stored scores depend on it).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    con = sqlite3.connect(str(path), timeout=30.0)
    try:
        con.execute("PRAGMA journal_mode=WAL")
        con.execute("PRAGMA synchronous=NORMAL")
        with con:
            con.executescript(_SCHEMA)
    except sqlite3.DatabaseError as exc:
        con.close()
        raise _corrupt_database(path, exc) from None
    if divergence_threshold_m is not None:
        row = con.execute("SELECT value FROM meta WHERE key = 'divergence_threshold_m'").fetchone()
        if row is None:
            with con:
                con.execute("INSERT INTO meta VALUES ('divergence_threshold_m', ?)", (repr(float(divergence_threshold_m)),))
        elif float(row[0]) != float(divergence_threshold_m):
            con.close()
            raise ConfigError("campaign.divergence_threshold_m",
                              f"{float(row[0])} as in the existing database {path.name} (or a new database)",
                              divergence_threshold_m)
    return con


def finished_keys(con: sqlite3.Connection, include_failed: bool = True) -> set[tuple[str, str, str, int]]:
    """Keys (scenario_hash, estimator, options, seed) already in the database."""
    sql = "SELECT scenario_hash, estimator, options, seed FROM episodes"
    if not include_failed:
        sql += " WHERE status = 'ok'"
    return {tuple(r) for r in con.execute(sql)}


def _store(con: sqlite3.Connection, task: EpisodeTask, out: dict) -> None:
    with con:  # one transaction per episode
        con.execute(_UPSERT, (
            task.scenario_hash, task.estimator, task.options_json, task.seed, task.scenario_label,
            task.estimator_label, out["status"],
            None if out["scores"] is None else json.dumps(out["scores"]),
            None if out["outages"] is None else json.dumps(out["outages"]),
            out["samples"], out["error"], out["wall_s"], out["worker"],
            datetime.now(timezone.utc).isoformat(timespec="seconds")))


# ============================================================================ executors
_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
                "NUMEXPR_NUM_THREADS")


@contextlib.contextmanager
def _single_threaded_children():
    """Environment for worker processes started inside: one BLAS / OpenMP thread each
    (variables the user set are kept). The episodes use small matrices, where BLAS
    threads only cost wake-ups (measured: 0.43 s CPU for six 20-s episodes with the
    default threads, 0.36 s with one), and several processes with several threads
    each oversubscribe the cores. Dask's nanny does the same for its workers."""
    added = [k for k in _THREAD_VARS if k not in os.environ]
    for k in added:
        os.environ[k] = "1"
    try:
        yield
    finally:
        for k in added:
            os.environ.pop(k, None)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _die_with_parent(campaign_pid: int) -> None:
    """Worker initializer: the worker is killed when the campaign process dies, even by
    SIGKILL. Its parent is the campaign process (``spawn``) or the fork server
    (``forkserver``), which exits when the campaign process dies. Linux:
    ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` for the death of the parent; everywhere a watcher
    thread checks once a second that the parent is the same and the campaign process
    alive, and exits the worker otherwise."""
    import signal
    import sys
    import threading

    parent = os.getppid()
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG = 1
        except (OSError, AttributeError):
            pass
    if not _alive(campaign_pid) or (parent == 1 and campaign_pid != 1):  # died before the prctl took effect
        os._exit(1)

    def watch():
        while True:
            time.sleep(1.0)
            if os.getppid() != parent or not _alive(campaign_pid):
                os._exit(1)

    threading.Thread(target=watch, name="navsim-parent-watch", daemon=True).start()


# imported once by the fork server, so that forked workers start with the episode code loaded
_FORKSERVER_PRELOAD = ["navsim.campaign", "navsim.report", "navsim.episode", "navsim.estimators", "navsim.metrics"]


def _worker_context():
    """The start method of local workers: ``forkserver`` (preloading the episode code)
    where available, else ``spawn``."""
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(_FORKSERVER_PRELOAD)
        return ctx
    return multiprocessing.get_context("spawn")


def _run_local(todo: list[EpisodeTask], workers: int, handle: Callable[[EpisodeTask, dict], None]) -> None:
    if workers == 0:
        for task in todo:
            handle(task, run_episode_task(task))
        return
    # forkserver (or spawn): no fork of this process, which may run threads; the fork
    # server and the workers start during the submissions below with the environment set there
    pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=_worker_context(),
                                  initializer=_die_with_parent, initargs=(os.getpid(),))
    try:
        with _single_threaded_children():
            futures = {pool.submit(run_episode_task, t): t for t in todo}
        for fut in cf.as_completed(futures):
            try:
                out = fut.result()
            except cf.process.BrokenProcessPool as exc:
                raise CampaignInterrupted(f"a local worker process died ({exc}); the finished episodes are in the "
                                          "database, run the campaign again to finish the rest") from None
            handle(futures[fut], out)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


DASK_RESUBMITS = 3  # times a lost episode result is resubmitted before it is stored as failed


def _run_dask(todo: list[EpisodeTask], scheduler, handle: Callable[[EpisodeTask, dict], None],
              timeout_s: float = 30.0) -> None:
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise DependencyNotInstalled("distributed", "campaign") from None
    own = isinstance(scheduler, str)
    if own:
        try:
            client = Client(scheduler, timeout=f"{timeout_s}s")
        except (OSError, TimeoutError) as exc:
            raise CampaignInterrupted(f"no Dask scheduler answered at {scheduler} within {timeout_s:g} s "
                                      f"({type(exc).__name__}: {exc})") from None
    else:
        client = scheduler
    try:
        futures = {}
        for task in todo:
            fut = client.submit(run_episode_task, task, pure=False)
            futures[fut.key] = (fut, task, 0)
        pending = as_completed([f for f, _, _ in futures.values()])
        for fut in pending:
            task, tries = futures.pop(fut.key)[1:]
            error = None
            if fut.status == "error":  # e.g. KilledWorker: the task killed its workers too often
                error = fut.exception()
            else:
                try:
                    out = fut.result()
                except Exception as exc:  # noqa: BLE001 - the result was lost with its worker
                    # (cancelled, or the scheduler lost it between completion and fetch):
                    # run the episode again elsewhere, a bounded number of times
                    fut.release()
                    if tries < DASK_RESUBMITS:
                        again = client.submit(run_episode_task, task, pure=False)
                        futures[again.key] = (again, task, tries + 1)
                        pending.add(again)
                        continue
                    error = exc
            if error is not None:
                out = {"status": "failed", "scores": None, "outages": None, "samples": None,
                       "error": f"{type(error).__name__}: {error}", "wall_s": None, "worker": None}
            fut.release()
            handle(task, out)
    finally:
        for fut, *_ in futures.values():
            fut.cancel()
        if own:
            client.close()


@dataclass
class CampaignResult:
    """What one call of :func:`run_campaign` did: ``total`` episodes of the campaign,
    ``skipped`` already in the database, ``ran`` now, ``failed`` of those."""

    total: int
    skipped: int
    ran: int = 0
    failed: int = 0
    wall_s: float = 0.0


def run_campaign(spec: CampaignSpec, *, scheduler=None, workers: int | None = None, retry_failed: bool = False,
                 progress: bool = True, on_result: Callable[[EpisodeTask, dict], None] | None = None,
                 tasks: Sequence[EpisodeTask] | None = None) -> CampaignResult:
    """Run the episodes of the campaign not yet in its database.

    Parameters
    ----------
    spec : the campaign. scheduler : None for local processes, a ``tcp://HOST:PORT``
        address or a ``distributed.Client`` for Dask.
    workers : local processes (default: every core, ``os.cpu_count()``); 0 runs the
        episodes in this process.
    retry_failed : run again the episodes recorded as failed.
    progress : tqdm bar on stderr (episodes done, failures, time left).
    on_result : called with (task, outcome) after each row is committed (a test hook;
        an exception raised there stops the campaign, the rows so far are kept).
    tasks : run only these (a subset of :func:`episode_tasks`); default all.
    """
    from tqdm import tqdm

    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 0):
        raise ConfigError("--workers", "a non-negative integer", workers)
    all_tasks = list(tasks) if tasks is not None else episode_tasks(spec)
    con = open_database(spec.database, spec.divergence_threshold_m)
    t0 = time.perf_counter()
    try:
        done = finished_keys(con, include_failed=not retry_failed)
        todo = [t for t in all_tasks if t.key not in done]
        result = CampaignResult(total=len(all_tasks), skipped=len(all_tasks) - len(todo))
        bar = tqdm(total=len(todo), unit="episode", desc=spec.name, file=sys.stderr, disable=not progress,
                   leave=False, dynamic_ncols=True)
        bar.set_postfix(failed=0, skipped=result.skipped)

        def handle(task: EpisodeTask, out: dict) -> None:
            _store(con, task, out)
            result.ran += 1
            result.failed += out["status"] != "ok"
            bar.set_postfix(failed=result.failed, skipped=result.skipped, refresh=False)
            bar.update(1)
            if on_result is not None:
                on_result(task, out)

        try:
            if not todo:
                pass
            elif scheduler is not None:
                _run_dask(todo, scheduler, handle)
            else:
                _run_local(todo, (os.cpu_count() or 1) if workers is None else workers, handle)
        finally:
            bar.refresh()  # the final count and failures, whatever the refresh interval
            bar.close()
    finally:
        con.close()
    result.wall_s = time.perf_counter() - t0
    return result


# ============================================================================ reading and reporting
def read_rows(database: str | Path, spec: CampaignSpec | None = None) -> list[dict]:
    """Rows of the database as dicts (``scores`` / ``outages`` decoded, ``samples`` as
    a float array); with ``spec`` only the episodes of that campaign."""
    if not Path(database).is_file():
        raise ConfigError("campaign.database", "an existing campaign database", Path(database).name)
    con = sqlite3.connect(str(database), timeout=30.0)
    con.row_factory = sqlite3.Row
    try:
        rows = [dict(r) for r in con.execute("SELECT * FROM episodes ORDER BY id")]
    except sqlite3.DatabaseError as exc:
        raise _corrupt_database(Path(database), exc) from None
    finally:
        con.close()
    for r in rows:
        r["scores"] = json.loads(r["scores"]) if r["scores"] else None
        r["outages"] = json.loads(r["outages"]) if r["outages"] else []
        r["samples"] = np.frombuffer(r["samples"], dtype=np.float32).astype(float) if r["samples"] else np.zeros(0)
    if spec is not None:
        keys = {t.key for t in episode_tasks(spec)}
        rows = [r for r in rows if (r["scenario_hash"], r["estimator"], r["options"], r["seed"]) in keys]
    return rows


def _score_from_row(row: dict):
    from ..metrics import SCORE_FIELDS, EpisodeScore, Outage

    flat = row["scores"]
    values = {k: (math.nan if flat.get(k) is None and k != "seed" else flat.get(k)) for k in SCORE_FIELDS}
    outages = tuple(Outage(**{k: (math.nan if v is None else v) for k, v in o.items()}) for o in row["outages"])
    return EpisodeScore(**values, outages=outages)


def build_results(spec: CampaignSpec, rows: list[dict] | None = None) -> dict:
    """One :class:`navsim.report.BenchResult` per scenario label from the database rows
    (estimators named by their labels, mean and interval per metric)."""
    from ..metrics import aggregate
    from ..report import BenchResult

    if rows is None:
        rows = read_rows(spec.database, spec) if Path(spec.database).exists() else []
    labels = {(e.name, e.options_json): e.label for e in spec.estimators}
    out = {}
    for sc in spec.scenarios:
        names = [e.label for e in spec.estimators]
        res = BenchResult(sc.label, names, list(spec.seeds), spec.interval, 0.95)
        samples: dict[str, list] = {n: [] for n in names}
        for r in rows:
            if r["scenario_hash"] != sc.config_hash:
                continue
            label = labels[(r["estimator"], r["options"])]
            if r["status"] == "ok":
                res.scores.setdefault(label, {})[r["seed"]] = _score_from_row(r)
                samples[label].append(r["samples"])
            else:
                res.failures.append({"estimator": label, "seed": r["seed"], "error": r["error"]})
        for n in names:
            got = [res.scores.get(n, {}).get(s) for s in spec.seeds]
            res.summary[n] = aggregate([g for g in got if g is not None], method=spec.interval, confidence=0.95)
            res.horizontal_samples[n] = np.concatenate(samples[n]) if samples[n] else np.zeros(0)
            res.mc_nees[n] = None
        out[sc.label] = res
    return out


def _html_table(result, metrics: Sequence[str]) -> str:
    from ..metrics import EpisodeScore
    from ..report import format_cell

    units = EpisodeScore.units()
    names = result.estimators
    head = "".join(f"<th>{html.escape(n)}</th>" for n in names)
    rows = ["<tr><td>runs finished</td><td></td>" + "".join(
        f"<td>{len(result.scores.get(n, {}))}/{len(result.seeds)}</td>" for n in names) + "</tr>"]
    for m in metrics:
        cells = "".join(f"<td>{html.escape(format_cell(result.summary[n][m]))}</td>" for n in names)
        rows.append(f"<tr><td>{html.escape(m)}</td><td>{html.escape(units[m])}</td>{cells}</tr>")
    return f"<table><tr><th>metric</th><th>unit</th>{head}</tr>\n" + "\n".join(rows) + "</table>"


def write_report(spec: CampaignSpec, out_dir: str | Path | None = None, plots: bool = True) -> list[Path]:
    """Write the campaign report: per scenario a folder with navsim.report's bench
    files and plots, and ``index.md`` / ``index.html`` over all scenarios."""
    from ..metrics import NUMERIC_FIELDS
    from ..provenance import provenance, provenance_line
    from ..report import KEY_METRICS, bench_markdown, write_bench

    out = Path(out_dir) if out_dir is not None else Path(spec.report_dir)
    out.mkdir(parents=True, exist_ok=True)
    results = build_results(spec)
    metrics = [m for m in NUMERIC_FIELDS if m not in ("duration_s", "steps", "divergence_threshold_m")]
    paths: list[Path] = []
    interval = "Student-t 95 % interval of the mean" if spec.interval == "t" else "95 % percentile interval of the runs"
    md = [f"# navsim campaign: {spec.name}", "",
          f"{len(spec.scenarios)} scenario(s) x {len(spec.estimators)} estimator(s) x {len(spec.seeds)} seed(s) "
          f"= {spec.size} episodes. Cells: mean across seeds [{interval}]; key metrics here, every metric in each "
          "scenario's bench.md / bench.csv.", ""]
    body = [f"<h1>navsim campaign: {html.escape(spec.name)}</h1>",
            f"<p>{len(spec.scenarios)} scenario(s) &times; {len(spec.estimators)} estimator(s) &times; "
            f"{len(spec.seeds)} seed(s) = {spec.size} episodes. Cells: mean across seeds [{interval}].</p>"]
    prov = provenance({sc.label: sc.config_hash for sc in spec.scenarios})
    md += [f"Provenance: {provenance_line(prov)}", ""]
    body.append(f"<p><small>Provenance: {html.escape(provenance_line(prov))}</small></p>")
    for sc in spec.scenarios:
        res = results[sc.label]
        res.provenance = {**prov, "scenario_hash": sc.config_hash}
        folder = out / sc.label
        have_any = any(res.scores.values())
        files = write_bench(res, folder, plots=plots and have_any)
        paths += files
        pngs = [p for p in files if p.suffix == ".png"]
        table = bench_markdown(res, KEY_METRICS).split("\n", 2)[2]
        md += [f"## {sc.label} (configuration {sc.config_hash})", "", table.strip(), ""]
        md += [f"![{p.stem}]({sc.label}/{p.name})" for p in pngs] + [""]
        md += [f"Every metric: [{sc.label}/bench.md]({sc.label}/bench.md), per-episode rows: "
               f"[{sc.label}/runs.csv]({sc.label}/runs.csv)", ""]
        body.append(f"<h2>{html.escape(sc.label)} <small>(configuration {sc.config_hash})</small></h2>")
        body.append(_html_table(res, metrics))
        for p in pngs:
            body.append(f'<p><img src="{html.escape(sc.label)}/{html.escape(p.name)}" alt="{html.escape(p.stem)}" '
                        'style="max-width:100%"></p>')
        if res.failures:
            body.append("<h3>Failures</h3><ul>" + "".join(
                f"<li>{html.escape(f['estimator'])} seed {f['seed']}: {html.escape(str(f['error']))}</li>"
                for f in res.failures) + "</ul>")
        body.append(f'<p><a href="{html.escape(sc.label)}/bench.csv">bench.csv</a> &middot; '
                    f'<a href="{html.escape(sc.label)}/runs.csv">runs.csv</a> &middot; '
                    f'<a href="{html.escape(sc.label)}/bench.json">bench.json</a></p>')
    md_path = out / "index.md"
    md_path.write_text("\n".join(md), encoding="utf-8")
    prov_path = out / "provenance.json"
    prov_path.write_text(json.dumps(prov, indent=1) + "\n", encoding="utf-8")
    paths.append(prov_path)
    style = ("body{font-family:sans-serif;margin:2em;max-width:80em}table{border-collapse:collapse;font-size:90%}"
             "td,th{border:1px solid #bbb;padding:2px 6px;text-align:left}tr:nth-child(even){background:#f4f4f4}")
    html_path = out / "index.html"
    html_path.write_text("<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\">"
                         f"<title>navsim campaign: {html.escape(spec.name)}</title><style>{style}</style></head>"
                         "<body>\n" + "\n".join(body) + "\n</body></html>\n", encoding="utf-8")
    return [md_path, html_path] + paths


# ============================================================================ command line
def cmd_campaign(args) -> int:
    """``navsim campaign``: run what is missing, then write the report."""
    spec = load_campaign(args.spec)
    if not args.report_only:
        res = run_campaign(spec, scheduler=args.scheduler, workers=args.workers, retry_failed=args.retry_failed,
                           progress=not args.quiet)
        print(f"{spec.name}: {res.total} episodes, {res.skipped} already in {spec.database.name}, "
              f"{res.ran} run now ({res.failed} failed) in {res.wall_s:.1f} s")
    elif not spec.database.exists():
        raise ConfigError("--report-only", f"an existing database {spec.database.name} (run the campaign first)",
                          str(spec.database))
    paths = write_report(spec, plots=not args.no_plots)
    print(paths[1])
    return 0


def add_campaign_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``navsim campaign`` on an argparse sub-parser collection."""
    p = subparsers.add_parser("campaign", help="Monte Carlo campaign from a TOML spec, locally or on a Dask cluster")
    p.add_argument("spec", help="campaign TOML file (results go to an SQLite database beside it)")
    p.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="run on this Dask distributed scheduler (needs navsim-track[campaign])")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local worker processes (default: every core; 0 = in this process)")
    p.add_argument("--report-only", action="store_true", help="only write the report from the database")
    p.add_argument("--retry-failed", action="store_true", help="run again the episodes recorded as failed")
    p.add_argument("--no-plots", action="store_true", help="report without PNG files")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_campaign)
    return p
