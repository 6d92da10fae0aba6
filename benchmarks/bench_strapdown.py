"""Batch throughput of the seed-000 coning and sculling algorithms (samples/s).

Each algorithm is called once on 1e6 steps of random increments (vectorised numpy),
best of three runs, and the throughput is printed as a table. Run with
``python benchmarks/bench_strapdown.py [n_steps]``.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from navsim.strapdown import CONING, SCULLING
from navsim.strapdown.coning import CONING_INPUTS
from navsim.strapdown.sculling import SCULLING_INPUTS


def _best_time(fn, repeats: int = 3) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def main(n_steps: int = 1_000_000) -> list[tuple[str, str, float]]:
    rng = np.random.default_rng(0)
    dt = 0.01
    scale = np.array([dt, dt**2, dt**3, dt**4])[None, :, None]
    dtheta_r = rng.standard_normal((n_steps, 4, 3)) * 1e-2 * scale
    dv_r = rng.standard_normal((n_steps, 4, 3)) * scale
    subs = {m: (rng.standard_normal((n_steps, m, 3)) * 1e-4, rng.standard_normal((n_steps, m, 3)) * 1e-2) for m in (2, 3)}
    rows = []
    for name, fn in CONING.items():
        source, count = CONING_INPUTS[name]
        args = (subs[count][0], None, dt) if source == "sub" else (None, dtheta_r, dt)
        rows.append(("coning", name, n_steps / _best_time(lambda: fn(*args))))
    seen = set()
    for name, fn in SCULLING.items():
        if fn in seen:  # aliases such as "accel-invariant-linear" = "invariant-4.4"
            continue
        seen.add(fn)
        spec = SCULLING_INPUTS[name]
        if "sub" in spec:
            args = (*subs[spec["sub"]], None, None, dt)
        else:
            args = (None, None, dtheta_r, dv_r, dt)
        rows.append(("sculling", name, n_steps / _best_time(lambda: fn(*args))))
    print(f"{'kind':9s} {'algorithm':24s} {'samples/s':>12s}   (n = {n_steps:.0e} steps, best of 3)")
    for kind, name, rate in rows:
        print(f"{kind:9s} {name:24s} {rate:12.3e}")
    return rows


if __name__ == "__main__":
    main(int(float(sys.argv[1])) if len(sys.argv) > 1 else 1_000_000)
