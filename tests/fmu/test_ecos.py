"""A third importer: ECOS (the ``ecospy`` package, optional: ``pip install
'navsim-track[ecos]'``) runs plant + estimator connected by name, in both orders of
adding the models.

ECOS's fixed-step algorithm is a Jacobi master, so the estimator's solution after the
step ending at (k+1)*dt is run_episode's of step k-1 (``nav.lag_steps`` = 1), bit for bit
(the estimator's ``step`` runs on the very float64 values run_episode(use_batch=False)
feeds it). ECOS runs in a subprocess (tests/fmu/ecos_pair.py) whose exit code is checked:
0, no crash at free or at exit.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from navsim import estimators
from navsim.episode import run_episode

SEED = 3
HERE = Path(__file__).parent


def ecos_or_skip() -> None:
    """Skip, with the reason, when ecospy or its native libraries are missing."""
    out = subprocess.run([sys.executable, "-c", "import ecospy"], capture_output=True, text=True, timeout=120)
    if out.returncode:
        last = (out.stderr.strip().splitlines() or ["?"])[-1]
        if "No module named 'ecospy'" in last:
            pytest.skip("ecospy is not installed (optional: pip install 'navsim-track[ecos]')")
        pytest.skip(f"ECOS's native library does not load: {last} (on Debian: apt-get install libtbb12)")


def run_ecos(*args, steps: int) -> dict:
    ecos_or_skip()
    out = subprocess.run([sys.executable, str(HERE / "ecos_pair.py"), *map(str, args), str(steps), str(SEED)],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, f"ECOS host exit code {out.returncode}: {out.stderr[-2000:]}"
    return json.loads(out.stdout.strip().splitlines()[-1])


def check_lagged(result: dict, scenario, n: int) -> None:
    ref = run_episode(scenario, estimators.make("lc-ekf"), seed=SEED, use_batch=False)
    want = np.column_stack([ref.est_lat, ref.est_lon, ref.est_h, ref.est_velocity_n, ref.est_hpr, ref.t])
    rows, counters = np.array(result["rows"]), np.array(result["counters"])
    np.testing.assert_array_equal(counters[:, 0], np.arange(n))  # Jacobi: one step behind
    np.testing.assert_array_equal(counters[:, 1], np.ones(n))
    np.testing.assert_array_equal(rows[1:], want[:n - 1])  # bit for bit (module docstring)


@pytest.mark.parametrize("order", ["plant-first", "estimator-first"])
def test_plant_and_estimator_under_ecos_equal_run_episode_lagged(order, plant2, estimator2, scenario):
    n = scenario.timing.steps
    result = run_ecos("structure", plant2, estimator2, order, steps=n)
    assert result["connections"] > 280
    check_lagged(result, scenario, n)
