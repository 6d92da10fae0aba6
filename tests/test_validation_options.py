"""The estimator option checks of navsim.validation: accepted values come back as the
documented type, every kind of bad value is refused with a ConfigError naming the field
and the expectation (the values are the edge cases of each definition)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navsim.errors import ConfigError
from navsim.validation import (
    check_auto_none,
    check_choice,
    check_integer,
    check_optional_positive_finite,
    check_positive_finite,
    check_probability,
    check_time_constant,
)


def test_choice_and_auto_none():
    assert check_auto_none("lever_arm", "auto") == "auto"
    assert check_auto_none("lever_arm", "none") == "none"
    assert check_choice("update", "sequential", ("joint", "sequential", "gated")) == "sequential"
    for bad in ("Auto", "", None, 0, True, ("auto",)):
        with pytest.raises(ConfigError, match=r"lever_arm: expected 'auto' or 'none'"):
            check_auto_none("lever_arm", bad)
    with pytest.raises(ConfigError, match=r"update: expected one of \['gated', 'joint', 'sequential'\]"):
        check_choice("update", "fast", ("joint", "sequential", "gated"))


def test_positive_finite():
    for good in (1, 2.5, np.float64(0.25), np.int64(3), 5e-324, 1e308):
        got = check_positive_finite("baro_period_s", good)
        assert type(got) is float and got == float(good)
    for bad in (0, 0.0, -1.0, -0.0, math.inf, -math.inf, math.nan, True, False, "1.0", None, [1.0]):
        with pytest.raises(ConfigError, match="baro_period_s: expected a positive finite time, s"):
            check_positive_finite("baro_period_s", bad, "a positive finite time, s")
    assert check_optional_positive_finite("sigma", None) is None
    assert check_optional_positive_finite("sigma", 2) == 2.0
    with pytest.raises(ConfigError, match="sigma: expected None or a positive finite number"):
        check_optional_positive_finite("sigma", math.inf)


def test_time_constant_takes_inf_as_the_random_constant():
    assert check_time_constant("tau", math.inf) == math.inf
    assert math.exp(-0.1 / check_time_constant("tau", math.inf)) == 1.0  # phi = 1: a random constant
    assert check_time_constant("tau", 1800) == 1800.0
    for bad in (0.0, -5.0, -math.inf, math.nan, True, "60", None):
        with pytest.raises(ConfigError, match=r"tau: expected a positive time constant, s \(inf: a random constant\)"):
            check_time_constant("tau", bad)


# The filters' option checks are these functions: a bool, NaN or a string never passes as a number,
# a time constant, a count or a probability (True == 1 in Python, so a bare isinstance(x, (int,
# float)) test would take it), and the message names the option.
BAD_OPTIONS = [
    ("lc-ekf", "baro_period_s", True), ("lc-ekf", "divergence_epochs", True), ("lc-ekf", "min_satellites", 4.5),
    ("lc-ekf", "divergence_probability", math.nan), ("lc-ekf", "fix_error_tau_s", (True, 60.0)),
    ("lc-ekf", "fix_error_tau_s", 60.0), ("lc-ekf", "covariance_period_s", math.inf), ("lc-ekf", "odometer", "yes"),
    ("tc-ekf", "ionosphere_tau_s", True), ("tc-ekf", "troposphere_tau_s", "3600"), ("tc-ekf", "divergence_epochs", 0),
    ("tc-ukf", "baro_period_s", math.nan), ("tc-ukf", "pseudorange_sigma_m", -1.0), ("tc-ukf", "clock", None),
    ("gnss-ls", "min_satellites", True), ("gnss-ls", "accel_psd", math.inf), ("gnss-cv", "accel_psd", True),
    ("gnss-cv", "measurement_scale", "2"), ("ins-only", "covariance_period_s", True),
    ("full-state-ekf", "cov_step_s", math.nan), ("full-state-ekf", "input_model", "linear"),
    ("full-state-ekf", "lever_arm", True),
    ("paper-ekf", "node_step_m", True), ("paper-ekf", "node_step_m", math.inf), ("paper-ekf", "cov_step_s", True),
    ("paper-ekf", "stiffness_limit", 3.0), ("paper-ekf", "stiffness_limit", True), ("paper-ekf", "engine", "fast"),
    ("paper-ekf", "bias_states", None), ("paper-ekf", "mode", "paper"), ("paper-ekf", "lever_arm", 0),
]


@pytest.mark.parametrize(("name", "option", "value"), BAD_OPTIONS)
def test_filters_refuse_bad_options_through_the_shared_checks(name, option, value):
    from navsim import estimators

    with pytest.raises(ConfigError, match=rf"{option}: expected"):
        estimators.make(name, **{option: value})


def test_filters_keep_whole_numbers_and_infinite_time_constants():
    from navsim import estimators

    est = estimators.make("tc-ekf", divergence_epochs=10.0, ionosphere_tau_s=math.inf)
    assert type(est.options.divergence_epochs) is int and est.options.divergence_epochs == 10
    lc = estimators.make("lc-ekf", fix_error_tau_s=(math.inf, 7200), min_satellites=5.0)
    assert lc.fix_error_tau_s == (math.inf, 7200.0) and lc.min_satellites == 5
    assert check_integer("n", np.int64(7), 1) == 7
    for bad in (True, 0, 2.5, math.inf, math.nan, "3"):
        with pytest.raises(ConfigError, match="n: expected an integer >= 1"):
            check_integer("n", bad, 1)
    assert check_probability("p", 0.5) == 0.5
    for bad in (0.0, 1.0, math.nan, True, "0.5"):
        with pytest.raises(ConfigError, match=r"p: expected a probability in \(0, 1\)"):
            check_probability("p", bad)
