"""Generation speed: truth + IMU samples per second, printed as a table.

    .venv/bin/python benchmarks/bench_generation.py [--duration 1000]

Cases: the paper scenario (1000 s) with the IMU at 100 Hz and at 1 kHz, GNSS off (truth +
IMU only, the issue's figure) and on (everything). If pyins (PyPI ``python-ins``) is
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


def navsim_rate(rate_hz: float, duration: float, gnss: bool, chunk: int = 20_000) -> tuple[float, float]:
    period = 1.0 / rate_hz
    scenario = load_scenario("paper-2012").with_overrides({
        "timing": {"tick_s": period, "imu_period_s": period, "nav_period_s": period, "duration_s": duration},
        "gnss": {"enabled": gnss},
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
    try:
        import pandas as pd
        from pyins import sim as pyins_sim
    except ImportError:
        return None
    n = int(duration * rate_hz) + 1
    t = np.arange(n) / rate_hz
    # a gently curving drive at 20 m/s in local NED-like coordinates, as in pyins' examples
    lla = np.zeros((n, 3))
    lla[:, 0] = 47.2 + 20.0 * t / 111_000.0
    lla[:, 1] = 39.7 + 0.001 * np.sin(2 * np.pi * t / 300)
    rph = np.zeros((n, 3))
    rph[:, 2] = 5.0 * np.sin(2 * np.pi * t / 300)
    trajectory = pd.DataFrame({"lat": lla[:, 0], "lon": lla[:, 1], "alt": lla[:, 2],
                               "roll": rph[:, 0], "pitch": rph[:, 1], "heading": rph[:, 2]}, index=t)
    try:
        generate = pyins_sim.generate_imu
        short = trajectory.iloc[:200]
        try:
            generate(short.index, short[["lat", "lon", "alt"]].values, short[["roll", "pitch", "heading"]].values, sensor_type="increment")
        except TypeError:
            return None
        t0 = time.perf_counter()
        generate(trajectory.index, trajectory[["lat", "lon", "alt"]].values, trajectory[["roll", "pitch", "heading"]].values, sensor_type="increment")
        return n / (time.perf_counter() - t0)
    except Exception as exc:  # the reference is optional; report why it did not run
        print(f"pyins reference failed: {exc!r}")
        return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=1000.0)
    args = parser.parse_args()
    print(f"{'case':40s} {'samples/s':>12s} {'wall s':>8s}")
    for rate in (100.0, 1000.0):
        for gnss in (False, True):
            sps, wall = navsim_rate(rate, args.duration, gnss)
            label = f"navsim {rate:.0f} Hz, truth+IMU" + (" + GNSS/outages" if gnss else "")
            print(f"{label:40s} {sps:12,.0f} {wall:8.2f}")
        ref = pyins_rate(rate, args.duration)
        if ref is not None:
            print(f"{f'pyins generate_imu {rate:.0f} Hz (same process)':40s} {ref:12,.0f}")
    print("anchors on this kind of machine: gnss-ins-sim ~18 k samples/s, pyins ~150 k samples/s")


if __name__ == "__main__":
    main()
