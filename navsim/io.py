"""Writing episodes to disk: NPZ and CSV, streamed chunk by chunk in bounded memory.

File layout (``navsim simulate SCENARIO --seed N -o FILE``)
------------------------------------------------------------
NPZ (``FILE.npz``): one array per key of :func:`chunk_arrays`, plus ``scenario_toml``
(the resolved scenario as TOML text), ``seed`` and ``config_hash``.

Per navigation step (leading dimension = steps; times are step *ends*):

=====================  ===============  ==========================================
key                    shape            meaning, unit
=====================  ===============  ==========================================
t                      (n,)             time, s
s, speed, accel_along  (n,)             arc length m, speed m/s, along-track m/s^2
lat, lon, h            (n,)             geodetic position, rad, rad, m
velocity_n             (n, 3)           ENU velocity, m/s
heading, pitch, roll   (n,)             attitude, rad
omega_ib_b             (n, 3)           true body rate vs inertial space, rad/s
specific_force_b       (n, 3)           true specific force, m/s^2
position_e, velocity_e (n, 3)           ECEF position m, velocity m/s
dtheta_r, dv_r         (n, R, 3)        IMU multiple-integral increments over the step
dtheta_sample, dv_sample (n, m, R, 3)   the same per IMU sample
rate_b, accel_b        (n, m, 3)        IMU rate outputs at sample ends
odometer_ds_m          (n,)             wheel odometer distance over the step, m
odometer_pulses        (n,) int64       encoder pulses counted in the step
=====================  ===============  ==========================================

The two odometer keys are present only when the scenario has an odometer
(``[odometer] enabled = true``); files of scenarios without one are unchanged.

Per GNSS epoch (leading dimension = epochs; ``gnss_step`` is the global step index):
``gnss_t`` (k,), ``gnss_step`` (k,), ``gnss_sat_pos_e``/``gnss_sat_vel_e`` (k, m, 3),
``gnss_pseudorange_m``, ``gnss_pseudorange_rate_mps``, ``gnss_valid``,
``gnss_elevation``, ``gnss_azimuth`` (k, m), ``gnss_receiver_outage``,
``gnss_clock_bias_m``, ``gnss_clock_drift_mps`` (k,).

CSV: ``FILE.csv`` holds the per-step keys with vector components as separate columns
(``velocity_n_0`` ...; multiple integrals as ``dtheta_r<r>_<axis>``); ``FILE_gnss.csv``
holds one row per epoch and satellite channel (``t, step, prn, valid, pseudorange_m,
pseudorange_rate_mps, elevation, azimuth, sat_x, sat_y, sat_z, sat_vx, sat_vy, sat_vz``).
"""

from __future__ import annotations

import contextlib
import csv
import os
import stat
import tempfile
import zipfile
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, Iterable, Iterator

import numpy as np

if TYPE_CHECKING:  # type hints only
    from matplotlib.figure import Figure

    from .simulator import Chunk, ChunkBatch

__all__ = ["chunk_arrays", "write_npz", "write_csv", "atomic_output", "write_text_atomic", "save_figure",
           "check_output_dir", "STEP_KEYS", "GNSS_KEYS", "ODOMETER_KEYS"]

STEP_KEYS = (
    "t", "s", "speed", "accel_along", "lat", "lon", "h", "velocity_n", "heading", "pitch", "roll",
    "omega_ib_b", "specific_force_b", "position_e", "velocity_e",
    "dtheta_r", "dv_r", "dtheta_sample", "dv_sample", "rate_b", "accel_b",
)
ODOMETER_KEYS = ("odometer_ds_m", "odometer_pulses")
"""Per-step keys written after :data:`STEP_KEYS` when the chunk has an odometer."""
GNSS_KEYS = (
    "gnss_t", "gnss_step", "gnss_sat_pos_e", "gnss_sat_vel_e", "gnss_pseudorange_m",
    "gnss_pseudorange_rate_mps", "gnss_valid", "gnss_elevation", "gnss_azimuth",
    "gnss_receiver_outage", "gnss_clock_bias_m", "gnss_clock_drift_mps",
)


