"""The simulator: the one owner of evolving world state and random streams.

:class:`Simulator` turns a :class:`~navsim.scenario.Scenario` into truth and
measurements, step by step or in vectorised chunks, with the same numbers either way.

Time base
    Integer ticks; the navigation step is the unit of :meth:`Simulator.advance`. A step
    k covers ``[k, k+1) * nav_period_s`` and holds ``m = samples_per_step`` IMU samples.
    GNSS epochs fall at the *end* of every ``steps_per_epoch``-th step.
Random streams
    ``reset(seed)`` makes ``SeedSequence(seed)`` and spawns, in this fixed order, the
    streams ``motion, imu, gnss, outages, initial_error, odometer, baro`` (:data:`STREAMS`;
    ``odometer`` and then ``baro`` were appended last: a spawned child keeps its index, so the
    earlier streams are the same numbers as before they existed). Each sensor
    draws a fixed-width block per sample or epoch, so the numbers do not depend on the
    chunk size, and switching one source off changes no other stream.
IMU truth
    For each sample the true ``omega_ib_b`` and ``specific_force_b`` are evaluated at
    Gauss-Legendre nodes and combined into the increments of multiple integrals of seed
    000 eq. (1.14) (:func:`navsim.sensors.imu.multiple_integral_rule`), then the
    truth-side error model is applied in the increment domain.

Examples
--------
>>> from navsim.scenario import load_scenario
>>> sim = Simulator(load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 2.0}}))
>>> start = sim.reset(seed=0)
>>> chunk = sim.advance(100)
>>> chunk.imu.dtheta_r.shape
(100, 4, 3)
"""

from __future__ import annotations

import dataclasses
import math
import sys
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Iterator, Sequence

import numpy as np
from numpy.typing import ArrayLike

from .earth import earth_model, mat_en
from .errors import ConfigError
from .motion import (
    ConstantSpeed,
    ExternalMotion,
    Oscillation,
    Station,
    Timetable,
    TrueState,
    true_state,
)
from .scenario import Scenario
from .sensors import baro as baro_mod
from .sensors import gnss as gnss_mod
from .sensors import imu as imu_mod
from .sensors import odometer as odometer_mod
from .sensors import outages as outage_mod
from .sensors.models import build_gnss_error_model, build_imu_model
from .threads import limited
from .truthgen import TruthGenerator
from .types import Prior  # the initial estimate handed to estimators: truth plus a drawn error
from .validation import check_seed, check_steps, validate_scenario

if TYPE_CHECKING:  # type hints only
    from concurrent.futures import Future, ThreadPoolExecutor

    from .earth import EarthModel
    from .scenario import TimingConfig
    from .track import Track

__all__ = ["STREAMS", "Simulator", "SimulatorBatch", "ImuBlock", "Chunk", "ChunkBatch", "Prior", "Start", "build_track",
           "build_profile", "build_imu_model", "build_gnss", "build_gnss_error_model"]

STREAMS = ("motion", "imu", "gnss", "outages", "initial_error", "odometer", "baro")
"""Names of the child random streams, in spawn order (never reorder: it changes numbers)."""

IMU_GROUP = 32
"""Most members per call of the batched IMU error model in :class:`SimulatorBatch`."""

IMU_TILE = 8192
"""About this many member-samples per call of the batched IMU error model (cache size)."""

OUTPUT_POOL = 2
"""Sets of chunk output buffers a :class:`SimulatorBatch` keeps for reuse."""


# ============================================================================ outputs
@dataclass(frozen=True, slots=True)
class ImuBlock:
    """IMU output of n navigation steps of m samples each (with sensor errors).

    Attributes
    ----------
    dtheta_r, dv_r : (n, R, 3)
        Increments of r-fold integrals of angular rate (rad s^(r-1)) and specific force
        (m/s * s^(r-1)) over each navigation step, seed 000 eq. (1.14); ``[:, 0]`` are
        the ordinary increments dTheta, dV.
    dtheta_sample, dv_sample : (n, m, R, 3)
        The same over each IMU sample inside the step.
    rate_b, accel_b : (n, m, 3)
        Rate outputs (rad/s, m/s^2) at the end of each sample.
    """

    dtheta_r: np.ndarray
    dv_r: np.ndarray
    dtheta_sample: np.ndarray
    dv_sample: np.ndarray
    rate_b: np.ndarray
    accel_b: np.ndarray

    @property
    def dtheta_sub(self) -> np.ndarray:
        """First-order per-sample increments (n, m, 3): the traditional algorithms' input."""
        return self.dtheta_sample[:, :, 0, :]

    @property
    def dv_sub(self) -> np.ndarray:
        return self.dv_sample[:, :, 0, :]


