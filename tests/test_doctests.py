"""The examples in the package's docstrings run: every module of navsim, navsim.envs and
navsim.fmu whose source holds a ``>>>`` example is imported and its doctests executed
(examples that cannot run here carry ``# doctest: +SKIP`` with the reason in the text)."""

from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"navsim": ROOT / "navsim", "navsim.envs": ROOT / "envs", "navsim.fmu": ROOT / "fmu"}


def _modules_with_examples() -> list[str]:
    names = []
    for package, folder in PACKAGES.items():
        for path in sorted(folder.rglob("*.py")):
            if ">>>" not in path.read_text(encoding="utf-8"):
                continue
            parts = path.relative_to(folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            names.append(".".join((package, *parts)))
    return names


MODULES = _modules_with_examples()


def test_the_examples_are_found():
    # the finder reads the sources: a module with examples cannot be left out silently
    assert "navsim.sensors.baro" in MODULES and "navsim.scenario" in MODULES and len(MODULES) >= 5


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_run(name):
    if name.startswith("navsim.envs"):
        pytest.importorskip("gymnasium")
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    tests = finder.find(module, name)  # each with a copy of the module globals
    assert tests, f"{name} has '>>>' in its source but no doctest was found"
    for test in tests:
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples of {name} failed (output above)"
