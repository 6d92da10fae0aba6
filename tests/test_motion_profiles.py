"""Speed profiles: closed forms against numerical integration, stops, continuity."""

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

from navsim.errors import ConfigError
from navsim.motion import ConstantSpeed, ExternalMotion, Station, Timetable


def make_timetable():
    return Timetable(
        stations=(Station(0.0, 10.0), Station(3000.0, 30.0), Station(3400.0, 20.0)),
        cruise_speed=25.0, max_accel=0.8, max_decel=0.6, jerk_time=2.0,
    )


def test_timetable_integrals_are_consistent():
    tt = make_timetable()
    t = np.linspace(0, tt.end_time + 50, 400_001)
    s, v, a = tt.evaluate(t)
    # speed is the integral of acceleration and s the integral of speed
    np.testing.assert_allclose(cumulative_trapezoid(a, t, initial=0), v, atol=1e-6)
    np.testing.assert_allclose(s[0] + cumulative_trapezoid(v, t, initial=0), s, atol=1e-4)
    # limits respected: speed within [0, cruise], acceleration within the limits
    assert v.min() > -1e-9 and v.max() <= 25.0 + 1e-9
    assert a.max() <= 0.8 + 1e-12 and a.min() >= -0.6 - 1e-12


def test_timetable_stops_exactly_at_platforms_and_dwells():
    tt = make_timetable()
    t = np.linspace(0, tt.end_time + 50, 200_001)
    s, v, _ = tt.evaluate(t)
    for station in tt.stations:
        at = np.abs(s - station.s) < 1e-6
        stopped = at & (np.abs(v) < 1e-9)
        # the train stands at each mark for at least its dwell time
        assert stopped.any()
        dwell = t[stopped].max() - t[stopped].min()
        assert dwell >= station.dwell - 1e-3 or station is tt.stations[-1]
    # the short second leg cannot reach cruise speed: peak below it, still stops exactly
    leg2 = (s > 3000.0 + 1e-6) & (s < 3400.0 - 1e-6)
    assert v[leg2].max() < 25.0


def test_acceleration_is_continuous():
    tt = make_timetable()
    t = np.linspace(0, tt.end_time, 1_000_001)
    _, _, a = tt.evaluate(t)
    jerk_bound = np.pi / 2 * 0.8 / 2.0
    assert np.max(np.abs(np.diff(a))) <= jerk_bound * (t[1] - t[0]) * 1.0001


def test_timetable_validation_names_fields():
    with pytest.raises(ConfigError, match=r"motion.stations\[1\].s"):
        Timetable(stations=(Station(100.0), Station(50.0)))
    with pytest.raises(ConfigError, match="motion.max_accel"):
        Timetable(stations=(Station(0.0), Station(50.0)), max_accel=-1)


def test_constant_speed():
    s, v, a = ConstantSpeed(12.5, s0=3.0).evaluate(np.array([0.0, 2.0]))
    np.testing.assert_allclose(s, [3.0, 28.0])
    np.testing.assert_allclose(v, 12.5)
    np.testing.assert_allclose(a, 0.0)


def test_external_motion_hermite_matches_samples_and_polynomial():
    # a quintic motion is reproduced exactly from samples of (s, v, a)
    coef = np.array([0.3, -0.02, 0.5, 1.2, 10.0, 5.0])  # highest power first
    p, dp, ddp = np.poly1d(coef), np.poly1d(coef).deriv(), np.poly1d(coef).deriv(2)
    ext = ExternalMotion(0.0, p(0.0), dp(0.0), ddp(0.0))
    for tk in (0.7, 1.5, 2.0):
        ext.push(tk, p(tk), dp(tk), ddp(tk))
    t = np.linspace(0, 2.0, 101)
    s, v, a = ext.evaluate(t)
    np.testing.assert_allclose(s, p(t), rtol=1e-12)
    np.testing.assert_allclose(v, dp(t), rtol=1e-11)
    np.testing.assert_allclose(a, ddp(t), rtol=1e-9, atol=1e-9)


def test_external_motion_rejects_bad_samples():
    ext = ExternalMotion()
    ext.push(1.0, 1.0, 1.0, 0.0)
    with pytest.raises(ConfigError, match="motion.external.t"):
        ext.push(1.0, 2.0, 1.0, 0.0)
    with pytest.raises(ConfigError, match="finite"):
        ext.push(2.0, float("nan"), 1.0, 0.0)
    with pytest.raises(ConfigError, match="samples covering"):
        ext.evaluate(np.array([1.5]))


def _timetable_reference(tt: Timetable, t: float) -> tuple[float, float]:
    """s and ds/dt at t with the ramp sums in exact rational arithmetic.

    Completed ramps are polynomials in x = (t - t_k) / T (done exactly with Fractions;
    only the constant R2(1) = 1/4 - 1/pi^2 and R1(1) = 1/2 carry a float); an active
    ramp's trigonometric part is bounded and added in floating point.
    """
    import math
    from fractions import Fraction as F

    tj = F(tt.jerk_time)
    r2_1 = F(0.25) - F(1.0 / math.pi**2)
    s, v = F(tt.stations[0].s), F(0)
    for t_k, c in zip(tt._event_times, tt._event_steps):
        x = (F(t) - F(float(t_k))) / tj
        c = F(float(c))
        if x <= 0:
            continue
        if x >= 1:
            b = x - 1
            s += c * tj * tj * (r2_1 + b * (b + 1) / 2)
            v += c * tj * (F(1, 2) + b)
        else:
            xf = float(x)
            s += c * tj * tj * (x * x / 4 + F((math.cos(math.pi * xf) - 1.0) / (2.0 * math.pi**2)))
            v += c * tj * (x / 2 - F(math.sin(math.pi * xf) / (2.0 * math.pi)))
    return float(s), float(v)


def test_timetable_evaluation_has_the_rounding_of_s_only():
    """Late in a long run, s(t) from the piecewise states matches an exact-arithmetic
    reference to the rounding of s itself (the plain sum of ramps does not: its terms
    grow like t^2 and cancel)."""
    tt = Timetable(stations=tuple(Station(3000.0 * k, 20.0) for k in range(12)),
                   cruise_speed=40.0, max_accel=0.7, max_decel=0.7, jerk_time=0.75)
    times = np.concatenate([tt.breakpoints[-6:] + 0.3, [tt.end_time - 5.0, 0.5 * tt.end_time, 1.0]])
    s, v, _ = tt.evaluate(times)
    s_old, _, _ = tt._sum_of_ramps(times)
    err_new = err_old = 0.0
    for k, t in enumerate(times):
        s_ref, v_ref = _timetable_reference(tt, float(t))
        err_new = max(err_new, abs(s[k] - s_ref))
        err_old = max(err_old, abs(s_old[k] - s_ref))
        assert abs(v[k] - v_ref) < 1e-12
    assert err_new < 2e-11  # s ~ 3e4 m: a few ulp
    assert err_old > err_new  # the reason for the piecewise evaluation
