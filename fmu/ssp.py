"""An SSP (System Structure and Parameterization, SSP 1.0) archive of the plant + estimator pair.

:func:`build_ssp` writes one ``.ssp`` file (a zip archive) that OMSimulator, ECOS and
libcosim users load instead of wiring the two FMUs by hand::

    SystemStructure.ssd      the system: both components, every connection, parameters
    resources/plant.fmu      navsim's plant FMU of the scenario (FMI 2.0)
    resources/estimator.fmu  navsim's estimator FMU of the same scenario (FMI 2.0)

``SystemStructure.ssd`` declares, for each component, a connector per FMI variable that
is connected or parameterised (``kind`` = its causality; type ``ssc:Real``,
``ssc:Integer``, ``ssc:Boolean``, ``ssc:String``), one ``ssd:Connection`` from each plant
output to the estimator input of the same name (every estimator input: sensor data,
prior, the plant's ``time.step`` / ``time.t_s``), and an inline ``ssv:ParameterSet`` per
component, both named ``navsim`` (:data:`PARAMETER_SET`), binding the parameters (the
plant's ``seed`` and sensor settings, the estimator's ``estimator.name`` /
``estimator.options``) to the values given here (default: the FMUs' start values);
libcosim applies the bindings when it loads the file, ECOS when the set is named at
initialisation (``sim.init(parameter_set="navsim")``). ``ssd:DefaultExperiment`` gives the episode's start
and stop time; the step size is the navigation step (an SSP 1.0 file has no standard
place for it: pass it to the tool, e.g. ECOS's ``step_size`` or libcosim's
``from_ssp_file(path, step_size)``), as the estimator FMU's master requirements say
(:mod:`navsim.fmu.runtime`). A Jacobi master (libcosim, ECOS) gives the estimate of the
previous navigation step, marked by ``nav.t_s`` and ``nav.lag_steps``.

SSP 1.0 connectors are scalars, so the archive carries the FMI 2.0 FMUs (whose arrays are
scalar variables with structured names ``x[i,j]``).
"""

from __future__ import annotations

import tempfile
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any
from xml.dom import minidom
from xml.etree.ElementTree import Element, SubElement, tostring

from navsim.errors import ConfigError

from .variables import Var, scalar_names

if TYPE_CHECKING:  # type hints only
    from navsim.scenario import Scenario

__all__ = ["build_ssp", "system_structure_xml", "SSD_FILE", "PARAMETER_SET"]

SSD_FILE = "SystemStructure.ssd"
#: name of the parameter set of both components (ECOS applies it by name: ``init(parameter_set=...)``)
PARAMETER_SET = "navsim"
_NS = {
    "xmlns:ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "xmlns:ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "xmlns:ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
}
_SSC = {"real": "ssc:Real", "int": "ssc:Integer", "bool": "ssc:Boolean", "string": "ssc:String"}
_SSV = {"real": "ssv:Real", "int": "ssv:Integer", "bool": "ssv:Boolean", "string": "ssv:String"}


def _value(var: Var, value: Any) -> str:
    if var.type == "real":
        return repr(float(value))
    if var.type == "int":
        return str(int(value))
    if var.type == "bool":
        return "true" if value else "false"
    return str(value)


def _component(elements: Element, name: str, source: str, table: list[Var], connected: set[str],
               parameters: dict) -> None:
    comp = SubElement(elements, "ssd:Component", name=name, source=source, type="application/x-fmu-sharedlibrary")
    conns = SubElement(comp, "ssd:Connectors")
    for var in table:
        if var.causality == "parameter" or var.name in connected:
            for scalar in scalar_names(var):
                c = SubElement(conns, "ssd:Connector", name=scalar, kind=var.causality)
                SubElement(c, _SSC[var.type])
    values = {v.name: parameters.get(v.name, v.start) for v in table if v.causality == "parameter"}
    binding = SubElement(SubElement(comp, "ssd:ParameterBindings"), "ssd:ParameterBinding")
    pset = SubElement(SubElement(binding, "ssd:ParameterValues"), "ssv:ParameterSet", version="1.0",
                      name=PARAMETER_SET)
    params = SubElement(pset, "ssv:Parameters")
    by_name = {v.name: v for v in table}
    for key, value in values.items():
        if value is None:
            continue
        p = SubElement(params, "ssv:Parameter", name=key)
        SubElement(p, _SSV[by_name[key].type], value=_value(by_name[key], value))


