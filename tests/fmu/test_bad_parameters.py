"""Bad FMU parameter values (issue 16): ``exitInitializationMode`` answers an error status
(not pythonfmu's Fatal) with one log line naming the parameter, the expectation and the
value, through the C guard (:func:`navsim.fmu.runtime.refuse_through_guard`); the
instance stays in initialisation mode, so a valid value and a second
``exitInitializationMode`` start the episode the valid value gives from the start."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("fmpy")

from navsim.fmu.master import FmuCallError, FmuInstance  # noqa: E402

# (parameters, the words the log line must hold: parameter, expectation, value)
BAD = [
    ({"seed": -1}, ("seed: expected an integer >= 0", "got -1")),
    ({"imu.preset": "magic"}, ("imu.preset: expected one of", "got 'magic'")),
    ({"scenario.overrides": "timing = ["}, ("scenario.overrides: expected TOML key = value lines",)),
    ({"scenario.overrides": 'track = { bundled = "../../x" }'}, ("track.bundled: expected the name of a bundled track",
                                                                 "got '../../x'")),
    ({"scenario.overrides": "timing = { duration_s = -1.0 }"}, ("timing.duration_s: expected", "got -1.0")),
]


@pytest.fixture(params=[2, 3])
def plant(request):
    import shutil

    from navsim.fmu.guard import headers_dir

    if shutil.which("gcc") is None or headers_dir() is None:
        pytest.skip("the FMU is built without the C guard here: no gcc or no FMI headers (fmpy)")
    return request.getfixturevalue(f"plant{request.param}")


def _first_step(inst) -> np.ndarray:
    name = next(n for n in inst.variables if n.startswith("imu.dv_r1"))
    inst.do_step(0.0, 0.01)
    return np.atleast_1d(np.asarray(inst.get([name])[name], dtype=float))


@pytest.mark.parametrize("params, words", BAD, ids=[f"{next(iter(p))}={next(iter(p.values()))}" for p, _ in BAD])
def test_a_bad_parameter_is_an_error_status_with_a_line_naming_it(plant, params, words):
    with FmuInstance(plant, "p") as inst:
        seen = len(inst.log)
        with pytest.raises(FmuCallError, match=r"exitInitializationMode.*\(error\)"):
            inst.initialize(params)
        lines = [m for _, m in inst.log[seen:] if "bad parameter value" in m]
        assert len(lines) == 1 and all(w in lines[0] for w in words), inst.log[seen:]


def test_after_a_bad_parameter_a_valid_value_starts_the_episode(plant):
    with FmuInstance(plant, "fresh") as ref:
        ref.initialize({"seed": 3})
        expected = _first_step(ref)
    with FmuInstance(plant, "p") as inst:
        with pytest.raises(FmuCallError, match=r"\(error\)"):
            inst.initialize({"seed": -1})
        inst.set({"seed": 3})  # still in initialisation mode
        inst._call("exitInitializationMode", inst.fmu.exitInitializationMode)
        np.testing.assert_array_equal(_first_step(inst), expected)  # the same core calls: bit for bit


def test_the_battery_counts_a_bad_fmu_parameter_as_a_clear_error_only_with_its_log_line(plant2, tmp_path):
    """tools/bad_inputs.py's FMU case through fmpy (an outside host): an error status and
    one log line with the parameter, the expectation and the value; the same case whose
    words are not in the log is a traceback."""
    import importlib.util
    import json
    import sys
    import zipfile
    from pathlib import Path

    with zipfile.ZipFile(plant2) as z:
        if not json.loads(z.read("resources/navsim_fmu.json")).get("guard"):
            pytest.skip("the FMU was built without the C guard (no gcc or no FMI headers)")
    spec = importlib.util.spec_from_file_location("bad_inputs", Path(__file__).parents[2] / "tools" / "bad_inputs.py")
    bad_inputs = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("bad_inputs", bad_inputs)
    spec.loader.exec_module(bad_inputs)
    case = next(c for c in bad_inputs.cases() if c.name == "FMU seed = -1")
    result = bad_inputs.run_case(case, tmp_path, {}, str(plant2))
    assert result["class"] == "clear-error" and "seed: expected an integer >= 0, got -1" in result["detail"], result
    wrong = bad_inputs.Case("wrong words", case.category, "fmu", case.payload.replace("got -1", "got -2"))
    assert bad_inputs.run_case(wrong, tmp_path, {}, str(plant2))["class"] == "traceback"