@dataclass(frozen=True, slots=True)
class _ChunkFields:
    """The fields :class:`Chunk` and :class:`ChunkBatch` share (one source for both)."""

    step0: int
    t: np.ndarray
    truth: TrueState
    imu: ImuBlock
    gnss: gnss_mod.GnssEpochs | None
    gnss_step: np.ndarray
    receiver_outage: np.ndarray
    odometer: odometer_mod.OdometerOutput | None = None
    baro: baro_mod.BaroOutput | None = None

    def __len__(self) -> int:
        return len(self.t)


@dataclass(frozen=True, slots=True)
class Chunk(_ChunkFields):
    """Truth and measurements of ``n`` consecutive navigation steps.

    Attributes
    ----------
    step0 : int
        Index of the first step. ``t`` (n,) are the step *end* times, s.
    truth : TrueState
        The true state at the step end times.
    imu : ImuBlock
        IMU output over each step.
    gnss : GnssEpochs or None
        The GNSS epochs that fall in this chunk (None when GNSS is disabled);
        ``gnss_step`` (k,) gives, for each epoch, the index of its step in the chunk.
    receiver_outage : (k,) bool
        True where the whole receiver was in an outage at that epoch.
    odometer : OdometerOutput or None
        The wheel odometer over each step (``ds_m``, ``pulses``: (n,)), None when the
        scenario has no odometer (:mod:`navsim.sensors.odometer`).
    baro : BaroOutput or None
        The barometric altimeter's reading at each step end (``altitude_m``,
        ``pressure_pa``, ``bias_pa``: (n,)), None without one (:mod:`navsim.sensors.baro`).
    """


@dataclass(frozen=True, slots=True)
class ChunkBatch(_ChunkFields):
    """The chunks of B lockstep episodes of one scenario (:class:`SimulatorBatch`).

    Attributes
    ----------
    step0, t, gnss_step : as :class:`Chunk` (shared).
    truth : TrueState
        The true state, shared by all members (one motion).
    imu : ImuBlock
        Arrays with a leading member axis, e.g. ``dtheta_r`` (B, n, R, 3).
    gnss : GnssEpochs or None
        Arrays with a leading member axis (B, k, ...); the geometry (``t``,
        ``sat_pos_e``, ``sat_vel_e``, ``elevation``, ``azimuth``) as broadcast views.
    receiver_outage : (B, k) bool
    odometer : OdometerOutput or None
        Arrays (B, n); None without an odometer.
    baro : BaroOutput or None
        Arrays (B, n); None without a barometer.
    """

    @property
    def size(self) -> int:
        """Number of members B."""
        return self.imu.dtheta_r.shape[0]

    def member(self, j: int) -> Chunk:
        """The :class:`Chunk` of member j (views, no copy)."""
        imu = ImuBlock(*(getattr(self.imu, f)[j] for f in ImuBlock.__slots__))
        gnss = None if self.gnss is None else type(self.gnss)(
            **{f: getattr(self.gnss, f)[j] for f in type(self.gnss).__slots__})
        odometer = None if self.odometer is None else type(self.odometer)(
            **{f: getattr(self.odometer, f)[j] for f in type(self.odometer).__slots__})
        baro = None if self.baro is None else baro_mod.BaroOutput(
            *(getattr(self.baro, f)[j] for f in baro_mod.BaroOutput.__slots__))
        return Chunk(step0=self.step0, t=self.t, truth=self.truth, imu=imu, gnss=gnss, gnss_step=self.gnss_step,
                     receiver_outage=self.receiver_outage[j], odometer=odometer, baro=baro)


@dataclass(frozen=True, slots=True)
class Start:
    """What :meth:`Simulator.reset` returns: the truth at t0 and the estimator's prior."""

    truth: TrueState
    prior: Prior


# ============================================================================ builders
def build_track(scenario: Scenario) -> Track:
    """The scenario's track object (bundled or from a file), on the scenario's Earth."""
    from . import track as track_mod
    from . import trackio

    cfg = scenario.track
    earth = earth_model(scenario.earth)
    if cfg.bundled:
        track = trackio.load_bundled_track(cfg.bundled, earth=earth)
    else:
        track = trackio.load_track_file(scenario.resolve_path(cfg.file), earth=earth, smoothing_m=cfg.smoothing_m)
    if cfg.cant != "track":
        track = track.with_cant_model(track_mod.CantModel(
            mode=cfg.cant, design_speed_mps=cfg.cant_design_speed_mps, max_cant=math.radians(cfg.cant_max_deg)))
    return track


