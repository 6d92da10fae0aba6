"""The ``navsim run`` and ``navsim bench`` reports: one episode scored, or many compared.

``navsim run SCENARIO --estimator NAME --seed N``
    simulate one episode, run one estimator on it (:func:`navsim.episode.run_episode`)
    and print its :class:`~navsim.metrics.EpisodeScore` as a table of figures with
    units, or with ``--json`` exactly one flat JSON object (keys carry units, NaN ->
    null); ``--plot FILE.png`` draws the errors against time with the GNSS outages
    shaded and +-3 sigma bounds from the estimator's covariance.
``navsim bench SCENARIO --estimators A,B,C --seeds 0:20 [--out DIR]``
    every estimator on every seed. Each seed's episode is simulated once and replayed
    to every estimator (a deep copy per estimator, so no estimator can disturb
    another's input); the numbers are identical to ``navsim run`` of that estimator
    and seed because the simulator is chunk-invariant and both use the same chunk
    length. A failing estimator on one seed is recorded with its error and the bench
    goes on. The table across estimators gives the mean and a 95 % interval across
    seeds (Student-t interval of the mean by default, ``--interval percentile`` for
    the spread of single runs; see :func:`navsim.metrics.aggregate`); with ``--out DIR``
    it is written as ``bench.md``, ``bench.csv`` and ``bench.json`` with the per-run
    rows in ``runs.csv`` and the plots ``bench_errors.png`` (error distributions per
    estimator), ``bench_outages.png`` (maximum drift per outage) and
    ``bench_nees.png`` (Monte Carlo NEES with chi-square bounds).

Both sub-commands are registered on an argparse sub-parser collection by
:func:`add_run_parser` and :func:`add_bench_parser` (``navsim.cli`` calls them). Bad
input raises :class:`~navsim.errors.ConfigError` (the CLI prints it and exits 2).
"""

from __future__ import annotations

import argparse
import copy
import csv
import io
import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterator, Sequence

import numpy as np

from .errors import ConfigError
from .metrics import (
    DIVERGENCE_NEES_WINDOW_S,
    SCORE_FIELDS,
    EpisodeScore,
    McNees,
    MetricSummary,
    aggregate,
    error_series,
    monte_carlo_nees,
    nees_components,
    nees_series,
    score_episode,
)
from .provenance import provenance, provenance_line

if TYPE_CHECKING:  # type hints only
    from .episode import EpisodeRecord
    from .scenario import Scenario
    from .simulator import Chunk, Simulator, Start

__all__ = [
    "add_run_parser",
    "format_cell",
    "add_bench_parser",
    "cmd_run",
    "cmd_bench",
    "parse_seeds",
    "parse_options",
    "run_one",
    "BenchResult",
    "bench",
    "format_score_table",
    "divergence_text",
    "diverged_counts",
    "bench_markdown",
    "bench_summary_csv",
    "bench_runs_csv",
    "bench_json",
    "write_bench",
    "CHUNK_STEPS",
    "KEY_METRICS",
]

CHUNK_STEPS = 10_000
"""Steps per simulated chunk, the same for ``run`` and ``bench`` (estimators with a batch
fast path see chunk-sized batches, so equal chunks keep their numbers identical)."""

KEY_METRICS = (
    "horizontal_rmse_m", "horizontal_cep95_m", "horizontal_final_m", "vertical_rmse_m", "along_track_rmse_m",
    "cross_track_rmse_m", "velocity_rms_mps", "attitude_rms_deg", "outage_max_drift_m", "outage_rms_drift_m",
    "anees", "nis_normalised", "diverged", "step_time_us",
)
"""The metrics of the short table printed by ``navsim bench`` (all are in the files)."""

_CACHE_LIMIT_BYTES = 1.5e9


# ============================================================================ parsing
def _toml_value(text: str) -> Any:
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib

    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text  # a bare string


