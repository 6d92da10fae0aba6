"""Campaigns (package form; everything in :mod:`.executors` for now)."""

from .executors import (
    CPU_FIELDS,
    DASK_RESUBMITS,
    SAMPLES_PER_EPISODE,
    CampaignInterrupted,
    CampaignResult,
    CampaignSpec,
    EpisodeTask,
    EstimatorEntry,
    ScenarioEntry,
    add_campaign_parser,
    build_results,
    campaign_from_dict,
    cmd_campaign,
    episode_tasks,
    finished_keys,
    load_campaign,
    open_database,
    read_rows,
    run_campaign,
    run_episode_task,
    write_report,
)

__all__ = ["ScenarioEntry", "EstimatorEntry", "CampaignSpec", "EpisodeTask", "CampaignResult", "load_campaign",
           "campaign_from_dict", "episode_tasks", "run_episode_task", "open_database", "finished_keys",
           "run_campaign", "read_rows", "build_results", "write_report", "add_campaign_parser", "cmd_campaign",
           "CampaignInterrupted", "CPU_FIELDS", "DASK_RESUBMITS", "SAMPLES_PER_EPISODE"]