def build_profile(scenario: Scenario) -> ConstantSpeed | Timetable | ExternalMotion:
    """The scenario's speed profile (a fresh :class:`ExternalMotion` for "external")."""
    m = scenario.motion
    if m.profile == "constant":
        return ConstantSpeed(speed=m.speed_mps, s0=m.start_s_m, amplitude=m.speed_amplitude_mps,
                             period=m.speed_period_s)
    if m.profile == "timetable":
        return Timetable(
            stations=tuple(Station(s=st.s_m, dwell=st.dwell_s) for st in m.stations),
            cruise_speed=m.cruise_speed_mps, max_accel=m.max_accel_mps2,
            max_decel=m.max_decel_mps2, jerk_time=m.jerk_time_s,
        )
    return ExternalMotion(0.0, m.start_s_m, m.speed_mps, 0.0)


def _oscillations(scenario: Scenario) -> tuple[Oscillation, ...]:
    return tuple(
        Oscillation(o.angle, o.amplitude_rad(), o.frequency_hz, math.radians(o.phase_deg))
        for o in scenario.motion.oscillations
    )


def build_gnss(scenario: Scenario, earth: EarthModel) -> tuple[gnss_mod.Constellation, gnss_mod.GnssErrorModel]:
    """Constellation and truth-side GNSS error model of the scenario."""
    cfg = scenario.gnss
    if cfg.constellation.startswith("yuma:"):
        constellation = gnss_mod.load_yuma(scenario.resolve_path(cfg.constellation[5:], "almanac"))
    elif cfg.constellation in ("gps", "glonass"):
        constellation = gnss_mod.walker_constellation(cfg.constellation, phase_rad=math.radians(cfg.epoch_phase_deg))
    else:
        raise ConfigError("gnss.constellation", "'gps', 'glonass' or 'yuma:<file>'", cfg.constellation)
    return constellation, build_gnss_error_model(scenario)


