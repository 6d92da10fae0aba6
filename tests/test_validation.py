"""One clear error for every bad input (issue 16): the CLI answers each case of bad
input, fault or meaningless setting with exit status 2 and one line naming the field,
the expectation and the value, never a traceback and never a file's contents; a
property-based test generates scenario files and CLI arguments."""

from __future__ import annotations

import sqlite3

import pytest

from navsim.cli import main
from navsim.errors import ConfigError
from navsim.scenario import load_scenario
from navsim.simulator import Simulator
from navsim.validation import check_seed, check_steps, validate_scenario

BASE = 'name = "t"\n[timing]\nduration_s = 2.0\n[track]\nbundled = "paper-2012"\n'
SECRET = "s3cret-line-that-must-never-be-echoed"


def _run(capsys, argv):
    code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    return code, err


def _one_clear_line(code, err):
    assert code == 2, (code, err)
    assert len(err) == 1 and "error:" in err[0] and "Traceback" not in err[0], err
    assert SECRET not in err[0]


def _scenario_file(tmp_path, text, name="s.toml"):
    path = tmp_path / name
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8")
    return str(path)


CASES = {
    "not utf-8": lambda d: ["show", _scenario_file(d, b'name = "\xff\xfe"\n')],
    "frequency 0": lambda d: ["show", _scenario_file(d, BASE + "[motion]\noscillations = [{angle='roll', frequency_hz=0.0, amplitude_deg=1.0}]\n")],
    "gyro string": lambda d: ["show", _scenario_file(d, BASE + '[imu]\ngyro = "abc"\n')],
    "2-point track": lambda d: (d.joinpath("two.csv").write_text("lat_deg,lon_deg\n55.0,37.0\n55.001,37.0\n"),
                                ["simulate", _scenario_file(d, 'name="t"\n[timing]\nduration_s=2.0\n[track]\nfile="two.csv"\n'),
                                 "-o", str(d / "o.npz"), "-q"])[1],
    "track doubling back": lambda d: (d.joinpath("b.csv").write_text(
        "lat_deg,lon_deg\n55.0,37.0\n55.01,37.0\n55.0,37.0001\n55.01,37.0002\n"),
        ["simulate", _scenario_file(d, 'name="t"\n[timing]\nduration_s=2.0\n[track]\nfile="b.csv"\n'), "-o", str(d / "o.npz"), "-q"])[1],
    "seed -1": lambda d: ["simulate", "paper-2012", "--set", "timing.duration_s=2", "--seed", "-1", "-o", str(d / "o.npz")],
    "run seed -1": lambda d: ["run", "paper-2012", "--set", "timing.duration_s=2", "--seed", "-1", "--estimator", "ins-only"],
    "chunk 0": lambda d: ["simulate", "paper-2012", "--set", "timing.duration_s=2", "--chunk", "0", "-o", str(d / "o.npz")],
    "output under a file": lambda d: (d.joinpath("f").write_text("x"),
                                      ["simulate", "paper-2012", "--set", "timing.duration_s=2", "-o", str(d / "f" / "o.npz"), "-q"])[1],
    "1 kHz oscillation on a 100 Hz IMU": lambda d: ["show", _scenario_file(d, BASE + "[motion]\noscillations = [{angle='roll', frequency_hz=1000.0, amplitude_deg=0.1}]\n")],
    "outage window [-5, 4]": lambda d: ["simulate", _scenario_file(d, BASE + "[outages]\nwindows_s = [[-5.0, 4.0]]\n"), "-o", str(d / "o.npz"), "-q"],
    "bundled ../": lambda d: ["show", "paper-2012", "--set", "track.bundled=../../../etc/x"],
    "bundled absolute": lambda d: ["show", "paper-2012", "--set", f"track.bundled={d}/x"],
    "yuma: a file that is not an almanac": lambda d: (d.joinpath("p").write_text(SECRET + ":x:0:0\n"),
        ["simulate", "paper-2012", "--set", f"gnss.constellation=yuma:{d / 'p'}", "--set", "timing.duration_s=2", "-o", str(d / "o.npz"), "-q"])[1],
    "csv track with a text cell": lambda d: (d.joinpath("c.csv").write_text(
        f"lat_deg,lon_deg\n55.0,37.0\n{SECRET},37.0\n55.002,37.0\n55.003,37.0\n"),
        ["simulate", _scenario_file(d, 'name="t"\n[timing]\nduration_s=2.0\n[track]\nfile="c.csv"\n'), "-o", str(d / "o.npz"), "-q"])[1],
    "unknown key": lambda d: ["show", "paper-2012", "--set", "timing.nope=1"],
    "invalid TOML": lambda d: ["show", _scenario_file(d, "name = [\n")],
    "missing file": lambda d: ["show", str(d / "nope.toml")],
    "unknown option": lambda d: ["simulate", "--no-such-option"],
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input_is_one_line_and_exit_2(case, tmp_path, capsys):
    _one_clear_line(*_run(capsys, CASES[case](tmp_path)))


def test_corrupt_campaign_database_names_the_file_and_a_recovery(tmp_path, capsys):
    spec = tmp_path / "c.toml"
    spec.write_text('[campaign]\nname="c"\nseeds="0:1"\n[overrides]\ntiming={duration_s=2.0}\n'
                    '[[scenarios]]\nname="paper-2012"\n[[estimators]]\nname="ins-only"\n', encoding="utf-8")
    (tmp_path / "c.sqlite").write_bytes(SECRET.encode() * 50)
    code, err = _run(capsys, ["campaign", str(spec), "--workers", "0", "--no-plots"])
    _one_clear_line(code, err)
    assert "c.sqlite" in err[0] and "move it aside" in err[0]
    with pytest.raises(sqlite3.DatabaseError):  # the file was left as it was, for recovery
        sqlite3.connect(str(tmp_path / "c.sqlite")).execute("SELECT * FROM episodes")


def test_validation_pass_is_used_by_the_python_api_before_any_work():
    sc = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 2.0}})
    over = {"motion": {"oscillations": [{"angle": "roll", "frequency_hz": 50.0, "amplitude_deg": 0.1}]}}
    with pytest.raises(ConfigError, match=r"motion.oscillations\[0\].frequency_hz.*Nyquist.*50 Hz"):
        sc.with_overrides(over)  # scenario building runs the pass ...
    import dataclasses

    from navsim.scenario import OscillationConfig

    built = dataclasses.replace(sc, motion=dataclasses.replace(sc.motion, oscillations=(
        OscillationConfig("roll", 50.0, amplitude_deg=0.1),)))
    with pytest.raises(ConfigError, match="Nyquist"):
        Simulator(built)  # ... and so does the simulator, for scenarios built field by field
    validate_scenario(sc.with_overrides({"motion": {"oscillations": [
        {"angle": "roll", "frequency_hz": 49.0, "amplitude_deg": 0.1}]}}))  # just below: accepted
    with pytest.raises(ConfigError, match="seed"):
        check_seed(-1)
    assert check_seed(None) is None and check_seed(7) == 7
    with pytest.raises(ConfigError, match="chunk"):
        check_steps(0, sc)
    sim = Simulator(sc)
    sim.reset(0)
    with pytest.raises(ConfigError, match="chunk_steps"):
        next(sim.chunks(0))
    with pytest.raises(ConfigError, match="n_steps"):
        sim.advance(0)


