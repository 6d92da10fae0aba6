"""Reproduction of the experiments of seed 000 (Litmanovich 2002).

``run(plot_dir=None, quick=False)`` returns rows
``{"ref": "000 (2.12)", "quantity": ..., "paper": number | None, "navsim": number,
"unit": ...}`` and, with ``plot_dir``, writes one PNG per experiment:

``000_coning_drift.png``
    Pure coning (exact closed-form increments, half-cone angle 0.01 rad): computational
    drift eps (the cone-axis component of Phi_alg - Phi_exact, divided by DeltaT, as the
    paper defines it after (2.11)) against W*DeltaT for every coning algorithm; the
    fitted leading coefficient of eps/(alpha^2 W/2) = c (W DeltaT)^p beside (2.12),
    (2.13), (3.11), (4.14).
``000_sculling_error.png``
    Sculling (angle theta0 sin(Wt) about x, in-phase a_y = a0 sin(Wt)): the mean
    acceleration error dW against W*DeltaT, against (2.6), (2.7), (3.10), (4.11), (4.12).
``000_local_error.png``
    General multi-harmonic motion: local error |alg - exact| against DeltaT (exact by
    Gauss-Legendre quadrature of (1.12)/(1.8)/(5.4)), fitted log-log slopes against the
    orders of (2.5), (2.11), (3.8), (3.9), (4.9), (4.10), (4.13), and the ratio of the
    measured error to the printed expression (extrapolated to DeltaT -> 0).
``000_position.png``
    Final position error after 2 s with exact V_i(k), C(k) and ideal increments: (5.1)
    rectangle and trapezoid against the exact form (5.2) with the constant, smoothing and
    invariant partial increments, for linear vibration with and without rotation.
``000_fig1_pseudo_sculling_constant.png``, ``000_fig2_pseudo_sculling_linear.png``,
``000_fig3_pseudo_coning.png``
    Section 6: relative acceleration error dW/dW_ps (6.1) and relative drift eps/eps_pc
    (6.2) against the relative frequency f_h/f of the sensor harmonic (transposed
    frequency 0.3 f for sculling, 0.4 f for coning), full navigation integration.

Findings (numbers from ``run()``; see also the module tests)
------------------------------------------------------------
* Coning and sculling coefficients: every printed test-motion error, (2.6), (2.7),
  (2.12), (2.13), (3.10), (3.11), (4.11), (4.12), (4.14), is reproduced within 1 %
  (two-sample sculling (2.6) only with the corrected coefficient 2/3 in (2.3)).
* Local errors: the orders of (2.5), (2.11), (3.8), (3.9), (4.9), (4.10), (4.13) are
  reproduced (fitted slopes 5.0, 5.0, 5.0, 7.0, 5.0, 5.0, 7.0). Magnitudes of (2.5),
  (2.11), (3.8), (3.9), (4.13) agree; the coning expressions are printed as
  exact - computed, the sculling ones as computed - exact. (4.9) and (4.10) are printed
  with DeltaT^5/1440 but the measured coefficient is DeltaT^5/720 (and (4.10) has the
  opposite sign, -B_w x C_a); 1/720 is also the only value consistent with the paper's
  own (4.11): for sculling motion the mean of C_w x B_a is -theta0 a0 W^4/2, and
  1/720 * T^5 * theta0 a0 W^4/2 / T = (theta0 a0/2)(W T)^4/720 = (4.11).
* The general-motion error quoted for the coning-optimized (2.10) after (2.13),
  DeltaT^4/120 (A x C), is not reproduced: changing X, Y from (33/80, 57/80) to
  (9/20, 27/40) adds 3/80 (DT1 x DT3 - DT2 x DT3 + DT2 x DT1), whose A x C part is
  exactly zero for equal sub-intervals (the weights 1, 7, 19 of C in DT1..3 cancel:
  18 - 12 - 6 = 0). The measured leading error is -DeltaT^5/6480 (A x D + B x C): same
  order as the unoptimized algorithm, with an extra B x C term, which is why the
  optimized algorithm is worse in general motion but not by an order.
* (5.2) with ideal increments: for pure linear vibration its error is round-off
  (~1e-15 m) at every step, while the rectangle rule's error grows with DeltaT; with an
  added rotation the exact form's error comes only from the partial increment
  algorithm and is orders of magnitude below (5.1).
* Section 6 (pseudo-coning/sculling; full navigation integration, normalised by (6.1),
  (6.2); exact integration gives 1 at every f_h/f). At f_h/f = 100.3 the relative
  pseudo-sculling error is 1.5e-3 for (2.4) (= the constant-model smoothing algorithm)
  against 6.6e-6 for (4.5)/(4.7); for linear models 2.9e-3 (2.3), 1.5e-3 (3.6),
  1.7e-5 (4.4)/(4.6). Relative pseudo-coning drift at f_h/f = 100.4: 2.5e-3 (2.10),
  2.2e-3 (optimized (2.10)), 9.4e-4 (3.7), 5.8e-5 (4.8). Traditional and smoothing
  curves fall roughly as (f_h/f)^-1, invariant ones as (f_h/f)^-2. So the paper's
  conclusion (new algorithms attenuate better, invariant best, its advantage growing with
  frequency) holds for the geometric mean over f_h/f >= 1 and at high f_h/f, but not at
  every frequency: near f_h/f = 1.3-2.4 the quadratic invariant coning algorithm (4.8)
  (0.31 at 1.4) is worse than both the traditional (2.10) (0.18) and (3.7)
  (0.07), and (4.4)/(4.6) (0.067 at 1.3) are worse than (3.6) (0.038).

References
----------
.. [000] Litmanovich Yu.A., "Determination of the parameters of angular and translational
   motion of a rigid body from inertial information in the form of increments of
   multiple integrals of the measured quantities", Izv. RAN, 2002 (seed 000).
"""

