"""A fixed battery of bad inputs through the CLI and the Python API, each classified.

    python tools/bad_inputs.py [--jobs 2] [--only SUBSTRING] [--json OUT.json]

Every case runs in a fresh Python process (``sys.executable``; navsim as that interpreter
imports it, so ``PYTHONPATH=OTHER_TREE`` runs the battery against another checkout) in its
own temporary folder, and is classified as

clear-error
    the CLI exits with status 2 and one line on stderr, no traceback; an API call raises
    navsim's own error type (:class:`navsim.errors.NavsimError`);
traceback
    anything else that fails: a Python traceback, another exit status, another
    exception type, or no answer within the time limit;
accepted
    the bad input went through without an error (exit status 0);
warned
    an input that is legitimate by the documentation but probably not meant (a case
    marked ``expect="warning"``: a track file without heights, 0 m by the documented
    default) went through with exit status 0 and one ``navsim: warning:`` line; the
    same case without the warning is *accepted*;
data-lost
    a file that existed before the call (a previous output) is gone, changed or
    half-written afterwards; this class wins over the others.

Categories: scenario files (non-UTF-8, invalid TOML, zero / negative / NaN fields, wrong
types, unknown keys), track files (degenerate, doubling back, corrupt, non-UTF-8), paths
(bundled names with separators, unreadable almanacs), CLI arguments, output paths blocked
by a file in the way, corrupt campaign databases and specs, Gymnasium kwargs and actions,
and the FMU's parameters through fmpy (skipped when fmpy or the FMU build is not
available). An FMU case is a clear error only when ``exitInitializationMode`` returns the
error status (not Fatal) and the FMU's log holds one line with the parameter, the
expectation and the value (the case's ``words``). The script prints a Markdown table (one row per case) and the counts per
class. The default test suite runs a sample of it (``tests/test_bad_inputs.py``, one case or two
per category; the FMU sample in ``tests/fmu/test_bad_parameters.py``) and the whole
battery under the ``slow`` mark.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sqlite3
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

CLI = "import sys\nfrom navsim.cli import main\nsys.exit(main(sys.argv[1:]))\n"

PY = """import sys
try:
    from navsim.errors import NavsimError
except ImportError:  # pragma: no cover - a tree without the error hierarchy
    NavsimError = ValueError
try:
{body}
except NavsimError as exc:
    print("CLEAR", type(exc).__name__, str(exc).splitlines()[0][:200], file=sys.stderr)
    sys.exit(2)