# ============================================================================ simulator
class Simulator:
    """Step-wise and chunked generation of truth and measurements for one scenario.

    Parameters
    ----------
    scenario : Scenario
        The configuration; everything heavy (track, constellation) is built once here.
    """

    def __init__(self, scenario: Scenario):
        validate_scenario(scenario)  # the one validation pass, before any work
        self.scenario = scenario
        self.timing = scenario.timing
        self.earth = earth_model(scenario.earth)
        self.track = build_track(scenario)
        self.profile = build_profile(scenario)
        self.oscillations = _oscillations(scenario)
        self.imu_model = build_imu_model(scenario)
        self._imu_error_free = imu_mod.is_error_free(self.imu_model)
        self.constellation, self.gnss_model = build_gnss(scenario, self.earth)
        self.outage_model = scenario.outages
        self.odometer_model = scenario.odometer.model() if scenario.odometer.enabled else None
        self.baro_model = scenario.baro.model() if scenario.baro.enabled else None
        self.truthgen = TruthGenerator(
            self.track, self.profile, self.oscillations, self.timing.imu_period_s, scenario.imu.orders,
            scenario.imu.quadrature_nodes, t_end=self.timing.duration_s)
        self._check_motion_fits_track()
        self._step: int | None = None
        self._no_epochs: gnss_mod.GnssEpochs | None = None  # the empty GnssEpochs of an epoch-less chunk (built once)

    # -- validation ----------------------------------------------------------------
    def _check_motion_fits_track(self) -> None:
        if isinstance(self.profile, ExternalMotion):
            return
        t = np.linspace(0.0, self.timing.duration_s, 2001)
        s = self.profile.evaluate(t)[0]
        bad = np.flatnonzero((s < 0) | (s > self.track.length))
        if bad.size:
            raise ConfigError(
                "motion", f"arc length within the track [0, {self.track.length:.1f}] m for the whole episode",
                f"s = {s[bad[0]]:.1f} m at t = {t[bad[0]]:.1f} s",
            )

    # -- state -----------------------------------------------------------------------
    _imu_state: imu_mod.ImuState | None = None
    _imu_row: tuple[imu_mod.BatchImuState, int] | None = None  # set by a batch: row j of its state

    @property
    def imu_state(self) -> imu_mod.ImuState:
        """The IMU error state after the steps generated so far (:class:`navsim.sensors.imu.ImuState`)."""
        if self._imu_state is None:
            if self._imu_row is None:
                raise RuntimeError("call Simulator.reset(seed) before stepping")
            batch_state, j = self._imu_row
            self._imu_state = batch_state.member(j)
        return self._imu_state

    @imu_state.setter
    def imu_state(self, state: imu_mod.ImuState) -> None:
        self._imu_state, self._imu_row = state, None

    @property
    def step_index(self) -> int:
        """Number of navigation steps generated since the last reset."""
        return self._require_reset()

    @property
    def t(self) -> float:
        """Current time, s (exactly step_index * nav_period)."""
        return self.step_index * self.timing.nav_period_s

    @property
    def done(self) -> bool:
        return self.step_index >= self.timing.steps

    def _require_reset(self) -> int:
        """The step index; RuntimeError before the first reset."""
        if self._step is None:
            raise RuntimeError("call Simulator.reset(seed) before stepping")
        return self._step

    def reset(self, seed: int | None = None) -> Start:
        """Start a new episode: fresh random streams, initial sensor states, the prior."""
        seq = np.random.SeedSequence(check_seed(seed))
        self.seed_entropy = seq.entropy
        self.rngs = dict(zip(STREAMS, (np.random.Generator(np.random.PCG64(s)) for s in seq.spawn(len(STREAMS)))))
        self._step = 0
        self._served = 0
        self._buffer: Chunk | None = None
        self._buffer_pos = 0
        if isinstance(self.profile, ExternalMotion):
            m = self.scenario.motion
            self.profile.reset(0.0, m.start_s_m, m.speed_mps, 0.0)
        self.truthgen._cache.clear()
        self.imu_state = imu_mod.ImuState.initial(self.imu_model, self.rngs["imu"])
        self.gnss_state = gnss_mod.GnssState.initial(self.gnss_model, self.constellation, self.rngs["gnss"])
        self.outage_state = outage_mod.OutageState.initial(self.outage_model, len(self.constellation.prn), self.rngs["outages"])
        truth0 = self.truth_at(np.array([0.0]))
        if self.odometer_model is not None:
            self.odometer_state = odometer_mod.OdometerState.initial(self.odometer_model, self.rngs["odometer"])
            self._odometer_s = float(truth0.s[0])  # arc length at the end of the last step
        if self.baro_model is not None:
            self.baro_state = baro_mod.BaroState.initial(self.baro_model, self.rngs["baro"])
        return Start(truth=truth0, prior=self._draw_prior(truth0))

    def _draw_prior(self, truth0: TrueState) -> Prior:
        init = self.scenario.initial
        sig_att = math.radians(init.attitude_deg)
        e = self.rngs["initial_error"].standard_normal(9)
        pos_err_n = init.position_m * e[:3]
        r_n, r_e = self.earth.radii(truth0.lat[0])
        lat = truth0.lat[0] + pos_err_n[1] / (r_n + truth0.h[0])
        lon = truth0.lon[0] + pos_err_n[0] / ((r_e + truth0.h[0]) * math.cos(truth0.lat[0]))
        return Prior(
            t=0.0, lat=float(lat), lon=float(lon), h=float(truth0.h[0] + pos_err_n[2]),
            velocity_n=truth0.velocity_n[0] + init.velocity_mps * e[3:6],
            heading=float(truth0.heading[0] + sig_att * e[8]),
            pitch=float(truth0.pitch[0] + sig_att * e[6]),
            roll=float(truth0.roll[0] + sig_att * e[7]),
            covariance=init.covariance(),
        )

    def truth_at(self, t: ArrayLike) -> TrueState:
        """The true state at arbitrary times (s) within the episode."""
        return true_state(self.track, self.profile, np.asarray(t, dtype=float), self.oscillations)

    # -- external motion ---------------------------------------------------------------
    def push_motion(self, s: float, speed: float, accel: float, t: float | None = None) -> None:
        """Give the external motion state (profile "external").

        By default the state is at the end of the next step; ``t`` (s) places it at any
        later time instead (e.g. an FMU communication point several steps ahead).
        """
        if not isinstance(self.profile, ExternalMotion):
            raise ConfigError("motion.profile", "'external' to push motion samples", self.scenario.motion.profile)
        self._require_reset()
        if not 0.0 <= s <= self.track.length:
            raise ConfigError("motion.external.s", f"an arc length in [0, {self.track.length:.1f}] m", s)
        if t is None:
            t = (self.step_index + 1) * self.timing.nav_period_s
        self.profile.push(t, s, speed, accel)

    # -- generation --------------------------------------------------------------------
    def advance(self, n_steps: int = 1) -> Chunk:
        """Generate the next ``n_steps`` navigation steps (fewer at the episode's end)."""
        if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)) or n_steps < 1:
            raise ConfigError("n_steps", "a positive whole number of navigation steps", n_steps)
        return _generate([self], n_steps).member(0)

    def step(self, buffer_steps: int = 1000) -> tuple[Chunk, int]:
        """Serve the next single step as ``(chunk, i)``: step ``i`` of a buffered chunk.

        For scripted motion the simulator generates ``buffer_steps`` ahead in one
        vectorised pass and serves them one by one (the numbers are those of any other
        chunking); with external motion each call generates exactly one step after the
        caller's :meth:`push_motion`. :attr:`served` counts the steps handed out.
        Do not mix with :meth:`advance` within an episode.
        """
        self._require_reset()
        if isinstance(self.profile, ExternalMotion):
            chunk = self.advance(1)
            self._served += 1
            return chunk, 0
        if self._buffer is None or self._buffer_pos >= len(self._buffer):
            if self._served >= self.timing.steps:
                raise RuntimeError("the episode is over: call reset()")
            self._buffer = self.advance(check_steps(buffer_steps, self.scenario, "buffer_steps"))
            self._buffer_pos = 0
        i = self._buffer_pos
        self._buffer_pos += 1
        self._served += 1
        return self._buffer, i

    @property
    def served(self) -> int:
        """Steps handed out by :meth:`step` since the last reset."""
        self._require_reset()
        return self._served

    def chunks(self, chunk_steps: int = 10_000) -> Iterator[Chunk]:
        """Iterate over the rest of the episode in chunks of ``chunk_steps`` steps."""
        chunk_steps = check_steps(chunk_steps, self.scenario, "chunk_steps")
        self._require_reset()
        while self.step_index < self.timing.steps:
            yield self.advance(chunk_steps)

    def run(self, seed: int | None = None, chunk_steps: int = 10_000) -> tuple[Start, list[Chunk]]:
        """Reset and generate a whole episode; returns the start and the list of chunks."""
        start = self.reset(seed)
        return start, list(self.chunks(chunk_steps))


