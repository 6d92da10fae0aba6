"""The bad-input battery (tools/bad_inputs.py): a sample of its cases in the default suite,
the whole battery under ``slow`` (minutes: one Python process per case).

Each sampled case runs as the battery runs it (a fresh process, its own folder) and must
end in the class the issue asks for: a clear error (exit 2 with one line, no traceback;
an API call raising navsim's error type), or, for a documented default, "warned" (exit 0
with one warning line); never a traceback, an accepted bad input or a lost file. The
sample takes one case or two of every category, among them the cases that were not clear
errors before this battery's last fixes (a 1e-9 s tick, a CSV without heights, an SQLite
file of another schema, a database scored before the divergence check). The FMU cases
need a built FMU: ``tests/fmu/test_bad_parameters.py`` runs one through this battery."""

from __future__ import annotations

import importlib.util
import sys
import tempfile
from pathlib import Path

import pytest

_SPEC = importlib.util.spec_from_file_location("bad_inputs", Path(__file__).parents[1] / "tools" / "bad_inputs.py")
bad_inputs = importlib.util.module_from_spec(_SPEC)
sys.modules.setdefault("bad_inputs", bad_inputs)  # dataclasses look their module up there
_SPEC.loader.exec_module(bad_inputs)

SAMPLE = {
    "non-UTF-8 scenario file": "clear-error",
    "timing.tick_s = 1e-9 (memory)": "clear-error",
    "CSV without a height column (0 m, warned)": "warned",
    "track doubling back": "clear-error",
    "--chunk 0": "clear-error",
    "bad --set keeps the previous output": "clear-error",
    "database with a foreign schema": "clear-error",
    "database scored before the divergence check": "clear-error",
    "gym: action of shape (3,)": "clear-error",
}


_BASES: dict = {}  # the bundled scenario's TOML, read once (one process) for the cases built on it


def _run(name: str) -> dict:
    case = next(c for c in bad_inputs.cases() if c.name == name)
    with tempfile.TemporaryDirectory() as tmp:
        return bad_inputs.run_case(case, Path(tmp), _BASES, None)


def test_the_battery_has_the_issue_categories_and_at_least_80_cases():
    cases = bad_inputs.cases()
    assert len(cases) >= 80 and len({c.name for c in cases}) == len(cases)
    assert {c.category for c in cases} >= {"scenario file", "track file", "CLI argument", "output path", "campaign",
                                          "Python API / Gymnasium", "FMU parameter"}
    assert {c.category for c in cases if c.name in SAMPLE} == {c.category for c in cases} - {"FMU parameter"}
    assert {c.name for c in cases if c.expect == "warning"} == {n for n, k in SAMPLE.items() if k == "warned"}


@pytest.mark.parametrize("name", list(SAMPLE))
def test_sampled_case_ends_in_its_class(name):
    result = _run(name)
    assert result["class"] == SAMPLE[name], result


def test_the_classes_are_told_apart():
    """The classifier itself: a traceback, an accepted bad input, a warning where none is
    documented and a changed previous output are each caught (cases built here)."""
    Case = bad_inputs.Case
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        raw = bad_inputs.run_case(Case("raw", "x", "py", "raise KeyError('boom')"), root, {}, None)
        ok = bad_inputs.run_case(Case("ok", "x", "cli", ["show", "paper-2012"]), root, {}, None)
        lost = bad_inputs.run_case(Case("lost", "x", "py", "open('p', 'w').write('new')\nsys.exit(2)",
                                        files={"p": "old"}, keep=("p",)), root, {}, None)
    assert (raw["class"], ok["class"], lost["class"]) == ("traceback", "accepted", "data-lost")


@pytest.mark.slow
def test_the_whole_battery_has_no_traceback_no_accepted_and_no_lost_file():
    out = bad_inputs.main_results(jobs=2)
    bad = [r for r in out if r["class"] not in ("clear-error", "warned", "skipped")]
    assert not bad, bad