def chunk_arrays(chunk: Chunk | ChunkBatch, n_sats: int | None = None) -> dict[str, np.ndarray]:
    """The arrays of one :class:`~navsim.simulator.Chunk` under the keys documented above."""
    truth, imu = chunk.truth, chunk.imu
    out = {key: getattr(truth, key) for key in STEP_KEYS[:15]}
    out.update(
        dtheta_r=imu.dtheta_r, dv_r=imu.dv_r, dtheta_sample=imu.dtheta_sample,
        dv_sample=imu.dv_sample, rate_b=imu.rate_b, accel_b=imu.accel_b,
    )
    odometer = getattr(chunk, "odometer", None)
    if odometer is not None:
        out.update(odometer_ds_m=odometer.ds_m, odometer_pulses=odometer.pulses)
    g = chunk.gnss
    if g is None:
        m = n_sats or 0
        empty = lambda *shape, dtype=float: np.zeros((0, *shape), dtype=dtype)  # noqa: E731
        out.update(
            gnss_t=empty(), gnss_step=empty(dtype=np.int64), gnss_sat_pos_e=empty(m, 3),
            gnss_sat_vel_e=empty(m, 3), gnss_pseudorange_m=empty(m), gnss_pseudorange_rate_mps=empty(m),
            gnss_valid=empty(m, dtype=bool), gnss_elevation=empty(m), gnss_azimuth=empty(m),
            gnss_receiver_outage=empty(dtype=bool), gnss_clock_bias_m=empty(), gnss_clock_drift_mps=empty(),
        )
        return out
    out.update(
        gnss_t=g.t, gnss_step=chunk.step0 + chunk.gnss_step, gnss_sat_pos_e=g.sat_pos_e,
        gnss_sat_vel_e=g.sat_vel_e, gnss_pseudorange_m=g.pseudorange_m,
        gnss_pseudorange_rate_mps=g.pseudorange_rate_mps, gnss_valid=g.valid,
        gnss_elevation=g.elevation, gnss_azimuth=g.azimuth, gnss_receiver_outage=chunk.receiver_outage,
        gnss_clock_bias_m=g.clock_bias_m, gnss_clock_drift_mps=g.clock_drift_mps,
    )
    return out


def _umask() -> int:
    """The process's umask (read by setting and restoring it; there is no read-only call)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str], mode: str = "wb", **open_kw: Any) -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path`` for writing; on success it is flushed to disk
    and renamed onto ``path`` (``os.replace``, atomic on POSIX and Windows), on any
    failure (an exception, a full disk) it is removed. A reader, or a killed writer,
    therefore sees the previous file or the new one whole, never a half-written one
    (a kill can leave a ``.<name>.*.part`` file beside it, never the target).

    The file gets the permissions an ordinary ``open`` would give it: those of the file it
    replaces, or for a new file ``0o666`` less the process's umask (``mkstemp`` makes the
    temporary file ``0o600``)."""
    path = Path(path)
    try:
        perm = stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        perm = 0o666 & ~_umask()
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    try:
        with os.fdopen(fd, mode, **open_kw) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, perm)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def check_output_dir(folder: str | Path) -> Path:
    """Create ``folder`` if needed and prove it writable before any work is done: a small
    probe file is written, flushed to disk and removed (a read-only or full file system,
    or a file in the way, raises :class:`OSError` here rather than after the computing)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    fd, probe = tempfile.mkstemp(prefix=".navsim-probe-", dir=folder)
    try:
        os.write(fd, b"\0" * 4096)
        os.fsync(fd)
    finally:
        os.close(fd)
        os.unlink(probe)
    return folder


def save_figure(fig: Figure, path: str | Path, **savefig_kw: Any) -> Path:
    """Save a Matplotlib figure through :func:`atomic_output` (the format from the file's
    suffix, PNG when it has none); the folder is created if needed. A failed or killed
    save leaves the previous file whole."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fmt = path.suffix.lstrip(".").lower() or "png"
    with atomic_output(path, "wb") as fh:
        fig.savefig(fh, format=fmt, **savefig_kw)
    return path


def write_text_atomic(path: str | os.PathLike[str], text: str, encoding: str = "utf-8") -> Path:
    """Write a text file through :func:`atomic_output` (UTF-8 unless told)."""
    with atomic_output(path, "w", encoding=encoding, newline="") as fh:
        fh.write(text)
    return Path(path)


