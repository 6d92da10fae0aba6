"""Translation of simulator chunks into per-step observations, truth rows and flags.

One pass per chunk (vectorised over its steps) prepares everything the per-step code
needs, so :meth:`NavigationEnv.step` only indexes: observation arrays (read-only, one
row per step), truth rows as Python floats for the reward, the held GNSS flags, and the
chunk-local epoch index of every step. The vector env stacks the same arrays across
its sub-environments. No physics here: every number comes from the
:class:`~navsim.simulator.Chunk`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PreparedChunk", "prepare_chunk", "chunk_truth_table", "held_flags", "EpisodeTape", "TRUTH_COLUMNS"]

TRUTH_COLUMNS = ("lat", "lon", "h", "vE", "vN", "vU", "heading", "pitch", "roll", "k_north", "k_east", "s")
"""Columns of :attr:`PreparedChunk.truth`: the action layout, then the metres-per-radian
factors ``k_north = R_N + h`` and ``k_east = (R_E + h) cos(lat)`` of the reward, then
the arc length s."""


@dataclass(slots=True)
class PreparedChunk:
    """A chunk ready to be served step by step.

    Attributes
    ----------
    n : int
        Steps in the chunk. step0 : int, index of its first step in the episode.
    obs : dict of read-only (n, size) arrays
        The observation rows of :meth:`navsim.signals.ObservationCodec.encode_chunk`:
        row i of every key is the observation of step ``step0 + i``.
    epoch_at : list[int]
        For each step, the chunk-local index of the GNSS epoch at its end, or -1.
    truth : ndarray (n, 12)
        Truth rows in :data:`TRUTH_COLUMNS` order; ``truth_rows`` the same as lists.
    receiver_outage, n_valid : list
        Per step, the receiver-outage flag and the count of valid channels of the latest
        epoch at or before the step (held between epochs; carried across chunks).
    chunk : the simulator's Chunk.
    """

    n: int
    step0: int
    obs: dict
    epoch_at: list
    truth: np.ndarray
    truth_rows: list
    receiver_outage: list
    n_valid: list
    last_outage: bool
    last_n_valid: int
    chunk: object


def chunk_truth_table(chunk, earth) -> tuple[np.ndarray, np.ndarray]:
    """The truth rows (n, 12) in :data:`TRUTH_COLUMNS` order and, per step, the
    chunk-local index of the GNSS epoch at its end (-1: none), of a Chunk or ChunkBatch."""
    n = len(chunk)
    tr = chunk.truth
    r_n, r_e = earth.radii(tr.lat)
    truth = np.empty((n, len(TRUTH_COLUMNS)))
    truth[:, 0], truth[:, 1], truth[:, 2] = tr.lat, tr.lon, tr.h
    truth[:, 3:6] = tr.velocity_n
    truth[:, 6], truth[:, 7], truth[:, 8] = tr.heading, tr.pitch, tr.roll
    truth[:, 9] = r_n + tr.h
    truth[:, 10] = (r_e + tr.h) * np.cos(tr.lat)
    truth[:, 11] = tr.s
    epoch_at = np.full(n, -1, dtype=np.int64)
    if chunk.gnss is not None and len(chunk.gnss_step):
        epoch_at[chunk.gnss_step] = np.arange(len(chunk.gnss_step))
    return truth, epoch_at


def held_flags(epoch_at: np.ndarray, outage_epoch, n_valid_epoch, held_outage, held_n_valid):
    """Per step, the receiver-outage flag and valid-channel count of the latest epoch at
    or before the step, the held values (from the previous chunk) before the first one.

    ``outage_epoch``, ``n_valid_epoch``: (..., k) per epoch; ``held_*``: scalars or (...,).
    Returns two (..., n) arrays.
    """
    latest = np.maximum.accumulate(np.where(epoch_at >= 0, epoch_at, -1))
    have = latest >= 0
    at = np.maximum(latest, 0)
    outage_epoch, n_valid_epoch = np.asarray(outage_epoch), np.asarray(n_valid_epoch)
    if outage_epoch.shape[-1] == 0:  # no epoch in this chunk
        shape = (*outage_epoch.shape[:-1], len(epoch_at))
        return (np.broadcast_to(np.asarray(held_outage, dtype=bool)[..., None], shape).copy(),
                np.broadcast_to(np.asarray(held_n_valid)[..., None], shape).copy())
    outage = np.where(have, outage_epoch[..., at], np.asarray(held_outage)[..., None])
    n_valid = np.where(have, n_valid_epoch[..., at], np.asarray(held_n_valid)[..., None])
    return outage.astype(bool), n_valid.astype(np.int64)


def prepare_chunk(chunk, earth, codec, held_outage: bool, held_n_valid: int, rows: bool = True) -> PreparedChunk:
    """Prepare a :class:`~navsim.simulator.Chunk` (see :class:`PreparedChunk`).

    ``codec``: the env's :class:`navsim.signals.ObservationCodec`. ``held_outage``,
    ``held_n_valid``: the flags of the last epoch of the previous chunk (False, 0 at the
    episode start). ``rows``: also build the truth as Python lists (the single env's
    reward reads them).
    """
    n = len(chunk)
    truth, epoch_at = chunk_truth_table(chunk, earth)
    g = chunk.gnss
    if g is not None and len(chunk.gnss_step):
        outage, n_valid = held_flags(epoch_at, chunk.receiver_outage, g.valid.sum(axis=1), held_outage, held_n_valid)
        last_outage, last_n_valid = bool(outage[-1]), int(n_valid[-1])
    else:
        outage = np.full(n, held_outage)
        n_valid = np.full(n, held_n_valid)
        last_outage, last_n_valid = held_outage, held_n_valid
    return PreparedChunk(
        n=n, step0=chunk.step0, obs=codec.encode_chunk(chunk), epoch_at=epoch_at.tolist(), truth=truth,
        truth_rows=truth.tolist() if rows else [], receiver_outage=outage.astype(bool).tolist(),
        n_valid=n_valid.astype(int).tolist(), last_outage=last_outage, last_n_valid=last_n_valid, chunk=chunk,
    )


class EpisodeTape:
    """Truth, GNSS availability and the agent's actions of one episode, for scoring.

    Truth is written per chunk into arrays preallocated for the whole episode (or, with
    ``truth_of``, shared with another tape of a lockstep episode, which writes it); actions
    arrive one per step as lists (appending a list is cheaper than a NumPy row write)
    and become one (n, 9) array at the end. ``covariance``, ``nis``: optional per-step
    extras an :class:`~navsim.envs.agent.EstimateAction` carries.
    """

    def __init__(self, n_steps: int, truth_of: EpisodeTape | None = None):
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
                raise ValueError("EpisodeTape: truth_of has another episode length")
            self.s, self.lat, self.lon, self.h = truth_of.s, truth_of.lat, truth_of.lon, truth_of.h
            self.velocity_n, self.hpr = truth_of.velocity_n, truth_of.hpr
        self.actions: list = []
        self.cov: dict[int, np.ndarray] = {}
        self.nis: dict[int, tuple[float, int]] = {}
        self.cpu: dict[int, float] = {}
        self.cov_array: np.ndarray | None = None
        self.nis_array: np.ndarray | None = None
        self.nis_dof_array: np.ndarray | None = None
        self.gnss_t: list = []
        self.gnss_n_valid: list = []
        self.gnss_outage: list = []

    def add_chunk(self, prepared) -> None:
        """Copy the truth and GNSS availability of a chunk (a PreparedChunk or a
        simulator Chunk) into the tape."""
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

    def add_estimates(self, step0: int, out) -> None:
        """Record an :class:`~navsim.estimators.base.EstimateBatch` of steps from ``step0``
        (solutions in physical units, covariance, NIS)."""
        n = len(out.solution)
        self.actions.extend(out.solution.tolist())
        if out.covariance is not None:
            if self.cov_array is None:
                self.cov_array = np.full((self.n, 9, 9), np.nan)
            self.cov_array[step0:step0 + n] = out.covariance
        if self.nis_array is None:
            self.nis_array = np.full(self.n, np.nan)
            self.nis_dof_array = np.zeros(self.n, dtype=int)
        self.nis_array[step0:step0 + n] = out.nis
        self.nis_dof_array[step0:step0 + n] = out.nis_dof

    def estimates(self, scale=None) -> np.ndarray:
        """(n, 9) solutions so far (actions times ``scale``), nan-padded to the episode length."""
        est = np.full((self.n, 9), np.nan)
        if self.actions:
            est[: len(self.actions)] = np.asarray(self.actions, dtype=float)
        return est if scale is None else est * scale

    def record(self, scenario, seed, name: str, earth, prior, scale=None):
        """The :class:`~navsim.episode.EpisodeRecord` of the episode (as ``run_episode``)."""
        from navsim.episode import EpisodeRecord

        n = self.n
        est = self.estimates(scale)
        cov = self.cov_array
        if self.cov:
            cov = np.full((n, 9, 9), np.nan)
            for k, c in self.cov.items():
                cov[k] = c
        nis = np.full(n, np.nan)
        nis_dof = np.zeros(n, dtype=int)
        if self.nis_array is not None:
            nis, nis_dof = self.nis_array, self.nis_dof_array
        for k, (value, dof) in self.nis.items():
            nis[k], nis_dof[k] = value, dof
        cpu = np.full(n, np.nan)
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