def _unreferenced_count() -> int:
    """``sys.getrefcount`` of an array held by a list only, read as :func:`_output_buffers` reads it."""
    bufs = [np.empty(0)]
    return sys.getrefcount(bufs[0])


_UNREFERENCED = _unreferenced_count()


def _output_buffers(pool: list[list[np.ndarray]] | None, shapes: tuple[tuple[int, ...], ...]) -> list[np.ndarray]:
    """Arrays of ``shapes`` for a chunk's IMU output: a set of ``pool`` that nothing else
    references any more (no view of it is alive: every view and every chunk, observation
    or record made from one holds a reference to its arrays), else new arrays (and the
    pool, at most :data:`OUTPUT_POOL` sets, keeps them). Reusing written pages saves the
    page faults of fresh memory (the kernel zeroes every new page on first touch)."""
    if pool is None:
        return [np.empty(shape) for shape in shapes]
    for i, bufs in enumerate(pool):
        # free: as many references as right after its allocation (the pool's list only;
        # measured the same way, whatever the interpreter counts for the call itself)
        if all(bufs[k].shape == shapes[k] and sys.getrefcount(bufs[k]) <= _UNREFERENCED
               for k in range(len(shapes))):
            pool.append(pool.pop(i))  # most recently used last
            return bufs
    bufs = [np.empty(shape) for shape in shapes]
    pool.append(bufs)
    if len(pool) > OUTPUT_POOL:
        pool.pop(0)  # the least recently used set (still referenced elsewhere, or of another shape)
    return bufs


