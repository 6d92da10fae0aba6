"""Plots for people who would rather look than read (matplotlib, imported lazily).

:func:`plot_episode` draws one simulated episode: the track with the vehicle's path and
the places where GNSS was lost, speed, the specific force and body rate seen by the IMU,
and the number of valid satellites per epoch with outages shaded.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import DependencyNotInstalled

__all__ = ["plot_episode"]


def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover - depends on the install
        raise DependencyNotInstalled("matplotlib", "plot") from None
    return plt


def _spans(t, flag):
    """(start, end) time spans where a boolean flag is True."""
    flag = np.asarray(flag, dtype=bool)
    if not flag.any():
        return []
    edges = np.flatnonzero(np.diff(np.r_[0, flag.astype(int), 0]))
    starts, ends = edges[::2], edges[1::2] - 1
    return [(t[a], t[b]) for a, b in zip(starts, ends)]


def plot_episode(data, path: str | Path, title: str = "", max_points: int = 20_000) -> Path:
    """Write a 4-panel PNG of an episode given the arrays of :mod:`navsim.io`."""
    plt = _pyplot()
    t = np.asarray(data["t"])
    stride = max(1, len(t) // max_points)
    sl = slice(None, None, stride)
    lat, lon = np.degrees(data["lat"][sl]), np.degrees(data["lon"][sl])
    gnss_t = np.asarray(data["gnss_t"])
    n_valid = np.asarray(data["gnss_valid"]).sum(axis=1) if len(gnss_t) else np.zeros(0)
    lost = n_valid < 4
    fig, axes = plt.subplots(2, 2, figsize=(12, 8), constrained_layout=True)
    ax = axes[0, 0]
    ax.plot(lon, lat, color="0.3", lw=1.5, label="path")
    if len(gnss_t) and lost.any():
        idx = np.searchsorted(t, gnss_t[lost])
        idx = np.clip(idx, 0, len(t) - 1)
        ax.plot(np.degrees(data["lon"][idx]), np.degrees(data["lat"][idx]), "r.", ms=3, label="fewer than 4 satellites")
    ax.plot(lon[0], lat[0], "go", label="start")
    ax.set_xlabel("longitude, deg")
    ax.set_ylabel("latitude, deg")
    ax.set_aspect(1.0 / np.cos(np.radians(np.mean(lat))), adjustable="datalim")
    ax.legend(loc="best", fontsize=8)
    ax.set_title("track and path")
    ax = axes[0, 1]
    ax.plot(t[sl], data["speed"][sl], color="C0")
    ax.set_xlabel("t, s")
    ax.set_ylabel("speed, m/s", color="C0")
    ax2 = ax.twinx()
    ax2.plot(t[sl], data["h"][sl], color="C1")
    ax2.set_ylabel("height, m", color="C1")
    ax.set_title("along-track motion")
    ax = axes[1, 0]
    force = np.asarray(data["specific_force_b"][sl])
    for i, name in enumerate("xyz"):
        ax.plot(t[sl], force[:, i], lw=0.8, label=f"f_{name}")
    ax.set_xlabel("t, s")
    ax.set_ylabel("specific force (truth), m/s^2")
    ax.legend(loc="best", fontsize=8)
    ax.set_title("what the accelerometers see")
    ax = axes[1, 1]
    if len(gnss_t):
        ax.step(gnss_t, n_valid, where="post", color="C2")
        for a, b in _spans(gnss_t, lost):
            ax.axvspan(a, b, color="r", alpha=0.15, lw=0)
    ax.set_xlabel("t, s")
    ax.set_ylabel("valid satellites")
    ax.set_title("GNSS availability (red: outage)")
    fig.suptitle(title)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