"""

SHORT = ["--set", "timing.duration_s=1"]
GOOD_TRACK_CSV = "lat_deg,lon_deg,h_m\n" + "".join(f"55.{i:04d},37.{i:04d},150\n" for i in range(0, 2000, 100))


@dataclass
class Case:
    name: str
    category: str
    kind: str  # "cli" or "py"
    payload: object  # argv list (cli) or Python body (py)
    files: dict = field(default_factory=dict)  # name -> str | bytes written before the run
    keep: tuple = ()  # files that must survive unchanged (a previous output)
    timeout: float = 240.0
    expect: str = "error"  # "error", or "warning": a documented default, accepted with one warning line


def _scenario(extra: str, base: str = "paper-2012") -> str:
    """A scenario file: the bundled base (its text from the installed navsim) plus TOML lines."""
    return f"__BASE__:{base}\n{extra}"


def _toml_scen(sections: str) -> dict:
    return {"s.toml": _scenario(sections)}


def cases() -> list[Case]:
    c: list[Case] = []
    add = c.append
    # ------------------------------------------------------------------ scenario files
    scen = [
        ("non-UTF-8 scenario file", {"s.toml": b'name = "x\xff\xfe"\n'}),
        ("invalid TOML", {"s.toml": "name = \n[timing\n"}),
        ("empty scenario file", {"s.toml": ""}),
        ("oscillation frequency_hz = 0", _toml_scen(
            '[[motion.oscillations]]\nangle = "pitch"\nfrequency_hz = 0.0\namplitude_deg = 0.1\n')),
        ("oscillation above the IMU Nyquist (1 kHz on 100 Hz)", _toml_scen(
            '[[motion.oscillations]]\nangle = "pitch"\nfrequency_hz = 1000.0\namplitude_deg = 0.1\n')),
        ("imu.gyro is a string", {"s.toml": 'name = "x"\n[imu]\ngyro = "fast"\n'}),
        ("imu.gyro.scale_factor is a string", {"s.toml": 'name = "x"\n[imu.gyro]\nscale_factor = "x"\n'}),
        ("gnss.overrides negative sigma", {"s.toml": '[gnss]\noverrides = { pseudorange_sigma_m = -3.0 }\n'}),
        ("timing.duration_s = 0", {"s.toml": "[timing]\nduration_s = 0.0\n"}),
        ("timing.duration_s = -5", {"s.toml": "[timing]\nduration_s = -5.0\n"}),
        ("timing.duration_s = nan", {"s.toml": "[timing]\nduration_s = nan\n"}),
        ("timing.duration_s = inf", {"s.toml": "[timing]\nduration_s = inf\n"}),
        ("timing.duration_s is a string", {"s.toml": '[timing]\nduration_s = "long"\n'}),
        ("timing.nav_period_s = 0", {"s.toml": "[timing]\nnav_period_s = 0.0\n"}),
        ("timing.tick_s = 1e-9 (memory)", {"s.toml": "[timing]\ntick_s = 1e-9\nimu_period_s = 1e-9\n"
                                                       "nav_period_s = 1e-9\n"}),
        ("timing.gnss_period_s not a multiple of the step", {"s.toml": "[timing]\ngnss_period_s = 0.333\n"}),
        ("unknown section", {"s.toml": "[nonsense]\na = 1\n"}),
        ("unknown key in timing", {"s.toml": "[timing]\nduraton_s = 5.0\n"}),
        ("outage window before t = 0", {"s.toml": "[outages]\nwindows_s = [[-5.0, 4.0]]\n"}),
        ("outage window reversed", {"s.toml": "[outages]\nwindows_s = [[5.0, 4.0]]\n"}),
        ("outage windows is a string", {"s.toml": '[outages]\nwindows_s = "none"\n'}),
        ("unknown constellation", {"s.toml": '[gnss]\nconstellation = "galileo"\n'}),
        ("constellation yuma:/etc/passwd", {"s.toml": '[gnss]\nconstellation = "yuma:/etc/passwd"\n'}),
        ("constellation yuma: of a missing file", {"s.toml": '[gnss]\nconstellation = "yuma:nope.alm"\n'}),
        ("track.bundled with ../", {"s.toml": '[track]\nbundled = "../../../etc/x"\n'}),
        ("track.bundled absolute", {"s.toml": '[track]\nbundled = "/etc/passwd"\n'}),
        ("track.bundled unknown", {"s.toml": '[track]\nbundled = "nope"\n'}),
        ("track.file missing", {"s.toml": '[track]\nbundled = ""\nfile = "none.csv"\n'}),
        ("imu.orders = 0", {"s.toml": "[imu]\norders = 0\n"}),
        ("imu.orders = 9", {"s.toml": "[imu]\norders = 9\n"}),
        ("imu.preset unknown", {"s.toml": '[imu]\npreset = "magic"\n'}),
        ("gnss.preset unknown", {"s.toml": '[gnss]\npreset = "magic"\n'}),
        ("motion.speed_mps negative", {"s.toml": "[motion]\nspeed_mps = -3.0\n"}),
        ("motion.profile unknown", {"s.toml": '[motion]\nprofile = "teleport"\n'}),
        ("timetable with one station", {"s.toml": '[motion]\nprofile = "timetable"\nstations = [{s_m = 100.0}]\n'}),
        ("elevation mask 120 deg", {"s.toml": "[outages]\nelevation_mask_deg = 120.0\n"}),
        ("lever arm of 2 numbers", {"s.toml": "[gnss]\nlever_arm_m = [0.0, 1.0]\n"}),
        ("earth model unknown", {"s.toml": 'earth = "flat"\n'}),
    ]
    raw = ("non-UTF-8 scenario file", "invalid TOML", "empty scenario file")
    for name, files in scen:
        if name not in raw and not files["s.toml"].startswith("__BASE__"):
            files = {"s.toml": _scenario(files["s.toml"])}  # the bundled scenario, 1 s long, plus the bad lines
        add(Case(name, "scenario file", "cli", ["simulate", "s.toml", "-q", "-o", "out.npz"], files))
    # ------------------------------------------------------------------ track files
    tracks = [
        ("2-point CSV track", "t.csv", "lat_deg,lon_deg,h_m\n55.0,37.0,100\n55.01,37.0,100\n"),
        ("track doubling back", "t.csv", "lat_deg,lon_deg,h_m\n55.0,37.0,100\n55.01,37.0,100\n55.02,37.0,100\n"
                                         "55.01,37.0001,100\n55.0,37.0002,100\n"),
        ("all points identical", "t.csv", "lat_deg,lon_deg,h_m\n" + "55.0,37.0,100\n" * 6),
        ("CSV with text in a cell", "t.csv", "lat_deg,lon_deg,h_m\n55.0,37.0,100\n55.01,north,100\n55.02,37.0,100\n"
                                             "55.03,37.0,100\n"),
        ("CSV without a height column (0 m, warned)", "t.csv",
         "lat_deg,lon_deg\n55.0,37.0\n55.01,37.0\n55.02,37.0\n55.03,37.0\n"),
        ("CSV without a longitude column", "t.csv", "lat_deg,h_m\n55.0,100\n55.01,100\n55.02,100\n55.03,100\n"),
        ("CSV with latitude 95 deg", "t.csv", "lat_deg,lon_deg,h_m\n95.0,37.0,100\n95.01,37.0,100\n95.02,37.0,100\n"
                                              "95.03,37.0,100\n"),
        ("non-UTF-8 CSV", "t.csv", b"lat_deg,lon_deg,h_m\n55.0,37.0,100\xff\n"),
        ("GeoJSON that is not JSON", "t.geojson", "{not json"),
        ("GeoJSON without coordinates", "t.geojson", '{"type": "Feature", "geometry": {"type": "LineString"}}'),
        ("GeoJSON of a Point", "t.geojson", '{"type": "Feature", "geometry": {"type": "Point", "coordinates": [37, 55]}}'),
        ("GPX with an entity bomb", "t.gpx", '<?xml version="1.0"?><!DOCTYPE x [<!ENTITY a "aaaaaaaa">'
                                             '<!ENTITY b "&a;&a;&a;&a;">]><gpx>&b;</gpx>'),
        ("GPX that is not XML", "t.gpx", "<gpx><trk>"),
        ("track file of an unknown format", "t.xyz", "1 2 3\n"),
        ("empty CSV", "t.csv", ""),
    ]
    for name, fname, text in tracks:
        files = {"s.toml": _scenario(f'[track]\nbundled = ""\nfile = "{fname}"\n'), fname: text}
        add(Case(name, "track file", "cli", ["simulate", "s.toml", "-q", "-o", "out.npz", *SHORT], files,
                 expect="warning" if "warned" in name else "error"))
    # ------------------------------------------------------------------ CLI arguments
    cli = [
        ("--seed -1", ["simulate", "paper-2012", "--seed", "-1", "-q", "-o", "o.npz", *SHORT]),
        ("--seed text", ["simulate", "paper-2012", "--seed", "abc", "-q", "-o", "o.npz", *SHORT]),
        ("--chunk 0", ["simulate", "paper-2012", "--chunk", "0", "-q", "-o", "o.npz", *SHORT]),
        ("--chunk -3", ["simulate", "paper-2012", "--chunk", "-3", "-q", "-o", "o.npz", *SHORT]),
        ("--set without =", ["show", "paper-2012", "--set", "timing.duration_s"]),
        ("--set unknown key", ["show", "paper-2012", "--set", "timing.nosuch=1"]),
        ("--set text for a number", ["show", "paper-2012", "--set", "timing.duration_s=abc"]),
        ("--set duration 0", ["show", "paper-2012", "--set", "timing.duration_s=0"]),
        ("unknown scenario name", ["show", "no-such-scenario"]),
        ("scenario path that does not exist", ["show", "missing/s.toml"]),
        ("unknown sub-command", ["frobnicate"]),
        ("run with an unknown estimator", ["run", "paper-2012", "--estimator", "magic", "-q", *SHORT]),
        ("run with an unknown option", ["run", "paper-2012", "--estimator", "lc-ekf", "--option", "bogus=1", "-q",
                                        *SHORT]),
        ("run with a malformed option", ["run", "paper-2012", "--estimator", "lc-ekf", "--option", "bogus", "-q",
                                         *SHORT]),
        ("run with an import path that does not exist", ["run", "paper-2012", "--estimator", "no_mod:Thing", "-q",
                                                         *SHORT]),
        ("run --divergence-threshold-m 0", ["run", "paper-2012", "--estimator", "gnss-ls",
                                            "--divergence-threshold-m", "0", "-q", *SHORT]),
        ("run --divergence-threshold-m nan", ["run", "paper-2012", "--estimator", "gnss-ls",
                                              "--divergence-threshold-m", "nan", "-q", *SHORT]),
        ("bench --seeds 5:2", ["bench", "paper-2012", "--estimators", "gnss-ls", "--seeds", "5:2", "-q", *SHORT]),
        ("bench --seeds text", ["bench", "paper-2012", "--estimators", "gnss-ls", "--seeds", "a:b", "-q", *SHORT]),
        ("bench --estimators empty", ["bench", "paper-2012", "--estimators", "", "--seeds", "0:1", "-q", *SHORT]),
        ("bench --interval unknown", ["bench", "paper-2012", "--estimators", "gnss-ls", "--seeds", "0:1",
                                      "--interval", "magic", "-q", *SHORT]),
        ("paper with an unknown seed", ["paper", "999"]),
        ("fmu build with an unknown --what", ["fmu", "build", "paper-2012", "--what", "nothing", "-o", "x.fmu"]),
        ("campaign of a missing spec", ["campaign", "missing.toml"]),
    ]
    for name, argv in cli:
        add(Case(name, "CLI argument", "cli", argv))
    # ------------------------------------------------------------------ outputs blocked / previous outputs
    blocker = {"blocked": "a file where a folder should be\n"}
    prev = b"PREVIOUS OUTPUT, must survive"
    outs = [
        ("simulate -o into a file-in-the-way folder", ["simulate", "paper-2012", "-q", "-o", "blocked/o.npz", *SHORT],
         blocker, ()),
        ("simulate CSV into a file-in-the-way folder", ["simulate", "paper-2012", "-q", "-o", "blocked/o.csv", *SHORT],
         blocker, ()),
        ("simulate --plot into a file-in-the-way folder", ["simulate", "paper-2012", "-q", "-o", "o.npz", "--plot",
                                                          "blocked/p.png", *SHORT], blocker, ()),
        ("bench --out is a file", ["bench", "paper-2012", "--estimators", "gnss-ls", "--seeds", "0:1", "-q", "--out",
                                   "blocked", *SHORT], blocker, ()),
        ("bench --out below a file", ["bench", "paper-2012", "--estimators", "gnss-ls", "--seeds", "0:1", "-q",
                                      "--out", "blocked/b", *SHORT], blocker, ()),
        ("run --plot into a file-in-the-way folder", ["run", "paper-2012", "--estimator", "gnss-ls", "-q", "--plot",
                                                     "blocked/p.png", *SHORT], blocker, ()),
        ("simulate -o onto a folder", ["simulate", "paper-2012", "-q", "-o", "adir", *SHORT], {"adir/keep": prev},
         ("adir/keep",)),
        ("bad --set keeps the previous output", ["simulate", "paper-2012", "-q", "-o", "o.npz", "--set",
                                                 "timing.duration_s=-1"], {"o.npz": prev}, ("o.npz",)),
        ("bad scenario keeps the previous CSV", ["simulate", "s.toml", "-q", "-o", "o.csv"],
         {"o.csv": prev, "s.toml": "[timing]\nduration_s = 0.0\n"}, ("o.csv",)),
        ("failed bench keeps the previous bench.md", ["bench", "paper-2012", "--estimators", "magic", "--seeds",
                                                      "0:1", "-q", "--out", "b", *SHORT], {"b/bench.md": prev},
         ("b/bench.md",)),
    ]
    for name, argv, files, keep in outs:
        add(Case(name, "output path", "cli", argv, dict(files), keep))
    # ------------------------------------------------------------------ campaigns
    spec = ('[campaign]\nseeds = "0:1"\ndatabase = "db.sqlite"\n[overrides]\ntiming = { duration_s = 1.0 }\n'
            '[[scenarios]]\nname = "paper-2012"\n[[estimators]]\nname = "gnss-ls"\n')
    camp = [
        ("database of random bytes", {"c.toml": spec, "db.sqlite": os.urandom(4096)}, ("db.sqlite",)),
        ("database truncated after the header", {"c.toml": spec, "db.sqlite": b"SQLite format 3\x00" + b"\x10" * 84},
         ("db.sqlite",)),
        ("database with a foreign schema", {"c.toml": spec, "db.sqlite": "__SQLITE_FOREIGN__"}, ("db.sqlite",)),
        ("database scored before the divergence check", {"c.toml": spec, "db.sqlite": "__SQLITE_SCORE_V1__"},
         ("db.sqlite",)),
        ("database of a newer navsim", {"c.toml": spec, "db.sqlite": "__SQLITE_NEWER__"}, ("db.sqlite",)),
        ("database path is a folder", {"c.toml": spec, "db.sqlite/x": "x"}, ()),
        ("spec of invalid TOML", {"c.toml": "[campaign\n"}, ()),
        ("spec non-UTF-8", {"c.toml": b"[campaign]\nname = \"\xff\"\n"}, ()),
        ("spec seeds text", {"c.toml": spec.replace('"0:1"', '"many"')}, ()),
        ("spec without scenarios", {"c.toml": '[campaign]\nseeds = "0:1"\n[[estimators]]\nname = "gnss-ls"\n'}, ()),
        ("spec with an unknown estimator", {"c.toml": spec.replace('name = "gnss-ls"', 'name = "magic"')}, ()),
        ("spec override of a bundled path", {"c.toml": spec.replace("timing = { duration_s = 1.0 }",
                                                                    'track = { bundled = "../../x" }')}, ()),
        ("spec divergence threshold negative", {"c.toml": spec.replace("[campaign]\n",
                                                                       "[campaign]\ndivergence_threshold_m = -1\n")},
         ()),
    ]
    for name, files, keep in camp:
        add(Case(name, "campaign", "cli", ["campaign", "c.toml", "--workers", "1", "-q"], files, keep))
    # ------------------------------------------------------------------ Python API
    api = [
        ("load_scenario of a missing bundled name", "from navsim.scenario import load_scenario\n"
                                                    "load_scenario('nope')"),
        ("with_overrides of an unknown section", "from navsim.scenario import load_scenario\n"
                                                 "load_scenario('paper-2012').with_overrides({'bogus': {}})"),
        ("with_overrides duration None", "from navsim.scenario import load_scenario\n"
                                         "load_scenario('paper-2012').with_overrides({'timing': {'duration_s': None}})"),
        ("Simulator.reset(-1)", "from navsim.scenario import load_scenario\nfrom navsim.simulator import Simulator\n"
                                "Simulator(load_scenario('paper-2012').with_overrides({'timing': {'duration_s': 1.0}}))"
                                ".reset(-1)"),
        ("estimators.make of an unknown name", "from navsim import estimators\nestimators.make('magic')"),
        ("estimators.make with a bad option", "from navsim import estimators\nestimators.make('lc-ekf', bogus=1)"),
        ("gym: duration -1", "import gymnasium as gym, navsim\ngym.make('navsim/PaperRail-v0', "
                             "timing={'duration_s': -1.0}).reset(seed=0)"),
        ("gym: unknown kwarg", "import gymnasium as gym, navsim\ngym.make('navsim/PaperRail-v0', warp=9)"),
        ("gym: reward_cap -1", "import gymnasium as gym, navsim\ngym.make('navsim/PaperRail-v0', reward_cap=-1.0)"),
        ("gym: reward_weights of 2", "import gymnasium as gym, navsim\n"
                                     "gym.make('navsim/PaperRail-v0', reward_weights=(1.0, 2.0))"),
        ("gym: bundled track path", "import gymnasium as gym, navsim\n"
                                    "gym.make('navsim/PaperRail-v0', track={'bundled': '/etc/passwd'}).reset(seed=0)"),
        ("gym vector: num_envs 0", "import gymnasium as gym, navsim\ngym.make_vec('navsim/PaperRail-v0', num_envs=0, "
                                   "vectorization_mode='vector_entry_point')"),
        ("gym: action of shape (3,)", "import gymnasium as gym, numpy as np, navsim\n"
                                      "e = gym.make('navsim/PaperRail-v0', timing={'duration_s': 1.0}).unwrapped\n"
                                      "e.reset(seed=0)\ne.step(np.zeros(3))"),
        ("gym: action of shape (20,)", "import gymnasium as gym, numpy as np, navsim\n"
                                       "e = gym.make('navsim/PaperRail-v0', timing={'duration_s': 1.0}).unwrapped\n"
                                       "e.reset(seed=0)\ne.step(np.zeros(20))"),
        ("gym: action of strings", "import gymnasium as gym, numpy as np, navsim\n"
                                   "e = gym.make('navsim/PaperRail-v0', timing={'duration_s': 1.0}).unwrapped\n"
                                   "e.reset(seed=0)\ne.step(np.array(['a'] * 9))"),
        ("gym vector: actions of shape (9,)", "import gymnasium as gym, numpy as np, navsim\n"
                                              "e = gym.make_vec('navsim/PaperRail-v0', num_envs=2, vectorization_mode="
                                              "'vector_entry_point', timing={'duration_s': 1.0})\n"
                                              "e.reset(seed=0)\ne.step(np.zeros(9))"),
        ("gym vector: complex actions", "import gymnasium as gym, numpy as np, navsim\n"
                                        "e = gym.make_vec('navsim/PaperRail-v0', num_envs=2, vectorization_mode="
                                        "'vector_entry_point', timing={'duration_s': 1.0})\n"
                                        "e.reset(seed=0)\ne.step(np.zeros((2, 9), complex))"),
        ("gym adaptive: action of shape (5,)", "import gymnasium as gym, numpy as np, navsim\n"
                                               "e = gym.make('navsim/AdaptiveFilter-v0', timing={'duration_s': 3.0})\n"
                                               "e.reset(seed=0)\ne.step(np.zeros(5))"),
        ("gym adaptive: NaN action", "import gymnasium as gym, numpy as np, navsim\n"
                                     "e = gym.make('navsim/AdaptiveFilter-v0', timing={'duration_s': 3.0})\n"
                                     "e.reset(seed=0)\ne.step(np.array([np.nan, 0.0]))"),
        ("gym driving: action of shape (4,)", "import gymnasium as gym, numpy as np, navsim\n"
                                              "e = gym.make('navsim/TrainDriving-v0')\n"
                                              "e.reset(seed=0)\ne.step(np.zeros(4))"),
        ("gym driving: string action", "import gymnasium as gym, numpy as np, navsim\n"
                                       "e = gym.make('navsim/TrainDriving-v0')\n"
                                       "e.reset(seed=0)\ne.step('go')"),
    ]
    for name, body in api:
        add(Case(name, "Python API / Gymnasium", "py", body))
    # ------------------------------------------------------------------ FMU parameters (fmpy)
    fmu = [  # (name, start values, words the FMU's log line must hold: parameter, expectation, value)
        ("FMU seed = -1", "{'seed': -1}", ("seed: expected", "got -1")),
        ("FMU scenario.overrides not TOML", "{'scenario.overrides': 'timing = ['}",
         ("scenario.overrides: expected TOML", "got 'timing = [")),
        ("FMU scenario.overrides bundled path", "{'scenario.overrides': 'track = { bundled = \"../../x\" }'}",
         ("track.bundled: expected", "got '../../x'")),
        ("FMU scenario.overrides duration -1", "{'scenario.overrides': 'timing = { duration_s = -1.0 }'}",
         ("timing.duration_s: expected", "got -1.0")),
        ("FMU imu preset unknown", "{'imu.preset': 'magic'}", ("imu.preset: expected", "got 'magic'")),
    ]
    for name, params, words in fmu:
        body = ("import fmpy\nfrom pathlib import Path\n"
                "fmu = Path(__FMU__)\n"
                "if not fmu.exists():\n    sys.exit(77)\n"
                "log = []\n"
                "def logger(env, instance, status, category, message):\n"
                "    log.append((status, message.decode('utf-8', 'replace')))\n"
                "try:\n"
                f"    fmpy.simulate_fmu(str(fmu), stop_time=0.05, step_size=0.01, start_values={params}, logger=logger)\n"
                "except Exception as exc:\n"
                "    lines = [m for st, m in log if st >= 3]\n"
                f"    named = [m for m in lines if all(w in m for w in {words!r})]\n"
                "    if getattr(exc, 'status', None) == 3 and len(lines) == 1 and named:\n"
                "        print('CLEAR', named[0][:200], file=sys.stderr)\n"
                "        sys.exit(2)\n"
                "    print('FMU status', getattr(exc, 'status', None), 'log', lines, file=sys.stderr)\n"
                "    raise\n")
        add(Case(name, "FMU parameter", "fmu", body))
    return c


def _base_text(base: str) -> str:
    code = ("from navsim.scenario import load_scenario\n"
            f"print(load_scenario({base!r}).to_toml())\n")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout


def _write_files(folder: Path, files: dict, base_cache: dict) -> None:
    for name, content in files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, str) and content.startswith("__BASE__:"):
            first, _, rest = content.partition("\n")
            base = first.split(":", 1)[1]
            if base not in base_cache:
                base_cache[base] = _base_text(base)
            content = _merge_toml(base_cache[base], rest)
        if content == "__SQLITE_FOREIGN__":
            con = sqlite3.connect(path)
            con.execute("CREATE TABLE episodes (x INTEGER)")
            con.execute("CREATE TABLE meta (key TEXT, value TEXT)")
            con.commit()
            con.close()
        elif content in ("__SQLITE_SCORE_V1__", "__SQLITE_NEWER__"):
            _versioned_database(path, content)
        elif isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")


# the campaign table of navsim's layout (navsim/campaign/database.py), written here so the
# battery also runs against trees that have no version keys
_EPISODES = """CREATE TABLE episodes (id INTEGER PRIMARY KEY, scenario_hash TEXT NOT NULL, estimator TEXT NOT NULL,
options TEXT NOT NULL, seed INTEGER NOT NULL, scenario TEXT NOT NULL, estimator_label TEXT NOT NULL,
status TEXT NOT NULL, scores TEXT, outages TEXT, samples BLOB, error TEXT, wall_s REAL, worker TEXT,
finished_utc TEXT NOT NULL, UNIQUE (scenario_hash, estimator, options, seed));
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
"""


def _versioned_database(path: Path, kind: str) -> None:
    """A campaign database with one finished row: of the navsim before the divergence check
    (no version keys, no stored threshold) or of a newer navsim (score version 99)."""
    con = sqlite3.connect(path)
    con.executescript(_EPISODES)
    con.execute("INSERT INTO episodes VALUES (1, 'h', 'gnss-ls', '{}', 0, 'paper-2012', 'gnss-ls', 'ok', "
                "'{\"rmse_h_m\": 1.0}', '[]', NULL, NULL, 1.0, 'w', '2026-01-01T00:00:00+00:00')")
    if kind == "__SQLITE_NEWER__":
        con.executemany("INSERT INTO meta VALUES (?, ?)", [("format", "navsim-campaign"), ("schema_version", "1"),
                                                         ("score_version", "99")])
    con.commit()
    con.close()


def _merge_toml(base: str, extra: str) -> str:
    """The base scenario's TOML with the sections of ``extra`` merged in (extra wins)."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    import tomli_w

    data = tomllib.loads(base)
    data.pop("name", None)
    add = tomllib.loads(extra) if extra.strip() else {}

    def merge(a, b):
        for k, v in b.items():
            if isinstance(v, dict) and isinstance(a.get(k), dict):
                merge(a[k], v)
            else:
                a[k] = v

    merge(data, {"timing": {"duration_s": 1.0}})  # short episodes; the extra lines may set it again
    merge(data, add)
    data["name"] = "battery"
    return tomli_w.dumps(data)


