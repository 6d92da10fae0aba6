"""Snapshot every score of every bundled estimator on every bundled scenario, and compare two snapshots.

The restructuring and speed work must keep the numbers: this tool records them before a
change and checks them after.

    python tools/score_snapshot.py snap OUT.json [--seeds 0:3] [--duration 300]
    python tools/score_snapshot.py compare BEFORE.json AFTER.json [--rtol 0]

``snap`` runs :func:`navsim.episode.run_episode` for every registered estimator on every
bundled scenario (seeds A..B-1, ``timing.duration_s`` = DURATION) and writes the flat
scores (``EpisodeScore.to_flat_dict``) as JSON; an estimator that refuses a scenario is
recorded with its error message. ``compare`` (timing figures left out) prints, per metric, the largest absolute and
relative difference, counts the bit-identical values, and exits 1 when any difference
exceeds ``--rtol`` (relative to the larger magnitude; 0 = bit for bit) or when the two
snapshots hold different episodes or errors.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time


def _seeds(text: str) -> list[int]:
    a, b = (int(x) for x in text.split(":"))
    return list(range(a, b))


def snap(out: str, seeds: list[int], duration: float, estimator_names: list[str] | None) -> None:
    from navsim import estimators
    from navsim.episode import run_episode
    from navsim.metrics import score_episode
    from navsim.scenario import list_scenarios, load_scenario

    names = estimator_names or list(estimators.available())
    rows: dict[str, object] = {}
    t0 = time.perf_counter()
    for scen_name in list_scenarios():
        scenario = load_scenario(scen_name).with_overrides({"timing": {"duration_s": duration}})
        for est in names:
            for seed in seeds:
                key = f"{scen_name}|{est}|{seed}"
                try:
                    record = run_episode(scenario, estimators.make(est), seed=seed)
                    flat = score_episode(record).to_flat_dict()
                    rows[key] = {k: v for k, v in flat.items() if isinstance(v, (int, float, bool)) or v is None}
                except Exception as exc:  # recorded, compared like a score
                    rows[key] = {"error": f"{type(exc).__name__}: {exc}"}
                print(f"{time.perf_counter() - t0:7.1f} s  {key}", file=sys.stderr, flush=True)
    with open(out, "w", encoding="utf-8") as fh:
        json.dump({"seeds": seeds, "duration_s": duration, "rows": rows}, fh, indent=1, sort_keys=True)


# Wall-clock and CPU figures differ from run to run; they are not scores of the estimate.
TIMING_METRICS = frozenset({"cpu_total_s", "realtime_factor", "step_time_us"})


def _num(v):
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else v


def compare(a_path: str, b_path: str, rtol: float) -> int:
    with open(a_path, encoding="utf-8") as fh:
        a = json.load(fh)["rows"]
    with open(b_path, encoding="utf-8") as fh:
        b = json.load(fh)["rows"]
    bad = 0
    if set(a) - set(b):  # an episode of A is missing in B: a failure
        print("episodes missing in B:", sorted(set(a) - set(b)))
        bad += 1
    new = sorted(set(b) - set(a))
    if new:  # new scenarios or estimators of B: reported, not compared (no reference)
        names = sorted({"|".join(k.split("|")[:2]) for k in new})
        print(f"new in B, not compared ({len(new)} episodes):", ", ".join(names))
    per_metric: dict[str, list[float]] = {}
    identical = total = 0
    for key in sorted(set(a) & set(b)):
        ra, rb = a[key], b[key]
        if "error" in ra or "error" in rb:
            if ra.get("error") != rb.get("error"):
                print(f"{key}: error {ra.get('error')!r} -> {rb.get('error')!r}")
                bad += 1
            continue
        for m in sorted((set(ra) | set(rb)) - TIMING_METRICS):
            va, vb = _num(ra.get(m)), _num(rb.get(m))
            total += 1
            if va == vb or (isinstance(va, float) and isinstance(vb, float) and math.isnan(va) and math.isnan(vb)):
                identical += 1
                per_metric.setdefault(m, [0.0, 0.0])
                continue
            if not (isinstance(va, float) and isinstance(vb, float)):
                print(f"{key} {m}: {va!r} -> {vb!r}")
                bad += 1
                continue
            d = abs(va - vb)
            rel = d / max(abs(va), abs(vb)) if math.isfinite(d) else math.inf
            acc = per_metric.setdefault(m, [0.0, 0.0])
            acc[0] = max(acc[0], d)
            acc[1] = max(acc[1], rel)
            if not rel <= rtol:
                bad += 1
    print(f"{identical} of {total} values bit-identical")
    for m, (d, rel) in sorted(per_metric.items()):
        if d or rel:
            print(f"  {m:40s} max |diff| {d:.3e}  max rel {rel:.3e}")
    print("OK" if bad == 0 else f"{bad} differences beyond rtol {rtol:g}")
    return 0 if bad == 0 else 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("snap")
    s.add_argument("out")
    s.add_argument("--seeds", default="0:3")
    s.add_argument("--duration", type=float, default=300.0)
    s.add_argument("--estimators", default="", help="comma list (default: every registered one)")
    c = sub.add_parser("compare")
    c.add_argument("before")
    c.add_argument("after")
    c.add_argument("--rtol", type=float, default=0.0)
    args = ap.parse_args(argv)
    if args.cmd == "snap":
        snap(args.out, _seeds(args.seeds), args.duration, [e for e in args.estimators.split(",") if e] or None)
        return 0
    return compare(args.before, args.after, args.rtol)


if __name__ == "__main__":
    sys.exit(main())
