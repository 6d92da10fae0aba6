"""Ideal IMU increments and truth at sample instants, fast and to near machine precision.

Two methods give the same quantities:

*direct*
    For each IMU sample, the true ``omega_ib_b`` and ``specific_force_b`` at
    Gauss-Legendre nodes inside the sample, combined into the r-fold integrals of seed
    000 eq. (1.14) by :func:`navsim.sensors.imu.multiple_integral_rule`, and the full
    true state evaluated at each sample end. A sample that contains a *breakpoint* of
    the motion (below) is integrated piecewise: Gauss-Legendre on each side of the
    breakpoint with the Cauchy kernel of the whole sample (see :meth:`TruthGenerator.
    _split_samples`), so it is exact there too.
*block* (default where the motion is known in advance)
    The samples are grouped in fixed blocks (about ``block_s`` seconds, aligned to the
    absolute sample index). On a block every channel of the truth (rates, specific
    force, position, velocity, attitude, along-track motion) is fitted by a Chebyshev
    polynomial of degree N - 1 through N Chebyshev nodes; the multiple integrals over
    every sample and the values at every sample end are then exact linear functions
    of the node values, applied as one precomputed matrix. Only N truth evaluations are
    needed per block instead of ``(nodes + 1)`` per sample.

Breakpoints. Scripted motion is piecewise analytic: a :class:`~navsim.motion.Timetable`
has a jump in the second derivative of its acceleration at every ramp start and end
(``profile.breakpoints``), and a spline track's pieces join C^4 at its knots
(``track.knot_s``), where the design cant, which follows the curvature, has a kink in
its rate. The generator finds, once, the times where the motion crosses them (profile
breakpoints directly; knots by bisection of s(t) = s_knot, s(t) being monotonic between
profile breakpoints) and splits every block that contains one:

* maximal *runs* of whole samples between breakpoints are fitted like blocks (a run of m
  samples uses its own cached matrices for (m, N)); N grows with the run's length
  (about ``cheb_nodes * sqrt(m / block) + 2`` rounded up to a rung of 12, 16, 20, ...,
  ``cheb_nodes``) and climbs the rungs if the tail check fails; runs so short that
  N >= m (nodes + 1) use the direct method, which is then cheaper;
* a sample that straddles a breakpoint is integrated piecewise (exact, above) with
  ``max(nodes, R + 1)`` nodes per piece.

Breakpoints within 1e-9 samples of a sample boundary are put on it (no straddling
sample). The decomposition is a function of the absolute breakpoints and block index
only, so the chunk invariance of the block method is kept.

The fit is checked a posteriori on every block and run: with ``scale`` the sum of the
magnitudes of a channel's Chebyshev coefficients (shared by the components of a vector,
and at least a physical floor: Earth rate for the rates, 1 m/s^2, 1 m/s, 1 m and 1 rad for
the others, so that a channel that happens to be near zero - a heading near north, the
speed at a stop - is judged on the absolute rounding of the quantity, not on its own
relative noise), the fit passes if the last two coefficients are below ``tol * scale``
(1e-13), or if they sit on a plateau - the rounding noise of the truth evaluation itself,
which reaches 1e-12 of a rate in the urban road's turns and 1e-11 of the Earth-rate floor
on its straights - namely below 1e-12 ``scale`` with the last 8 coefficients no larger
than 4 times the last two, or below ``noise_tol * scale`` (1e-10) with the whole upper
half that flat. A kink's algebraic tail (c_k ~ k^-p) is flat over 8 coefficients but
falls by 2^p >= 4 over the upper half: with splitting switched off, 0.4 % of the blocks
that contain a breakpoint pass (those where the kink is below 1e-12). A block or run
that fails is computed with the direct method instead.
So the choice is a deterministic function of the block, and the numbers do not depend
on how the episode is chunked.

External motion (pushed step by step) is always computed with the direct method: its
future is unknown, and its quintic Hermite pieces join with limited smoothness.

Where it pays (``benchmarks/bench_generation.py``, whole episodes, truth generator alone,
loaded 2-core VM, CPU time, spread of repeated runs): mountain railway (200 Hz) 24 k ->
175-215 k samples/s, urban road (100 Hz, a knot every 2 m, about 7 per second) 21 k ->
53-88 k samples/s, paper track (100 Hz, 1000 s, no breakpoints) 0.31-0.41 -> 0.60-0.78 M
samples/s (through the simulator, truth + ideal IMU: 0.36 -> 0.79 M; at 1 kHz 1.09 ->
1.52 M). The
share of blocks in which some fit falls back to the direct method went from 97 % / 98 %
to 5 % / 22 % (0.2 % / 0.5 % of the samples); 0.9 % / 5.2 % of the samples straddle a
breakpoint and are integrated piecewise. On the paper track the floors of the tail
check removed the 11 % of blocks that fell back on the relative noise of a heading near
north. On the urban road about 1.7 truth evaluations per sample remain (runs of ~14
samples with 16 nodes, 11 evaluations per straddling sample); fitting each run on its
exact breakpoint-to-breakpoint span would remove the straddlers' evaluations at the
price of per-run matrices.

Accuracy. Away from breakpoints, fits agree with 12-node Gauss-Legendre to < 3e-13 of the
largest increment in the first 100-300 s of both spline scenarios; later the truth
evaluation itself is noisier (two direct evaluations with 12 and 20 nodes disagree by up
to 3.6e-12 at t = 450 s on the urban road and 1784 s on the mountain line): the arc
length of a :class:`~navsim.motion.Timetable` is a sum of ramp integrals that all grow
with t, so s(t) carries ~1e-10 m of rounding noise late in an episode, which the urban
road's tight curves turn into ~1e-10 m/s^2 of specific force noise. At a straddling
sample the previous direct rule (4 nodes across the kink) was wrong by up to 1e-5 of the
sample's own rate increment on the urban road (8e-9 of the largest increment; 2e-8 for
the velocity increments; at most 5e-11 rad and 3e-9 m/s per sample, as if the rate and
specific force were off by 5e-9 rad/s and 3e-7 m/s^2 for one sample) and 3e-7 (3e-8; 9e-12
rad, 1e-11 m/s) on the mountain railway; piecewise it agrees with a 24-node-per-piece
reference to 1e-15 of the largest increment.

References
----------
.. [1] Litmanovich Yu.A. (2002), seed 000, eq. (1.14).
.. [2] Trefethen L.N., Approximation Theory and Approximation Practice, SIAM 2013,
       ch. 3-4 (Chebyshev interpolation and the decay of its coefficients).
.. [3] Aurentz J.L., Trefethen L.N., Chopping a Chebyshev series, ACM TOMS 43(4), 2017
       (a plateau of the coefficients at the noise level as the convergence test).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np

from . import truthgen_kernel as _truth_kernel
from .earth import mat_en
from .motion import ExternalMotion, TrueState, body_kinematics, true_state, truth_channels
from .rotations import mat_nb_from_hpr
from .sensors.imu import multiple_integral_rule
from .threads import limited

if TYPE_CHECKING:  # type hints only
    from .motion import Oscillation, SpeedProfile
    from .track import Track

__all__ = ["IdealSamples", "TruthGenerator"]

# truth channels interpolated on blocks (vectors expanded to components)
_SCALAR_FIELDS = ("s", "speed", "accel_along", "lat", "lon", "h", "heading", "pitch", "roll")
_N_CHANNELS = 18
_HEADING = 15  # column of the heading in the channel array
_VECTOR_GROUPS = (slice(0, 3), slice(3, 6), slice(6, 9))
# smallest scale of each channel in the tail check (units of the channel): Earth rate for
# omega_ib_b (rad/s), then m/s^2, m/s, m, m/s, m/s^2, rad, rad, m, rad, rad, rad
_SCALE_FLOOR = np.array([7.292115e-5] * 3 + [1.0] * 15)
_PLATEAU_RATIO = 4.0  # plateau: max of the window at most this times the last 2
_SHORT_PLATEAU_TOL = 1e-12  # largest tail accepted on a plateau of the last 8 coefficients
_RUNGS = (12, 16, 20, 24, 28)  # node counts tried on short runs (then cheb_nodes)
_SNAP = 1e-9  # breakpoints this close (in samples) to a sample boundary are put on it
_BISECTION_STEPS = 20  # knot crossing times: bisection steps, then
_NEWTON_STEPS = 4  # safeguarded Newton steps
_MATRIX_CACHE: OrderedDict = OrderedDict()  # run matrices, see _run_matrices
_MATRIX_CACHE_BYTES = 64 * 2**20
_matrix_cache_bytes = 0
USE_KERNEL = True  # sample-end truth by the compiled pass when numba is installed (navsim.truthgen_kernel)


@dataclass(frozen=True, slots=True)
class IdealSamples:
    """Error-free IMU output and truth for n consecutive samples.

    dtheta_r, dv_r : (n, R, 3) r-fold integrals over each sample. omega_end, force_end :
    (n, 3) true rate and specific force at each sample end. truth : TrueState at the
    sample ends. used_block : (n,) bool, True where a Chebyshev fit (block or run)
    produced the sample, False where the direct method did.
    """

    dtheta_r: np.ndarray
    dv_r: np.ndarray
    omega_end: np.ndarray
    force_end: np.ndarray
    truth: TrueState
    used_block: np.ndarray


class TruthGenerator:
    """Generate :class:`IdealSamples` for sample ranges of one episode.

    Parameters
    ----------
    track, profile, oscillations
        The motion (see :mod:`navsim.motion`).
    h : float
        IMU sample period, s.
    orders : int
        Number of multiple-integral orders R.
    n_nodes : int
        Gauss-Legendre nodes per sample of the direct method.
    t_end : float
        End of the episode, s: blocks reaching past it use the direct method, so the
        motion is never fitted outside the episode.
    block_s : float
        Target block length, s (a block is ``max(1, round(block_s / h))`` samples).
    cheb_nodes : int
        Chebyshev nodes per block (N).
    tol : float
        Relative tolerance of the a-posteriori tail check.
    noise_tol : float
        Relative tolerance of the tail when the coefficients have reached a plateau (the
        rounding noise of the truth evaluation); ``noise_tol <= tol`` switches it off.
    split_at_breakpoints : bool
        Find the motion's breakpoints and split blocks and samples there (default). False:
        no splitting, as before this option existed (a block across a breakpoint fails the
        tail check and falls back, and the direct method integrates a straddling sample
        across its kink, first-order accurate there); for comparisons and benchmarks.

    Attributes
    ----------
    breakpoints : ndarray
        Breakpoint times in units of samples (t / h), increasing; integers where a
        breakpoint falls (within 1e-9 samples) on a sample boundary.
    """

    def __init__(self, track: Track, profile: SpeedProfile, oscillations: Sequence[Oscillation], h: float,
                 orders: int, n_nodes: int, t_end: float, block_s: float = 1.0, cheb_nodes: int = 32, tol: float = 1e-13,
                 noise_tol: float = 1e-10, split_at_breakpoints: bool = True):
        self.track, self.profile, self.oscillations = track, profile, tuple(oscillations)
        self.h, self.orders, self.t_end = float(h), int(orders), float(t_end)
        self.n_nodes = int(n_nodes)
        self._nodes, self._weights = multiple_integral_rule(n_nodes, orders)
        # piecewise rule for straddling samples: at least R + 1 nodes per piece (a piece is
        # at most one sample long; 4, 5, 6, 8 nodes agree with 16 to the truth's rounding
        # noise on the bundled scenarios)
        self._split_nodes = max(self.n_nodes, self.orders + 1)
        self.block = max(1, int(round(block_s / h)))
        self.cheb_nodes = int(cheb_nodes)
        self.tol = float(tol)
        self.noise_tol = float(noise_tol)
        self._rungs = tuple(n for n in _RUNGS if n < self.cheb_nodes) + (self.cheb_nodes,)
        scripted = not isinstance(profile, ExternalMotion)
        self.use_blocks = scripted and self.block >= 4
        self.breakpoints = self._find_breakpoints() if scripted and split_at_breakpoints else np.zeros(0)
        if self.use_blocks:
            self._build_block_matrices()
        self._cache: dict[int, IdealSamples] = {}

    # ------------------------------------------------------------------ block matrices
    def _build_block_matrices(self) -> None:
        self._tau, self._coef_from_values, self._end_matrix, self._int_matrix = self._run_matrices(
            self.block, self.cheb_nodes)

    def _run_matrices(self, m: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Node offsets (s), values -> coefficients, values -> sample-end values and
        values -> multiple integrals, for a run of m samples fitted with n nodes."""
        return _run_matrices(m, n, self.orders, self.h)

    # ------------------------------------------------------------------ breakpoints
    def _find_breakpoints(self) -> np.ndarray:
        """Times (in samples) where the scripted motion is not analytic, sorted, unique."""
        h = self.h
        span = self.block * h
        t_lim = (math.floor(self.t_end / span) + 2) * span
        prof: np.ndarray = np.asarray(getattr(self.profile, "breakpoints", np.zeros(0)), dtype=float).ravel()
        prof = prof[(prof > 0.0) & (prof < t_lim)]
        times = [prof]
        knots = np.sort(np.asarray(getattr(self.track, "knot_s", np.zeros(0)), dtype=float).ravel())
        if knots.size:
            grid = np.unique(np.concatenate([np.linspace(0.0, t_lim, int(math.ceil(t_lim / span)) + 1), prof]))
            s = np.asarray(self.profile.evaluate(grid)[0], dtype=float)
            # knots met exactly at a grid time
            times.append(grid[np.isin(s, knots)])
            # knots strictly between the arc lengths at the ends of a grid interval: one
            # crossing (s is monotonic between profile breakpoints, which are in the grid)
            lo_s, hi_s = np.minimum(s[:-1], s[1:]), np.maximum(s[:-1], s[1:])
            first = np.searchsorted(knots, lo_s, side="right")
            count = np.maximum(np.searchsorted(knots, hi_s, side="left") - first, 0)
            interval = np.repeat(np.arange(grid.size - 1), count)
            offset = np.repeat(np.cumsum(count) - count, count)
            target = knots[first[interval] + np.arange(interval.size) - offset]
            t_lo, t_hi = grid[interval], grid[interval + 1]
            sign_lo = np.sign(s[interval] - target)
            # s(t) = s_knot: bisection to a bracket of span / 2^20, then Newton steps with
            # ds/dt, each kept inside the bracket (else bisected); fixed step counts, so the
            # result is deterministic
            t_mid = 0.5 * (t_lo + t_hi)
            for step in range(_BISECTION_STEPS + _NEWTON_STEPS):
                s_mid, v_mid, _ = self.profile.evaluate(t_mid)
                f = s_mid - target
                same = np.sign(f) == sign_lo
                t_lo = np.where(same, t_mid, t_lo)
                t_hi = np.where(same, t_hi, t_mid)
                bisect = 0.5 * (t_lo + t_hi)
                if step < _BISECTION_STEPS:
                    t_mid = bisect
                    continue
                with np.errstate(divide="ignore", invalid="ignore"):
                    newton = t_mid - f / v_mid
                t_mid = np.where((newton >= t_lo) & (newton <= t_hi), newton, bisect)
            times.append(t_mid)
        t = np.unique(np.concatenate(times))
        t = t[(t > 0.0) & (t < t_lim)]
        beta = t / h
        near = np.rint(beta)
        beta = np.where(np.abs(beta - near) <= _SNAP, near, beta)
        return np.unique(beta)

    def _inside(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Index range [a, b) of the breakpoints strictly inside (lo, hi) (sample units)."""
        bp = self.breakpoints
        return np.searchsorted(bp, lo, side="right"), np.searchsorted(bp, hi, side="left")

    # ------------------------------------------------------------------ public
    @limited  # small products: single-threaded BLAS (navsim.threads)
    def samples(self, i0: int, n: int) -> IdealSamples:
        """Ideal output and truth for samples ``i0 .. i0 + n - 1``."""
        if not self.use_blocks:
            return self._direct(np.arange(i0, i0 + n))
        b = self.block
        first, last = i0 // b, (i0 + n - 1) // b
        blocks = self._blocks(first, last + 1)
        lo = i0 - first * b
        return _slice(blocks, lo, lo + n)

    # ------------------------------------------------------------------ direct method
    def _direct(self, index: np.ndarray) -> IdealSamples:
        """Direct method for samples ``index``; piecewise on samples that straddle a breakpoint."""
        index = np.asarray(index)
        if self.breakpoints.size == 0 or index.size == 0:
            return self._direct_plain(index)
        a, b = self._inside(index, index + 1)
        straddle = b > a
        if not straddle.any():
            return self._direct_plain(index)
        parts = [(np.flatnonzero(straddle), self._split_samples(index[straddle]))]
        if not straddle.all():
            parts.append((np.flatnonzero(~straddle), self._direct_plain(index[~straddle])))
        return _gather(index.size, parts)

    def _direct_plain(self, index: np.ndarray) -> IdealSamples:
        h = self.h
        n, q = len(index), len(self._nodes)
        t_start = index * h
        t_nodes = t_start[:, None] + self._nodes[None, :] * h
        # one evaluation for the quadrature nodes and the sample ends (fewer numpy calls)
        state = true_state(self.track, self.profile, np.concatenate([t_nodes.ravel(), (index + 1) * h]),
                           self.oscillations)
        omega_nodes = state.omega_ib_b[: n * q].reshape(n, q, 3)
        force_nodes = state.specific_force_b[: n * q].reshape(n, q, 3)
        powers = h ** np.arange(1, self.orders + 1)
        # (1.14): r-fold integral = h^r sum_j w[r-1, j] g(t_k + tau_j h)
        dtheta = powers[None, :, None] * np.einsum("rj,njc->nrc", self._weights, omega_nodes)
        dv = powers[None, :, None] * np.einsum("rj,njc->nrc", self._weights, force_nodes)
        truth = TrueState(**{f: getattr(state, f)[n * q:] for f in TrueState.__dataclass_fields__})
        return IdealSamples(dtheta, dv, truth.omega_ib_b, truth.specific_force_b, truth,
                            np.zeros(len(index), dtype=bool))

    def _split_samples(self, index: np.ndarray) -> IdealSamples:
        """Samples that contain breakpoints, integrated piece by piece.

        With the sample [t_k, t_k + h] cut at fractions 0 < f_1 < ... < f_p < 1, the
        r-fold integral (1.14) is, by Cauchy's formula,
        ``h^r sum_pieces int_{f_i}^{f_i+1} (1 - u)^(r-1) / (r-1)! g(t_k + u h) du``: each
        piece gets Gauss-Legendre nodes of its own (the integrand is analytic on it) and
        the kernel of the whole sample, which is the same as composing the pieces' own
        multiple integrals with :func:`navsim.sensors.imu.compose_multiple_integrals`'
        binomial relation, without the intermediate step.
        """
        h, R = self.h, self.orders
        bp = self.breakpoints
        a, b = self._inside(index, index + 1)
        count = b - a  # breakpoints inside each sample (>= 1)
        n_pieces = count + 1
        owner = np.repeat(np.arange(index.size), n_pieces)
        start = np.cumsum(n_pieces) - n_pieces
        r = np.arange(owner.size) - start[owner]  # piece number within its sample
        last = bp.size - 1
        left = np.where(r == 0, 0.0, bp[np.minimum(a[owner] + r - 1, last)] - index[owner])
        right = np.where(r == count[owner], 1.0, bp[np.minimum(a[owner] + r, last)] - index[owner])
        x, w = _gauss_legendre(self._split_nodes)
        u = left[:, None] + (right - left)[:, None] * (0.5 * (x + 1.0))[None, :]  # (P, q) in the sample
        weight = (right - left)[:, None] * (0.5 * w)[None, :]
        order = np.arange(R)
        inv_fact = np.array([1.0 / math.factorial(k) for k in order])
        kern = (h ** (order + 1) * inv_fact)[None, :, None] * (1.0 - u)[:, None, :] ** order[None, :, None] \
            * weight[:, None, :]  # (P, R, q)
        t_nodes = index[owner][:, None] * h + u * h
        q = self._split_nodes
        omega, force = body_kinematics(self.track, self.profile, t_nodes.ravel(), self.oscillations)
        dtheta = np.add.reduceat(np.einsum("prj,pjc->prc", kern, omega.reshape(-1, q, 3)), start, axis=0)
        dv = np.add.reduceat(np.einsum("prj,pjc->prc", kern, force.reshape(-1, q, 3)), start, axis=0)
        truth = true_state(self.track, self.profile, (index + 1) * h, self.oscillations)
        return IdealSamples(dtheta, dv, truth.omega_ib_b, truth.specific_force_b, truth,
                            np.zeros(index.size, dtype=bool))

    # ------------------------------------------------------------------ block method
    def _blocks(self, k0: int, k1: int) -> IdealSamples:
        """Blocks k0 .. k1 - 1, all fitted in one vectorised pass; the newest is cached."""
        b, h = self.block, self.h
        cached = self._cache.get(k0)
        if cached is not None and k1 == k0 + 1:
            return cached
        parts = [cached] if cached is not None else []
        start = k0 + len(parts)
        # blocks that end after the episode use the direct method
        last_full = int(np.floor((self.t_end + 1e-9 * h) / (b * h)))  # blocks 0 .. last_full-1 fit
        fit_end = max(start, min(k1, last_full))
        if fit_end > start:
            parts.append(self._fit_blocks(np.arange(start, fit_end)))
        if k1 > fit_end:
            parts.append(self._direct(np.arange(fit_end * b, k1 * b)))
        result = _concat(parts)
        self._cache = {k1 - 1: _slice(result, (k1 - 1 - k0) * b, (k1 - k0) * b)}
        return result

    def _fit_blocks(self, ks: np.ndarray) -> IdealSamples:
        """Whole blocks ks; those containing breakpoints are split into runs."""
        b = self.block
        if self.breakpoints.size == 0:
            return self._fit_plain(ks)
        a, e = self._inside(ks * b, (ks + 1) * b)
        cut = e > a
        if not cut.any():
            return self._fit_plain(ks)
        if cut.all():
            return self._fit_cut(ks)
        rows = np.arange(ks.size * b).reshape(ks.size, b)
        return _gather(ks.size * b, [(rows[cut].ravel(), self._fit_cut(ks[cut])),
                                     (rows[~cut].ravel(), self._fit_plain(ks[~cut]))])

    def _fit_plain(self, ks: np.ndarray) -> IdealSamples:
        """Blocks without breakpoints: one fit per block, the precomputed block matrices."""
        b, h, R, nc = self.block, self.h, self.orders, self.cheb_nodes
        nb = len(ks)
        t0 = ks * b * h
        raw = _raw_channels(self.track, self.profile, (t0[:, None] + self._tau[None, :]).ravel(), self.oscillations)
        channels = _channels(raw, nb, nc)
        good = self._converged(np.matmul(self._coef_from_values, channels))
        ends = np.matmul(self._end_matrix, channels).reshape(nb * b, _N_CHANNELS)
        integ = np.matmul(self._int_matrix, channels[:, :, :6]).reshape(nb * b, R, 6)
        t_end = (np.repeat(ks * b, b) + np.tile(np.arange(1, b + 1), nb)) * h
        result = self._from_channels(ends, integ, t_end, np.repeat(good, b))
        if good.all():
            return result
        # blocks whose Chebyshev tail is too large: recompute them directly
        bad = np.flatnonzero(~good)
        index = (ks[bad][:, None] * b + np.arange(b)[None, :]).ravel()
        rows = (bad[:, None] * b + np.arange(b)[None, :]).ravel()
        return _assign(result, rows, self._direct(index))

    def _first_rung(self, m: int) -> int:
        target = self.cheb_nodes * math.sqrt(m / self.block) + 2.0
        for n in self._rungs:
            if n >= target:
                return n
        return self._rungs[-1]

    def _fit_cut(self, ks: np.ndarray) -> IdealSamples:
        """Blocks ks that contain breakpoints: runs of whole samples between breakpoints are
        fitted (own node count, escalated on failure), straddling samples integrated
        piecewise, runs that are too short or fail at the largest rung done directly."""
        b, h, R = self.block, self.h, self.orders
        bp = self.breakpoints
        a, e = self._inside(ks * b, (ks + 1) * b)
        run_start: list[int] = []
        run_len: list[int] = []
        straddlers: list[int] = []
        for k, lo, hi in zip(ks.tolist(), a.tolist(), e.tolist()):
            base = k * b
            edges = {0, b}
            cut_samples: set[int] = set()
            for beta in (bp[lo:hi] - base).tolist():
                j = math.floor(beta)
                if beta == j:
                    edges.add(j)
                else:
                    cut_samples.add(j)
                    edges.update((j, j + 1))
            edge = sorted(edges)
            for j0, j1 in zip(edge[:-1], edge[1:]):
                if not (j1 == j0 + 1 and j0 in cut_samples):
                    run_start.append(base + j0)
                    run_len.append(j1 - j0)
            straddlers.extend(base + j for j in sorted(cut_samples))
        global_index = (ks[:, None] * b + np.arange(b)[None, :]).ravel()
        row_of = _row_map(ks, b)
        n_rows = ks.size * b
        ends = np.zeros((n_rows, _N_CHANNELS))
        integ = np.zeros((n_rows, R, 6))
        fitted = np.zeros(n_rows, dtype=bool)
        direct_runs: list[tuple[int, int, int]] = []
        pending: list[tuple[int, int, int]] = []  # (start, m, n_nodes)
        cost_direct = self.n_nodes + 1
        for s0, m in zip(run_start, run_len):
            n = self._first_rung(m)
            (direct_runs if n >= m * cost_direct else pending).append((s0, m, n))
        while pending:
            times = np.concatenate([s0 * h + self._run_matrices(m, n)[0] for s0, m, n in pending])
            raw = _raw_channels(self.track, self.profile, times, self.oscillations)
            groups: dict[tuple[int, int], list[int]] = {}
            offsets: np.ndarray = np.cumsum([0] + [n for _, _, n in pending])
            for i, (_, m, n) in enumerate(pending):
                groups.setdefault((m, n), []).append(i)
            retry: list[tuple[int, int, int]] = []
            for (m, n), members in groups.items():
                _, coef_from_values, end_matrix, int_matrix = self._run_matrices(m, n)
                pts = (offsets[members][:, None] + np.arange(n)[None, :]).ravel()
                channels = _channels(raw[pts], len(members), n)
                good = self._converged(np.matmul(coef_from_values, channels))
                starts = np.array([pending[i][0] for i in members])
                ok = np.flatnonzero(good)
                if ok.size:
                    rows = row_of(starts[ok][:, None] + np.arange(m)[None, :]).ravel()
                    ends[rows] = np.matmul(end_matrix, channels[ok]).reshape(-1, _N_CHANNELS)
                    integ[rows] = np.matmul(int_matrix, channels[ok, :, :6]).reshape(-1, R, 6)
                    fitted[rows] = True
                for bad in np.flatnonzero(~good):
                    s0 = int(starts[bad])
                    higher = [r for r in self._rungs if r > n]
                    if higher and higher[0] < m * cost_direct:
                        retry.append((s0, m, higher[0]))
                    else:
                        direct_runs.append((s0, m, n))
            pending = retry
        # every row from the fitted channels (rows not fitted hold zeros), then the others
        result = self._from_channels(ends, integ, (global_index + 1) * h, fitted)
        if straddlers:
            index = np.array(straddlers)
            _overwrite(result, row_of(index), self._split_samples(index))
        if direct_runs:
            index = np.concatenate([np.arange(s0, s0 + m) for s0, m, _ in direct_runs])
            _overwrite(result, row_of(index), self._direct_plain(index))
        return result

    # ------------------------------------------------------------------ helpers
    def _converged(self, coef: np.ndarray) -> np.ndarray:
        """Tail check of Chebyshev coefficients ``coef`` (nb, N, 18): bool (nb,)."""
        mag = np.abs(coef)
        scale = mag.sum(axis=1)  # (nb, 18)
        # vector channels share a scale (a small component of a large vector is fine)
        for group in _VECTOR_GROUPS:
            scale[:, group] = scale[:, group].max(axis=1, keepdims=True)
        scale = np.maximum(scale, _SCALE_FLOOR)
        tail = mag[:, -2:].max(axis=1)
        ok = tail <= self.tol * scale
        n = coef.shape[1]
        if self.noise_tol > self.tol and n >= 12:
            # a plateau at the evaluation noise: the coefficients before the last two are no
            # larger than a few times the last two. Over the last 8 coefficients a kink's
            # algebraic tail (c_k ~ k^-p) looks flat too, so that short plateau is accepted
            # only up to _SHORT_PLATEAU_TOL; up to noise_tol the whole upper half must be
            # flat, which a kink's tail is not (it falls by 2^p >= 4 across it)
            short = mag[:, -8:-2].max(axis=1) <= _PLATEAU_RATIO * tail
            long = mag[:, n // 2:-2].max(axis=1) <= _PLATEAU_RATIO * tail
            ok |= short & (tail <= min(_SHORT_PLATEAU_TOL, self.noise_tol) * scale)
            ok |= long & (tail <= self.noise_tol * scale)
        return ok.all(axis=1)

    def _from_channels(self, ends: np.ndarray, integ: np.ndarray, t_end: np.ndarray,
                       used_block: np.ndarray) -> IdealSamples:
        """IdealSamples from fitted channel values at sample ends (n, 18) and integrals (n, R, 6)."""
        s, speed, accel, lat, lon, hgt, hd, pitch, roll = ends[:, 9:].T
        velocity_n = ends[:, 6:9]
        earth = self.track.earth
        compiled = _truth_kernel.kernel() if USE_KERNEL else None
        if compiled is not None:
            # one pass per sample, the same expressions in the same order (bit for bit)
            n = ends.shape[0]
            hd, mat_nb = np.empty(n), np.empty((n, 3, 3))
            position_e, velocity_e = np.empty((n, 3)), np.empty((n, 3))
            compiled(ends, _truth_kernel.earth_constants(earth), hd, mat_nb, position_e, velocity_e)
        else:
            hd = np.angle(np.exp(1j * hd))  # back to (-pi, pi]
            mat_nb = mat_nb_from_hpr(hd, pitch, roll)
            position_e = earth.geodetic_to_ecef(lat, lon, hgt)
            velocity_e = np.einsum("nji,nj->ni", mat_en(lat, lon), velocity_n)
        truth = TrueState(
            t=t_end, s=s, speed=speed, accel_along=accel, lat=lat, lon=lon,
            h=hgt, velocity_n=velocity_n, heading=hd, pitch=pitch, roll=roll,
            mat_nb=mat_nb, omega_ib_b=ends[:, 0:3], specific_force_b=ends[:, 3:6],
            position_e=position_e, velocity_e=velocity_e,
        )
        return IdealSamples(integ[..., 0:3], integ[..., 3:6], ends[:, 0:3], ends[:, 3:6], truth, used_block)


@lru_cache(maxsize=64)
def _gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    x, w = np.polynomial.legendre.leggauss(n)
    x.flags.writeable = False
    w.flags.writeable = False
    return x, w


@lru_cache(maxsize=64)
def _cheb_inverse(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Chebyshev nodes of the first kind on [-1, 1] (increasing) and V^-1 (values -> coefficients)."""
    x = np.cos(np.pi * (np.arange(n) + 0.5) / n)[::-1]
    inv = np.linalg.inv(np.polynomial.chebyshev.chebvander(x, n - 1))
    x.flags.writeable = False
    inv.flags.writeable = False
    return x, inv


def _run_matrices(m: int, n: int, orders: int, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Matrices of a run of m samples of length h fitted with n Chebyshev nodes.

    Returns node offsets from the run start (s, (n,)), values -> coefficients (n, n),
    values -> values at the m sample ends (m, n) and values -> r-fold integrals over each
    sample (m * orders, n); pure function of its arguments (cached, least recently used
    first out beyond _MATRIX_CACHE_BYTES; read-only arrays).
    """
    key = (m, n, orders, h)
    hit = _MATRIX_CACHE.get(key)
    if hit is not None:
        _MATRIX_CACHE.move_to_end(key)
        return hit
    R = orders
    span = m * h
    # Chebyshev nodes of the first kind on [0, span], in increasing time
    x, coef_from_values = _cheb_inverse(n)
    tau = 0.5 * span * (x + 1.0)
    # values at sample ends
    x_end = 2.0 * (np.arange(1, m + 1) * h) / span - 1.0
    end = np.polynomial.chebyshev.chebvander(x_end, n - 1) @ coef_from_values
    # r-fold integrals over each sample: Gauss-Legendre, exact for degree < n + R
    gl_x, gl_w = _gauss_legendre(n // 2 + R + 2)
    u = 0.5 * (gl_x + 1.0)  # in (0, 1) within a sample
    w = 0.5 * gl_w
    t_q = (np.arange(m)[:, None] + u[None, :]) * h  # (m, q)
    basis = np.polynomial.chebyshev.chebvander(2.0 * t_q / span - 1.0, n - 1)  # (m, q, n)
    # (1.14) via Cauchy: h^r (1 - u)^(r-1) / (r-1)!
    kernels = np.stack([(h ** r) * (1.0 - u) ** (r - 1) / math.factorial(r - 1) * w for r in range(1, R + 1)])
    integ = (np.einsum("rq,bqk->brk", kernels, basis) @ coef_from_values).reshape(m * R, n)
    for a in (tau, end, integ):
        a.flags.writeable = False
    out = (tau, coef_from_values, end, integ)
    _MATRIX_CACHE[key] = out
    global _matrix_cache_bytes
    _matrix_cache_bytes += end.nbytes + integ.nbytes
    while _matrix_cache_bytes > _MATRIX_CACHE_BYTES and len(_MATRIX_CACHE) > 1:
        _, (_, _, old_end, old_integ) = _MATRIX_CACHE.popitem(last=False)
        _matrix_cache_bytes -= old_end.nbytes + old_integ.nbytes
    return out


def _raw_channels(track: Track, profile: SpeedProfile, t: np.ndarray,
                  oscillations: Sequence[Oscillation]) -> np.ndarray:
    """The 18 interpolated channels at times t, (n, 18); heading as evaluated (the fields
    of :func:`navsim.motion.true_state`: omega_ib_b, specific_force_b, velocity_n, then
    _SCALAR_FIELDS, in that order)."""
    return np.column_stack(truth_channels(track, profile, t, oscillations))


def _channels(raw: np.ndarray, nb: int, n: int) -> np.ndarray:
    """Channels of nb fits of n nodes each, (nb, n, 18), heading unwrapped within each fit."""
    out = raw.reshape(nb, n, _N_CHANNELS).copy()
    out[:, :, _HEADING] = np.unwrap(out[:, :, _HEADING], axis=1)
    return out


def _row_map(ks: np.ndarray, b: int) -> Callable[[Any], np.ndarray]:
    """Sample index -> row in the output of blocks ks (sorted, possibly not contiguous)."""
    first = int(ks[0]) * b
    if int(ks[-1]) - int(ks[0]) == ks.size - 1:
        return lambda index: np.asarray(index) - first
    return lambda index: np.searchsorted(ks, np.asarray(index) // b) * b + np.asarray(index) % b


def _gather(n: int, parts: list[tuple[np.ndarray, IdealSamples]]) -> IdealSamples:
    """IdealSamples of n rows assembled from (rows, part) pairs that cover every row once."""
    ref = parts[0][1]
    out = {}
    for f in ("dtheta_r", "dv_r", "omega_end", "force_end", "used_block"):
        arr = np.empty((n,) + getattr(ref, f).shape[1:], dtype=getattr(ref, f).dtype)
        for rows, part in parts:
            arr[rows] = getattr(part, f)
        out[f] = arr
    truth = {}
    for f in TrueState.__dataclass_fields__:
        x = getattr(ref.truth, f)
        arr = np.empty((n,) + x.shape[1:], dtype=x.dtype)
        for rows, part in parts:
            arr[rows] = getattr(part.truth, f)
        truth[f] = arr
    return IdealSamples(out["dtheta_r"], out["dv_r"], out["omega_end"], out["force_end"], TrueState(**truth),
                        out["used_block"])


def _overwrite(x: IdealSamples, rows: np.ndarray, y: IdealSamples) -> None:
    """Write y into rows of x in place (x's arrays must be owned by the caller)."""
    for f in ("dtheta_r", "dv_r", "omega_end", "force_end", "used_block"):
        getattr(x, f)[rows] = getattr(y, f)
    for f in TrueState.__dataclass_fields__:
        getattr(x.truth, f)[rows] = getattr(y.truth, f)


def _assign(x: IdealSamples, rows: np.ndarray, y: IdealSamples) -> IdealSamples:
    """Copy of x with rows replaced by y."""
    out = {}
    for f in ("dtheta_r", "dv_r", "omega_end", "force_end", "used_block"):
        arr = getattr(x, f).copy()
        arr[rows] = getattr(y, f)
        out[f] = arr
    truth = {}
    for f in TrueState.__dataclass_fields__:
        arr = getattr(x.truth, f).copy()
        arr[rows] = getattr(y.truth, f)
        truth[f] = arr
    return IdealSamples(out["dtheta_r"], out["dv_r"], out["omega_end"], out["force_end"], TrueState(**truth),
                        out["used_block"])


def _concat(parts: list[IdealSamples]) -> IdealSamples:
    if len(parts) == 1:
        return parts[0]
    truth = TrueState(**{f: np.concatenate([getattr(p.truth, f) for p in parts])
                         for f in TrueState.__dataclass_fields__})
    dtheta_r, dv_r, omega_end, force_end = (np.concatenate([getattr(p, f) for p in parts])
                                            for f in ("dtheta_r", "dv_r", "omega_end", "force_end"))
    return IdealSamples(dtheta_r, dv_r, omega_end, force_end, truth=truth,
                        used_block=np.concatenate([p.used_block for p in parts]))


def _slice(x: IdealSamples, lo: int, hi: int) -> IdealSamples:
    sl = slice(lo, hi)
    truth = TrueState(**{f: getattr(x.truth, f)[sl] for f in TrueState.__dataclass_fields__})
    return IdealSamples(x.dtheta_r[sl], x.dv_r[sl], x.omega_end[sl], x.force_end[sl], truth, x.used_block[sl])
