"""The argument parser of ``navsim`` (:func:`build_parser`): every sub-command, argparse errors
as one line with exit status 2.
"""

from __future__ import annotations

import argparse
from typing import Callable, NoReturn

from .commands import cmd_estimators, cmd_paper, cmd_scenarios, cmd_show, cmd_simulate


def _int_at_least(low: int, what: str) -> Callable[[str], int]:
    """An argparse type: an integer >= ``low`` (``what`` names it in the error)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = low - 1  # refused below, with the same message
        if value < low:
            raise argparse.ArgumentTypeError(f"expected {what} >= {low}, got {text!r}")
        return value

    return parse


_seed = _int_at_least(0, "an integer")  # a seed is an integer >= 0
_positive_int = _int_at_least(1, "a whole number")


class _Parser(argparse.ArgumentParser):
    """argparse with the one-line error of the rest of the command (exit status 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = _Parser(prog="navsim", description="The ``navsim`` command.")
    parser.add_argument("--version", action="version", version=f"navsim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    sub.add_parser("scenarios", help="list the bundled scenarios").set_defaults(func=cmd_scenarios)

    p = sub.add_parser("estimators", help="list the estimators, their options and availability")
    p.add_argument("names", nargs="*", help="only these names or import paths")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(func=cmd_estimators)

    p = sub.add_parser("show", help="print the resolved scenario as TOML")
    p.add_argument("scenario", help="bundled scenario name or path to a .toml file")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a field, e.g. timing.duration_s=60")
    p.set_defaults(func=cmd_show)

    p = sub.add_parser("simulate", help="write truth and measurements of one episode")
    p.add_argument("scenario", help="bundled scenario name or path to a .toml file")
    p.add_argument("--seed", type=_seed, default=0)
    p.add_argument("-o", "--output", required=True, help="output file (.npz or .csv; its folder is created if missing)")
    p.add_argument("--format", choices=("npz", "csv"), help="default: from the file suffix")
    p.add_argument("--chunk", type=_positive_int, default=10_000, help="steps generated per chunk (memory bound)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a field")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.add_argument("--plot", default=None, metavar="PNG", help="also write a plot of the episode")
    p.set_defaults(func=cmd_simulate)

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
    p.set_defaults(func=cmd_paper)
    return parser
