"""Build navsim's plant and estimator FMUs (FMI 2.0 and FMI 3.0 co-simulation).

:func:`build_fmu` writes the archive itself instead of calling pythonfmu's builders, so
that the ``modelDescription.xml`` is generated complete and valid from the shared table
(:mod:`navsim.fmu.variables`): units in ``UnitDefinitions``, start values, and a
``ModelStructure`` with every output in ``Outputs`` and every output and calculated
parameter whose ``initial`` is ``calculated`` in ``InitialUnknowns`` (pythonfmu 0.7
leaves ``InitialUnknowns`` out, which fails ``fmpy validate``; pythonfmu3 0.3.4 also
writes ``canHandleVariableCommunicationStepSize`` from a stale loop variable).

Archive layout::

    modelDescription.xml
    binaries/<platform>/<modelIdentifier>.<so|dll>   pythonfmu's / pythonfmu3's FMI shim
    resources/slavemodule.txt                         the slave module's name
    resources/<module>.py                              one class: navsim.fmu.fmi2/fmi3 slave
    resources/pythonfmu[3]/*.py                        the shim's Python side
    resources/navsim_scenario.toml                     the embedded scenario
    resources/navsim_fmu.json                          kind, FMI version, build version, ...
    resources/<track or almanac files>                 files the scenario refers to
    documentation/index.html                           what a host needs (HOST_REQUIREMENTS)

What a host needs: see :data:`HOST_REQUIREMENTS`.
"""

from __future__ import annotations

import datetime
import json
import shutil
import sys
import tempfile
import uuid
import zipfile
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING
from xml.dom import minidom
from xml.etree.ElementTree import Element, SubElement, tostring

from navsim.errors import ConfigError, DependencyNotInstalled

from .runtime import META_FILE, SCENARIO_FILE, plant_defaults
from .variables import UNITS, Dimensions, Var, estimator_variables, plant_variables, scalar_names

if TYPE_CHECKING:
    from navsim.scenario import Scenario

__all__ = ["build_fmu", "model_description_xml", "variable_tables", "default_estimator", "host_environment",
           "HOST_REQUIREMENTS",
           "MODEL_IDENTIFIERS"]

MODEL_IDENTIFIERS = {"plant": "NavsimPlant", "estimator": "NavsimEstimator"}

HOST_REQUIREMENTS = """\
What a host needs to run a navsim FMU
=====================================
* A CPython 3.10+ with navsim (distribution navsim-track) and its dependencies (numpy,
  scipy) importable: the FMU's shared library (pythonfmu's / pythonfmu3's shim) runs
  navsim's Python code in that interpreter. pythonfmu itself is embedded in the FMU.
* Python hosts (fmpy, libcosimpy, a Python master loop): nothing else; the FMU runs in
  the host's own interpreter, so install navsim in the host's environment.
* Non-Python hosts on Linux (OMSimulator, ECOS or cosim command-line tools, a C master):
  the shim does not link libpython, so preload it and point Python at the environment
  that has navsim; `navsim fmu host-env` prints the three lines for its own interpreter:
      export LD_PRELOAD=<LIBDIR>/libpython3.X.so.1.0      # the shared libpython
      export PYTHONHOME=<sys.base_prefix>                 # the base installation
      export PYTHONPATH=<venv>/lib/python3.X/site-packages
  Editable and regular (wheel) installs both work (the FMU processes the .pth files of
  PYTHONPATH, where an editable install keeps its import hook). The host exits cleanly
  (exit code 0): see navsim.fmu.runtime for the exit-time crash this avoids.
  (On Windows: put pythonXY.dll's folder on PATH.)
* Binaries are included for linux64/x86_64-linux and win64/x86_64-windows.
* Communication step: a whole number of simulator ticks, the same for both FMUs: at most
  one navigation step, or k whole navigation steps where k divides the steps of a GNSS
  period and of the episode (the plant composes the k steps' multiple integrals exactly;
  the estimator runs with a navigation step of k steps and processes each interval as one
  update, every GNSS epoch at an interval's end). Any other step is refused with an error
  status and a log message.
* Masters: connect every estimator input to the plant output of the same name (time.step
  and time.t_s included). Any fixed-step master works: Gauss-Seidel stepping the plant
  first gives the estimate of the step just ended (nav.lag_steps = 0); Jacobi (libcosim,
  ECOS, most masters) or Gauss-Seidel stepping the estimator first gives the estimate of
  the previous communication step (nav.lag_steps = 1, or k). nav.t_s always says the time the estimate refers
  to: compare it with truth at nav.t_s. The estimator reads the plant's step counter and
  takes each plant step once and in order; skipped, repeated or stale data (a missed
  transfer, time.step not connected) are refused with an error status and a log line.
* The variables navsim.version, navsim.build_version, navsim.config_hash and
  navsim.scenario (calculated parameters) say what ran: log them.
"""


