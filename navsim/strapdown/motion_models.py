"""Synthetic test motions with exact increments and exact reference integrals (seed 000).

A :class:`Signal` is a vector function of time made of a polynomial and harmonics,

    x(t) = sum_p poly[p] t**p / p!  +  Re( sum_h amps[h] exp(i freqs[h] t) ),

for which every increment of a multiple integral (1.14) over [t0, t0 + h] is closed form:

* polynomial: ``int_0^h (h-s)**(r-1)/(r-1)! (t0+s)**p/p! ds
  = sum_{q<=p} t0**(p-q)/(p-q)! h**(q+r)/(q+r)!`` (Beta integrals);
* harmonic: ``int_0^h (h-s)**(r-1)/(r-1)! exp(i nu (t0+s)) ds
  = exp(i nu t0) h**r phi_r(i nu h)``, ``phi_r(z) = sum_j z**j/(j+r)!``
  (the "phi functions" of exponential integrators): a power series for |z| < 1, the
  recurrence ``phi_r = (phi_{r-1} - 1/(r-1)!)/z`` from ``phi_0 = exp(z)`` otherwise.

A :class:`Motion` pairs the angular rate ``omega`` (rad/s) and the specific force ``accel``
(m/s^2), both in body axes, and gives the sub-sample increments, the multiple integrals,
and the exact reference values of the integrals the algorithms approximate: (1.12)
deltaTheta_c, (1.8) deltaV_s and (5.4) dS_s, by composite Gauss-Legendre quadrature of
the closed-form integrands (DeltaTheta(t_k, t) itself is closed form at every node).

Factories: :func:`coning_motion` (exact coning, half-cone angle alpha, frequency Omega),
:func:`sculling_motion` (in-phase harmonic angle about x and acceleration along y),
:func:`pseudo_coning` and :func:`pseudo_sculling` (the sensor harmonics of §6),
:func:`polynomial_motion` (general motion by Taylor coefficients at t = 0).

References
----------
.. [000] Litmanovich Yu.A., Izv. RAN, 2002 (seed 000), eqs. (1.8), (1.12), (1.14),
   (5.4), §6.
.. [4] Savage P.G., "Strapdown inertial navigation integration algorithm design Part 1:
   attitude algorithms", J. Guidance, Control and Dynamics 21(1), 1998 (coning motion).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from math import factorial
from typing import Callable

import numpy as np
from numpy.polynomial.legendre import leggauss
from numpy.typing import ArrayLike

from ..errors import ConfigError
from ..types import FloatOrArray

__all__ = [
    "phi_functions",
    "Signal",
    "Motion",
    "coning_motion",
    "coning_quaternion",
    "sculling_motion",
    "pseudo_coning",
    "pseudo_sculling",
    "polynomial_motion",
]

_GL_NODES = 24
_GL_X, _GL_W = leggauss(_GL_NODES)


def phi_functions(z: np.ndarray, r_max: int) -> np.ndarray:
    """phi_r(z) = sum_j z**j / (j + r)! for r = 1 .. r_max, shape z.shape + (r_max,).

    Series for |z| < 1 (40 terms, error below 1e-40 relative), else the recurrence
    phi_r = (phi_{r-1} - 1/(r-1)!)/z from phi_0 = exp(z), which is stable for |z| >= 1.
    """
    z = np.asarray(z, dtype=complex)
    out = np.empty(z.shape + (r_max,), dtype=complex)
    small = np.abs(z) < 1.0
    zs = np.where(small, z, 0.0)
    for r in range(1, r_max + 1):
        term = np.full(z.shape, 1.0 / factorial(r), dtype=complex)
        total = term.copy()
        for j in range(1, 40):
            term = term * zs / (j + r)
            total = total + term
        out[..., r - 1] = total
    zl = np.where(small, 1.0, z)
    prev = np.exp(zl)
    for r in range(1, r_max + 1):
        prev = (prev - 1.0 / factorial(r - 1)) / zl
        out[..., r - 1] = np.where(small, out[..., r - 1], prev)
    return out


@dataclass(frozen=True, slots=True)
class Signal:
    """x(t) = sum_p poly[p] t**p/p! + Re(sum_h amps[h] exp(i freqs[h] t)), shape (3,).

    Parameters
    ----------
    poly : array (P, 3)
        Taylor coefficients at t = 0 (value, first derivative, ...), units of x * s**p.
    freqs : array (H,)
        Circular frequencies, rad/s.
    amps : complex array (H, 3)
        Complex amplitudes, units of x.
    """

    poly: np.ndarray = field(default_factory=lambda: np.zeros((1, 3)))
    freqs: np.ndarray = field(default_factory=lambda: np.zeros(0))
    amps: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=complex))

    def __post_init__(self) -> None:
        poly = np.atleast_2d(np.asarray(self.poly, dtype=float))
        freqs = np.atleast_1d(np.asarray(self.freqs, dtype=float))
        amps = np.asarray(self.amps, dtype=complex).reshape(-1, 3)
        if poly.ndim != 2 or poly.shape[1] != 3:
            raise ConfigError("Signal.poly", "array of shape (P, 3)", poly.shape)
        if amps.shape[0] != freqs.shape[0]:
            raise ConfigError("Signal.amps", f"array of shape ({freqs.shape[0]}, 3)", amps.shape)
        if not np.all(np.isfinite(freqs)):
            raise ConfigError("Signal.freqs", "finite frequencies in rad/s", freqs)
        object.__setattr__(self, "poly", poly)
        object.__setattr__(self, "freqs", freqs)
        object.__setattr__(self, "amps", amps)

    def derivative(self, t: FloatOrArray, order: int = 0) -> np.ndarray:
        """d^order x / dt^order at times t (n,), shape (n, 3)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        out = np.zeros(t.shape + (3,))
        for p in range(order, self.poly.shape[0]):
            out += np.multiply.outer(t ** (p - order) / factorial(p - order), self.poly[p])
        if self.freqs.size:
            phase = np.exp(1j * np.multiply.outer(t, self.freqs))  # (n, H)
            out += np.real((phase * (1j * self.freqs) ** order) @ self.amps)
        return out

    def value(self, t: FloatOrArray) -> np.ndarray:
        """x(t), shape (n, 3)."""
        return self.derivative(t, 0)

    def multiple_integrals(self, t_start: FloatOrArray, dt: FloatOrArray, r_max: int) -> np.ndarray:
        """Increments (1.14) over [t_start, t_start + dt], orders 1..r_max: (n, r_max, 3).

        ``dt`` may be a scalar or an array broadcastable to ``t_start``.
        """
        t0 = np.atleast_1d(np.asarray(t_start, dtype=float))
        h = np.broadcast_to(np.asarray(dt, dtype=float), t0.shape)
        out = np.zeros(t0.shape + (r_max, 3))
        for r in range(1, r_max + 1):
            for p in range(self.poly.shape[0]):
                weight = np.zeros_like(t0)
                for q in range(p + 1):
                    weight = weight + t0 ** (p - q) / factorial(p - q) * h ** (q + r) / factorial(q + r)
                out[:, r - 1] += np.multiply.outer(weight, self.poly[p])
        if self.freqs.size:
            z = 1j * np.multiply.outer(h, self.freqs)  # (n, H)
            phi = phi_functions(z, r_max)  # (n, H, R)
            phase = np.exp(1j * np.multiply.outer(t0, self.freqs))  # (n, H)
            for r in range(1, r_max + 1):
                coeff = phase * phi[..., r - 1] * (h**r)[:, None]
                out[:, r - 1] += np.real(coeff @ self.amps)
        return out

    def integral(self, t_start: FloatOrArray, t_end: FloatOrArray) -> np.ndarray:
        """First integral over [t_start, t_end] (elementwise), shape (n, 3)."""
        t0 = np.atleast_1d(np.asarray(t_start, dtype=float))
        h = np.broadcast_to(np.asarray(t_end, dtype=float), t0.shape) - t0
        return self.multiple_integrals(t0, h, 1)[:, 0]

    def sub_increments(self, t_start: FloatOrArray, dt: float, m: int) -> np.ndarray:
        """m first-order increments over equal sub-intervals of the step: (n, m, 3)."""
        t0 = np.atleast_1d(np.asarray(t_start, dtype=float))
        parts = [self.integral(t0 + j * dt / m, t0 + (j + 1) * dt / m) for j in range(m)]
        return np.stack(parts, axis=1)

    @property
    def max_freq(self) -> float:
        return float(np.max(np.abs(self.freqs))) if self.freqs.size else 0.0


