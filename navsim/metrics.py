"""Metrics: pure functions over arrays of an episode record, and the typed episode score.

Errors follow the estimator covariance convention of :mod:`navsim.estimators.base`:
``[dE, dN, dU, dvE, dvN, dvU, psiE, psiN, psiU]`` with position errors in metres in the
true position's ENU frame and psi the small rotation of the estimated attitude relative
to the true one about ENU axes (``mat_nb_est = exp([psi x]) mat_nb_true``).

What is measured (all over the steps of one episode, error = estimate - truth)
------------------------------------------------------------------------------
Position
    horizontal ``hypot(dE, dN)``, vertical ``dU``, along-track ``a = u . (dE, dN)`` and
    cross-track ``c = r . (dE, dN)`` where ``u = (sin psi, cos psi)`` is the unit
    horizontal tangent of the track at the *true* arc length (direction of increasing
    s, heading psi from :func:`navsim.track.track_frame`) and ``r = (cos psi, -sin psi)``
    points to its right (the body x axis of a vehicle moving forward): cross-track
    error is positive when the estimate lies right of the truth. For each: RMSE,
    maximum and final *absolute* error, and the 50 % / 95 % percentiles of the absolute
    error (CEP50 / CEP95; for horizontal the empirical circular error probable).
Velocity, attitude
    norm of the 3-D velocity error (m/s) and of psi (reported in degrees, the edge of
    the system), RMS / max / final; heading error = wrapped difference of the headings.
GNSS outages
    maximal runs of GNSS epochs with fewer than 4 valid satellites. An outage runs from
    the last good epoch before it to the first good epoch after it (exclusive: the
    estimate at that step already holds the new fix); at the episode's edges it runs
    from the start / to the end. Its *drift* is the maximum horizontal error inside it
    (the error itself, not its growth since the outage began: the KF-GINS protocol,
    where the error before an outage is small), and the episode figure is the RMS over
    outages of those maxima (Niu et al. 2025 [2], protocol of Niu et al. 2006).
Consistency
    NEES over the components whose covariance is finite (nan diagonal = not estimated,
    skipped; the components used are listed). ANEES is the time average of NEES (mean
    d for a consistent filter of dimension d). One run's NEES sequence is correlated in
    time, so the chi-square bounds of the time average use an effective sample count
    ``N_eff = N / tau`` with tau the integrated autocorrelation time of the NEES
    sequence (Sokal's automatic window, c = 5 [3]); ``chi2(d N_eff) / N_eff`` then has the
    mean d and the variance ``2 d tau / N`` of the time average. For independent
    samples (tau = 1) these are Bar-Shalom's bounds [1]. The fraction of steps whose NEES
    lies in the per-step 95 % interval of chi2(d) is given too (0.95 when consistent).
    NIS: innovations of a consistent filter are white, so ``sum NIS ~ chi2(sum dof)``;
    the normalised figure ``sum NIS / sum dof`` (1 when consistent) gets exact bounds.
    Across seeds, :func:`monte_carlo_nees` gives the classic Monte Carlo ANEES per step
    with bounds ``chi2(M d) / M``.
Divergence (filter-independent, :func:`detect_divergence`)
    An episode counts as diverged when any of three checks fires, each on the estimate
    and its claimed covariance only (never on the estimator's own flags):

    1. *non-finite estimate*: a non-finite position at any step, or a non-finite velocity
       or attitude at a step while that quantity is finite at other steps (an estimator
       that never reports a velocity or an attitude is not penalised for it);
    2. *horizontal threshold*: ``hypot(dE, dN)`` above ``divergence_threshold_m``
       (default 1000 m) at any step;
    3. *error far outside the claimed covariance for a sustained time*: the per-step NEES
       on the claimed subspace (dimension d, see Consistency) above the ``q`` quantile of
       chi2(d) (default q = 0.9999: 33.7 for d = 9, 25.7 for d = 5, 18.4 for d = 2) at
       no less than 80 % of the steps of some window of ``divergence_nees_window_s``
       (default 20 s). A consistent filter exceeds that quantile at a step with
       probability 1e-4; to do so at 80 % of a 20-s window the error must stay beyond it
       through many correlation times, which a consistent filter essentially never does.
       The 20 % allowance keeps dips from splitting a sustained excess (with a covariance
       100 times too small the NEES still falls below the quantile at 8.8 % of the steps
       for d = 2, 0.16 % for d = 5), and a single spike never fills a window. Episodes
       shorter than the window are not checked; a window of ``inf`` switches check 3 off.

    ``diverged_at_s`` is the earliest time any check fires (for check 3 the first step
    of the sustained run) and ``divergence_reason`` says which checks fired, when and
    with what value. The accuracy figures of a diverged episode (every horizontal,
    vertical, along/cross-track, velocity, attitude, heading and outage-drift figure,
    and the per-outage drifts) are NaN: never a figure computed from the finite or the
    pre-divergence fraction of the episode. The consistency figures (NEES, NIS) stay,
    since they document the divergence, except when the estimate is non-finite (check
    1), where they too would come from the finite fraction and are NaN.
CPU
    mean ``estimator.step`` CPU time per step, microseconds (with a batch fast path the
    chunk time divided by its steps, see :func:`navsim.episode.run_episode`).

Monte Carlo aggregation (:func:`aggregate`): per metric, the mean across seeds and a
95 % interval, by default the Student-t confidence interval of the *mean*
(``mean +- t_{0.975, n-1} s / sqrt(n)``); ``method="percentile"`` gives instead the
2.5 / 97.5 % percentiles of the per-seed values (the spread of single runs).

References
----------
.. [1] Bar-Shalom Y., Li X.R., Kirubarajan T., Estimation with Applications to Tracking
       and Navigation, Wiley 2001, section 5.4 (NEES, NIS and their chi-square tests).
.. [2] Niu X., Tang H., Zhang Q. et al., KF-GINS: an open-source GNSS/INS integrated
       navigation software, GPS Solutions 29:202, 2025 (60 s outages; RMS over outages
       of the maximum drift per outage).
.. [3] Sokal A., Monte Carlo methods in statistical mechanics: foundations and new
       algorithms, 1996 lecture notes, section 3 (integrated autocorrelation time and
       the automatic windowing procedure).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Sequence

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from .errors import ConfigError
from .estimators.base import STATE_LABELS
from .naverror import local_level_error, wrap_angle
from .rotations import mat_nb_from_hpr, mat_to_quat, quat_to_rotvec

if TYPE_CHECKING:  # type hints only
    from .episode import EpisodeRecord
    from .track import Track

Components = Sequence[int] | NDArray[np.integer[Any]]  # indices into the 9 error components

__all__ = [
    "error_vector",
    "nees",
    "ErrorSeries",
    "error_series",
    "ErrorStats",
    "error_stats",
    "Outage",
    "find_outages",
    "outage_drifts",
    "NeesSummary",
    "nees_summary",
    "NisSummary",
    "nis_summary",
    "integrated_autocorrelation_time",
    "EpisodeScore",
    "SCORE_FIELDS",
    "score_episode",
    "Divergence",
    "detect_divergence",
    "ACCURACY_FIELDS",
    "MetricSummary",
    "aggregate",
    "McNees",
    "monte_carlo_nees",
]

MIN_SATELLITES = 4
"""A GNSS epoch with fewer valid satellites than this is part of an outage."""


# ============================================================================ raw errors
def error_vector(record: EpisodeRecord) -> np.ndarray:
    """Estimation error (n, 9) = estimate - truth in the convention above."""
    d_e, d_n, d_u = local_level_error(record.est_lat, record.est_lon, record.est_h, record.truth_lat,
                                      record.truth_lon, record.truth_h, record.earth)
    dv = record.est_velocity_n - record.truth_velocity_n
    mat_est = mat_nb_from_hpr(*record.est_hpr.T)
    mat_true = mat_nb_from_hpr(*record.truth_hpr.T)
    finite = np.all(np.isfinite(record.est_hpr), axis=1)
    psi = np.full((len(d_e), 3), np.nan)
    if finite.any():
        rel = mat_est[finite] @ np.swapaxes(mat_true[finite], -1, -2)
        psi[finite] = quat_to_rotvec(mat_to_quat(rel))
    return np.column_stack([d_e, d_n, d_u, dv, psi])


def nees(errors: np.ndarray, covariance: np.ndarray, components: slice | Components = slice(None)) -> np.ndarray:
    """Normalised estimation error squared e^T P^-1 e per step over the chosen components.

    ``components`` : a slice or a sequence of indices into the 9 components. Steps
    whose covariance block has a non-finite entry give nan; a singular block is
    inverted with the pseudo-inverse.
    """
    e = errors[:, components]
    p = covariance[:, components][:, :, components]
    out = np.full(len(e), np.nan)
    ok = np.all(np.isfinite(p.reshape(len(p), -1)), axis=1) & np.all(np.isfinite(e), axis=1)
    if ok.any():
        try:
            sol = np.linalg.solve(p[ok], e[ok][..., None])[..., 0]
        except np.linalg.LinAlgError:
            sol = np.einsum("nij,nj->ni", np.linalg.pinv(p[ok], hermitian=True), e[ok])
        out[ok] = np.einsum("ni,ni->n", e[ok], sol)
    return out


def _sqrt_nonneg(x: np.ndarray) -> np.ndarray:
    """sqrt where x >= 0, nan elsewhere (no RuntimeWarning on negative or nan input)."""
    x = np.asarray(x, dtype=float)
    out = np.full(x.shape, np.nan)
    ok = np.isfinite(x) & (x >= 0.0)
    out[ok] = np.sqrt(x[ok])
    return out


@dataclass(frozen=True)
class ErrorSeries:
    """Per-step errors of one episode (every array has leading length n).

    Attributes
    ----------
    t : (n,) step end times, s.
    error : (n, 9) :func:`error_vector` (m, m/s, rad).
    horizontal_m, vertical_m : (n,) ``hypot(dE, dN)`` and ``dU``, m.
    along_m, cross_m : (n,) along-track (direction of increasing s) and cross-track
        (positive right of the track) errors, m.
    velocity_mps : (n,) norm of the velocity error, m/s.
    attitude_rad : (n,) norm of psi, rad. heading_rad : (n,) wrapped heading error, rad.
    tangent_heading : (n,) heading of the track tangent at the true arc length, rad.
    sigma : (n, 9) or None, square roots of the covariance diagonal (nan = not given).
    sigma_horizontal_m : (n,) or None, ``sqrt(P_EE + P_NN)`` (the drms of the estimate).
    sigma_along_m, sigma_cross_m : (n,) or None, covariance rotated to the track axes.
    """

    t: np.ndarray
    error: np.ndarray
    horizontal_m: np.ndarray
    vertical_m: np.ndarray
    along_m: np.ndarray
    cross_m: np.ndarray
    velocity_mps: np.ndarray
    attitude_rad: np.ndarray
    heading_rad: np.ndarray
    tangent_heading: np.ndarray
    sigma: np.ndarray | None
    sigma_horizontal_m: np.ndarray | None
    sigma_along_m: np.ndarray | None
    sigma_cross_m: np.ndarray | None


def error_series(record: EpisodeRecord, track: Track | None = None) -> ErrorSeries:
    """Per-step errors of an :class:`~navsim.episode.EpisodeRecord`.

    Parameters
    ----------
    record : EpisodeRecord
    track : optional
        The scenario's track (built with :func:`navsim.simulator.build_track` when
        omitted); its tangent at ``record.truth_s`` splits along / cross track.
    """
    if track is None:
        from .simulator import build_track

        track = build_track(record.scenario)
    from .track import track_frame

    err = error_vector(record)
    frame = track_frame(track, np.asarray(record.truth_s, dtype=float))
    tangent_heading = np.asarray(frame.heading, dtype=float)
    u_e, u_n = np.sin(tangent_heading), np.cos(tangent_heading)
    d_e, d_n = err[:, 0], err[:, 1]
    along = u_e * d_e + u_n * d_n
    cross = u_n * d_e - u_e * d_n  # right of the direction of increasing s
    heading_err = wrap_angle(record.est_hpr[:, 0] - record.truth_hpr[:, 0])
    sigma = sig_h = sig_a = sig_c = None
    cov = record.est_cov
    if cov is not None:
        sigma = _sqrt_nonneg(np.diagonal(cov, axis1=1, axis2=2))
        p_ee, p_nn, p_en = cov[:, 0, 0], cov[:, 1, 1], 0.5 * (cov[:, 0, 1] + cov[:, 1, 0])
        sig_h = _sqrt_nonneg(p_ee + p_nn)
        sig_a = _sqrt_nonneg(u_e * u_e * p_ee + 2.0 * u_e * u_n * p_en + u_n * u_n * p_nn)
        sig_c = _sqrt_nonneg(u_n * u_n * p_ee - 2.0 * u_e * u_n * p_en + u_e * u_e * p_nn)
    return ErrorSeries(
        t=np.asarray(record.t, dtype=float), error=err, horizontal_m=np.hypot(d_e, d_n), vertical_m=err[:, 2],
        along_m=along, cross_m=cross, velocity_mps=np.linalg.norm(err[:, 3:6], axis=1),
        attitude_rad=np.linalg.norm(err[:, 6:9], axis=1), heading_rad=heading_err,
        tangent_heading=tangent_heading, sigma=sigma, sigma_horizontal_m=sig_h, sigma_along_m=sig_a,
        sigma_cross_m=sig_c,
    )


# ============================================================================ statistics
@dataclass(frozen=True, slots=True)
class ErrorStats:
    """Statistics of one error component over the finite steps (same unit as the input).

    rms, max, final are of the absolute value (final: last step, nan if non-finite);
    p50, p95 : percentiles of the absolute value (CEP50 / CEP95 for horizontal error).
    """

    rms: float
    max: float
    final: float
    p50: float
    p95: float


def error_stats(values: np.ndarray) -> ErrorStats:
    """RMS, max, final and 50 / 95 % percentiles of ``|values|`` over the finite entries."""
    values = np.asarray(values, dtype=float)
    a = np.abs(values[np.isfinite(values)])
    final = abs(float(values[-1])) if len(values) and np.isfinite(values[-1]) else math.nan
    if a.size == 0:
        return ErrorStats(math.nan, math.nan, final, math.nan, math.nan)
    p50, p95 = np.percentile(a, [50.0, 95.0])
    return ErrorStats(float(np.sqrt(np.mean(a * a))), float(a.max()), final, float(p50), float(p95))


@dataclass(frozen=True, slots=True)
class Outage:
    """One GNSS outage and the drift inside it.

    Attributes
    ----------
    t_first, t_last : times of the first and last GNSS epoch of the run of bad epochs, s.
    n_epochs : number of bad epochs. duration_s : ``n_epochs * gnss_period``, s.
    t_from, t_to : the steps scored are those with ``t_from < t < t_to`` (last good
        epoch before, first good epoch after; the episode's edges when there is none;
        ``t_to`` is inclusive at the episode's end).
    closed : False when GNSS did not come back before the episode ended.
    max_drift_m : maximum horizontal error over the scored steps, m (nan if none).
    max_vertical_m : maximum absolute vertical error there, m.
    t_max : time of the maximum horizontal error, s.
    """

    t_first: float
    t_last: float
    n_epochs: int
    duration_s: float
    t_from: float
    t_to: float
    closed: bool
    max_drift_m: float = math.nan
    max_vertical_m: float = math.nan
    t_max: float = math.nan

    def as_dict(self) -> dict:
        return {f.name: _json_value(getattr(self, f.name)) for f in dataclasses.fields(self)}


def find_outages(gnss_t: np.ndarray, n_valid: np.ndarray, t_start: float, t_end: float,
                 gnss_period_s: float | None = None, min_satellites: int = MIN_SATELLITES) -> list[Outage]:
    """Maximal runs of GNSS epochs with fewer than ``min_satellites`` valid satellites.

    Parameters
    ----------
    gnss_t, n_valid : (k,) epoch times (s, increasing) and valid satellite counts.
    t_start, t_end : episode start (time of the prior) and end, s.
    gnss_period_s : epoch period (default: the median spacing of ``gnss_t``).

    Returns
    -------
    list of :class:`Outage` without drift figures (see :func:`outage_drifts`).
    """
    gnss_t = np.asarray(gnss_t, dtype=float)
    bad = np.asarray(n_valid) < min_satellites
    if gnss_t.shape != bad.shape:
        raise ConfigError("n_valid", f"one count per GNSS epoch ({gnss_t.shape})", bad.shape)
    if not bad.any():
        return []
    if gnss_period_s is None:
        gnss_period_s = float(np.median(np.diff(gnss_t))) if len(gnss_t) > 1 else float(t_end - t_start)
    edges = np.flatnonzero(np.diff(np.r_[0, bad.astype(np.int8), 0]))
    out = []
    for i0, i1 in zip(edges[::2], edges[1::2] - 1):
        closed = i1 + 1 < len(gnss_t)
        out.append(Outage(
            t_first=float(gnss_t[i0]), t_last=float(gnss_t[i1]), n_epochs=int(i1 - i0 + 1),
            duration_s=float((i1 - i0 + 1) * gnss_period_s),
            t_from=float(gnss_t[i0 - 1]) if i0 > 0 else float(t_start),
            t_to=float(gnss_t[i1 + 1]) if closed else float(t_end), closed=bool(closed),
        ))
    return out


def outage_drifts(t: np.ndarray, horizontal_m: np.ndarray, vertical_m: np.ndarray, outages: Iterable[Outage],
                  tol_s: float | None = None) -> tuple[Outage, ...]:
    """Fill in the maximum horizontal (and vertical) error inside each outage.

    ``tol_s`` (default: half the smallest step) guards the open / closed ends against
    rounding of the time stamps.
    """
    t = np.asarray(t, dtype=float)
    if tol_s is None:
        tol_s = 0.5 * float(np.min(np.diff(t))) if len(t) > 1 else 1e-9
    result = []
    for o in outages:
        upper = t < o.t_to - tol_s if o.closed else t <= o.t_to + tol_s
        inside = (t > o.t_from + tol_s) & upper
        h = np.where(inside & np.isfinite(horizontal_m), horizontal_m, -np.inf)
        if inside.any() and np.isfinite(h.max()):
            k = int(np.argmax(h))
            v = np.abs(np.where(inside & np.isfinite(vertical_m), vertical_m, 0.0))
            result.append(dataclasses.replace(o, max_drift_m=float(h[k]), max_vertical_m=float(v.max()),
                                              t_max=float(t[k])))
        else:
            result.append(o)
    return tuple(result)


def integrated_autocorrelation_time(x: np.ndarray, c: float = 5.0) -> float:
    """Integrated autocorrelation time ``tau = 1 + 2 sum_k rho_k`` of a series.

    The sum runs to the smallest lag M with ``M >= c tau(M)`` (Sokal's automatic
    window [3]); autocorrelations by FFT. tau = 1 for white noise; clipped to
    ``[1, len(x)]``. Non-finite entries are dropped first.
    """
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    n = len(x)
    if n < 4:
        return 1.0
    y = x - x.mean()
    var = float(np.dot(y, y)) / n
    if var == 0.0:
        return float(n)  # a constant sequence carries one sample of information
    size = 1 << (2 * n - 1).bit_length()
    f = np.fft.rfft(y, size)
    acf = np.fft.irfft(f * np.conj(f), size)[:n] / (n * var)
    taus = 2.0 * np.cumsum(acf) - 1.0  # tau(M) = 1 + 2 sum_{k=1..M} rho_k
    window = np.flatnonzero(np.arange(n) >= c * taus)
    tau = float(taus[window[0]]) if window.size else float(taus[-1])
    return float(min(max(tau, 1.0), n))


@dataclass(frozen=True, slots=True)
class NeesSummary:
    """NEES over one episode.

    components : labels of the components used. rank : the dimension d of the NEES: the
    number of components, or less when the covariance claims only a subspace of them (see
    :func:`nees_series`). steps : number of steps with a finite NEES. anees : time
    average of NEES (d when consistent).
    lower, upper : 95 % bounds of the time average, ``chi2.ppf(0.025 / 0.975, d N_eff)
    / N_eff``. n_eff : effective sample count N / tau. in_bounds_fraction : fraction of
    steps with NEES inside the per-step 95 % interval of chi2(d). series : (n,) NEES.
    """

    components: tuple[str, ...]
    steps: int
    anees: float
    lower: float
    upper: float
    n_eff: float
    in_bounds_fraction: float
    series: np.ndarray = field(repr=False)
    rank: int | None = None

    @property
    def dof(self) -> int:
        return len(self.components) if self.rank is None else self.rank


def nees_components(covariance: np.ndarray) -> np.ndarray:
    """Indices of the components whose covariance diagonal is finite at every step that
    has a covariance at all (steps whose whole diagonal is nan are ignored)."""
    diag = np.diagonal(covariance, axis1=1, axis2=2)
    finite = np.isfinite(diag)
    given = finite.any(axis=1)
    if not given.any():
        return np.zeros(0, dtype=int)
    return np.flatnonzero(finite[given].all(axis=0))


# Numerical rank of a covariance block: eigenvalues of its correlation matrix
# D^-1/2 P D^-1/2 (scale-free, so metres, m/s and radians mix safely) below this are zero.
# A full-rank filter's correlation eigenvalues stay far above it (a correlation coefficient
# of 1 - 1e-9 between two states would be needed to reach it); a covariance mapped from r
# states through a Jacobian (the along-track filter: s and v) has 9 - r eigenvalues at
# rounding level, ~1e-16.
RANK_TOLERANCE = 1e-9
_RANK_SAMPLES = 64  # steps sampled to find an episode's claimed rank


def claimed_rank(covariance: np.ndarray, components: Components) -> int:
    """The dimension of the error subspace a filter's covariance claims over
    ``components``: the largest numerical rank (:data:`RANK_TOLERANCE`) of the block at up to
    64 steps sampled evenly over the episode (steps with a non-finite block skipped)."""
    p = covariance[:, components][:, :, components]
    ok = np.flatnonzero(np.all(np.isfinite(p.reshape(len(p), -1)), axis=1))
    if ok.size == 0:
        return len(components)
    pick = ok[np.unique(np.linspace(0, ok.size - 1, min(_RANK_SAMPLES, ok.size)).round().astype(int))]
    block = p[pick]
    d = np.sqrt(np.clip(np.diagonal(block, axis1=1, axis2=2), 0.0, None))
    scale = np.where(d > 0.0, 1.0 / np.where(d > 0.0, d, 1.0), 0.0)
    corr = block * scale[:, :, None] * scale[:, None, :]
    lam = np.linalg.eigvalsh(corr)
    return int(np.max(np.sum(lam > RANK_TOLERANCE * np.maximum(lam[:, -1:], 1e-300), axis=1)))


def nees_subspace(errors: np.ndarray, covariance: np.ndarray, components: Components, rank: int) -> np.ndarray:
    """NEES on the ``rank``-dimensional subspace a singular covariance claims.

    Per step, with the block P = V diag(lam) V^T (eigenvalues descending), NEES =
    sum_{i < rank} (v_i^T e)^2 / lam_i: the Moore-Penrose form e^T P^+ e with P^+ taken on
    the claimed subspace (range of P), i.e. the error projected orthogonally onto it; the
    error outside it (e.g. cross-track, which a map-constrained filter claims is zero) is
    not scored. Chi-square with ``rank`` degrees of freedom when consistent. The rank comes
    from the scale-free :func:`claimed_rank`; the projection is in the block's own units,
    where the range of P is a well-defined subspace.
    """
    e = errors[:, components]
    p = covariance[:, components][:, :, components]
    out = np.full(len(e), np.nan)
    ok = np.all(np.isfinite(p.reshape(len(p), -1)), axis=1) & np.all(np.isfinite(e), axis=1)
    if ok.any():
        lam, v = np.linalg.eigh(p[ok])
        lam, v = lam[:, ::-1][:, :rank], v[:, :, ::-1][:, :, :rank]
        proj = np.einsum("nij,ni->nj", v, e[ok])
        out[ok] = np.sum(proj**2 / lam, axis=1)
    return out


def nees_series(errors: np.ndarray, covariance: np.ndarray, components: Components) -> tuple[np.ndarray, int]:
    """NEES per step and its dimension: over ``components`` when the covariance is full
    rank there (:func:`nees`), else on the subspace it claims (:func:`nees_subspace`)."""
    rank = claimed_rank(covariance, components)
    if rank >= len(components):
        return nees(errors, covariance, components), len(components)
    return nees_subspace(errors, covariance, components, rank), rank


def nees_summary(errors: np.ndarray, covariance: np.ndarray | None, confidence: float = 0.95) -> NeesSummary | None:
    """NEES, ANEES and their chi-square bounds (None without a usable covariance).

    Over the components with a finite covariance (:func:`nees_components`); when the
    covariance there is singular, on the subspace it claims, with that dimension
    (:func:`nees_series`; ``NeesSummary.rank``)."""
    if covariance is None:
        return None
    comps = nees_components(covariance)
    if comps.size == 0:
        return None
    series, d = nees_series(errors, covariance, comps)
    ok = np.isfinite(series)
    if not ok.any():
        return None
    x = series[ok]
    anees = float(x.mean())
    n_eff = len(x) / integrated_autocorrelation_time(x)
    alpha = 1.0 - confidence
    lower, upper = stats.chi2.ppf([alpha / 2, 1.0 - alpha / 2], d * n_eff) / n_eff
    lo1, hi1 = stats.chi2.ppf([alpha / 2, 1.0 - alpha / 2], d)
    inside = float(np.mean((x >= lo1) & (x <= hi1)))
    return NeesSummary(tuple(STATE_LABELS[i] for i in comps), int(len(x)), anees, float(lower), float(upper),
                       float(n_eff), inside, series, rank=d)


@dataclass(frozen=True, slots=True)
class NisSummary:
    """NIS over the measurement updates of one episode.

    updates : number of updates with a NIS. anis : mean NIS per update. mean_dof : mean
    degrees of freedom per update. normalised : ``sum NIS / sum dof`` (1 when
    consistent), lower, upper : its 95 % bounds ``chi2.ppf(q, sum dof) / sum dof``.
    in_bounds_fraction : updates whose NIS lies in the 95 % interval of chi2(dof).
    """

    updates: int
    anis: float
    mean_dof: float
    normalised: float
    lower: float
    upper: float
    in_bounds_fraction: float


def nis_summary(nis: np.ndarray, dof: np.ndarray, confidence: float = 0.95) -> NisSummary | None:
    """NIS statistics (None when no update has a NIS with dof >= 1)."""
    nis = np.asarray(nis, dtype=float)
    dof = np.asarray(dof)
    ok = np.isfinite(nis) & (dof >= 1)
    if not ok.any():
        return None
    x, k = nis[ok], dof[ok].astype(float)
    total = float(k.sum())
    alpha = 1.0 - confidence
    lower, upper = stats.chi2.ppf([alpha / 2, 1.0 - alpha / 2], total) / total
    inside = (x >= stats.chi2.ppf(alpha / 2, k)) & (x <= stats.chi2.ppf(1.0 - alpha / 2, k))
    return NisSummary(int(ok.sum()), float(x.mean()), float(k.mean()), float(x.sum() / total), float(lower),
                      float(upper), float(inside.mean()))


# ============================================================================ the score
# name -> (unit, description); the order is the order of reports
SCORE_FIELDS: dict[str, tuple[str, str]] = {
    "scenario": ("", "scenario name"),
    "estimator": ("", "estimator name"),
    "seed": ("", "random seed of the episode"),
    "duration_s": ("s", "episode length"),
    "steps": ("", "navigation steps"),
}
for _name, _label in (("horizontal", "horizontal position error"), ("vertical", "vertical position error"),
                      ("along_track", "along-track position error"), ("cross_track", "cross-track position error")):
    SCORE_FIELDS.update({
        f"{_name}_rmse_m": ("m", f"{_label}, RMS"),
        f"{_name}_max_m": ("m", f"{_label}, maximum absolute"),
        f"{_name}_final_m": ("m", f"{_label}, absolute at the last step"),
        f"{_name}_cep50_m": ("m", f"{_label}, 50th percentile of the absolute value"),
        f"{_name}_cep95_m": ("m", f"{_label}, 95th percentile of the absolute value"),
    })
SCORE_FIELDS.update({
    "velocity_rms_mps": ("m/s", "3-D velocity error norm, RMS"),
    "velocity_max_mps": ("m/s", "3-D velocity error norm, maximum"),
    "velocity_final_mps": ("m/s", "3-D velocity error norm at the last step"),
    "attitude_rms_deg": ("deg", "attitude error angle |psi|, RMS"),
    "attitude_max_deg": ("deg", "attitude error angle |psi|, maximum"),
    "attitude_final_deg": ("deg", "attitude error angle |psi| at the last step"),
    "heading_rms_deg": ("deg", "heading error, RMS"),
    "heading_max_deg": ("deg", "heading error, maximum absolute"),
    "outage_count": ("", "GNSS outages (runs of epochs with < 4 valid satellites)"),
    "outage_total_s": ("s", "total duration of the outages"),
    "outage_max_drift_m": ("m", "largest maximum horizontal error inside an outage"),
    "outage_rms_drift_m": ("m", "RMS over outages of the maximum horizontal error inside each"),
    "outage_rms_drift_vertical_m": ("m", "RMS over outages of the maximum vertical error inside each"),
    "nees_components": ("", "covariance components used for NEES"),
    "nees_dof": ("", "NEES dimension d (the covariance's rank over nees_components when it claims a subspace)"),
    "anees": ("", "time-average NEES (d when consistent)"),
    "anees_lower": ("", "95 % lower bound of ANEES (chi2 with N_eff = N / tau)"),
    "anees_upper": ("", "95 % upper bound of ANEES"),
    "nees_n_eff": ("", "effective number of independent NEES samples"),
    "nees_in_bounds_fraction": ("", "steps with NEES in the 95 % chi2(d) interval (0.95 when consistent)"),
    "nis_updates": ("", "measurement updates with a NIS"),
    "anis": ("", "mean NIS per update"),
    "nis_mean_dof": ("", "mean NIS degrees of freedom per update"),
    "nis_normalised": ("", "sum NIS / sum dof (1 when consistent)"),
    "nis_normalised_lower": ("", "95 % lower bound of nis_normalised"),
    "nis_normalised_upper": ("", "95 % upper bound of nis_normalised"),
    "nis_in_bounds_fraction": ("", "updates with NIS in the 95 % chi2(dof) interval"),
    "diverged": ("", "non-finite estimate, horizontal error above the threshold, or NEES above the chi2 "
                     "0.9999 quantile for a sustained time (accuracy figures are then NaN)"),
    "diverged_at_s": ("s", "first time of divergence"),
    "divergence_reason": ("", "which divergence checks fired, when and with what value (empty if none)"),
    "divergence_threshold_m": ("m", "horizontal error threshold of the divergence flag"),
    "step_time_us": ("us", "estimator CPU time per navigation step, mean"),
    "cpu_total_s": ("s", "estimator CPU time, total"),
    "realtime_factor": ("", "episode duration / estimator CPU time"),
})
del _name, _label


def _json_value(value: Any) -> Any:
    """JSON-safe scalar: NaN / inf -> None, numpy scalars -> Python."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    return value


@dataclass(frozen=True, slots=True)
class EpisodeScore:
    """Every figure of one episode; units and meanings in :data:`SCORE_FIELDS`
    (field names end in their unit). nan = not available. ``outages`` holds the
    per-outage details (not part of the flat dict)."""

    scenario: str
    estimator: str
    seed: int | None
    duration_s: float
    steps: int
    horizontal_rmse_m: float
    horizontal_max_m: float
    horizontal_final_m: float
    horizontal_cep50_m: float
    horizontal_cep95_m: float
    vertical_rmse_m: float
    vertical_max_m: float
    vertical_final_m: float
    vertical_cep50_m: float
    vertical_cep95_m: float
    along_track_rmse_m: float
    along_track_max_m: float
    along_track_final_m: float
    along_track_cep50_m: float
    along_track_cep95_m: float
    cross_track_rmse_m: float
    cross_track_max_m: float
    cross_track_final_m: float
    cross_track_cep50_m: float
    cross_track_cep95_m: float
    velocity_rms_mps: float
    velocity_max_mps: float
    velocity_final_mps: float
    attitude_rms_deg: float
    attitude_max_deg: float
    attitude_final_deg: float
    heading_rms_deg: float
    heading_max_deg: float
    outage_count: int
    outage_total_s: float
    outage_max_drift_m: float
    outage_rms_drift_m: float
    outage_rms_drift_vertical_m: float
    nees_components: str
    nees_dof: int
    anees: float
    anees_lower: float
    anees_upper: float
    nees_n_eff: float
    nees_in_bounds_fraction: float
    nis_updates: int
    anis: float
    nis_mean_dof: float
    nis_normalised: float
    nis_normalised_lower: float
    nis_normalised_upper: float
    nis_in_bounds_fraction: float
    diverged: bool
    diverged_at_s: float
    divergence_reason: str
    divergence_threshold_m: float
    step_time_us: float
    cpu_total_s: float
    realtime_factor: float
    outages: tuple[Outage, ...] = ()

    def to_flat_dict(self) -> dict:
        """One flat JSON-safe dict (keys carry units; NaN -> None), without ``outages``."""
        return {name: _json_value(getattr(self, name)) for name in SCORE_FIELDS}

    @staticmethod
    def units() -> dict[str, str]:
        """Field name -> unit ("" = dimensionless or a label)."""
        return {name: unit for name, (unit, _) in SCORE_FIELDS.items()}

    @staticmethod
    def descriptions() -> dict[str, str]:
        return {name: text for name, (_, text) in SCORE_FIELDS.items()}


# Fields that measure the accuracy of the estimate: NaN for a diverged episode.
ACCURACY_FIELDS: tuple[str, ...] = tuple(
    name for name in SCORE_FIELDS
    if name.startswith(("horizontal_", "vertical_", "along_track_", "cross_track_", "velocity_", "attitude_",
                        "heading_", "outage_max_drift", "outage_rms_drift")))
# Consistency figures: NaN as well when the estimate is non-finite somewhere.
_CONSISTENCY_FIELDS = ("anees", "anees_lower", "anees_upper", "nees_n_eff", "nees_in_bounds_fraction", "anis",
                       "nis_mean_dof", "nis_normalised", "nis_normalised_lower", "nis_normalised_upper",
                       "nis_in_bounds_fraction")

DIVERGENCE_NEES_QUANTILE = 0.9999
"""Per-step chi2(d) quantile above which the NEES counts as far outside the covariance."""
DIVERGENCE_NEES_WINDOW_S = 20.0
"""Window (s) in which the NEES must stay above that quantile for the episode to count as diverged."""
_NEES_WINDOW_FRACTION = 0.8  # ... at no less than this fraction of the window's steps


@dataclass(frozen=True, slots=True)
class Divergence:
    """Result of :func:`detect_divergence`.

    diverged : any check fired. at_s : earliest time a check fired, s (nan if none).
    reason : the checks that fired, ``"; "``-separated ("" if none). non_finite : check 1
    (non-finite estimate) fired.
    """

    diverged: bool
    at_s: float
    reason: str
    non_finite: bool


def detect_divergence(t: np.ndarray, estimate: Mapping[str, np.ndarray], horizontal_m: np.ndarray,
                      nees_per_step: np.ndarray | None = None, nees_dof: int = 0, *, dt: float | None = None,
                      threshold_m: float = 1000.0, nees_quantile: float = DIVERGENCE_NEES_QUANTILE,
                      nees_window_s: float = DIVERGENCE_NEES_WINDOW_S) -> Divergence:
    """The filter-independent divergence checks of the module docstring (checks 1-3).

    Parameters
    ----------
    t : (n,) step end times, s.
    estimate : ``{"position": (n, 3), "velocity": (n, 3), "attitude": (n, 3)}`` (any
        subset; position is checked at every step, the others only where they are given
        at some step).
    horizontal_m : (n,) horizontal error, m.
    nees_per_step, nees_dof : per-step NEES on the claimed subspace and its dimension d
        (None / 0: check 3 skipped).
    dt : step length, s (default: the median spacing of ``t``); the window of check 3
        holds ``round(nees_window_s / dt)`` steps.
    threshold_m : horizontal threshold of check 2, m (> 0).
    nees_quantile : q of check 3, in (0, 1). nees_window_s : its window, s (> 0; ``inf``
        switches check 3 off).
    """
    if not threshold_m > 0:
        raise ConfigError("divergence_threshold_m", "a positive number", threshold_m)
    if not 0.0 < nees_quantile < 1.0:
        raise ConfigError("divergence_nees_quantile", "a probability in (0, 1)", nees_quantile)
    if not nees_window_s > 0:
        raise ConfigError("divergence_nees_window_s", "a positive number of seconds", nees_window_s)
    t = np.asarray(t, dtype=float)
    n = len(t)
    if n == 0:
        return Divergence(False, math.nan, "", False)
    if dt is None:
        dt = float(np.median(np.diff(t))) if n > 1 else 0.0
    found: list[tuple[float, str]] = []
    non_finite = False
    for key in ("position", "velocity", "attitude"):
        x = estimate.get(key)
        if x is None:
            continue
        ok = np.all(np.isfinite(np.asarray(x, dtype=float).reshape(n, -1)), axis=1)
        if ok.all() or (key != "position" and not ok.any()):
            continue
        non_finite = True
        k = int(np.argmin(ok))
        found.append((float(t[k]), f"non-finite {key} estimate at {t[k]:.6g} s ({int((~ok).sum())} of {n} steps)"))
    h = np.asarray(horizontal_m, dtype=float)
    above = np.nan_to_num(h, nan=0.0) > threshold_m
    if above.any():
        k = int(np.argmax(above))
        found.append((float(t[k]), f"horizontal error {h[k]:.6g} m > {threshold_m:g} m at {t[k]:.6g} s"))
    if nees_per_step is not None and nees_dof >= 1 and math.isfinite(nees_window_s):
        x = np.asarray(nees_per_step, dtype=float)
        limit = float(stats.chi2.ppf(nees_quantile, nees_dof))
        over = np.nan_to_num(x, nan=0.0) > limit
        m = int(round(nees_window_s / dt)) if dt > 0 else n + 1
        if 1 <= m <= n and over.any():
            count = np.convolve(over.astype(np.int64), np.ones(m, dtype=np.int64), mode="valid")  # per window start
            hit = np.flatnonzero(count >= math.ceil(_NEES_WINDOW_FRACTION * m))
            if hit.size:
                k0 = int(hit[0])
                a = k0 + int(np.argmax(over[k0:k0 + m]))  # first step above the limit in that window
                found.append((float(t[a]), f"NEES > {limit:.4g} (chi2({nees_dof}) {nees_quantile:g} quantile) at "
                              f"{int(count[k0])} of the {m} steps of the {nees_window_s:g}-s window from {t[k0]:.6g} s "
                              f"(max there {x[k0:k0 + m].max():.4g})"))
    if not found:
        return Divergence(False, math.nan, "", False)
    found.sort(key=lambda r: r[0])
    return Divergence(True, found[0][0], "; ".join(r for _, r in found), non_finite)


def score_episode(record: EpisodeRecord, *, track: Track | None = None, series: ErrorSeries | None = None,
                  divergence_threshold_m: float = 1000.0, min_satellites: int = MIN_SATELLITES,
                  divergence_nees_quantile: float = DIVERGENCE_NEES_QUANTILE,
                  divergence_nees_window_s: float = DIVERGENCE_NEES_WINDOW_S) -> EpisodeScore:
    """Score one :class:`~navsim.episode.EpisodeRecord` (see the module docstring).

    Parameters
    ----------
    record : EpisodeRecord
    track : the scenario's track (built from ``record.scenario`` when omitted).
    series : precomputed :func:`error_series` of the record (saves recomputing it).
    divergence_threshold_m : horizontal error above which the episode counts as diverged, m.
    divergence_nees_quantile, divergence_nees_window_s : the NEES check of
        :func:`detect_divergence` (chi2 quantile, window in s).

    A diverged episode (:func:`detect_divergence`) has NaN accuracy figures
    (:data:`ACCURACY_FIELDS`) and its reason in ``divergence_reason``.
    """
    if not divergence_threshold_m > 0:
        raise ConfigError("divergence_threshold_m", "a positive number", divergence_threshold_m)
    s = series if series is not None else error_series(record, track)
    t = s.t
    n = len(t)
    timing = record.scenario.timing
    dt = float(timing.nav_period_s)
    t_start = float(t[0] - dt) if n else 0.0
    t_end = float(t[-1]) if n else 0.0
    h, v, a, c = (error_stats(x) for x in (s.horizontal_m, s.vertical_m, s.along_m, s.cross_m))
    vel, att, head = error_stats(s.velocity_mps), error_stats(np.degrees(s.attitude_rad)), error_stats(np.degrees(s.heading_rad))
    outages: Sequence[Outage] = find_outages(record.gnss_t, record.gnss_n_valid, t_start, t_end, timing.gnss_period_s,
                                             min_satellites)
    outages = outage_drifts(t, s.horizontal_m, s.vertical_m, outages, tol_s=0.5 * dt)
    drifts = np.array([o.max_drift_m for o in outages if math.isfinite(o.max_drift_m)])
    vdrifts = np.array([o.max_vertical_m for o in outages if math.isfinite(o.max_vertical_m)])
    ns = nees_summary(s.error, record.est_cov)
    nis = nis_summary(record.nis, record.nis_dof)
    position = np.column_stack([record.est_lat, record.est_lon, record.est_h])
    div = detect_divergence(
        t, {"position": position, "velocity": record.est_velocity_n, "attitude": record.est_hpr}, s.horizontal_m,
        ns.series if ns else None, ns.dof if ns else 0, dt=dt, threshold_m=divergence_threshold_m,
        nees_quantile=divergence_nees_quantile, nees_window_s=divergence_nees_window_s)
    cpu = np.asarray(record.step_time_s, dtype=float)
    cpu_total = float(cpu.sum())
    nan = math.nan
    fields = dict(
        scenario=record.scenario.name, estimator=record.estimator, seed=record.seed,
        duration_s=float(n * dt), steps=n,
        **_stats_fields("horizontal", h), **_stats_fields("vertical", v),
        **_stats_fields("along_track", a), **_stats_fields("cross_track", c),
        velocity_rms_mps=vel.rms, velocity_max_mps=vel.max, velocity_final_mps=vel.final,
        attitude_rms_deg=att.rms, attitude_max_deg=att.max, attitude_final_deg=att.final,
        heading_rms_deg=head.rms, heading_max_deg=head.max,
        outage_count=len(outages), outage_total_s=float(sum(o.duration_s for o in outages)),
        outage_max_drift_m=float(drifts.max()) if drifts.size else nan,
        outage_rms_drift_m=float(np.sqrt(np.mean(drifts**2))) if drifts.size else nan,
        outage_rms_drift_vertical_m=float(np.sqrt(np.mean(vdrifts**2))) if vdrifts.size else nan,
        nees_components=",".join(ns.components) if ns else "", nees_dof=ns.dof if ns else 0,
        anees=ns.anees if ns else nan, anees_lower=ns.lower if ns else nan, anees_upper=ns.upper if ns else nan,
        nees_n_eff=ns.n_eff if ns else nan, nees_in_bounds_fraction=ns.in_bounds_fraction if ns else nan,
        nis_updates=nis.updates if nis else 0, anis=nis.anis if nis else nan,
        nis_mean_dof=nis.mean_dof if nis else nan, nis_normalised=nis.normalised if nis else nan,
        nis_normalised_lower=nis.lower if nis else nan, nis_normalised_upper=nis.upper if nis else nan,
        nis_in_bounds_fraction=nis.in_bounds_fraction if nis else nan,
        diverged=div.diverged, diverged_at_s=div.at_s, divergence_reason=div.reason,
        divergence_threshold_m=float(divergence_threshold_m),
        step_time_us=float(cpu.mean() * 1e6) if n else nan, cpu_total_s=cpu_total,
        realtime_factor=float(n * dt / cpu_total) if cpu_total > 0 else nan,
        outages=outages,
    )
    if div.diverged:  # never a figure computed from the finite / pre-divergence fraction
        fields.update(dict.fromkeys(ACCURACY_FIELDS, nan))
        fields["outages"] = tuple(dataclasses.replace(o, max_drift_m=nan, max_vertical_m=nan, t_max=nan)
                                  for o in outages)
        if div.non_finite:
            fields.update(dict.fromkeys(_CONSISTENCY_FIELDS, nan))
    return EpisodeScore(**fields)


def _stats_fields(prefix: str, st: ErrorStats) -> dict:
    return {f"{prefix}_rmse_m": st.rms, f"{prefix}_max_m": st.max, f"{prefix}_final_m": st.final,
            f"{prefix}_cep50_m": st.p50, f"{prefix}_cep95_m": st.p95}


# ============================================================================ Monte Carlo
@dataclass(frozen=True, slots=True)
class MetricSummary:
    """One metric across seeds: mean, 95 % interval [low, high] (see :func:`aggregate`),
    sample standard deviation, number of finite per-seed values and the unit."""

    name: str
    unit: str
    mean: float
    low: float
    high: float
    std: float
    n: int
    method: str

    def as_dict(self) -> dict:
        return {f.name: _json_value(getattr(self, f.name)) for f in dataclasses.fields(self)}


NUMERIC_FIELDS: tuple[str, ...] = tuple(
    name for name in SCORE_FIELDS
    if name not in ("scenario", "estimator", "seed", "nees_components", "divergence_reason"))


def _summary_of(name: str, unit: str, values: np.ndarray, method: str, confidence: float) -> MetricSummary:
    x = values[np.isfinite(values)]
    n = int(x.size)
    if n == 0:
        return MetricSummary(name, unit, math.nan, math.nan, math.nan, math.nan, 0, method)
    mean = float(x.mean())
    std = float(x.std(ddof=1)) if n > 1 else math.nan
    alpha = 1.0 - confidence
    if n == 1:
        low = high = math.nan
    elif method == "t":
        half = float(stats.t.ppf(1.0 - alpha / 2, n - 1)) * std / math.sqrt(n)
        low, high = mean - half, mean + half
    else:
        low, high = (float(q) for q in np.percentile(x, [100 * alpha / 2, 100 * (1 - alpha / 2)]))
    return MetricSummary(name, unit, mean, low, high, std, n, method)


def aggregate(scores: Sequence[EpisodeScore | Mapping], *, method: str = "t",
              confidence: float = 0.95) -> dict[str, MetricSummary]:
    """Mean and interval of every numeric metric across episodes (seeds).

    Parameters
    ----------
    scores : EpisodeScore objects or their flat dicts (None / NaN entries are skipped
        per metric; ``n`` tells how many values entered).
    method : "t"
        Student-t confidence interval of the mean, ``mean +- t_{(1+c)/2, n-1} s/sqrt(n)``
        (how well the mean is known); "percentile": the (1-c)/2 and (1+c)/2 percentiles
        of the per-seed values (where single runs fall). Both need n >= 2 (nan otherwise).
    confidence : interval probability, default 0.95.
    """
    if method not in ("t", "percentile"):
        raise ConfigError("method", "'t' or 'percentile'", method)
    if not 0.0 < confidence < 1.0:
        raise ConfigError("confidence", "a probability in (0, 1)", confidence)
    rows = [s.to_flat_dict() if isinstance(s, EpisodeScore) else dict(s) for s in scores]
    units = EpisodeScore.units()
    out = {}
    for name in NUMERIC_FIELDS:
        values = np.array([float(r[name]) if r.get(name) is not None else math.nan for r in rows], dtype=float)
        out[name] = _summary_of(name, units[name], values, method, confidence)
    return out


@dataclass(frozen=True, slots=True)
class McNees:
    """Monte Carlo NEES over M runs: ``mean`` (n,) average NEES per step over the runs
    finite there, ``runs`` (n,) how many, ``lower`` / ``upper`` (n,) the 95 % bounds
    ``chi2.ppf(q, runs d) / runs``, ``in_bounds_fraction`` of steps with M runs inside,
    ``anees`` the time average of ``mean``."""

    mean: np.ndarray
    runs: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    in_bounds_fraction: float
    anees: float
    dof: int


def monte_carlo_nees(nees_runs: np.ndarray, dof: int, confidence: float = 0.95) -> McNees:
    """Bar-Shalom's Monte Carlo consistency test [1]: (M, n) NEES of M independent runs
    on the same time grid (nan = missing), dimension ``dof``."""
    x = np.atleast_2d(np.asarray(nees_runs, dtype=float))
    finite = np.isfinite(x)
    runs = finite.sum(axis=0)
    total = np.where(finite, x, 0.0).sum(axis=0)
    mean = np.full(x.shape[1], np.nan)
    has = runs > 0
    mean[has] = total[has] / runs[has]
    alpha = 1.0 - confidence
    lower = np.full_like(mean, np.nan)
    upper = np.full_like(mean, np.nan)
    lower[has] = stats.chi2.ppf(alpha / 2, runs[has] * dof) / runs[has]
    upper[has] = stats.chi2.ppf(1 - alpha / 2, runs[has] * dof) / runs[has]
    full = runs == x.shape[0]
    inside = float(np.mean((mean[full] >= lower[full]) & (mean[full] <= upper[full]))) if full.any() else math.nan
    anees = float(mean[has].mean()) if has.any() else math.nan
    return McNees(mean, runs, lower, upper, inside, anees, int(dof))
