"""Freeing FMU instances that failed (a Fatal status) leaves the host's heap intact.

pythonfmu's shims (pythonfmu 0.7, pythonfmu3 0.3.4) release their references to the
slave class, instance and log queue when they report Fatal (``handle_py_exception`` ->
``cleanPyObject``) and again in the instance's destructor at ``freeInstance``. A Python
host that freed two or more failed instances (``tests/fmu/test_robustness.py`` does,
with bad parameters) then had objects freed while still referenced, and crashed at exit
in the final garbage collection (SIGSEGV, exit code 139, or "corrupted double-linked
list", exit code 134), after every test had passed. The minimal reproduction (then
with a negative seed, Fatal before the guard answered bad parameters with an error;
here with an output variable set, still Fatal) crashed in 5 of 5 runs for FMI 2 and
for FMI 3 before the fix (navsim's C guard and
``FmuInstance.free`` no longer hand a failed instance to the shim's ``freeInstance``).
It runs in a subprocess: the crash takes the process with it, at its exit.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

pytest.importorskip("fmpy")

from test_lifecycle import _guarded  # noqa: E402

#: instantiate, fail with a Fatal status (setting an output variable: pythonfmu turns the
#: Python error into Fatal), free; three times per path
REPRO = """
import ctypes
from navsim.fmu.master import FmuCallError, FmuInstance

def fail(path, name):
    inst = FmuInstance(path, name)
    try:
        inst.set({{"truth.s_m": 1.0}})
    except FmuCallError as exc:
        assert "(fatal)" in str(exc), exc
    else:
        raise AssertionError("an output variable was set")
    return inst

for path, fmi in {fmus!r}:
    for i in range(3):  # through FmuInstance.free (it keeps a failed instance)
        fail(path, "a%d" % i).free()
    for i in range(3):  # through the FMU's own freeInstance, as another host calls it
        inst = fail(path, "b%d" % i)
        getattr(inst.fmu.dll, "fmi%dFreeInstance" % fmi)(ctypes.c_void_p(inst.fmu.component))
        inst.free()
    with FmuInstance(path, "ok") as ok:  # the FMU still works
        ok.initialize({{"seed": 1}})
        ok.do_step(0.0, 0.01)
        assert ok.get(["time.step"])["time.step"] == 1
print("alive")
"""


def _run(fmus) -> subprocess.CompletedProcess:
    code = textwrap.dedent(REPRO.format(fmus=[(str(p), fmi) for p, fmi in fmus]))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)


def _guarded_plants(request):
    fmus = [(request.getfixturevalue(f"plant{fmi}"), fmi) for fmi in (2, 3)]
    if not all(_guarded(p) for p, _ in fmus):
        pytest.skip("the FMUs are built without the C guard here (no gcc or no FMI headers)")
    return fmus


def test_freeing_failed_instances_exits_cleanly(request):
    out = _run(_guarded_plants(request))
    assert out.returncode == 0 and "alive" in out.stdout, (out.returncode, out.stderr[-2000:])


@pytest.mark.slow
def test_freeing_failed_instances_exits_cleanly_repeated(request):
    """Five more runs (the crash depended on the heap layout, not on timing)."""
    fmus = _guarded_plants(request)
    codes = [_run(fmus).returncode for _ in range(5)]
    assert codes == [0] * 5, codes


@pytest.mark.slow
@pytest.mark.parametrize("fmi", [2, 3])
def test_failed_instances_of_an_unguarded_fmu(fmi, scenario, tmp_path):
    """Without the C guard, FmuInstance.free alone keeps the shim from the double release
    (the raw-freeInstance half of the reproduction would still crash: not run here)."""
    pytest.importorskip("pythonfmu" if fmi == 2 else "pythonfmu3")
    from navsim.fmu.build import build_fmu

    path = build_fmu(scenario, "plant", fmi, tmp_path / f"bare{fmi}.fmu", guarded=False)
    assert not _guarded(path)
    code = textwrap.dedent(f"""
        from navsim.fmu.master import FmuCallError, FmuInstance
        for i in range(4):
            inst = FmuInstance({str(path)!r}, "p%d" % i)
            try:
                inst.set({{"truth.s_m": 1.0}})
            except FmuCallError:
                pass
            inst.free()
        print("alive")
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0 and "alive" in out.stdout, (out.returncode, out.stderr[-2000:])
