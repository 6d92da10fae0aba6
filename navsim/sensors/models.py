"""The truth-side error models of a scenario's IMU and GNSS receiver: the named preset with
the scenario's per-field overrides applied and checked.

``[imu.gyro]`` / ``[imu.accel]`` override fields of the preset's
:class:`~navsim.sensors.imu.SensorErrors`, ``[gnss.overrides]`` fields of its
:class:`~navsim.sensors.gnss.GnssErrorModel`. An unknown field, or a value the model's
own checks refuse, raises :class:`~navsim.errors.ConfigError` naming the dotted field.
:func:`navsim.validation.validate_scenario` builds both when a scenario is loaded (so
``navsim show`` refuses what ``navsim run`` would) and :class:`~navsim.simulator.Simulator`
builds them for use.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any, Mapping, TypeVar

import numpy as np

from ..errors import ConfigError
from . import gnss as gnss_mod
from . import imu as imu_mod

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

    from ..scenario import Scenario

__all__ = ["build_gnss_error_model", "build_imu_model", "replace_checked"]

_D = TypeVar("_D", bound="DataclassInstance")


def replace_checked(obj: _D, overrides: Mapping[str, Any], prefix: str) -> _D:
    """``dataclasses.replace(obj, **overrides)`` with every key a field of ``obj`` (lists
    become arrays or tuples where the field holds one); errors name ``prefix.key``."""
    names = {f.name for f in dataclasses.fields(obj)}
    for key in overrides:
        if key not in names:
            raise ConfigError(f"{prefix}.{key}", f"a field of {type(obj).__name__}: {sorted(names)}", key)
    converted: dict[str, Any] = {}
    for key, value in overrides.items():
        current = getattr(obj, key)
        if isinstance(current, np.ndarray):
            try:
                converted[key] = np.asarray(value, dtype=float)
            except (TypeError, ValueError):
                raise ConfigError(f"{prefix}.{key}", f"a number or numbers of shape {current.shape}", value) from None
        else:
            converted[key] = tuple(value) if isinstance(current, tuple) and isinstance(value, list) else value
    try:
        return dataclasses.replace(obj, **converted)
    except ConfigError as exc:  # the model's own check: name the field as the scenario spells it
        key = exc.field.rsplit(".", 1)[-1]
        if key in overrides and exc.field != f"{prefix}.{key}":
            raise ConfigError(f"{prefix}.{key}", exc.expected, overrides[key]) from None
        raise
    except (TypeError, ValueError) as exc:
        raise ConfigError(prefix, "valid field values", f"{dict(overrides)} ({exc})") from None


def build_imu_model(scenario: Scenario) -> imu_mod.ImuErrorModel:
    """The truth-side IMU error model: preset plus ``[imu.gyro]``/``[imu.accel]`` overrides."""
    model = imu_mod.imu_preset(scenario.imu.preset)
    changes: dict[str, Any] = {}
    if scenario.imu.gyro:
        changes["gyro"] = replace_checked(model.gyro, scenario.imu.gyro, "imu.gyro")
    if scenario.imu.accel:
        changes["accel"] = replace_checked(model.accel, scenario.imu.accel, "imu.accel")
    return dataclasses.replace(model, **changes) if changes else model


def build_gnss_error_model(scenario: Scenario) -> gnss_mod.GnssErrorModel:
    """The truth-side GNSS error model: preset plus ``gnss.overrides``."""
    cfg = scenario.gnss
    model = gnss_mod.GnssErrorModel.preset(cfg.preset)
    if cfg.overrides:
        model = replace_checked(model, cfg.overrides, "gnss.overrides")
    return model