def _imu_errors(sims: list[Simulator], t_start: np.ndarray, h: float, dtheta_true: np.ndarray, dv_true: np.ndarray,
                omega_end: np.ndarray, force_end: np.ndarray, executor: ThreadPoolExecutor | None,
                pool: list[list[np.ndarray]] | None = None) -> imu_mod.ImuOutput | _Pending:
    """The IMU errors of every member, in cache-sized tiles of members x samples.

    Members are taken in groups of at most :data:`IMU_GROUP` and the samples in blocks
    of about :data:`IMU_TILE` member-samples per call; the error model is chunk-invariant
    (one draw block per call, the recursive state carried), so the tiling changes no
    number. With an executor the groups run on threads (NumPy's generators and ufunc
    loops release the GIL, and so do the compiled draws and white-noise pass): each group
    is a task of the executor's queue, taken by the first free worker (the members of a
    group have their own streams and states, so the order changes no number), and the
    result is a :class:`_Pending`, so that the caller's thread generates the other
    sensors meanwhile. ``pool``: output
    buffers to reuse (:func:`_output_buffers`).
    """
    members, ns = len(sims), len(t_start)
    model = sims[0].imu_model
    group = min(members, IMU_GROUP)
    span = max(64, IMU_TILE // group)
    shapes = ((members, *dtheta_true.shape), (members, *dv_true.shape), (members, ns, 3), (members, ns, 3))
    out = imu_mod.ImuOutput(*_output_buffers(pool, shapes))

    def run(g0: int) -> None:
        part = sims[g0:g0 + group]
        rngs = [sim.rngs["imu"] for sim in part]
        state = _group_state(part)
        for s0 in range(0, ns, span):
            s = slice(s0, s0 + span)
            rows = slice(g0, g0 + len(part))
            dest = imu_mod.ImuOutput(out.dtheta_r[rows, s], out.dv_r[rows, s], out.rate_b[rows, s],
                                     out.accel_b[rows, s])  # views: written in place
            _, state = imu_mod.apply_imu_errors_batch_state(
                t_start[s], h, dtheta_true[s], dv_true[s], omega_end[s], force_end[s], model, state, rngs,
                out=dest)
        for j, sim in enumerate(part):  # row j of the group's state, made an ImuState when read
            sim._imu_state, sim._imu_row = None, (state, j)

    starts = range(0, members, group)
    if executor is not None and len(starts) > 1:
        # one task per group, taken by whichever worker is free (a worker delayed by
        # other work on its core does not hold up the chunk; the groups are independent)
        return _Pending(out, [executor.submit(run, g0) for g0 in starts])
    for g0 in starts:
        run(g0)
    return out


def _group_state(part: list[Simulator]) -> imu_mod.BatchImuState:
    """The IMU states of a group of members as one batch state: the batch state they are
    the rows of, in order, when they still are (the previous chunk's group), else stacked."""
    row = part[0]._imu_row
    if row is not None and row[0].size == len(part):
        state = row[0]
        if all(sim._imu_row is not None and sim._imu_row[0] is state and sim._imu_row[1] == j
               for j, sim in enumerate(part)):
            return state
    return imu_mod.BatchImuState.of([sim.imu_state for sim in part])  # checks the lockstep


class _Pending:
    """IMU outputs being computed on worker threads; :meth:`result` waits for them."""

    def __init__(self, out: imu_mod.ImuOutput, futures: list[Future[None]]) -> None:
        self.out, self.futures = out, futures

    def result(self) -> imu_mod.ImuOutput:
        for future in self.futures:
            future.result()
        return self.out


def _other_sensors(sims: list[Simulator], lead: Simulator, truth: TrueState, steps: np.ndarray, t_end_steps: np.ndarray,
                   timing: TimingConfig, dt: float, members: int
                   ) -> tuple[np.ndarray, gnss_mod.GnssEpochs | None, np.ndarray, odometer_mod.OdometerOutput | None,
                              baro_mod.BaroOutput | None]:
    """GNSS epochs and outages, odometer and barometer of a chunk (each member's own
    streams and states; no IMU state is read or written)."""
    # --- GNSS epochs at the end of every steps_per_epoch-th step
    epoch_steps = np.flatnonzero((steps + 1) % timing.steps_per_epoch == 0)
    gnss_epochs, receiver_outage = None, np.zeros((members, len(epoch_steps)), dtype=bool)
    if lead.scenario.gnss.enabled and not len(epoch_steps):
        # no epoch in these steps: nothing is drawn or advanced, reuse the empty epochs
        no = lead._no_epochs
        if no is None:
            no, _ = gnss_mod.simulate_epochs(
                t_end_steps[:0], truth.position_e[:0], truth.velocity_e[:0], lead.constellation,
                lead.gnss_model, lead.gnss_state, np.random.default_rng(0), lead.earth)
            for sim in sims:
                sim._no_epochs = no
        gnss_epochs = type(no)(**{f: np.broadcast_to(getattr(no, f), (members, *getattr(no, f).shape))
                                  for f in type(no).__slots__})
    elif lead.scenario.gnss.enabled:
        idx = epoch_steps
        antenna_e, antenna_vel_e = truth.position_e[idx], truth.velocity_e[idx]
        if lead.scenario.gnss.has_lever_arm:  # measured at the antenna, not at the IMU
            mat_eb = np.swapaxes(mat_en(truth.lat[idx], truth.lon[idx]), -1, -2) @ truth.mat_nb[idx]
            antenna_e, antenna_vel_e = gnss_mod.antenna_state(
                antenna_e, antenna_vel_e, mat_eb, truth.omega_ib_b[idx],
                np.asarray(lead.scenario.gnss.lever_arm_m, dtype=float), lead.earth)
        geometry = gnss_mod.sky_geometry(t_end_steps[idx], antenna_e, lead.constellation, lead.earth)
        gnss_epochs, gnss_states = gnss_mod.simulate_epochs_batch(
            t_end_steps[idx], antenna_e, antenna_vel_e, lead.constellation,
            lead.gnss_model, [sim.gnss_state for sim in sims], [sim.rngs["gnss"] for sim in sims], lead.earth,
            geometry=geometry,
        )
        visible, receiver_outage, outage_states = outage_mod.visibility_batch(
            t_end_steps[idx], truth.s[idx], truth.heading[idx], gnss_epochs.elevation[0], gnss_epochs.azimuth[0],
            lead.track.segments, lead.outage_model, [sim.outage_state for sim in sims],
            [sim.rngs["outages"] for sim in sims], prn=lead.constellation.prn,
        )
        gnss_epochs = dataclasses.replace(gnss_epochs, valid=gnss_epochs.valid & visible)
        for sim, g_state, o_state in zip(sims, gnss_states, outage_states):
            sim.gnss_state, sim.outage_state = g_state, o_state
    # --- wheel odometer: true arc-length increments of the steps, errors per member
    odometer = None
    if lead.odometer_model is not None:
        ds_true = np.diff(truth.s, prepend=lead._odometer_s)
        odometer, odo_states = odometer_mod.simulate_odometer_batch(
            ds_true, truth.accel_along, lead.odometer_model, [sim.odometer_state for sim in sims],
            [sim.rngs["odometer"] for sim in sims], dt=dt)
        s_end = float(truth.s[-1])
        for sim, odo_state in zip(sims, odo_states):
            sim.odometer_state, sim._odometer_s = odo_state, s_end
    # --- barometric altimeter: the true height at the step ends, errors per member
    baro = None
    if lead.baro_model is not None:
        baro, baro_states = baro_mod.simulate_baro_batch(
            truth.h, lead.baro_model, [sim.baro_state for sim in sims], [sim.rngs["baro"] for sim in sims], dt=dt)
        for sim, b_state in zip(sims, baro_states):
            sim.baro_state = b_state
    return epoch_steps, gnss_epochs, receiver_outage, odometer, baro


@limited  # small products: single-threaded BLAS (navsim.threads)
def _generate(sims: list[Simulator], n_steps: int, executor: ThreadPoolExecutor | None = None,
              pool: list[list[np.ndarray]] | None = None) -> ChunkBatch:
    """Generate the next steps of simulators in lockstep on one scenario and truth.

    The truth, the satellite geometry and the deterministic outage masks are computed
    once; each simulator's sensor errors come from its own states and streams through the
    batched sensor functions, so simulator j gets exactly the numbers it would get alone.
    """
    lead = sims[0]
    at = [sim._require_reset() for sim in sims]
    k0 = at[0]
    if any(k != k0 for k in at):
        raise RuntimeError("simulators out of lockstep")
    timing = lead.timing
    n = min(int(n_steps), timing.steps - k0)
    if n <= 0:
        raise RuntimeError("the episode is over: call reset()")
    members = len(sims)
    m, h, dt = timing.samples_per_step, timing.imu_period_s, timing.nav_period_s
    steps = np.arange(k0, k0 + n)
    # sample start times from integer ticks (never a float accumulator)
    sample_index = k0 * m + np.arange(n * m)
    t_start = sample_index * h
    t_end_steps = (steps + 1) * dt
    # --- ideal IMU increments and truth at sample ends (block Chebyshev or direct), once
    ideal = lead.truthgen.samples(k0 * m, n * m)
    truth = ideal.truth if m == 1 else _every(ideal.truth, m)
    dtheta_true, dv_true = ideal.dtheta_r, ideal.dv_r
    omega_end, force_end = ideal.omega_end, ideal.force_end
    if lead._imu_error_free:
        def shared(a: np.ndarray) -> np.ndarray:
            return np.broadcast_to(a, (members, *a.shape))
        imu_out: imu_mod.ImuOutput | _Pending = imu_mod.ImuOutput(shared(dtheta_true), shared(dv_true),
                                                                  shared(omega_end), shared(force_end))
    else:  # with an executor, on its threads while this one generates the other sensors
        imu_out = _imu_errors(sims, t_start, h, dtheta_true, dv_true, omega_end, force_end, executor, pool)
    try:
        epoch_steps, gnss_epochs, receiver_outage, odometer, baro = _other_sensors(
            sims, lead, truth, steps, t_end_steps, timing, dt, members)
    finally:  # the IMU threads are done before anything is returned or raised
        out = imu_out.result() if isinstance(imu_out, _Pending) else imu_out
    R = dtheta_true.shape[1]
    dtheta_sample = out.dtheta_r.reshape(members, n, m, R, 3)
    dv_sample = out.dv_r.reshape(members, n, m, R, 3)
    if m == 1:
        dtheta_step, dv_step = dtheta_sample[:, :, 0], dv_sample[:, :, 0]
    else:
        dtheta_step = imu_mod.compose_multiple_integrals(dtheta_sample.reshape(members * n, m, R, 3), h)
        dv_step = imu_mod.compose_multiple_integrals(dv_sample.reshape(members * n, m, R, 3), h)
        dtheta_step = dtheta_step.reshape(members, n, R, 3)
        dv_step = dv_step.reshape(members, n, R, 3)
    imu = ImuBlock(
        dtheta_r=dtheta_step, dv_r=dv_step, dtheta_sample=dtheta_sample, dv_sample=dv_sample,
        rate_b=out.rate_b.reshape(members, n, m, 3), accel_b=out.accel_b.reshape(members, n, m, 3),
    )
    for sim in sims:
        sim._step = k0 + n  # every member was at k0 (lockstep)
    return ChunkBatch(step0=k0, t=t_end_steps, truth=truth, imu=imu, gnss=gnss_epochs,
                      gnss_step=epoch_steps, receiver_outage=receiver_outage, odometer=odometer, baro=baro)


class SimulatorBatch:
    """B episodes of one scenario in lockstep: one truth, B sets of sensor errors.

    Member j, reset with seed ``seeds[j]``, produces exactly the numbers of
    ``Simulator(scenario).reset(seeds[j])`` followed by the same ``advance`` calls: the
    members are :class:`Simulator` objects sharing the immutable parts (track, motion,
    constellation, truth generator) and each owning its random streams and sensor
    states. The truth, the satellite geometry and the deterministic outage masks are
    computed once per chunk and the sensor errors of all members in one vectorised pass
    (:func:`navsim.sensors.imu.apply_imu_errors_batch`,
    :func:`navsim.sensors.gnss.simulate_epochs_batch`,
    :func:`navsim.sensors.outages.visibility_batch`). The native vector environment
    stands on it.

    Parameters
    ----------
    scenario : Scenario
        Scripted motion only (external motion is pushed per episode).
    size : int
        Number of members B.
    threads : int
        Worker threads for the IMU error pass (default 1: none), each taking the next
        group of members while the calling thread generates the GNSS, outage, odometer
        and barometer data. Each member's numbers are the same whatever the number of threads.
    executor : optional
        Instead of the worker threads: an object with ``submit(fn, *args)`` (returning an
        object with ``result()``) and ``shutdown(wait=True)`` that runs the IMU groups
        (the native vector env's, whose waiting threads run the groups themselves).

    The chunks' IMU output arrays come from a pool of :data:`OUTPUT_POOL` sets, reused
    once nothing references a set any more (a kept chunk or observation keeps its set
    out of the pool's reach), and the members' IMU states are carried between chunks as
    one :class:`navsim.sensors.imu.BatchImuState` per group (a member's ``imu_state`` is
    made from its row when read).

    Examples
    --------
    >>> from navsim.scenario import load_scenario
    >>> from navsim.simulator import SimulatorBatch
    >>> batch = SimulatorBatch(load_scenario("paper-2012").with_overrides({"timing": {"duration_s": 2.0}}), 3)
    >>> starts = batch.reset([0, 1, 2])
    >>> batch.advance(100).imu.dtheta_r.shape
    (3, 100, 4, 3)
    """

    def __init__(self, scenario: Scenario, size: int, threads: int = 1, executor: Any = None):
        import copy

        if isinstance(size, bool) or int(size) != size or size < 1:
            raise ConfigError("size", "a positive integer", size)
        if isinstance(threads, bool) or int(threads) != threads or threads < 1:
            raise ConfigError("threads", "a positive integer", threads)
        self.threads = int(threads)
        self._executor = executor  # the caller's (it is shut down by close)
        if executor is None and self.threads > 1:
            from concurrent.futures import ThreadPoolExecutor

            self._executor = ThreadPoolExecutor(self.threads, thread_name_prefix="navsim-batch")
        base = Simulator(scenario)
        if isinstance(base.profile, ExternalMotion):
            raise ConfigError("motion.profile", "scripted motion for a simulator batch", "external")
        self.scenario = scenario
        self.members = [base] + [copy.copy(base) for _ in range(int(size) - 1)]
        self._pool: list = []  # the chunks' IMU output buffers, reused once unreferenced

    def __len__(self) -> int:
        return len(self.members)

    @property
    def timing(self) -> TimingConfig:
        return self.members[0].timing

    @property
    def step_index(self) -> int:
        return self.members[0].step_index

    @property
    def done(self) -> bool:
        return self.members[0].done

    def reset(self, seeds: Sequence[int | None]) -> list[Start]:
        """Reset every member; ``seeds`` is a sequence of B seeds (None: fresh entropy)."""
        seeds = list(seeds)
        if len(seeds) != len(self.members):
            raise ConfigError("seeds", f"{len(self.members)} seeds", len(seeds))
        return [sim.reset(seed) for sim, seed in zip(self.members, seeds)]

    def advance(self, n_steps: int = 1) -> ChunkBatch:
        """Generate the next ``n_steps`` steps of every member (fewer at the episode's end)."""
        return _generate(self.members, n_steps, self._executor, self._pool)

    def close(self) -> None:
        """Stop the worker threads (if any); idempotent."""
        if self._executor is not None:
            self._executor.shutdown(wait=True)
            self._executor = None


def _every(truth: TrueState, m: int) -> TrueState:
    """The states at every m-th sample end (the navigation step ends)."""
    return TrueState(**{f: getattr(truth, f)[m - 1::m] for f in TrueState.__dataclass_fields__})


def concat_chunks(chunks: list[Chunk]) -> dict[str, np.ndarray]:
    """Flatten chunks into one dict of arrays (the layout written by ``navsim simulate``)."""
    from .io import chunk_arrays

    parts = [chunk_arrays(c) for c in chunks]
    return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}

