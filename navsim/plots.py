"""Plots for people who would rather look than read (matplotlib, imported lazily).

:func:`plot_episode` draws one simulated episode: the track with the vehicle's path and
the places where GNSS was lost, speed, the specific force and body rate seen by the IMU,
and the number of valid satellites per epoch with outages shaded.

:func:`plot_errors` draws an estimator's errors against time with +-3 sigma bounds and
GNSS outages shaded (``navsim run --plot``); :func:`plot_bench_errors`,
:func:`plot_outage_drifts` and :func:`plot_mc_nees` draw the comparisons of
``navsim bench``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Sequence

import numpy as np

from .errors import DependencyNotInstalled

if TYPE_CHECKING:  # type hints only
    from .metrics import ErrorSeries, Outage

__all__ = ["plot_episode", "plot_errors", "plot_bench_errors", "plot_outage_drifts", "plot_mc_nees"]


def _pyplot() -> Any:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover - depends on the install
        raise DependencyNotInstalled("matplotlib", "plot") from None
    return plt


def _spans(t: np.ndarray, flag: np.ndarray) -> list[tuple[float, float]]:
    """(start, end) time spans where a boolean flag is True."""
    flag = np.asarray(flag, dtype=bool)
    if not flag.any():
        return []
    edges = np.flatnonzero(np.diff(np.r_[0, flag.astype(int), 0]))
    starts, ends = edges[::2], edges[1::2] - 1
    return [(t[a], t[b]) for a, b in zip(starts, ends)]


def plot_episode(data: Mapping[str, np.ndarray], path: str | Path, title: str = "", max_points: int = 20_000) -> Path:
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
    return _save(fig, plt, path)


# ============================================================================ estimator errors
def _shade_outages(ax: Any, outages: Sequence[Outage]) -> None:
    for o in outages:
        ax.axvspan(o.t_from, o.t_to, color="r", alpha=0.12, lw=0)


def _band(ax: Any, t: np.ndarray, sigma: np.ndarray | None, color: str, label: str | None = None) -> None:
    """Dashed +-3 sigma lines (sigma may be None or contain nan: not drawn there)."""
    if sigma is None or not np.isfinite(sigma).any():
        return
    ax.plot(t, 3.0 * sigma, ls="--", lw=0.8, color=color, label=label)
    ax.plot(t, -3.0 * sigma, ls="--", lw=0.8, color=color)


def plot_errors(series: ErrorSeries, path: str | Path, *, outages: Sequence[Outage] = (), title: str = "",
                max_points: int = 20_000) -> Path:
    """Write a 6-panel PNG of an estimator's errors against time.

    Panels: horizontal error with its 3-drms bound ``3 sqrt(P_EE + P_NN)``; vertical,
    along-track and cross-track errors with +-3 sigma; velocity and attitude error
    components (ENU) with +-3 sigma. GNSS outages (:class:`navsim.metrics.Outage`) are
    shaded red. ``series`` is a :class:`navsim.metrics.ErrorSeries`.
    """
    plt = _pyplot()
    t = np.asarray(series.t)
    stride = max(1, len(t) // max_points)
    sl = slice(stride - 1, None, stride)
    ts = t[sl]
    sig = series.sigma[sl] if series.sigma is not None else None

    def pick(x: np.ndarray | None) -> np.ndarray | None:
        return None if x is None else np.asarray(x)[sl]

    fig, axes = plt.subplots(3, 2, figsize=(13, 10), sharex=True, constrained_layout=True)
    ax = axes[0, 0]
    ax.plot(ts, series.horizontal_m[sl], color="C0", lw=1, label="|error|")
    if series.sigma_horizontal_m is not None and np.isfinite(series.sigma_horizontal_m).any():
        ax.plot(ts, 3.0 * series.sigma_horizontal_m[sl], ls="--", lw=0.8, color="k", label="3 drms")
    ax.set_ylabel("horizontal error, m")
    ax.set_title("horizontal position")
    for ax, x, s, label in ((axes[0, 1], series.vertical_m, None if sig is None else sig[:, 2], "vertical (up)"),
                            (axes[1, 0], series.along_m, pick(series.sigma_along_m), "along-track (increasing s)"),
                            (axes[1, 1], series.cross_m, pick(series.sigma_cross_m), "cross-track (right +)")):
        ax.plot(ts, np.asarray(x)[sl], color="C0", lw=1, label="error")
        _band(ax, ts, s, "k", "+-3 sigma")
        ax.set_ylabel(f"{label.split(' ')[0]} error, m")
        ax.set_title(label)
    for ax, cols, scale, unit, name in ((axes[2, 0], (3, 4, 5), 1.0, "m/s", "velocity"),
                                        (axes[2, 1], (6, 7, 8), np.degrees(1.0), "deg", "attitude")):
        for j, (col, axis) in enumerate(zip(cols, "ENU")):
            ax.plot(ts, scale * series.error[sl, col], lw=0.9, color=f"C{j}", label=f"{name} {axis}")
            _band(ax, ts, None if sig is None else scale * sig[:, col], f"C{j}")
        ax.set_ylabel(f"{name} error, {unit}")
        ax.set_title(f"{name} (dashed: +-3 sigma)")
        ax.set_xlabel("t, s")
    for ax in axes.flat:
        _shade_outages(ax, outages)
        ax.grid(True, lw=0.3)
        ax.legend(loc="upper left", fontsize=7)
    fig.suptitle(title + ("  (red: GNSS outage)" if len(outages) else ""))
    return _save(fig, plt, path)


def _save(fig: Any, plt: Any, path: str | Path) -> Path:
    """Save atomically (a temporary file beside ``path`` renamed into place) and close."""
    from .io import save_figure

    try:
        return save_figure(fig, path, dpi=110)
    finally:
        plt.close(fig)


# ============================================================================ benchmarks
def _finite(values: Iterable[float | None]) -> np.ndarray:
    x = np.asarray([np.nan if v is None else v for v in values], dtype=float)
    return x[np.isfinite(x)]


def plot_bench_errors(samples: dict, per_seed: dict, path: str | Path, title: str = "") -> Path:
    """Error distributions per estimator (PNG, 3 panels).

    samples[name] : horizontal errors pooled over the seeds (m), drawn as empirical
    CDFs; per_seed[name] : the :class:`navsim.metrics.EpisodeScore` of each seed, whose
    horizontal RMSE and outage RMS drift are drawn as box plots. A diverged run's figures
    are NaN (:func:`navsim.metrics.detect_divergence`): it is left out of the boxes and
    counted in the estimator's label ("name (k diverged)").
    """
    plt = _pyplot()
    names = list(samples)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8), constrained_layout=True)
    ax = axes[0]
    positive = []
    for j, name in enumerate(names):
        x = np.sort(_finite(samples[name]))
        if x.size:
            ax.step(x, np.arange(1, x.size + 1) / x.size, where="post", color=f"C{j % 10}", label=name)
            positive.append(x[x > 0])
    pos = np.concatenate(positive) if positive else np.zeros(0)
    if pos.size and float(np.max(pos)) > 100 * max(float(np.min(pos)), 1e-12):
        ax.set_xscale("log")
    ax.axhline(0.5, color="0.6", lw=0.6)
    ax.axhline(0.95, color="0.6", lw=0.6)
    ax.set_xlabel("horizontal error, m")
    ax.set_ylabel("fraction of steps (all seeds)")
    ax.set_title("distribution of the horizontal error")
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=8)
    for ax, key, label in ((axes[1], "horizontal_rmse_m", "horizontal RMSE per seed, m"),
                           (axes[2], "outage_rms_drift_m", "outage RMS drift per seed, m")):
        data = [_finite(getattr(s, key) for s in per_seed.get(n, [])) for n in names]
        keep = [(n, d) for n, d in zip(names, data) if d.size]
        div = {n: sum(bool(getattr(s, "diverged", False)) for s in per_seed.get(n, [])) for n in names}
        if keep:
            ax.boxplot([d for _, d in keep], showmeans=True)
            ax.set_xticks(range(1, len(keep) + 1), [f"{n} ({div[n]} diverged)" if div[n] else n for n, _ in keep],
                          rotation=30, ha="right")
            allv = np.concatenate([d for _, d in keep])
            if allv.min() > 0 and allv.max() > 100 * allv.min():
                ax.set_yscale("log")
        else:
            ax.text(0.5, 0.5, "no data", ha="center", va="center", transform=ax.transAxes)
        ax.set_ylabel(label)
        ax.grid(True, axis="y", lw=0.3)
    axes[1].set_title("per-seed RMSE (box: quartiles, triangle: mean)")
    axes[2].set_title("per-seed RMS over outages of the max drift")
    fig.suptitle(title)
    return _save(fig, plt, path)


def plot_outage_drifts(per_seed: dict, path: str | Path, title: str = "", max_groups: int = 12) -> Path:
    """Maximum horizontal drift of every outage (PNG), one colour per estimator.

    per_seed[name] : the :class:`navsim.metrics.EpisodeScore` of each seed. When the
    outages start at no more than ``max_groups`` distinct times (scheduled windows),
    they are grouped by start time: one point per seed, a bar at the mean. Otherwise
    (random outages) the drift is drawn against the outage duration.
    """
    plt = _pyplot()
    names = list(per_seed)
    fig, ax = plt.subplots(figsize=(11, 5), constrained_layout=True)
    points = {n: [(o.t_first, o.duration_s, o.max_drift_m) for s in per_seed[n] for o in s.outages
                  if np.isfinite(o.max_drift_m)] for n in names}
    starts = sorted({round(p[0], 6) for pts in points.values() for p in pts})
    grouped = 0 < len(starts) <= max_groups
    all_ys = [p[2] for pts in points.values() for p in pts]
    width = 0.8 / max(len(names), 1)
    for j, name in enumerate(names):
        pts = np.array(points[name], dtype=float).reshape(-1, 3)
        if not len(pts):
            continue
        color = f"C{j % 10}"
        if grouped:
            group = np.searchsorted(starts, np.round(pts[:, 0], 6))
            x = group + (j - (len(names) - 1) / 2) * width
            ax.plot(x, pts[:, 2], "o", ms=3.5, alpha=0.6, color=color, label=name)
            for g in np.unique(group):
                xg = g + (j - (len(names) - 1) / 2) * width
                ax.plot([xg - width / 3, xg + width / 3], [pts[group == g, 2].mean()] * 2, color=color, lw=2.5)
        else:
            ax.plot(pts[:, 1], pts[:, 2], "o", ms=3.5, alpha=0.6, color=color, label=name)
    if all_ys:
        vals = np.array(all_ys)
        if vals.min() > 0 and vals.max() > 100 * vals.min():
            ax.set_yscale("log")
        ax.legend(fontsize=8)
    else:
        ax.text(0.5, 0.5, "no GNSS outage in these episodes", ha="center", va="center", transform=ax.transAxes)
    if grouped:
        ax.set_xticks(range(len(starts)), [f"{t:g} s" for t in starts])
        ax.set_xlabel("outage (time of its first epoch without a fix)")
        ax.set_title("drift per outage (points: seeds; bars: mean)")
    else:
        ax.set_xlabel("outage duration, s")
        ax.set_title("drift per outage against its duration (points: outages of all seeds)")
    ax.set_ylabel("maximum horizontal error inside the outage, m")
    ax.grid(True, lw=0.3)
    fig.suptitle(title)
    return _save(fig, plt, path)


def plot_mc_nees(t: np.ndarray, mc: dict, path: str | Path, title: str = "") -> Path:
    """Monte Carlo NEES per estimator (PNG): average over seeds divided by its dimension
    d, with the 95 % bounds ``chi2(M d) / (M d)`` dashed (1 = consistent)."""
    plt = _pyplot()
    t = np.asarray(t)
    fig, ax = plt.subplots(figsize=(11, 5), constrained_layout=True)
    for j, (name, m) in enumerate(mc.items()):
        color = f"C{j % 10}"
        ax.plot(t, m.mean / m.dof, color=color, lw=0.9,
                label=f"{name} (d={m.dof}, {100 * m.in_bounds_fraction:.0f} % of steps inside)")
        ax.plot(t, m.lower / m.dof, color=color, ls="--", lw=0.7)
        ax.plot(t, m.upper / m.dof, color=color, ls="--", lw=0.7)
    ax.set_yscale("log")
    ax.axhline(1.0, color="k", lw=0.6)
    ax.set_xlabel("t, s")
    ax.set_ylabel("average NEES / d")
    ax.set_title("Monte Carlo consistency (dashed: 95 % chi-square bounds)")
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize=8)
    fig.suptitle(title)
    return _save(fig, plt, path)
