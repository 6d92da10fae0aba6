"""A non-Python host: a small C program (tests/fmu/c_host/host.c, compiled with gcc
against the FMI 2 headers fmpy ships) runs the plant FMU in a process with no Python of
its own, with the documented recipe (`navsim fmu host-env`: LD_PRELOAD the shared
libpython, PYTHONHOME, PYTHONPATH). It must print the core's numbers and exit with code
0: no crash at exit (the Py_Finalize use-after-free of navsim.fmu.runtime), and it works
with this checkout's editable install (the FMU processes the .pth files of PYTHONPATH).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")

from navsim.simulator import Simulator  # noqa: E402

HERE = Path(__file__).parent


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.skip("gcc is needed to compile the C host")
    headers = Path(fmpy.__file__).parent / "c-code"
    exe = tmp_path_factory.mktemp("c_host") / "host"
    subprocess.run([gcc, "-O1", "-Wall", "-Werror", f"-I{headers}", str(HERE / "c_host" / "host.c"), "-o", str(exe),
                    "-ldl"], check=True, capture_output=True)
    return exe


@pytest.fixture(scope="module")
def host_env():
    from navsim.errors import ConfigError
    from navsim.fmu.build import host_environment

    try:
        extra = host_environment()
    except ConfigError as exc:
        pytest.skip(f"no shared libpython for a non-Python host: {exc}")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV", "LD_PRELOAD"))}
    return {**env, **extra}


def _extract(fmu: Path, folder: Path):
    from fmpy import read_model_description

    with zipfile.ZipFile(fmu) as z:
        z.extractall(folder)
    md = read_model_description(str(folder))
    return md, {v.name: v.valueReference for v in md.modelVariables}


def run_host(host, env, fmu, folder, steps, *extra):
    md, vr = _extract(fmu, folder)
    args = [str(host), str(folder), md.guid, md.coSimulation.modelIdentifier, str(steps), "0.01", str(vr["seed"]),
            str(vr["truth.s_m"]), *extra]
    return subprocess.run(args, env=env, capture_output=True, text=True, timeout=300)


def test_c_host_runs_the_plant_and_exits_cleanly(host, host_env, plant2, scenario, tmp_path):
    out = run_host(host, host_env, plant2, tmp_path / "plant", 50)
    assert out.returncode == 0, f"exit code {out.returncode}: {out.stderr[-3000:]}"
    rows = np.array([[float(x) for x in line.split()] for line in out.stdout.splitlines()])
    sim = Simulator(scenario)
    sim.reset(7)  # the host sets seed = 7
    chunk = sim.advance(50)
    np.testing.assert_array_equal(rows[:, 1], chunk.truth.s)  # the values the core computes, bit for bit
    np.testing.assert_allclose(rows[:, 0], chunk.t, rtol=0, atol=1e-15)  # the host's k*h in double


def test_c_host_misuse_gives_error_statuses(host, host_env, plant2, tmp_path):
    """The same host makes the calls FMI forbids (navsim.fmu.guard): a parameter after
    initialisation, a second exitInitializationMode, doStep after terminate (each
    fmi2Error with a log line) and freeInstance twice (refused): exit code 0."""
    with zipfile.ZipFile(plant2) as z:
        if not json.loads(z.read("resources/navsim_fmu.json")).get("guard"):
            pytest.skip("the FMU was built without the C guard (no gcc or no FMI headers)")
    out = run_host(host, host_env, plant2, tmp_path / "plant", 3, "misuse")
    assert out.returncode == 0, f"exit code {out.returncode}: {out.stderr[-3000:]}"
    assert "misuse set-parameter 3 exit-init-again 3 terminate 0 step-after-terminate 3" in out.stdout
    assert "freed twice" in out.stdout
    for text in ("is a parameter; parameters cannot be set after initialisation",
                 "fmi2ExitInitializationMode refused in state 'step mode'",
                 "fmi2DoStep refused in state 'terminated'", "fmi2FreeInstance called after freeInstance; refused"):
        assert text in out.stderr, text


@pytest.mark.slow  # builds a wheel and installs it with numpy and scipy into a new venv: about 2 min
def test_c_host_with_a_wheel_install(host, plant2, scenario, tmp_path):
    """The same C host and recipe with navsim installed from a wheel (``pip wheel
    --no-deps`` of this checkout) into a fresh venv with its dependencies (numpy, scipy,
    ... from the wheel's metadata, and pythonfmu, whose module the FMU's slave class
    subclasses), the recipe printed by that venv's own ``navsim fmu host-env``: the core's
    numbers and exit code 0, as with the editable install above."""
    import sys
    import venv

    root = HERE.parent.parent
    src = tmp_path / "src"  # a copy: setuptools builds in the source tree, and a stale build/ would leak in
    shutil.copytree(root, src, ignore=shutil.ignore_patterns(".git", ".venv*", "build", "dist", "*.egg-info",
                                                            "__pycache__", ".pytest_cache", "out"))
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(wheels), str(src)],
                   check=True, capture_output=True, timeout=600)
    (wheel,) = wheels.glob("navsim_track-*.whl")
    fresh = tmp_path / "fresh"
    venv.create(fresh, with_pip=True)
    py = fresh / "bin" / "python"
    subprocess.run([str(py), "-m", "pip", "install", "-q", str(wheel), "pythonfmu"], check=True,
                   capture_output=True, timeout=1200)
    out = subprocess.run([str(fresh / "bin" / "navsim"), "fmu", "host-env"], capture_output=True, text=True,
                         check=True, env={k: v for k, v in os.environ.items() if not k.startswith("PYTHON")})
    recipe = dict(line.removeprefix("export ").split("=", 1) for line in out.stdout.splitlines())
    assert set(recipe) == {"LD_PRELOAD", "PYTHONHOME", "PYTHONPATH"}
    site = Path(recipe["PYTHONPATH"])
    assert site.is_relative_to(fresh) and (site / "navsim" / "fmu" / "runtime.py").is_file()
    assert not list(site.glob("__editable__*"))  # a regular install: the package files themselves
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV", "LD_PRELOAD"))}
    out = run_host(host, {**env, **recipe}, plant2, tmp_path / "plant", 50)
    assert out.returncode == 0, f"exit code {out.returncode}: {out.stderr[-3000:]}"
    rows = np.array([[float(x) for x in line.split()] for line in out.stdout.splitlines()])
    sim = Simulator(scenario)
    sim.reset(7)  # the host sets seed = 7
    np.testing.assert_array_equal(rows[:, 1], sim.advance(50).truth.s)
