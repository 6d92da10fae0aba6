"""FMU lifecycle misuse (the C guard of navsim.fmu.guard in front of pythonfmu's shim):
calls out of order, a parameter after initialisation, a second exitInitializationMode, a
start time other than 0 and a second freeInstance give an error status and a log line,
and the instance stays usable where FMI allows it (error, not fatal). Before the guard:
a double free aborted (FMI 2) or crashed (FMI 3), a parameter after initialisation was
fatal and a second exitInitializationMode silently restarted the episode."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import zipfile

import pytest

pytest.importorskip("fmpy")

from navsim.fmu.master import FmuCallError, FmuInstance  # noqa: E402


def _guarded(path) -> bool:
    with zipfile.ZipFile(path) as z:
        return json.loads(z.read("resources/navsim_fmu.json")).get("guard", False)


@pytest.fixture(params=[2, 3])
def plant(request):
    import shutil

    from navsim.fmu.guard import headers_dir

    if shutil.which("gcc") is None or headers_dir() is None:
        pytest.skip("the FMU is built without the C guard here: no gcc or no FMI headers (fmpy)")
    path = request.getfixturevalue(f"plant{request.param}")
    assert _guarded(path)
    return path


def _messages(inst, seen):
    return " | ".join(m for _, m in inst.log[seen:])


def test_out_of_order_calls_parameters_and_start_time(plant):
    with FmuInstance(plant, "p") as inst:
        seen = len(inst.log)
        with pytest.raises(FmuCallError, match=r"\(error\).*refused in state 'instantiated'"):
            inst.do_step(0.0, 0.01)  # before initialisation
        with pytest.raises(FmuCallError, match=r"\(error\).*start time 5 s refused"):
            inst.initialize({"seed": 1}, start_time=5.0)
        assert "start time 5 s refused" in _messages(inst, seen)
    with FmuInstance(plant, "p") as inst:
        inst.initialize({"seed": 1})
        inst.do_step(0.0, 0.01)
        seen = len(inst.log)
        with pytest.raises(FmuCallError, match=r"\(error\).*is a parameter; parameters cannot be set after"):
            inst.set({"seed": 5})
        assert "is a parameter" in _messages(inst, seen)
        with pytest.raises(FmuCallError, match=r"\(error\).*ExitInitializationMode refused in state 'step mode'"):
            inst._call("exitInitializationMode", inst.fmu.exitInitializationMode)
        inst.do_step(0.01, 0.01)  # still usable, and not restarted: the episode goes on from 0.02 s
        assert inst.get(["time.step"])["time.step"] == 2
        inst.terminate()
        inst.terminate()  # a second terminate does nothing
        with pytest.raises(FmuCallError, match=r"\(error\).*refused in state 'terminated'"):
            inst.do_step(0.02, 0.01)
        inst.reset()  # reset: a new episode with new parameters
        inst.initialize({"seed": 2})
        inst.do_step(0.0, 0.01)
        assert inst.get(["time.step"])["time.step"] == 1


def test_freeing_twice_is_refused_not_a_crash(plant):
    """In a subprocess (a double free would abort it): free twice through the FMI
    function, then call doStep on the freed instance; exit code 0 and a line each."""
    fmi = 2 if "plant2" in str(plant) else 3
    code = textwrap.dedent(f"""
        import ctypes
        from navsim.fmu.master import FmuInstance
        inst = FmuInstance({str(plant)!r}, "p")
        inst.initialize({{"seed": 1}})
        inst.do_step(0.0, 0.01)
        dll, c = inst.fmu.dll, ctypes.c_void_p(inst.fmu.component)
        free = getattr(dll, "fmi{fmi}FreeInstance")
        free(c)
        free(c)  # the second free
        step = getattr(dll, "fmi{fmi}DoStep")
        if {fmi} == 2:
            status = step(c, ctypes.c_double(0.01), ctypes.c_double(0.01), ctypes.c_int(1))
        else:
            b, d = ctypes.c_bool(), ctypes.c_double()
            status = step(c, ctypes.c_double(0.01), ctypes.c_double(0.01), ctypes.c_bool(True), ctypes.byref(b),
                          ctypes.byref(b), ctypes.byref(b), ctypes.byref(d))
        print("status", status)
        inst.free()  # fmpy frees again and unloads the library
        print("alive")
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0 and "alive" in out.stdout, (out.returncode, out.stderr[-2000:])
    assert "status 3" in out.stdout  # fmi2Error / fmi3Error
    assert out.stderr.count("called after freeInstance; refused") == 3, out.stderr[-2000:]
