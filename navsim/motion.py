"""True motion along a known track: speed profiles, attitude and the full true state.

The vehicle's arc length s(t) along the track comes from a speed profile; the track
gives the geometry (position, unit tangent, heading, grade, cant and their derivatives
with respect to s); this module combines the two into a mutually consistent true state:

.. math::

    v^n = \\dot s\\, t^n(s), \\qquad
    \\dot v^n = \\ddot s\\, t^n + \\dot s^2\\, \\frac{dt^n}{ds}, \\\\
    f^n = \\dot v^n + (2\\omega_{ie}^n + \\omega_{en}^n) \\times v^n - g^n, \\qquad
    f^b = C_b^{n\\,T} f^n, \\\\
    \\omega_{ib}^b = \\omega_{nb}^b + C_b^{n\\,T}(\\omega_{ie}^n + \\omega_{en}^n),

where ``dv^n/dt`` is the rate of change of the ENU components (the form in which the
local-level navigation equation, 003 eq. (1), is written), ``omega_nb_b`` follows from the
heading, pitch and roll rates (:func:`navsim.rotations.body_rate_from_hpr_rates`) and
``g^n`` is the Earth model's plumb-line gravity. Everything is analytic in t, so the IMU
can integrate it to near machine precision.

Attitude: the body y axis points along the track tangent (heading, grade); roll is the
track's cant; configurable harmonic body oscillations add to heading, pitch and roll.

Speed profiles (all vectorised over t, all with continuous acceleration):

* :class:`ConstantSpeed`;
* :class:`Timetable`: stop-to-stop legs (accelerate, cruise, brake, dwell) with
  jerk-limited acceleration built from raised-cosine ramps;
* :class:`ExternalMotion`: samples (t, s, speed, acceleration) given step by step (the
  Gymnasium env and the FMU feed it), joined by quintic Hermite interpolation, which
  matches position, speed and acceleration at every sample.

References
----------
.. [1] Sokolov S.V., Vdovichenko S.S. (2012), seed 003, eq. (1).
.. [2] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., 2013, eqs. (5.54) (local-navigation-frame velocity equation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal, Protocol, Sequence, overload

import numpy as np

from .errors import ConfigError
from .rotations import body_rate_from_hpr_rates, mat_nb_from_hpr

if TYPE_CHECKING:  # type hints only
    from .track import Track

__all__ = [
    "SpeedProfile",
    "ConstantSpeed",
    "Timetable",
    "Station",
    "ExternalMotion",
    "Oscillation",
    "TrueState",
    "true_state",
    "body_kinematics",
    "truth_channels",
]


# ============================================================================ profiles
class SpeedProfile(Protocol):
    """Along-track motion: arc length, speed and acceleration as functions of time."""

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return s (m), ds/dt (m/s) and d2s/dt2 (m/s^2) at times t (s)."""
        ...

    @property
    def end_time(self) -> float:
        """Last time (s) at which the profile is defined (inf if unbounded)."""
        ...


@dataclass(frozen=True, slots=True)
class ConstantSpeed:
    """s(t) = s0 + speed * t, optionally with a harmonic speed variation.

    With ``amplitude`` A (m/s) and ``period`` T (s) the speed is ``v(t) = speed + A sin(2 pi
    t / T)``, so ``s(t) = s0 + speed t + A T / (2 pi) (1 - cos(2 pi t / T))`` and the
    along-track acceleration ``a(t) = 2 pi A / T cos(2 pi t / T)`` (amplitude 2 pi A / T;
    smooth, no breakpoints). A = 0 (default) is the constant speed, number for number.
    """

    speed: float
    s0: float = 0.0
    amplitude: float = 0.0
    period: float = 300.0

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        if self.amplitude == 0.0:
            return self.s0 + self.speed * t, np.full_like(t, self.speed), np.zeros_like(t)
        w = 2.0 * math.pi / self.period
        arg = w * t
        s = self.s0 + self.speed * t + self.amplitude / w * (1.0 - np.cos(arg))
        return s, self.speed + self.amplitude * np.sin(arg), self.amplitude * w * np.cos(arg)

    @property
    def end_time(self) -> float:
        return math.inf

    @property
    def breakpoints(self) -> np.ndarray:
        """Times (s) where s(t) is not infinitely differentiable: none."""
        return np.zeros(0)


