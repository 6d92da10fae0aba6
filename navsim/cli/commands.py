"""The handlers of the core sub-commands of ``navsim``: ``scenarios``, ``estimators``, ``show``,
``simulate`` and ``paper`` (``run`` and ``bench``: :mod:`navsim.report`; ``campaign``:
:mod:`navsim.campaign`; ``fmu``: :mod:`navsim.fmu.cli`).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Iterator

from ..errors import NavsimError
from ..overrides import scenario_from_args as _scenario

if TYPE_CHECKING:  # type hints only
    from ..simulator import Chunk


def cmd_scenarios(args: argparse.Namespace) -> int:
    from ..scenario import list_scenarios, load_scenario

    for name in list_scenarios():
        print(f"{name:24s} {load_scenario(name).description}")
    return 0


def cmd_estimators(args: argparse.Namespace) -> int:
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


def cmd_show(args: argparse.Namespace) -> int:
    print(_scenario(args).to_toml(), end="")
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
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

    def chunks() -> Iterator[Chunk]:
        for chunk in sim.chunks(args.chunk):
            bar.update(len(chunk))
            yield chunk

    n_sats = len(sim.constellation.prn)
    paths: tuple[Path, ...]
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


def cmd_paper(args: argparse.Namespace) -> int:
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


def _fmt(value: object) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)
