"""Reading and reporting a campaign: the rows (:func:`read_rows`), the per-scenario aggregates
(:func:`build_results`, mean and 95 % interval by :func:`navsim.metrics.aggregate`) and the
report folder (:func:`write_report`: ``bench.md``, CSV, JSON, plots, ``index.md``,
``index.html``).
"""


from __future__ import annotations

import html
import json
import math
import sqlite3
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ..errors import ConfigError
from .database import check_database, corrupt_database
from .spec import CampaignSpec
from .tasks import episode_tasks

if TYPE_CHECKING:  # type hints only
    from ..metrics import EpisodeScore
    from ..report import BenchResult


def read_rows(database: str | Path, spec: CampaignSpec | None = None) -> list[dict]:
    """Rows of the database as dicts (``scores`` / ``outages`` decoded, ``samples`` as
    a float array); with ``spec`` only the episodes of that campaign. A file of another
    schema or of a newer navsim is refused, an older score version warned about
    (:func:`~navsim.campaign.database.check_database`)."""
    if not Path(database).is_file():
        raise ConfigError("campaign.database", "an existing campaign database", Path(database).name)
    con = sqlite3.connect(str(database), timeout=30.0)
    con.row_factory = sqlite3.Row
    try:
        check_database(con, Path(database), resume=False)  # another schema or a newer navsim: refused
        rows = [dict(r) for r in con.execute("SELECT * FROM episodes ORDER BY id")]
    except sqlite3.DatabaseError as exc:
        raise corrupt_database(Path(database), exc) from None
    finally:
        con.close()
    for r in rows:
        r["scores"] = json.loads(r["scores"]) if r["scores"] else None
        r["outages"] = json.loads(r["outages"]) if r["outages"] else []
        r["samples"] = np.frombuffer(r["samples"], dtype=np.float32).astype(float) if r["samples"] else np.zeros(0)
    if spec is not None:
        keys = {t.key for t in episode_tasks(spec)}
        rows = [r for r in rows if (r["scenario_hash"], r["estimator"], r["options"], r["seed"]) in keys]
    return rows


def _nan_for_none(fields: dict[str, Any]) -> dict[str, Any]:
    return {k: (math.nan if v is None else v) for k, v in fields.items()}


def _score_from_row(row: dict) -> EpisodeScore:
    from ..metrics import SCORE_FIELDS, EpisodeScore, Outage

    flat = row["scores"]
    values: dict[str, Any] = {k: (math.nan if flat.get(k) is None and k != "seed" else flat.get(k)) for k in SCORE_FIELDS}
    values["divergence_reason"] = flat.get("divergence_reason") or ""  # absent from rows of older versions
    outages = tuple(Outage(**_nan_for_none(o)) for o in row["outages"])
    return EpisodeScore(**values, outages=outages)


def build_results(spec: CampaignSpec, rows: list[dict] | None = None) -> dict:
    """One :class:`navsim.report.BenchResult` per scenario label from the database rows
    (estimators named by their labels, mean and interval per metric)."""
    from ..metrics import aggregate
    from ..report import BenchResult

    if rows is None:
        rows = read_rows(spec.database, spec) if Path(spec.database).exists() else []
    labels = {(e.name, e.options_json): e.label for e in spec.estimators}
    out = {}
    for sc in spec.scenarios:
        names = [e.label for e in spec.estimators]
        res = BenchResult(sc.label, names, list(spec.seeds), spec.interval, 0.95)
        samples: dict[str, list] = {n: [] for n in names}
        for r in rows:
            if r["scenario_hash"] != sc.config_hash:
                continue
            label = labels[(r["estimator"], r["options"])]
            if r["status"] == "ok":
                score = _score_from_row(r)
                res.scores.setdefault(label, {})[r["seed"]] = score
                if not score.diverged:  # as navsim.report.bench: diverged runs are left out of the pooled errors
                    samples[label].append(r["samples"])
            else:
                res.failures.append({"estimator": label, "seed": r["seed"], "error": r["error"]})
        for n in names:
            got = [res.scores.get(n, {}).get(s) for s in spec.seeds]
            res.summary[n] = aggregate([g for g in got if g is not None], method=spec.interval, confidence=0.95)
            res.horizontal_samples[n] = np.concatenate(samples[n]) if samples[n] else np.zeros(0)
            res.mc_nees[n] = None
        out[sc.label] = res
    return out


def _html_table(result: BenchResult, metrics: Sequence[str]) -> str:
    from ..metrics import EpisodeScore
    from ..report import diverged_counts, format_cell

    units = EpisodeScore.units()
    names = result.estimators
    head = "".join(f"<th>{html.escape(n)}</th>" for n in names)
    rows = ["<tr><td>runs finished</td><td></td>" + "".join(
        f"<td>{len(result.scores.get(n, {}))}/{len(result.seeds)}</td>" for n in names) + "</tr>"]
    div = diverged_counts(result)
    rows.append("<tr><td>diverged runs (left out of the accuracy cells)</td><td></td>" + "".join(
        f"<td>{div[n]}/{len(result.scores.get(n, {}))}</td>" for n in names) + "</tr>")
    for m in metrics:
        cells = "".join(f"<td>{html.escape(format_cell(result.summary[n][m]))}</td>" for n in names)
        rows.append(f"<tr><td>{html.escape(m)}</td><td>{html.escape(units[m])}</td>{cells}</tr>")
    return f"<table><tr><th>metric</th><th>unit</th>{head}</tr>\n" + "\n".join(rows) + "</table>"


