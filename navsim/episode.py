"""Running an estimator over a simulated episode.

:func:`run_episode` owns the loop every face uses (CLI, benchmarks, later the Gymnasium
env and the FMU): it builds the estimator's :class:`~navsim.estimators.base.Context`
from the scenario (the map and the *nominal* sensor specification, never the error
draws), resets the estimator with the simulator's prior, feeds it one
:class:`~navsim.estimators.base.Measurement` per navigation step and records the
estimates beside the truth. Truth flows only into the returned record, which metrics
consume.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from .scenario import Scenario
from .sensors import imu as imu_mod
from .simulator import Chunk, Simulator
from .types import (
    Context,
    Estimate,
    GnssObservation,
    Measurement,
    MeasurementBatch,
    NominalGnss,
    NominalImu,
    NominalOdometer,
    Prior,
)

__all__ = ["make_context", "measurements", "EpisodeRecord", "run_episode"]

C_LIGHT = 299_792_458.0


def make_context(sim: Simulator) -> Context:
    """The estimator's context: map, Earth, time base and the nominal sensor spec."""
    nominal = imu_mod.nominal_noise(sim.imu_model)

    def rms(x) -> float:
        return float(np.sqrt(np.mean(np.square(x))))

    imu = NominalImu(
        gyro_arw=rms(nominal["gyro_arw"]), accel_vrw=rms(nominal["accel_vrw"]),
        gyro_bias_sigma=float(np.hypot(rms(nominal["gyro_bias_sigma"]), rms(nominal["gyro_bias_instability_sigma"]))),
        accel_bias_sigma=float(np.hypot(rms(nominal["accel_bias_sigma"]), rms(nominal["accel_bias_instability_sigma"]))),
        gyro_bias_tau_s=float(np.min(nominal["gyro_bias_correlation_time_s"])),
        accel_bias_tau_s=float(np.min(nominal["accel_bias_correlation_time_s"])),
        gyro_rrw=rms(nominal["gyro_rate_random_walk"]), accel_rrw=rms(nominal["accel_rate_random_walk"]),
    )
    g = sim.gnss_model
    clock = bool(g.clock_enabled)
    iono, tropo = g.ionosphere_zenith_m > 0.0, g.troposphere_zenith_m > 0.0
    atmosphere = bool(iono or tropo)
    gnss = NominalGnss(
        pseudorange_sigma_m=float(np.hypot(g.pseudorange_sigma_m, g.multipath_sigma_m)),
        doppler_sigma_mps=float(g.doppler_sigma_mps),
        clock_modelled=clock,
        clock_bias_sigma_m=max(abs(g.clock_bias_m), 100.0) if clock else 0.0,
        clock_drift_sigma_mps=max(abs(g.clock_drift_mps), 1.0) if clock else 0.0,
        clock_phase_psd=C_LIGHT**2 * g.clock_h0 / 2.0 if clock else 0.0,
        clock_freq_psd=2.0 * math.pi**2 * C_LIGHT**2 * g.clock_h_2 if clock else 0.0,
        # Atmosphere: the designer knows the receiver is single-frequency and uncorrected
        # (the delays are on), not the delays. A-priori values a receiver applies from
        # standard models: ionosphere, the constant (night-time) term of the GPS broadcast
        # (Klobuchar) model, 5 ns = 1.50 m (navsim broadcasts no coefficients); sigma
        # 4.5 m, DO-229D J.2.3 tau_vert at mid-latitudes (the bundled scenarios lie at
        # 44-47 deg). Troposphere, DO-229D A.4.2.4 at sea level and 45 deg, annual mean
        # (P 1015.75 hPa, T 283.15 K, e 11.66 hPa): 2.313 m dry + 0.135 m wet = 2.448 m;
        # sigma 0.12 m, DO-229D sigma_TVE. Thin shell at 350 km (Klobuchar), exponential
        # height law with the 8 km scale height of the standard atmosphere.
        atmosphere_modelled=atmosphere,
        ionosphere_zenith_m=5e-9 * C_LIGHT if iono else 0.0,
        ionosphere_zenith_sigma_m=4.5 if iono else 0.0,
        troposphere_zenith_m=2.448 if tropo else 0.0,
        troposphere_zenith_sigma_m=0.12 if tropo else 0.0,
        lever_arm_b_m=tuple(float(x) for x in sim.scenario.gnss.lever_arm_m),  # surveyed at installation
    )
    odometer = None
    model = getattr(sim, "odometer_model", None)
    if model is not None:  # the datasheet of the odometer (never its drawn errors)
        odometer = NominalOdometer(
            pulse_length_m=model.pulse_length_m, scale_factor_sigma=model.scale_factor_sigma,
            scale_factor_gm_sigma=model.scale_factor_gm_sigma, scale_factor_tau_s=model.scale_factor_gm_tau_s,
            noise_density_m_per_sqrt_s=model.noise_density_m_per_sqrt_s,
            slip_fraction=max(model.slip_fraction, model.slide_fraction),
            slip_accel_threshold_mps2=model.slip_accel_threshold_mps2 if model.has_slip else float("inf"),
        )
    timing = sim.timing
    return Context(
        track=sim.track, earth=sim.earth, nav_period_s=timing.nav_period_s, imu_period_s=timing.imu_period_s,
        gnss_period_s=timing.gnss_period_s, samples_per_step=timing.samples_per_step,
        orders=sim.scenario.imu.orders, imu=imu, gnss=gnss,
        scenario_name=sim.scenario.name, config_hash=sim.scenario.config_hash(), odometer=odometer,
    )


