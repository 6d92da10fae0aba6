"""The estimator equality tests (step path = batch path) under both OpenBLAS kernel
families, whatever CPU the suite runs on.

OpenBLAS picks its kernels at run time from the CPU: fused multiply-add kernels
(``Haswell``, the default on AVX2 machines) or not (``Sandybridge``). Products of other
shapes or another summation order round differently under the two, so an equality that
holds on one CPU can fail on another (issue 16). Each case reruns the step/batch equality
tests of every estimator in a fresh interpreter with ``OPENBLAS_CORETYPE`` set, after
checking (threadpoolctl) that OpenBLAS really loaded that kernel.

NumPy likewise picks its own SIMD code for transcendental ufuncs on AVX-512 CPUs, where
``arctan2``, ``arcsin`` & co. then differ from the C library's by an ulp and the
step/batch comparisons of the attitude angles fall back to a tolerance
(``tests/tolerances.py``). On such a CPU the last case reruns those tests with NumPy's
AVX-512 dispatch switched off (``NPY_DISABLE_CPU_FEATURES``), where they must hold bit for
bit again, so both branches are exercised on every machine that has both.
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


NUMPY_AVX512 = "X86_V4 AVX512_ICL AVX512_SPR"  # NumPy 2.x's names of its AVX-512 targets
ELEMENTARY = (EQUALITY + " or step_equals_batch or wrap_is or kernel_equals or with_and_without_kernel")


def test_equalities_bit_for_bit_without_numpy_avx512():
    probe = "import sys; sys.path.insert(0, 'tests'); import tolerances; print(tolerances.numpy_matches_libm())"
    default = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120,
                             cwd=str(TESTS.parent))
    assert default.returncode == 0, default.stderr
    if default.stdout.strip() == "True":
        pytest.skip("NumPy's transcendental functions are the C library's here: the default run is bit for bit")
    env = dict(os.environ, NPY_DISABLE_CPU_FEATURES=NUMPY_AVX512, PYTHONHASHSEED="0")
    env.pop("PYTEST_XDIST_WORKER", None)
    env.pop("PYTEST_ADDOPTS", None)
    switched = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120,
                              cwd=str(TESTS.parent))
    assert switched.returncode == 0, switched.stderr
    if switched.stdout.strip() != "True":
        pytest.skip(f"NumPy's functions differ from the C library's even without AVX-512 ({NUMPY_AVX512!r} off)")
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-k", ELEMENTARY, str(TESTS / "estimators"),
         str(TESTS / "test_truthgen_kernel.py"), str(TESTS / "test_naverror_context.py")],
        env=env, capture_output=True, text=True, timeout=1200, cwd=str(TESTS.parent))
    tail = "\n".join(run.stdout.splitlines()[-30:])
    assert run.returncode == 0, f"equality tests fail with NumPy's AVX-512 code off:\n{tail}\n{run.stderr[-2000:]}"
    assert " passed" in tail and " failed" not in tail, tail
