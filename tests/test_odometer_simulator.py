"""The wheel odometer in the scenario, the simulator, the batch simulator and io.

The comparison with the code before the odometer existed runs when the environment
variable NAVSIM_REFERENCE_TREE names a checkout of that commit (e.g. made with
``git worktree add <dir> <commit>``): the reference runs in a subprocess, so the two
``navsim`` packages never meet in one interpreter.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from navsim.errors import ConfigError
from navsim.scenario import Scenario, load_scenario
from navsim.simulator import STREAMS, Simulator, SimulatorBatch

ODO = {"enabled": True, "preset": "rail-tachometer"}


def _short(duration=3.0, odometer=None, name="mountain-railway"):
    over = {"timing": {"duration_s": duration}}
    if odometer is not None:
        over["odometer"] = odometer
    return load_scenario(name).with_overrides(over)


# ----------------------------------------------------------------------- scenario
def test_default_table_changes_neither_toml_nor_hash():
    for name in ("paper-2012", "mountain-railway", "urban-road"):
        sc = load_scenario(name)
        assert "odometer" not in sc.to_dict()
        assert "odometer" not in sc.to_toml()
        assert not sc.odometer.enabled
    sc = load_scenario("paper-2012")
    on = sc.with_overrides({"odometer": ODO})
    assert on.config_hash() != sc.config_hash()
    assert on.with_overrides({"odometer": {"enabled": False}}).config_hash() == sc.config_hash()


def test_odometer_table_round_trips_and_validates(tmp_path):
    sc = load_scenario("paper-2012").with_overrides(
        {"odometer": {"enabled": True, "preset": "car-wheel-speed", "overrides": {"slip_fraction": 0.05}}})
    assert Scenario.from_dict(sc.to_dict(), base_dir=sc.base_dir) == sc
    path = tmp_path / "s.toml"
    path.write_text(sc.to_toml())
    again = load_scenario(path)
    assert again.odometer == sc.odometer and again.config_hash() == sc.config_hash()
    assert sc.odometer.model().slip_fraction == 0.05
    with pytest.raises(ConfigError, match="odometer.preset"):
        sc.with_overrides({"odometer": {"preset": "unicycle"}})
    with pytest.raises(ConfigError, match="odometer.overrides.wheel"):
        sc.with_overrides({"odometer": {"overrides": {"wheel": 1.0}}})
    with pytest.raises(ConfigError, match=r"odometer\.overrides\.slip_fraction"):
        sc.with_overrides({"odometer": {"overrides": {"slip_fraction": 2.0}}})
    with pytest.raises(ConfigError, match="odometer.enabled"):
        sc.with_overrides({"odometer": {"enabled": "yes"}})


# ----------------------------------------------------------------------- streams
def test_appended_stream_leaves_the_earlier_streams_unchanged():
    assert STREAMS[5] == "odometer" and STREAMS[6:] == ("baro",)  # appended after it: its index is kept
    seq5 = np.random.SeedSequence(42).spawn(5)
    seq6 = np.random.SeedSequence(42).spawn(6)
    for a, b in zip(seq5, seq6):
        assert np.array_equal(np.random.Generator(np.random.PCG64(a)).standard_normal(8),
                              np.random.Generator(np.random.PCG64(b)).standard_normal(8))


def test_switching_the_odometer_on_changes_no_other_number():
    off, on = Simulator(_short()), Simulator(_short(odometer=ODO))
    a, b = off.reset(3), on.reset(3)
    assert np.array_equal(a.prior.covariance, b.prior.covariance)
    assert np.array_equal(a.prior.velocity_n, b.prior.velocity_n)
    assert a.prior.lat == b.prior.lat and a.prior.heading == b.prior.heading
    ca, cb = off.advance(300), on.advance(300)
    assert ca.odometer is None and cb.odometer is not None
    assert np.array_equal(ca.imu.dtheta_r, cb.imu.dtheta_r) and np.array_equal(ca.imu.dv_r, cb.imu.dv_r)
    assert np.array_equal(ca.gnss.pseudorange_m, cb.gnss.pseudorange_m)
    assert np.array_equal(ca.gnss.valid, cb.gnss.valid)


# ----------------------------------------------------------------------- generation
def test_ideal_odometer_sums_to_the_true_distance():
    sim = Simulator(_short(20.0, odometer={"enabled": True, "preset": "ideal"}))
    start = sim.reset(0)
    chunks = list(sim.chunks(700))
    ds = np.concatenate([c.odometer.ds_m for c in chunks])
    s = np.concatenate([c.truth.s for c in chunks])
    np.testing.assert_allclose(np.cumsum(ds), s - start.truth.s[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(ds, np.diff(s, prepend=start.truth.s[0]), rtol=0, atol=1e-12)


def test_quantised_distance_tracks_the_truth_within_a_pulse_plus_scale():
    sc = _short(20.0, odometer={"enabled": True, "preset": "rail-tachometer",
                                "overrides": {"scale_factor_sigma": 0.0, "scale_factor_gm_sigma": 0.0,
                                              "noise_density_m_per_sqrt_s": 0.0, "slip_fraction": 0.0,
                                              "slide_fraction": 0.0}})
    sim = Simulator(sc)
    start = sim.reset(1)
    chunk = sim.advance(2000)
    p = sc.odometer.model().pulse_length_m
    gap = (chunk.truth.s - start.truth.s[0]) - np.cumsum(chunk.odometer.ds_m)
    assert gap.min() >= -1e-9 and gap.max() < p + 1e-9
    assert np.all(chunk.odometer.pulses == np.rint(chunk.odometer.ds_m / p))


def test_simulator_chunk_invariance_with_odometer():
    sc = _short(6.0, odometer=ODO)
    a, b = Simulator(sc), Simulator(sc)
    a.reset(5), b.reset(5)
    whole = a.advance(600)
    parts = [b.advance(n) for n in (1, 136, 63, 400)]
    for name in ("ds_m", "pulses", "scale_factor"):
        assert np.array_equal(np.concatenate([getattr(c.odometer, name) for c in parts]), getattr(whole.odometer, name))


def test_batch_member_equals_single_simulator_with_odometer():
    sc = _short(4.0, odometer=ODO)
    batch = SimulatorBatch(sc, 3)
    batch.reset([7, 8, 9])
    chunks = [batch.advance(n) for n in (150, 250)]
    for j, seed in enumerate((7, 8, 9)):
        sim = Simulator(sc)
        sim.reset(seed)
        for cb, n in zip(chunks, (150, 250)):
            single = sim.advance(n)
            member = cb.member(j)
            assert np.array_equal(member.odometer.ds_m, single.odometer.ds_m)
            assert np.array_equal(member.odometer.pulses, single.odometer.pulses)
            assert np.array_equal(member.imu.dv_r, single.imu.dv_r)


def test_io_writes_the_odometer_keys(tmp_path):
    from navsim.io import write_csv, write_npz

    sim = Simulator(_short(2.0, odometer=ODO))
    sim.reset(0)
    chunks = list(sim.chunks(90))
    data = np.load(write_npz(tmp_path / "e.npz", chunks))
    assert np.array_equal(data["odometer_ds_m"], np.concatenate([c.odometer.ds_m for c in chunks]))
    assert data["odometer_pulses"].dtype == np.int64
    steps, _ = write_csv(tmp_path / "e.csv", chunks)
    header = steps.read_text().splitlines()[0].split(",")
    assert header[-2:] == ["odometer_ds_m", "odometer_pulses"]
    off = Simulator(_short(2.0))
    off.reset(0)
    assert "odometer_ds_m" not in np.load(write_npz(tmp_path / "f.npz", list(off.chunks(90)))).files


# ----------------------------------------------------------------------- against the old code
_REFERENCE = os.environ.get("NAVSIM_REFERENCE_TREE")

_DUMP = textwrap.dedent("""
    import sys
    sys.path.insert(0, sys.argv[1])
    import numpy as np
    from navsim.scenario import load_scenario
    from navsim.simulator import Simulator, SimulatorBatch
    from navsim.episode import run_episode
    from navsim.estimators import make
    from navsim.io import chunk_arrays
    out = {}
    for name in ("paper-2012", "mountain-railway", "urban-road"):
        sc = load_scenario(name).with_overrides({"timing": {"duration_s": 30.0}})
        sim = Simulator(sc)
        start = sim.reset(11)
        arrays = chunk_arrays(sim.advance(3000))
        for k, v in arrays.items():
            out[f"{name}/{k}"] = v
        out[f"{name}/prior"] = np.array([start.prior.lat, start.prior.lon, start.prior.h, start.prior.heading])
        out[f"{name}/hash"] = np.array(sc.config_hash())
        out[f"{name}/toml"] = np.array(sc.to_toml())
        b = SimulatorBatch(sc, 2)
        b.reset([11, 12])
        out[f"{name}/batch_dv"] = b.advance(500).imu.dv_r
        for est in ("lc-ekf", "along-track"):
            rec = run_episode(sc, make(est), seed=2, simulator=sim)
            out[f"{name}/{est}"] = np.column_stack([rec.est_lat, rec.est_lon, rec.est_h, rec.est_velocity_n])
            out[f"{name}/{est}/cov"] = rec.est_cov
    np.savez(sys.argv[2], **out)
""")


@pytest.mark.skipif(not _REFERENCE, reason="set NAVSIM_REFERENCE_TREE to a checkout of the pre-odometer commit")
def test_disabled_odometer_is_bit_identical_to_the_reference_tree(tmp_path):
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    files = {}
    for label, tree in (("ref", _REFERENCE), ("new", here)):
        files[label] = tmp_path / f"{label}.npz"
        subprocess.run([sys.executable, "-c", _DUMP, tree, str(files[label])], check=True,
                       env={**os.environ, "PYTHONPATH": tree})
    ref, new = np.load(files["ref"]), np.load(files["new"])
    assert sorted(ref.files) == sorted(new.files)
    for key in ref.files:
        assert np.array_equal(ref[key], new[key], equal_nan=ref[key].dtype.kind == "f"), key
