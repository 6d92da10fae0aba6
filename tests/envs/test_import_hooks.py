"""Registration on import and the lazy navsim.evaluate, checked in fresh interpreters."""

import subprocess
import sys


def run(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout


def test_core_import_does_not_import_gymnasium():
    assert run("import sys, navsim, navsim.simulator, navsim.episode; print('gymnasium' in sys.modules)").strip() == "False"


def test_ids_registered_when_gymnasium_came_first():
    out = run("import gymnasium as gym, navsim; print('navsim/PaperRail-v0' in gym.registry)")
    assert out.strip() == "True"


def test_evaluate_is_reexported_lazily():
    out = run("import navsim; print(navsim.evaluate.__module__)")
    assert out.strip() == "navsim.envs.agent"
