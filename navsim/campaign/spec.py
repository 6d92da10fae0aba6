"""The campaign specification: the TOML ``[campaign]``, ``[[scenario]]`` and ``[[estimator]]``
tables read and validated into :class:`CampaignSpec` (:func:`load_campaign`,
:func:`campaign_from_dict`); the format is described in :mod:`navsim.campaign`.
"""


from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Iterator

from ..errors import ConfigError, NavsimError

if TYPE_CHECKING:  # type hints only
    from ..scenario import Scenario

SAMPLES_PER_EPISODE = 500
"""Horizontal-error samples kept per episode (evenly in time) for the distribution plots."""

CPU_FIELDS = ("step_time_us", "cpu_total_s", "realtime_factor")
"""Score fields that depend on the machine (CPU time), not on the numbers."""


class CampaignInterrupted(NavsimError):
    """The campaign cannot go on: the local process pool broke (a worker process died)
    or the Dask scheduler does not answer. The finished rows are kept."""


def _canonical_json(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


@dataclass(frozen=True, slots=True)
class ScenarioEntry:
    """One scenario of the campaign: ``label`` (unique), the resolved
    :class:`~navsim.scenario.Scenario` and its configuration hash."""

    label: str
    scenario: Scenario
    config_hash: str


@dataclass(frozen=True, slots=True)
class EstimatorEntry:
    """One estimator: registry ``name``, keyword ``options``, unique ``label``;
    ``options_json`` is the canonical JSON that enters the database key."""

    label: str
    name: str
    options: dict
    options_json: str


@dataclass(frozen=True, slots=True)
class CampaignSpec:
    """A validated campaign (see the module docstring for the TOML form).

    database, report_dir : paths (absolute or relative to the working directory).
    """

    name: str
    scenarios: tuple[ScenarioEntry, ...]
    estimators: tuple[EstimatorEntry, ...]
    seeds: tuple[int, ...]
    database: Path
    report_dir: Path
    divergence_threshold_m: float = 1000.0
    interval: str = "t"

    def __post_init__(self) -> None:
        if not self.scenarios:
            raise ConfigError("scenarios", "at least one [[scenarios]] entry", [])
        if not self.estimators:
            raise ConfigError("estimators", "at least one [[estimators]] entry", [])
        if not self.seeds:
            raise ConfigError("campaign.seeds", "at least one seed", list(self.seeds))
        if self.interval not in ("t", "percentile"):
            raise ConfigError("campaign.interval", "'t' or 'percentile'", self.interval)
        if not (self.divergence_threshold_m > 0 and math.isfinite(self.divergence_threshold_m)):
            raise ConfigError("campaign.divergence_threshold_m", "a positive finite number", self.divergence_threshold_m)

    @property
    def size(self) -> int:
        """Number of episodes."""
        return len(self.scenarios) * len(self.estimators) * len(self.seeds)


def _check_keys(table: dict, allowed: Iterable[str], where: str, source: str | None) -> None:
    extra = sorted(set(table) - set(allowed))
    if extra:
        # the unknown key is what came (its value is not at fault)
        raise ConfigError(f"{where}.{extra[0]}" if where else extra[0], f"one of the keys {sorted(allowed)}",
                          extra[0], source=source)


def _tables(data: dict, key: str, keys: tuple[str, ...], source: str | None) -> Iterator[tuple[str, dict]]:
    """The tables of the non-empty array ``[[key]]``, each as ``(where, table)``, checked to be
    tables with no keys but ``keys``."""
    raw = data.get(key)
    if not isinstance(raw, list) or not raw:
        raise ConfigError(key, f"a non-empty array of tables [[{key}]]", raw, source=source)
    for i, entry in enumerate(raw):
        where = f"{key}[{i}]"
        if not isinstance(entry, dict):
            raise ConfigError(where, f"a table with {', '.join(keys)}", entry, source=source)
        _check_keys(entry, keys, where, source)
        yield where, entry


def _seeds(value: Any, source: str | None) -> tuple[int, ...]:
    from ..report import parse_seeds

    if isinstance(value, list):
        if not value or not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in value):
            raise ConfigError("campaign.seeds", "a non-empty list of non-negative integers", value, source=source)
        if len(set(value)) != len(value):
            raise ConfigError("campaign.seeds", "distinct seeds", value, source=source)
        return tuple(value)
    if isinstance(value, int) and not isinstance(value, bool):
        value = str(value)
    if not isinstance(value, str):
        raise ConfigError("campaign.seeds", "a string 'A:B' / 'A:B:STEP' / '1,4,7' or a list of ints", value,
                          source=source)
    try:
        return tuple(parse_seeds(value))
    except ConfigError as exc:
        raise ConfigError("campaign.seeds", exc.expected, exc.got, source=source) from None


