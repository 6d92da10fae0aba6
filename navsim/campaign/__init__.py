"""Monte Carlo campaigns: scenarios x estimators x seeds, locally or on a Dask cluster.

``navsim campaign SPEC.toml [--scheduler tcp://HOST:PORT] [--workers N] [--report-only]``

A campaign is declared in TOML::

    [campaign]
    name = "outage study"            # optional, default: the file's stem
    seeds = "0:100"                  # "A:B", "A:B:STEP", "1,4,7" or a list of ints
    divergence_threshold_m = 1000.0  # optional
    interval = "t"                   # "t" (interval of the mean) or "percentile"
    database = "study.sqlite"        # optional, default SPEC stem + ".sqlite", beside the spec
    report = "study_report"          # optional report folder, default SPEC stem + "_report"

    [overrides]                      # optional, applied to every scenario first
    timing = { duration_s = 200.0 }

    [[scenarios]]
    name = "paper-2012"              # bundled name or a .toml path relative to the spec
    label = "paper-short"            # optional, default: name (labels must differ)
    overrides = { outages = { windows_s = [[80.0, 140.0]] } }

    [[estimators]]
    name = "lc-ekf"
    label = "lc-ekf"                 # optional, default: name, or name(k=v,...) with options
    options = { }                    # keyword options of navsim.estimators.make

Every episode (one scenario, one estimator with its options, one seed) is one task:
the worker builds the scenario from its resolved dictionary, runs
:func:`navsim.report.run_one` and scores it with :func:`navsim.metrics.score_episode`
(so a campaign episode has exactly the numbers of ``navsim run`` with the same
settings). Executors:

- local (default): :class:`concurrent.futures.ProcessPoolExecutor` with every core
  (``--workers N`` to choose), processes forked from a fork server that imported the
  episode code once (``forkserver``, where the platform has it: no fork of the campaign
  process, which may run threads; elsewhere ``spawn``, a fresh interpreter per worker),
  with one BLAS / OpenMP thread each unless the environment says otherwise; every
  worker dies with the campaign process (:func:`_die_with_parent`); ``workers=0`` runs
  the episodes in this process;
- Dask: ``--scheduler tcp://HOST:PORT`` submits the same tasks to an existing
  ``distributed`` cluster (``pip install 'navsim-track[campaign]'``), one future per
  episode, collected with ``distributed.as_completed``. When a worker dies the
  scheduler reruns its tasks elsewhere (Dask's own ``allowed-failures`` policy); the
  parent sees each future finish once.

Results go into an SQLite database beside the spec (stdlib :mod:`sqlite3`), table
``episodes``: one row per episode, unique on ``(scenario_hash, estimator, options,
seed)`` where ``scenario_hash`` is :meth:`navsim.scenario.Scenario.config_hash` of the
resolved scenario and ``options`` the canonical JSON of the estimator options. Only
the parent process writes, one transaction per finished episode, as results arrive: a
killed campaign loses at most the episodes still running, and a rerun skips every
episode already in the table (a finished row is never overwritten; failed episodes
are recorded with their error text and are retried only with ``retry_failed``). The
row holds the flat scores (JSON, keys carry units), the per-outage drifts (JSON) and
an evenly subsampled series of the horizontal error (float32 blob) for the
distribution plots.

The report (:func:`write_report`) groups the rows per scenario: for every estimator
the mean and 95 % interval of every metric (:func:`navsim.metrics.aggregate`), written
with :func:`navsim.report.write_bench` (``bench.md``, CSV, JSON, error-distribution and
drift-per-outage plots) into one folder per scenario, and an ``index.md`` and a static
``index.html`` (tables and the PNGs) at the top of the report folder.

Modules
-------
* :mod:`~navsim.campaign.spec`: the TOML specification, validated.
* :mod:`~navsim.campaign.tasks`: episode tasks and how one is run and scored.
* :mod:`~navsim.campaign.database`: the SQLite results database.
* :mod:`~navsim.campaign.executors`: local processes, Dask, :func:`run_campaign`.
* :mod:`~navsim.campaign.results`: rows, aggregates, the report folder.
* :mod:`~navsim.campaign.command`: the ``navsim campaign`` subcommand.

References
----------
Dask distributed, https://distributed.dask.org (Client.submit, as_completed,
LocalCluster). SQLite UPSERT, https://sqlite.org/lang_upsert.html.
"""
from .command import add_campaign_parser, cmd_campaign
from .database import finished_keys, open_database
from .executors import DASK_RESUBMITS, CampaignResult, run_campaign
from .results import build_results, read_rows, write_report
from .spec import (
    CPU_FIELDS,
    SAMPLES_PER_EPISODE,
    CampaignInterrupted,
    CampaignSpec,
    EstimatorEntry,
    ScenarioEntry,
    campaign_from_dict,
    load_campaign,
)
from .tasks import EpisodeTask, episode_tasks, run_episode_task

__all__ = ["ScenarioEntry", "EstimatorEntry", "CampaignSpec", "EpisodeTask", "CampaignResult", "load_campaign",
           "campaign_from_dict", "episode_tasks", "run_episode_task", "open_database", "finished_keys",
           "run_campaign", "read_rows", "build_results", "write_report", "add_campaign_parser", "cmd_campaign",
           "CampaignInterrupted", "CPU_FIELDS", "DASK_RESUBMITS", "SAMPLES_PER_EPISODE"]