def test_steps_beyond_the_machine_memory_are_refused(monkeypatch):
    import navsim.validation as v

    sc = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 2.0}})
    monkeypatch.setattr(v, "machine_memory_bytes", lambda: 1000)  # a machine with 1 kB
    with pytest.raises(ConfigError, match="timing.imu_period_s.*GiB"):
        validate_scenario(sc)
    monkeypatch.setattr(v, "machine_memory_bytes", lambda: 10 * max(v._step_bytes(sc), v.truth_block_bytes(sc)))
    validate_scenario(sc)
    monkeypatch.setattr(v, "machine_memory_bytes", lambda: 10 * v._step_bytes(sc))  # chunks of up to 10 steps
    with pytest.raises(ConfigError, match="chunk.*fewer steps"):
        check_steps(100, sc)
    assert check_steps(5, sc) == 5


def test_machine_memory_is_the_physical_memory():
    import os

    import navsim.validation as v

    if not hasattr(os, "sysconf") or "SC_PHYS_PAGES" not in os.sysconf_names:
        pytest.skip("no SC_PHYS_PAGES here")
    assert v.machine_memory_bytes() == os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def test_a_nanosecond_tick_is_refused_for_its_memory_before_any_allocation(capsys):
    """The battery's case: tick = IMU period = navigation step = 1e-9 s. The truth
    generator's 1-s block would hold 1e9 samples: m (q + R + 1) n float64 values, counted
    twice, far beyond any machine; refused in one line before anything is built."""
    import navsim.validation as v

    over = {"timing": {"duration_s": 1.0, "tick_s": 1e-9, "imu_period_s": 1e-9, "nav_period_s": 1e-9}}
    sc_ok = load_scenario("paper-2012")
    R, n = sc_ok.imu.orders, 32
    assert v.truth_block_bytes(sc_ok) == 2 * 8 * 100 * (n // 2 + R + 2 + R + 1) * n  # 100 Hz: a block of 100 samples
    with pytest.raises(ConfigError, match=r"timing.imu_period_s: expected an IMU period whose truth generation fits "
                                          r"in memory \(a 1-s block of 1e\+09 samples"):
        sc_ok.with_overrides(over)
    code, err = _run(capsys, ["simulate", "paper-2012", "-q", "-o", "o.npz", *[
        a for k, x in over["timing"].items() for a in ("--set", f"timing.{k}={x}")]])
    _one_clear_line(code, err)


def test_an_episode_record_beyond_the_machine_memory_is_refused(monkeypatch):
    import navsim.validation as v
    from navsim.episode import EpisodeRecorder

    monkeypatch.setattr(v, "machine_memory_bytes", lambda: 100 * v.EPISODE_BYTES_PER_STEP)
    monkeypatch.setattr(v, "truth_block_bytes", lambda sc: 0)  # only the record is too big on this machine
    EpisodeRecorder(100)
    with pytest.raises(ConfigError, match=r"an episode whose record fits in memory \(101 navigation steps need"):
        EpisodeRecorder(101)
    sc = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 1.01}})  # 101 steps of 0.01 s
    assert sc.timing.steps == 101
    from navsim import estimators
    from navsim.episode import run_episode

    with pytest.raises(ConfigError, match="timing.duration_s / timing.nav_period_s"):
        run_episode(sc, estimators.make("gnss-ls"), seed=0)


