"""Episode tasks: one scenario, one estimator with its options, one seed (:class:`EpisodeTask`,
:func:`episode_tasks`), run and scored by :func:`run_episode_task` with
:func:`navsim.report.run_one` and :func:`navsim.metrics.score_episode`.
"""


from __future__ import annotations

import json
import os
import socket
import time
from dataclasses import dataclass

import numpy as np

from .spec import SAMPLES_PER_EPISODE, CampaignSpec


@dataclass(frozen=True, slots=True)
class EpisodeTask:
    """Everything a worker needs for one episode (plain data, cheap to pickle)."""

    scenario_label: str
    scenario_hash: str
    scenario_dict: dict
    scenario_base_dir: str
    estimator_label: str
    estimator: str
    options_json: str
    seed: int
    divergence_threshold_m: float

    @property
    def key(self) -> tuple[str, str, str, int]:
        """The database key (scenario_hash, estimator, options, seed)."""
        return (self.scenario_hash, self.estimator, self.options_json, self.seed)


def episode_tasks(spec: CampaignSpec) -> list[EpisodeTask]:
    """Every episode of the campaign, ordered scenario, seed, estimator."""
    out = []
    for sc in spec.scenarios:
        data = sc.scenario.to_dict()
        for seed in spec.seeds:
            for est in spec.estimators:
                out.append(EpisodeTask(sc.label, sc.config_hash, data, sc.scenario.base_dir, est.label, est.name,
                                       est.options_json, int(seed), spec.divergence_threshold_m))
    return out


def run_episode_task(task: EpisodeTask) -> dict:
    """Run and score one episode (in a worker). Never raises for a failing episode.

    Returns
    -------
    dict with ``status`` ("ok" or "failed"), ``scores`` (flat dict) , ``outages``
    (list of dicts), ``samples`` (float32 bytes of the horizontal error, m, at most
    :data:`SAMPLES_PER_EPISODE` values), ``error`` (text), ``wall_s``, ``cpu_s`` (CPU time
    of the worker process for the episode; not stored in the database) and ``worker``
    (host:pid).
    """
    from ..metrics import error_series, score_episode
    from ..report import run_one
    from ..scenario import Scenario

    t0, c0 = time.perf_counter(), time.process_time()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    try:
        scenario = Scenario.from_dict(task.scenario_dict, base_dir=task.scenario_base_dir)
        if scenario.config_hash() != task.scenario_hash:
            raise RuntimeError(f"scenario hash {scenario.config_hash()} on the worker, {task.scenario_hash} expected "
                               "(different navsim versions?)")
        record = run_one(scenario, task.estimator, task.seed, json.loads(task.options_json))
        series = error_series(record)
        score = score_episode(record, series=series, divergence_threshold_m=task.divergence_threshold_m)
        h = np.asarray(series.horizontal_m, dtype=float)
        stride = max(1, len(h) // SAMPLES_PER_EPISODE)
        return {"status": "ok", "scores": score.to_flat_dict(), "outages": [o.as_dict() for o in score.outages],
                "samples": h[stride - 1::stride].astype(np.float32).tobytes(), "error": None,
                "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0, "worker": worker}
    except Exception as exc:  # noqa: BLE001 - a failing episode is a result
        return {"status": "failed", "scores": None, "outages": None, "samples": None,
                "error": f"{type(exc).__name__}: {exc}", "wall_s": time.perf_counter() - t0,
                "cpu_s": time.process_time() - c0, "worker": worker}
