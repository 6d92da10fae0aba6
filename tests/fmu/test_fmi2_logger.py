"""FMI 2 log messages reach the instance that sent them, whatever was freed before.

fmpy's native logger proxy (``fmpy.logging.addLoggerProxy``, which formats the printf
arguments of an FMI 2 logger call) keeps the Python logger in one static variable that
every ``addLoggerProxy`` call overwrites. With one Python callback per instance, each
instance logged into the newest instance's log, and after that instance (or a finished
``fmpy.simulate_fmu``) was garbage-collected the next message called a freed ctypes
thunk: SIGSEGV, or a corrupted heap found at the process's exit ("corrupted
double-linked list", exit code 139) after every test had passed. The second test runs
in a subprocess because that crash takes the process with it.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

pytest.importorskip("fmpy")

from navsim.fmu.master import FmuCallError, FmuInstance  # noqa: E402


def test_each_instance_keeps_its_own_messages(plant2):
    a = FmuInstance(plant2, "a")
    b = FmuInstance(plant2, "b")
    try:
        a.initialize({"seed": 0})
        b.initialize({"seed": 0})
        seen_a, seen_b = len(a.log), len(b.log)
        with pytest.raises(FmuCallError, match="not a whole number"):
            a.do_step(0.0, 0.015)
        assert any("not a whole number" in m for _, m in a.log[seen_a:]), a.log
        assert len(b.log) == seen_b, b.log  # before: a's messages landed in b's log
        assert any("scenario" in m for _, m in a.log[:seen_a]) and any("scenario" in m for _, m in b.log[:seen_b])
    finally:
        a.free()
        b.free()


def test_logging_after_newer_instances_and_simulate_fmu_are_gone(plant2):
    script = textwrap.dedent(f"""
        import gc, sys
        import fmpy
        from navsim.fmu.master import FmuCallError, FmuInstance
        path = {str(plant2)!r}
        a = FmuInstance(path, "a")
        a.initialize({{"seed": 0}})
        b = FmuInstance(path, "b")
        b.free()
        del b
        fmpy.simulate_fmu(path, stop_time=0.05, step_size=0.01, output=["time.step"])  # fmpy's own logger
        gc.collect()
        for _ in range(3):
            seen = len(a.log)
            try:
                a.do_step(0.0, 0.015)
            except FmuCallError:
                pass
            assert any("not a whole number" in m for _, m in a.log[seen:]), a.log
        a.free()
        print("ok")
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0 and out.stdout.strip().endswith("ok"), (out.returncode, out.stdout[-1000:], out.stderr[-3000:])