def parse_options(items: Sequence[str], estimators: Sequence[str] | None = None) -> dict[str | None, dict]:
    """``--option`` items into keyword options per estimator.

    ``KEY=VALUE`` applies to every estimator (key None in the result);
    ``NAME.KEY=VALUE`` only to estimator NAME (which must be among ``estimators`` when
    given). Values are TOML (``3``, ``1e-3``, ``true``, ``"text"``, ``[1, 2]``) or a bare
    string.
    """
    out: dict[str | None, dict] = {}
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError("--option", "KEY=VALUE or ESTIMATOR.KEY=VALUE", item)
        name, dot, sub = key.rpartition(".")
        target = name if dot else None
        if target is not None and estimators is not None and target not in estimators:
            raise ConfigError("--option", f"an estimator of the run ({', '.join(estimators)}) before the dot", item)
        out.setdefault(target, {})[sub if dot else key] = _toml_value(value.strip())
    return out


def _options_for(options: dict[str | None, dict], name: str) -> dict:
    merged = dict(options.get(None, {}))
    merged.update(options.get(name, {}))
    return merged


def parse_seeds(text: str) -> list[int]:
    """Seeds from ``"A:B"`` (A..B-1, Python range), ``"A:B:STEP"``, ``"1,4,7"`` or ``"N"``."""
    text = str(text).strip()
    try:
        if ":" in text:
            parts = [int(p) for p in text.split(":")]
            if len(parts) not in (2, 3):
                raise ValueError
            seeds = list(range(*parts))
        else:
            seeds = [int(p) for p in text.split(",") if p.strip()]
    except ValueError:
        raise ConfigError("--seeds", "A:B (seeds A..B-1), A:B:STEP, a comma list or one integer", text) from None
    if not seeds or min(seeds) < 0:
        raise ConfigError("--seeds", "at least one non-negative seed", text)
    if len(set(seeds)) != len(seeds):
        raise ConfigError("--seeds", "distinct seeds", text)
    return seeds


def _check_estimators(names: Sequence[str]) -> list[str]:
    from .estimators import available, check

    names = [n.strip() for n in names if n.strip()]
    field = "--estimators" if len(names) != 1 else "--estimator"
    if not names:
        raise ConfigError(field, f"estimator names among {', '.join(available()) or '(none installed)'} "
                          "or import paths package.module:Factory", "")
    for n in names:
        try:
            check(n)
        except ConfigError as exc:
            raise ConfigError(field, exc.expected, n) from None
    if len(set(names)) != len(names):
        raise ConfigError("--estimators", "distinct names", ",".join(names))
    return names


def _load_scenario(args: argparse.Namespace) -> Scenario:
    from .overrides import scenario_from_args

    return scenario_from_args(args)


# ============================================================================ running
class _Replay:
    """A simulator stand-in that hands out one seed's cached episode (deep copies).

    ``run_episode`` calls ``reset(seed)``, reads the model attributes through
    :func:`navsim.episode.make_context` and iterates ``chunks(n)``; everything else is
    delegated to the real simulator.
    """

    def __init__(self, sim: Simulator, seed: int | None, chunk_steps: int):
        self._sim = sim
        self._seed = seed
        self._chunk_steps = chunk_steps
        self._start = sim.reset(seed)
        self._chunks = list(sim.chunks(chunk_steps))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sim, name)

    def reset(self, seed: int | None = None) -> Start:
        if seed != self._seed:
            raise RuntimeError(f"replay of seed {self._seed} asked for seed {seed}")
        return copy.deepcopy(self._start)

    def chunks(self, chunk_steps: int = CHUNK_STEPS) -> Iterator[Chunk]:
        if chunk_steps != self._chunk_steps:
            raise RuntimeError(f"replay cached with chunks of {self._chunk_steps} steps, asked for {chunk_steps}")
        for chunk in self._chunks:
            yield copy.deepcopy(chunk)


def _cache_bytes(scenario: Scenario) -> float:
    """Rough memory of one cached episode (IMU multiple integrals dominate)."""
    timing = scenario.timing
    r = scenario.imu.orders
    per_step = 8 * (2 * timing.samples_per_step * (r * 3 + 3) + 2 * r * 3 + 60)
    return float(timing.steps) * per_step


