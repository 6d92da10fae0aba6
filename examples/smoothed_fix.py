"""An estimator written outside navsim, to show the plug-in path end to end.

``SmoothedFix`` is a GNSS-only estimator built from navsim's public receiver-side API
(:mod:`navsim.receiver`): at each GNSS epoch it takes the single-epoch least-squares
position and velocity fixes, and blends the position with its own constant-velocity
prediction by a fixed gain ``gain`` (an alpha filter; ``gain = 1`` is the raw fix).
Between epochs and through outages it extrapolates with the last velocity. Its covariance
is a simple diagonal guess: sigma_rho^2 * DOP^2 * gain/(2 - gain) per axis at a fix (the
steady-state variance of an alpha filter on white fix errors), growing as
``q tau^3 / 3`` while extrapolating (velocity: sigma_dot^2 * DOP^2, growing as ``q tau``). Attitude is not estimated (NaN), as for the bundled
GNSS-only estimators.

Use it by import path wherever navsim takes an estimator name (from the folder that holds
``examples/``, or give the file):

    navsim run paper-2012 --estimator examples.smoothed_fix:SmoothedFix --option gain=0.5
    navsim bench paper-2012 --estimators lc-ekf,examples/smoothed_fix.py:SmoothedFix --seeds 0:3
    navsim fmu build paper-2012 --what estimator --estimator examples/smoothed_fix.py:SmoothedFix -o est.fmu

The interface is two methods (no base class): ``reset(context, prior)`` and
``step(measurement) -> NavSolution`` (:mod:`navsim.types`).
"""

from __future__ import annotations

import math

import numpy as np

from navsim.earth import mat_en
from navsim.receiver import least_squares_fix, velocity_fix
from navsim.types import Context, Measurement, NavSolution


class SmoothedFix:
    """GNSS-only alpha filter on least-squares fixes (an example of a user's estimator).

    Parameters
    ----------
    gain : float in (0, 1]
        Weight of a new fix against the prediction.
    accel_psd : float
        White-acceleration PSD, m^2/s^3, that grows the covariance while extrapolating.
    """

    def __init__(self, gain: float = 0.5, accel_psd: float = 0.05) -> None:
        if not 0.0 < gain <= 1.0:
            raise ValueError(f"gain: expected a value in (0, 1], got {gain!r}")
        self.gain = float(gain)
        self.accel_psd = float(accel_psd)

    def reset(self, context: Context, prior: NavSolution) -> None:
        self.earth = context.earth
        self.sigma = context.gnss.pseudorange_sigma_m
        self.sigma_v = context.gnss.doppler_sigma_mps
        self.vvar0 = self.sigma_v**2
        self.t0 = prior.t
        self.r_e = self.earth.geodetic_to_ecef(prior.lat, prior.lon, prior.h)
        self.v_e = mat_en(prior.lat, prior.lon).T @ np.asarray(prior.velocity_n, dtype=float)
        self.var0 = float(np.max(np.diag(prior.covariance)[:3])) if prior.covariance is not None else self.sigma**2

    def step(self, m: Measurement) -> NavSolution:
        tau = m.t - self.t0
        predicted = self.r_e + self.v_e * tau
        g = m.gnss
        if g is not None and np.count_nonzero(g.valid) >= 4:
            fix = least_squares_fix(g.sat_pos_e, g.pseudorange_m, g.valid, self.earth, initial=predicted)
            vfix = velocity_fix(g.sat_pos_e, g.sat_vel_e, g.pseudorange_rate_mps, g.valid, fix.position_e)
            if bool(fix.ok) and bool(vfix.ok):
                self.r_e = predicted + self.gain * (fix.position_e - predicted)
                self.v_e = np.asarray(vfix.velocity_e, dtype=float)
                self.t0, tau = m.t, 0.0
                dop2 = float(np.trace(fix.covariance[:3, :3])) / 3.0
                self.var0 = self.sigma**2 * dop2 * self.gain / (2.0 - self.gain)
                self.vvar0 = self.sigma_v**2 * float(np.trace(vfix.covariance[:3, :3])) / 3.0
                predicted = self.r_e
        lat, lon, h = (float(x) for x in self.earth.ecef_to_geodetic(predicted))
        v_n = mat_en(lat, lon) @ self.v_e  # mat_en: ECEF -> ENU
        cov = np.full((9, 9), np.nan)
        cov[:6, :6] = 0.0
        var = self.var0 + self.accel_psd * tau**3 / 3.0
        cov[0, 0] = cov[1, 1] = cov[2, 2] = var
        cov[3, 3] = cov[4, 4] = cov[5, 5] = self.vvar0 + self.accel_psd * tau
        return NavSolution(m.t, lat, lon, h, v_n, math.nan, math.nan, math.nan, covariance=cov)
