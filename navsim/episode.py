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

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Iterator, cast

import numpy as np

from .earth import earth_model
from .estimators.base import Estimator
from .scenario import Scenario
from .sensors import imu as imu_mod
from .sensors.models import build_gnss_error_model, build_imu_model
from .signals import MEASUREMENT_SIGNALS, OPTIONAL_SENSORS
from .simulator import Chunk, Simulator, build_track
from .types import (
    Context,
    Estimate,
    EstimateBatch,
    GnssObservation,
    Measurement,
    MeasurementBatch,
    Prior,
)
from .validation import check_episode_memory

if TYPE_CHECKING:  # type hints only
    from .earth import EarthModel

__all__ = ["make_context", "measurements", "measurement_batch", "step_batch", "EpisodeRecord", "EpisodeRecorder",
           "run_episode"]


def make_context(source: Scenario | Simulator) -> Context:
    """The estimator's context: map, Earth, time base and the nominal sensor specification.

    ``source`` is a :class:`~navsim.scenario.Scenario` (no simulator is built: the track
    and each sensor's error model are built from the scenario and asked for their
    nominal specification, :func:`navsim.sensors.imu.nominal_imu`,
    :meth:`navsim.sensors.gnss.GnssErrorModel.nominal`, and for each enabled optional
    sensor of :data:`navsim.signals.OPTIONAL_SENSORS` its declared ``nominal``) or a
    built :class:`~navsim.simulator.Simulator` (its track and models are reused). Both
    give the same context for the same scenario.
    """
    if isinstance(source, Scenario):
        scenario = source
        track = build_track(scenario)
        earth = earth_model(scenario.earth)
        imu_model = build_imu_model(scenario)
        gnss_model = build_gnss_error_model(scenario)
        models = {s.name: s.model(scenario) for s in OPTIONAL_SENSORS}
    else:
        scenario, track, earth = source.scenario, source.track, source.earth
        imu_model, gnss_model = source.imu_model, source.gnss_model
        models = {s.name: getattr(source, f"{s.name}_model", None) for s in OPTIONAL_SENSORS}
    timing = scenario.timing
    nominal = {s.name: None if models[s.name] is None else s.nominal(models[s.name], track, scenario)
               for s in OPTIONAL_SENSORS}
    return Context(
        track=track, earth=earth, nav_period_s=timing.nav_period_s, imu_period_s=timing.imu_period_s,
        gnss_period_s=timing.gnss_period_s, samples_per_step=timing.samples_per_step,
        orders=scenario.imu.orders, imu=imu_mod.nominal_imu(imu_model),
        gnss=gnss_model.nominal(scenario.gnss.lever_arm_m),  # the lever arm as surveyed at installation
        scenario_name=scenario.name, config_hash=scenario.config_hash(), **nominal,
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
        **{s.measurement: s.read(chunk) for s in MEASUREMENT_SIGNALS},  # the optional sensors' (signal table)
    )


def step_batch(estimator: Estimator, batch: MeasurementBatch) -> EstimateBatch:
    """The estimator over a batch: its ``step_batch`` fast path when it has one, else
    ``step`` on each measurement in turn (the same numbers, see
    :mod:`navsim.estimators.base`)."""
    fast = getattr(estimator, "step_batch", None)
    if callable(fast):
        return fast(batch)
    rows, covs, nis, dof = [], [], [], []
    for i in range(len(batch)):
        e = estimator.step(batch.measurement(i))
        rows.append(e.as_action())
        covs.append(e.covariance)
        nis.append(np.nan if e.nis is None else e.nis)
        dof.append(e.nis_dof or 0)
    cov = None if any(c is None for c in covs) else np.stack(cast("list[np.ndarray]", covs))
    return EstimateBatch(np.array(rows), cov, np.array(nis, dtype=float), np.array(dof, dtype=int))


