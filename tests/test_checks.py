"""Static checks of the package as part of the test command: ruff (rules and line length in
pyproject.toml, [tool.ruff]) on navsim, envs and fmu, and mypy (configuration and its
documented per-module exceptions in pyproject.toml, [tool.mypy]) on the core package."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _tool(name: str) -> list[str]:
    exe = Path(sys.executable).with_name(name)
    if exe.exists():
        return [str(exe)]
    found = shutil.which(name)
    if found is None:
        pytest.skip(f"{name} is not installed (it is in the 'test' extra)")
    return [found]


def test_ruff_is_clean_on_the_package():
    out = subprocess.run([*_tool("ruff"), "check", "--no-cache", "navsim", "envs", "fmu"], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr


def test_mypy_passes_on_the_core_package(tmp_path):
    out = subprocess.run([*_tool("mypy"), "--cache-dir", str(tmp_path / "mypy_cache")], cwd=ROOT,
                         capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "Success" in out.stdout
