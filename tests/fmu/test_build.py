"""Built FMUs: fmpy validation, a complete ModelStructure, embedded scenario."""

from __future__ import annotations

import json
import zipfile
import xml.etree.ElementTree as ET

import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy.validation import validate_fmu  # noqa: E402


@pytest.mark.parametrize("name", ["plant2", "plant3", "estimator2", "estimator3"])
def test_fmpy_validate_reports_no_problem(name, request):
    path = request.getfixturevalue(name)
    assert validate_fmu(str(path)) == []


def _md(path):
    with zipfile.ZipFile(path) as z:
        return ET.fromstring(z.read("modelDescription.xml")), z.namelist(), z


def test_fmi2_model_structure_lists_outputs_and_initial_unknowns(plant2):
    root, names, _ = _md(plant2)
    svs = root.find("ModelVariables").findall("ScalarVariable")
    outputs = {i + 1 for i, v in enumerate(svs) if v.get("causality") == "output"}
    calculated = {i + 1 for i, v in enumerate(svs) if v.get("initial") == "calculated"}
    ms = root.find("ModelStructure")
    assert {int(u.get("index")) for u in ms.find("Outputs")} == outputs
    assert {int(u.get("index")) for u in ms.find("InitialUnknowns")} == calculated
    assert calculated >= outputs and len(calculated) > len(outputs)  # + version / config hash
    # value references are the scalar indices (pythonfmu's convention) and every unit is defined
    assert [int(v.get("valueReference")) for v in svs] == list(range(len(svs)))
    units = {u.get("name") for u in root.find("UnitDefinitions")}
    assert {e.get("unit") for v in svs for e in v if e.get("unit")} <= units


def test_fmi3_arrays_and_structure(plant3, scenario):
    from navsim.simulator import Simulator

    root, names, _ = _md(plant3)
    mv = root.find("ModelVariables")
    by_name = {v.get("name"): v for v in mv}
    n_sat = len(Simulator(scenario).constellation.prn)
    pr = by_name["gnss.pseudorange_m"]
    assert pr.tag == "Float64" and [d.get("start") for d in pr.findall("Dimension")] == [str(n_sat)]
    assert [d.get("start") for d in by_name["gnss.sat_pos_e"].findall("Dimension")] == [str(n_sat), "3"]
    assert by_name["time"].get("causality") == "independent"
    outs = {v.get("valueReference") for v in mv if v.get("causality") == "output"}
    assert {e.get("valueReference") for e in root.find("ModelStructure").findall("Output")} == outs


def test_archive_contents(plant2, estimator3, scenario):
    for path, kind, fmi in ((plant2, "plant", 2), (estimator3, "estimator", 3)):
        with zipfile.ZipFile(path) as z:
            names = set(z.namelist())
            meta = json.loads(z.read("resources/navsim_fmu.json"))
            module = z.read("resources/slavemodule.txt").decode()
            assert f"resources/{module}.py" in names
            assert "resources/navsim_scenario.toml" in names and "documentation/index.html" in names
            assert any(n.startswith("binaries/") and n.endswith(".so") for n in names)
        assert meta["kind"] == kind and meta["fmi"] == fmi and meta["config_hash"] == scenario.config_hash()


def test_build_rejects_bad_arguments(tmp_path, scenario):
    from navsim.errors import ConfigError
    from navsim.fmu.build import build_fmu

    with pytest.raises(ConfigError, match="--what"):
        build_fmu(scenario, "controller", 2, tmp_path / "x.fmu")
    with pytest.raises(ConfigError, match="--fmi"):
        build_fmu(scenario, "plant", 1, tmp_path / "x.fmu")
    with pytest.raises(ConfigError, match="--estimator"):
        build_fmu(scenario, "estimator", 2, tmp_path / "x.fmu", estimator="no-such-filter")