def host_environment() -> dict[str, str]:
    """The environment a non-Python Linux host needs to run navsim's FMUs with this
    interpreter and its environment (the recipe of :data:`HOST_REQUIREMENTS`):
    ``LD_PRELOAD`` the shared libpython, ``PYTHONHOME`` the base installation,
    ``PYTHONPATH`` the environment's site-packages (editable installs work too: the
    FMU's slave script processes the ``.pth`` files there). ``navsim fmu host-env``
    prints it as shell ``export`` lines."""
    import os
    import sysconfig

    libdir = sysconfig.get_config_var("LIBDIR") or ""
    soname = sysconfig.get_config_var("INSTSONAME") or sysconfig.get_config_var("LDLIBRARY") or ""
    lib = os.path.join(libdir, soname)
    if not (soname.endswith((".so", ".dylib")) or ".so." in soname) or not os.path.exists(lib):
        raise ConfigError("libpython", "a shared libpython (Python built with --enable-shared)", lib)
    return {"LD_PRELOAD": lib, "PYTHONHOME": sys.base_prefix, "PYTHONPATH": sysconfig.get_paths()["purelib"]}


def _require(kind_module: str, extra: str = "fmu") -> ModuleType:
    import importlib

    try:
        return importlib.import_module(kind_module)
    except ImportError:
        raise DependencyNotInstalled(kind_module, extra) from None


# =========================================================================== XML
def _fmt(var: Var, value: float | int | bool | str) -> str:
    if var.type == "real":
        return repr(float(value))
    if var.type == "int":
        return str(int(value))
    if var.type == "bool":
        return "true" if value else "false"
    return str(value)


def _initial(var: Var) -> str | None:
    if var.causality == "parameter":
        return "exact"
    if var.causality in ("output", "calculatedParameter"):
        return "calculated"
    return None  # inputs: no initial attribute


def _units_used(table: list[Var]) -> list[str]:
    return sorted({v.unit for v in table if v.unit})


def _unit_definitions(root: Element, table: list[Var]) -> None:
    units = _units_used(table)
    if not units:
        return
    defs = SubElement(root, "UnitDefinitions")
    for name in units:
        unit = SubElement(defs, "Unit", name=name)
        SubElement(unit, "BaseUnit", {k: str(e) for k, e in UNITS[name].items()})


def _log_categories(root: Element, fmi: int) -> None:
    cats = SubElement(root, "LogCategories")
    prefix = f"fmi{fmi}"
    for name, text in (("logStatusWarning", "warning"), ("logStatusDiscard", "discard"),
                       ("logStatusError", "error"), ("logStatusFatal", "fatal"), ("logAll", "all")):
        SubElement(cats, "Category", name=name, description=f"Log messages with {prefix} status {text}"
                   if name != "logAll" else "Log all messages")


_FMI2_TYPE = {"real": "Real", "int": "Integer", "bool": "Boolean", "string": "String"}
_FMI3_TYPE = {"real": "Float64", "int": "Int32", "bool": "Boolean", "string": "String"}


