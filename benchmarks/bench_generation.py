"""Generation speed: truth + IMU samples per second, printed as a table.

    .venv/bin/python benchmarks/bench_generation.py [--duration 1000]

Cases: the paper scenario (1000 s) with the IMU at 100 Hz and at 1 kHz: truth + ideal IMU
(the issue's figure), truth + IMU with the paper's noise, and everything (GNSS, outages). If pyins (PyPI ``python-ins``) is
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


def navsim_rate(rate_hz: float, duration: float, gnss: bool, imu: str, chunk: int = 20_000) -> tuple[float, float]:
    period = 1.0 / rate_hz
    scenario = load_scenario("paper-2012").with_overrides({
        "timing": {"tick_s": period, "imu_period_s": period, "nav_period_s": period, "duration_s": duration},
        "gnss": {"enabled": gnss}, "imu": {"preset": imu},
    })
    sim = Simulator(scenario)
    sim.reset(0)
    t0 = time.perf_counter()
    samples = 0
    for c in sim.chunks(chunk):
        samples += c.imu.dtheta_sample.shape[0] * c.imu.dtheta_sample.shape[1]
    elapsed = time.perf_counter() - t0
    return samples / elapsed, elapsed


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
    print("anchors on this kind of machine: gnss-ins-sim ~18 k samples/s, pyins ~150 k samples/s")


if __name__ == "__main__":
    main()