def run_one(scenario: Scenario, estimator_name: str, seed: int | None, options: dict | None = None, *,
            progress: Callable[[int], None] | None = None, simulator: Simulator | None = None) -> EpisodeRecord:
    """Build the estimator by name and run one episode; returns the EpisodeRecord."""
    from .episode import run_episode
    from .estimators import make

    estimator = make(estimator_name, **(options or {}))
    return run_episode(scenario, estimator, seed, name=estimator_name, chunk_steps=CHUNK_STEPS,
                       progress=progress, simulator=simulator)


@dataclass
class BenchResult:
    """Everything a bench produced.

    scores[name][seed] : EpisodeScore of the runs that finished. failures : list of
    ``{"estimator", "seed", "error"}``. summary[name][metric] : MetricSummary across the
    seeds. horizontal_samples[name] : horizontal errors pooled over seeds (subsampled
    evenly in time, m), for distribution plots. mc_nees[name] : Monte Carlo NEES over
    the seeds (on the subsampled grid ``mc_t``) or None.
    """

    scenario: str
    estimators: list[str]
    seeds: list[int]
    method: str
    confidence: float
    scores: dict[str, dict[int, EpisodeScore]] = field(default_factory=dict)
    failures: list[dict] = field(default_factory=list)
    provenance: dict = field(default_factory=dict)
    summary: dict[str, dict[str, MetricSummary]] = field(default_factory=dict)
    horizontal_samples: dict[str, np.ndarray] = field(default_factory=dict)
    mc_t: np.ndarray | None = None
    mc_nees: dict[str, McNees | None] = field(default_factory=dict)