def test_a_track_file_without_heights_warns_and_takes_0_m(tmp_path, capsys):
    """Heights are optional in every track format (documented in navsim.trackio): 0 m,
    with a warning, because a forgotten column flattens the track without an error."""
    import warnings

    from navsim.errors import NavsimWarning
    from navsim.trackio import read_csv, read_geojson, read_gpx

    pts = [(55.0 + 0.001 * i, 37.0 + 0.0005 * i) for i in range(5)]
    (tmp_path / "t.csv").write_text("lat_deg,lon_deg\n" + "".join(f"{a},{b}\n" for a, b in pts), encoding="utf-8")
    (tmp_path / "t.geojson").write_text('{"type": "LineString", "coordinates": [%s]}' % ", ".join(
        f"[{b}, {a}]" for a, b in pts), encoding="utf-8")
    (tmp_path / "t.gpx").write_text("<gpx><trk><trkseg>" + "".join(
        f'<trkpt lat="{a}" lon="{b}"/>' for a, b in pts) + "</trkseg></trk></gpx>", encoding="utf-8")
    for reader, name in ((read_csv, "t.csv"), (read_geojson, "t.geojson"), (read_gpx, "t.gpx")):
        with pytest.warns(NavsimWarning, match=rf"track file {name}: .*heights taken as 0 m"):
            wp = reader(tmp_path / name)
        assert (wp.h == 0.0).all()
    (tmp_path / "h.csv").write_text("lat_deg,lon_deg,h_m\n" + "".join(f"{a},{b},150\n" for a, b in pts),
                                    encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("error", NavsimWarning)  # with heights: no warning
        read_csv(tmp_path / "h.csv")
    scen = _scenario_file(tmp_path, 'name = "t"\n[timing]\nduration_s = 1.0\n[track]\nfile = "t.csv"\n'
                                    '[motion]\nspeed_mps = 5.0\n')
    code, err = _run(capsys, ["simulate", scen, "-q", "-o", str(tmp_path / "o.npz")])
    assert code == 0 and err == ["navsim: warning: track file t.csv: no height column (one of ['h_m', 'h', 'ele', "
                                 "'elevation', 'elevation_m', 'alt', 'alt_m', 'altitude', 'height', 'height_m']); "
                                 "heights taken as 0 m above the Earth model (a track without grade)"], err


# ----------------------------------------------------------------------- property-based
hypothesis = pytest.importorskip("hypothesis")
st = hypothesis.strategies

_numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64), st.integers(-10**6, 10**6),
                     st.sampled_from([0, 0.0, -1.0, 1e-9, 1e9, 0.005, 0.01, 0.1, 1.0]))
_values = st.one_of(_numbers, st.booleans(), st.text(max_size=8), st.lists(_numbers, max_size=3))
_fields = st.sampled_from([
    "timing.tick_s", "timing.imu_period_s", "timing.nav_period_s", "timing.gnss_period_s", "timing.duration_s",
    "motion.speed_mps", "motion.start_s_m", "motion.profile", "imu.preset", "imu.orders", "imu.quadrature_nodes",
    "gnss.constellation", "gnss.preset", "gnss.lever_arm_m", "gnss.epoch_phase_deg", "outages.windows_s",
    "initial.position_m", "earth", "track.bundled", "track.cant", "odometer.enabled", "nonsense.key",
])


def _toml_value(value) -> str:
    import tomli_w

    return tomli_w.dumps({"v": value})[4:].strip()


@hypothesis.settings(max_examples=40, deadline=None, derandomize=True,
                     suppress_health_check=list(hypothesis.HealthCheck))
