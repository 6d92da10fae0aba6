"""A sample of the bad-input battery (tools/bad_inputs.py; the whole battery takes minutes):
each case must end as a clear error, never a traceback, an accepted bad input or a lost file.

The sampled cases start one Python process each (a few seconds apiece), so they are marked
``slow``; the check of the battery's size and categories runs by default."""

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

SAMPLE = ("non-UTF-8 scenario file", "oscillation frequency_hz = 0", "2-point CSV track", "--chunk 0",
          "bench --out is a file", "bad --set keeps the previous output", "database of random bytes",
          "gym: action of shape (3,)")


def test_the_battery_has_the_issue_categories_and_at_least_80_cases():
    cases = bad_inputs.cases()
    assert len(cases) >= 80 and len({c.name for c in cases}) == len(cases)
    assert {c.category for c in cases} >= {"scenario file", "track file", "CLI argument", "output path", "campaign",
                                          "Python API / Gymnasium", "FMU parameter"}


@pytest.mark.slow
@pytest.mark.parametrize("name", SAMPLE)
def test_sampled_case_is_a_clear_error(name):
    case = next(c for c in bad_inputs.cases() if c.name == name)
    with tempfile.TemporaryDirectory() as tmp:
        result = bad_inputs.run_case(case, Path(tmp), {}, None)
    assert result["class"] == "clear-error", result
