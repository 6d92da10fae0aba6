"""The truth-side GNSS error model and the epoch simulation.

:class:`GnssErrorModel`: seed 003's white pseudorange and Doppler noise (eqs. (2), (3)) and,
for standalone studies, a two-state receiver clock driven by the Allan-variance coefficients
h0, h-2 (Brown & Hwang 2012 sec. 9.3), ionospheric (thin shell, Misra & Enge 2006 ch. 5) and
tropospheric (RTCA DO-229D A.4.2.4) delays and first-order Gauss-Markov multipath per
satellite (shape of DO-229D J.2.4). :func:`simulate_epochs` (one receiver) and
:func:`simulate_epochs_batch` (N receivers) draw the observables (2), (3) at the epochs
from explicit random streams, carrying :class:`GnssState` between chunks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ...earth import WGS84, EarthModel
from ...errors import ConfigError, check_nonnegative
from ...types import FloatOrArray
from .._common import RecentBatches, frozen_array
from ..imu import apply as _imu_apply
from ..imu import kernel as _imu_kernel
from .constants import C_LIGHT
from .constellation import Constellation
from .orbits import SkyGeometry, sky_geometry

if TYPE_CHECKING:
    from ...types import NominalGnss


@dataclass(frozen=True, slots=True)
class GnssErrorModel:
    """Truth-side GNSS error model (what the simulator draws, not what a filter assumes).

    Parameters
    ----------
    pseudorange_sigma_m : float
        White pseudorange noise, m (seed 003: 15 m).
    doppler_sigma_mps : float
        White pseudorange-rate noise, m/s (seed 003: 0.5 m/s).
    elevation_mask_deg : float
        Satellites below this elevation are not tracked.
    clock_enabled : bool
        Receiver clock error on/off (seed 003 treats it as compensated: off).
    clock_bias_m, clock_drift_mps : float
        Initial clock bias c*dt (m) and drift c*dt_dot (m/s).
    clock_h0, clock_h_2 : float
        Allan-variance coefficients of white FM (s) and random-walk FM (1/s). Defaults
        are the typical TCXO of Brown & Hwang Table 9.1 (h0 = 2e-19, h-2 = 2e-20).
    ionosphere_zenith_m : float
        Vertical ionospheric code delay, m (0 = off), mapped with the thin-shell
        obliquity factor at ``ionosphere_shell_height_m``.
    troposphere_zenith_m : float
        Zenith tropospheric delay at sea level, m (0 = off), scaled by
        exp(-h / troposphere_scale_height_m) and mapped with the DO-229 function.
    multipath_sigma_m : float
        Multipath standard deviation at the horizon, m (0 = off); it falls as
        exp(-E / multipath_elevation_scale_deg). Each satellite's multipath is a
        first-order Gauss-Markov process with correlation time
        ``multipath_time_constant_s``. Multipath enters the pseudorange only.
    """

    pseudorange_sigma_m: float = 15.0
    doppler_sigma_mps: float = 0.5
    elevation_mask_deg: float = 5.0
    clock_enabled: bool = False
    clock_bias_m: float = 0.0
    clock_drift_mps: float = 0.0
    clock_h0: float = 2e-19
    clock_h_2: float = 2e-20
    ionosphere_zenith_m: float = 0.0
    ionosphere_shell_height_m: float = 350_000.0
    troposphere_zenith_m: float = 0.0
    troposphere_scale_height_m: float = 8_000.0
    multipath_sigma_m: float = 0.0
    multipath_elevation_scale_deg: float = 10.0
    multipath_time_constant_s: float = 30.0

    def __post_init__(self) -> None:
        for name in (
            "pseudorange_sigma_m",
            "doppler_sigma_mps",
            "clock_h0",
            "clock_h_2",
            "ionosphere_zenith_m",
            "troposphere_zenith_m",
            "multipath_sigma_m",
        ):
            object.__setattr__(self, name, check_nonnegative(f"gnss.{name}", getattr(self, name)))
        for name in (
            "ionosphere_shell_height_m",
            "troposphere_scale_height_m",
            "multipath_elevation_scale_deg",
            "multipath_time_constant_s",
        ):
            value = check_nonnegative(f"gnss.{name}", getattr(self, name))
            if value == 0.0:
                raise ConfigError(f"gnss.{name}", "a positive number", getattr(self, name))
            object.__setattr__(self, name, value)
        mask = float(self.elevation_mask_deg)
        if not -90.0 <= mask < 90.0:
            raise ConfigError("gnss.elevation_mask_deg", "a value in [-90, 90)", mask)
        object.__setattr__(self, "elevation_mask_deg", mask)
        if not isinstance(self.clock_enabled, (bool, np.bool_)):
            raise ConfigError("gnss.clock_enabled", "true or false", self.clock_enabled)
        for name in ("clock_bias_m", "clock_drift_mps"):
            value = float(getattr(self, name))
            if not np.isfinite(value):
                raise ConfigError(f"gnss.{name}", "a finite number", value)
            object.__setattr__(self, name, value)

    PRESETS = ("paper-2012", "standalone", "ideal")

    @classmethod
    def preset(cls, name: str) -> GnssErrorModel:
        """Named models.

        ``"paper-2012"``
            Seed 003's example: white noise only, 15 m and 0.5 m/s, no clock error; the
            paper gives no mask, navsim uses 5 deg.
        ``"standalone"``
            An uncorrected standalone receiver: 1 m code noise, 0.05 m/s Doppler noise,
            TCXO clock (initial 10 us bias = 2998 m, 0.2 ppm drift = 60 m/s), 5 m
            vertical ionosphere, 2.4 m zenith troposphere, 3 m horizon multipath
            (30 s correlation), 10 deg mask.
        ``"ideal"``
            No error at all (mask 0 deg).
        """
        if name == "paper-2012":
            return cls(pseudorange_sigma_m=15.0, doppler_sigma_mps=0.5, elevation_mask_deg=5.0)
        if name == "standalone":
            return cls(
                pseudorange_sigma_m=1.0,
                doppler_sigma_mps=0.05,
                elevation_mask_deg=10.0,
                clock_enabled=True,
                clock_bias_m=1e-5 * C_LIGHT,
                clock_drift_mps=0.2e-6 * C_LIGHT,
                ionosphere_zenith_m=5.0,
                troposphere_zenith_m=2.4,
                multipath_sigma_m=3.0,
            )
        if name == "ideal":
            return cls(pseudorange_sigma_m=0.0, doppler_sigma_mps=0.0, elevation_mask_deg=0.0)
        raise ConfigError("gnss.preset", f"one of {list(cls.PRESETS)}", name)

    def nominal(self, lever_arm_b_m: Sequence[float] = (0.0, 0.0, 0.0)) -> NominalGnss:
        """The receiver specification an estimator is told (:class:`navsim.types.NominalGnss`).

        Code sigma = hypot(white noise, multipath sigma at the horizon); the clock, when
        on, with initial sigmas max(|bias|, 100 m), max(|drift|, 1 m/s) and the PSDs
        c^2 h0 / 2, 2 pi^2 c^2 h_-2 (Brown & Hwang sec. 9.3). Atmosphere: the designer
        knows the receiver is single-frequency and uncorrected (the delays are on), not
        the delays. A-priori values a receiver applies from standard models: ionosphere,
        the constant (night-time) term of the GPS broadcast (Klobuchar) model,
        5 ns = 1.50 m (navsim broadcasts no coefficients); sigma 4.5 m, DO-229D J.2.3
        tau_vert at mid-latitudes (the bundled scenarios lie at 44-47 deg). Troposphere,
        DO-229D A.4.2.4 at sea level and 45 deg, annual mean (P 1015.75 hPa,
        T 283.15 K, e 11.66 hPa): 2.313 m dry + 0.135 m wet = 2.448 m; sigma 0.12 m,
        DO-229D sigma_TVE. Thin shell at 350 km (Klobuchar), exponential height law with
        the 8 km scale height of the standard atmosphere. ``lever_arm_b_m``: the antenna
        lever arm as surveyed at installation (body axes, m).
        """
        from ...types import NominalGnss

        lever = tuple(float(x) for x in lever_arm_b_m)
        if len(lever) != 3:
            raise ConfigError("lever_arm_b_m", "3 numbers (body axes x, y, z, m)", lever_arm_b_m)
        clock = bool(self.clock_enabled)
        iono, tropo = self.ionosphere_zenith_m > 0.0, self.troposphere_zenith_m > 0.0
        return NominalGnss(
            pseudorange_sigma_m=float(np.hypot(self.pseudorange_sigma_m, self.multipath_sigma_m)),
            doppler_sigma_mps=float(self.doppler_sigma_mps),
            clock_modelled=clock,
            clock_bias_sigma_m=max(abs(self.clock_bias_m), 100.0) if clock else 0.0,
            clock_drift_sigma_mps=max(abs(self.clock_drift_mps), 1.0) if clock else 0.0,
            clock_phase_psd=C_LIGHT**2 * self.clock_h0 / 2.0 if clock else 0.0,
            clock_freq_psd=2.0 * math.pi**2 * C_LIGHT**2 * self.clock_h_2 if clock else 0.0,
            atmosphere_modelled=bool(iono or tropo),
            ionosphere_zenith_m=5e-9 * C_LIGHT if iono else 0.0,
            ionosphere_zenith_sigma_m=4.5 if iono else 0.0,
            troposphere_zenith_m=2.448 if tropo else 0.0,
            troposphere_zenith_sigma_m=0.12 if tropo else 0.0,
            lever_arm_b_m=(lever[0], lever[1], lever[2]),
        )

    # ----------------------------------------------------------------- pieces
    @property
    def clock_psd(self) -> tuple[float, float]:
        """(S_f, S_g): white-FM and random-walk-FM intensities in m^2/s and m^2/s^3.

        S_f = c^2 h0 / 2, S_g = c^2 2 pi^2 h_-2 (Brown & Hwang sec. 9.3).
        """
        return (
            C_LIGHT**2 * self.clock_h0 / 2.0,
            C_LIGHT**2 * 2.0 * np.pi**2 * self.clock_h_2,
        )

    def clock_allan_variance(self, tau: FloatOrArray) -> np.ndarray:
        """Allan variance sigma_y^2(tau) = h0/(2 tau) + (2 pi^2/3) h_-2 tau of the clock."""
        tau = np.asarray(tau, dtype=float)
        return self.clock_h0 / (2.0 * tau) + 2.0 * np.pi**2 / 3.0 * self.clock_h_2 * tau

    def ionosphere_delay_m(self, elevation: ArrayLike, earth: EarthModel = WGS84) -> np.ndarray:
        """Slant ionospheric delay, m: zenith delay x thin-shell obliquity factor."""
        elevation = np.asarray(elevation, dtype=float)
        ratio = earth.a * np.cos(elevation) / (earth.a + self.ionosphere_shell_height_m)
        return self.ionosphere_zenith_m / np.sqrt(1.0 - ratio**2)

    def troposphere_delay_m(self, elevation: ArrayLike, height_m: ArrayLike) -> np.ndarray:
        """Slant tropospheric delay, m: scaled zenith delay x DO-229 mapping function."""
        elevation = np.asarray(elevation, dtype=float)
        height = np.asarray(height_m, dtype=float)
        zenith = self.troposphere_zenith_m * np.exp(-height / self.troposphere_scale_height_m)
        return zenith * 1.001 / np.sqrt(0.002001 + np.sin(elevation) ** 2)

    def multipath_sigma(self, elevation: ArrayLike) -> np.ndarray:
        """Multipath standard deviation at elevation E, m: sigma_mp exp(-E / E0)."""
        above: np.ndarray = np.clip(np.asarray(elevation, dtype=float), 0.0, None)
        return self.multipath_sigma_m * np.exp(
            -above / np.radians(self.multipath_elevation_scale_deg)
        )

    @staticmethod
    def draw_width(n_satellites: int) -> int:
        """Width of the per-epoch block of standard normals: 2 clock + 3 per satellite."""
        return 2 + 3 * int(n_satellites)


@dataclass(frozen=True, slots=True, eq=False)
class GnssState:
    """Recursive truth-side GNSS error state carried between calls.

    Attributes
    ----------
    t_s : float
        Time of the last simulated epoch (NaN before the first one).
    clock_bias_m, clock_drift_mps : float
        Receiver clock bias and drift at ``t_s`` (at the first epoch if NaN).
    multipath : ndarray (m,)
        Unit-variance Gauss-Markov states, one per satellite (scaled by the
        elevation-dependent sigma when applied).
    """

    t_s: float
    clock_bias_m: float
    clock_drift_mps: float
    multipath: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "multipath", frozen_array(self.multipath))

    @classmethod
    def _batch(cls, t_s: float, bias: np.ndarray, drift: np.ndarray, multipath: np.ndarray) -> list[GnssState]:
        """The states of B receivers after a batched call: ``multipath`` (B, m) copied once
        to a read-only array, receiver j gets row j as a view (no per-state checks); the
        arrays are remembered with the states (:data:`_RECENT`) for the next call."""
        rows = frozen_array(multipath)
        bias, drift = frozen_array(bias), frozen_array(drift)
        new, set_t, set_b, set_d, set_x = object.__new__, _SET_T, _SET_B, _SET_D, _SET_X
        out = []
        for b, d, x in zip(bias.tolist(), drift.tolist(), rows):
            state = new(cls)
            set_t(state, t_s)
            set_b(state, b)
            set_d(state, d)
            set_x(state, x)
            out.append(state)
        _RECENT.remember(out, (t_s, bias, drift, rows))
        return out

    @classmethod
    def initial(
        cls, model: GnssErrorModel, constellation: Constellation, rng: np.random.Generator
    ) -> GnssState:
        """State before the first epoch: the model's initial clock, stationary multipath.

        Always draws m standard normals (whether multipath is on or not), so switching
        multipath does not shift the stream.
        """
        multipath = rng.standard_normal(constellation.n_satellites)
        bias = model.clock_bias_m if model.clock_enabled else 0.0
        drift = model.clock_drift_mps if model.clock_enabled else 0.0
        return cls(float("nan"), bias, drift, multipath)


# the slots' own setters (a frozen dataclass refuses setattr): for GnssState._batch
_SET_T, _SET_B, _SET_D, _SET_X = (getattr(GnssState, name).__set__
                                  for name in ("t_s", "clock_bias_m", "clock_drift_mps", "multipath"))
_RECENT = RecentBatches()
"""The GNSS states made by the last batched calls and their arrays (:func:`simulate_epochs_batch`)."""


@dataclass(frozen=True, slots=True, eq=False)
class GnssEpochs:
    """GNSS measurements at k epochs for m satellites (arrays, invalid entries = 0).

    Attributes
    ----------
    t : (k,) s
    sat_pos_e, sat_vel_e : (k, m, 3) ECEF m, m/s
    pseudorange_m : (k, m)
    pseudorange_rate_mps : (k, m)  d(range)/dt + clock drift + noise (003 eq. (3))
    valid : (k, m) bool  tracked (above the mask, visible, finite)
    elevation, azimuth : (k, m) rad
    clock_bias_m, clock_drift_mps : (k,)  truth-side receiver clock (for metrics only)
    """

    t: np.ndarray
    sat_pos_e: np.ndarray
    sat_vel_e: np.ndarray
    pseudorange_m: np.ndarray
    pseudorange_rate_mps: np.ndarray
    valid: np.ndarray
    elevation: np.ndarray
    azimuth: np.ndarray
    clock_bias_m: np.ndarray
    clock_drift_mps: np.ndarray

    @property
    def n_valid(self) -> np.ndarray:
        """Number of valid satellites per epoch, (k,)."""
        return self.valid.sum(axis=1)

    @classmethod
    def concatenate(cls, parts: Sequence[GnssEpochs]) -> GnssEpochs:
        """Join chunks along the epoch axis."""
        names = cls.__slots__
        return cls(**{n: np.concatenate([getattr(p, n) for p in parts]) for n in names})


def _clock_cholesky(model: GnssErrorModel, dt: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cholesky factor entries of the two-state clock process noise over dt (Brown & Hwang 9.3)."""
    s_f, s_g = model.clock_psd
    q_bb = s_f * dt + s_g * dt**3 / 3.0
    q_bd = s_g * dt**2 / 2.0
    q_dd = s_g * dt
    l00 = np.sqrt(q_bb)
    with np.errstate(invalid="ignore", divide="ignore"):
        l10 = np.where(l00 > 0.0, q_bd / l00, 0.0)
    l11 = np.sqrt(np.clip(q_dd - l10**2, 0.0, None))
    return l00, l10, l11


