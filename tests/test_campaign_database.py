"""The campaign database's identity and versions (issue 16): a file of another schema or of
a newer navsim is refused before anything is written into it, a database whose rows were
scored before the divergence check is refused on resume (warned about when only read),
and every new database records its format, schema and score versions."""

from __future__ import annotations

import hashlib
import sqlite3

import pytest

from navsim import campaign as cp
from navsim.campaign import database as db
from navsim.errors import NavsimError, NavsimWarning

SPEC = """
[campaign]
name = "tiny"
seeds = "0:2"
[overrides]
timing = { duration_s = 1.0 }
[[scenarios]]
name = "paper-2012"
[[estimators]]
name = "gnss-ls"
"""

OK = {"status": "ok", "scores": {"rmse_h_m": 1.0}, "outages": [], "samples": b"", "error": None, "wall_s": 1.0,
      "worker": "w"}


def _spec(tmp_path):
    path = tmp_path / "camp.toml"
    path.write_text(SPEC, encoding="utf-8")
    return cp.load_campaign(path)


def _digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _meta(path) -> dict:
    con = sqlite3.connect(str(path))
    try:
        return dict(con.execute("SELECT key, value FROM meta"))
    finally:
        con.close()


def _database_with_a_row(spec, drop_keys=()):
    """A database with one finished row, then (to imitate an older navsim) without the
    given meta keys."""
    con = db.open_database(spec.database, spec.divergence_threshold_m)
    try:
        db.store(con, cp.episode_tasks(spec)[0], OK)
        with con:
            for key in drop_keys:
                con.execute("DELETE FROM meta WHERE key = ?", (key,))
        con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    finally:
        con.close()


def test_a_new_database_records_its_format_and_versions(tmp_path):
    spec = _spec(tmp_path)
    db.open_database(spec.database, spec.divergence_threshold_m).close()
    assert _meta(spec.database) == {"format": "navsim-campaign", "schema_version": str(db.SCHEMA_VERSION),
                                    "score_version": str(db.SCORE_VERSION), "divergence_threshold_m": "1000.0"}


@pytest.mark.parametrize("tables", [
    ("CREATE TABLE episodes (x INTEGER)", "CREATE TABLE meta (key TEXT, value TEXT)"),  # the battery's case
    ("CREATE TABLE results (a TEXT)",),
    ("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)",),
])
def test_a_file_of_another_schema_is_refused_and_left_as_it_was(tmp_path, tables):
    spec = _spec(tmp_path)
    con = sqlite3.connect(str(spec.database))
    for sql in tables:
        con.execute(sql)
    con.commit()
    con.close()
    before = _digest(spec.database)
    with pytest.raises(NavsimError, match=r"not a navsim campaign database .*another schema.*move it aside"):
        cp.run_campaign(spec, workers=0, progress=False)
    with pytest.raises(NavsimError, match="not a navsim campaign database"):
        cp.read_rows(spec.database)
    assert _digest(spec.database) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["camp.sqlite", "camp.toml"]  # no -wal / -shm beside it


def test_another_format_key_is_refused(tmp_path):
    spec = _spec(tmp_path)
    _database_with_a_row(spec)
    con = sqlite3.connect(str(spec.database))
    with con:
        con.execute("UPDATE meta SET value = 'someone-else' WHERE key = 'format'")
    con.close()
    with pytest.raises(NavsimError, match="format 'someone-else'"):
        db.open_database(spec.database)


@pytest.mark.parametrize("key", ["schema_version", "score_version"])
def test_a_database_of_a_newer_navsim_is_refused_for_writing_and_reading(tmp_path, key):
    spec = _spec(tmp_path)
    _database_with_a_row(spec)
    con = sqlite3.connect(str(spec.database))
    with con:
        con.execute("UPDATE meta SET value = ? WHERE key = ?", (str(getattr(db, key.upper()) + 1), key))
    con.close()
    before = _digest(spec.database)
    with pytest.raises(NavsimError, match=r"written by a newer navsim.*use that navsim version"):
        cp.run_campaign(spec, workers=0, progress=False)
    with pytest.raises(NavsimError, match="written by a newer navsim"):
        cp.read_rows(spec.database)
    assert _digest(spec.database) == before


def test_rows_scored_before_the_divergence_check_are_refused_on_resume_and_warned_on_reading(tmp_path):
    """A database of the navsim before the divergence check has no version keys and no
    stored divergence threshold (stored since that check): score version 1."""
    spec = _spec(tmp_path)
    _database_with_a_row(spec, drop_keys=("format", "schema_version", "score_version", "divergence_threshold_m"))
    before = _digest(spec.database)
    with pytest.raises(NavsimError, match=r"1 rows were scored by score version 1 .*resumed campaign would keep "
                                          r"the old rows; to rescore every episode move it aside"):
        cp.run_campaign(spec, workers=0, progress=False)
    assert _digest(spec.database) == before
    with pytest.warns(NavsimWarning, match="score version 1.*its report shows the old scores"):
        rows = cp.read_rows(spec.database)
    assert len(rows) == 1


def test_a_database_of_the_divergence_check_without_version_keys_resumes(tmp_path):
    """Written after the divergence check but before the version keys: score version 2
    (its divergence threshold is stored); a resume adds the keys and runs what is missing."""
    spec = _spec(tmp_path)
    _database_with_a_row(spec, drop_keys=("format", "schema_version", "score_version"))
    res = cp.run_campaign(spec, workers=0, progress=False)
    assert (res.total, res.skipped, res.ran) == (2, 1, 1)
    assert _meta(spec.database)["score_version"] == str(db.SCORE_VERSION)


def test_cli_refuses_a_foreign_database_with_one_line(tmp_path, capsys):
    from navsim.cli import main

    spec = _spec(tmp_path)
    con = sqlite3.connect(str(spec.database))
    con.execute("CREATE TABLE episodes (x INTEGER)")
    con.commit()
    con.close()
    assert main(["campaign", str(tmp_path / "camp.toml"), "--workers", "0", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "camp.sqlite: not a navsim campaign database" in err[0], err