@hypothesis.given(st.lists(st.tuples(_fields, _values), min_size=1, max_size=3),
                  st.sampled_from(["show", "simulate", "run"]), st.integers(-3, 3), st.sampled_from([None, 0, 1, 50]))
def test_generated_scenarios_run_or_exit_2_with_one_line(tmp_path_factory, capsys, fields, command, seed, chunk):
    """Generated scenario files (1..3 fields set to arbitrary numbers, strings, lists) and
    CLI arguments: every run ends with status 0, or 2 with one error line; never a
    traceback (an unexpected exception fails the test)."""
    d = tmp_path_factory.mktemp("h")
    lines = ['name = "h"', "[timing]", "duration_s = 1.0", "[track]", 'bundled = "paper-2012"']
    sections: dict = {}
    for key, value in fields:
        section, _, name = key.rpartition(".")
        try:
            text = _toml_value(value)
        except (TypeError, ValueError):  # NaN/inf have TOML spellings; anything else is skipped
            continue
        sections.setdefault(section, {})[name] = text
    body = []
    for section, items in sections.items():
        if section == "":
            for name, text in items.items():
                lines.insert(1, f"{name} = {text}")
            continue
        if section in ("timing", "track"):
            idx = lines.index(f"[{section}]") + 1
            for name, text in items.items():
                lines.insert(idx, f"{name} = {text}")
            continue
        body.append(f"[{section}]")
        body += [f"{name} = {text}" for name, text in items.items()]
    path = d / "s.toml"
    path.write_text("\n".join(lines + body) + "\n", encoding="utf-8")
    argv = [command, str(path)]
    if command == "simulate":
        argv += ["-o", str(d / "o.npz"), "-q", "--seed", str(seed)] + ([] if chunk is None else ["--chunk", str(chunk)])
    elif command == "run":
        argv += ["--estimator", "ins-only", "--seed", str(seed)]
    hypothesis.note(path.read_text())
    code = main(argv)
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert code in (0, 2), code
    if code == 2:
        assert len(err) == 1 and "error:" in err[0], err


# ----------------------------------------------------------------------- files and hashes
def test_scenario_hash_covers_the_contents_of_its_files(tmp_path):
    pts = "lat_deg,lon_deg\n55.0,37.0\n55.001,37.0005\n55.002,37.001\n55.003,37.0015\n55.004,37.002\n"
    (tmp_path / "t.csv").write_text(pts, encoding="utf-8")
    path = _scenario_file(tmp_path, 'name="t"\n[timing]\nduration_s=2.0\n[track]\nfile="t.csv"\n')
    first = load_scenario(path).config_hash()
    assert load_scenario(path).config_hash() == first  # same contents, same hash
    (tmp_path / "t.csv").write_text(pts.replace("55.004,37.002", "55.004,37.0021"), encoding="utf-8")
    second = load_scenario(path).config_hash()
    assert second != first  # an edited track is another scenario (campaign rows are not reused)
    bundled = load_scenario("paper-2012")
    assert bundled.file_dependencies() == {}  # bundled data only: the hash is the published one


def test_track_file_resolves_relative_to_the_scenario_file(tmp_path, monkeypatch):
    sub = tmp_path / "scen"
    sub.mkdir()
    (sub / "t.csv").write_text("lat_deg,lon_deg\n55.0,37.0\n55.001,37.0005\n55.002,37.001\n55.003,37.0015\n",
                               encoding="utf-8")
    path = _scenario_file(sub, 'name="t"\n[timing]\nduration_s=2.0\n[track]\nfile="t.csv"\n')
    monkeypatch.chdir(tmp_path)  # the current directory has no t.csv: the scenario's folder is used
    sim = Simulator(load_scenario(path))
    assert sim.track.length > 300.0


@pytest.mark.parametrize("section,field,message", [
    ('[gnss]\noverrides = { pseudorange_sigma_m = -3.0 }', "gnss.overrides.pseudorange_sigma_m", "got -3.0"),
    ('[gnss]\noverrides = { sigma = 1.0 }', "gnss.overrides.sigma", "a field of GnssErrorModel"),
    ('[imu.gyro]\nscale_factor = "x"', "imu.gyro.scale_factor", "got 'x'"),  # was a ValueError traceback
    ('[imu.accel]\nwhite_noise_density = -1', "imu.accel.white_noise_density", "got -1"),
])
def test_sensor_model_overrides_are_checked_when_the_file_is_read(tmp_path, capsys, section, field, message):
    """`navsim show` refuses what `navsim run` would: the sensor models' overrides are built
    by the validation pass of loading, and the one-line error names the file and the field
    as the file spells it (not the model's internal name, not the array it became)."""
    path = tmp_path / "mine.toml"
    path.write_text(f'name = "mine"\n{section}\n', encoding="utf-8")
    assert main(["show", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith(f"navsim: error: mine.toml: {field}: expected") and message in err