def _epochs(chunk: Chunk, prn: np.ndarray) -> dict[int, GnssObservation]:
    epochs = {}
    if chunk.gnss is not None:
        g = chunk.gnss
        for j, local in enumerate(chunk.gnss_step):
            epochs[int(local)] = GnssObservation(
                t=float(g.t[j]), prn=prn, sat_pos_e=g.sat_pos_e[j], sat_vel_e=g.sat_vel_e[j],
                pseudorange_m=g.pseudorange_m[j], pseudorange_rate_mps=g.pseudorange_rate_mps[j], valid=g.valid[j],
            )
    return epochs


def measurement_batch(chunk: Chunk, prn: np.ndarray, dt: float) -> MeasurementBatch:
    """The whole chunk as one :class:`MeasurementBatch`."""
    imu = chunk.imu
    return MeasurementBatch(
        step=chunk.step0 + np.arange(len(chunk)), t=chunk.t, dt=dt, dtheta_r=imu.dtheta_r, dv_r=imu.dv_r,
        dtheta_sub=imu.dtheta_sample[:, :, 0], dv_sub=imu.dv_sample[:, :, 0],
        gnss=tuple(sorted(_epochs(chunk, prn).items())),
        odometer_ds_m=None if chunk.odometer is None else chunk.odometer.ds_m,
    )


def measurements(chunk: Chunk, prn: np.ndarray, dt: float) -> Iterator[Measurement]:
    """The per-step measurements of a chunk (GNSS attached at epoch steps)."""
    epochs = _epochs(chunk, prn)
    imu = chunk.imu
    odometer = None if chunk.odometer is None else chunk.odometer.ds_m.tolist()
    for i in range(len(chunk)):
        yield Measurement(
            step=chunk.step0 + i, t=float(chunk.t[i]), dt=dt, dtheta_r=imu.dtheta_r[i], dv_r=imu.dv_r[i],
            dtheta_sub=imu.dtheta_sample[i, :, 0], dv_sub=imu.dv_sample[i, :, 0], gnss=epochs.get(i),
            odometer_ds_m=None if odometer is None else odometer[i],
        )


@dataclass(frozen=True)
class EpisodeRecord:
    """Truth, estimates and GNSS availability of one episode (arrays over steps).

    truth_* and est_* : (n,) or (n, 3) at the step ends; est_cov : (n, 9, 9) or None;
    nis, nis_dof : (n,) with nan / 0 where no update happened; step_time_s : (n,) CPU
    seconds spent in ``estimator.step``; gnss_t, gnss_n_valid, gnss_receiver_outage :
    per epoch.
    """

    scenario: Scenario
    seed: int | None
    estimator: str
    earth: object
    t: np.ndarray
    truth_s: np.ndarray
    truth_lat: np.ndarray
    truth_lon: np.ndarray
    truth_h: np.ndarray
    truth_velocity_n: np.ndarray
    truth_hpr: np.ndarray
    est_lat: np.ndarray
    est_lon: np.ndarray
    est_h: np.ndarray
    est_velocity_n: np.ndarray
    est_hpr: np.ndarray
    est_cov: np.ndarray | None
    nis: np.ndarray
    nis_dof: np.ndarray
    step_time_s: np.ndarray
    gnss_t: np.ndarray
    gnss_n_valid: np.ndarray
    gnss_receiver_outage: np.ndarray
    prior: Prior


