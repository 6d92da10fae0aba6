"""The SSP archive of the pair (`navsim fmu ssp`): every connection and the parameters in
SystemStructure.ssd, loaded by libcosim and by ECOS, equal to run_episode lagged by one
step (both tools step Jacobi-style; bit for bit, as in test_libcosimpy.py)."""

from __future__ import annotations

import zipfile
from xml.etree import ElementTree

import numpy as np
import pytest

from navsim import estimators
from navsim.episode import run_episode

SEED = 3
NS = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
      "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues"}


@pytest.fixture(scope="module")
def ssp(fmu_dir, scenario):
    pytest.importorskip("pythonfmu")
    from navsim.fmu.cli import main

    path = fmu_dir / "pair.ssp"
    assert main(["fmu", "ssp", "paper-2012", "-o", str(path), "--estimator", "lc-ekf", "--seed", str(SEED),
                 "--set", "timing.duration_s=6", "--set", "outages.windows_s=[[2.0, 4.0]]"]) == 0
    return path


def _lagged_reference(scenario):
    ref = run_episode(scenario, estimators.make("lc-ekf"), seed=SEED, use_batch=False)
    return np.column_stack([ref.est_lat, ref.est_lon, ref.est_h, ref.est_velocity_n, ref.est_hpr, ref.t])


def test_system_structure_has_every_connection_and_the_parameters(ssp, scenario):
    from fmpy import read_model_description

    with zipfile.ZipFile(ssp) as z:
        assert set(z.namelist()) == {"SystemStructure.ssd", "resources/plant.fmu", "resources/estimator.fmu"}
        root = ElementTree.fromstring(z.read("SystemStructure.ssd"))
        folder = ssp.parent / "pair_unzipped"
        z.extractall(folder)
    est_inputs = {v.name for v in read_model_description(str(folder / "resources/estimator.fmu")).modelVariables
                  if v.causality == "input"}
    plant_outputs = {v.name for v in read_model_description(str(folder / "resources/plant.fmu")).modelVariables
                     if v.causality == "output"}
    conns = root.findall("ssd:System/ssd:Connections/ssd:Connection", NS)
    pairs = {(c.get("startElement"), c.get("startConnector"), c.get("endElement"), c.get("endConnector"))
             for c in conns}
    assert len(pairs) == len(conns) == len(est_inputs) > 280
    assert pairs == {("plant", n, "estimator", n) for n in est_inputs}
    assert est_inputs <= plant_outputs and {"time.step", "time.t_s"} <= est_inputs
    params = {}
    for comp in root.findall("ssd:System/ssd:Elements/ssd:Component", NS):
        for p in comp.findall(".//ssv:Parameter", NS):
            params[(comp.get("name"), p.get("name"))] = next(iter(p)).get("value")
        connectors = {c.get("name") for c in comp.findall("ssd:Connectors/ssd:Connector", NS)}
        assert est_inputs <= connectors, comp.get("name")  # both ends of every connection declared
    assert params[("plant", "seed")] == str(SEED)
    assert params[("estimator", "estimator.name")] == "lc-ekf"
    assert params[("plant", "imu.preset")] == scenario.imu.preset
    stop = root.find("ssd:DefaultExperiment", NS).get("stopTime")
    assert float(stop) == scenario.timing.duration_s


def test_ssp_under_libcosim_equals_run_episode_lagged(ssp, scenario):
    pytest.importorskip("libcosimpy")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    from test_libcosimpy import NAV, _quiet

    _quiet()
    n, dt = scenario.timing.steps, scenario.timing.nav_period_s
    ex = CosimExecution.from_ssp_file(str(ssp), step_size=int(round(dt * 1e9)))  # step size in ns
    assert ex.num_slaves() == 2
    idx = ex.slave_index_from_instance_name("estimator")
    ref = {v.name.decode(): v.reference for v in ex.slave_variables(idx)}
    observer = CosimObserver.create_last_value()
    ex.add_observer(observer)
    rows, steps = [], []
    for _ in range(n):
        assert ex.step(1)
        rows.append(observer.last_real_values(idx, [ref[k] for k in NAV]))
        steps.append(observer.last_integer_values(idx, [ref["nav.step"]])[0])
    np.testing.assert_array_equal(steps, np.arange(n))  # Jacobi: one step behind
    np.testing.assert_array_equal(np.array(rows)[1:], _lagged_reference(scenario)[:n - 1])


def test_ssp_under_ecos_equals_run_episode_lagged(ssp, scenario):
    from test_ecos import check_lagged, run_ecos

    n = scenario.timing.steps
    check_lagged(run_ecos("ssp", ssp, "-", "-", steps=n), scenario, n)