from __future__ import annotations

import os
from typing import Any, Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..rotations import quat_from_rotvec, quat_multiply, quat_to_rotvec
from ..strapdown import CONING, POSITION, SCULLING
from ..strapdown.coning import CONING_INPUTS
from ..strapdown.motion_models import (
    Motion,
    Signal,
    coning_motion,
    pseudo_coning,
    pseudo_sculling,
    sculling_motion,
)
from ..strapdown.position import (
    partial_increment_constant,
    partial_increment_invariant,
    partial_increment_smoothing,
)
from ..strapdown.sculling import SCULLING_INPUTS
from ..types import FloatOrArray

__all__ = [
    "CONING_PAPER",
    "SCULLING_PAPER",
    "coning_drift",
    "sculling_error",
    "fit_leading",
    "general_motion",
    "local_errors",
    "local_error_fit",
    "position_errors",
    "pseudo_sculling_error",
    "pseudo_coning_drift",
    "pseudo_summary",
    "run",
]

HALF_ANGLE = 0.01  # rad, coning test motion
SCULL_ANGLE = 0.01  # rad, sculling angle amplitude
SCULL_ACCEL = 1.0  # m/s^2
RATE = 2.0 * np.pi  # rad/s; results are functions of W*DeltaT only

#: (reference, algorithm, paper order p, paper coefficient c): eps/(alpha^2 W/2) = c (W T)^p
CONING_PAPER: list[tuple[str, str, int, float | None]] = [
    ("000 (1.11)", "one-sample", 2, None),
    ("000 [9]", "two-sample", 4, None),
    ("000 (2.12)", "three-sample", 4, 1.0 / 3240.0),
    ("000 (2.13)", "three-sample-optimized", 6, 1.0 / 102060.0),
    ("000 (3.7)", "smoothing-linear", 4, None),
    ("000 (3.11)", "smoothing", 6, 1.0 / 50400.0),
    ("000 (4.3)", "invariant-constant", 2, None),
    ("000 (4.3)", "invariant-linear", 4, None),
    ("000 (4.14)", "invariant", 6, 1.0 / 100800.0),
]

#: dW/(theta0 a0/2) = c (W T)^p
SCULLING_PAPER: list[tuple[str, str, int, float]] = [
    ("000 (2.7)", "first-order", 2, 1.0 / 6.0),
    ("000 (2.6)", "two-sample", 4, 3.0 / 1440.0),
    ("000 (3.10)", "smoothing", 4, 4.0 / 1440.0),
    ("000 (4.11)", "invariant-4.4", 4, 1.0 / 720.0),
    ("000 (4.11)", "invariant-4.6", 4, 1.0 / 720.0),
    ("000 (4.12)", "invariant-4.5", 2, 1.0 / 12.0),
    ("000 (4.12)", "invariant-4.7", 2, 1.0 / 12.0),
]

_X_VALUES = np.array([0.8, 0.6, 0.45, 0.35, 0.25, 0.18])


