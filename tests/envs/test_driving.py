"""Train plant (closed forms) and the driving task (stops, overrun, observation from the estimate)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import navsim.envs  # noqa: E402,F401
from gymnasium.utils.env_checker import check_env  # noqa: E402
from navsim.envs.driving import braking_curve_driver as _driver  # noqa: E402
from navsim.envs.plant import G0, TrainParameters, TrainPlant  # noqa: E402

from navsim.errors import ConfigError  # noqa: E402

FLAT = lambda s: 0.0  # noqa: E731
SHORT = {"motion": {"stations": [{"s_m": 400.0, "dwell_s": 3.0}, {"s_m": 900.0, "dwell_s": 5.0}]}}


def test_constant_traction_with_linear_resistance_matches_closed_form():
    p = TrainParameters(max_power_w=1e12, davis_c_n_per_mps2=0.0, rotary_allowance=0.0)
    plant = TrainPlant(FLAT, p)
    plant.reset(0.0, 0.0)
    s, v, a, energy = plant.advance(1.0, 0.01, 2000)  # 20 s at F_max
    m, F, A, B = p.mass_kg, p.max_traction_n, p.davis_a_n, p.davis_b_n_per_mps
    t = 0.01 * np.arange(1, 2001)
    v_exact = (F - A) / B * (1.0 - np.exp(-B * t / m))  # v' = (F - A - B v) / m
    s_exact = (F - A) / B * (t - m / B * (1.0 - np.exp(-B * t / m)))
    assert np.allclose(v, v_exact, rtol=1e-9, atol=1e-9)
    assert np.allclose(s, s_exact, rtol=1e-8, atol=1e-8)
    assert energy == pytest.approx(F * s_exact[-1], rel=1e-4)  # force-limited: E = F * distance (trapezoid in time)


def test_braking_stops_at_v0_squared_over_2b_and_does_not_roll_back():
    p = TrainParameters(davis_a_n=0.0, davis_b_n_per_mps=0.0, davis_c_n_per_mps2=0.0)
    plant = TrainPlant(FLAT, p)
    plant.reset(100.0, 20.0)
    s, v, a, _ = plant.advance(-1.0, 0.01, 3000)
    b = p.max_brake_decel_mps2
    stop = np.argmax(v == 0.0)
    assert stop * 0.01 == pytest.approx(20.0 / b, abs=0.011)
    assert s[-1] == pytest.approx(100.0 + 20.0**2 / (2 * b), abs=1e-6)
    assert np.all(v[stop:] == 0.0) and np.all(np.diff(s) >= 0.0)
    # on a 5 % grade traction of 10 % cannot start the train: it stays, it does not roll back
    steep = TrainPlant(lambda s: 0.05, p)
    steep.reset(50.0, 0.0)
    s, v, _, _ = steep.advance(0.1, 0.01, 100)
    assert np.all(s == 50.0) and np.all(v == 0.0)
    # full traction does: 160 kN > 200 t * g * 0.05 = 98 kN
    s, v, a, _ = steep.advance(1.0, 0.01, 100)
    assert v[-1] > 0.0 and a[-1] == pytest.approx((p.max_traction_n / max(1, 1) - p.mass_kg * G0 * 0.05)
                                                    / p.effective_mass_kg, rel=0.05)




def test_check_env_without_warnings():
    env = gym.make("navsim/TrainDriving-v0", **SHORT)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    assert [str(w.message) for w in caught] == []


def test_driver_on_the_estimate_stops_at_the_mark():
    env = gym.make("navsim/TrainDriving-v0", truth_in_info=True, **SHORT)
    obs, info = env.reset(seed=3)
    assert np.array_equal(info["marks_m"], [400.0, 900.0])
    gaps = []
    while True:
        obs, r, term, trunc, info = env.step(_driver(obs))
        gaps.append(abs((900.0 - info["truth"]["s"]) / 1000.0 - obs[0]) * 1000.0)  # estimate vs truth, m
        if term or trunc:
            break
    assert term and not trunc and "overrun_m" not in info
    (stop,) = info["stops"]
    assert abs(stop["stop_error_m"]) <= 2.0
    assert 0.0 < max(gaps) < 20.0  # the observation is the estimate: close to, not equal to, the truth
    assert info["energy_kwh"] > 0.0 and info["episode_score"].steps == env.unwrapped.steps_done < env.unwrapped.n_steps


def test_full_traction_overruns_and_is_penalised():
    env = gym.make("navsim/TrainDriving-v0", **SHORT)
    obs, info = env.reset(seed=0)
    total = 0.0
    while True:
        obs, r, term, trunc, info = env.step(np.ones(1, np.float32))
        total += r
        if term or trunc:
            break
    assert term and info["overrun_m"] > 2.0 and total < -20.0


# ---------------------------------------------------------------- the reward: lateness accrues, unserved stations cost
TWO_STOPS = {"motion": {"stations": [{"s_m": 400.0, "dwell_s": 10.0}, {"s_m": 1500.0, "dwell_s": 20.0}]}}
THREE_STOPS = {"motion": {"stations": [{"s_m": 400.0, "dwell_s": 10.0}, {"s_m": 1500.0, "dwell_s": 20.0},
                                       {"s_m": 3000.0, "dwell_s": 10.0}]}}
STAND = lambda obs: np.array([0.0], np.float32)  # noqa: E731
CONSTANT = lambda obs: np.array([0.3], np.float32)  # noqa: E731  the naive driver: one command all the way


_timetable_driver = _driver  # braking curve on the estimate, cruising at 17 m/s: on time for the 5 %-stretched timetable


def _episode(policy, seed, layout, **kwargs):
    env = gym.make("navsim/TrainDriving-v0", **layout, **kwargs)
    obs, info = env.reset(seed=seed)
    total = 0.0
    while True:
        obs, r, term, trunc, info = env.step(policy(obs))
        total += r
        if term or trunc:
            return total, info, env.unwrapped


def test_standing_still_costs_the_accrued_lateness_and_the_unserved_stations():
    # comfort and energy off: what is left is the lateness and the unserved charge
    total, info, env = _episode(STAND, 100, TWO_STOPS, weights={"comfort": 0.0, "energy": 0.0})
    w = env.weights
    end = env.steps_done * env.dt
    # closed form: station 1 late from its scheduled arrival to the end (sum of per-period increments: rel 1e-9)
    expected = -w["late"] * sum(max(end - a, 0.0) for a in env.sched_arr[1:]) / 60.0 - w["unserved"] * 1
    assert info["unserved"] == 1 and info["stops"] == []
    assert total == pytest.approx(expected, rel=1e-9, abs=1e-9)
    assert total < -w["unserved"] - 2.0  # the lateness (27 s at 5 per minute) is a real part of it


def test_a_missed_station_costs_the_overrun_more_than_one_never_reached():
    """(R.2)-(R.4) with comfort and energy off: the constant command drives through the
    station (an overrun, the episode ends there); the missed station then accrues the same
    lateness to the time limit and the same unserved charge as standing still in front of
    it, so the two returns differ by the overrun charge exactly (sums of per-period
    increments of size ~1: rel 1e-9)."""
    quiet = {"weights": {"comfort": 0.0, "energy": 0.0}}
    stand = _episode(STAND, 100, TWO_STOPS, **quiet)
    naive = _episode(CONSTANT, 100, TWO_STOPS, **quiet)
    w = naive[2].weights
    assert "overrun_m" in naive[1] and naive[1]["unserved"] == 1 and naive[1]["missed"] == 1
    assert naive[2].steps_done < stand[2].steps_done  # it ended at the overrun, before the time limit
    assert naive[1]["late_charged_s"] == pytest.approx(stand[1]["late_charged_s"], rel=1e-12)
    assert naive[0] == pytest.approx(stand[0] - w["overrun"], rel=1e-9)


CONSTANT_DRIVERS = {"u = 0.3": ({}, CONSTANT), "u = 1": ({}, lambda obs: np.ones(1, np.float32)),
                    "line speed demand": ({"action_mode": "target_speed"}, lambda obs: np.ones(1, np.float32))}


def test_reward_orders_naive_and_standing_below_the_timetable_driver():
    """Held-out seed (no policy was tuned on it): every constant-command driver (it runs
    through the station) < standing still < the timetable driver. The margins are the
    charges: an overrun costs 20 more than standing still, which costs the 40 of the
    unserved station plus its lateness, while the timetable driver earns up to the bonus 10."""
    timed = _episode(_timetable_driver, 100, TWO_STOPS)
    stand = _episode(STAND, 100, TWO_STOPS)
    (stop,) = timed[1]["stops"]
    assert abs(stop["stop_error_m"]) <= 2.0 and stop["late_s"] <= 0.0 and timed[1]["unserved"] == 0
    assert stand[0] + 40.0 < timed[0]
    for name, (kwargs, policy) in CONSTANT_DRIVERS.items():
        total, info, _ = _episode(policy, 100, TWO_STOPS, **kwargs)
        assert "overrun_m" in info and info["unserved"] == 1, name
        assert total + 15.0 < stand[0], name  # 20 more minus at most the energy difference
        assert total + 60.0 < timed[0], name


@pytest.mark.slow
def test_reward_order_three_stations_three_held_out_seeds():
    for seed in (100, 101, 102):
        stand, naive, timed = (_episode(p, seed, THREE_STOPS)[0] for p in (STAND, CONSTANT, _timetable_driver))
        assert naive + 15.0 < stand < timed - 80.0


# ---------------------------------------------------------------- the final-approach observation and the optional shaping
def test_shaping_telescopes_and_leaves_the_task_reward_unchanged():
    """Potential-based shaping (Ng et al. 1999): over an episode the shaping terms sum to
    Phi(end) - Phi(start). Full traction from rest at 400 m drives through the 900-m mark
    (an overrun: no station left, so Phi(end) = 0; Phi(start) = -c_p * 0.5 km - c_a, the
    braking term 0 at rest, the approach term at its cap 500 m > 50 m): the shaping totals
    0.5 c_p + c_a; the task reward is that of the env without shaping, the same operations
    in the same order (bit for bit)."""
    full = lambda obs: np.ones(1, np.float32)  # noqa: E731
    c_p, c_b, c_a = 20.0, 2.0, 7.0
    env = gym.make("navsim/TrainDriving-v0", progress_shaping=c_p, braking_shaping=c_b, approach_shaping=c_a, **SHORT)
    obs, _ = env.reset(seed=5)
    shaped, task, braking_seen = [], [], False
    while True:
        obs, r, term, trunc, info = env.step(full(obs))
        shaped.append(r)
        task.append(info["task_reward"])
        # the braking-curve entry: (v_b(d) - v) / 2 with v_b = sqrt(2 * 0.5 * max(d, 0)), from entries 0 and 1
        d, v = obs[0] * 1000.0, obs[1] * 30.0
        # float32 entries: d to ~1e-4 m, so sqrt(d) near d = 0 to ~1e-2 m/s
        assert obs[10] == pytest.approx(np.clip((math.sqrt(max(d, 0.0)) - v) / 2.0, -5, 5), abs=5e-3)
        assert obs[9] == pytest.approx(np.clip(d / 10.0, -3, 3), abs=1e-5)
        braking_seen |= obs[10] < 0  # the train was above the braking curve at some point
        if term or trunc:
            break
    assert term and "overrun_m" in info and braking_seen
    assert sum(shaped) - sum(task) == pytest.approx(0.5 * c_p + c_a, rel=1e-9)
    plain = _episode(full, 5, SHORT)
    assert plain[0] == sum(task)


# ---------------------------------------------------------------- action_mode="target_speed": the speed demand (D.1)
def test_target_speed_mode_passes_check_env_and_rejects_bad_options():
    env = gym.make("navsim/TrainDriving-v0", action_mode="target_speed", **SHORT)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    assert [str(w.message) for w in caught] == []
    for bad in ({"action_mode": "speed"}, {"speed_gain": 0.0}, {"speed_gain": float("nan")}):
        with pytest.raises(ConfigError):
            gym.make("navsim/TrainDriving-v0", **SHORT, **bad)


def test_target_speed_command_is_the_controller_on_the_estimate():
    """(D.1): the command applied over a period (observation entry 6 after the step) is
    clip(k_v ((a + 1) / 2 v_top - max(v_hat, 0)), -1, 1) with v_hat the speed estimate seen
    before the step (entry 1 x 30 m/s, float32: ~1e-6 m/s, so 1e-5 in u); a = -1 never pulls."""
    k_v = 0.8
    env = gym.make("navsim/TrainDriving-v0", action_mode="target_speed", speed_gain=k_v, **SHORT)
    v_top = env.unwrapped._line_speed
    obs, _ = env.reset(seed=2)
    actions = [-0.5] * 5 + [0.9] * 20 + [0.2] * 10 + [-1.0] * 15
    checked = 0
    for a in actions:
        v_hat, dwelling = float(obs[1]) * 30.0, obs[7] > 0
        obs, r, term, trunc, info = env.step(np.array([a], np.float32))
        expected = 0.0 if dwelling else float(np.clip(k_v * (0.5 * (a + 1.0) * v_top - max(v_hat, 0.0)), -1, 1))
        assert obs[6] == pytest.approx(expected, abs=1e-5)
        if a == -1.0:
            assert obs[6] <= 0.0
        checked += not dwelling
        if term or trunc:
            break
    assert checked > 30 and float(obs[1]) * 30.0 < 1.0  # the stop demand brought the train (nearly) to rest


def test_target_speed_braking_curve_demand_serves_the_station():
    """The braking curve as a speed demand (v_ref = min(cruise, sqrt(2 b d))) through (D.1):
    the target-speed mode can express a driver that stops within the tolerance."""
    env = gym.make("navsim/TrainDriving-v0", action_mode="target_speed", **SHORT)
    v_top = env.unwrapped._line_speed
    obs, _ = env.reset(seed=3)
    while True:
        v_ref = min(17.0, math.sqrt(2 * 0.45 * max(float(obs[0]) * 1000.0 - 0.5, 0.0)))
        obs, r, term, trunc, info = env.step(np.array([2.0 * v_ref / v_top - 1.0], np.float32))
        if term or trunc:
            break
    assert term and "overrun_m" not in info
    (stop,) = info["stops"]
    assert abs(stop["stop_error_m"]) <= 2.0


def test_ppo_demo_pipeline_runs():
    """The PPO demos' shared pipeline (benchmarks/_ppo_common.py) for a few hundred steps:
    it trains, gives a policy with valid actions and a learning curve; no learning asserted."""
    pytest.importorskip("stable_baselines3", reason="stable-baselines3 is in the test extra only on Python 3.11")
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "_ppo_common.py"
    spec = importlib.util.spec_from_file_location("_ppo_common", path)
    common = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(common)
    policy, stats = common.train("navsim/TrainDriving-v0", SHORT, 256, 2, n_steps=64,
                                 train_kwargs={"progress_shaping": 20.0})
    assert stats["steps"] == 256 and stats["wall_s"] > 0.0
    assert len(stats["curve"]) >= 2 and all(math.isfinite(r) for _, r in stats["curve"])  # episodes of <= 100 steps
    res = common.compare("navsim/TrainDriving-v0", SHORT, {"ppo": policy, "stand": STAND}, [7])
    (ret, info), = res["ppo"]
    assert math.isfinite(ret) and "episode_score" in info
    env = gym.make("navsim/TrainDriving-v0", **SHORT)
    obs, _ = env.reset(seed=7)
    assert env.action_space.contains(np.asarray(policy(obs), dtype=np.float32).reshape(1))
    assert res["stand"][0][0] == _episode(STAND, 7, SHORT)[0]


# ---------------------------------------------------------------- the fast paths: the same numbers
def test_plant_table_path_equals_the_generic_path_bit_for_bit():
    """TrainPlant with the grade table inline (and the end-of-step force reused as the next
    first RK4 stage) against the generic path through ``sin_grade``: the same operations on
    the same numbers, over traction, power limit, braking to rest, standing and restart."""
    env = gym.make("navsim/TrainDriving-v0", **SHORT).unwrapped
    fast = env.plant
    generic = TrainPlant(env.map.sin_grade, fast.p)
    assert fast._table is not None and generic._table is None
    for plant in (fast, generic):
        plant.reset(380.0, 0.0)
    for u in [1.0] * 30 + [0.4, 0.0, -0.2] * 5 + [-1.0] * 25 + [0.05, 0.3, 1.0] * 4:
        a, b = fast.advance(u, 0.02, 50), generic.advance(u, 0.02, 50)
        for x, y in zip(a[:3], b[:3]):
            assert np.array_equal(x, y)
        assert a[3] == b[3] and (fast.s, fast.v, fast.a) == (generic.s, generic.v, generic.a)
    assert generic.s > 900.0  # the sequence crossed the station and the grade table's cells


def _replay(actions):
    """A policy that plays the given actions in order, whatever it observes."""
    it = iter(actions)
    return lambda obs: next(it).reshape(1)


def _trace(env, policy, seed):
    obs, _ = env.reset(seed=seed)
    out = [obs.tobytes()]
    while True:
        obs, r, term, trunc, info = env.step(policy(obs))
        out.append((obs.tobytes(), r, info["task_reward"], info["truth"], info["energy_kwh"], info["late_charged_s"]))
        if term or trunc:
            out.append((info["stops"], info["unserved"], info["missed"]))
            return out


def test_fast_env_equals_the_reference_env_for_a_fixed_action_sequence():
    """The training configuration (plant table path, ``episode_score=False``) against the
    reference (generic plant path, the episode recorded and scored): observations, rewards
    and infos equal bit for bit for the same actions (a fixed random sequence: an overrun;
    the braking-curve driver, whose actions then agree as well: a stop), in both action
    modes, with the shaping on."""
    fixed = np.clip(np.random.default_rng(11).normal(0.4, 0.7, 300), -1, 1).astype(np.float32)
    events = set()
    for mode in ("command", "target_speed"):
        ref = gym.make("navsim/TrainDriving-v0", truth_in_info=True, action_mode=mode,
                       approach_shaping=5.0, **SHORT).unwrapped
        ref.plant._table = None  # the generic path
        fast = gym.make("navsim/TrainDriving-v0", truth_in_info=True, action_mode=mode, approach_shaping=5.0,
                        episode_score=False, **SHORT).unwrapped
        for make in ((lambda: _driver), lambda: _replay(fixed)):
            if mode == "target_speed" and make() is _driver:
                continue  # the driver speaks the command mode
            a, b = _trace(ref, make(), 21), _trace(fast, make(), 21)
            assert a == b
            events |= {"stop_error_m" in st and "stop" or "overrun" for st in a[-1][0]}
    assert events == {"stop", "overrun"}