def campaign_from_dict(data: dict, base_dir: str | Path = ".", stem: str = "campaign",
                       source: str | None = None) -> CampaignSpec:
    """Validate a campaign dictionary (as read from TOML) and resolve its scenarios.

    base_dir : folder of the spec (scenario paths, database and report are relative
    to it). stem : default name and file stem. Errors are
    :class:`~navsim.errors.ConfigError` naming the field (e.g. ``scenarios[1].overrides``).
    """
    from ..estimators import available, make
    from ..estimators import check as check_estimator
    from ..scenario import load_scenario

    base = Path(base_dir)
    if not isinstance(data, dict):
        raise ConfigError("campaign", "a TOML table", data, source=source)
    _check_keys(data, ("campaign", "overrides", "scenarios", "estimators"), "", source)
    camp = data.get("campaign", {})
    if not isinstance(camp, dict):
        raise ConfigError("campaign", "a table [campaign]", camp, source=source)
    _check_keys(camp, ("name", "seeds", "divergence_threshold_m", "interval", "database", "report"), "campaign", source)
    if "seeds" not in camp:
        raise ConfigError("campaign.seeds", "seeds of the campaign, e.g. \"0:20\"", None, source=source)
    seeds = _seeds(camp["seeds"], source)
    common = data.get("overrides", {})
    if not isinstance(common, dict):
        raise ConfigError("overrides", "a table of scenario overrides", common, source=source)

    scenarios: list[ScenarioEntry] = []
    for where, entry in _tables(data, "scenarios", ("name", "label", "overrides"), source):
        name = entry.get("name")
        if not isinstance(name, str) or not name:
            raise ConfigError(f"{where}.name", "a bundled scenario name or a .toml path", name, source=source)
        overrides = entry.get("overrides", {})
        if not isinstance(overrides, dict):
            raise ConfigError(f"{where}.overrides", "a table of scenario overrides", overrides, source=source)
        target = name
        if name.endswith(".toml") and not Path(name).is_absolute():
            target = str(base / name)
        try:
            scenario = load_scenario(target)
            if common:
                scenario = scenario.with_overrides(common)
            if overrides:
                scenario = scenario.with_overrides(overrides)
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc.field}", exc.expected, exc.got, source=source) from None
        label = entry.get("label", name if not name.endswith(".toml") else Path(name).stem)
        if not isinstance(label, str) or not label or "/" in label or label in {s.label for s in scenarios}:
            raise ConfigError(f"{where}.label", "a unique non-empty label without '/'", label, source=source)
        scenarios.append(ScenarioEntry(label, scenario, scenario.config_hash()))

    have = available()
    estimators: list[EstimatorEntry] = []
    for where, entry in _tables(data, "estimators", ("name", "label", "options"), source):
        name = entry.get("name")
        if not isinstance(name, str):
            raise ConfigError(f"{where}.name", f"one of {', '.join(have)} or an import path package.module:Factory",
                              name, source=source)
        module_part = name.rsplit(":", 1)[0]
        if module_part.endswith(".py") and not Path(module_part).expanduser().is_absolute():
            # a user's estimator file, relative to the spec like its scenario paths
            name = str((base / module_part).resolve()) + ":" + name.rsplit(":", 1)[1]
        try:
            check_estimator(name)
        except ConfigError as exc:
            raise ConfigError(f"{where}.name", exc.expected, name, source=source) from None
        options = entry.get("options", {})
        if not isinstance(options, dict):
            raise ConfigError(f"{where}.options", "a table of keyword options", options, source=source)
        try:
            make(name, **options)
        except Exception as exc:  # noqa: BLE001 - any refusal of the options is a configuration error
            raise ConfigError(f"{where}.options", f"options accepted by {name} ({exc})", options,
                              source=source) from None
        default = name if not options else name + "(" + ",".join(f"{k}={options[k]}" for k in sorted(options)) + ")"
        label = entry.get("label", default)
        if not isinstance(label, str) or not label or label in {e.label for e in estimators}:
            raise ConfigError(f"{where}.label", "a unique non-empty label", label, source=source)
        opt_json = _canonical_json(options)
        if any(e.name == name and e.options_json == opt_json for e in estimators):
            raise ConfigError(f"{where}", "an estimator and options not already in the campaign", name, source=source)
        estimators.append(EstimatorEntry(label, name, dict(options), opt_json))

    cname = camp.get("name", stem)
    if not isinstance(cname, str):
        raise ConfigError("campaign.name", "a string", cname, source=source)
    database = camp.get("database", f"{stem}.sqlite")
    report = camp.get("report", f"{stem}_report")
    for key, value in (("database", database), ("report", report)):
        if not isinstance(value, str) or not value:
            raise ConfigError(f"campaign.{key}", "a file name", value, source=source)
    threshold = camp.get("divergence_threshold_m", 1000.0)
    if isinstance(threshold, bool) or not isinstance(threshold, (int, float)):
        raise ConfigError("campaign.divergence_threshold_m", "a positive number", threshold, source=source)
    try:
        return CampaignSpec(cname, tuple(scenarios), tuple(estimators), seeds, base / database, base / report,
                            float(threshold), camp.get("interval", "t"))
    except ConfigError as exc:
        raise ConfigError(exc.field, exc.expected, exc.got, source=source) from None


def load_campaign(path: str | Path) -> CampaignSpec:
    """Read and validate a campaign TOML file (see the module docstring)."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        import tomli as tomllib

    path = Path(path)
    if not path.is_file():
        raise ConfigError("campaign", "an existing TOML file", str(path))
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("campaign", "valid TOML", str(exc), source=path.name) from None
    return campaign_from_dict(data, base_dir=path.parent, stem=path.stem, source=path.name)
