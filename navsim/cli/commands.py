"""The ``navsim`` command.

Sub-commands
------------
``navsim --version``                         print the installed version
``navsim scenarios``                         list the bundled scenarios
``navsim estimators [NAME ...] [--json]``    list the estimators, their options and availability
``navsim show SCENARIO``                     print the resolved scenario as TOML
``navsim simulate SCENARIO --seed N -o F``   write truth and measurements (NPZ or CSV)
``navsim run SCENARIO --estimator NAME``     score one estimator on one episode
``navsim bench SCENARIO --estimators A,B``   compare estimators across seeds
``navsim campaign SPEC.toml [--scheduler]``  scenarios x estimators x seeds, local or on Dask
``navsim paper 000|001|003 [--json]``        rerun a seed paper's experiments
``navsim fmu build|validate|cosim|run|info``  FMUs: export navsim, import motion FMUs

Exit status: 0 on success, 2 on bad input (the message names the field), 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..errors import NavsimError
from ..overrides import scenario_from_args as _scenario

__all__ = ["main"]


def _cmd_scenarios(args) -> int:
    from ..scenario import list_scenarios, load_scenario

    for name in list_scenarios():
        print(f"{name:24s} {load_scenario(name).description}")
    return 0


def _cmd_estimators(args) -> int:
    from ..estimators import describe

    infos = describe(args.names or None)
    if args.json:
        print(json.dumps([{"name": i.name, "target": i.target, "available": i.available, "missing": i.missing,
                           "options": {k: (v if isinstance(v, (int, float, str, bool)) or v is None else repr(v))
                                       for k, v in i.options.items()},
                           "summary": i.summary} for i in infos], indent=1))
        return 0
    for i in infos:
        state = "" if i.available else f"  [unavailable: {i.missing}]"
        print(f"{i.name:16s} {i.target}{state}")
        if i.summary:
            print(f"{'':16s} {i.summary}")
        if i.options:
            print(f"{'':16s} options: " + ", ".join(f"{k}={v!r}" for k, v in i.options.items()))
    print("\nAny other estimator: give its import path package.module:Factory (or file.py:Factory) "
          "wherever a name is taken.")
    return 0


def _cmd_show(args) -> int:
    print(_scenario(args).to_toml(), end="")
    return 0


def _cmd_simulate(args) -> int:
    from tqdm import tqdm

    from ..io import check_output_dir, write_csv, write_npz
    from ..simulator import Simulator

    scenario = _scenario(args)
    sim = Simulator(scenario)
    sim.reset(args.seed)
    out = Path(args.output)
    check_output_dir(out.parent)  # before the episode is simulated
    fmt = args.format or ("csv" if out.suffix == ".csv" else "npz")
    total = scenario.timing.steps
    bar = tqdm(total=total, unit="step", disable=args.quiet or None, desc=f"simulate {scenario.name}", file=sys.stderr)

    def chunks():
        for chunk in sim.chunks(args.chunk):
            bar.update(len(chunk))
            yield chunk

    n_sats = len(sim.constellation.prn)
    if fmt == "csv":
        paths = write_csv(out, chunks(), n_sats=n_sats)
    else:
        meta = {"scenario_toml": scenario.to_toml(), "seed": -1 if args.seed is None else args.seed,
                "config_hash": scenario.config_hash()}
        paths = (write_npz(out, chunks(), meta=meta, n_sats=n_sats),)
    bar.close()
    for path in paths:
        print(path)
    if args.plot:
        import numpy as np

        from ..plots import plot_episode

        if fmt == "csv":
            raise NavsimError("--plot: expected an .npz output to plot from, got a CSV output")
        with np.load(paths[0]) as data:
            print(plot_episode(data, args.plot, title=f"{scenario.name}, seed {args.seed}"))
    return 0


def _cmd_paper(args) -> int:
    import importlib

    try:
        module = importlib.import_module(f"navsim.paper.seed{args.seed_id}")
    except ModuleNotFoundError:
        raise NavsimError(f"seed: expected one of 000, 001, 003 with its reproduction installed, got {args.seed_id!r}") from None
    kwargs = {"plot_dir": args.plot_dir, "quick": args.quick}
    if args.seeds is not None:
        import inspect

        if "seeds" not in inspect.signature(module.run).parameters:
            raise NavsimError(f"--seeds: seed {args.seed_id}'s reproduction has fixed runs; only 003 takes --seeds")
        from ..report import parse_seeds

        kwargs["seeds"] = parse_seeds(args.seeds)
    from ..provenance import provenance, provenance_line

    rows = module.run(**kwargs)
    scenarios = None
    if args.seed_id == "003":  # its experiments run on the bundled paper-2012 scenarios
        from ..scenario import list_scenarios, load_scenario

        scenarios = {n: load_scenario(n) for n in list_scenarios() if n.startswith("paper-2012")}
    prov = provenance(scenarios)
    if args.json:
        # provenance as rows of the same schema, so the output stays one list of rows
        rows = list(rows) + [{"ref": "provenance", "quantity": k, "paper": None, "navsim": v, "unit": ""}
                             for k, v in prov.items()]
        print(json.dumps(rows, indent=1))
        return 0
    header = ("ref", "quantity", "paper", "navsim", "unit")
    table = [[row["ref"], row["quantity"], _fmt(row["paper"]), _fmt(row["navsim"]), row["unit"]]
             for row in rows if "text" not in row]
    widths = [max(len(str(r[i])) for r in [header, *table]) + 2 for i in range(5)]
    for cells in [header, *table]:
        print("".join(str(c).ljust(w) for c, w in zip(cells, widths)).rstrip())
    for row in rows:  # the experiment table and the verdicts (seed 003)
        if "text" in row:
            print(f"\n{row['ref']}, {row['quantity']}:\n{row['text']}")
    print(f"\nProvenance: {provenance_line(prov)}")
    if args.plot_dir:
        print(f"plots in {args.plot_dir}", file=sys.stderr)
    return 0


def _fmt(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _seed(text: str) -> int:
    """argparse type: a seed is an integer >= 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}")
    return value


