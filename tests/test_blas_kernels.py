"""The estimator equality tests (step path = batch path) under both OpenBLAS kernel
families, whatever CPU the suite runs on.

OpenBLAS picks its kernels at run time from the CPU: fused multiply-add kernels
(``Haswell``, the default on AVX2 machines) or not (``Sandybridge``). Products of other
shapes or another summation order round differently under the two, so an equality that
holds on one CPU can fail on another (issue 16). Each case reruns the step/batch equality
tests of every estimator in a fresh interpreter with ``OPENBLAS_CORETYPE`` set, after
checking (threadpoolctl) that OpenBLAS really loaded that kernel.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
EQUALITY = "batch_equals_step or equals_repeated_step or step_equals_step_batch"
KERNELS = {"Haswell": {"avx2", "fma"}, "Sandybridge": {"avx"}}


def _cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text(encoding="ascii", errors="replace")
    except OSError:
        return set()
    for line in text.splitlines():
        if line.startswith("flags"):
            return set(line.split(":", 1)[1].split())
    return set()


def _child_env(kernel: str) -> dict:
    env = dict(os.environ, OPENBLAS_CORETYPE=kernel, PYTHONHASHSEED="0")
    env.pop("PYTEST_XDIST_WORKER", None)
    env.pop("PYTEST_ADDOPTS", None)
    return env


@pytest.mark.parametrize("kernel", sorted(KERNELS))
def test_estimator_equalities_hold_under_kernel(kernel):
    if platform.machine().lower() not in ("x86_64", "amd64"):
        pytest.skip("OpenBLAS x86 kernel families only")
    missing = KERNELS[kernel] - _cpu_flags()
    if missing:
        pytest.skip(f"this CPU lacks {sorted(missing)} for the {kernel} kernels")
    probe = subprocess.run(
        [sys.executable, "-c", "import numpy, threadpoolctl; print([i.get('architecture') for i in "
                               "threadpoolctl.threadpool_info() if i.get('internal_api') == 'openblas'])"],
        env=_child_env(kernel), capture_output=True, text=True, timeout=120)
    assert probe.returncode == 0, probe.stderr
    if probe.stdout.strip() == "[]":
        pytest.skip("numpy is not linked against OpenBLAS")
    assert kernel.lower() in probe.stdout.lower(), probe.stdout
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-k", EQUALITY, str(TESTS / "estimators")],
        env=_child_env(kernel), capture_output=True, text=True, timeout=1200, cwd=str(TESTS.parent))
    tail = "\n".join(run.stdout.splitlines()[-30:])
    assert run.returncode == 0, f"equality tests fail under OPENBLAS_CORETYPE={kernel}:\n{tail}\n{run.stderr[-2000:]}"
    assert " passed" in tail and " failed" not in tail, tail
