"""Scenario configuration: validation messages, TOML round trip, overrides."""

import sys

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10
    import tomli as tomllib

import pytest

from navsim.errors import ConfigError
from navsim.scenario import Scenario, list_scenarios, load_scenario
from navsim.simulator import Simulator


def test_bundled_scenarios_load_and_round_trip():
    names = list_scenarios()
    assert {"paper-2012", "mountain-railway", "urban-road"} <= set(names)
    for name in names:
        sc = load_scenario(name)
        again = Scenario.from_dict(tomllib.loads(sc.to_toml()), base_dir=sc.base_dir)
        assert again == sc
        assert again.config_hash() == sc.config_hash()


def test_overrides_change_hash_and_values():
    sc = load_scenario("paper-2012")
    sc2 = sc.with_overrides({"timing": {"duration_s": 10.0}, "gnss": {"overrides": {"pseudorange_sigma_m": 3.0}}})
    assert sc2.timing.steps == 1000 and sc2.gnss.overrides == {"pseudorange_sigma_m": 3.0}
    assert sc2.config_hash() != sc.config_hash()
    assert Simulator(sc2).gnss_model.pseudorange_sigma_m == 3.0


@pytest.mark.parametrize("overrides,field", [
    ({"timing": {"imu_period_s": 0.015}}, "timing.imu_period_s"),
    ({"timing": {"nav_period_s": -0.01}}, "timing.nav_period_s"),
    ({"timing": {"gnss_period_s": 0.333}}, "timing.gnss_period_s"),
    ({"timing": {"duration_s": 10.005}}, "timing.duration_s"),
    ({"timing": {"tick": 0.01}}, "timing.tick"),
    ({"imu": {"orders": 9}}, "imu.orders"),
    ({"motion": {"profile": "teleport"}}, "motion.profile"),
    ({"motion": {"speed_mps": "fast"}}, "motion.speed_mps"),
    ({"earth": "flat"}, "earth"),
    ({"outages": {"windows_s": [[700.0, 400.0]]}}, "windows_s"),
    ({"colour": "red"}, "colour"),
])
def test_bad_values_name_the_field(overrides, field):
    with pytest.raises(ConfigError) as info:
        load_scenario("paper-2012").with_overrides(overrides)
    assert field in str(info.value)
    assert "expected" in str(info.value) and "got" in str(info.value)


@pytest.mark.parametrize("overrides,field", [
    ({"imu": {"gyro": {"no_such_error": 1.0}}}, "imu.gyro.no_such_error"),
    ({"gnss": {"overrides": {"sigma": 1.0}}}, "gnss.overrides.sigma"),
    ({"gnss": {"constellation": "galileo"}}, "gnss.constellation"),
    ({"motion": {"speed_mps": 50.0}}, "motion"),  # runs off the end of the 24 km track
])
def test_errors_found_when_the_simulator_is_built(overrides, field):
    with pytest.raises(ConfigError, match=field.replace(".", r"\.")):
        Simulator(load_scenario("paper-2012").with_overrides(overrides))


def test_malformed_and_missing_files(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\n[timing\nduration_s = 3")
    with pytest.raises(ConfigError, match="bad.toml: scenario: expected valid TOML"):
        load_scenario(bad)
    with pytest.raises(ConfigError, match="bundled scenario"):
        load_scenario("no-such-scenario")
    unknown = tmp_path / "unknown.toml"
    unknown.write_text("name = 'x'\n[track]\nbundled = 'paper-2012'\nfile = 'a.csv'\n")
    with pytest.raises(ConfigError, match="unknown.toml: track: expected exactly one"):
        load_scenario(unknown)


def test_scenario_file_with_relative_track(tmp_path):
    import numpy as np

    from navsim.trackio import write_csv

    lat = np.radians([47.0, 47.001, 47.002, 47.003])
    lon = np.radians([39.0, 39.0005, 39.001, 39.0015])
    write_csv(tmp_path / "line.csv", lat, lon, [10, 11, 12, 13])
    path = tmp_path / "mine.toml"
    path.write_text("name = 'mine'\n[track]\nfile = 'line.csv'\n[motion]\nspeed_mps = 5.0\n[timing]\nduration_s = 20.0\n")
    sim = Simulator(load_scenario(path))
    sim.reset(0)
    assert len(sim.advance(100)) == 100
