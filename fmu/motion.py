"""Another tool's co-simulation FMU as the motion source of a navsim scenario.

An external FMU (for example a longitudinal train-dynamics model with a traction input)
is stepped through fmpy at the navigation step; its outputs are mapped to the
along-track state that the core's external motion profile takes (arc length s, speed
ds/dt, acceleration d2s/dt2 at the *end* of each step), which the simulator joins with
quintic Hermite polynomials (:class:`navsim.motion.ExternalMotion`).

Variable mapping (:class:`MotionMapping`)
    ``s = s_offset_m + s_scale * <position variable>``,
    ``speed = s_scale * <speed variable>``,
    ``accel = s_scale * <acceleration variable>``; ``s_scale = -1`` runs the track
    backwards in the FMU's coordinate. The acceleration variable may be omitted
    (``accel=None``): the acceleration is then the backward difference of the speed
    over the step (first order; give the FMU's own acceleration output when it has
    one). ``inputs`` holds constant values for the FMU's inputs or parameters (e.g. a
    traction force or notch), set before initialisation; ``input_schedule`` is an
    optional callable ``(t_s) -> {name: value}`` evaluated at each step start (a driver
    or controller).

Usable from
    * the simulator: :class:`FmuDrivenSimulator` is a :class:`~navsim.simulator.Simulator`
      whose every step first steps the FMU (``reset(seed)`` re-initialises the FMU), so
      ``run_episode(scenario, estimator, seed, simulator=FmuDrivenSimulator(...))`` and
      ``Simulator.step()`` users work unchanged;
    * the CLI: ``navsim fmu run SCENARIO --motion-fmu TRAIN.fmu --motion-map s=x,speed=v,accel=a
      --motion-input F_traction=2e5 --estimator lc-ekf``;
    * the Gymnasium env: build its simulator as an :class:`FmuDrivenSimulator` (or call
      :meth:`FmuMotionSource.step` then ``Simulator.push_motion`` before each step).

The scenario's motion profile is switched to ``"external"``, its ``start_s_m`` and
``speed_mps`` to the FMU's initial state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from navsim.errors import ConfigError
from navsim.motion import ExternalMotion
from navsim.simulator import Chunk, Simulator, Start

from .master import FmuInstance

if TYPE_CHECKING:
    from navsim.scenario import Scenario

InputValue = float | bool | str
"""A value of an FMU input or parameter set by name (a Real / Integer, a Boolean, a String)."""

__all__ = ["MotionMapping", "FmuMotionSource", "FmuDrivenSimulator", "parse_mapping"]


@dataclass(frozen=True, slots=True)
class MotionMapping:
    """How an external FMU's variables give the along-track state (see module docstring).

    position, speed : FMU output names (m, m/s in the FMU's coordinate).
    accel : FMU output name (m/s^2) or None (backward difference of speed).
    s_offset_m, s_scale : affine map to the track's arc length (s_scale is +1 or -1).
    inputs : constant FMU inputs/parameters set before initialisation.
    """

    position: str = "s"
    speed: str = "v"
    accel: str | None = "a"
    s_offset_m: float = 0.0
    s_scale: float = 1.0
    inputs: dict[str, InputValue] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.s_scale not in (1.0, -1.0):
            raise ConfigError("motion_map.s_scale", "+1 or -1", self.s_scale)
        if not math.isfinite(self.s_offset_m):
            raise ConfigError("motion_map.s_offset_m", "a finite arc length, m", self.s_offset_m)


def parse_mapping(text: str, inputs: list[str] | None = None) -> MotionMapping:
    """``"s=x,speed=v,accel=a,offset=100,scale=-1"`` and ``["F=2e5"]`` -> MotionMapping."""
    kw: dict[str, Any] = {}
    for item in filter(None, (p.strip() for p in (text or "").split(","))):
        key, sep, value = item.partition("=")
        if not sep:
            raise ConfigError("--motion-map", "comma-separated key=value items", item)
        name = {"s": "position", "position": "position", "speed": "speed", "accel": "accel",
                "offset": "s_offset_m", "scale": "s_scale"}.get(key.strip())
        if name is None:
            raise ConfigError("--motion-map", "keys s, speed, accel, offset, scale", item)
        if name in ("s_offset_m", "s_scale"):
            try:
                kw[name] = float(value)
            except ValueError:
                raise ConfigError(f"--motion-map {name}", "a number", value) from None
        else:
            kw[name] = None if value.strip().lower() in ("", "none") else value.strip()
    values: dict[str, InputValue] = {}
    for item in inputs or ():
        key, sep, value = item.partition("=")
        if not sep:
            raise ConfigError("--motion-input", "NAME=VALUE", item)
        try:
            values[key.strip()] = float(value)
        except ValueError:
            values[key.strip()] = value.strip().lower() == "true" if value.strip().lower() in ("true", "false") \
                else value
    return MotionMapping(**kw, inputs=values)


class FmuMotionSource:
    """Steps an external co-simulation FMU and gives (s, speed, accel) at step ends.

    Parameters
    ----------
    fmu : path of the FMU (FMI 2 or 3 co-simulation).
    mapping : :class:`MotionMapping`.
    step_s : communication step, s (the navigation step).
    input_schedule : optional ``(t_s) -> {name: value}`` evaluated at each step start.
    """

    def __init__(self, fmu: str | Path, mapping: MotionMapping, step_s: float,
                 input_schedule: Callable[[float], dict[str, Any]] | None = None):
        self.path = Path(fmu)
        self.mapping = mapping
        self.step_s = float(step_s)
        self.schedule = input_schedule
        self.inst = FmuInstance(self.path, "motion")
        names = [mapping.position, mapping.speed] + ([mapping.accel] if mapping.accel else [])
        for name in names + list(mapping.inputs):
            if name not in self.inst.variables:
                raise ConfigError("motion_map", f"a variable of {self.path.name} ({sorted(self.inst.variables)[:12]})", name)
        self._names = names
        self._k = 0
        self._started = False

    def _read(self) -> tuple[float, float, float]:
        values = self.inst.get(self._names)
        m = self.mapping
        s = m.s_offset_m + m.s_scale * float(values[m.position])
        v = m.s_scale * float(values[m.speed])
        a = m.s_scale * float(values[m.accel]) if m.accel else math.nan
        return s, v, a

    def start(self) -> tuple[float, float, float]:
        """(Re-)initialise the FMU; return the initial (s, speed, accel)."""
        if self._started:
            self.inst.terminate()
            self.inst.reset()
        self.inst.initialize(dict(self.mapping.inputs))
        self._started = True
        self._k = 0
        s, v, a = self._read()
        self._last_v = v
        return s, v, (0.0 if math.isnan(a) else a)

    def step(self) -> tuple[float, float, float]:
        """Advance one step; the state at its end."""
        t = self._k * self.step_s
        if self.schedule is not None:
            self.inst.set(self.schedule(t))
        self.inst.do_step(t, self.step_s)
        self._k += 1
        s, v, a = self._read()
        if math.isnan(a):
            a = (v - self._last_v) / self.step_s
        self._last_v = v
        return s, v, a

    def close(self) -> None:
        if self._started:
            try:
                self.inst.terminate()
            except Exception:  # noqa: BLE001 - closing must not fail
                pass
        self.inst.free()


class FmuDrivenSimulator(Simulator):
    """A :class:`~navsim.simulator.Simulator` whose motion comes from an external FMU.

    Built as ``FmuDrivenSimulator(scenario, source)``; ``advance(n)`` steps the FMU n
    times and pushes each end-of-step state before generating; ``reset(seed)`` restarts
    the FMU and starts the episode at its initial state.
    """

    def __init__(self, scenario: Scenario, source: FmuMotionSource):
        if abs(source.step_s - scenario.timing.nav_period_s) > 1e-12:
            raise ConfigError("motion FMU step", f"the navigation step {scenario.timing.nav_period_s} s",
                              source.step_s)
        s0, v0, a0 = source.start()
        self.source = source
        self._a0 = a0
        scenario = scenario.with_overrides({"motion": {"profile": "external", "start_s_m": s0, "speed_mps": v0}})
        super().__init__(scenario)

    def reset(self, seed: int | None = None) -> Start:
        s0, v0, a0 = self.source.start()
        start = super().reset(seed)
        m = self.scenario.motion
        if (s0, v0) != (m.start_s_m, m.speed_mps):
            raise ConfigError("motion FMU", f"the same initial state at every reset ({m.start_s_m}, "
                              f"{m.speed_mps})", (s0, v0))
        if a0 != 0.0:  # the FMU's initial acceleration (Simulator.reset assumes 0)
            assert isinstance(self.profile, ExternalMotion), "the scenario's profile is set to external"
            self.profile.reset(0.0, s0, v0, a0)
            start = Start(truth=self.truth_at([0.0]), prior=start.prior)
        return start

    def advance(self, n_steps: int = 1) -> Chunk:
        k0 = self.step_index
        n = min(int(n_steps), self.timing.steps - k0)
        for k in range(k0, k0 + max(n, 0)):  # the state at the end of step k
            s, v, a = self.source.step()
            self.push_motion(s, v, a, t=(k + 1) * self.timing.nav_period_s)
        return super().advance(n_steps)