# Raised-cosine acceleration ramp R(x) (0 -> 1 over x in [0, 1]) and its integrals; the
# jerk R'(x) = (pi/2) sin(pi x) vanishes at both ends, so acceleration is C^1.
def _ramp(x: np.ndarray) -> np.ndarray:
    xc = np.clip(x, 0.0, 1.0)
    return 0.5 * (1.0 - np.cos(np.pi * xc))


def _ramp_int1(x: np.ndarray) -> np.ndarray:  # integral of R from 0 to x
    xc = np.clip(x, 0.0, 1.0)
    inside = 0.5 * xc - np.sin(np.pi * xc) / (2.0 * np.pi)
    return inside + np.maximum(x - 1.0, 0.0)


def _ramp_int2(x: np.ndarray) -> np.ndarray:  # integral of _ramp_int1 from 0 to x
    xc = np.clip(x, 0.0, 1.0)
    inside = 0.25 * xc**2 + (np.cos(np.pi * xc) - 1.0) / (2.0 * np.pi**2)
    beyond = np.maximum(x - 1.0, 0.0)
    # for x > 1: R2(1) + (x^2 - 1)/2 - (x - 1)/2 = R2(1) + beyond * (beyond + 1) / 2
    return inside + 0.5 * beyond * (beyond + 1.0)


@dataclass(frozen=True, slots=True)
class Station:
    """A stop of a timetable: arc length of the platform mark and dwell time."""

    s: float
    dwell: float = 30.0