def write_npz(path: str | Path, chunks: Iterable, meta: dict | None = None, n_sats: int | None = None) -> Path:
    """Stream chunks into an NPZ file without holding the episode in memory.

    Each array is appended to a raw temporary file chunk by chunk; at the end every one
    is copied into the zip member behind a ``.npy`` header with the final shape. The zip
    is written beside ``path`` and renamed into place (:func:`atomic_output`).
    """
    path = Path(path)
    with tempfile.TemporaryDirectory(prefix="navsim-") as tmp:
        files: dict[str, IO[bytes]] = {}
        specs: dict[str, list[Any]] = {}  # key: [dtype, trailing shape, row count]
        try:
            for chunk in chunks:
                for key, arr in chunk_arrays(chunk, n_sats).items():
                    arr = np.ascontiguousarray(arr)
                    if key not in files:
                        files[key] = open(Path(tmp) / f"{key}.raw", "wb")
                        specs[key] = [arr.dtype, arr.shape[1:], 0]
                    files[key].write(arr.tobytes())
                    specs[key][2] += arr.shape[0]
        finally:
            for f in files.values():
                f.close()
        with atomic_output(path) as out, zipfile.ZipFile(out, "w", compression=zipfile.ZIP_STORED, allowZip64=True) as zf:
            for key, (dtype, tail, count) in specs.items():
                with zf.open(f"{key}.npy", "w", force_zip64=True) as member:
                    np.lib.format.write_array_header_1_0(
                        member, {"descr": np.lib.format.dtype_to_descr(dtype), "fortran_order": False,
                                 "shape": (count, *tail)})
                    with open(Path(tmp) / f"{key}.raw", "rb") as raw:
                        while block := raw.read(1 << 22):
                            member.write(block)
            for key, value in (meta or {}).items():
                with zf.open(f"{key}.npy", "w") as member:
                    np.lib.format.write_array(member, np.asarray(value))
    return path


def _columns(key: str, arr: np.ndarray) -> list[str]:
    if arr.ndim == 1:
        return [key]
    if arr.ndim == 2:
        return [f"{key}_{i}" for i in range(arr.shape[1])]
    if arr.ndim == 3:  # (n, R, 3)
        return [f"{key}{r + 1}_{i}" for r in range(arr.shape[1]) for i in range(arr.shape[2])]
    return [f"{key}{j}_{r + 1}_{i}" for j in range(arr.shape[1]) for r in range(arr.shape[2]) for i in range(arr.shape[3])]


def write_csv(path: str | Path, chunks: Iterable, n_sats: int | None = None) -> tuple[Path, Path]:
    """Stream chunks into ``path`` (per step) and ``<stem>_gnss.csv`` (per epoch and channel),
    each through :func:`atomic_output` (renamed into place when complete)."""
    path = Path(path)
    gnss_path = path.with_name(path.stem + "_gnss.csv")
    with atomic_output(path, "w", newline="") as fs, atomic_output(gnss_path, "w", newline="") as fg:
        steps, gnss = csv.writer(fs), csv.writer(fg)
        header_done = False
        gnss.writerow(["t", "step", "prn", "valid", "pseudorange_m", "pseudorange_rate_mps", "elevation",
                       "azimuth", "sat_x", "sat_y", "sat_z", "sat_vx", "sat_vy", "sat_vz"])
        for chunk in chunks:
            arrays = chunk_arrays(chunk, n_sats)
            step_arrays = [(k, arrays[k]) for k in STEP_KEYS + ODOMETER_KEYS if k in arrays]
            if not header_done:
                steps.writerow([c for k, a in step_arrays for c in _columns(k, a)])
                header_done = True
            table = np.concatenate([a.reshape(len(a), -1) for _, a in step_arrays], axis=1)
            steps.writerows(table.tolist())
            if chunk.gnss is not None and len(chunk.gnss.t):
                g = chunk.gnss
                k, m = g.pseudorange_m.shape
                prn = np.broadcast_to(np.asarray(chunk_prn(chunk, m)), (k, m))
                rows = np.column_stack([
                    np.repeat(g.t, m), np.repeat(chunk.step0 + chunk.gnss_step, m), prn.ravel(),
                    g.valid.ravel().astype(int), g.pseudorange_m.ravel(), g.pseudorange_rate_mps.ravel(),
                    g.elevation.ravel(), g.azimuth.ravel(), g.sat_pos_e.reshape(-1, 3), g.sat_vel_e.reshape(-1, 3),
                ])
                gnss.writerows(rows.tolist())
    return path, gnss_path


def chunk_prn(chunk: Chunk | ChunkBatch, m: int) -> np.ndarray:
    prn = getattr(chunk.gnss, "prn", None)
    return np.arange(1, m + 1) if prn is None else np.asarray(prn)