@dataclass(frozen=True, slots=True)
class Motion:
    """Angular rate ``omega`` (rad/s) and specific force ``accel`` (m/s^2), body axes."""

    omega: Signal
    accel: Signal = field(default_factory=Signal)

    def increments(self, t_start: FloatOrArray, dt: float, r_max: int) -> tuple[np.ndarray, np.ndarray]:
        """(dtheta_r, dv_r), each (n, r_max, 3), over [t_start, t_start + dt]."""
        return self.omega.multiple_integrals(t_start, dt, r_max), self.accel.multiple_integrals(t_start, dt, r_max)

    def sub_increments(self, t_start: FloatOrArray, dt: float, m: int) -> tuple[np.ndarray, np.ndarray]:
        """(dtheta_sub, dv_sub), each (n, m, 3)."""
        return self.omega.sub_increments(t_start, dt, m), self.accel.sub_increments(t_start, dt, m)

    # ---------------------------------------------------------------- exact references
    def _nodes(self, t_start: FloatOrArray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Composite Gauss-Legendre nodes: offsets tau (n, K), weights (n, K), t0 (n,)."""
        t0 = np.atleast_1d(np.asarray(t_start, dtype=float))
        h = float(dt)
        phase_span = max(self.omega.max_freq, self.accel.max_freq) * h
        panels = max(1, int(np.ceil(phase_span / 1.5)))
        edges = np.linspace(0.0, h, panels + 1)
        half = 0.5 * np.diff(edges)
        mid = 0.5 * (edges[1:] + edges[:-1])
        tau = (mid[:, None] + half[:, None] * _GL_X[None, :]).ravel()
        weights = (half[:, None] * _GL_W[None, :]).ravel()
        return np.broadcast_to(tau, t0.shape + tau.shape), np.broadcast_to(weights, t0.shape + tau.shape), t0

    def _quadrature(self, t_start: FloatOrArray, dt: float, first: Signal, second: Signal,
                    kernel: Callable[..., np.ndarray]) -> np.ndarray:
        tau, weights, t0 = self._nodes(t_start, dt)
        times = (t0[:, None] + tau).ravel()
        starts = np.repeat(t0, tau.shape[1])
        angle = first.integral(starts, times).reshape(tau.shape + (3,))  # DeltaTheta(t_k, t)
        value = second.value(times).reshape(tau.shape + (3,))
        integrand = np.cross(angle, value) * kernel(tau, float(dt))[..., None]
        return np.einsum("nk,nkj->nj", weights, integrand)

    def exact_coning(self, t_start: FloatOrArray, dt: float) -> np.ndarray:
        """(1.12) deltaTheta_c = 1/2 int DeltaTheta(t_k, t) x omega(t) dt, shape (n, 3)."""
        return 0.5 * self._quadrature(t_start, dt, self.omega, self.omega, lambda tau, h: np.ones_like(tau))

    def exact_sculling(self, t_start: FloatOrArray, dt: float) -> np.ndarray:
        """(1.8) deltaV_s = int DeltaTheta(t_k, t) x a(t) dt, shape (n, 3)."""
        return self._quadrature(t_start, dt, self.omega, self.accel, lambda tau, h: np.ones_like(tau))

    def exact_partial_displacement(self, t_start: FloatOrArray, dt: float) -> np.ndarray:
        """(5.4) dS_s = int_0^T (T - tau) DeltaTheta(t_k, tau) x a(tau) dtau, (n, 3)."""
        return self._quadrature(t_start, dt, self.omega, self.accel, lambda tau, h: h - tau)

    def exact_rotation_vector(self, t_start: FloatOrArray, dt: float) -> np.ndarray:
        """DeltaTheta + deltaTheta_c of (1.11) with the exact (1.12), shape (n, 3)."""
        return self.omega.integral(t_start, np.asarray(t_start) + dt) + self.exact_coning(t_start, dt)

    def exact_velocity_bracket(self, t_start: FloatOrArray, dt: float) -> np.ndarray:
        """DeltaV + deltaV_s of (1.6) with the exact (1.8), shape (n, 3)."""
        return self.accel.integral(t_start, np.asarray(t_start) + dt) + self.exact_sculling(t_start, dt)


# ------------------------------------------------------------------------------ factories
def coning_motion(half_angle: float, rate: float) -> Motion:
    """Exact coning: omega = [-W sin(a) sin(Wt), W sin(a) cos(Wt), -W (1 - cos a)].

    The body attitude is :func:`coning_quaternion` (half-cone angle ``half_angle`` rad,
    circular frequency ``rate`` = W rad/s); the cone axis is z. The specific force is 0.
    """
    if not 0.0 < half_angle < np.pi / 2:
        raise ConfigError("half_angle", "an angle in (0, pi/2) rad", half_angle)
    if not rate > 0.0:
        raise ConfigError("rate", "a positive circular frequency in rad/s", rate)
    s = np.sin(half_angle)
    amp = rate * s
    omega = Signal(
        poly=np.array([[0.0, 0.0, -rate * (1.0 - np.cos(half_angle))]]),
        freqs=np.array([rate]),
        # Re(i A e^{iWt}) = -A sin Wt on x, Re(A e^{iWt}) = A cos Wt on y
        amps=np.array([[1j * amp, amp, 0.0]]),
    )
    return Motion(omega=omega)


def coning_quaternion(half_angle: float, rate: float, t: FloatOrArray) -> np.ndarray:
    """Attitude q_ib(t) = [cos(a/2), sin(a/2) cos(Wt), sin(a/2) sin(Wt), 0] of the coning body."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    c, s = np.cos(half_angle / 2), np.sin(half_angle / 2)
    return np.stack([np.full_like(t, c), s * np.cos(rate * t), s * np.sin(rate * t), np.zeros_like(t)], axis=-1)


def sculling_motion(angle_amp: float, accel_amp: float, rate: float) -> Motion:
    """Sculling: angle theta0 sin(W t) about x and in-phase a_y = a0 sin(W t).

    omega_x = theta0 W cos(W t); the rectified (sculling) acceleration theta0 a0 / 2
    appears along z.
    """
    if not rate > 0.0:
        raise ConfigError("rate", "a positive circular frequency in rad/s", rate)
    omega = Signal(freqs=np.array([rate]), amps=np.array([[angle_amp * rate, 0.0, 0.0]]))
    accel = Signal(freqs=np.array([rate]), amps=np.array([[0.0, -1j * accel_amp, 0.0]]))
    return Motion(omega=omega, accel=accel)


def pseudo_coning(rate_amp: float, freq: float) -> Motion:
    """Two gyro harmonics 90 deg apart (§6): omega_x = -w0 sin(W t), omega_y = w0 cos(W t).

    They look like coning with half-angle w0/W but without the z rate; integrating them
    exactly drifts at eps_pc = w0**2 / (2 W) (6.2) about z.
    """
    if not freq > 0.0:
        raise ConfigError("freq", "a positive circular frequency in rad/s", freq)
    omega = Signal(freqs=np.array([freq]), amps=np.array([[1j * rate_amp, rate_amp, 0.0]]))
    return Motion(omega=omega)


def pseudo_sculling(rate_amp: float, accel_amp: float, freq: float) -> Motion:
    """Gyro x and accelerometer y harmonics 90 deg apart (§6).

    omega_x = w0 cos(W t), a_y = a0 sin(W t): exact integration rectifies them into the
    acceleration dW_ps = w0 a0 / (2 W) (6.1) along z.
    """
    return sculling_motion(rate_amp / freq, accel_amp, freq)


def polynomial_motion(omega_taylor: ArrayLike, accel_taylor: ArrayLike | None = None) -> Motion:
    """General motion by Taylor coefficients at t = 0, arrays (P, 3): omega = A + B t + C t^2/2 + ..."""
    accel = Signal() if accel_taylor is None else Signal(poly=np.asarray(accel_taylor, dtype=float))
    return Motion(omega=Signal(poly=np.asarray(omega_taylor, dtype=float)), accel=accel)
