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
from typing import TYPE_CHECKING

import numpy as np

from navsim.episode import EpisodeRecorder
from navsim.naverror import local_level_factors

if TYPE_CHECKING:  # type hints only
    from navsim.earth import EarthModel
    from navsim.signals import ObservationCodec
    from navsim.simulator import Chunk, ChunkBatch

__all__ = ["PreparedChunk", "prepare_chunk", "chunk_truth_table", "held_flags", "EpisodeTape", "TRUTH_COLUMNS"]

EpisodeTape = EpisodeRecorder
"""The one episode recorder (:class:`navsim.episode.EpisodeRecorder`), by its env name."""

TRUTH_COLUMNS = ("lat", "lon", "h", "vE", "vN", "vU", "heading", "pitch", "roll", "k_north", "re_h", "cos_lat", "s")
"""Columns of :attr:`PreparedChunk.truth`: the action layout, then the factors
``R_N + h``, ``R_E + h`` and ``cos(lat)`` of the navigation error
(:func:`navsim.naverror.local_level_factors`), then the arc length s."""


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
    truth : ndarray (n, 13)
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
    chunk: Chunk | ChunkBatch


def chunk_truth_table(chunk: Chunk | ChunkBatch, earth: EarthModel) -> tuple[np.ndarray, np.ndarray]:
    """The truth rows (n, 13) in :data:`TRUTH_COLUMNS` order and, per step, the
    chunk-local index of the GNSS epoch at its end (-1: none), of a Chunk or ChunkBatch."""
    n = len(chunk)
    tr = chunk.truth
    truth = np.empty((n, len(TRUTH_COLUMNS)))
    truth[:, 0], truth[:, 1], truth[:, 2] = tr.lat, tr.lon, tr.h
    truth[:, 3:6] = tr.velocity_n
    truth[:, 6], truth[:, 7], truth[:, 8] = tr.heading, tr.pitch, tr.roll
    truth[:, 9], truth[:, 10], truth[:, 11] = local_level_factors(tr.lat, tr.h, earth)
    truth[:, 12] = tr.s
    epoch_at = np.full(n, -1, dtype=np.int64)
    if chunk.gnss is not None and len(chunk.gnss_step):
        epoch_at[chunk.gnss_step] = np.arange(len(chunk.gnss_step))
    return truth, epoch_at


def held_flags(epoch_at: np.ndarray, outage_epoch: np.ndarray, n_valid_epoch: np.ndarray, held_outage: bool | np.ndarray,
               held_n_valid: int | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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


def prepare_chunk(chunk: Chunk | ChunkBatch, earth: EarthModel, codec: ObservationCodec, held_outage: bool, held_n_valid: int,
                  rows: bool = True) -> PreparedChunk:
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
