"""The SQLite results database (stdlib :mod:`sqlite3`): table ``episodes``, one row per
episode, unique on ``(scenario_hash, estimator, options, seed)``, written by the parent only
(one transaction per finished episode; a finished row is never overwritten, SQLite UPSERT).
"""


from __future__ import annotations

import json
import sqlite3
from datetime import datetime, timezone
from pathlib import Path

from ..errors import ConfigError, NavsimError
from .tasks import EpisodeTask

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


def corrupt_database(path: Path, exc: Exception) -> NavsimError:
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
        raise corrupt_database(path, exc) from None
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


def store(con: sqlite3.Connection, task: EpisodeTask, out: dict) -> None:
    with con:  # one transaction per episode
        con.execute(_UPSERT, (
            task.scenario_hash, task.estimator, task.options_json, task.seed, task.scenario_label,
            task.estimator_label, out["status"],
            None if out["scores"] is None else json.dumps(out["scores"]),
            None if out["outages"] is None else json.dumps(out["outages"]),
            out["samples"], out["error"], out["wall_s"], out["worker"],
            datetime.now(timezone.utc).isoformat(timespec="seconds")))