def measurements(chunk: Chunk, prn: np.ndarray, dt: float) -> Iterator[Measurement]:
    """The per-step measurements of a chunk (GNSS attached at epoch steps)."""
    epochs = _epochs(chunk, prn)
    imu = chunk.imu
    extras = [(s.measurement, values.tolist()) for s in MEASUREMENT_SIGNALS  # the optional sensors' fields
              if (values := s.read(chunk)) is not None]
    for i in range(len(chunk)):
        yield Measurement(
            step=chunk.step0 + i, t=float(chunk.t[i]), dt=dt, dtheta_r=imu.dtheta_r[i], dv_r=imu.dv_r[i],
            dtheta_sub=imu.dtheta_sample[i, :, 0], dv_sub=imu.dv_sample[i, :, 0], gnss=epochs.get(i),
            **{field: values[i] for field, values in extras},
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
    earth: EarthModel
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


class EpisodeRecorder:
    """Truth, GNSS availability and estimates of one episode: the one recorder of every face.

    :func:`run_episode`, the navigation env, the vector env and the FMU master fill one
    and call :meth:`record` for the :class:`EpisodeRecord` that metrics score.

    Truth is written per chunk (:meth:`add_chunk`) into arrays preallocated for the
    whole episode (or, with ``truth_of``, shared with another recorder of a lockstep
    episode, which writes it). Estimates arrive in step order as rows of :attr:`actions`
    (appending a list is cheaper than a NumPy row write): as batches
    (:meth:`add_estimates`), one :class:`~navsim.types.NavSolution` per step
    (:meth:`add_estimate`), or rows an env appends itself, with optional per-step extras
    in the dicts :attr:`cov`, :attr:`nis` and :attr:`cpu`; :meth:`record` merges them.
    """

    def __init__(self, n_steps: int, truth_of: EpisodeRecorder | None = None) -> None:
        check_episode_memory(n_steps)  # before any allocation (ConfigError with the estimate)
        self.n = n_steps
        self.owns_truth = truth_of is None
        if truth_of is None:
            self.s = np.empty(n_steps)
            self.lat = np.empty(n_steps)
            self.lon = np.empty(n_steps)
            self.h = np.empty(n_steps)
            self.velocity_n = np.empty((n_steps, 3))
            self.hpr = np.empty((n_steps, 3))
        else:  # the same truth (lockstep episodes of one scenario): share its arrays
            if truth_of.n != n_steps:
                raise ValueError("EpisodeRecorder: truth_of has another episode length")
            self.s, self.lat, self.lon, self.h = truth_of.s, truth_of.lat, truth_of.lon, truth_of.h
            self.velocity_n, self.hpr = truth_of.velocity_n, truth_of.hpr
        self.actions: list = []
        self.cov: dict[int, np.ndarray] = {}
        self.nis: dict[int, tuple[float, int]] = {}
        self.cpu: dict[int, float] = {}
        self.cov_array: np.ndarray | None = None
        self.nis_array: np.ndarray | None = None
        self.nis_dof_array: np.ndarray | None = None
        self.cpu_array: np.ndarray | None = None
        self.gnss_t: list = []
        self.gnss_n_valid: list = []
        self.gnss_outage: list = []

    def add_chunk(self, prepared: Any) -> None:
        """Copy the truth and GNSS availability of a chunk (a simulator Chunk, or an
        object with the chunk as ``.chunk``) into the recorder."""
        chunk = getattr(prepared, "chunk", prepared)
        k = slice(chunk.step0, chunk.step0 + len(chunk))
        tr = chunk.truth
        if self.owns_truth:
            self.s[k], self.lat[k], self.lon[k], self.h[k] = tr.s, tr.lat, tr.lon, tr.h
            self.velocity_n[k] = tr.velocity_n
            self.hpr[k, 0], self.hpr[k, 1], self.hpr[k, 2] = tr.heading, tr.pitch, tr.roll
        g = chunk.gnss
        if g is not None:
            self.gnss_t.append(g.t)
            self.gnss_n_valid.append(g.valid.sum(axis=1))
            self.gnss_outage.append(chunk.receiver_outage)

    def add_truth(self, k: int, s: float, lat: float, lon: float, h: float, velocity_n: Any, hpr: Any) -> None:
        """The truth of step ``k`` from per-step values (a face that sees no chunk, e.g. the
        FMU master reading the plant's outputs): arc length, lat, lon, h, ENU velocity (3,),
        heading/pitch/roll (3,)."""
        self.s[k], self.lat[k], self.lon[k], self.h[k] = s, lat, lon, h
        self.velocity_n[k] = velocity_n
        self.hpr[k] = hpr

    def add_epochs(self, t: Any, n_valid: Any, receiver_outage: Any) -> None:
        """GNSS availability of epochs, in time order: times (s), valid channels, receiver outage."""
        self.gnss_t.append(np.asarray(t, dtype=float))
        self.gnss_n_valid.append(np.asarray(n_valid, dtype=int))
        self.gnss_outage.append(np.asarray(receiver_outage, dtype=bool))

    def _nis_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        nis, dof = self.nis_array, self.nis_dof_array
        if nis is None or dof is None:  # made together, on the first NIS recorded
            nis = self.nis_array = np.full(self.n, np.nan)
            dof = self.nis_dof_array = np.zeros(self.n, dtype=int)
        return nis, dof

    def _cov_array(self) -> np.ndarray:
        if self.cov_array is None:
            self.cov_array = np.full((self.n, 9, 9), np.nan)
        return self.cov_array

    def add_estimates(self, step0: int, out: EstimateBatch, cpu_s: float | None = None) -> None:
        """Record an :class:`~navsim.types.EstimateBatch` of the steps from ``step0`` on
        (the next steps: solutions in physical units, covariance, NIS; ``cpu_s``: CPU
        seconds per step)."""
        n = len(out.solution)
        k = slice(step0, step0 + n)
        self.actions.extend(out.solution.tolist())
        if out.covariance is not None:
            self._cov_array()[k] = out.covariance
        nis, dof = self._nis_arrays()
        nis[k] = out.nis
        dof[k] = out.nis_dof
        if cpu_s is not None:
            self._cpu_array()[k] = cpu_s

    def _cpu_array(self) -> np.ndarray:
        if self.cpu_array is None:
            self.cpu_array = np.full(self.n, np.nan)
        return self.cpu_array

    def add_estimate(self, k: int, e: Estimate, cpu_s: float | None = None) -> None:
        """Record the solution of step ``k``, the next step (covariance copied: the
        estimator may reuse its arrays)."""
        v = e.velocity_n
        self.actions.append([e.lat, e.lon, e.h, v[0], v[1], v[2], e.heading, e.pitch, e.roll])
        if e.covariance is not None:
            self._cov_array()[k] = e.covariance
        if e.nis is not None:
            nis, dof = self._nis_arrays()
            nis[k], dof[k] = e.nis, e.nis_dof or 0
        if cpu_s is not None:
            self._cpu_array()[k] = cpu_s

    def estimates(self, scale: np.ndarray | None = None) -> np.ndarray:
        """(n, 9) solutions so far (action rows times ``scale``), nan-padded to the episode length."""
        est = np.full((self.n, 9), np.nan)
        if self.actions:
            est[: len(self.actions)] = np.asarray(self.actions, dtype=float)
        return est if scale is None else est * scale

    def record(self, scenario: Scenario, seed: int | None, name: str, earth: Any, prior: Prior,
               scale: np.ndarray | None = None) -> EpisodeRecord:
        """The :class:`EpisodeRecord` of the episode (``scale``: of the action rows)."""
        n = self.n
        est = self.estimates(scale)
        cov = self.cov_array
        if self.cov:
            cov = self._cov_array()
            for k, c in self.cov.items():
                cov[k] = c
        nis = np.full(n, np.nan)
        nis_dof = np.zeros(n, dtype=int)
        if self.nis_array is not None:
            nis, nis_dof = self._nis_arrays()
        for k, (value, dof) in self.nis.items():
            nis[k], nis_dof[k] = value, dof
        cpu = np.full(n, np.nan) if self.cpu_array is None else self.cpu_array
        if self.cpu:
            cpu[list(self.cpu)] = list(self.cpu.values())
        dt = scenario.timing.nav_period_s
        cat = np.concatenate
        return EpisodeRecord(
            scenario=scenario, seed=seed, estimator=name, earth=earth, t=(np.arange(n) + 1) * dt,
            truth_s=self.s, truth_lat=self.lat, truth_lon=self.lon, truth_h=self.h,
            truth_velocity_n=self.velocity_n, truth_hpr=self.hpr,
            est_lat=est[:, 0], est_lon=est[:, 1], est_h=est[:, 2], est_velocity_n=est[:, 3:6], est_hpr=est[:, 6:9],
            est_cov=cov, nis=nis, nis_dof=nis_dof, step_time_s=cpu,
            gnss_t=cat(self.gnss_t) if self.gnss_t else np.zeros(0),
            gnss_n_valid=cat(self.gnss_n_valid) if self.gnss_n_valid else np.zeros(0, dtype=int),
            gnss_receiver_outage=cat(self.gnss_outage) if self.gnss_outage else np.zeros(0, dtype=bool),
            prior=prior,
        )


def run_episode(scenario: Scenario, estimator: Estimator, seed: int | None = 0, *, name: str = "",
                chunk_steps: int = 10_000, progress: Callable[[int], Any] | None = None,
                simulator: Simulator | None = None, use_batch: bool = True) -> EpisodeRecord:
    """Simulate one episode of ``scenario`` and run ``estimator`` on it.

    ``progress`` is an optional callable ``progress(n_steps_done)`` (e.g. a tqdm bar's
    ``update``). ``simulator`` lets callers reuse a built simulator of the same scenario.
    ``use_batch``: use the estimator's ``step_batch`` fast path when it has one (the
    per-step CPU time is then the chunk's time divided by its steps).
    """
    sim = simulator or Simulator(scenario)
    start = sim.reset(seed)
    estimator.reset(make_context(sim), start.prior)
    recorder = EpisodeRecorder(scenario.timing.steps)
    prn = np.asarray(sim.constellation.prn)
    dt = scenario.timing.nav_period_s
    clock = time.process_time
    batch_path = getattr(estimator, "step_batch", None) if use_batch else None
    for chunk in sim.chunks(chunk_steps):
        if batch_path is not None:
            t0 = clock()
            out = batch_path(measurement_batch(chunk, prn, dt))
            recorder.add_estimates(chunk.step0, out, (clock() - t0) / len(chunk))
        for meas in (measurements(chunk, prn, dt) if batch_path is None else ()):
            t0 = clock()
            e = estimator.step(meas)
            recorder.add_estimate(meas.step, e, clock() - t0)
        recorder.add_chunk(chunk)
        if progress is not None:
            progress(len(chunk))
    return recorder.record(scenario, seed, name or type(estimator).__name__, sim.earth, start.prior)