def run_case(case: Case, root: Path, base_cache: dict, fmu_path: str | None) -> dict:
    folder = Path(tempfile.mkdtemp(prefix="case-", dir=root))
    _write_files(folder, case.files, base_cache)
    kept = {k: (folder / k).read_bytes() for k in case.keep}
    if case.kind == "cli":
        argv = [sys.executable, "-c", CLI, *case.payload]
    else:
        body = str(case.payload)
        if case.kind == "fmu":
            if fmu_path is None:
                return {"name": case.name, "category": case.category, "class": "skipped",
                        "detail": "no FMU (fmpy or the build missing)"}
            body = body.replace("__FMU__", repr(fmu_path))
        indented = "\n".join("    " + line for line in body.splitlines())
        argv = [sys.executable, "-c", PY.format(body=indented)]
    try:
        proc = subprocess.run(argv, cwd=folder, capture_output=True, text=True, timeout=case.timeout,
                              errors="replace")
        rc, err = proc.returncode, proc.stderr
    except subprocess.TimeoutExpired:
        rc, err = None, "timeout"
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    lost = []
    for k, data in kept.items():
        p = folder / k
        if not p.is_file() or p.read_bytes() != data:
            lost.append(k)
    if case.kind == "fmu" and rc == 77:
        cls, detail = "skipped", "no FMU"
    elif lost:
        cls, detail = "data-lost", f"changed or removed: {', '.join(lost)}"
    elif rc == 0 and case.expect == "warning" and len(lines) == 1 and lines[0].startswith("navsim: warning:"):
        cls, detail = "warned", lines[0][:160]
    elif rc == 0:
        cls, detail = "accepted", "exit 0" + (" (no warning line)" if case.expect == "warning" else "")
    elif rc == 2 and "Traceback" not in err and (case.kind != "cli" or len(lines) == 1):
        cls, detail = "clear-error", lines[-1][:160] if lines else ""
    else:
        tail = lines[-1][:160] if lines else ""
        cls, detail = "traceback", f"exit {rc}: {tail}"
    shutil.rmtree(folder, ignore_errors=True)
    return {"name": case.name, "category": case.category, "class": cls, "detail": detail}


