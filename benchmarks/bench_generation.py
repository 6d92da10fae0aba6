"""Generation speed: truth + IMU samples per CPU second, as Markdown tables.

    .venv/bin/python benchmarks/bench_generation.py [--duration 1000] [--repeats 3] [--quick]

Cases: the paper scenario (``--duration`` s, default 1000) with the IMU at 100 Hz and at
1 kHz: truth + ideal IMU (the issue's figure) with the core's BLAS thread limit (the
default, :mod:`navsim.threads`) and without it (BLAS threads as the machine sets them:
the state before the limit), interleaved with pyins in the same process; then truth + IMU
with the paper's noise, and everything (GNSS, outages). Then the spline-track scenarios
(mountain-railway at 200 Hz, urban-road at 100 Hz, the first ``--duration`` s of each):
truth + ideal IMU through the simulator, and the truth generator alone with and without
splitting at the motion's breakpoints (spline knots, timetable ramp ends), with the share
of blocks where a fit fell back to the direct method (samples that straddle a breakpoint
are integrated piecewise by design and are not counted as fallback).

Rates are per CPU second of this process (``time.process_time``: BLAS helper threads are
counted), since the machine may be shared; the wall-clock rate is printed beside. pyins
(PyPI ``python-ins``, optional): its ``sim.generate_imu`` (increments) on a trajectory of
the same length, timed after a warm-up call that compiles its numba code.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from navsim import threads
from navsim.scenario import load_scenario
from navsim.simulator import Simulator
from navsim.truthgen import TruthGenerator


def navsim_rate(rate_hz: float, duration: float, gnss: bool, imu: str, chunk: int = 20_000) -> tuple[float, float]:
    """(samples per CPU second, samples per wall second) of the paper scenario at ``rate_hz``."""
    period = 1.0 / rate_hz
    scenario = load_scenario("paper-2012").with_overrides({
        "timing": {"tick_s": period, "imu_period_s": period, "nav_period_s": period, "duration_s": duration},
        "gnss": {"enabled": gnss}, "imu": {"preset": imu},
    })
    return _simulate_rate(scenario, chunk)


def _simulate_rate(scenario, chunk: int) -> tuple[float, float]:
    """IMU samples per CPU second and per wall second of generating the whole scenario in chunks."""
    sim = Simulator(scenario)
    sim.reset(0)
    c0, t0 = time.process_time(), time.perf_counter()
    samples = 0
    for c in sim.chunks(chunk):
        samples += c.imu.dtheta_sample.shape[0] * c.imu.dtheta_sample.shape[1]
    cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    return samples / cpu, samples / wall


def scenario_rate(name: str, duration: float, chunk: int = 20_000) -> tuple[float, float]:
    """Truth + ideal IMU through the simulator on a bundled scenario at its own IMU rate."""
    base = load_scenario(name)
    scenario = base.with_overrides({
        "timing": {"duration_s": min(duration, base.timing.duration_s)},
        "gnss": {"enabled": False}, "imu": {"preset": "ideal"},
    })
    return _simulate_rate(scenario, chunk)


def truthgen_rate(name: str, duration: float, split: bool, chunk: int = 20_000) -> tuple[float, float, float, float]:
    """The truth generator alone: samples per CPU second, CPU s, share of blocks with a fallback to the
    direct method and share of samples that straddle a breakpoint."""
    sim = Simulator(load_scenario(name))
    t_end = min(duration, sim.timing.duration_s)
    gen = TruthGenerator(sim.track, sim.profile, sim.oscillations, sim.timing.imu_period_s,
                         sim.scenario.imu.orders, sim.scenario.imu.quadrature_nodes, t_end,
                         split_at_breakpoints=split)
    n = int(round(t_end / gen.h))
    t0 = time.process_time()
    used = np.concatenate([gen.samples(i0, min(chunk, n - i0)).used_block for i0 in range(0, n, chunk)])
    elapsed = time.process_time() - t0
    index = np.arange(n)
    probe = gen if split else TruthGenerator(sim.track, sim.profile, sim.oscillations, gen.h, gen.orders,
                                             gen.n_nodes, t_end)
    lo, hi = probe._inside(index, index + 1)
    straddle = hi > lo
    fallback = ~used & (~straddle if split else True)
    nb = n // gen.block
    blocks = fallback[: nb * gen.block].reshape(nb, gen.block).any(axis=1)
    return n / elapsed, elapsed, float(blocks.mean()), float(straddle.mean())


def pyins_rate(rate_hz: float, duration: float) -> float | None:
    """pyins ``sim.generate_imu`` (increments) on a gently curving 20 m/s drive, samples per
    CPU second (None if pyins is not installed)."""
    try:
        from pyins import sim as pyins_sim
    except ImportError:
        return None
    n = int(duration * rate_hz) + 1
    t = np.arange(n) / rate_hz
    lla = np.column_stack([47.2 + 20.0 * t / 111_000.0, 39.7 + 0.001 * np.sin(2 * np.pi * t / 300), np.zeros(n)])
    rph = np.column_stack([np.zeros(n), np.zeros(n), 5.0 * np.sin(2 * np.pi * t / 300)])
    pyins_sim.generate_imu(t[:200], lla[:200], rph[:200], sensor_type="increment")  # warm-up (numba)
    t0 = time.process_time()
    pyins_sim.generate_imu(t, lla, rph, sensor_type="increment")
    return n / (time.process_time() - t0)


def _median(fn, repeats: int):
    values = [fn() for _ in range(repeats)]
    return tuple(statistics.median(v) for v in zip(*values)) if isinstance(values[0], tuple) \
        else statistics.median(values)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=1000.0)
    parser.add_argument("--repeats", type=int, default=3, help="interleaved repeats per row (median)")
    parser.add_argument("--quick", action="store_true", help="100-s episodes, one repeat")
    args = parser.parse_args()
    duration, repeats = (100.0, 1) if args.quick else (args.duration, args.repeats)
    navsim_rate(100.0, 20.0, True, "paper-2012")  # warm-up: imports, caches
    pyins_rate(100.0, 2.0)  # warm-up: numba compilation
    print(f"Paper scenario, {duration:g} s; samples per CPU second (and per wall second: the machine is "
          f"shared), median of {repeats} interleaved repeats; pyins in the same process.\n")
    print("| case | samples/CPU s | samples/wall s | x pyins (CPU) |")
    print("|---|---:|---:|---:|")
    for rate in (100.0, 1000.0):
        # interleaved: with the core's BLAS limit (default), without it (BLAS threads as
        # the machine sets them), pyins
        rows: dict[str, list] = {"limit": [], "free": [], "pyins": []}
        for _ in range(repeats):
            threads.set_core_blas_threads(1)
            rows["limit"].append(navsim_rate(rate, duration, False, "ideal"))
            threads.set_core_blas_threads(None)
            rows["free"].append(navsim_rate(rate, duration, False, "ideal"))
            threads.set_core_blas_threads(1)
            rows["pyins"].append(pyins_rate(rate, duration))
        ref = None if rows["pyins"][0] is None else statistics.median(rows["pyins"])
        for key, label in (("limit", "truth + ideal IMU, default (core BLAS limit 1 thread)"),
                           ("free", "truth + ideal IMU, BLAS threads not limited (before)")):
            cpu = statistics.median(r[0] for r in rows[key])
            wall = statistics.median(r[1] for r in rows[key])
            ratio = f"{cpu / ref:.1f}" if ref else "-"
            print(f"| navsim {rate:.0f} Hz, {label} | {cpu:,.0f} | {wall:,.0f} | {ratio} |")
        if ref is not None:
            print(f"| pyins generate_imu {rate:.0f} Hz, ideal | {ref:,.0f} | | 1.0 |")
        else:
            print(f"| pyins not installed (pip install python-ins): no reference | | | |")
        for gnss, imu in ((False, "paper-2012"), (True, "paper-2012")):
            cpu, wall = _median(lambda: navsim_rate(rate, duration, gnss, imu), repeats)
            label = f"navsim {rate:.0f} Hz, truth + IMU ({imu})" + (" + GNSS/outages" if gnss else "")
            ratio = f"{cpu / ref:.1f}" if ref else "-"
            print(f"| {label} | {cpu:,.0f} | {wall:,.0f} | {ratio} |")
    print("\nSpline-track scenarios at their own IMU rate (truth + ideal IMU through the simulator; then the "
          "truth generator alone, CPU time):\n")
    print("| case | samples/CPU s | blocks falling back | straddling samples |")
    print("|---|---:|---:|---:|")
    for name in ("mountain-railway", "urban-road"):
        cpu, wall = _median(lambda: scenario_rate(name, duration), repeats)
        print(f"| navsim {name}, truth + IMU (ideal) | {cpu:,.0f} | | |")
        for split in (True, False):
            sps, _, fell_back, straddle = truthgen_rate(name, duration, split)
            label = f"truth generator, {'split at breakpoints' if split else 'not split (before)'}"
            print(f"| {label} | {sps:,.0f} | {100 * fell_back:.1f} % | "
                  + (f"{100 * straddle:.2f} % |" if split else "|"))


if __name__ == "__main__":
    main()