def simulate_epochs(
    t: np.ndarray,
    position_e: np.ndarray,
    velocity_e: np.ndarray,
    constellation: Constellation,
    model: GnssErrorModel,
    state: GnssState,
    rng: np.random.Generator,
    earth: EarthModel = WGS84,
    visible: np.ndarray | None = None,
    *,
    geometry: SkyGeometry | None = None,
) -> tuple[GnssEpochs, GnssState]:
    """Simulate pseudoranges and pseudorange rates at k epochs.

    Parameters
    ----------
    t : array_like (k,)
        Epoch times, s, strictly increasing and after ``state.t_s``.
    position_e, velocity_e : array_like (k, 3)
        True receiver ECEF position (m) and ECEF-frame velocity (m/s). NaN rows give
        invalid epochs.
    constellation, model, state, rng
        ``rng`` is the GNSS stream; one block ``standard_normal((k, 2 + 3 m))`` is drawn
        per call (row = epoch: 2 clock, m code, m Doppler, m multipath), so the result is
        chunk-invariant and independent of what is switched on or visible.
    earth : EarthModel
    visible : array_like (k, m) bool, optional
        Visibility from :func:`navsim.sensors.outages.visibility` (True = signal
        present).
    geometry : SkyGeometry, optional
        Precomputed :func:`sky_geometry` for the same t, position_e and constellation.

    Returns
    -------
    epochs : GnssEpochs
    new_state : GnssState

    Notes
    -----
    pseudorange = rho + b + I + T + MP + w_R (003 eq. (2) plus the optional terms),
    pseudorange rate = (r_s - r).(v_s - v)/rho + b_dot + w_V (003 eq. (3)). rho is the
    geometric range at the reception instant (no light time, no Sagnac), as in (2).
    Atmospheric delay rates (below 1 cm/s) are left out of the Doppler observable.
    This is the one-receiver case of :func:`simulate_epochs_batch`.
    """
    if visible is not None:
        visible = np.asarray(visible, dtype=bool)[None]
    epochs, states = simulate_epochs_batch(t, position_e, velocity_e, constellation, model, [state], [rng], earth,
                                           visible, geometry=geometry)
    return GnssEpochs(**{name: getattr(epochs, name)[0] for name in GnssEpochs.__slots__}), states[0]