def write_report(spec: CampaignSpec, out_dir: str | Path | None = None, plots: bool = True) -> list[Path]:
    """Write the campaign report: per scenario a folder with navsim.report's bench
    files and plots, and ``index.md`` / ``index.html`` over all scenarios."""
    from ..io import write_text_atomic
    from ..metrics import NUMERIC_FIELDS
    from ..provenance import provenance, provenance_line
    from ..report import KEY_METRICS, bench_markdown, write_bench

    out = Path(out_dir) if out_dir is not None else Path(spec.report_dir)
    out.mkdir(parents=True, exist_ok=True)
    results = build_results(spec)
    metrics = [m for m in NUMERIC_FIELDS if m not in ("duration_s", "steps", "divergence_threshold_m")]
    paths: list[Path] = []
    interval = "Student-t 95 % interval of the mean" if spec.interval == "t" else "95 % percentile interval of the runs"
    md = [f"# navsim campaign: {spec.name}", "",
          f"{len(spec.scenarios)} scenario(s) x {len(spec.estimators)} estimator(s) x {len(spec.seeds)} seed(s) "
          f"= {spec.size} episodes. Cells: mean across seeds [{interval}]; key metrics here, every metric in each "
          "scenario's bench.md / bench.csv.", ""]
    body = [f"<h1>navsim campaign: {html.escape(spec.name)}</h1>",
            f"<p>{len(spec.scenarios)} scenario(s) &times; {len(spec.estimators)} estimator(s) &times; "
            f"{len(spec.seeds)} seed(s) = {spec.size} episodes. Cells: mean across seeds [{interval}].</p>"]
    prov = provenance({sc.label: sc.config_hash for sc in spec.scenarios})
    md += [f"Provenance: {provenance_line(prov)}", ""]
    body.append(f"<p><small>Provenance: {html.escape(provenance_line(prov))}</small></p>")
    for sc in spec.scenarios:
        res = results[sc.label]
        res.provenance = {**prov, "scenario_hash": sc.config_hash}
        folder = out / sc.label
        have_any = any(res.scores.values())
        files = write_bench(res, folder, plots=plots and have_any)
        paths += files
        pngs = [p for p in files if p.suffix == ".png"]
        table = bench_markdown(res, KEY_METRICS).split("\n", 2)[2]
        md += [f"## {sc.label} (configuration {sc.config_hash})", "", table.strip(), ""]
        md += [f"![{p.stem}]({sc.label}/{p.name})" for p in pngs] + [""]
        md += [f"Every metric: [{sc.label}/bench.md]({sc.label}/bench.md), per-episode rows: "
               f"[{sc.label}/runs.csv]({sc.label}/runs.csv)", ""]
        body.append(f"<h2>{html.escape(sc.label)} <small>(configuration {sc.config_hash})</small></h2>")
        body.append(_html_table(res, metrics))
        for p in pngs:
            body.append(f'<p><img src="{html.escape(sc.label)}/{html.escape(p.name)}" alt="{html.escape(p.stem)}" '
                        'style="max-width:100%"></p>')
        if res.failures:
            body.append("<h3>Failures</h3><ul>" + "".join(
                f"<li>{html.escape(f['estimator'])} seed {f['seed']}: {html.escape(str(f['error']))}</li>"
                for f in res.failures) + "</ul>")
        body.append(f'<p><a href="{html.escape(sc.label)}/bench.csv">bench.csv</a> &middot; '
                    f'<a href="{html.escape(sc.label)}/runs.csv">runs.csv</a> &middot; '
                    f'<a href="{html.escape(sc.label)}/bench.json">bench.json</a></p>')
    md_path = out / "index.md"
    write_text_atomic(md_path, "\n".join(md))
    prov_path = out / "provenance.json"
    write_text_atomic(prov_path, json.dumps(prov, indent=1) + "\n")
    paths.append(prov_path)
    style = ("body{font-family:sans-serif;margin:2em;max-width:80em}table{border-collapse:collapse;font-size:90%}"
             "td,th{border:1px solid #bbb;padding:2px 6px;text-align:left}tr:nth-child(even){background:#f4f4f4}")
    html_path = out / "index.html"
    write_text_atomic(html_path, "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\">"
                      f"<title>navsim campaign: {html.escape(spec.name)}</title><style>{style}</style></head>"
                      "<body>\n" + "\n".join(body) + "\n</body></html>\n")
    return [md_path, html_path] + paths
