"""Provenance in every output that carries scores: version, command, scenario hash, date."""

from __future__ import annotations

import datetime as dt
import json

from navsim import __version__
from navsim.cli import main
from navsim.scenario import load_scenario

SET = ["--set", "timing.duration_s=4"]


def _check(p: dict, scenario_hash, words: list[str]) -> None:
    assert p["navsim_version"] == __version__
    assert p["scenario_hash"] == scenario_hash
    assert all(w in p["command"] for w in words)
    when = dt.datetime.fromisoformat(p["date_utc"])
    assert abs((dt.datetime.now(dt.timezone.utc) - when).total_seconds()) < 3600


def test_run_json_records_the_resolved_scenario(capsys, monkeypatch):
    monkeypatch.setattr("sys.argv", ["navsim", "run", "paper-2012", *SET, "--estimator", "gnss-ls", "--json"])
    assert main(["run", "paper-2012", *SET, "--estimator", "gnss-ls", "-q", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    want = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 4.0}}).config_hash()
    assert want != load_scenario("paper-2012").config_hash()  # the override is in the hash
    _check(out, want, ["navsim run", "gnss-ls"])


def test_bench_outputs_carry_provenance(tmp_path, monkeypatch):
    argv = ["bench", "paper-2012", *SET, "--estimators", "gnss-ls", "--seeds", "0:2", "--out", str(tmp_path),
            "--no-plots", "-q"]
    monkeypatch.setattr("sys.argv", ["navsim", *argv])
    assert main(argv) == 0
    data = json.loads((tmp_path / "bench.json").read_text())
    want = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 4.0}}).config_hash()
    _check(data["provenance"], want, ["navsim bench", "--seeds 0:2"])
    assert f"scenario configuration {want}" in (tmp_path / "bench.md").read_text()


def test_campaign_report_carries_provenance(tmp_path):
    from navsim import campaign as cp

    spec_path = tmp_path / "c.toml"
    spec_path.write_text('[campaign]\nseeds = "0:1"\n[overrides]\ntiming = { duration_s = 4.0 }\n'
                         '[[scenarios]]\nname = "paper-2012"\n[[estimators]]\nname = "gnss-ls"\n', encoding="utf-8")
    spec = cp.load_campaign(spec_path)
    cp.run_campaign(spec, workers=0, progress=False)
    cp.write_report(spec, tmp_path / "rep", plots=False)
    prov = json.loads((tmp_path / "rep" / "provenance.json").read_text())
    label = spec.scenarios[0].label
    _check(prov, {label: spec.scenarios[0].config_hash}, [])
    bench = json.loads((tmp_path / "rep" / label / "bench.json").read_text())
    assert bench["provenance"]["scenario_hash"] == spec.scenarios[0].config_hash
    assert "Provenance: navsim" in (tmp_path / "rep" / "index.md").read_text()
    assert "Provenance: navsim" in (tmp_path / "rep" / "index.html").read_text()


def test_paper_json_ends_with_provenance_rows(capsys):
    assert main(["paper", "001", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    prov = {r["quantity"]: r["navsim"] for r in rows if r["ref"] == "provenance"}
    assert all(set(r) >= {"ref", "quantity", "paper", "navsim", "unit"} for r in rows)
    _check(prov, None, [])
