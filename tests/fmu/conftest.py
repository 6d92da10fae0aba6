"""Shared fixtures: one build per FMU kind and FMI version per test session."""

from __future__ import annotations

import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest

HERE = Path(__file__).parent


def short_scenario():
    from navsim.scenario import load_scenario

    return load_scenario("paper-2012").with_overrides(
        {"timing": {"duration_s": 6.0}, "outages": {"windows_s": [[2.0, 4.0]]}})


@pytest.fixture(scope="session")
def scenario():
    return short_scenario()


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fmus")


def _build(fmu_dir, scenario, what, fmi, **kw):
    pytest.importorskip("pythonfmu" if fmi == 2 else "pythonfmu3")
    from navsim.fmu.build import build_fmu

    return build_fmu(scenario, what, fmi, fmu_dir / f"{what}{fmi}.fmu", **kw)


@pytest.fixture(scope="session")
def plant2(fmu_dir, scenario):
    return _build(fmu_dir, scenario, "plant", 2)


@pytest.fixture(scope="session")
def plant3(fmu_dir, scenario):
    return _build(fmu_dir, scenario, "plant", 3)


@pytest.fixture(scope="session")
def estimator2(fmu_dir, scenario):
    return _build(fmu_dir, scenario, "estimator", 2, estimator="lc-ekf")


@pytest.fixture(scope="session")
def estimator3(fmu_dir, scenario):
    return _build(fmu_dir, scenario, "estimator", 3, estimator="lc-ekf")


@pytest.fixture(scope="session")
def train_fmu(tmp_path_factory):
    """The C train-dynamics FMU of train_fmu/, compiled with gcc."""
    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.skip("gcc is needed to compile the test's C FMU")
    fmpy = pytest.importorskip("fmpy")
    headers = Path(fmpy.__file__).parent / "c-code"
    out = tmp_path_factory.mktemp("train")
    lib = out / "TrainModel.so"
    subprocess.run([gcc, "-O2", "-shared", "-fPIC", f"-I{headers}", str(HERE / "train_fmu" / "train.c"),
                    "-o", str(lib), "-lm"], check=True, capture_output=True)
    path = out / "train.fmu"
    with zipfile.ZipFile(path, "w") as z:
        z.write(HERE / "train_fmu" / "modelDescription.xml", "modelDescription.xml")
        z.write(lib, "binaries/linux64/TrainModel.so")
    return path