def _positive_int(text: str) -> int:
    """argparse type: a whole number >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return value


class _Parser(argparse.ArgumentParser):
    """argparse with the one-line error of the rest of the command (exit status 2)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = _Parser(prog="navsim", description=__doc__.split("\n")[0])
    parser.add_argument("--version", action="version", version=f"navsim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    sub.add_parser("scenarios", help="list the bundled scenarios").set_defaults(func=_cmd_scenarios)

    p = sub.add_parser("estimators", help="list the estimators, their options and availability")
    p.add_argument("names", nargs="*", help="only these names or import paths")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(func=_cmd_estimators)

    p = sub.add_parser("show", help="print the resolved scenario as TOML")
    p.add_argument("scenario", help="bundled scenario name or path to a .toml file")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a field, e.g. timing.duration_s=60")
    p.set_defaults(func=_cmd_show)

    p = sub.add_parser("simulate", help="write truth and measurements of one episode")
    p.add_argument("scenario", help="bundled scenario name or path to a .toml file")
    p.add_argument("--seed", type=_seed, default=0)
    p.add_argument("-o", "--output", required=True, help="output file (.npz or .csv)")
    p.add_argument("--format", choices=("npz", "csv"), help="default: from the file suffix")
    p.add_argument("--chunk", type=_positive_int, default=10_000, help="steps generated per chunk (memory bound)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a field")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.add_argument("--plot", default=None, metavar="PNG", help="also write a plot of the episode")
    p.set_defaults(func=_cmd_simulate)

    from ..report import add_bench_parser, add_run_parser

    add_run_parser(sub)
    add_bench_parser(sub)
    from ..campaign import add_campaign_parser

    add_campaign_parser(sub)
    try:
        from ..fmu.cli import add_fmu_parser
    except ImportError:  # the FMU face is installed with the package; its extras may not be
        pass
    else:
        add_fmu_parser(sub)

    p = sub.add_parser("paper", help="rerun a seed paper's experiments beside its printed figures")
    p.add_argument("seed_id", choices=("000", "001", "003"))
    p.add_argument("--json", action="store_true", help="print rows as JSON")
    p.add_argument("--plot-dir", default=None, help="write one PNG per experiment here")
    p.add_argument("--quick", action="store_true", help="shorter runs (for smoke tests)")
    p.add_argument("--seeds", default=None, help="seeds A:B of the experiment table (003 only; default 0:10)")
    p.set_defaults(func=_cmd_paper)
    return parser


def expected_failure(exc: BaseException) -> str | None:
    """The one-line message of an expected failure (bad input, I/O, a corrupt file), or
    None for anything else (a bug: its traceback is kept). Messages name the file and the
    reason, never the file's contents."""
    import sqlite3
    import zipfile

    if isinstance(exc, NavsimError):
        return str(exc)
    if isinstance(exc, UnicodeDecodeError):
        return f"a file is not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at offset {exc.start})"
    if isinstance(exc, OSError):
        where = f": {Path(exc.filename).name}" if getattr(exc, "filename", None) else ""
        return f"{exc.strerror or type(exc).__name__}{where}"
    if isinstance(exc, sqlite3.DatabaseError):
        return f"a database cannot be used ({exc})"
    if isinstance(exc, (zipfile.BadZipFile, EOFError)):
        return f"a file is truncated or not the expected archive ({type(exc).__name__})"
    if isinstance(exc, MemoryError):
        return "not enough memory for these settings (fewer steps per chunk, a longer IMU period or a shorter episode)"
    return None


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a bad argument (one line, status 2)
        return exc.code if isinstance(exc.code, int) else 2
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("navsim: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        message = expected_failure(exc)
        if message is None:
            raise
        print(f"navsim: error: {' '.join(message.split())}", file=sys.stderr)
        return 2