# -------------------------------------------------------------------------- helpers
def _coning_inputs(name: str, motion: Motion, t_start: FloatOrArray,
                   dt: float) -> tuple[np.ndarray | None, np.ndarray | None]:
    source, count = CONING_INPUTS[name]
    if source == "sub":
        return motion.omega.sub_increments(t_start, dt, count), None
    return None, motion.omega.multiple_integrals(t_start, dt, max(count, 1))


def _sculling_inputs(name: str, motion: Motion, t_start: FloatOrArray, dt: float) -> tuple[
        np.ndarray | None, np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    spec = SCULLING_INPUTS[name]
    if "sub" in spec:
        th, dv = motion.sub_increments(t_start, dt, spec["sub"])
        return th, dv, None, None
    order = max(spec["dtheta_r"], spec["dv_r"])
    th, dv = motion.increments(t_start, dt, order)
    return None, None, th, dv


def fit_leading(x: np.ndarray, y: np.ndarray, order: int | None = None) -> tuple[float, float]:
    """Fit y = c x^p (1 + b x^2 + d x^4) for small x.

    Returns (slope, c): slope is the least-squares log-log slope over the three smallest
    x; c the leading coefficient with p = ``order`` (or the rounded slope).
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    idx = np.argsort(x)[:3]
    slope = float(np.polyfit(np.log(x[idx]), np.log(np.abs(y[idx])), 1)[0])
    p = int(round(slope)) if order is None else order
    design = np.stack([np.ones_like(x), x**2, x**4], axis=1)
    coef = np.linalg.lstsq(design, y / x**p, rcond=None)[0]
    return slope, float(coef[0])


# ------------------------------------------------------------------ coning and sculling
def coning_drift(name: str, x_values: np.ndarray = _X_VALUES, half_angle: float = HALF_ANGLE) -> np.ndarray:
    """Relative computational drift eps / (sin(alpha)^2 W / 2) at W*DeltaT = x_values.

    eps = (Phi_alg - Phi_exact)_z / DeltaT, z = cone axis; Phi_exact = DeltaTheta +
    (1.12) by quadrature. Signed (negative: the algorithm under-compensates).
    """
    motion = coning_motion(half_angle, RATE)
    norm = np.sin(half_angle) ** 2 * RATE / 2.0
    out = []
    for x in np.atleast_1d(x_values):
        dt = x / RATE
        t0 = np.array([0.123])
        sub, multi = _coning_inputs(name, motion, t0, dt)
        error = CONING[name](sub, multi, dt) - motion.exact_rotation_vector(t0, dt)
        out.append(error[0, 2] / dt / norm)
    return np.array(out)


def sculling_error(name: str, x_values: np.ndarray = _X_VALUES) -> np.ndarray:
    """Relative mean acceleration error dW / (theta0 a0 / 2) at W*DeltaT = x_values.

    dW = mean over the phase of t_k of (bracket_alg - bracket_exact)_z / DeltaT; the
    phase dependence is a second harmonic, so 8 equally spaced phases give the exact mean.
    """
    motion = sculling_motion(SCULL_ANGLE, SCULL_ACCEL, RATE)
    norm = SCULL_ANGLE * SCULL_ACCEL / 2.0
    t0 = np.arange(8) / 8.0 * (2.0 * np.pi / RATE)
    out = []
    for x in np.atleast_1d(x_values):
        dt = x / RATE
        inputs = _sculling_inputs(name, motion, t0, dt)
        error = SCULLING[name](*inputs, dt) - motion.exact_velocity_bracket(t0, dt)
        out.append(error[:, 2].mean() / dt / norm)
    return np.array(out)


# ------------------------------------------------------------------------ local errors
def general_motion() -> Motion:
    """A fixed multi-harmonic motion with all derivatives non-zero (rad/s, m/s^2)."""
    omega = Signal(
        poly=np.array([[0.3, -0.2, 0.1]]),
        freqs=np.array([1.1, 1.7, 2.3]),
        amps=np.array(
            [
                [1.5 * np.exp(-1.37j), 0.0, 0.6 * np.exp(0.3j)],
                [0.3, 1.2 * np.exp(0.8j), 0.9j],
                [0.15 * np.exp(2.0j), 0.75, 1.8 * np.exp(-0.57j)],
            ]
        ),
    )
    accel = Signal(
        poly=np.array([[0.5, -1.0, 9.8]]),
        freqs=np.array([0.9, 2.6]),
        amps=np.array([[1.0 * np.exp(0.4j), 0.7, 0.2j], [0.3, 0.5 * np.exp(1.1j), 0.8 * np.exp(-2.0j)]]),
    )
    return Motion(omega=omega, accel=accel)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.cross(a, b)


def _printed_local_error(ref: str, motion: Motion, t0: FloatOrArray, dt: float) -> np.ndarray:
    """The printed local-error expressions evaluated with the motion's derivatives at t0."""
    w = [motion.omega.derivative(t0, k) for k in range(4)]  # A, B, C, D of omega
    a = [motion.accel.derivative(t0, k) for k in range(4)]
    if ref == "(2.11)":
        return dt**5 / 6480.0 * _cross(w[0], w[3])
    if ref == "after (2.13)":
        return dt**4 / 120.0 * _cross(w[0], w[2])
    if ref == "(3.9)":
        return dt**7 / 100800.0 * _cross(w[2], w[3])
    if ref == "(4.13)":
        return dt**7 / 201600.0 * _cross(w[2], w[3])
    if ref == "(2.5)":
        return dt**5 / 720.0 * (
            _cross(w[2], a[1]) - _cross(w[1], a[2]) + 0.25 * _cross(w[3], a[0]) - 0.25 * _cross(w[0], a[3])
        )
    if ref == "(3.8)":
        return dt**5 / 720.0 * (_cross(w[2], a[1]) - _cross(w[1], a[2]))
    if ref == "(4.9)":
        return dt**5 / 1440.0 * _cross(w[2], a[1])
    if ref == "(4.10)":
        return dt**5 / 1440.0 * _cross(w[1], a[2])
    raise KeyError(ref)


#: (printed reference, kind, algorithm, printed order of the local error)
LOCAL_ERROR_CASES: list[tuple[str, str, str, int]] = [
    ("(2.11)", "coning", "three-sample", 5),
    ("after (2.13)", "coning", "three-sample-optimized", 4),
    ("(3.9)", "coning", "smoothing", 7),
    ("(4.13)", "coning", "invariant", 7),
    ("(2.5)", "sculling", "two-sample", 5),
    ("(3.8)", "sculling", "smoothing", 5),
    ("(4.9)", "sculling", "invariant-4.4", 5),
    ("(4.10)", "sculling", "invariant-4.6", 5),
]

_STEPS = np.array([0.2, 0.1, 0.05, 0.025, 0.0125])
# DeltaT^7 errors reach round-off (~1e-17 rad) below 0.05 s for this motion
_STEPS_HIGH = np.array([0.4, 0.2, 0.1, 0.05])


def local_errors(kind: str, name: str, steps: ArrayLike = _STEPS, motion: Motion | None = None,
                 t_start: float = 0.37) -> np.ndarray:
    """Local error (alg - exact) vectors at t_start for each step: (len(steps), 3).

    kind is "coning", "sculling" or "position" (the partial increment dS_s of (5.4);
    name "exact", "exact-smoothing" or "exact-invariant").
    """
    motion = general_motion() if motion is None else motion
    t0 = np.array([t_start])
    out = []
    for dt in np.atleast_1d(steps):
        if kind == "coning":
            sub, multi = _coning_inputs(name, motion, t0, dt)
            err = CONING[name](sub, multi, dt) - motion.exact_rotation_vector(t0, dt)
        elif kind == "sculling":
            inputs = _sculling_inputs(name, motion, t0, dt)
            err = SCULLING[name](*inputs, dt) - motion.exact_velocity_bracket(t0, dt)
        elif kind == "position":
            partial = {
                "exact": partial_increment_constant,
                "exact-smoothing": partial_increment_smoothing,
                "exact-invariant": partial_increment_invariant,
            }[name]
            th, dv = motion.increments(t0, dt, 4)
            err = partial(th, dv, dt) - motion.exact_partial_displacement(t0, dt)
        else:
            raise KeyError(kind)
        out.append(err[0])
    return np.array(out)


def local_error_fit(ref: str, kind: str, name: str, order: int, motion: Motion | None = None) -> dict:
    """Local error of one algorithm on :func:`general_motion` against a printed expression.

    Returns a dict with ``steps``, ``norms`` (|alg - exact|), ``slope`` (log-log over
    the three smallest steps) and ``ratio``: the projection of the measured error
    (alg - exact) on the printed expression, divided by the printed expression,
    extrapolated linearly to DeltaT -> 0 from the two smallest steps.
    """
    motion = general_motion() if motion is None else motion
    t0 = np.array([0.37])
    steps = _STEPS_HIGH if order == 7 else _STEPS
    errors = local_errors(kind, name, steps, motion)
    norms = np.linalg.norm(errors, axis=1)
    slope = float(np.polyfit(np.log(steps[-3:]), np.log(norms[-3:]), 1)[0])
    printed = np.array([_printed_local_error(ref, motion, t0, dt)[0] for dt in steps])
    ratio = np.einsum("ij,ij->i", errors, printed) / np.einsum("ij,ij->i", printed, printed)
    ratio0 = float(ratio[-1] + (ratio[-1] - ratio[-2]) * steps[-1] / (steps[-2] - steps[-1]))
    return {"ref": ref, "kind": kind, "name": name, "order": order, "slope": slope, "ratio": ratio0,
            "steps": steps, "norms": norms}


def _local_error_study() -> list[dict]:
    motion = general_motion()
    results = [local_error_fit(ref, kind, name, order, motion) for ref, kind, name, order in LOCAL_ERROR_CASES]
    steps = _STEPS
    for name in ("exact", "exact-smoothing", "exact-invariant"):
        errors = local_errors("position", name, steps, motion)
        norms = np.linalg.norm(errors, axis=1)
        slope = float(np.polyfit(np.log(steps[-3:]), np.log(norms[-3:]), 1)[0])
        results.append({"ref": "(5.4)", "kind": "position", "name": name, "order": None, "slope": slope,
                        "ratio": None, "steps": steps, "norms": norms})
    return results


# ---------------------------------------------------------------------------- position
def _rot_x(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    zero, one = np.zeros_like(angle), np.ones_like(angle)
    return np.stack(
        [np.stack([one, zero, zero], -1), np.stack([zero, c, -s], -1), np.stack([zero, s, c], -1)], -2
    )


def position_motion(rotating: bool) -> Motion:
    """Linear vibration (13.7 Hz) on a constant specific force, optionally with a 0.5 Hz roll
    oscillation theta(t) = 0.05 sin(pi t) about x (single axis, so C_ib = R_x(theta))."""
    vib = 2.0 * np.pi * 13.7  # not a whole number of periods in 2 s
    accel = Signal(
        poly=np.array([[0.1, 0.5, 0.0]]),
        freqs=np.array([vib]),
        amps=np.array([[0.0, 2.0 * np.exp(-1.27j), 0.3]]),
    )
    roll = np.pi
    amp = 0.05 * roll if rotating else 0.0
    omega = Signal(freqs=np.array([roll]), amps=np.array([[amp, 0.0, 0.0]]))
    return Motion(omega=omega, accel=accel)


def position_errors(motion: Motion, steps: Iterable[float], duration: float = 2.0,
                    methods: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """Norm of the final position error after ``duration`` for each method and step.

    The inputs V_i(k) and C(k) are exact (closed-form attitude, velocity by quadrature),
    so the error is that of the position algorithm alone. Truth: per step
    ``V_k T + int (t_k+1 - t) C(t) a(t) dt`` by composite Gauss-Legendre quadrature.
    """
    methods = list(POSITION) if methods is None else methods
    velocity0 = np.array([1.0, 20.0, 0.0])
    out: dict[str, list[float]] = {m: [] for m in methods}
    x_gl, w_gl = np.polynomial.legendre.leggauss(24)
    for dt in steps:
        k = int(round(duration / dt))
        t_k = np.arange(k) * dt
        panels = max(1, int(np.ceil(motion.accel.max_freq * dt / 1.5)))
        edges = np.linspace(0.0, dt, panels + 1)
        half = 0.5 * np.diff(edges)
        tau = ((0.5 * (edges[1:] + edges[:-1]))[:, None] + half[:, None] * x_gl).ravel()
        weight = (half[:, None] * w_gl).ravel()
        times = (t_k[:, None] + tau).ravel()
        angle = motion.omega.integral(np.zeros_like(times), times)[:, 0]
        force_i = np.einsum("nij,nj->ni", _rot_x(angle), motion.accel.value(times)).reshape(k, tau.size, 3)
        dv_exact = np.einsum("k,nkj->nj", weight, force_i)
        ds_exact = np.einsum("k,nkj->nj", weight * (dt - tau), force_i)
        velocity = velocity0 + np.concatenate([np.zeros((1, 3)), np.cumsum(dv_exact, axis=0)[:-1]])
        truth = np.sum(velocity * dt + ds_exact, axis=0)
        mat = _rot_x(motion.omega.integral(np.zeros(k), t_k)[:, 0])
        th_r, dv_r = motion.increments(t_k, dt, 4)
        th_s, dv_s = motion.sub_increments(t_k, dt, 2)
        for m in methods:
            disp = POSITION[m](velocity, mat, th_s, dv_s, th_r, dv_r, dt)
            out[m].append(float(np.linalg.norm(disp.sum(axis=0) - truth)))
    return {m: np.array(v) for m, v in out.items()}


# ------------------------------------------------------------------------- section 6
PSEUDO_SCULLING_CONSTANT = ["first-order", "invariant-4.5", "invariant-4.7"]
PSEUDO_SCULLING_LINEAR = ["two-sample", "smoothing", "invariant-4.4", "invariant-4.6"]
PSEUDO_CONING = ["one-sample", "two-sample", "three-sample", "three-sample-optimized",
                 "smoothing-linear", "smoothing", "invariant-linear", "invariant"]
CLASS_OF = {
    "first-order": "traditional = smoothing (2.4)",
    "two-sample": "traditional", "three-sample": "traditional",
    "three-sample-optimized": "traditional", "one-sample": "traditional",
    "smoothing": "smoothing", "smoothing-linear": "smoothing",
    "invariant-4.4": "invariant", "invariant-4.5": "invariant", "invariant-4.6": "invariant",
    "invariant-4.7": "invariant", "invariant": "invariant", "invariant-linear": "invariant",
}


def pseudo_sculling_error(name: str, fbar: np.ndarray, transposed: float = 0.3, theta0: float = 1e-3) -> np.ndarray:
    """Relative systematic acceleration error dW / dW_ps (6.1) at relative frequencies fbar.

    Full navigation integration at f = 1 Hz (DeltaT = 1 s) of the harmonics
    omega_x = w0 cos(w_h t), a_y = a0 sin(w_h t) (w0 = theta0 w_h, a0 = 1):
    V(k+1) = V(k) + C(k)(DeltaV + dV_s), C(k) = R_x(theta(t_k)) exactly (single axis).
    fbar must be n + transposed; the step phases then repeat with a period of
    1/gcd steps (10 for 0.3), over which the mean is exact. ``name = "exact"`` uses the
    exact (1.8).
    """
    period = int(round(1.0 / (np.gcd(int(round(transposed * 10)), 10) / 10.0)))
    out = []
    for fb in np.atleast_1d(fbar):
        freq = 2.0 * np.pi * fb
        motion = pseudo_sculling(theta0 * freq, 1.0, freq)
        t_k = np.arange(period, dtype=float)
        if name == "exact":
            bracket = motion.exact_velocity_bracket(t_k, 1.0)
        else:
            bracket = SCULLING[name](*_sculling_inputs(name, motion, t_k, 1.0), 1.0)
        theta = motion.omega.integral(np.zeros(period), t_k)[:, 0]
        dv_z = np.sin(theta) * bracket[:, 1] + np.cos(theta) * bracket[:, 2]
        out.append(dv_z.mean() / (theta0 * 1.0 / 2.0))  # (6.1) dW_ps = w0 a0 / (2 w_h)
    return np.array(out)


def pseudo_coning_drift(name: str, fbar: np.ndarray, transposed: float = 0.4, alpha: float = 1e-4) -> np.ndarray:
    """Relative drift eps / eps_pc (6.2) at relative frequencies fbar (= n + transposed).

    Gyro harmonics omega_x = -w0 sin(w_h t), omega_y = w0 cos(w_h t), w0 = alpha w_h,
    f = 1 Hz; the attitude is q(k+1) = q(k) * q(Phi_k) with Phi_k from the algorithm;
    Phi_k repeats with the period P of the transposed frequency (5 steps for 0.4), so
    the drift is rotvec(q(Phi_0) ... q(Phi_P-1))_z / P. ``name = "exact"`` uses the
    exact (1.11).
    """
    period = int(round(10 / np.gcd(int(round(transposed * 10)), 10)))
    out = []
    for fb in np.atleast_1d(fbar):
        freq = 2.0 * np.pi * fb
        motion = pseudo_coning(alpha * freq, freq)
        t_k = np.arange(period, dtype=float)
        if name == "exact":
            phi = motion.exact_rotation_vector(t_k, 1.0)
        else:
            sub, multi = _coning_inputs(name, motion, t_k, 1.0)
            phi = CONING[name](sub, multi, 1.0)
        quat = np.array([1.0, 0.0, 0.0, 0.0])
        for row in quat_from_rotvec(phi):
            quat = quat_multiply(quat, row)
        drift = quat_to_rotvec(quat)[2] / period
        out.append(drift / (alpha**2 * freq / 2.0))  # (6.2) eps_pc = w0^2 / (2 w_h)
    return np.array(out)


def _fbar_grid(transposed: float, quick: bool) -> np.ndarray:
    n = np.unique(np.round(np.logspace(0, 2 if not quick else 1.5, 12 if quick else 30)).astype(int))
    return np.concatenate([[0.0], n]) + transposed


def pseudo_summary(quick: bool = False) -> dict:
    """Relative errors of section 6 for every algorithm, on the fbar grids."""
    fs = _fbar_grid(0.3, quick)
    fc = _fbar_grid(0.4, quick)
    sculling = {n: pseudo_sculling_error(n, fs) for n in ["exact"] + PSEUDO_SCULLING_CONSTANT + PSEUDO_SCULLING_LINEAR}
    coning = {n: pseudo_coning_drift(n, fc) for n in ["exact"] + PSEUDO_CONING}
    return {"fbar_sculling": fs, "sculling": sculling, "fbar_coning": fc, "coning": coning}


def _log_mean(values: np.ndarray) -> float:
    """Geometric mean of |values| (the level of a curve on the paper's log plots)."""
    return float(np.exp(np.mean(np.log(np.abs(values) + 1e-300))))


# -------------------------------------------------------------------------------- run
def run(plot_dir: str | None = None, quick: bool = False) -> list[dict]:
    """Reproduce the experiments of seed 000; see the module docstring."""
    rows: list[dict] = []

    curves_of: dict[str, dict[str, np.ndarray]] = {}  # the coning and sculling curves, for the plots
    for what, scale, table, error in (("coning drift", "|eps|/(alpha^2 W/2)", CONING_PAPER, coning_drift),
                                      ("sculling error", "|dW|/(theta0 a0/2)", SCULLING_PAPER, sculling_error)):
        curves = curves_of[what] = {name: error(name) for _, name, _, _ in table}
        for ref, name, order, paper in table:
            slope, coef = fit_leading(_X_VALUES, curves[name], order)
            rows.append({"ref": ref, "quantity": f"{what} order in W*dT, {name}", "paper": order,
                         "navsim": slope, "unit": "-"})
            rows.append({"ref": ref, "quantity": f"{what} coefficient {scale}/(W dT)^{order}, {name}",
                         "paper": paper, "navsim": abs(coef), "unit": "-"})

    local = _local_error_study()
    for item in local:
        label = f"{item['kind']} {item['name']}"
        rows.append({"ref": "000 " + item["ref"], "quantity": f"local error order (log-log slope), {label}",
                     "paper": item["order"], "navsim": item["slope"], "unit": "-"})
        if item["ratio"] is not None:
            rows.append({"ref": "000 " + item["ref"],
                         "quantity": f"local error (alg - exact) / printed expression, dT->0, {label}",
                         "paper": 1.0, "navsim": item["ratio"], "unit": "-"})

    steps = np.array([0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1])
    if quick:
        steps = np.array([0.002, 0.01, 0.05, 0.1])
    position = {rot: position_errors(position_motion(rot), steps) for rot in (False, True)}
    for rot, errs in position.items():
        case = "vibration + roll" if rot else "pure linear vibration"
        for method, values in errs.items():
            for i in (0, len(steps) - 1):
                rows.append({"ref": "000 (5.1)" if method in ("rectangle", "trapezoid") else "000 (5.2)",
                             "quantity": f"position error after 2 s, {method}, {case}, dT={steps[i]:g} s",
                             "paper": None, "navsim": float(values[i]), "unit": "m"})

    pseudo = pseudo_summary(quick)
    for key, names, ref in (("sculling", PSEUDO_SCULLING_CONSTANT, "000 Fig. 1"),
                            ("sculling", PSEUDO_SCULLING_LINEAR, "000 Fig. 2"),
                            ("coning", PSEUDO_CONING, "000 Fig. 3")):
        grid = pseudo["fbar_" + key]
        quantity = "relative acceleration error dW/dW_ps" if key == "sculling" else "relative drift eps/eps_pc"
        for name in names:
            values = pseudo[key][name]
            for fb in (grid[0], grid[1], grid[len(grid) // 2], grid[-1]):
                j = int(np.argmin(np.abs(grid - fb)))
                rows.append({"ref": ref, "quantity": f"{quantity}, {name} ({CLASS_OF[name]}), f_h/f={grid[j]:g}",
                             "paper": None, "navsim": float(abs(values[j])), "unit": "-"})
            rows.append({"ref": ref, "quantity": f"{quantity}, {name}, geometric mean over f_h/f>=1",
                         "paper": None, "navsim": _log_mean(values[grid > 1.0]), "unit": "-"})
        rows.append({"ref": ref, "quantity": f"{quantity}, exact integration (check: 1), f_h/f={grid[-1]:g}",
                     "paper": 1.0, "navsim": float(pseudo[key]["exact"][-1]), "unit": "-"})

    if plot_dir is not None:
        _plots(plot_dir, curves_of["coning drift"], curves_of["sculling error"], local, steps, position, pseudo)
    return rows


def _plots(plot_dir: str, coning: dict[str, np.ndarray], sculling: dict[str, np.ndarray], local: list[dict],
           steps: np.ndarray, position: dict[bool, dict[str, np.ndarray]], pseudo: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(plot_dir, exist_ok=True)

    def save(fig: Any, name: str) -> None:
        fig.tight_layout()
        from ..io import save_figure

        save_figure(fig, os.path.join(plot_dir, name), dpi=110)
        plt.close(fig)

    for title, data, table, fname, ylabel in (
        ("Pure coning: computational drift", coning, CONING_PAPER, "000_coning_drift.png",
         "|eps| / (alpha^2 W / 2)"),
        ("Sculling: acceleration error", sculling, SCULLING_PAPER, "000_sculling_error.png",
         "|dW| / (theta0 a0 / 2)"),
    ):
        fig, ax = plt.subplots(figsize=(7, 5))
        for ref, name, order, paper in table:
            line = ax.loglog(_X_VALUES, np.abs(data[name]), "o-", label=f"{name} {ref}")[0]
            if paper is not None:
                ax.loglog(_X_VALUES, paper * _X_VALUES**order, "--", color=line.get_color(), lw=0.8)
        ax.set_xlabel("W * DeltaT (rad)")
        ax.set_ylabel(ylabel)
        ax.set_title(title + " (dashed: paper)")
        ax.legend(fontsize=7)
        save(fig, fname)

    fig, ax = plt.subplots(figsize=(7, 5))
    for item in local:
        ax.loglog(item["steps"], item["norms"], "o-", label=f"{item['kind']} {item['name']} {item['ref']}: "
                  f"slope {item['slope']:.2f}")
    ax.set_xlabel("DeltaT (s)")
    ax.set_ylabel("|local error|")
    ax.set_title("General motion: local error vs step")
    ax.legend(fontsize=6)
    save(fig, "000_local_error.png")

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), sharey=True)
    for ax, (rot, errs) in zip(axes, position.items()):
        for method, values in errs.items():
            ax.loglog(steps, np.maximum(values, 1e-17), "o-", label=method)
        ax.set_title("vibration + roll" if rot else "pure linear vibration")
        ax.set_xlabel("DeltaT (s)")
    axes[0].set_ylabel("position error after 2 s (m)")
    axes[0].legend(fontsize=8)
    save(fig, "000_position.png")

    for key, names, fname, ylabel in (
        ("sculling", PSEUDO_SCULLING_CONSTANT, "000_fig1_pseudo_sculling_constant.png", "dW / dW_ps"),
        ("sculling", PSEUDO_SCULLING_LINEAR, "000_fig2_pseudo_sculling_linear.png", "dW / dW_ps"),
        ("coning", PSEUDO_CONING, "000_fig3_pseudo_coning.png", "eps / eps_pc"),
    ):
        grid = pseudo["fbar_" + key]
        fig, ax = plt.subplots(figsize=(7, 5))
        for name in ["exact"] + names:
            ax.loglog(grid, np.maximum(np.abs(pseudo[key][name]), 1e-18), "o-" if name != "exact" else "k:",
                      ms=3, label=f"{name} ({CLASS_OF.get(name, 'reference')})")
        ax.set_xlabel("f_h / f")
        ax.set_ylabel("|" + ylabel + "|")
        ax.set_title(f"Pseudo-{key} (transposed f_h = {grid[0]:g} f)")
        ax.legend(fontsize=7)
        save(fig, fname)