def model_description_xml(kind: str, table: list[Var], fmi: int, *, model_name: str, description: str,
                          version: str, duration_s: float, step_s: float, token: str | None = None) -> bytes:
    """The ``modelDescription.xml`` of a navsim FMU, generated from its variable table."""
    token = token or str(uuid.uuid4())
    identifier = MODEL_IDENTIFIERS[kind]
    now = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    attrs = {"fmiVersion": "2.0" if fmi == 2 else "3.0", "modelName": model_name, "description": description,
             "generationTool": f"navsim {version}", "generationDateAndTime": now, "version": version,
             "variableNamingConvention": "structured"}
    attrs["guid" if fmi == 2 else "instantiationToken"] = "{" + token + "}"
    root = Element("fmiModelDescription", attrs)
    cs = {"modelIdentifier": identifier, "needsExecutionTool": "true",
          "canHandleVariableCommunicationStepSize": "true", "canBeInstantiatedOnlyOncePerProcess": "false"}
    if fmi == 2:
        cs.update(canNotUseMemoryManagementFunctions="true", canGetAndSetFMUstate="false",
                  canSerializeFMUstate="false")
    else:
        cs.update(canGetAndSetFMUState="false", canSerializeFMUState="false")
    SubElement(root, "CoSimulation", cs)
    _unit_definitions(root, table)
    _log_categories(root, fmi)
    SubElement(root, "DefaultExperiment", startTime="0.0", stopTime=repr(float(duration_s)), stepSize=repr(float(step_s)))
    variables = SubElement(root, "ModelVariables")
    outputs: list[int] = []
    initial_unknowns: list[int] = []
    if fmi == 2:
        index = 0
        for var in table:
            for name in scalar_names(var):
                index += 1
                a = {"name": name, "valueReference": str(index - 1), "description": var.description,
                     "causality": var.causality, "variability": var.variability}
                if initial := _initial(var):
                    a["initial"] = initial
                sv = SubElement(variables, "ScalarVariable", a)
                t: dict[str, str] = {}
                if var.unit and var.type == "real":
                    t["unit"] = var.unit
                if var.start is not None:
                    t["start"] = _fmt(var, var.start)
                SubElement(sv, _FMI2_TYPE[var.type], t)
                if var.causality == "output":
                    outputs.append(index)
                if _initial(var) == "calculated":
                    initial_unknowns.append(index)
        structure = SubElement(root, "ModelStructure")
        if outputs:
            node = SubElement(structure, "Outputs")
            for i in outputs:
                SubElement(node, "Unknown", index=str(i))
        if initial_unknowns:
            node = SubElement(structure, "InitialUnknowns")
            for i in initial_unknowns:
                SubElement(node, "Unknown", index=str(i))
    else:
        SubElement(variables, "Float64", name="time", valueReference="0", causality="independent",
                   variability="continuous", unit="s", description="Simulation time")
        for vr, var in enumerate(table, start=1):
            a = {"name": var.name, "valueReference": str(vr), "description": var.description,
                 "causality": var.causality, "variability": var.variability}
            if initial := _initial(var):
                a["initial"] = initial
            if var.unit and var.type == "real":
                a["unit"] = var.unit
            if var.start is not None and var.type != "string":
                a["start"] = " ".join([_fmt(var, var.start)] * var.size)
            node = SubElement(variables, _FMI3_TYPE[var.type], a)
            if var.start is not None and var.type == "string":
                SubElement(node, "Start", value=str(var.start))
            for d in var.shape:
                SubElement(node, "Dimension", start=str(d))
            if var.causality == "output":
                outputs.append(vr)
            if _initial(var) == "calculated":
                initial_unknowns.append(vr)
        structure = SubElement(root, "ModelStructure")
        for vr in outputs:
            SubElement(structure, "Output", valueReference=str(vr))
        for vr in initial_unknowns:
            SubElement(structure, "InitialUnknown", valueReference=str(vr))
    return minidom.parseString(tostring(root, "utf-8")).toprettyxml(indent="  ", encoding="UTF-8")


# =========================================================================== archive
_SLAVE_SCRIPT = '''"""navsim {kind} FMU (FMI {fmi}) entry point, generated by `navsim fmu build`.

The class is navsim.fmu.fmi{fmi}.{cls}; the import alias gives it the base-class name
that pythonfmu's loader looks for.
"""
try:
    import navsim  # noqa: F401
except ImportError:
    # A non-Python host embeds Python with PYTHONPATH=.../site-packages, which is not a site
    # directory, so its .pth files (an editable install's import hook) never ran: run them.
    import os
    import site

    for _entry in os.environ.get("PYTHONPATH", "").split(os.pathsep):
        if _entry:
            site.addsitedir(_entry)
from navsim.fmu.fmi{fmi} import {cls} as Fmi{fmi}Slave


class {identifier}(Fmi{fmi}Slave):
    """navsim {kind} (see navsim.fmu.runtime)."""
{extra}'''

_FMI2_PIN = """

from navsim.fmu.fmi2 import pin_module_dict

pin_module_dict(globals())  # balances pythonfmu 0.7's loader (see pin_module_dict)
"""