@dataclass(frozen=True)
class Timetable:
    """Stop-to-stop running between stations with jerk-limited acceleration.

    The vehicle starts at rest at ``stations[0].s`` at t = 0 (after an initial dwell of
    ``stations[0].dwell``), runs to each next station at up to ``cruise_speed``, brakes
    to stop exactly at the platform mark, dwells, and so on; after the last station it
    stays at rest. Acceleration changes follow raised-cosine ramps of duration
    ``jerk_time`` (peak jerk ``pi/2 * a / jerk_time``).

    The profile is a sum of ramp events, ``a(t) = sum_k c_k R((t - t_k)/T_j)``, so s, ds/dt
    and d2s/dt2 are closed forms (:func:`_ramp_int2`, :func:`_ramp_int1`, :func:`_ramp`).
    """

    stations: tuple[Station, ...]
    cruise_speed: float = 25.0
    max_accel: float = 0.8
    max_decel: float = 0.8
    jerk_time: float = 2.0
    _event_times: np.ndarray = field(init=False, repr=False)
    _event_steps: np.ndarray = field(init=False, repr=False)
    _end_time: float = field(init=False, repr=False)

    def __post_init__(self) -> None:
        stations = tuple(self.stations)
        if len(stations) < 2:
            raise ConfigError("motion.stations", "at least two stations", len(stations))
        for name in ("cruise_speed", "max_accel", "max_decel", "jerk_time"):
            value = getattr(self, name)
            if not (value > 0 and math.isfinite(value)):
                raise ConfigError(f"motion.{name}", "a positive number", value)
        for i, (a, b) in enumerate(zip(stations, stations[1:])):
            if not b.s > a.s:
                raise ConfigError(f"motion.stations[{i + 1}].s", f"> stations[{i}].s = {a.s}", b.s)
        for i, st in enumerate(stations):
            if st.dwell < 0:
                raise ConfigError(f"motion.stations[{i}].dwell", "a dwell >= 0 s", st.dwell)
        times, steps = [], []
        t = stations[0].dwell
        for a, b in zip(stations, stations[1:]):
            leg_times, leg_steps, duration = self._plan_leg(b.s - a.s)
            times += [t + x for x in leg_times]
            steps += leg_steps
            t += duration + b.dwell
        object.__setattr__(self, "stations", stations)
        object.__setattr__(self, "_event_times", np.array(times))
        object.__setattr__(self, "_event_steps", np.array(steps))
        object.__setattr__(self, "_end_time", t)
        object.__setattr__(self, "_pieces", self._piecewise())

    def _piecewise(self) -> tuple[np.ndarray, ...]:
        """The state at every breakpoint and the ramps active in each interval after it.

        Summing every ramp's closed form from t = 0 (as ``_sum_of_ramps`` does) adds
        terms that grow like t^2 and cancel, leaving rounding noise of about
        eps a t^2 (1e-10 m after an hour). Here the state at each breakpoint is exact
        (:meth:`_exact_state`) and, inside an interval, only the ramps active in it enter,
        each as a bounded local difference: the rounding is that of s itself.
        """
        tj = self.jerk_time
        starts, c = self._event_times, self._event_steps
        bounds = self.breakpoints
        k_active = 1
        active = []
        for b0 in bounds:
            on = np.flatnonzero((starts <= b0) & (starts + tj > b0))
            active.append(on)
            k_active = max(k_active, len(on))
        n = len(bounds)
        t_ev = np.zeros((n, k_active))
        c_ev = np.zeros((n, k_active))
        for i, on in enumerate(active):
            t_ev[i, :len(on)], c_ev[i, :len(on)] = starts[on], c[on]
        s0 = np.empty(n)
        v0 = np.empty(n)
        a_done = np.empty(n)
        for i, b0 in enumerate(bounds):
            s0[i], v0[i] = self._exact_state(float(b0))
            a_done[i] = float(np.sum(c[starts + tj <= b0]))
        return bounds, s0, v0, a_done, t_ev, c_ev

    def _exact_state(self, t: float) -> tuple[float, float]:
        """s and ds/dt at t, correctly rounded: the sums of ramps in rational arithmetic.

        A ramp that has ended contributes polynomials of x = (t - t_k) / T, summed
        exactly (the constant 1/pi^2 enters as its float value: an error below 1e-17 of
        c T^2); a ramp in progress contributes bounded trigonometric terms in float.
        Used once per breakpoint at construction.
        """
        from fractions import Fraction as F

        tj = F(self.jerk_time)
        r2_1 = F(0.25) - F(1.0 / math.pi**2)  # R2(1)
        s, v = F(self.stations[0].s), F(0)
        for t_k, c in zip(self._event_times.tolist(), self._event_steps.tolist()):
            x = (F(t) - F(t_k)) / tj
            if x <= 0:
                continue
            if x >= 1:
                b = x - 1
                s += F(c) * tj * tj * (r2_1 + b * (b + 1) / 2)
                v += F(c) * tj * (F(1, 2) + b)
            else:
                xf = float(x)
                s += F(c) * tj * tj * (x * x / 4 + F((math.cos(math.pi * xf) - 1.0) / (2.0 * math.pi**2)))
                v += F(c) * tj * (x / 2 - F(math.sin(math.pi * xf) / (2.0 * math.pi)))
        return float(s), float(v)

    def _local(self, t: np.ndarray, b0: np.ndarray, s0: np.ndarray, v0: np.ndarray, a_done: np.ndarray, t_ev: np.ndarray,
               c_ev: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """s, ds/dt, d2s/dt2 at t >= b0 within one interval, from the state at b0."""
        tj = self.jerk_time
        tau = t - b0
        x0 = (np.asarray(b0)[..., None] - t_ev) / tj  # in [0, 1) for active ramps
        x = (t[..., None] - t_ev) / tj
        r1_0 = _ramp_int1(x0)
        accel = a_done + np.sum(c_ev * _ramp(x), axis=-1)
        speed = v0 + a_done * tau + tj * np.sum(c_ev * (_ramp_int1(x) - r1_0), axis=-1)
        rest = _ramp_int2(x) - _ramp_int2(x0) - r1_0 * (x - x0)
        s = s0 + v0 * tau + 0.5 * a_done * tau * tau + tj * tj * np.sum(c_ev * rest, axis=-1)
        return s, speed, accel

    # -- planning ------------------------------------------------------------------
    def _change(self, dv: float, accel: float) -> tuple[float, float, float]:
        """Peak acceleration, plateau and total duration of a speed change dv > 0."""
        tj = self.jerk_time
        if dv >= accel * tj:
            return accel, dv / accel - tj, dv / accel + tj
        return dv / tj, 0.0, 2.0 * tj  # too small for a plateau: reduced peak

    def _stop_to_stop_distance(self, v: float) -> float:
        # by symmetry of the ramp, distance of a change 0 -> v is v * T / 2
        return 0.5 * v * (self._change(v, self.max_accel)[2] + self._change(v, self.max_decel)[2])

    def _plan_leg(self, length: float) -> tuple[list[float], list[float], float]:
        v = self.cruise_speed
        if self._stop_to_stop_distance(v) > length:
            lo, hi = 0.0, v
            for _ in range(200):  # bisection: distance is increasing in v
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if self._stop_to_stop_distance(mid) <= length else (lo, mid)
            v = lo
        a_acc, plateau_acc, t_acc = self._change(v, self.max_accel)
        a_dec, plateau_dec, t_dec = self._change(v, self.max_decel)
        cruise = (length - self._stop_to_stop_distance(v)) / v
        tj = self.jerk_time
        t_brake = t_acc + cruise
        times = [0.0, tj + plateau_acc, t_brake, t_brake + tj + plateau_dec]
        steps = [a_acc, -a_acc, -a_dec, a_dec]
        return times, steps, t_acc + cruise + t_dec

    # -- evaluation ------------------------------------------------------------------
    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """s, ds/dt, d2s/dt2 at times t (s), from the state at the last breakpoint."""
        t = np.asarray(t, dtype=float)
        bounds, s0, v0, a_done, t_ev, c_ev = self._pieces  # type: ignore[attr-defined]  # set in __post_init__, not a field
        i = np.searchsorted(bounds, t, side="right") - 1
        before = i < 0  # the first dwell: at rest at the first station
        j = np.maximum(i, 0)
        tb = np.where(before, bounds[0], t)  # evaluate at the first breakpoint, overwritten below
        s, speed, accel = self._local(tb, bounds[j], s0[j], v0[j], a_done[j], t_ev[j], c_ev[j])
        if np.any(before):
            s = np.where(before, self.stations[0].s, s)
            speed = np.where(before, 0.0, speed)
            accel = np.where(before, 0.0, accel)
        return s, speed, accel

    def _sum_of_ramps(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The same as :meth:`evaluate`, summing every ramp from t = 0 (a reference for
        tests: exact in exact arithmetic, noisier in floating point late in the run)."""
        t = np.asarray(t, dtype=float)
        tj = self.jerk_time
        x = (t[..., None] - self._event_times) / tj
        c = self._event_steps
        accel = np.sum(c * _ramp(x), axis=-1)
        speed = tj * np.sum(c * _ramp_int1(x), axis=-1)
        s = self.stations[0].s + tj * tj * np.sum(c * _ramp_int2(x), axis=-1)
        return s, speed, accel

    @property
    def end_time(self) -> float:
        """Time of arrival at the last station plus its dwell, s."""
        return self._end_time

    @property
    def breakpoints(self) -> np.ndarray:
        """Times (s, increasing, unique) where a ramp starts or ends.

        The acceleration is C^1 there (the jerk of a raised-cosine ramp vanishes at both
        ends) but its second derivative jumps; between two breakpoints s(t) is analytic and
        non-decreasing (stops begin and end at breakpoints). Read-only: the fast truth
        generator (:mod:`navsim.truthgen`) splits its interpolation intervals there.
        """
        return np.unique(np.concatenate([self._event_times, self._event_times + self.jerk_time]))


class ExternalMotion:
    """Along-track motion supplied sample by sample from outside (env, FMU, an FMU).

    Samples ``(t, s, speed, accel)`` must come at increasing times; between two samples
    the motion is the quintic Hermite polynomial that matches position, speed and
    acceleration at both ends, so the specific force is continuous and the IMU's
    integrals are exact for it. ``evaluate`` at a time beyond the last sample raises.

    This is the one mutable profile: the :class:`~navsim.simulator.Simulator` owns it.
    """

    def __init__(self, t0: float = 0.0, s0: float = 0.0, speed0: float = 0.0, accel0: float = 0.0):
        # growing buffers (capacity doubles), so pushing and evaluating stay O(1) / O(log n)
        self._tbuf: np.ndarray = np.empty(1024)
        self._xbuf: np.ndarray = np.empty((1024, 3))
        self._n = 1
        self._tbuf[0] = float(t0)
        self._xbuf[0] = (float(s0), float(speed0), float(accel0))

    def push(self, t: float, s: float, speed: float, accel: float) -> None:
        """Append the motion state at time t (> the last sample's time)."""
        values = (float(s), float(speed), float(accel))
        if not all(math.isfinite(v) for v in values):
            raise ConfigError("motion.external", "finite arc length, speed and acceleration", values)
        last = self._tbuf[self._n - 1]
        if not t > last:
            raise ConfigError("motion.external.t", f"a time after {last}", t)
        if self._n == len(self._tbuf):
            self._tbuf = np.concatenate([self._tbuf, np.empty(self._n)])
            self._xbuf = np.concatenate([self._xbuf, np.empty((self._n, 3))])
        self._tbuf[self._n] = float(t)
        self._xbuf[self._n] = values
        self._n += 1

    def reset(self, t0: float = 0.0, s0: float = 0.0, speed0: float = 0.0, accel0: float = 0.0) -> None:
        self.__init__(t0, s0, speed0, accel0)  # type: ignore[misc]  # a reset is a fresh construction

    @property
    def end_time(self) -> float:
        return float(self._tbuf[self._n - 1])

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        knots = self._tbuf[: self._n]
        if t.size and (t.max() > knots[-1] + 1e-12 or t.min() < knots[0] - 1e-12):
            raise ConfigError(
                "motion.external", f"samples covering [{t.min()}, {t.max()}] s",
                f"samples for [{knots[0]}, {knots[-1]}] s",
            )
        values = self._xbuf[: self._n]
        if len(knots) == 1:
            z = np.zeros_like(t)
            return values[0, 0] + z, values[0, 1] + z, values[0, 2] + z
        i = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(knots) - 2)
        dt = knots[i + 1] - knots[i]
        u = (t - knots[i]) / dt
        p0, v0, a0 = values[i, 0], values[i, 1] * dt, values[i, 2] * dt * dt
        p1, v1, a1 = values[i + 1, 0], values[i + 1, 1] * dt, values[i + 1, 2] * dt * dt
        # quintic Hermite basis on [0, 1]
        u2, u3 = u * u, u * u * u
        h = [
            1 - 10 * u3 + 15 * u3 * u - 6 * u3 * u2,
            u - 6 * u3 + 8 * u3 * u - 3 * u3 * u2,
            0.5 * u2 - 1.5 * u3 + 1.5 * u3 * u - 0.5 * u3 * u2,
            10 * u3 - 15 * u3 * u + 6 * u3 * u2,
            -4 * u3 + 7 * u3 * u - 3 * u3 * u2,
            0.5 * u3 - u3 * u + 0.5 * u3 * u2,
        ]
        dh = [
            -30 * u2 + 60 * u3 - 30 * u3 * u,
            1 - 18 * u2 + 32 * u3 - 15 * u3 * u,
            u - 4.5 * u2 + 6 * u3 - 2.5 * u3 * u,
            30 * u2 - 60 * u3 + 30 * u3 * u,
            -12 * u2 + 28 * u3 - 15 * u3 * u,
            1.5 * u2 - 4 * u3 + 2.5 * u3 * u,
        ]
        ddh = [
            -60 * u + 180 * u2 - 120 * u3,
            -36 * u + 96 * u2 - 60 * u3,
            1 - 9 * u + 18 * u2 - 10 * u3,
            60 * u - 180 * u2 + 120 * u3,
            -24 * u + 84 * u2 - 60 * u3,
            3 * u - 12 * u2 + 10 * u3,
        ]
        coef = (p0, v0, a0, p1, v1, a1)
        s = sum(c * b for c, b in zip(coef, h))
        speed = sum(c * b for c, b in zip(coef, dh)) / dt
        accel = sum(c * b for c, b in zip(coef, ddh)) / (dt * dt)
        return s, speed, accel


# ============================================================================ attitude
_ANGLES = ("heading", "pitch", "roll")


@dataclass(frozen=True, slots=True)
class Oscillation:
    """A harmonic body oscillation added to one attitude angle.

    ``angle(t) += amplitude * sin(2 pi frequency t + phase)``; the corresponding rate
    amplitude is ``amplitude * 2 pi frequency`` (seed 001's test: rate amplitudes
    0.174 rad/s at 0.8 Hz and 1 Hz, i.e. angle amplitudes 0.0346 and 0.0277 rad).
    """

    angle: str
    amplitude: float  # rad
    frequency: float  # Hz
    phase: float = 0.0  # rad

    def __post_init__(self) -> None:
        if self.angle not in _ANGLES:
            raise ConfigError("motion.oscillations.angle", f"one of {_ANGLES}", self.angle)
        if not (self.frequency > 0 and math.isfinite(self.frequency)):
            raise ConfigError("motion.oscillations.frequency_hz", "a positive frequency", self.frequency)
        if not math.isfinite(self.amplitude):
            raise ConfigError("motion.oscillations.amplitude", "a finite angle", self.amplitude)


def _oscillation_offsets(oscillations: Sequence[Oscillation],
                         t: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Angle offsets and their rates, each a dict angle -> array."""
    angles = {name: np.zeros_like(t) for name in _ANGLES}
    rates = {name: np.zeros_like(t) for name in _ANGLES}
    for osc in oscillations:
        w = 2.0 * np.pi * osc.frequency
        arg = w * t + osc.phase
        angles[osc.angle] = angles[osc.angle] + osc.amplitude * np.sin(arg)
        rates[osc.angle] = rates[osc.angle] + osc.amplitude * w * np.cos(arg)
    return angles, rates


# ============================================================================ true state
@dataclass(frozen=True, slots=True)
class TrueState:
    """The true state at an array of times (every field has leading shape (n,)).

    Attributes
    ----------
    t : (n,) s.  s, speed, accel_along : (n,) m, m/s, m/s^2 along the track.
    lat, lon, h : (n,) rad, rad, m.
    velocity_n : (n, 3) ENU ground velocity, m/s.
    heading, pitch, roll : (n,) rad (see :mod:`navsim.rotations`).
    mat_nb : (n, 3, 3) body-to-ENU DCM.
    omega_ib_b : (n, 3) body rate relative to inertial space, body axes, rad/s.
    specific_force_b : (n, 3) specific force in body axes, m/s^2.
    position_e, velocity_e : (n, 3) ECEF position (m) and velocity relative to the Earth (m/s).
    """

    t: np.ndarray
    s: np.ndarray
    speed: np.ndarray
    accel_along: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    velocity_n: np.ndarray
    heading: np.ndarray
    pitch: np.ndarray
    roll: np.ndarray
    mat_nb: np.ndarray
    omega_ib_b: np.ndarray
    specific_force_b: np.ndarray
    position_e: np.ndarray
    velocity_e: np.ndarray


@overload
def _kinematics(track: Track, profile: SpeedProfile, oscillations: Sequence[Oscillation], t: np.ndarray,
                full: Literal[True]) -> TrueState: ...


@overload
def _kinematics(track: Track, profile: SpeedProfile, oscillations: Sequence[Oscillation], t: np.ndarray,
                full: Literal[False]) -> tuple[np.ndarray, np.ndarray]: ...


@overload
def _kinematics(track: Track, profile: SpeedProfile, oscillations: Sequence[Oscillation], t: np.ndarray,
                full: Literal["channels"]) -> tuple[np.ndarray, ...]: ...


def _kinematics(track: Track, profile: SpeedProfile, oscillations: Sequence[Oscillation], t: np.ndarray,
                full: bool | str) -> TrueState | tuple[np.ndarray, ...]:
    from .earth import mat_en
    from .track import track_frame

    t = np.asarray(t, dtype=float)
    s, speed, accel = profile.evaluate(t)
    frame = track_frame(track, s)
    earth = track.earth
    velocity_n = speed[..., None] * frame.tangent_n
    # rate of change of the ENU components of v^n
    vdot_n = accel[..., None] * frame.tangent_n + (speed * speed)[..., None] * frame.dtangent_n_ds
    offsets, offset_rates = _oscillation_offsets(oscillations, t)
    heading = frame.heading + offsets["heading"]
    pitch = frame.pitch + offsets["pitch"]
    roll = frame.cant + offsets["roll"]
    heading_rate = frame.dheading_ds * speed + offset_rates["heading"]
    pitch_rate = frame.dpitch_ds * speed + offset_rates["pitch"]
    roll_rate = frame.dcant_ds * speed + offset_rates["roll"]
    mat_nb = mat_nb_from_hpr(heading, pitch, roll)
    omega_nb_b = body_rate_from_hpr_rates(heading, pitch, roll, heading_rate, pitch_rate, roll_rate)
    omega_ie_n = earth.earth_rate_n(frame.lat)
    omega_en_n = earth.transport_rate_n(frame.lat, frame.h, velocity_n)
    omega_in_n = omega_ie_n + omega_en_n
    # omega_ib_b = omega_nb_b + C_bn (omega_ie_n + omega_en_n)
    omega_ib_b = omega_nb_b + np.einsum("...ji,...j->...i", mat_nb, omega_in_n)
    # f_n = dv_n/dt + (2 omega_ie_n + omega_en_n) x v_n - g_n     (003 eq. (1) solved for f)
    f_n = vdot_n + np.cross(omega_ie_n + omega_in_n, velocity_n) - earth.gravity_n(frame.lat, frame.h)
    f_b = np.einsum("...ji,...j->...i", mat_nb, f_n)
    if not full:
        return omega_ib_b, f_b
    if full == "channels":  # navsim.truthgen's fitted channels: no ECEF position and velocity
        return (omega_ib_b, f_b, velocity_n, s, speed, accel, frame.lat, frame.lon, frame.h,
                heading, pitch, roll)
    position_e = earth.geodetic_to_ecef(frame.lat, frame.lon, frame.h)
    velocity_e = np.einsum("...ji,...j->...i", mat_en(frame.lat, frame.lon), velocity_n)
    return TrueState(
        t=t, s=s, speed=speed, accel_along=accel, lat=frame.lat, lon=frame.lon, h=frame.h,
        velocity_n=velocity_n, heading=heading, pitch=pitch, roll=roll, mat_nb=mat_nb,
        omega_ib_b=omega_ib_b, specific_force_b=f_b, position_e=position_e, velocity_e=velocity_e,
    )


def true_state(track: Track, profile: SpeedProfile, t: np.ndarray, oscillations: Sequence[Oscillation] = ()) -> TrueState:
    """The full true state at times ``t`` (s), vectorised. See the module docstring."""
    return _kinematics(track, profile, oscillations, t, full=True)


def body_kinematics(track: Track, profile: SpeedProfile, t: np.ndarray,
                    oscillations: Sequence[Oscillation] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Only ``omega_ib_b`` and ``specific_force_b`` at times t: what the IMU integrates."""
    return _kinematics(track, profile, oscillations, t, full=False)


def truth_channels(track: Track, profile: SpeedProfile, t: np.ndarray,
                   oscillations: Sequence[Oscillation] = ()) -> tuple[np.ndarray, ...]:
    """The fields of :func:`true_state` that :mod:`navsim.truthgen` fits, at times t (s):
    ``(omega_ib_b, specific_force_b, velocity_n, s, speed, accel_along, lat, lon, h, heading,
    pitch, roll)``, the same arrays as those of :func:`true_state` (the ECEF position and
    velocity and the time are not computed)."""
    return _kinematics(track, profile, oscillations, t, full="channels")
