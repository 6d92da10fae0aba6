"""GNSS signal outages: scheduled windows, track segments, sky masks, random dropouts.

:func:`visibility` turns the epoch times, the vehicle's arc length and heading along the
track, and the satellites' elevation/azimuth into a boolean visibility matrix that
:func:`navsim.sensors.gnss.simulate_epochs` combines with its own elevation mask:

* scheduled time windows ``t_start <= t < t_end`` (seed 003: signals lost from 400 s for
  300 s, i.e. the window (400, 700));
* arc-length windows ``s_start <= s < s_end`` and track segments by kind: inside a
  ``"tunnel"`` segment every signal is lost; inside a ``"cutting"`` or ``"urban"`` segment
  an urban-canyon mask applies (below);
* a fixed sky mask: a global extra elevation mask, azimuth sectors with their own
  elevation masks, and a list of masked PRNs;
* random dropouts: a two-state (available / out) Markov chain for the whole receiver and,
  optionally, one per satellite.

Urban canyon / cutting mask. Two parallel walls (buildings, cutting slopes) along the
street at lateral distance W from the antenna, rising H above it, block directions below
the wall's top edge. A ray at azimuth ``alpha`` relative to the street direction meets a
wall at horizontal distance ``W / |sin alpha|``, so the masking elevation is::

    E_mask(alpha) = arctan( tan(E_cross) |sin alpha| ),   tan(E_cross) = H / W

E_cross is the mask straight across the street (given per segment kind); along the street
(alpha = 0, pi) nothing is masked. The street direction is the track heading.

Random dropouts are a discrete-time Markov chain sampled at the epochs: from
"available" the chain goes "out" with probability ``dt / mean_available_s`` per epoch, and
back with probability ``dt / mean_outage_s`` (clipped at 1), so run lengths are geometric
with means exactly ``mean_available_s`` and ``mean_outage_s`` for a constant epoch
interval dt (the chain is meant for means of several epochs or more). The initial state
is drawn from the stationary distribution.

Randomness: outages use their own generator (the ``outages`` stream), so switching them
off leaves every GNSS noise draw unchanged. Each call draws one block
``rng.random((k, 1 + m))`` (row = epoch: receiver chain, then one per satellite) whether
or not the chains are enabled, and the chain states travel in :class:`OutageState`: the
result is chunk-invariant.

References
----------
.. [1] Sokolov S.V., Vdovichenko S.S. (2012), seed 003, numerical example: satellite
       signals lost at 400 s for 300 s.
.. [2] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., 2013, section 10.6.1 (signal blockage in urban canyons; the
       masking-angle geometry above is the elementary two-wall form of that discussion).
.. [3] Gilbert E.N. (1960), Capacity of a burst-noise channel, Bell Syst. Tech. J. 39,
       1253-1265 (the two-state Markov on/off channel model).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

import numpy as np

from ..errors import ConfigError, check_nonnegative
from ..types import FloatOrArray
from ._common import RecentBatches, frozen_array
from .imu import apply as _imu_apply
from .imu import kernel as _imu_kernel

__all__ = ["OutageModel", "OutageState", "visibility", "visibility_batch", "canyon_mask_elevation"]


def _pairs(field_name: str, value: Any, width: int) -> tuple[tuple[float, ...], ...]:
    try:
        rows = tuple(tuple(float(x) for x in row) for row in value)
    except (TypeError, ValueError):
        raise ConfigError(field_name, f"a list of {width}-number lists", value) from None
    for row in rows:
        if len(row) != width or not all(np.isfinite(row)):
            raise ConfigError(field_name, f"rows of {width} finite numbers", value)
    return rows


@dataclass(frozen=True, slots=True)
class OutageModel:
    """What blocks GNSS signals (truth side).

    Parameters
    ----------
    windows_s : tuple of (t_start, t_end)
        Scheduled receiver outages, ``t_start <= t < t_end``, s.
    arc_windows_m : tuple of (s_start, s_end)
        Receiver outages by arc length along the track, ``s_start <= s < s_end``, m.
    tunnel_kinds : tuple of str
        Track-segment kinds inside which every signal is lost.
    canyon_masks_deg : tuple of (kind, E_cross_deg)
        Track-segment kinds with an urban-canyon mask and its elevation straight across
        the street, deg in [0, 90).
    elevation_mask_deg : float
        Extra elevation mask for every satellite (the receiver's own mask is in the GNSS
        error model); -90 = none.
    sky_mask_deg : tuple of (az_from, az_to, elevation_mask)
        Azimuth sectors (clockwise from north, from ``az_from`` clockwise to ``az_to``,
        deg) in which satellites below ``elevation_mask`` deg are blocked (terrain).
    masked_prns : tuple of int
        Satellites never received.
    receiver_mean_outage_s, receiver_mean_available_s : float
        Random whole-receiver dropouts (mean outage and mean available durations, s);
        both 0 = off, both > 0 = on.
    satellite_mean_outage_s, satellite_mean_available_s : float
        The same per satellite, independently.
    """

    windows_s: tuple[tuple[float, float], ...] = ()
    arc_windows_m: tuple[tuple[float, float], ...] = ()
    tunnel_kinds: tuple[str, ...] = ("tunnel",)
    canyon_masks_deg: tuple[tuple[str, float], ...] = (("cutting", 30.0), ("urban", 60.0))
    elevation_mask_deg: float = -90.0
    sky_mask_deg: tuple[tuple[float, float, float], ...] = ()
    masked_prns: tuple[int, ...] = ()
    receiver_mean_outage_s: float = 0.0
    receiver_mean_available_s: float = 0.0
    satellite_mean_outage_s: float = 0.0
    satellite_mean_available_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("windows_s", "arc_windows_m"):
            rows = _pairs(f"outages.{name}", getattr(self, name), 2)
            for start, end in rows:
                if not start < end:
                    raise ConfigError(
                        f"outages.{name}", "start < end in every window", (start, end)
                    )
            object.__setattr__(self, name, rows)
        if isinstance(self.tunnel_kinds, str):
            raise ConfigError("outages.tunnel_kinds", "a list of kind names", self.tunnel_kinds)
        object.__setattr__(self, "tunnel_kinds", tuple(str(k) for k in self.tunnel_kinds))
        try:
            canyons = tuple((str(kind), float(angle)) for kind, angle in self.canyon_masks_deg)
        except (TypeError, ValueError):
            raise ConfigError(
                "outages.canyon_masks_deg", "a list of (kind, degrees) pairs", self.canyon_masks_deg
            ) from None
        for kind, angle in canyons:
            if not 0.0 <= angle < 90.0:
                raise ConfigError(f"outages.canyon_masks_deg.{kind}", "degrees in [0, 90)", angle)
        object.__setattr__(self, "canyon_masks_deg", canyons)
        mask = float(self.elevation_mask_deg)
        if not -90.0 <= mask <= 90.0:
            raise ConfigError("outages.elevation_mask_deg", "degrees in [-90, 90]", mask)
        object.__setattr__(self, "elevation_mask_deg", mask)
        sky = _pairs("outages.sky_mask_deg", self.sky_mask_deg, 3)
        for row in sky:
            if not -90.0 <= row[2] <= 90.0:
                raise ConfigError("outages.sky_mask_deg", "elevation masks in [-90, 90] deg", row)
        object.__setattr__(self, "sky_mask_deg", sky)
        try:
            prns = tuple(int(p) for p in self.masked_prns)
        except (TypeError, ValueError):
            raise ConfigError(
                "outages.masked_prns", "a list of integers", self.masked_prns
            ) from None
        object.__setattr__(self, "masked_prns", prns)
        for who in ("receiver", "satellite"):
            out = check_nonnegative(f"outages.{who}_mean_outage_s", getattr(self, f"{who}_mean_outage_s"))
            avail = check_nonnegative(
                f"outages.{who}_mean_available_s", getattr(self, f"{who}_mean_available_s")
            )
            if (out > 0.0) != (avail > 0.0):
                raise ConfigError(
                    f"outages.{who}_mean_outage_s",
                    f"both {who} means > 0 (random outages on) or both 0 (off)",
                    (out, avail),
                )
            object.__setattr__(self, f"{who}_mean_outage_s", out)
            object.__setattr__(self, f"{who}_mean_available_s", avail)

    @classmethod
    def preset(cls, name: str) -> OutageModel:
        """``"paper-2012"``: the window (400 s, 700 s) of seed 003; ``"none"``: nothing.

        Both keep the default segment rules (tunnels, cuttings, urban), which act only on
        tracks that have such segments.
        """
        if name == "paper-2012":
            return cls(windows_s=((400.0, 700.0),))
        if name == "none":
            return cls()
        raise ConfigError("outages.preset", "one of ['none', 'paper-2012']", name)

    @property
    def receiver_random(self) -> bool:
        """Random whole-receiver dropouts enabled."""
        return self.receiver_mean_outage_s > 0.0

    @property
    def satellite_random(self) -> bool:
        """Random per-satellite dropouts enabled."""
        return self.satellite_mean_outage_s > 0.0


@dataclass(frozen=True, slots=True, eq=False)
class OutageState:
    """Markov-chain states carried between calls.

    Attributes
    ----------
    t_s : float
        Time of the last epoch (NaN before the first).
    receiver_out : bool
        Receiver chain state at ``t_s`` (at the first epoch if NaN).
    satellite_out : ndarray (m,) bool
        Per-satellite chain states.
    """

    t_s: float
    receiver_out: bool
    satellite_out: np.ndarray

    def __post_init__(self) -> None:
        arr = np.array(self.satellite_out, dtype=bool, copy=True)
        arr.setflags(write=False)
        object.__setattr__(self, "satellite_out", arr)
        object.__setattr__(self, "receiver_out", bool(self.receiver_out))

    @classmethod
    def initial(
        cls, model: OutageModel, n_satellites: int, rng: np.random.Generator
    ) -> OutageState:
        """Chains drawn from their stationary distributions (always 1 + m uniforms)."""
        u = rng.random(1 + int(n_satellites))
        p_rx = _stationary_out(model.receiver_mean_outage_s, model.receiver_mean_available_s)
        p_sv = _stationary_out(model.satellite_mean_outage_s, model.satellite_mean_available_s)
        return cls(float("nan"), bool(u[0] < p_rx), u[1:] < p_sv)


# the slots' own setters (a frozen dataclass refuses setattr): for visibility_batch's states
_SET_T, _SET_RX, _SET_SV = (getattr(OutageState, name).__set__ for name in ("t_s", "receiver_out", "satellite_out"))
_RECENT = RecentBatches()
"""The outage states made by the last batched calls and their arrays (:func:`visibility_batch`)."""


def _stationary_out(mean_out: float, mean_avail: float) -> float:
    return mean_out / (mean_out + mean_avail) if mean_out > 0.0 else 0.0


def canyon_mask_elevation(relative_azimuth: FloatOrArray, cross_mask_rad: FloatOrArray) -> np.ndarray:
    """Masking elevation arctan(tan(E_cross) |sin alpha|) of a street canyon, rad.

    ``relative_azimuth`` is the azimuth from the street direction (rad).
    """
    return np.arctan(np.tan(cross_mask_rad) * np.abs(np.sin(relative_azimuth)))


def _markov(
    u: np.ndarray, dt: np.ndarray, initial: np.ndarray, mean_out: float, mean_avail: float,
    first: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """Run two-state chains (columns of u, (k, n)) over the epochs.

    Per epoch: an "out" chain stays out if u >= p_recover, an "available" one goes out
    if u < p_fail. Vectorised without a Python loop: where both rules give the same next
    state the epoch *resets* the chain to it; where they differ the next state is either
    "keep" or "toggle", so the state is the last reset's value XOR the parity of toggles
    since then (integer arithmetic, exact).

    Returns the (k, n) states and the last state (n,).
    """
    k, n = u.shape
    if mean_out <= 0.0 or k == 0:
        off = np.zeros((k, n), dtype=bool)
        return off, (np.zeros(n, dtype=bool) if mean_out <= 0.0 else initial.copy())
    p_recover = np.minimum(1.0, dt / mean_out)[:, None]
    p_fail = np.minimum(1.0, dt / mean_avail)[:, None]
    stay_out = u >= p_recover  # next state if currently out
    go_out = u < p_fail  # next state if currently available
    reset = stay_out == go_out
    toggle = ~stay_out & go_out
    if first:  # the first epoch ever takes the initial (stationary) draw as it is
        reset[0] = True
        go_out = go_out.copy()
        go_out[0] = initial
        toggle[0] = False
    index = np.arange(k)[:, None]
    last_reset = np.maximum.accumulate(np.where(reset, index, -1), axis=0)
    toggles = np.cumsum(toggle, axis=0)
    column = np.arange(n)[None, :]
    anchor = np.maximum(last_reset, 0)
    anchor_value = np.where(last_reset >= 0, go_out[anchor, column], initial[None, :])
    anchor_toggles = np.where(last_reset >= 0, toggles[anchor, column], 0)
    states = anchor_value ^ ((toggles - anchor_toggles) % 2 == 1)
    return states, states[-1].copy()


def visibility(
    t: np.ndarray,
    s: np.ndarray,
    heading: np.ndarray,
    elevation: np.ndarray,
    azimuth: np.ndarray,
    segments: Iterable[Any],
    model: OutageModel,
    state: OutageState,
    rng: np.random.Generator,
    *,
    prn: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, OutageState]:
    """Which satellite signals reach the antenna at each epoch.

    Parameters
    ----------
    t : array_like (k,)
        Epoch times, s, strictly increasing and after ``state.t_s``.
    s : array_like (k,)
        Arc length along the track, m.
    heading : array_like (k,)
        Track heading (street direction), rad clockwise from north.
    elevation, azimuth : array_like (k, m)
        Satellite elevation and azimuth (clockwise from north), rad.
    segments : iterable
        Track segments with attributes ``kind``, ``s_start``, ``s_end`` (and ``name``),
        e.g. :class:`navsim.track.TrackSegment`; ``s_start <= s < s_end`` is inside.
    model : OutageModel
    state : OutageState
    rng : numpy.random.Generator
        The outages stream (never the GNSS one).
    prn : array_like (m,) of int, optional
        Satellite ids; required when ``model.masked_prns`` is not empty.

    Returns
    -------
    visible : ndarray (k, m) bool
        True where the satellite's signal is present.
    receiver_outage : ndarray (k,) bool
        True where the whole receiver has lost every signal (window, tunnel, arc window,
        receiver dropout).
    new_state : OutageState

    This is the one-receiver case of :func:`visibility_batch`.
    """
    visible, receiver_outage, states = visibility_batch(t, s, heading, elevation, azimuth, segments, model, [state],
                                                        [rng], prn=prn)
    return visible[0], receiver_outage[0], states[0]


def visibility_batch(
    t: np.ndarray,
    s: np.ndarray,
    heading: np.ndarray,
    elevation: np.ndarray,
    azimuth: np.ndarray,
    segments: Iterable[Any],
    model: OutageModel,
    states: Sequence[OutageState],
    rngs: Sequence[np.random.Generator],
    *,
    prn: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, list[OutageState]]:
    """:func:`visibility` for B receivers on the same true motion, in one pass.

    The deterministic masks (windows, tunnels, canyons, sky masks) are computed once;
    receiver j draws its Markov-chain block from ``rngs[j]`` and gets exactly the result
    of ``visibility(..., states[j], rngs[j])``. Arguments as :func:`visibility`, except
    ``states`` (B OutageState at the same ``t_s``) and ``rngs`` (B generators).

    Returns
    -------
    visible : ndarray (B, k, m) bool
    receiver_outage : ndarray (B, k) bool
    new_states : list of B OutageState
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    k = t.size
    states, rngs = list(states), list(rngs)
    members = len(states)
    if not states or len(rngs) != members:
        raise ConfigError("rngs", f"one generator per state ({members}, at least one)", len(rngs))
    elevation = np.asarray(elevation, dtype=float)
    if elevation.ndim != 2 or elevation.shape[0] != k:
        raise ConfigError("elevation", f"shape ({k}, m)", elevation.shape)
    m = elevation.shape[1]
    azimuth = np.asarray(azimuth, dtype=float).reshape(k, m)
    s = np.broadcast_to(np.asarray(s, dtype=float), (k,))
    heading = np.broadcast_to(np.asarray(heading, dtype=float), (k,))
    made = _RECENT.recall(states)  # (t_s, receiver_out, satellite_out) of states this function made
    if made is not None and made[2].shape == (members, m):
        t_s = made[0]  # made together: one epoch time, rows of shape (m,)
    else:
        made = None
        for state in states:
            if state.satellite_out.shape != (m,):
                raise ConfigError("state.satellite_out", f"shape ({m},)", state.satellite_out.shape)
        t_s = states[0].t_s
        if any(not (st.t_s == t_s or (math.isnan(st.t_s) and math.isnan(t_s))) for st in states):
            raise ConfigError("states", "states at the same epoch time (lockstep)", sorted({st.t_s for st in states}))
    if not np.all(np.isfinite(t)):
        raise ConfigError("t", "finite times", t)
    dt = np.diff(np.concatenate([[t_s], t]))
    if not (np.all(dt[1:] > 0.0) and (not np.isfinite(t_s) or k == 0 or dt[0] > 0.0)):
        raise ConfigError("t", f"strictly increasing times after state.t_s={t_s}", t)
    dt = np.where(np.isfinite(dt), dt, 0.0)

    u = np.empty((members, k, 1 + m))
    group_draw = _imu_kernel.draws("uniform") if k and _imu_apply.USE_KERNEL else None
    if group_draw is not None:
        group_draw(rngs, u)  # one compiled call, the same numbers (navsim.sensors.imu.kernel)
    else:
        for j, rng in enumerate(rngs):
            rng.random(out=u[j])  # one block per call and receiver, row = epoch

    receiver_outage = np.zeros(k, dtype=bool)
    for start, end in model.windows_s:
        receiver_outage |= (t >= start) & (t < end)
    for start, end in model.arc_windows_m:
        receiver_outage |= (s >= start) & (s < end)

    mask: np.ndarray = np.full((k, m), np.radians(model.elevation_mask_deg))
    canyons = dict(model.canyon_masks_deg)
    tunnels = set(model.tunnel_kinds)
    relative = azimuth - heading[:, None]
    for segment in segments:
        kind = segment.kind
        if kind not in tunnels and kind not in canyons:
            continue
        inside = (s >= float(segment.s_start)) & (s < float(segment.s_end))
        if not np.any(inside):
            continue
        if kind in tunnels:
            receiver_outage |= inside
        else:
            e_mask = canyon_mask_elevation(relative, np.radians(canyons[kind]))
            mask = np.where(inside[:, None], np.maximum(mask, e_mask), mask)
    for az_from, az_to, el_mask in model.sky_mask_deg:
        a0, a1 = np.radians(az_from), np.radians(az_to)
        width = np.remainder(a1 - a0, 2.0 * np.pi)
        in_sector = np.remainder(azimuth - a0, 2.0 * np.pi) <= width
        mask = np.where(in_sector, np.maximum(mask, np.radians(el_mask)), mask)
    with np.errstate(invalid="ignore"):
        visible = elevation >= mask
    if model.masked_prns:
        if prn is None:
            raise ConfigError("prn", "satellite ids when outages.masked_prns is set", None)
        prn = np.asarray(prn).reshape(m)
        visible &= ~np.isin(prn, model.masked_prns)[None, :]

    # the chains of all receivers side by side as columns (they are independent)
    first = not np.isfinite(t_s)
    if made is not None:  # the same values as read from the states (read-only arrays)
        rx_start, sv_start = made[1], made[2].reshape(members * m)
    else:
        rx_start = np.array([st.receiver_out for st in states])
        sv_start = np.concatenate([st.satellite_out for st in states])
    rx_states, rx_last = _markov(
        u[:, :, 0].T, dt, rx_start, model.receiver_mean_outage_s, model.receiver_mean_available_s, first,
    )
    sv_states, sv_last = _markov(
        u[:, :, 1:].transpose(1, 0, 2).reshape(k, members * m), dt, sv_start,
        model.satellite_mean_outage_s, model.satellite_mean_available_s, first,
    )
    receiver_outage = receiver_outage[None, :] | rx_states.T  # (B, k)
    visible = visible[None] & ~sv_states.reshape(k, members, m).transpose(1, 0, 2)
    visible &= ~receiver_outage[:, :, None]
    if not k:
        return visible, receiver_outage, states
    rows = frozen_array(sv_last.reshape(members, m), dtype=bool)  # one read-only copy, row j for receiver j
    rx_out = frozen_array(rx_last, dtype=bool)
    t_last = float(t[-1])
    new, set_t, set_rx, set_sv = object.__new__, _SET_T, _SET_RX, _SET_SV
    new_states = []
    for rx, sv in zip(rx_out.tolist(), rows):
        state = new(OutageState)
        set_t(state, t_last)
        set_rx(state, rx)
        set_sv(state, sv)
        new_states.append(state)
    _RECENT.remember(new_states, (t_last, rx_out, rows))  # for the next call on these states
    return visible, receiver_outage, new_states