def _embed_scenario(scenario: Scenario, resources: dict[str, bytes]) -> str:
    """The scenario with its file references rewritten to files copied into resources/."""
    data = scenario.to_dict()
    if scenario.track.file:
        path = scenario.resolve_path(scenario.track.file)
        resources[path.name] = path.read_bytes()
        data["track"]["file"] = path.name
    if scenario.gnss.constellation.startswith("yuma:"):
        path = scenario.resolve_path(scenario.gnss.constellation[5:], "almanac")
        resources[path.name] = path.read_bytes()
        data["gnss"]["constellation"] = f"yuma:{path.name}"
    import tomli_w

    return tomli_w.dumps(data)


def default_estimator(estimator: str | None) -> str:
    """The estimator of an estimator FMU: ``estimator``, or paper-ekf when installed, else lc-ekf
    (ConfigError for a name that is not installed)."""
    from navsim import estimators

    if estimator is None:
        estimator = "paper-ekf" if "paper-ekf" in estimators.available() else "lc-ekf"
    try:
        estimators.check(estimator)
    except ConfigError as exc:
        raise ConfigError("--estimator", exc.expected, estimator) from None
    return estimator


USER_ESTIMATOR_DIR = "user_estimator"


def _embed_estimator(estimator: str, resources: dict[str, bytes]) -> str:
    """A user's estimator given as ``file.py:Factory`` is copied into resources/ (the FMU then
    needs no copy of the file on the host); the name recorded is ``user_estimator/file.py:Factory``,
    resolved against the FMU's resources folder. Registry names and dotted import paths are kept:
    a dotted module must be importable by the host's Python."""
    module, _, attr = estimator.rpartition(":")
    if not module.endswith(".py"):
        return estimator
    path = Path(module).expanduser()
    resources[f"{USER_ESTIMATOR_DIR}/{path.name}"] = path.read_bytes()
    return f"{USER_ESTIMATOR_DIR}/{path.name}:{attr}"


def variable_tables(scenario: Scenario, estimator: str | None = None, estimator_options: str = "") -> tuple[list[Var], list[Var]]:
    """The plant and the estimator FMU's variable tables for ``scenario`` (FMI-version independent)."""
    from navsim.simulator import Simulator

    dims = Dimensions.of(Simulator(scenario))
    return (plant_variables(dims, plant_defaults(scenario)),
            estimator_variables(dims, {"estimator.name": default_estimator(estimator),
                                       "estimator.options": estimator_options}))


