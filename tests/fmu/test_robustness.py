"""Bad step sizes, bad parameters, terminate/free twice, many resets: statuses, not crashes."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap

import pytest

pytest.importorskip("fmpy")

from navsim.fmu.master import FmuCallError, FmuInstance  # noqa: E402

#: pythonfmu maps a refused doStep to fmi2Discard; pythonfmu3 lets navsim return fmi3Error
REFUSED = {2: "discard", 3: "error"}


@pytest.mark.parametrize("fmi", [2, 3])
def test_wrong_step_sizes_are_refused_with_a_message(fmi, request):
    with FmuInstance(request.getfixturevalue(f"plant{fmi}"), "p") as inst:
        inst.initialize({"seed": 0})
        for h in (0.015, 0.0, -0.01, math.nan, math.inf):
            with pytest.raises(FmuCallError, match=rf"\({REFUSED[fmi]}\).*not a whole number .* ticks"):
                inst.do_step(0.0, h)
        inst.do_step(0.0, 0.01)  # still usable
        with pytest.raises(FmuCallError, match="does not match the FMU's time"):
            inst.do_step(0.5, 0.01)
        with pytest.raises(FmuCallError, match="beyond the episode's end"):
            inst.do_step(0.01, 100.0)
        inst.do_step(0.01, 0.02)
        assert inst.get(["time.step"])["time.step"] == 3
        inst.terminate()
        inst.terminate()  # a second terminate is harmless
        with pytest.raises(FmuCallError, match="after terminate|refused in state 'terminated'"):
            inst.do_step(0.03, 0.01)
        inst.free()
        inst.free()  # idempotent


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("params, field", [
    ({"imu.preset": "bogus"}, "imu.preset"),
    ({"gnss.pseudorange_sigma_m": -5.0}, "gnss.pseudorange_sigma_m"),
    ({"seed": -3}, "seed"),
    ({"outages.windows_s": "[[5, 2]]"}, "outages.windows_s"),
    ({"scenario.overrides": "imu.orders = 2"}, "dimensions"),
    ({"motion.use_inputs": True, "motion.s_m": -50.0}, "motion.start_s_m"),
    ({"motion.use_inputs": True, "motion.s_m": 10.0}, None),
])
def test_bad_parameters_give_an_error_status_naming_the_field(fmi, params, field, request):
    """With the C guard an error status (the instance stays in initialisation mode,
    tests/fmu/test_bad_parameters.py); an FMU built without it answers Fatal."""
    import json
    import zipfile

    path = request.getfixturevalue(f"plant{fmi}")
    with zipfile.ZipFile(path) as z:
        guarded = json.loads(z.read("resources/navsim_fmu.json")).get("guard", False)
    inst = FmuInstance(path, "p")
    try:
        if field is None:  # a valid start, then an input off the track: refused at the step that uses it
            inst.initialize(params)
            inst.set({"motion.s_m": 1e9})
            with pytest.raises(FmuCallError, match="motion inputs: motion.external.s: expected an arc length"):
                inst.do_step(0.0, 0.01)
        elif guarded:
            with pytest.raises(FmuCallError, match=rf"\(error\): .*refused: bad parameter value: .*{field}"):
                inst.initialize(params)
            with pytest.raises(FmuCallError, match="DoStep refused in state 'initialisation mode'"):
                inst.do_step(0.0, 0.01)
        else:
            with pytest.raises(FmuCallError, match=rf"\(fatal\): bad parameter value: .*{field}"):
                inst.initialize(params)
            with pytest.raises(FmuCallError, match="failed earlier"):
                inst.do_step(0.0, 0.01)
    finally:
        inst.free()
    with FmuInstance(request.getfixturevalue(f"plant{fmi}"), "again") as ok:  # the FMU still instantiates
        ok.initialize({"seed": 1})
        ok.do_step(0.0, 0.01)


def test_setting_a_parameter_after_initialisation_is_refused(plant2):
    inst = FmuInstance(plant2, "p")
    inst.initialize({"seed": 0})
    with pytest.raises(FmuCallError, match=r"seed .*cannot be set now|is a parameter; parameters cannot be set after"):
        inst.set({"seed": 5})
    inst.free()


def _rss_mb() -> float:
    with open("/proc/self/statm") as f:
        import os

        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


@pytest.mark.slow
@pytest.mark.parametrize("fmi", [2, 3])
def test_200_resets_with_steady_memory(fmi, request):
    with FmuInstance(request.getfixturevalue(f"plant{fmi}"), "p") as inst:
        rss = []
        for episode in range(200):
            if episode:
                inst.terminate()
                inst.reset()
            inst.initialize({"seed": episode})
            for k in range(20):
                inst.do_step(k * 0.01, 0.01)
            if episode in (20, 199):
                rss.append(_rss_mb())
        assert inst.get(["time.step"])["time.step"] == 20
    assert rss[1] - rss[0] < 25.0, rss  # MB over 180 episodes


@pytest.mark.slow
def test_host_survives_misuse_in_a_subprocess(plant2):
    """Everything above, plus instantiating many failing instances, in a fresh process."""
    code = textwrap.dedent(f"""
        from navsim.fmu.master import FmuInstance, FmuCallError
        for i in range(12):
            inst = FmuInstance({str(plant2)!r}, "p%d" % i)
            try:
                inst.initialize({{"seed": -1}})
            except FmuCallError:
                pass
            inst.terminate(); inst.free(); inst.free()
        inst = FmuInstance({str(plant2)!r}, "last")
        inst.initialize({{"seed": 2}}); inst.do_step(0.0, 0.01); inst.free()
        print("alive")
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and "alive" in out.stdout, out.stderr[-2000:]