def _build_fmu(root: Path) -> str | None:
    """Build the plant FMU once (None when fmpy or the build is unavailable)."""
    out = root / "plant.fmu"
    code = ("import sys\nimport fmpy\nfrom navsim.cli import main\n"
            f"sys.exit(main(['fmu', 'build', 'paper-2012', '--what', 'plant', '--fmi', '2', '-o', {str(out)!r}]))\n")
    try:
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=600)
    except subprocess.TimeoutExpired:
        return None
    return str(out) if proc.returncode == 0 and out.exists() else None


CLASSES = ("clear-error", "warned", "traceback", "accepted", "data-lost", "skipped")


def markdown(results: list[dict]) -> str:
    lines = ["| # | category | case | class | detail |", "|---|---|---|---|---|"]
    for i, r in enumerate(results, 1):
        detail = r["detail"].replace("|", "\\|").replace("\n", " ")
        lines.append(f"| {i} | {r['category']} | {r['name']} | {r['class']} | {detail} |")
    counts = {c: sum(r["class"] == c for r in results) for c in CLASSES}
    lines += ["", f"{len(results)} cases: " + ", ".join(f"{counts[c]} {c}" for c in CLASSES)]
    return "\n".join(lines) + "\n"


def main_results(jobs: int = 2, only: str = "", no_fmu: bool = False, progress: bool = False) -> list[dict]:
    """Run the battery (the cases whose name contains ``only``); one result dict per case."""
    todo = [c for c in cases() if only.lower() in c.name.lower()]
    with tempfile.TemporaryDirectory(prefix="navsim-bad-inputs-") as tmp:
        root = Path(tmp)
        fmu_path = None if no_fmu or not any(c.kind == "fmu" for c in todo) else _build_fmu(root)
        base_cache: dict = {"paper-2012": _base_text("paper-2012")}
        results = []
        with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
            for r in pool.map(lambda c: run_case(c, root, base_cache, fmu_path), todo):
                results.append(r)  # each result as it comes, so an interrupted run keeps its part
                if progress:
                    print(f"{len(results)}/{len(todo)} {r['class']:11s} {r['category']}: {r['name']}: {r['detail']}",
                          file=sys.stderr, flush=True)
    return results


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--only", default="", help="run the cases whose name contains this text")
    p.add_argument("--json", default=None, help="also write the results as JSON here")
    p.add_argument("--no-fmu", action="store_true", help="skip the FMU cases")
    args = p.parse_args(argv)
    results = main_results(args.jobs, args.only, args.no_fmu, progress=True)
    print(markdown(results), end="")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(results, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
