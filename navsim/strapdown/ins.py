"""Free-inertial navigation in the local-level (ENU) frame on any :class:`EarthModel`.

One mechanisation serves both Earths: the navigation equations of seed 003 eq. (1) on the
spherical Earth (:data:`navsim.earth.SPHERICAL`) and the usual WGS-84 local-level
mechanisation (:data:`navsim.earth.WGS84`, normal gravity, meridian and prime-vertical
radii). In ENU components,

    q_nb'      = 1/2 q_nb o omega_ib_b - 1/2 omega_in_n o q_nb,  omega_in = omega_ie + omega_en
    velocity'  = mat_nb f_b - (2 omega_ie_n + omega_en_n) x velocity + g_n
    lat' = v_N / (R_N + h),   lon' = v_E / ((R_E + h) cos lat),   h' = v_U

with ``omega_ie_n = Omega [0, cos lat, sin lat]``,
``omega_en_n = [-v_N/(R_N+h), v_E/(R_E+h), v_E tan(lat)/(R_E+h)]`` and the plumb-line
gravity ``g_n`` of :meth:`EarthModel.gravity_n`.

Seed 003 eq. (1) prints this velocity equation as
``f + ([0, 2 Omega cos phi, Omega sin phi] + omega_en) x V - [0, -Omega^2 (r+h) cos phi
sin phi, Omega^2 (r+h) cos^2 phi + g]``. Against the derivation above it differs in the
sign of the cross-product term, a missing factor 2 on the vertical Earth-rate component,
and the sign of the centrifugal term (see :meth:`EarthModel.gravity_n`). navsim's truth
and this INS use the physical form. The paper estimator's faithful mode is not this
module's business.

Discretisation (one navigation step t_k -> t_k+1 = t_k + dt)
-------------------------------------------------------------
Body-frame terms come from the registries of :mod:`navsim.strapdown` and are computed for
all steps at once, before the sequential loop:

* ``Phi = CONING[coning](...)``: the body rotation vector over the step (000, 1.11).
* ``dV_b = SCULLING[sculling](...)``: DeltaV + deltaV_s in body axes at t_k (000, 1.6).
* ``dS_b = POSITION[position](0, I, ...)``: for the exact forms (000, 5.2-5.4), the double
  integral of the specific force over the step in body axes at t_k (DeltaV^2 + deltaS_s).
  "rectangle" and "trapezoid" are applied to the ENU velocities inside the loop instead.

The sequential part is a predictor-corrector (Heun) step on the slowly varying terms,
second order in dt:

1. Evaluate the rates, radii and ``gc = g_n - (2 omega_ie + omega_en) x v`` at t_k.
2. Predict the velocity and position at t_k+1 with them, evaluate again there, and use
   the averages (trapezoid rule) of omega_in and gc over the step.
3. Attitude, exact factorisation into the two rotations:
   ``q_nb(k+1) = q(-zeta) o q_nb(k) o q(Phi)``, ``zeta = mean(omega_in_n) dt``.
4. Velocity: ``u = mat_nb(k) dV_b``;
   ``v(k+1) = v(k) + u - zeta x (u - S/dt) + mean(gc) dt`` where ``S = mat_nb(k) dS_b``
   for the exact position forms (the frame-rotation correction is then exact to first
   order in zeta), and ``S = u dt / 2`` otherwise.
5. Position: the displacement ``D = int v dt`` in ENU components by the named rule:
   rectangle ``v(k) dt`` (000, 5.1); trapezoid ``(v(k) + v(k+1)) dt/2``; exact forms
   ``v(k) dt + S - zeta x S / 3 + dt^2 (2 gc(k) + gc(k+1)) / 6`` (000, 5.2, transported
   to the rotating ENU frame). Then ``lat += D_N / (R_N + h)``,
   ``lon += D_E / ((R_E + h) cos lat)``, ``h += D_U`` with mid-step radii and latitude.

The same discrete equations are solved without the per-step loop by
``method="scan"`` (:mod:`navsim.strapdown.scan`: the body rotations' prefix products by a
parallel scan, the navigation-frame terms by a fixed-point iteration over windows of
steps, velocity and position by cumulative sums); it agrees with the loop to rounding and
is faster on long runs (figures: ``benchmarks/RESULTS.md``). ``method="auto"`` (the default) uses it from
:data:`AUTO_SCAN_MIN_STEPS` steps on. :func:`body_terms` and
:func:`integrate_body_terms` expose the two stages separately.

Two additions to the registry's first-order forms, both vectorised before the loop:

* The second-order rotation term that (1.6)-(1.8) and (5.3)-(5.4) of seed 000 neglect,
  ``1/2 int DeltaTheta x (DeltaTheta x a) dt``, with the constant-rate model:
  ``+ Phi x (Phi x DeltaV) / 6`` on dV_b and ``+ dt Phi x (Phi x DeltaV) / 24`` on dS_b
  (Savage's second-order velocity rotation term). Without it a vehicle oscillating in
  pitch and roll at 0.05 rad amplitude (body rates ~0.02 rad/s) gathers 1.6e-5 m/s of
  vertical velocity error in 300 s at 100 Hz; with it 2e-10 m/s.
* Compensated (Kahan) summation of lat, lon and h: the per-step increments are ~1e-8 of
  the values, and plain sums accumulated ~1e-5 m of rounding error in 3e4 steps.

Accuracy with exact increments (tests/strapdown/test_ins.py): 1000 s at 100 Hz on WGS-84,
moving north-east at ~25 m/s with 5 m height oscillation while the body turns at
0.02 rad/s and oscillates in pitch and roll: position error 3e-7 m, velocity 8e-10 m/s,
attitude 1e-13 rad; at 10 Hz 3e-4 m. (pyins' self-consistency figure on this kind of
machine: 0.075 m horizontal over 30 min at 100 Hz, 8.5 m at 10 Hz.)

Coordinates are geodetic latitude and longitude; the mechanisation is singular at the
poles (tan lat), as every ENU mechanisation is.

References
----------
.. [1] Sokolov S.V., Vdovichenko S.S. (2012), seed 003, eq. (1).
.. [2] Litmanovich Yu.A. (2002), seed 000, eqs. (1.3)-(1.14), (5.1)-(5.4).
.. [3] Savage P.G., Strapdown Analytics, 2nd ed., 2007, ch. 7 (attitude, velocity and
       position updates with navigation-frame rotation).
.. [4] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., 2013, section 5.4 (local-navigation-frame mechanisation).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..earth import WGS84, EarthModel
from ..errors import ConfigError
from ..rotations import quat_from_rotvec
from .registry import CONING, POSITION, SCULLING, required_inputs
from .state import InsSolution, InsState

__all__ = [
    "AUTO_SCAN_MIN_STEPS",
    "BodyTerms",
    "InsSolution",
    "InsState",
    "METHODS",
    "body_terms",
    "ins_step",
    "integrate",
    "integrate_body_terms",
    "resolve_methods",
    "sequential_rows",
]

METHODS = ("auto", "sequential", "scan", "compiled")
"""Integration methods of :func:`integrate` and :func:`integrate_body_terms`."""

AUTO_COMPILED = False
"""``method="auto"`` uses the compiled loop (numba installed) also where it would use the
scan (False: long runs keep the scan's numbers; short runs use the compiled loop, which is
the sequential loop bit for bit)."""

AUTO_SCAN_MIN_STEPS = 4096
"""``method="auto"`` uses the scan integrator from this many steps on, the loop below."""

_N_FRAME_RULES = ("rectangle", "trapezoid")
# preference order of the automatic choice (most accurate first)
_AUTO = {
    "coning": ("invariant", "smoothing", "three-sample", "two-sample", "one-sample"),
    "sculling": ("invariant-4.4", "smoothing", "two-sample", "first-order"),
    "position": ("exact-invariant", "exact-smoothing", "exact", "trapezoid"),
}

Method = str | Callable | None


# ------------------------------------------------------------------------------ inputs
def _as_steps(name: str, value: ArrayLike | None, single: bool) -> np.ndarray | None:
    if value is None:
        return None
    arr = np.asarray(value, dtype=float)
    if single and arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[1] < 1:
        shape = "(m, 3) or (1, m, 3)" if single else "(n, m, 3)"
        raise ConfigError(name, f"an array of shape {shape}", arr.shape)
    return arr


def _available(inputs: dict[str, np.ndarray | None], tokens: set[str]) -> bool:
    for token in tokens:
        if ":" not in token:
            continue
        key, count = token.split(":")
        arr = inputs.get(key)
        if arr is None:
            return False
        if key.endswith("_sub") and arr.shape[1] != int(count):
            return False
        if key.endswith("_r") and arr.shape[1] < int(count):
            return False
    return True


def resolve_methods(
    coning: Method, sculling: Method, position: Method, dtheta_sub: np.ndarray | None = None,
    dv_sub: np.ndarray | None = None, dtheta_r: np.ndarray | None = None, dv_r: np.ndarray | None = None
) -> tuple[Method, Method, Method]:
    """Fill ``None`` method names with the most accurate registered method the inputs allow.

    Preference (first whose inputs are present): coning invariant, smoothing,
    three-sample, two-sample, one-sample; sculling invariant-4.4, smoothing, two-sample,
    first-order; position exact-invariant, exact-smoothing, exact, trapezoid.
    Names and callables given explicitly are returned unchanged.
    """
    inputs = {"dtheta_sub": dtheta_sub, "dv_sub": dv_sub, "dtheta_r": dtheta_r, "dv_r": dv_r}
    chosen = []
    for kind, method in (("coning", coning), ("sculling", sculling), ("position", position)):
        if method is None:
            for name in _AUTO[kind]:
                if _available(inputs, required_inputs(kind, name)):
                    method = name
                    break
            else:
                method = _AUTO[kind][-1]
        chosen.append(method)
    return chosen[0], chosen[1], chosen[2]


def _lookup(kind: str, method: Method) -> Callable:
    if callable(method):
        return method
    registry = {"coning": CONING, "sculling": SCULLING, "position": POSITION}[kind]
    try:
        if not isinstance(method, str):
            raise TypeError(method)
        return registry[method]
    except (KeyError, TypeError):
        raise ConfigError(kind, f"a callable or one of {sorted(registry)}", method) from None


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (n, 3) arrays (np.cross costs ~50 us per call on small arrays)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


@dataclass(frozen=True, slots=True)
class BodyTerms:
    """Body-frame strapdown terms of n navigation steps (independent of the navigation state).

    Attributes
    ----------
    rotvec_body : ndarray, shape (n, 3)
        ``Phi``, the body rotation vector over each step (coning algorithm), rad.
    dv_body : ndarray, shape (n, 3)
        ``dV_b``: DeltaV + deltaV_s (sculling algorithm) + the second-order rotation term
        ``Phi x (Phi x DeltaV) / 6``, body axes at t_k, m/s.
    ds_body : ndarray, shape (n, 3) or None
        ``dS_b``: the body-frame double integral of the exact position forms
        (DeltaV^2 + deltaS_s + ``dt Phi x (Phi x DeltaV) / 24``), m; None for the
        "rectangle" and "trapezoid" rules.
    rule : {"rectangle", "trapezoid", None}
        The n-frame position rule, or None for the exact forms.
    dtheta_first, dv_first : ndarray, shape (n, 3)
        The first-order increments DeltaTheta, DeltaV over each step (rad, m/s).
    """

    rotvec_body: np.ndarray
    dv_body: np.ndarray
    ds_body: np.ndarray | None
    rule: str | None
    dtheta_first: np.ndarray
    dv_first: np.ndarray

    def __len__(self) -> int:
        return len(self.rotvec_body)

    @property
    def quat_body(self) -> np.ndarray:
        """``q(Phi)``, shape (n, 4), the input of :func:`integrate_body_terms`."""
        return quat_from_rotvec(self.rotvec_body)


def body_terms(dtheta_sub: np.ndarray | None = None, dv_sub: np.ndarray | None = None,
               dtheta_r: np.ndarray | None = None, dv_r: np.ndarray | None = None, dt: float = 0.01,
               coning: Method = None, sculling: Method = None, position: Method = None) -> BodyTerms:
    """The body-frame terms :func:`integrate` uses, for all n steps at once.

    Parameters are those of :func:`integrate` (increment arrays of shape (n, m, 3) or
    (n, R, 3), methods by name, callable or None for :func:`resolve_methods`).
    ``integrate(state, ...)`` equals
    ``integrate_body_terms(state, t.quat_body, t.dv_body, t.ds_body, t.rule, dt, earth)``
    with ``t = body_terms(...)``. Estimators that correct the terms (bias removal to
    first order, see navsim.estimators._inserror) start from the rotation vector and the
    first-order increments returned here.
    """
    coning, sculling, position = resolve_methods(coning, sculling, position, dtheta_sub, dv_sub, dtheta_r, dv_r)
    phi = np.asarray(_lookup("coning", coning)(dtheta_sub, dtheta_r, dt), dtype=float)
    dv_b = np.asarray(_lookup("sculling", sculling)(dtheta_sub, dv_sub, dtheta_r, dv_r, dt), dtype=float)
    rule = position if isinstance(position, str) and position in _N_FRAME_RULES else None
    ds_b = None
    if rule is None:
        n = phi.shape[0]
        zeros = np.zeros((n, 3))
        eye = np.broadcast_to(np.eye(3), (n, 3, 3))
        # with V = 0 and C = I the registry returns the body-frame double integral
        # DeltaV^2 + deltaS_s of (5.2)-(5.4)
        position_fn = _lookup("position", position)
        ds_b = np.asarray(position_fn(zeros, eye, dtheta_sub, dv_sub, dtheta_r, dv_r, dt), dtype=float)
    # second-order rotation terms that (1.6)-(1.8) and (5.3)-(5.4) neglect:
    # 1/2 int DeltaTheta x (DeltaTheta x a) dt = 1/6 Phi x (Phi x DV) for constant omega, a,
    # and its double integral 1/24 dt Phi x (Phi x DV)
    dth_raw = np.sum(dtheta_sub, axis=1) if dtheta_sub is not None else np.asarray(dtheta_r, dtype=float)[:, 0]
    dv_raw = np.sum(dv_sub, axis=1) if dv_sub is not None else np.asarray(dv_r, dtype=float)[:, 0]
    second = _cross(phi, _cross(phi, dv_raw))
    dv_b = dv_b + second / 6.0
    if ds_b is not None:
        ds_b = ds_b + (dt / 24.0) * second
    return BodyTerms(phi, dv_b, ds_b, rule, np.asarray(dth_raw, dtype=float), np.asarray(dv_raw, dtype=float))


def _body_terms(dtheta_sub: np.ndarray | None, dv_sub: np.ndarray | None, dtheta_r: np.ndarray | None,
                dv_r: np.ndarray | None, dt: float, coning: Method, sculling: Method,
                position: Method) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, str | None]:
    """Vectorised body-frame terms for all steps: q(Phi) (n, 4), dV_b (n, 3), dS_b or None, rule."""
    terms = body_terms(dtheta_sub, dv_sub, dtheta_r, dv_r, dt, coning, sculling, position)
    return terms.quat_body, terms.dv_body, terms.ds_body, terms.rule


# ------------------------------------------------------------------------------ the loop
def _run_sequential(state: InsState, quat_body: np.ndarray, dv_body: np.ndarray, ds_body: np.ndarray | None,
                    rule: str | None, dt: float, earth: EarthModel) -> InsSolution:
    """Sequential predictor-corrector loop on Python floats (see the module notes)."""
    out_pos, out_vel, out_q, compensation = sequential_rows(
        state.lat, state.lon, state.h, state.velocity_n.tolist(), state.quat_nb.tolist(), state.compensation,
        quat_body.tolist(), dv_body.tolist(), None if ds_body is None else ds_body.tolist(), rule, dt, earth)
    pos = np.array(out_pos)
    return InsSolution(pos[:, 0], pos[:, 1], pos[:, 2], np.array(out_vel), np.array(out_q), compensation)


def _run_compiled(state: InsState, quat_body: np.ndarray, dv_body: np.ndarray, ds_body: np.ndarray | None,
                  rule: str | None, dt: float, earth: EarthModel) -> InsSolution:
    """The sequential loop compiled (:mod:`navsim.strapdown.compiled`)."""
    from . import compiled

    n = len(dv_body)
    start = np.array([state.lat, state.lon, state.h, *state.compensation, *state.velocity_n, *state.quat_nb],
                     dtype=float)
    pos, vel, quat, comp = np.empty((3, n + 1)), np.empty((n + 1, 3)), np.empty((n + 1, 4)), np.empty(3)
    exact = ds_body is not None
    run = compiled.kernel()
    assert run is not None  # called only where compiled.available()
    run(compiled.earth_constants(earth), start, np.ascontiguousarray(quat_body),
        np.ascontiguousarray(dv_body), np.ascontiguousarray(ds_body) if exact else np.zeros((1, 3)),
        exact, rule == "trapezoid", float(dt), pos, vel, quat, comp)
    k_lat, k_lon, k_h = comp.tolist()
    return InsSolution(pos[0], pos[1], pos[2], vel, quat, (k_lat, k_lon, k_h))  # rows: lat, lon, h


def sequential_rows(lat: float, lon: float, h: float, velocity_n: Sequence[float], quat_nb: Sequence[float],
                    compensation: Sequence[float], quat_body: Sequence[Sequence[float]],
                    dv_body: Sequence[Sequence[float]], ds_body: Sequence[Sequence[float]] | None,
                    rule: str | None, dt: float, earth: EarthModel) -> tuple[
        list[tuple[float, float, float]], list[tuple[float, float, float]],
        list[tuple[float, float, float, float]], tuple[float, float, float]]:
    """The sequential loop of :func:`integrate_body_terms` on Python sequences.

    ``velocity_n`` (3,), ``quat_nb`` (4,), ``compensation`` (3,) of the start state (see
    :class:`InsState`); ``quat_body`` (n, 4), ``dv_body`` (n, 3), ``ds_body`` (n, 3) or
    None as nested sequences of floats. Returns ``(positions, velocities, quaternions,
    compensation)``: lists of n + 1 tuples ``(lat, lon, h)``, ``(vE, vN, vU)``,
    ``(q0, q1, q2, q3)`` (the first row is the start) and the final compensation terms.
    The same operations as ``integrate_body_terms(..., method="sequential")``, without
    array conversions or state validation (for estimators stepped one step at a time).
    """
    sin, cos, sqrt = math.sin, math.cos, math.sqrt
    a, e2, rate, f = earth.a, earth.e2, earth.rate, earth.f
    spherical = earth.name == "spherical"
    flat = earth.f == 0.0
    g0 = earth.g0
    gamma_e, k_som = 9.7803253359, 0.00193185265241  # TR8350.2, as in earth.gravity_n
    m_som = rate**2 * a**2 * a * (1.0 - f) / earth.gm
    rate2 = rate * rate

    def evaluate(lat: float, h: float, ve: float, vn: float, vu: float) -> tuple[
            float, float, float, float, float, float, float, float, float]:
        # radii, rates and gc = g - (2 w_ie + w_en) x v at one point; mirrors navsim.earth
        sl, cl = sin(lat), cos(lat)
        if flat:
            rnh = reh = a + h
        else:
            w2 = 1.0 - e2 * sl * sl
            w = sqrt(w2)
            reh = a / w + h
            rnh = a * (1.0 - e2) / (w2 * w) + h
        if spherical:
            rc = rate2 * (a + h) * cl
            gn, gu = -rc * sl, rc * cl - g0
        else:
            s2 = sl * sl
            gamma = gamma_e * (1.0 + k_som * s2) / sqrt(1.0 - e2 * s2)
            gn = 0.0
            gu = -gamma * (1.0 - 2.0 / a * (1.0 + f + m_som - 2.0 * f * s2) * h + 3.0 / (a * a) * h * h)
        wie_n, wie_u = rate * cl, rate * sl
        wen_e, wen_n = -vn / rnh, ve / reh
        wen_u = wen_n * sl / cl
        cn, cu = 2.0 * wie_n + wen_n, 2.0 * wie_u + wen_u  # 2 w_ie + w_en (east: wen_e)
        gce = -(cn * vu - cu * vn)
        gcn = gn - (cu * ve - wen_e * vu)
        gcu = gu - (wen_e * vn - cn * ve)
        return rnh, reh, cl, wen_e, wie_n + wen_n, wie_u + wen_u, gce, gcn, gcu

    ve, vn, vu = (float(x) for x in velocity_n)
    q0, q1, q2, q3 = (float(x) for x in quat_nb)
    exact = ds_body is not None
    ds_list: Sequence[Any] = ds_body if ds_body is not None else [None] * len(dv_body)
    trapezoid = rule == "trapezoid"
    half_dt, dt2_6, third = 0.5 * dt, dt * dt / 6.0, 1.0 / 3.0
    inv_dt = 1.0 / dt

    out_pos = [(lat, lon, h)]
    out_vel = [(ve, vn, vu)]
    out_q = [(q0, q1, q2, q3)]
    k_lat, k_lon, k_h = compensation
    ev = evaluate(lat, h, ve, vn, vu)
    left = len(dv_body)
    for (b0, b1, b2, b3), (dx, dy, dz), ds in zip(quat_body, dv_body, ds_list):
        left -= 1
        rnh, reh, cl, wx, wy, wz, ge, gn, gu = ev
        # mat_nb(k) from q(k)
        c00 = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
        c11 = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
        c22 = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
        c01, c10 = 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q2 + q0 * q3)
        c02, c20 = 2 * (q1 * q3 + q0 * q2), 2 * (q1 * q3 - q0 * q2)
        c12, c21 = 2 * (q2 * q3 - q0 * q1), 2 * (q2 * q3 + q0 * q1)
        # (1.6) specific-force increment in n(k) axes
        ue = c00 * dx + c01 * dy + c02 * dz
        un = c10 * dx + c11 * dy + c12 * dz
        uu = c20 * dx + c21 * dy + c22 * dz
        # predictor: rates at t_k, S = u dt/2
        ze, zn, zu = wx * half_dt, wy * half_dt, wz * half_dt  # zeta/2
        pe = ve + ue - (zn * uu - zu * un) + ge * dt
        pn = vn + un - (zu * ue - ze * uu) + gn * dt
        pu = vu + uu - (ze * un - zn * ue) + gu * dt
        lat_p = lat + (vn + pn) * half_dt / rnh
        h_p = h + (vu + pu) * half_dt
        rnh1, reh1, cl1, wx1, wy1, wz1, ge1, gn1, gu1 = evaluate(lat_p, h_p, pe, pn, pu)
        # corrector: trapezoid means of omega_in and gc over the step
        ze, zn, zu = (wx + wx1) * half_dt, (wy + wy1) * half_dt, (wz + wz1) * half_dt  # zeta
        if exact:
            se = c00 * ds[0] + c01 * ds[1] + c02 * ds[2]
            sn = c10 * ds[0] + c11 * ds[1] + c12 * ds[2]
            su = c20 * ds[0] + c21 * ds[1] + c22 * ds[2]
            re_, rn_, ru_ = ue - se * inv_dt, un - sn * inv_dt, uu - su * inv_dt
        else:
            re_, rn_, ru_ = 0.5 * ue, 0.5 * un, 0.5 * uu
        ve1 = ve + ue - (zn * ru_ - zu * rn_) + (ge + ge1) * half_dt
        vn1 = vn + un - (zu * re_ - ze * ru_) + (gn + gn1) * half_dt
        vu1 = vu + uu - (ze * rn_ - zn * re_) + (gu + gu1) * half_dt
        # position: displacement in ENU components
        if exact:  # (5.2) transported to the rotating ENU frame
            de = ve * dt + se - third * (zn * su - zu * sn) + dt2_6 * (2.0 * ge + ge1)
            dn = vn * dt + sn - third * (zu * se - ze * su) + dt2_6 * (2.0 * gn + gn1)
            du = vu * dt + su - third * (ze * sn - zn * se) + dt2_6 * (2.0 * gu + gu1)
        elif trapezoid:
            de, dn, du = (ve + ve1) * half_dt, (vn + vn1) * half_dt, (vu + vu1) * half_dt
        else:  # (5.1) rectangle
            de, dn, du = ve * dt, vn * dt, vu * dt
        # compensated (Kahan) sums: the increments are ~1e-8 of lat, lon, so plain sums
        # would accumulate ~1e-5 m of rounding error over 1e5 steps
        y = 2.0 * dn / (rnh + rnh1) - k_lat
        s = lat + y
        k_lat = (s - lat) - y
        lat = s
        y = 2.0 * de / ((reh + reh1) * 0.5 * (cl + cl1)) - k_lon
        s = lon + y
        k_lon = (s - lon) - y
        lon = s
        y = du - k_h
        s = h + y
        k_h = (s - h) - y
        h = s
        ve, vn, vu = ve1, vn1, vu1
        # attitude: q(k+1) = q(-zeta) o q(k) o q(Phi)
        a0 = q0 * b0 - q1 * b1 - q2 * b2 - q3 * b3
        a1 = q0 * b1 + q1 * b0 + q2 * b3 - q3 * b2
        a2 = q0 * b2 - q1 * b3 + q2 * b0 + q3 * b1
        a3 = q0 * b3 + q1 * b2 - q2 * b1 + q3 * b0
        z2 = ze * ze + zn * zn + zu * zu
        n0 = 1.0 - z2 / 8.0 + z2 * z2 / 384.0  # cos(|zeta|/2)
        sc = -0.5 + z2 / 48.0  # -sin(|zeta|/2)/|zeta|
        n1, n2, n3 = sc * ze, sc * zn, sc * zu
        q0 = n0 * a0 - n1 * a1 - n2 * a2 - n3 * a3
        q1 = n0 * a1 + n1 * a0 + n2 * a3 - n3 * a2
        q2 = n0 * a2 - n1 * a3 + n2 * a0 + n3 * a1
        q3 = n0 * a3 + n1 * a2 - n2 * a1 + n3 * a0
        s = 1.0 / sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0, q1, q2, q3 = q0 * s, q1 * s, q2 * s, q3 * s
        out_pos.append((lat, lon, h))
        out_vel.append((ve, vn, vu))
        out_q.append((q0, q1, q2, q3))
        if left:  # the rates at t_k+1 start the next step (none after the last)
            ev = evaluate(lat, h, ve, vn, vu)
    return out_pos, out_vel, out_q, (k_lat, k_lon, k_h)


# kept for callers of the former private name (navsim.estimators._inserror); use
# integrate_body_terms(..., method="sequential")
_run = _run_sequential


def _check_method(method: str, window: int | None) -> None:
    if method not in METHODS:
        raise ConfigError("method", f"one of {METHODS}", method)
    if window is not None and (isinstance(window, bool) or int(window) != window or window < 1):
        raise ConfigError("window", "a positive whole number of steps", window)


def integrate_body_terms(
    initial_state: InsState,
    quat_body: ArrayLike,
    dv_body: ArrayLike,
    ds_body: ArrayLike | None = None,
    rule: str | None = None,
    dt: float = 0.01,
    earth: EarthModel = WGS84,
    method: str = "auto",
    window: int | None = None,
) -> InsSolution:
    """Free-inertial navigation from precomputed body-frame terms (see :func:`body_terms`).

    Parameters
    ----------
    initial_state : InsState
    quat_body : array_like, shape (n, 4)
        ``q(Phi_k)``, body rotation over each step (scalar first).
    dv_body : array_like, shape (n, 3)
        Velocity increments in body axes at t_k, m/s.
    ds_body : array_like, shape (n, 3), optional
        Body-frame double integrals, m, for the exact position forms (``rule=None``).
    rule : {"rectangle", "trapezoid", None}
        Position rule; None requires ``ds_body``.
    dt : float
        Navigation step, s.
    earth : EarthModel
    method : {"auto", "sequential", "scan", "compiled"}
        "sequential": the per-step loop (module notes). "scan": the loop-free window
        fixed point of :mod:`navsim.strapdown.scan` (same solution to rounding, several
        times faster for long runs). "compiled": the sequential loop compiled by numba
        (:mod:`navsim.strapdown.compiled`, extra ``fast``; the sequential numbers bit for
        bit). "auto": "scan" for n >= AUTO_SCAN_MIN_STEPS steps (the compiled loop there
        too if :data:`AUTO_COMPILED`), below that the compiled loop if numba is installed,
        else the sequential loop.
    window : int, optional
        Steps per scan window (default :data:`navsim.strapdown.scan.DEFAULT_WINDOW`).

    Returns
    -------
    InsSolution
        n + 1 rows.
    """
    _check_method(method, window)
    dt = float(dt)
    if not (dt > 0.0 and math.isfinite(dt)):
        raise ConfigError("dt", "a positive finite step in seconds", dt)
    quat_body = np.asarray(quat_body, dtype=float)
    dv_body = np.asarray(dv_body, dtype=float)
    n = len(dv_body)
    if quat_body.shape != (n, 4) or dv_body.shape != (n, 3):
        raise ConfigError("quat_body/dv_body", "arrays of shapes (n, 4) and (n, 3)", (quat_body.shape, dv_body.shape))
    if rule not in (None, *_N_FRAME_RULES):
        raise ConfigError("rule", f"None or one of {_N_FRAME_RULES}", rule)
    if rule is None:
        if ds_body is None:
            raise ConfigError("ds_body", "an (n, 3) array when rule is None (exact position forms)", None)
        ds_body = np.asarray(ds_body, dtype=float)
        if ds_body.shape != (n, 3):
            raise ConfigError("ds_body", "an array of shape (n, 3)", ds_body.shape)
    else:
        ds_body = None
    if method == "compiled" or (method == "auto" and (n < AUTO_SCAN_MIN_STEPS or AUTO_COMPILED)):
        from . import compiled

        if compiled.available():
            return _run_compiled(initial_state, quat_body, dv_body, ds_body, rule, dt, earth)
        if method == "compiled":  # (auto falls through to the NumPy methods)
            raise ConfigError("method", "'compiled' with numba installed (extra 'fast'), or 'auto'/'scan'",
                              method)
    if method == "scan" or (method == "auto" and n >= AUTO_SCAN_MIN_STEPS):
        from .scan import DEFAULT_WINDOW, integrate_scan

        return integrate_scan(initial_state, quat_body, dv_body, ds_body, rule, dt, earth,
                              window=DEFAULT_WINDOW if window is None else int(window))
    return _run_sequential(initial_state, quat_body, dv_body, ds_body, rule, dt, earth)


def integrate(
    initial_state: InsState,
    dtheta_sub: ArrayLike | None = None,
    dv_sub: ArrayLike | None = None,
    dtheta_r: ArrayLike | None = None,
    dv_r: ArrayLike | None = None,
    dt: float = 0.01,
    earth: EarthModel = WGS84,
    coning: Method = None,
    sculling: Method = None,
    position: Method = None,
    method: str = "auto",
    window: int | None = None,
) -> InsSolution:
    """Free-inertial navigation over n steps from ideal or measured increments.

    Parameters
    ----------
    initial_state : InsState
        State at t_0.
    dtheta_sub, dv_sub : array_like, shape (n, m, 3), optional
        Gyro (rad) and accelerometer (m/s) sub-sample increments, m per step, in order.
    dtheta_r, dv_r : array_like, shape (n, R, 3), optional
        Multiple integrals over each step (seed 000 eq. 1.14), ``[:, r-1]`` r-fold.
    dt : float
        Navigation step, s.
    earth : EarthModel
        :data:`navsim.earth.SPHERICAL` (seed 003) or :data:`navsim.earth.WGS84`.
    coning, sculling, position : str or callable or None
        Names in ``navsim.strapdown.CONING`` / ``SCULLING`` / ``POSITION`` (looked up
        when called), callables with the registry signatures, or None for the most
        accurate method the inputs allow (:func:`resolve_methods`). Position rules
        "rectangle" and "trapezoid" act on the ENU velocities; the other names supply
        the body-frame double integral of the exact form (5.2).
    method : {"auto", "sequential", "scan", "compiled"}
        "sequential": the per-step predictor-corrector loop of the module notes.
        "scan": the same discrete equations solved without a per-step loop
        (:mod:`navsim.strapdown.scan`: parallel prefix products for the body rotations,
        a fixed-point iteration per window for the navigation-frame terms); the same
        solution up to rounding and 4-8 times faster on long runs (benchmarks/bench_ins.py).
        "compiled": the loop compiled by numba (extra ``fast``; bit for bit "sequential").
        "auto" (default): "scan" from :data:`AUTO_SCAN_MIN_STEPS` steps on, else
        "compiled" with numba installed or "sequential" (so short runs, :func:`ins_step`
        and stepped use are bit-for-bit the loop); see :func:`integrate_body_terms`.
    window : int, optional
        Steps per scan window (default :data:`navsim.strapdown.scan.DEFAULT_WINDOW`).

    Returns
    -------
    InsSolution
        Arrays of n + 1 rows, the first being ``initial_state``.

    Notes
    -----
    Chunking. With ``method="sequential"``, integrating n1 steps, then n2 steps from the
    final state, gives exactly the numbers of n1 + n2 steps at once (the registered
    methods use only the current step's data). With ``method="scan"`` this holds when n1
    is a multiple of the window; elsewhere the two differ at the rounding level (measured
    in tests/strapdown/test_ins_scan.py), as do "scan" and "sequential". "auto" chooses per
    call, so chunks of different sizes may use different methods: rounding-level
    differences again. Pass an explicit method where bitwise reproducibility across
    chunkings matters.
    """
    dt = float(dt)
    if not (dt > 0.0 and math.isfinite(dt)):
        raise ConfigError("dt", "a positive finite step in seconds", dt)
    if not isinstance(initial_state, InsState):
        raise ConfigError("initial_state", "an InsState", type(initial_state).__name__)
    if not isinstance(earth, EarthModel):
        raise ConfigError("earth", "a navsim.earth.EarthModel", earth)
    arrays = [_as_steps(n, v, False) for n, v in
              (("dtheta_sub", dtheta_sub), ("dv_sub", dv_sub), ("dtheta_r", dtheta_r), ("dv_r", dv_r))]
    present = [x for x in arrays if x is not None]
    if not present:
        raise ConfigError("increments", "dtheta_sub/dv_sub and/or dtheta_r/dv_r", None)
    n = present[0].shape[0]
    if any(x.shape[0] != n for x in present):
        raise ConfigError("increments", "arrays with the same number of steps n", [x.shape for x in present])
    _check_method(method, window)
    quat_body, dv_body, ds_body, rule = _body_terms(arrays[0], arrays[1], arrays[2], arrays[3], dt, coning, sculling,
                                                    position)
    return integrate_body_terms(initial_state, quat_body, dv_body, ds_body, rule, dt, earth, method, window)


def ins_step(
    state: InsState,
    dtheta_sub: ArrayLike | None = None,
    dv_sub: ArrayLike | None = None,
    dtheta_r: ArrayLike | None = None,
    dv_r: ArrayLike | None = None,
    dt: float = 0.01,
    earth: EarthModel = WGS84,
    coning: Method = None,
    sculling: Method = None,
    position: Method = None,
) -> InsState:
    """One navigation step; the same computation as one row of :func:`integrate`.

    Increment arrays of one step may be given as (m, 3) / (R, 3) or with a leading
    axis of length 1. See :func:`integrate` for the parameters.
    """
    arrays = [_as_steps(n, v, True) for n, v in
              (("dtheta_sub", dtheta_sub), ("dv_sub", dv_sub), ("dtheta_r", dtheta_r), ("dv_r", dv_r))]
    for name, arr in zip(("dtheta_sub", "dv_sub", "dtheta_r", "dv_r"), arrays):
        if arr is not None and arr.shape[0] != 1:
            raise ConfigError(name, "the increments of one step, shape (m, 3)", arr.shape)
    return integrate(state, arrays[0], arrays[1], arrays[2], arrays[3], dt=dt, earth=earth, coning=coning,
                     sculling=sculling, position=position).final