def build_fmu(scenario: Scenario | str, what: str = "plant", fmi: int = 2, output: str | Path | None = None, *,
              estimator: str | None = None, estimator_options: str = "", guarded: bool = True) -> Path:
    """Build a plant or estimator FMU of ``scenario``.

    Parameters
    ----------
    scenario : navsim.scenario.Scenario or str
        The embedded scenario (a bundled name or a path is loaded).
    what : ``"plant"`` or ``"estimator"``.
    fmi : 2 (pythonfmu) or 3 (pythonfmu3).
    output : the ``.fmu`` file (default ``<scenario>-<what>-fmi<fmi>.fmu``).
    estimator : estimator name or import path (``package.module:Factory``; a
        ``file.py:Factory`` is copied into the FMU) for the estimator FMU (default
        ``paper-ekf`` when installed, else ``lc-ekf``); the FMU parameter ``estimator.name``.
    estimator_options : TOML ``key = value`` lines passed to ``navsim.estimators.make``.
    guarded : put the C guard of :mod:`navsim.fmu.guard` (FMI state machine, misuse
        answered with error statuses) in front of the Linux shim when gcc and fmpy's FMI
        headers are available (``navsim_fmu.json`` says whether it is there).

    Returns
    -------
    Path of the written FMU.
    """
    import navsim
    from navsim.scenario import Scenario, load_scenario
    from navsim.simulator import Simulator

    if what not in MODEL_IDENTIFIERS:
        raise ConfigError("--what", "'plant' or 'estimator'", what)
    if fmi not in (2, 3):
        raise ConfigError("--fmi", "2 or 3", fmi)
    shim = _require("pythonfmu" if fmi == 2 else "pythonfmu3")
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    sim = Simulator(scenario)
    dims = Dimensions.of(sim)
    resources: dict[str, bytes] = {}
    meta = {"kind": what, "fmi": fmi, "build_version": navsim.__version__, "scenario": scenario.name,
            "config_hash": scenario.config_hash()}
    if what == "plant":
        table = plant_variables(dims, plant_defaults(scenario))
        text = (f"navsim plant: truth and sensor data (IMU increments and multiple integrals, GNSS pseudorange, "
                f"Doppler, satellite states) of scenario {scenario.name!r}")
    else:
        estimator = _embed_estimator(default_estimator(estimator), resources)
        meta.update(estimator=estimator, estimator_options=estimator_options)
        table = estimator_variables(dims, {"estimator.name": estimator, "estimator.options": estimator_options})
        text = (f"navsim estimator {estimator!r} on scenario {scenario.name!r}: navigation solution and its "
                f"uncertainty. Connect every input to the plant output of the same name (time.step included); "
                f"any fixed-step master with h <= {scenario.timing.nav_period_s!r} s or h = k navigation steps "
                f"(k dividing the GNSS period): nav.t_s is the time the solution refers to (one communication "
                f"step behind under a Jacobi master, nav.lag_steps)")
    text += ". Needs a Python with navsim and numpy (see documentation/index.html)."
    identifier = MODEL_IDENTIFIERS[what]
    module = f"navsim_{what}_fmi{fmi}"
    xml = model_description_xml(what, table, fmi, model_name=identifier, description=text,
                                version=navsim.__version__, duration_s=scenario.timing.duration_s,
                                step_s=scenario.timing.nav_period_s)
    resources[SCENARIO_FILE] = _embed_scenario(scenario, resources).encode()
    resources[META_FILE] = json.dumps(meta, indent=1).encode()
    resources["slavemodule.txt"] = module.encode()
    cls = "PlantSlave" if what == "plant" else "EstimatorSlave"
    resources[f"{module}.py"] = _SLAVE_SCRIPT.format(kind=what, fmi=fmi, cls=cls, identifier=identifier,
                                                              extra=_FMI2_PIN if fmi == 2 else "").encode()
    assert shim.__file__ is not None, f"{shim.__name__} is a regular package"
    shim_dir = Path(shim.__file__).parent
    package = "pythonfmu" if fmi == 2 else "pythonfmu3"
    output = Path(output or f"{scenario.name}-{what}-fmi{fmi}.fmu")
    output.parent.mkdir(parents=True, exist_ok=True)
    tmp = output.with_name(output.name + ".part")
    with tempfile.TemporaryDirectory() as work:
        from .guard import compile_guard

        guard = compile_guard(fmi, parameter_references(table, fmi), identifier, Path(work)) if guarded else None
        meta["guard"] = guard is not None
        resources[META_FILE] = json.dumps(meta, indent=1).encode()
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("modelDescription.xml", xml)
            for lib in sorted((shim_dir / "resources" / "binaries").rglob("*")):
                if lib.suffix in (".so", ".dll", ".dylib"):
                    if lib.suffix == ".so" and guard is not None:  # the guard in front of the shim (guard.py)
                        z.write(guard, f"binaries/{lib.parent.name}/{identifier}.so")
                        z.write(lib, f"binaries/{lib.parent.name}/{identifier}_pythonfmu.so")
                    else:
                        z.write(lib, f"binaries/{lib.parent.name}/{identifier}{lib.suffix}")
            _write_resources(z, resources, shim_dir, package)
    shutil.move(tmp, output)
    return output


def _write_resources(z: zipfile.ZipFile, resources: dict[str, bytes], shim_dir: Path, package: str) -> None:
    for name, blob in resources.items():
        z.writestr(f"resources/{name}", blob)
    for src in sorted(shim_dir.glob("*.py")):
        z.write(src, f"resources/{package}/{src.name}")
    z.writestr("documentation/index.html",
               "<html><body><pre>\n" + HOST_REQUIREMENTS.replace("&", "&amp;").replace("<", "&lt;")
               + "\n</pre></body></html>\n")


def parameter_references(table: list[Var], fmi: int) -> list[int]:
    """Value references of the parameters of ``table`` in an FMU of version ``fmi``
    (FMI 2: one per scalar, from 0; FMI 3: one per variable, from 1 after ``time``)."""
    out: list[int] = []
    vr = 0 if fmi == 2 else 1
    for var in table:
        n = len(scalar_names(var)) if fmi == 2 else 1
        if var.causality == "parameter":
            out.extend(range(vr, vr + n))
        vr += n
    return out
