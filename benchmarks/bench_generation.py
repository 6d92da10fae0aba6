"""Generation speed: truth + IMU samples per second, printed as a table.

    .venv/bin/python benchmarks/bench_generation.py [--duration 1000]

Cases: the paper scenario (1000 s) with the IMU at 100 Hz and at 1 kHz: truth + ideal IMU
(the issue's figure), truth + IMU with the paper's noise, and everything (GNSS, outages).
Then the spline-track scenarios (mountain-railway at 200 Hz, urban-road at 100 Hz, the first
``--duration`` s of each): truth + ideal IMU through the simulator, and the truth generator
alone with and without splitting at the motion's breakpoints (spline knots, timetable ramp
ends), with the share of blocks where a fit fell back to the direct method (samples that
straddle a breakpoint are integrated piecewise by design and are not counted as fallback).
If pyins (PyPI ``python-ins``) is
installed, its ``sim.generate_imu`` runs on a trajectory of the same length in the same
process as a reference (pyins times are measured after a warm-up call, which compiles its
numba code). Anchors measured on this kind of machine (shared/research): gnss-ins-sim
about 18 k samples/s, pyins about 150 k samples/s.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from navsim.scenario import load_scenario
from navsim.simulator import Simulator
from navsim.truthgen import TruthGenerator


def navsim_rate(rate_hz: float, duration: float, gnss: bool, imu: str, chunk: int = 20_000) -> tuple[float, float]:
    period = 1.0 / rate_hz
    scenario = load_scenario("paper-2012").with_overrides({
        "timing": {"tick_s": period, "imu_period_s": period, "nav_period_s": period, "duration_s": duration},
        "gnss": {"enabled": gnss}, "imu": {"preset": imu},
    })
    return _simulate_rate(scenario, chunk)


def _simulate_rate(scenario, chunk: int) -> tuple[float, float]:
    """IMU samples/s and wall seconds of generating the whole scenario in chunks."""
    sim = Simulator(scenario)
    sim.reset(0)
    t0 = time.perf_counter()
    samples = 0
    for c in sim.chunks(chunk):
        samples += c.imu.dtheta_sample.shape[0] * c.imu.dtheta_sample.shape[1]
    elapsed = time.perf_counter() - t0
    return samples / elapsed, elapsed


def scenario_rate(name: str, duration: float, chunk: int = 20_000) -> tuple[float, float]:
    """Truth + ideal IMU through the simulator on a bundled scenario at its own IMU rate."""
    base = load_scenario(name)
    scenario = base.with_overrides({
        "timing": {"duration_s": min(duration, base.timing.duration_s)},
        "gnss": {"enabled": False}, "imu": {"preset": "ideal"},
    })
    return _simulate_rate(scenario, chunk)


def truthgen_rate(name: str, duration: float, split: bool, chunk: int = 20_000) -> tuple[float, float, float, float]:
    """The truth generator alone: samples/s, wall s, share of blocks with a fallback to the
    direct method and share of samples that straddle a breakpoint."""
    sim = Simulator(load_scenario(name))
    t_end = min(duration, sim.timing.duration_s)
    gen = TruthGenerator(sim.track, sim.profile, sim.oscillations, sim.timing.imu_period_s,
                         sim.scenario.imu.orders, sim.scenario.imu.quadrature_nodes, t_end,
                         split_at_breakpoints=split)
    n = int(round(t_end / gen.h))
    t0 = time.perf_counter()
    used = np.concatenate([gen.samples(i0, min(chunk, n - i0)).used_block for i0 in range(0, n, chunk)])
    elapsed = time.perf_counter() - t0
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
    """pyins ``sim.generate_imu`` (increments) on a gently curving 20 m/s drive, samples/s."""
    try:
        from pyins import sim as pyins_sim
    except ImportError:
        return None
    n = int(duration * rate_hz) + 1
    t = np.arange(n) / rate_hz
    lla = np.column_stack([47.2 + 20.0 * t / 111_000.0, 39.7 + 0.001 * np.sin(2 * np.pi * t / 300), np.zeros(n)])
    rph = np.column_stack([np.zeros(n), np.zeros(n), 5.0 * np.sin(2 * np.pi * t / 300)])
    pyins_sim.generate_imu(t[:200], lla[:200], rph[:200], sensor_type="increment")  # warm-up (numba)
    t0 = time.perf_counter()
    pyins_sim.generate_imu(t, lla, rph, sensor_type="increment")
    return n / (time.perf_counter() - t0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=1000.0)
    args = parser.parse_args()
    navsim_rate(100.0, 20.0, True, "paper-2012")  # warm-up: imports, caches
    print(f"{'case':52s} {'samples/s':>12s} {'wall s':>8s}")
    for rate in (100.0, 1000.0):
        for gnss, imu in ((False, "ideal"), (False, "paper-2012"), (True, "paper-2012")):
            sps, wall = navsim_rate(rate, args.duration, gnss, imu)
            label = f"navsim {rate:.0f} Hz, truth + IMU ({imu})" + (" + GNSS/outages" if gnss else "")
            print(f"{label:52s} {sps:12,.0f} {wall:8.2f}")
        ref = pyins_rate(rate, args.duration)
        if ref is not None:
            print(f"{f'pyins generate_imu {rate:.0f} Hz, ideal (same process)':52s} {ref:12,.0f}")
        else:
            print("pyins not installed (pip install python-ins) - no same-process reference")
    for name in ("mountain-railway", "urban-road"):
        sps, wall = scenario_rate(name, args.duration)
        print(f"{f'navsim {name}, truth + IMU (ideal)':52s} {sps:12,.0f} {wall:8.2f}")
        for split in (True, False):
            sps, wall, fell_back, straddle = truthgen_rate(name, args.duration, split)
            label = f"  truth generator, {'split at breakpoints' if split else 'not split (before)'}"
            print(f"{label:52s} {sps:12,.0f} {wall:8.2f}   blocks falling back {100 * fell_back:5.1f} %"
                  + (f", straddling samples {100 * straddle:.2f} %" if split else ""))
    print("anchors on this kind of machine: gnss-ins-sim ~18 k samples/s, pyins ~150 k samples/s")


if __name__ == "__main__":
    main()