def bench(scenario: Scenario, estimators: Sequence[str], seeds: Sequence[int], options: dict | None = None, *,
          method: str = "t", confidence: float = 0.95, divergence_threshold_m: float = 1000.0,
          divergence_nees_window_s: float = DIVERGENCE_NEES_WINDOW_S,
          progress: Callable[[int], None] | None = None, describe: Callable[[str], None] | None = None,
          max_samples: int = 2000) -> BenchResult:
    """Run every estimator on every seed; one simulation per seed (see module docstring).

    Parameters
    ----------
    scenario : Scenario. estimators : registry names (checked against
        :func:`navsim.estimators.available`). seeds : ints.
    options : ``{None: {...}, name: {...}}`` keyword options (see :func:`parse_options`).
    method, confidence : interval of :func:`navsim.metrics.aggregate`.
    divergence_threshold_m, divergence_nees_window_s : the divergence checks of
        :func:`navsim.metrics.detect_divergence` (a diverged run has NaN accuracy figures).
    progress : callable(n_steps) for a progress bar; describe : callable(text) told
        which estimator and seed is running.
    max_samples : horizontal-error samples kept per episode for the plots.
    """
    from .estimators import make
    from .simulator import Simulator, build_track

    names = _check_estimators(list(estimators))
    options = options or {}
    from .metrics import detect_divergence

    detect_divergence(np.zeros(0), {}, np.zeros(0), threshold_m=divergence_threshold_m,  # checks the settings
                      nees_window_s=divergence_nees_window_s)
    for name in names:  # bad options are a configuration error: fail before simulating
        make(name, **_options_for(options, name))
    seeds = list(seeds)
    result = BenchResult(scenario.name, names, seeds, method, confidence, provenance=provenance(scenario))
    sim = Simulator(scenario)
    track = build_track(scenario)
    steps = scenario.timing.steps
    stride = max(1, steps // max_samples)
    cache = _cache_bytes(scenario) <= _CACHE_LIMIT_BYTES
    samples: dict[str, list] = {n: [] for n in names}
    nees_runs: dict[str, list] = {n: [] for n in names}
    for seed in seeds:
        source = _Replay(sim, seed, CHUNK_STEPS) if cache else sim
        for name in names:
            if describe is not None:
                describe(f"{name} seed {seed}")
            done = [0]

            def tick(k: int, done: list[int] = done) -> None:
                done[0] += k
                if progress is not None:
                    progress(k)

            try:
                record = run_one(scenario, name, seed, _options_for(options, name), progress=tick,
                                 simulator=source)  # type: ignore[arg-type]  # a _Replay delegates to the Simulator
                series = error_series(record, track)
                score = score_episode(record, series=series, divergence_threshold_m=divergence_threshold_m,
                                      divergence_nees_window_s=divergence_nees_window_s)
            except Exception as exc:  # noqa: BLE001 - a failing estimator is a result, not a crash
                result.failures.append({"estimator": name, "seed": seed, "error": f"{type(exc).__name__}: {exc}"})
                if progress is not None and steps > done[0]:
                    progress(steps - done[0])
                continue
            result.scores.setdefault(name, {})[seed] = score
            if not score.diverged:  # the pooled error distribution leaves diverged runs out, as the means do
                samples[name].append(series.horizontal_m[stride - 1::stride])
            if record.est_cov is not None and score.nees_dof:
                comps = nees_components(record.est_cov)
                x, d = nees_series(series.error, record.est_cov, comps)
                nees_runs[name].append((d, x[stride - 1::stride]))
        del source
    result.mc_t = (np.arange(steps) + 1)[stride - 1::stride] * scenario.timing.nav_period_s
    for name in names:
        got = [result.scores.get(name, {}).get(s) for s in seeds]
        result.summary[name] = aggregate([g for g in got if g is not None], method=method, confidence=confidence)
        result.horizontal_samples[name] = np.concatenate(samples[name]) if samples[name] else np.zeros(0)
        dofs = {d for d, _ in nees_runs[name]}
        result.mc_nees[name] = (monte_carlo_nees(np.array([x for _, x in nees_runs[name]]), dofs.pop(), confidence)
                                if len(dofs) == 1 else None)
    return result


# ============================================================================ formatting
def _fmt(value: Any, width: int = 0) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        text = "-"
    elif isinstance(value, (bool, np.bool_)):
        text = "yes" if value else "no"
    elif isinstance(value, float):
        text = f"{value:.4g}"
    else:
        text = str(value)
    return text.ljust(width) if width else text


def format_score_table(score: EpisodeScore) -> str:
    """The score as an aligned text table: figure, value, unit, description."""
    flat = score.to_flat_dict()
    rows = [(name, _fmt(flat[name]), unit, text) for name, (unit, text) in SCORE_FIELDS.items()
            if name != "divergence_reason"]
    w = [max(len(r[i]) for r in rows) for i in range(3)]
    lines = [f"{'figure'.ljust(w[0])}  {'value'.ljust(w[1])}  {'unit'.ljust(w[2])}  description"]
    lines += [f"{a.ljust(w[0])}  {b.ljust(w[1])}  {c.ljust(w[2])}  {d}" for a, b, c, d in rows]
    if score.diverged:
        lines.append(f"{divergence_text(score)}; the accuracy figures of a diverged episode are not given (-)")
    for i, o in enumerate(score.outages, 1):
        end = "" if o.closed else " (GNSS not back by the end)"
        lines.append(f"outage {i}: GNSS epochs {o.t_first:g}-{o.t_last:g} s ({o.n_epochs} epochs, {o.duration_s:g} s), "
                     f"max horizontal drift {_fmt(o.max_drift_m)} m at {o.t_max:.6g} s{end}")
    return "\n".join(lines)


def divergence_text(score: EpisodeScore) -> str:
    """``"diverged at 123.4 s (reason)"`` for a diverged episode, "" otherwise."""
    if not score.diverged:
        return ""
    return f"diverged at {_fmt(score.diverged_at_s)} s ({score.divergence_reason})"


def diverged_counts(result: "BenchResult") -> dict[str, int]:
    """Per estimator, how many of its finished runs diverged."""
    return {n: sum(bool(sc.diverged) for sc in result.scores.get(n, {}).values()) for n in result.estimators}


def format_cell(s: MetricSummary) -> str:
    """A table cell: ``mean [low, high]`` of a summary, the mean alone without an interval, "-" if empty."""
    if s.n == 0:
        return "-"
    if not math.isfinite(s.low):
        return _fmt(s.mean)
    return f"{_fmt(s.mean)} [{_fmt(s.low)}, {_fmt(s.high)}]"


def bench_markdown(result: BenchResult, metrics: Sequence[str] | None = None) -> str:
    """Markdown: one row per metric, one column per estimator, cells ``mean [low, high]``."""
    from .metrics import NUMERIC_FIELDS

    metrics = list(metrics) if metrics is not None else [
        m for m in NUMERIC_FIELDS if m not in ("duration_s", "steps", "divergence_threshold_m")]
    interval = ("Student-t interval of the mean" if result.method == "t" else "percentile interval of the runs")
    units = EpisodeScore.units()
    lines = [f"# navsim bench: {result.scenario}", "",
             f"Seeds {_seed_text(result.seeds)} ({len(result.seeds)}); cells: mean across seeds "
             f"[{100 * result.confidence:g} % {interval}]; 'diverged' is the fraction of runs. The accuracy "
             "cells average only the runs that did not diverge (their figures are NaN, see "
             "navsim.metrics.detect_divergence); the diverged runs are listed below the table.", ""]
    if result.provenance:
        lines += [f"Provenance: {provenance_line(result.provenance)}", ""]
    names = result.estimators
    lines.append("| metric | unit | " + " | ".join(names) + " |")
    lines.append("|---|---|" + "---|" * len(names))
    runs = [str(len(result.scores.get(n, {}))) + "/" + str(len(result.seeds)) for n in names]
    lines.append("| runs finished | | " + " | ".join(runs) + " |")
    div = diverged_counts(result)
    lines.append("| diverged runs (left out of the accuracy cells) | | "
                 + " | ".join(f"{div[n]}/{len(result.scores.get(n, {}))}" for n in names) + " |")
    for m in metrics:
        cells = [format_cell(result.summary[n][m]) for n in names]
        lines.append(f"| {m} | {units[m]} | " + " | ".join(cells) + " |")
    mc = [(n, mcn) for n in names if (mcn := result.mc_nees.get(n)) is not None]
    if mc:
        lines += ["", "Monte Carlo NEES (average over seeds per step, 95 % bounds chi2(M d)/M):", ""]
        for n, mcn in mc:
            lines.append(f"- {n}: d = {mcn.dof}, time-average {_fmt(mcn.anees)}, "
                         f"steps inside the bounds {_fmt(100 * mcn.in_bounds_fraction)} %")
    diverged = [(n, seed, sc) for n in names for seed, sc in sorted(result.scores.get(n, {}).items()) if sc.diverged]
    if diverged:
        lines += ["", "Diverged runs:", ""]
        lines += [f"- {n} seed {seed}: {divergence_text(sc)}" for n, seed, sc in diverged]
    if result.failures:
        lines += ["", "Failures:", ""]
        lines += [f"- {f['estimator']} seed {f['seed']}: {f['error']}" for f in result.failures]
    return "\n".join(lines) + "\n"


def _seed_text(seeds: Sequence[int]) -> str:
    if len(seeds) > 1 and list(seeds) == list(range(seeds[0], seeds[-1] + 1)):
        return f"{seeds[0]}-{seeds[-1]}"
    return ",".join(str(s) for s in seeds)


def bench_summary_csv(result: BenchResult) -> str:
    """CSV, one row per estimator: runs, failures, and mean/low/high/n of every metric."""
    from .metrics import NUMERIC_FIELDS

    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    header = ["estimator", "runs", "failures"]
    for m in NUMERIC_FIELDS:
        header += [f"{m}.mean", f"{m}.low", f"{m}.high", f"{m}.n"]
    writer.writerow(header)
    for n in result.estimators:
        row = [n, len(result.scores.get(n, {})), sum(f["estimator"] == n for f in result.failures)]
        for m in NUMERIC_FIELDS:
            d = result.summary[n][m].as_dict()
            row += ["" if d[k] is None else d[k] for k in ("mean", "low", "high", "n")]
        writer.writerow(row)
    return buf.getvalue()


def bench_runs_csv(result: BenchResult) -> str:
    """CSV, one row per estimator and seed: the flat score, or the error of a failed run."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    names = list(SCORE_FIELDS)
    writer.writerow(names + ["error"])
    failed = {(f["estimator"], f["seed"]): f["error"] for f in result.failures}
    for n in result.estimators:
        for s in result.seeds:
            score = result.scores.get(n, {}).get(s)
            if score is not None:
                flat = score.to_flat_dict()
                writer.writerow(["" if flat[k] is None else flat[k] for k in names] + [""])
            elif (n, s) in failed:
                row = {"scenario": result.scenario, "estimator": n, "seed": s}
                writer.writerow([row.get(k, "") for k in names] + [failed[(n, s)]])
    return buf.getvalue()


def bench_json(result: BenchResult) -> dict:
    """The whole bench as one JSON-safe dict (summary, runs with outages, failures)."""
    runs = []
    for n in result.estimators:
        for s in result.seeds:
            score = result.scores.get(n, {}).get(s)
            if score is not None:
                row = score.to_flat_dict()
                row["outages"] = [o.as_dict() for o in score.outages]
                runs.append(row)
    mc = {}
    for n, m in result.mc_nees.items():
        if m is not None:
            mc[n] = {"dof": m.dof, "runs": int(m.runs.max()) if len(m.runs) else 0,
                     "anees": _json_float(m.anees), "in_bounds_fraction": _json_float(m.in_bounds_fraction)}
    return {
        "scenario": result.scenario, "estimators": result.estimators, "seeds": result.seeds,
        "interval": {"method": result.method, "confidence": result.confidence},
        "summary": {n: {k: v.as_dict() for k, v in result.summary[n].items()} for n in result.estimators},
        "monte_carlo_nees": mc, "runs": runs, "failures": result.failures,
        "provenance": result.provenance,
    }


def _json_float(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def write_bench(result: BenchResult, out_dir: str | Path, plots: bool = True) -> list[Path]:
    """Write bench.md, bench.csv, runs.csv, bench.json and the plots into ``out_dir``."""
    from .io import write_text_atomic

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for fname, text in (("bench.md", bench_markdown(result)), ("bench.csv", bench_summary_csv(result)),
                        ("runs.csv", bench_runs_csv(result)),
                        ("bench.json", json.dumps(bench_json(result), indent=1) + "\n")):
        path = out / fname
        write_text_atomic(path, text)  # whole or not at all (renamed into place)
        paths.append(path)
    if plots:
        from .plots import plot_bench_errors, plot_mc_nees, plot_outage_drifts

        per_seed = {n: [result.scores[n][s] for s in result.seeds if s in result.scores.get(n, {})]
                    for n in result.estimators}
        title = f"{result.scenario}, seeds {_seed_text(result.seeds)}"
        paths.append(plot_bench_errors(result.horizontal_samples, per_seed, out / "bench_errors.png", title=title))
        paths.append(plot_outage_drifts(per_seed, out / "bench_outages.png", title=title))
        mc = {n: m for n, m in result.mc_nees.items() if m is not None}
        if mc:
            paths.append(plot_mc_nees(result.mc_t, mc, out / "bench_nees.png",  # type: ignore[arg-type]  # set with mc_nees
                                      title=title))
    return paths


# ============================================================================ commands
def _bar(total: int, quiet: bool, desc: str) -> Any:
    from tqdm import tqdm

    return tqdm(total=total, unit="step", disable=quiet or None, desc=desc, file=sys.stderr, leave=False)


def cmd_run(args: argparse.Namespace) -> int:
    """``navsim run``: one estimator on one episode."""
    scenario = _load_scenario(args)
    name = _check_estimators([args.estimator])[0]
    options = _options_for(parse_options(args.option or []), name)
    from .metrics import detect_divergence

    detect_divergence(np.zeros(0), {}, np.zeros(0), threshold_m=args.divergence_threshold_m,  # before the episode
                      nees_window_s=args.divergence_nees_window_s)
    bar = _bar(scenario.timing.steps, args.quiet, f"{name} on {scenario.name}")
    try:
        record = run_one(scenario, name, args.seed, options, progress=bar.update)
    finally:
        bar.close()
    series = error_series(record)
    score = score_episode(record, series=series, divergence_threshold_m=args.divergence_threshold_m,
                          divergence_nees_window_s=args.divergence_nees_window_s)
    prov = provenance(scenario)
    if args.json:
        print(json.dumps({**score.to_flat_dict(), **{k: prov[k] for k in
                                                     ("navsim_version", "command", "scenario_hash", "date_utc")}}))
    else:
        print(f"# {name} on {scenario.name}, seed {args.seed}")
        print(format_score_table(score))
        print(f"\nProvenance: {provenance_line(prov)}")
    if args.plot:
        from .plots import plot_errors

        title = f"{name} on {scenario.name}, seed {args.seed}"
        if score.diverged:
            title += f" (diverged at {_fmt(score.diverged_at_s)} s)"
        path = plot_errors(series, args.plot, outages=score.outages, title=title)
        print(f"plot: {path}", file=sys.stderr if args.json else sys.stdout)
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    """``navsim bench``: every estimator on every seed, table across estimators."""
    scenario = _load_scenario(args)
    names = _check_estimators(args.estimators.split(","))
    seeds = parse_seeds(args.seeds)
    options = parse_options(args.option or [], names)
    if args.out:
        from .io import check_output_dir

        check_output_dir(args.out)  # before any episode is computed
    bar = _bar(scenario.timing.steps * len(seeds) * len(names), args.quiet, f"bench {scenario.name}")
    try:
        result = bench(scenario, names, seeds, options, method=args.interval,
                       divergence_threshold_m=args.divergence_threshold_m,
                       divergence_nees_window_s=args.divergence_nees_window_s, progress=bar.update,
                       describe=bar.set_postfix_str)
    finally:
        bar.close()
    paths = write_bench(result, args.out, plots=not args.no_plots) if args.out else []
    if args.json:
        print(json.dumps(bench_json(result)))
    else:
        print(bench_markdown(result, KEY_METRICS), end="")
    for path in paths:
        print(path, file=sys.stderr if args.json else sys.stdout)
    return 0


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", help="bundled scenario name or path to a .toml file")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario field, e.g. timing.duration_s=60")
    p.add_argument("--divergence-threshold-m", type=float, default=1000.0, metavar="M",
                   help="horizontal error that flags divergence (default 1000 m)")
    p.add_argument("--divergence-nees-window-s", type=float, default=DIVERGENCE_NEES_WINDOW_S, metavar="S",
                   help="the NEES must exceed the chi2 0.9999 quantile at 80 %% of some window this long to flag "
                        f"divergence (default {DIVERGENCE_NEES_WINDOW_S:g} s; inf: no NEES check)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def add_run_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``navsim run`` on an argparse sub-parser collection."""
    p = subparsers.add_parser("run", help="run one estimator on one episode and score it")
    _common(p)
    p.add_argument("--estimator", required=True, help="estimator name (navsim estimators) or import path package.module:Factory")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="estimator option (TOML value), repeatable")
    p.add_argument("--plot", default=None, metavar="PNG", help="write errors vs time with +-3 sigma bounds")
    p.set_defaults(func=cmd_run)
    return p


def add_bench_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``navsim bench`` on an argparse sub-parser collection."""
    p = subparsers.add_parser("bench", help="every estimator on every seed, compared")
    _common(p)
    p.add_argument("--estimators", required=True, metavar="A,B,C",
                   help="comma-separated estimator names or import paths package.module:Factory")
    p.add_argument("--seeds", default="0:10", metavar="A:B",
                   help="seeds A..B-1 (default 0:10), or A:B:STEP, or a comma list")
    p.add_argument("--option", action="append", default=[], metavar="[EST.]KEY=VALUE",
                   help="estimator option for all estimators, or for EST only; repeatable")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="write bench.md/.csv/.json, runs.csv and plots here (created if missing)")
    p.add_argument("--interval", choices=("t", "percentile"), default="t",
                   help="95 %% interval: t = Student-t interval of the mean (default), percentile = spread of runs")
    p.add_argument("--no-plots", action="store_true", help="with --out: skip the PNG files")
    p.set_defaults(func=cmd_bench)
    return p
