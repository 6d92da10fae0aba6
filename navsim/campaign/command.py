"""The ``navsim campaign`` subcommand: its parser (:func:`add_campaign_parser`) and
:func:`cmd_campaign` (run what is missing, then write the report).
"""


from __future__ import annotations

import argparse

from ..errors import ConfigError
from .executors import run_campaign
from .results import write_report
from .spec import load_campaign


def cmd_campaign(args: argparse.Namespace) -> int:
    """``navsim campaign``: run what is missing, then write the report."""
    spec = load_campaign(args.spec)
    if not args.report_only:
        res = run_campaign(spec, scheduler=args.scheduler, workers=args.workers, retry_failed=args.retry_failed,
                           progress=not args.quiet)
        print(f"{spec.name}: {res.total} episodes, {res.skipped} already in {spec.database.name}, "
              f"{res.ran} run now ({res.failed} failed) in {res.wall_s:.1f} s")
    elif not spec.database.exists():
        raise ConfigError("--report-only", f"an existing database {spec.database.name} (run the campaign first)",
                          str(spec.database))
    paths = write_report(spec, plots=not args.no_plots)
    print(paths[1])
    return 0


def add_campaign_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``navsim campaign`` on an argparse sub-parser collection."""
    p = subparsers.add_parser("campaign", help="Monte Carlo campaign from a TOML spec, locally or on a Dask cluster")
    p.add_argument("spec", help="campaign TOML file (results go to an SQLite database beside it)")
    p.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="run on this Dask distributed scheduler (needs navsim-track[campaign])")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local worker processes (default: every core; 0 = in this process)")
    p.add_argument("--report-only", action="store_true", help="only write the report from the database")
    p.add_argument("--retry-failed", action="store_true", help="run again the episodes recorded as failed")
    p.add_argument("--no-plots", action="store_true", help="report without PNG files")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_campaign)
    return p
