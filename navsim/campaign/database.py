"""The SQLite results database (stdlib :mod:`sqlite3`): table ``episodes``, one row per
episode, unique on ``(scenario_hash, estimator, options, seed)``, written by the parent only
(one transaction per finished episode; a finished row is never overwritten, SQLite UPSERT).

Versions (table ``meta``, keys ``format`` = ``"navsim-campaign"``, ``schema_version``,
``score_version``):

* :data:`SCHEMA_VERSION` - the table layout below;
* :data:`SCORE_VERSION` - what the stored scores mean: 1 before the filter-independent
  divergence check (:func:`navsim.metrics.detect_divergence`; the accuracy figures of a
  diverged episode were computed), 2 with it (NaN accuracy figures and a
  ``divergence_reason``).

:func:`open_database` (a campaign run or resume) creates a new database at the current
versions and refuses, with a recovery hint and before writing anything into the file:
a file of another schema (not a navsim campaign database), a database of a newer schema
or score version (written by a newer navsim), and a database holding rows of an older
score version (their old scores would stand beside new ones: the campaign is *not*
rescored in place; move the file aside and run again to rescore every episode). A
database without version keys (written before the keys existed) is score version 2 when
it records the divergence threshold (stored since the divergence check), else version 1.
:func:`check_database` is the same check for readers (``--report-only``), which warn
about an older score version instead of refusing.
"""


from __future__ import annotations

import json
import sqlite3
from datetime import datetime, timezone
from pathlib import Path

from ..errors import ConfigError, NavsimError, NavsimWarning
from .tasks import EpisodeTask

FORMAT = "navsim-campaign"
SCHEMA_VERSION = 1
"""The layout of the tables below (``meta`` key ``schema_version``)."""
SCORE_VERSION = 2
"""The meaning of the stored scores (``meta`` key ``score_version``; see the module notes)."""

_COLUMNS = ("id", "scenario_hash", "estimator", "options", "seed", "scenario", "estimator_label", "status", "scores",
            "outages", "samples", "error", "wall_s", "worker", "finished_utc")

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


def _refuse(path: Path, what: str, hint: str) -> NavsimError:
    return NavsimError(f"campaign database {path.name}: {what}; {hint}")


def check_database(con: sqlite3.Connection, path: Path, resume: bool = True) -> int | None:
    """The score version of an existing campaign database, None for a file without tables
    (new); :class:`~navsim.errors.NavsimError` with a recovery hint for a file of another
    schema, a newer schema or score version, and (``resume``) an older score version
    with rows; a warning for the latter when reading (``resume=False``). Reads only.
    """
    aside = (f"move it aside (e.g. rename it to {path.name}.old) or set campaign.database to another file, "
             "and run the campaign again")
    tables = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    if not tables:
        return None
    layout = {t: tuple(r[1] for r in con.execute(f"PRAGMA table_info({t})")) for t in ("episodes", "meta")
              if t in tables}
    if layout.get("episodes") != _COLUMNS or layout.get("meta") != ("key", "value"):
        found = ", ".join(sorted(tables))
        raise _refuse(path, f"not a navsim campaign database (an SQLite file of another schema: tables {found})",
                      f"navsim does not write into it; {aside}")
    meta = dict(con.execute("SELECT key, value FROM meta"))
    if meta.get("format", FORMAT) != FORMAT:
        raise _refuse(path, f"not a navsim campaign database (format {meta['format']!r})",
                      f"navsim does not write into it; {aside}")
    try:
        schema = int(meta.get("schema_version", 1))
        score = int(meta["score_version"]) if "score_version" in meta else (
            2 if "divergence_threshold_m" in meta else 1)
    except ValueError:
        raise _refuse(path, "unreadable version keys in its meta table", aside) from None
    if schema > SCHEMA_VERSION or score > SCORE_VERSION:
        raise _refuse(path, f"written by a newer navsim (schema version {schema}, score version {score}; this navsim "
                            f"reads schema {SCHEMA_VERSION}, scores {SCORE_VERSION})",
                      f"use that navsim version, or {aside}")
    rows = con.execute("SELECT COUNT(*) FROM episodes").fetchone()[0]
    if score < SCORE_VERSION and rows:
        what = (f"its {rows} rows were scored by score version {score} (before the divergence check: the accuracy "
                f"figures of diverged episodes are not NaN); this navsim scores by version {SCORE_VERSION}")
        if resume:
            raise _refuse(path, what + ", and a resumed campaign would keep the old rows",
                          f"to rescore every episode {aside}")
        import warnings

        warnings.warn(f"campaign database {path.name}: {what}; its report shows the old scores", NavsimWarning,
                      stacklevel=3)
    return score if rows else None


def open_database(path: str | Path, divergence_threshold_m: float | None = None) -> sqlite3.Connection:
    """Open (create) the campaign database; WAL journal, so a reader never blocks the writer.

    An existing file is checked first (:func:`check_database`; nothing is written into
    a refused file). With ``divergence_threshold_m`` the value is stored on first use
    and a different value later is refused (the stored scores depend on it).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    con = sqlite3.connect(str(path), timeout=30.0)
    try:
        check_database(con, path)
        con.execute("PRAGMA journal_mode=WAL")
        con.execute("PRAGMA synchronous=NORMAL")
        with con:
            con.executescript(_SCHEMA)
            for key, value in (("format", FORMAT), ("schema_version", SCHEMA_VERSION),
                               ("score_version", SCORE_VERSION)):
                con.execute("INSERT OR IGNORE INTO meta VALUES (?, ?)", (key, str(value)))
    except sqlite3.DatabaseError as exc:
        con.close()
        raise corrupt_database(path, exc) from None
    except NavsimError:
        con.close()
        raise
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
