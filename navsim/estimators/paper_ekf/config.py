"""Options of the seed-003 track-model filter, validated (:class:`PaperEkfConfig`).

The meaning of each option (modes, input model, covariance step, stiffness limit, lever
arm, observer ablation, engines) is given in :mod:`navsim.estimators.paper_ekf`.
"""

from __future__ import annotations

from dataclasses import dataclass

from ...errors import ConfigError
from ...option_checks import check_auto_none, check_choice, check_optional_positive_finite, check_positive_finite
from . import kernel as _kernel

__all__ = ["PaperEkfConfig", "PRINTED_ITEMS"]

PRINTED_ITEMS = frozenset({"kinematics", "centrifugal"})  # printed errors ``as_printed`` may keep


@dataclass(frozen=True, slots=True)
class PaperEkfConfig:
    """Options of :class:`PaperEkf` (validated; see the module docstring).

    mode : "faithful" or "extended".
    as_printed : bool or frozenset of {"kinematics", "centrifugal"}: printed errors kept.
    cov_step_s : covariance (Riccati) step, s; None = the navigation step.
    input_model : "polynomial" or "mean" (inputs inside a step); None = polynomial in
        faithful, mean in extended mode.
    accel_in_update : stack Z_ax into the epoch update (16); None = True in faithful,
        False in extended mode.
    bias_states : "auto" (extended mode: when the nominal IMU has bias sigmas), "on", "off".
    node_step_m : node spacing of the lambda(phi) interpolation of non-polynomial tracks, m.
    stiffness_limit : largest (gain rate x interval) integrated in one RK4 step.
    lever_arm : "auto" (the observables are the antenna's, at ``context.gnss.lever_arm_b_m``)
        or "none" (uncompensated: ranges and Dopplers predicted at the track point, as in
        the paper).
    observer : True (default, the paper's filter) or False: the accelerometer observer
        (13) switched off - between epochs the state follows (7)-(8) open loop with the
        Riccati equation ``R' = A R + R A^T + Q`` (no gain, no Z_ax in (16)); the epoch
        update (16) uses the pseudoranges and Dopplers alone. Everything else identical.
    engine : "auto" (the compiled engine :mod:`navsim.estimators.paper_ekf.kernel` when
        numba is installed, else the reference), "python" (the reference engine, plain
        Python and NumPy) or "compiled" (ConfigError without numba).
    """

    mode: str = "faithful"
    as_printed: frozenset = frozenset()
    cov_step_s: float | None = None
    input_model: str | None = None
    accel_in_update: bool | None = None
    bias_states: str = "auto"
    node_step_m: float = 10.0
    stiffness_limit: float = 0.5
    lever_arm: str = "auto"
    observer: bool = True
    engine: str = "auto"

    def __post_init__(self) -> None:
        check_choice("mode", self.mode, ("faithful", "extended"))
        printed = self.as_printed
        if printed is True:
            printed = PRINTED_ITEMS
        elif printed is False or printed is None:
            printed = frozenset()
        elif isinstance(printed, str):
            printed = frozenset({printed})
        try:
            printed = frozenset(printed)
        except TypeError:
            raise ConfigError("as_printed", f"a bool or a subset of {sorted(PRINTED_ITEMS)}", self.as_printed) from None
        if not printed <= PRINTED_ITEMS:
            raise ConfigError("as_printed", f"a bool or a subset of {sorted(PRINTED_ITEMS)}", self.as_printed)
        if printed and self.mode != "faithful":
            raise ConfigError("as_printed", "only with mode='faithful'", self.as_printed)
        object.__setattr__(self, "as_printed", printed)
        check_optional_positive_finite("cov_step_s", self.cov_step_s, "None or a positive step (s)")
        if self.input_model not in (None, "polynomial", "mean"):
            raise ConfigError("input_model", "None, 'polynomial' or 'mean'", self.input_model)
        if self.accel_in_update not in (None, True, False):
            raise ConfigError("accel_in_update", "None, True or False", self.accel_in_update)
        check_choice("bias_states", self.bias_states, ("auto", "on", "off"))
        check_positive_finite("node_step_m", self.node_step_m, "a positive node spacing (m)")
        stiffness = "a number in (0, 2.5] (RK4 is stable below 2.78)"
        if check_positive_finite("stiffness_limit", self.stiffness_limit, stiffness) > 2.5:
            raise ConfigError("stiffness_limit", stiffness, self.stiffness_limit)
        check_auto_none("lever_arm", self.lever_arm)
        if self.observer not in (True, False):
            raise ConfigError("observer", "True or False", self.observer)
        check_choice("engine", self.engine, ("auto", "python", "compiled"))
        if self.engine == "compiled" and not _kernel.available():
            raise ConfigError("engine", "'auto' or 'python' (the compiled engine needs numba: "
                              "pip install 'navsim-track[fast]')", self.engine)
