"""The public noise-scaling protocol (set_noise_scale) of every bundled estimator."""

from __future__ import annotations

import numpy as np
import pytest

from navsim import estimators
from navsim.episode import make_context
from navsim.estimators.base import NoiseScaling, _get_path
from navsim.scenario import load_scenario
from navsim.simulator import Simulator


def _start(preset: str, sigma_m: float):
    sc = load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 2.0}, "imu": {"preset": preset},
                                                      "gnss": {"overrides": {"pseudorange_sigma_m": sigma_m,
                                                                             "doppler_sigma_mps": sigma_m / 30}}})
    sim = Simulator(sc)
    return make_context(sc), sim.reset(0).prior


@pytest.mark.parametrize("name", estimators.available())
def test_scales_are_relative_to_the_last_reset(name):
    est = estimators.make(name)
    assert isinstance(est, NoiseScaling)
    paths = (*est.NOISE_PROCESS, *est.NOISE_MEASUREMENT_VARIANCE, *est.NOISE_MEASUREMENT_SIGMA)
    assert paths, "a bundled estimator declares where its noise lives"
    first, second = _start("paper-2012", 15.0), _start("tactical", 3.0)
    est.reset(*first)
    est.set_noise_scale(4.0, 9.0)
    est.set_noise_scale(4.0, 9.0)  # twice: no compounding
    est.reset(*second)  # other nominal sensors: other base values
    want = {p: np.copy(_get_path(est, p)) for p in paths}
    est.reset(*first)
    before = {p: np.copy(_get_path(est, p)) for p in paths}
    assert any(not np.array_equal(before[p], want[p]) for p in paths)  # the two resets set other values
    est.set_noise_scale(2.0, 2.0)
    est.reset(*second)
    est.set_noise_scale(4.0, 9.0)
    for p in est.NOISE_PROCESS:
        assert np.allclose(_get_path(est, p), 4.0 * want[p], rtol=1e-15, atol=0)
    for p in est.NOISE_MEASUREMENT_VARIANCE:
        assert _get_path(est, p) == pytest.approx(9.0 * want[p], rel=1e-15)
    for p in est.NOISE_MEASUREMENT_SIGMA:
        assert _get_path(est, p) == pytest.approx(3.0 * want[p], rel=1e-15)
    est.set_noise_scale(1.0, 1.0)
    for p in paths:
        assert np.array_equal(_get_path(est, p), want[p])
    with pytest.raises(ValueError):
        est.set_noise_scale(0.0, 1.0)