def system_structure_xml(plant_table: list[Var], estimator_table: list[Var], *, name: str, duration_s: float,
                         plant_parameters: dict | None = None, estimator_parameters: dict | None = None,
                         plant_source: str = "resources/plant.fmu",
                         estimator_source: str = "resources/estimator.fmu") -> tuple[bytes, int]:
    """``SystemStructure.ssd`` of the pair and its number of (scalar) connections."""
    outputs = {v.name: v for v in plant_table if v.causality == "output"}
    inputs = [v for v in estimator_table if v.causality == "input"]
    missing = [v.name for v in inputs if v.name not in outputs or outputs[v.name].shape != v.shape]
    if missing:
        raise ConfigError("estimator inputs", "a plant output of the same name and shape for each", missing[:5])
    connected = {v.name for v in inputs}
    root = Element("ssd:SystemStructureDescription", {**_NS, "version": "1.0", "name": name})
    system = SubElement(root, "ssd:System", name=name)
    elements = SubElement(system, "ssd:Elements")
    _component(elements, "plant", plant_source, plant_table, connected, plant_parameters or {})
    _component(elements, "estimator", estimator_source, estimator_table, connected, estimator_parameters or {})
    conns = SubElement(system, "ssd:Connections")
    n = 0
    for var in inputs:
        for scalar in scalar_names(var):
            SubElement(conns, "ssd:Connection", startElement="plant", startConnector=scalar,
                       endElement="estimator", endConnector=scalar)
            n += 1
    SubElement(root, "ssd:DefaultExperiment", startTime="0.0", stopTime=repr(float(duration_s)))
    return minidom.parseString(tostring(root, "utf-8")).toprettyxml(indent="  ", encoding="UTF-8"), n


def build_ssp(scenario: Scenario | str, output: str | Path, *, estimator: str | None = None, estimator_options: str = "",
              seed: int = 0, plant_parameters: dict | None = None) -> Path:
    """Write ``output`` (``.ssp``): plant and estimator FMUs (FMI 2.0) of ``scenario`` and
    ``SystemStructure.ssd`` connecting them (see the module docstring).

    ``seed`` and ``plant_parameters`` (plant FMU parameter names -> values) go into the
    plant's parameter set; ``estimator`` / ``estimator_options`` are built into the
    estimator FMU and bound in its parameter set.
    """
    from navsim.scenario import Scenario, load_scenario

    from .build import build_fmu, variable_tables

    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=output.parent) as tmp:
        plant = build_fmu(scenario, "plant", 2, Path(tmp) / "plant.fmu")
        est = build_fmu(scenario, "estimator", 2, Path(tmp) / "estimator.fmu", estimator=estimator,
                        estimator_options=estimator_options)
        ptable, etable = variable_tables(scenario, estimator, estimator_options)
        params = {"seed": int(seed), **(plant_parameters or {})}
        unknown = sorted(set(params) - {v.name for v in ptable if v.causality == "parameter"})
        if unknown:
            raise ConfigError("plant_parameters", "plant FMU parameter names", unknown)
        xml, _ = system_structure_xml(ptable, etable, name=f"navsim-{scenario.name}", plant_parameters=params,
                                      duration_s=scenario.timing.duration_s)
        part = Path(tmp) / (output.name + ".part")
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr(SSD_FILE, xml)
            z.write(plant, "resources/plant.fmu")
            z.write(est, "resources/estimator.fmu")
        part.replace(output)
    return output
