"""Provenance of a result: which navsim, which command, which scenario, when.

Every output that carries scores (``navsim run --json``, ``navsim bench`` JSON/Markdown,
the campaign report, ``navsim paper --json``) records :func:`provenance`: the installed
navsim version, the command line that produced it, the resolved scenario's configuration
hash (:meth:`navsim.scenario.Scenario.config_hash`, which covers every field of the
resolved scenario) and the UTC date and time, plus the Python and NumPy versions.
"""

from __future__ import annotations

import datetime as _dt
import platform
import shlex
import sys
from typing import Any, Iterable

__all__ = ["provenance", "provenance_line"]


def _command(argv: Iterable[str] | None) -> str:
    args = list(sys.argv if argv is None else argv)
    if args:
        prog = args[0].replace("\\", "/").rsplit("/", 1)[-1]
        args[0] = "navsim" if prog in ("navsim", "__main__.py", "cli.py") else prog
    return shlex.join(args)


def provenance(scenarios: Any = None, *, argv: Iterable[str] | None = None) -> dict[str, Any]:
    """A JSON-safe dict: ``navsim_version``, ``command``, ``scenario_hash`` (one hash, or a
    ``{name: hash}`` dict for several scenarios, or None), ``date_utc`` (ISO 8601),
    ``python``, ``numpy``.

    scenarios : a Scenario, a ``{label: Scenario or hash}`` mapping, or None.
    argv : the command line (default ``sys.argv``).
    """
    import numpy as np

    from . import __version__

    if scenarios is None:
        hashes: Any = None
    elif isinstance(scenarios, dict):
        hashes = {k: (v if isinstance(v, str) else v.config_hash()) for k, v in scenarios.items()}
    else:
        hashes = scenarios.config_hash()
    return {
        "navsim_version": __version__,
        "command": _command(argv),
        "scenario_hash": hashes,
        "date_utc": _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat(),
        "python": platform.python_version(),
        "numpy": np.__version__,
    }


def provenance_line(p: dict[str, Any]) -> str:
    """One line of text for Markdown/console outputs."""
    h = p["scenario_hash"]
    hashes = ", ".join(f"{k} {v}" for k, v in h.items()) if isinstance(h, dict) else (h or "-")
    return (f"navsim {p['navsim_version']}, `{p['command']}`, scenario configuration {hashes}, "
            f"{p['date_utc']} (Python {p['python']}, NumPy {p['numpy']})")