def run_episode(scenario: Scenario, estimator, seed: int | None = 0, *, name: str = "",
                chunk_steps: int = 10_000, progress=None, simulator: Simulator | None = None,
                use_batch: bool = True) -> EpisodeRecord:
    """Simulate one episode of ``scenario`` and run ``estimator`` on it.

    ``progress`` is an optional callable ``progress(n_steps_done)`` (e.g. a tqdm bar's
    ``update``). ``simulator`` lets callers reuse a built simulator of the same scenario.
    ``use_batch``: use the estimator's ``step_batch`` fast path when it has one (the
    per-step CPU time is then the chunk's time divided by its steps).
    """
    sim = simulator or Simulator(scenario)
    start = sim.reset(seed)
    estimator.reset(make_context(sim), start.prior)
    n = scenario.timing.steps
    est = np.full((n, 9), np.nan)
    cov = None
    nis = np.full(n, np.nan)
    nis_dof = np.zeros(n, dtype=int)
    cpu = np.zeros(n)
    truth = {k: [] for k in ("s", "lat", "lon", "h", "velocity_n", "hpr")}
    gnss_t, n_valid, rx_out = [], [], []
    prn = np.asarray(sim.constellation.prn)
    dt = scenario.timing.nav_period_s
    clock = time.process_time
    batch_path = getattr(estimator, "step_batch", None) if use_batch else None
    for chunk in sim.chunks(chunk_steps):
        if batch_path is not None:
            t0 = clock()
            out = batch_path(measurement_batch(chunk, prn, dt))
            k = slice(chunk.step0, chunk.step0 + len(chunk))
            cpu[k] = (clock() - t0) / len(chunk)
            est[k] = out.solution
            if out.covariance is not None:
                if cov is None:
                    cov = np.full((n, 9, 9), np.nan)
                cov[k] = out.covariance
            nis[k], nis_dof[k] = out.nis, out.nis_dof
        for meas in (measurements(chunk, prn, dt) if batch_path is None else ()):
            t0 = clock()
            e: Estimate = estimator.step(meas)
            cpu[meas.step] = clock() - t0
            k = meas.step
            est[k] = (e.lat, e.lon, e.h, *e.velocity_n, e.heading, e.pitch, e.roll)
            if e.covariance is not None:
                if cov is None:
                    cov = np.full((n, 9, 9), np.nan)
                cov[k] = e.covariance
            if e.nis is not None:
                nis[k], nis_dof[k] = e.nis, e.nis_dof or 0
        tr = chunk.truth
        for key in ("s", "lat", "lon", "h", "velocity_n"):
            truth[key].append(getattr(tr, key))
        truth["hpr"].append(np.column_stack([tr.heading, tr.pitch, tr.roll]))
        if chunk.gnss is not None:
            gnss_t.append(chunk.gnss.t)
            n_valid.append(chunk.gnss.valid.sum(axis=1))
            rx_out.append(chunk.receiver_outage)
        if progress is not None:
            progress(len(chunk))
    cat = {k: np.concatenate(v) for k, v in truth.items()}
    return EpisodeRecord(
        scenario=scenario, seed=seed, estimator=name or type(estimator).__name__, earth=sim.earth,
        t=(np.arange(n) + 1) * dt, truth_s=cat["s"], truth_lat=cat["lat"], truth_lon=cat["lon"], truth_h=cat["h"],
        truth_velocity_n=cat["velocity_n"], truth_hpr=cat["hpr"],
        est_lat=est[:, 0], est_lon=est[:, 1], est_h=est[:, 2], est_velocity_n=est[:, 3:6], est_hpr=est[:, 6:9],
        est_cov=cov, nis=nis, nis_dof=nis_dof, step_time_s=cpu,
        gnss_t=np.concatenate(gnss_t) if gnss_t else np.zeros(0),
        gnss_n_valid=np.concatenate(n_valid) if n_valid else np.zeros(0, dtype=int),
        gnss_receiver_outage=np.concatenate(rx_out) if rx_out else np.zeros(0, dtype=bool),
        prior=start.prior,
    )
