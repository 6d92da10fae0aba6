"""Longitudinal train dynamics: the plant of the driving task.

This is the one piece of physics the Gymnasium face owns, and it is kept here, apart:
it is not navigation physics (the core's truth, sensors and estimators stay untouched)
but the controlled vehicle of a control task. Its output, the arc length, speed and
acceleration at the end of every navigation step, is pushed into the core's external
motion profile (:class:`navsim.motion.ExternalMotion`), from which the simulator makes
the true state and the sensor data as for any other motion. Why not in the core: the
core simulates given motion; choosing how a train responds to a driver's command is a
modelling decision of this task (other tasks would plug in other plants, e.g. an FMU).

Model (per unit of train mass, SI units)
----------------------------------------
The equation of motion along the track, with the Davis resistance and the grade::

    m_eff dv/dt = F_t(u, v) - F_b(u) - (A + B v + C v^2) sign(v) - m g sin(theta(s))     (P.1)
    ds/dt = v                                                                           (P.2)

* command ``u`` in [-1, 1]: ``u > 0`` traction, ``u < 0`` brake;
* traction ``F_t = u min(F_max, P_max / v)`` for u > 0 (force limit at low speed, power
  limit above ``P_max / F_max``);
* brake ``F_b = -u m_eff b_max`` for u < 0 (the brake decelerates at up to ``b_max``);
* ``m_eff = m (1 + rotary)`` the mass with the rotating-mass allowance;
* ``theta(s)`` the track's pitch (the grade), from the map.

The train cannot roll backwards under braking or at rest: when the speed would cross
zero under a non-positive net force it stops (v = 0, a = 0) and stays until traction
exceeds resistance and grade (static friction of the brakes, standard in train models).
The ODE is integrated with the classical Runge-Kutta method at the navigation step.

Default parameters: a 200 t two-car regional train (F_max 160 kN, P_max 1.6 MW,
b_max 1.0 m/s^2, Davis A = 2.0 kN, B = 40 N s/m, C = 6 N s^2/m^2, rotary allowance 6 %),
figures of the order given in [1], chapter 3.

References
----------
.. [1] Brünger O., Dahlhaus E., Running time estimation, in: Hansen I.A., Pachl J.
       (eds.), Railway Timetabling & Operations, Eurailpress 2014, ch. 4 (Davis
       resistance, tractive effort curves, braking).
.. [2] Davis W.J., The tractive resistance of electric locomotives and cars, General
       Electric Review 29, 1926 (the A + B v + C v^2 resistance).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from navsim.errors import ConfigError

__all__ = ["TrainParameters", "TrainPlant"]

G0 = 9.80665


@dataclass(frozen=True, slots=True)
class TrainParameters:
    """Parameters of (P.1) (SI units; see the module docstring)."""

    mass_kg: float = 200_000.0
    rotary_allowance: float = 0.06
    max_traction_n: float = 160_000.0
    max_power_w: float = 1.6e6
    max_brake_decel_mps2: float = 1.0
    davis_a_n: float = 2000.0
    davis_b_n_per_mps: float = 40.0
    davis_c_n_per_mps2: float = 6.0

    def __post_init__(self) -> None:
        for name in ("mass_kg", "max_traction_n", "max_power_w", "max_brake_decel_mps2"):
            value = getattr(self, name)
            if not (value > 0.0 and math.isfinite(value)):
                raise ConfigError(f"train.{name}", "a positive finite number", value)
        for name in ("rotary_allowance", "davis_a_n", "davis_b_n_per_mps", "davis_c_n_per_mps2"):
            value = getattr(self, name)
            if not (value >= 0.0 and math.isfinite(value)):
                raise ConfigError(f"train.{name}", "a non-negative finite number", value)

    @property
    def effective_mass_kg(self) -> float:
        return self.mass_kg * (1.0 + self.rotary_allowance)


class TrainPlant:
    """State (s, v) of a train on a track, advanced under a held command.

    Parameters
    ----------
    sin_grade : callable
        ``sin(theta)`` of the track at an arc length s (float in, float out).
    params : TrainParameters
    grade_table : (values, step_m, end_m), optional
        ``sin(theta)`` tabulated at ``s = 0, step_m, 2 step_m, ..., end_m`` with
        ``sin_grade`` its linear interpolation on ``min(max(s, 0), end_m) / step_m``
        (the driving task's map, :class:`navsim.envs.driving._MapTable`). Given,
        :meth:`advance` interpolates the table inline and reuses the end-of-step force
        evaluation as the next step's first RK4 stage: the same operations on the same
        numbers as the generic path (bit for bit), about 2.5x faster.
    """

    def __init__(self, sin_grade: Callable[[float], float], params: TrainParameters = TrainParameters(),
                 grade_table: tuple[list[float], float, float] | None = None):
        self.sin_grade = sin_grade
        self.p = params
        self.s, self.v, self.a = 0.0, 0.0, 0.0
        self._table: tuple[list[float], float, float, int] | None = None
        if grade_table is not None:
            values, step, end = list(map(float, grade_table[0])), float(grade_table[1]), float(grade_table[2])
            if len(values) < 2 or not (step > 0.0 and math.isfinite(step) and end > 0.0 and math.isfinite(end)):
                raise ConfigError("grade_table", "at least 2 values, a positive finite step and end, m", (step, end))
            self._table = (values, step, end, len(values) - 1)

    def reset(self, s0: float, v0: float = 0.0) -> None:
        self.s, self.v = float(s0), float(v0)
        self.a = self.acceleration(self.s, self.v, 0.0)[0]

    def acceleration(self, s: float, v: float, u: float, at_rest: bool = False) -> tuple[float, float]:
        """(dv/dt, traction power W) of (P.1) at (s, v) under command u.

        ``at_rest``: the train stands (v = 0): brakes and static friction hold it unless
        traction overcomes the starting resistance and the grade (no rolling back).
        """
        p = self.p
        m_eff = p.effective_mass_kg
        if u > 0.0:
            f_t = u * min(p.max_traction_n, p.max_power_w / max(v, 1e-3))
            f_b = 0.0
        else:
            f_t = 0.0
            f_b = -u * m_eff * p.max_brake_decel_mps2
        grade = p.mass_kg * G0 * self.sin_grade(s)
        if at_rest:
            net = f_t - p.davis_a_n - grade
            return (net / m_eff if net > 0.0 else 0.0), 0.0
        resist = p.davis_a_n + p.davis_b_n_per_mps * v + p.davis_c_n_per_mps2 * v * v
        return (f_t - f_b - resist - grade) / m_eff, f_t * v  # (P.1)

    def advance(self, u: float, dt: float, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Hold command u for n steps of dt (RK4 on (P.1)-(P.2)).

        A step in which the speed would cross zero ends at rest where it reaches zero,
        ``s + v^2 / (2 |a|)`` with the step's initial deceleration (exact for constant
        deceleration).

        Returns
        -------
        s, v, a : (n,) the state at the end of each step (m, m/s, m/s^2).
        energy_j : traction energy spent over the n steps, J (trapezoid rule in time).
        """
        if self._table is not None:
            return self._advance_table(u, dt, n)
        u = float(np.clip(u, -1.0, 1.0))
        out_s, out_v, out_a = np.empty(n), np.empty(n), np.empty(n)
        energy = 0.0
        s, v = self.s, self.v
        f = self.acceleration
        a_now = f(s, v, u, at_rest=v <= 0.0)[0]
        for k in range(n):
            rest = v <= 0.0
            a1, p1 = f(s, 0.0 if rest else v, u, at_rest=rest)
            if rest and a1 == 0.0:
                out_s[k], out_v[k], out_a[k] = s, 0.0, 0.0
                a_now = 0.0
                continue
            # (P.1)-(P.2) by RK4: y = (s, v), y' = (v, a(s, v))
            v2 = v + 0.5 * dt * a1
            a2, _ = f(s + 0.5 * dt * v, v2, u)
            v3 = v + 0.5 * dt * a2
            a3, _ = f(s + 0.5 * dt * v2, v3, u)
            v4 = v + dt * a3
            a4, p4 = f(s + dt * v3, v4, u)
            v_new = v + dt / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
            s_new = s + dt / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4)
            if v_new <= 0.0:  # comes to rest within the step (no rolling back)
                s_new = s + 0.5 * v * v / -a1 if (v > 0.0 and a1 < 0.0) else s
                v_new = 0.0
                p4 = 0.0
            energy += 0.5 * dt * (p1 + p4)
            s, v = s_new, v_new
            a_now = f(s, v, u, at_rest=v <= 0.0)[0]
            out_s[k], out_v[k], out_a[k] = s, v, a_now
        self.s, self.v, self.a = s, v, a_now
        return out_s, out_v, out_a, energy

    def _advance_table(self, u: float, dt: float, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """:meth:`advance` with the grade table inline (the same operations in the same order)."""
        assert self._table is not None
        tab, step, s_max, last = self._table
        u = float(np.clip(u, -1.0, 1.0))
        p = self.p
        m_eff = p.effective_mass_kg
        mg = p.mass_kg * G0
        A, B, C = p.davis_a_n, p.davis_b_n_per_mps, p.davis_c_n_per_mps2
        f_max, p_max = p.max_traction_n, p.max_power_w
        traction = u > 0.0
        f_b = 0.0 if traction else -u * m_eff * p.max_brake_decel_mps2

        def sin_grade(s: float) -> float:  # _MapTable.sin_grade
            x = min(max(s, 0.0), s_max) / step
            i = min(int(x), last - 1)
            f = x - i
            return (1.0 - f) * tab[i] + f * tab[i + 1]

        def moving(s: float, v: float) -> tuple[float, float]:  # acceleration(s, v, u)
            f_t = u * min(f_max, p_max / max(v, 1e-3)) if traction else 0.0
            return (f_t - f_b - (A + B * v + C * v * v) - mg * sin_grade(s)) / m_eff, f_t * v

        def at_rest(s: float) -> tuple[float, float]:  # acceleration(s, 0, u, at_rest=True)
            f_t = u * min(f_max, p_max / 1e-3) if traction else 0.0
            net = f_t - A - mg * sin_grade(s)
            return (net / m_eff if net > 0.0 else 0.0), 0.0

        out_s, out_v, out_a = np.empty(n), np.empty(n), np.empty(n)
        energy = 0.0
        s, v = self.s, self.v
        a_cur, p_cur = at_rest(s) if v <= 0.0 else moving(s, v)  # the first step's first stage
        a_now = a_cur
        for k in range(n):
            a1, p1 = a_cur, p_cur
            if v <= 0.0 and a1 == 0.0:
                out_s[k], out_v[k], out_a[k] = s, 0.0, 0.0
                a_now = 0.0
                continue
            v2 = v + 0.5 * dt * a1
            a2 = moving(s + 0.5 * dt * v, v2)[0]
            v3 = v + 0.5 * dt * a2
            a3 = moving(s + 0.5 * dt * v2, v3)[0]
            v4 = v + dt * a3
            a4, p4 = moving(s + dt * v3, v4)
            v_new = v + dt / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
            s_new = s + dt / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4)
            if v_new <= 0.0:
                s_new = s + 0.5 * v * v / -a1 if (v > 0.0 and a1 < 0.0) else s
                v_new = 0.0
                p4 = 0.0
            energy += 0.5 * dt * (p1 + p4)
            s, v = s_new, v_new
            a_cur, p_cur = at_rest(s) if v <= 0.0 else moving(s, v)  # a(t_k+1), and the next step's first stage
            a_now = a_cur
            out_s[k], out_v[k], out_a[k] = s, v, a_now
        self.s, self.v, self.a = s, v, a_now
        return out_s, out_v, out_a, energy
