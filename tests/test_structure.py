"""The layering the design promises, checked on the installed package.

Each check runs in a fresh interpreter (``python -c``), so what another test imported
earlier cannot hide an import.
"""

from __future__ import annotations

import json
import subprocess
import sys

# The truth side: what knows the true motion or the sensors' drawn errors.
TRUTH_SIDE = ("navsim.simulator", "navsim.truthgen", "navsim.motion", "navsim.sensors", "navsim.scenario")

ESTIMATOR_MODULES = (
    "navsim.estimators", "navsim.estimators.base", "navsim.estimators._inserror", "navsim.estimators.loosely",
    "navsim.estimators.tightly", "navsim.estimators.along_track", "navsim.estimators.gnss_only",
    "navsim.estimators.ins_only", "navsim.estimators.paper_ekf", "navsim.types", "navsim.receiver",
)


def _modules_after_import(names: tuple[str, ...]) -> list[str]:
    code = ("import importlib, json, sys\n"
            f"for name in {list(names)!r}:\n    importlib.import_module(name)\n"
            "print(json.dumps(sorted(sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_estimators_import_nothing_from_the_truth_side():
    loaded = _modules_after_import(ESTIMATOR_MODULES)
    assert "navsim.estimators.loosely" in loaded  # the import above did run
    leaked = [m for m in loaded if any(m == t or m.startswith(t + ".") for t in TRUTH_SIDE)]
    assert leaked == [], f"estimator modules pull in the truth side: {leaked}"


def test_prior_and_estimate_are_one_type_importable_by_their_old_names():
    from navsim import types
    from navsim.estimators.base import Estimate
    from navsim.simulator import Prior

    assert Prior is Estimate is types.NavSolution