def simulate_epochs_batch(
    t: np.ndarray,
    position_e: np.ndarray,
    velocity_e: np.ndarray,
    constellation: Constellation,
    model: GnssErrorModel,
    states: Sequence[GnssState],
    rngs: Sequence[np.random.Generator],
    earth: EarthModel = WGS84,
    visible: np.ndarray | None = None,
    *,
    geometry: SkyGeometry | None = None,
) -> tuple[GnssEpochs, list[GnssState]]:
    """:func:`simulate_epochs` for B receivers at the same place (one true motion).

    The geometry (satellite states, ranges, range rates, elevations, atmospheric delays)
    is computed once; receiver j draws its own block from ``rngs[j]`` and gets exactly the
    numbers of ``simulate_epochs(..., states[j], rngs[j], visible=visible[j])``.

    Parameters
    ----------
    t, position_e, velocity_e, constellation, model, earth, geometry
        As :func:`simulate_epochs`, shared by all receivers.
    states : sequence of B GnssState, all at the same ``t_s`` (lockstep).
    rngs : sequence of B numpy.random.Generator
    visible : array_like (B, k, m) bool, optional

    Returns
    -------
    epochs : GnssEpochs
        Every array with a leading receiver axis (B, k, ...); the shared ones (``t``,
        ``sat_pos_e``, ``sat_vel_e``, ``elevation``, ``azimuth``) as read-only broadcast
        views.
    new_states : list of B GnssState
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    k, m = t.size, constellation.n_satellites
    states, rngs = list(states), list(rngs)
    members = len(states)
    if not states or len(rngs) != members:
        raise ConfigError("rngs", f"one generator per state ({members}, at least one)", len(rngs))
    position_e = np.asarray(position_e, dtype=float).reshape(k, 3) if k else np.zeros((0, 3))
    velocity_e = np.asarray(velocity_e, dtype=float).reshape(k, 3) if k else np.zeros((0, 3))
    made = _RECENT.recall(states)  # (t_s, bias, drift, multipath) of states this function made
    if made is not None and made[3].shape == (members, m):
        t_s = made[0]  # made together: one epoch time, multipath rows of shape (m,)
    else:
        made = None
        for state in states:
            if state.multipath.shape != (m,):
                raise ConfigError("state.multipath", f"shape ({m},)", state.multipath.shape)
        t_s = states[0].t_s
        if any(not (s.t_s == t_s or (math.isnan(s.t_s) and math.isnan(t_s))) for s in states):
            raise ConfigError("states", "states at the same epoch time (lockstep)", sorted({s.t_s for s in states}))
    if not np.all(np.isfinite(t)):
        raise ConfigError("t", "finite times", t)
    dt = np.diff(np.concatenate([[t_s], t]))
    increasing = np.all(dt[1:] > 0.0) and (not np.isfinite(t_s) or k == 0 or dt[0] > 0.0)
    if not increasing:
        raise ConfigError("t", f"strictly increasing times after state.t_s={t_s}", t)
    if visible is None:
        visible = np.ones((1, k, m), dtype=bool)
    else:
        visible = np.broadcast_to(np.asarray(visible, dtype=bool), (members, k, m))
    geo = geometry if geometry is not None else sky_geometry(t, position_e, constellation, earth)
    if geo.range_m.shape != (k, m):
        raise ConfigError("geometry", f"a SkyGeometry for ({k}, {m}) epochs x satellites", geo.range_m.shape)

    draws = np.empty((members, k, GnssErrorModel.draw_width(m)))
    group_draw = _imu_kernel.draws("normal") if k and _imu_apply.USE_KERNEL else None
    if group_draw is not None:
        group_draw(rngs, draws)  # one compiled call, the same numbers (navsim.sensors.imu.kernel)
    else:
        for j, rng in enumerate(rngs):
            rng.standard_normal(out=draws[j])
    z_clock, z_code = draws[:, :, :2], draws[:, :, 2 : 2 + m]
    z_doppler, z_mp = draws[:, :, 2 + m : 2 + 2 * m], draws[:, :, 2 + 2 * m :]

    # ---- recursive parts: receiver clock and multipath, epoch by epoch (members at once)
    first = not np.isfinite(t_s)
    step = np.where(np.isfinite(dt), dt, 0.0)
    l00, l10, l11 = _clock_cholesky(model, step)
    phi = np.exp(-step / model.multipath_time_constant_s)
    kick = np.sqrt(1.0 - phi**2)
    bias = np.empty((members, k))
    drift = np.empty((members, k))
    multipath = np.empty((members, k, m))
    if made is not None:  # the same values as read from the states below (read-only arrays)
        b, d, x = made[1], made[2], made[3]
    else:
        b = np.array([s.clock_bias_m for s in states])
        d = np.array([s.clock_drift_mps for s in states])
        x = np.stack([s.multipath for s in states])
    clock_on = model.clock_enabled
    for j in range(k):
        if not (first and j == 0):
            if clock_on:
                # two-state clock: b += d dt + w_b, d += w_d, cov(w) = Q(dt)
                b = b + d * step[j] + l00[j] * z_clock[:, j, 0]
                d = d + l10[j] * z_clock[:, j, 0] + l11[j] * z_clock[:, j, 1]
            x = phi[j] * x + kick[j] * z_mp[:, j]  # first-order Gauss-Markov
        bias[:, j], drift[:, j] = b, d
        multipath[:, j] = x

    # ---- measurements: the geometry once, the errors per member
    los_e = geo.sat_pos_e - position_e[:, None, :]
    rel_vel_e = geo.sat_vel_e - velocity_e[:, None, :]
    rho = geo.range_m
    with np.errstate(invalid="ignore", divide="ignore"):
        range_rate = np.einsum("kmi,kmi->km", los_e, rel_vel_e) / rho  # (3)
    elevation = geo.elevation
    pseudorange = rho + bias[:, :, None] + model.pseudorange_sigma_m * z_code  # (2)
    if model.ionosphere_zenith_m > 0.0:
        pseudorange = pseudorange + model.ionosphere_delay_m(elevation, earth)
    if model.troposphere_zenith_m > 0.0:
        pseudorange = pseudorange + model.troposphere_delay_m(elevation, geo.height_m[:, None])
    if model.multipath_sigma_m > 0.0:
        pseudorange = pseudorange + model.multipath_sigma(elevation) * multipath
    pseudorange_rate = range_rate + drift[:, :, None] + model.doppler_sigma_mps * z_doppler

    finite = np.isfinite(pseudorange) & np.isfinite(pseudorange_rate) & np.isfinite(elevation)
    with np.errstate(invalid="ignore"):
        above = elevation >= np.radians(model.elevation_mask_deg)
    valid = above & visible & finite
    zero = np.zeros(())

    def shared(a: np.ndarray) -> np.ndarray:
        return np.broadcast_to(a, (members, *a.shape))

    epochs = GnssEpochs(
        t=shared(t.copy()),
        sat_pos_e=shared(geo.sat_pos_e),
        sat_vel_e=shared(geo.sat_vel_e),
        pseudorange_m=np.where(valid, pseudorange, zero),
        pseudorange_rate_mps=np.where(valid, pseudorange_rate, zero),
        valid=valid,
        elevation=shared(np.where(np.isfinite(elevation), elevation, zero)),
        azimuth=shared(np.where(np.isfinite(geo.azimuth), geo.azimuth, zero)),
        clock_bias_m=bias,
        clock_drift_mps=drift,
    )
    if not k:
        return epochs, states
    return epochs, GnssState._batch(float(t[-1]), b, d, x)
