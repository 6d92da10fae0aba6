"""Where a scenario's files are found (issue 16): ``track.file`` and a YUMA almanac are
looked for relative to the scenario file, then the current directory, then (bare names
only) navsim's bundled data; a missing file is one error naming every place tried."""

from __future__ import annotations

import shutil
from importlib import resources
from pathlib import Path

import pytest

from navsim.errors import ConfigError
from navsim.scenario import load_scenario
from navsim.simulator import build_track

BUNDLED = Path(str(resources.files("navsim") / "data" / "tracks" / "urban-road.geojson"))
ALMANAC = Path(str(resources.files("navsim") / "data" / "almanac" / "gps_walker_24_6_1.alm"))


def _own(tmp_path: Path, track: str, almanac: str | None = None):
    """tmp_path/scen/mine.toml: the urban-road scenario with its track given by file name."""
    sc = load_scenario("urban-road").with_overrides({"track": {"bundled": "", "file": track}})
    if almanac:
        sc = sc.with_overrides({"gnss": {"constellation": f"yuma:{almanac}"}})
    folder = tmp_path / "scen"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "mine.toml"
    path.write_text(sc.to_toml(), encoding="utf-8")
    return load_scenario(path)


@pytest.fixture
def elsewhere(tmp_path, monkeypatch):
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    return cwd


def test_relative_to_the_scenario_file_first(tmp_path, elsewhere):
    sc = _own(tmp_path, "line.geojson")
    shutil.copy(BUNDLED, tmp_path / "scen" / "line.geojson")
    shutil.copy(BUNDLED, elsewhere / "line.geojson")  # also in the current directory: the scenario's folder wins
    assert sc.resolve_path("line.geojson") == tmp_path / "scen" / "line.geojson"
    assert build_track(sc).length == pytest.approx(build_track(load_scenario("urban-road")).length)


def test_then_the_current_directory(tmp_path, elsewhere):
    sc = _own(tmp_path, "sub/line.geojson")
    (elsewhere / "sub").mkdir()
    shutil.copy(BUNDLED, elsewhere / "sub" / "line.geojson")
    assert sc.resolve_path("sub/line.geojson") == elsewhere / "sub" / "line.geojson"
    assert build_track(sc).length > 0


def test_then_bundled_data_for_a_bare_name(tmp_path, elsewhere):
    sc = _own(tmp_path, "urban-road.geojson", almanac="gps_walker_24_6_1.alm")
    assert sc.resolve_path("urban-road.geojson") == BUNDLED
    assert sc.resolve_path("gps_walker_24_6_1.alm", "almanac") == ALMANAC
    assert sc.file_dependencies() == {"track.file": BUNDLED, "gnss.constellation": ALMANAC}


def test_an_absolute_path_is_itself(tmp_path, elsewhere):
    target = tmp_path / "abs.geojson"
    shutil.copy(BUNDLED, target)
    sc = _own(tmp_path, str(target))
    assert sc.resolve_path(str(target)) == target
    assert sc.file_candidates(str(target)) == [target]


def test_missing_file_names_every_place_tried_and_no_contents(tmp_path, elsewhere):
    sc = _own(tmp_path, "nowhere.geojson")
    with pytest.raises(ConfigError) as err:
        build_track(sc)
    text = str(err.value)
    assert text.startswith("track.file: expected an existing file (looked in: ")
    assert text.endswith(", got 'nowhere.geojson'")  # the value as written, quoted once
    for place in (tmp_path / "scen" / "nowhere.geojson", elsewhere / "nowhere.geojson",
                  BUNDLED.parent / "nowhere.geojson"):
        assert str(place) in text
    # a path with a folder is never looked up among the bundled data
    with pytest.raises(ConfigError) as err:
        sc.resolve_path("../tracks/urban-road.geojson")
    assert str(BUNDLED.parent) not in str(err.value)
    with pytest.raises(ConfigError, match="gnss.constellation"):
        sc.resolve_path("no.alm", "almanac")
