"""Applying the IMU errors in the increment domain, for every order r at once
(:func:`apply_imu_errors`, :func:`apply_imu_errors_batch` for N members), with the
quantizer's residual carry (Groves 2013 sec. 4.4) and the Gauss-Markov / rate-random-walk
recursions (:func:`first_order_recursion`). The model and its stated approximations are in
:mod:`navsim.sensors.imu`.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...errors import ConfigError
from . import kernel as _imu_kernel
from .error_model import ImuErrorModel, SensorErrors, level_lsb
from .integrals import MAX_ORDER, check_h, harmonic_multiple_integrals, unit_noise_factor
from .state import BatchImuState, ImuOutput, ImuState

USE_KERNEL = True
"""Use the compiled white-noise pass when numba is installed (:mod:`navsim.sensors.imu.kernel`;
the numbers are the same either way)."""

QUANTIZATION_BLOCK = 1024
"""Quantizer accumulators are renormalised every this many samples (global index)."""


def _mat3_apply(mat: NDArray, vec: NDArray) -> NDArray:
    """``mat @ vec`` over the last axis of ``vec`` (..., 3), without tiny-matrix BLAS calls."""
    return (
        vec[..., 0, None] * mat[:, 0] + vec[..., 1, None] * mat[:, 1] + vec[..., 2, None] * mat[:, 2]
    )


def _first_order_recursion(phi: NDArray, drive: NDArray, start: NDArray) -> NDArray:
    """``x_{k+1} = phi x_k + drive_k`` per channel along axis 1; returns x_1..x_n.

    ``drive`` is (B, n, ...) (B members, n samples), ``start`` (B, ...), ``phi`` broadcasts
    against ``start``. ``scipy.signal.lfilter`` with ``zi = phi * x_0`` evaluates exactly
    ``y_k = drive_k + phi * y_{k-1}``, so the result does not depend on chunking nor on
    how many members are filtered together. All-zero input (the error switched off)
    gives exact zeros without filtering.
    """
    n = drive.shape[1]
    if not (drive.any() or start.any()):
        return np.zeros(drive.shape)
    out = np.empty(drive.shape)  # C order: the reshaped views below must share its memory
    if n <= 16:  # a few samples (step-by-step use): the plain recursion, same arithmetic
        x = start.copy()
        for k in range(n):
            x = drive[:, k] + phi * x  # y_k = drive_k + phi y_{k-1}, as lfilter evaluates it
            out[:, k] = x
        return out
    from scipy.signal import lfilter  # lazy: scipy.signal costs ~0.7 s to import

    b = drive.shape[0]
    flat_drive = drive.reshape(b, n, -1)
    flat_out = out.reshape(b, n, -1)  # a view (out is C-contiguous)
    flat_start = start.reshape(b, -1)
    for c, p in enumerate(np.broadcast_to(phi, start.shape[1:]).ravel()):
        flat_out[:, :, c], _ = lfilter([1.0], [1.0, -p], flat_drive[:, :, c], axis=1, zi=p * flat_start[:, c, None])
    return out


first_order_recursion = _first_order_recursion
"""Public name of the batched first-order recursion (used by the odometer's Gauss-Markov term)."""


def _quantize(
    values: NDArray, lsb: NDArray, acc: NDArray, count: NDArray, start_index: int
) -> tuple[NDArray, NDArray, NDArray]:
    """Quantize with residual carry, vectorised over samples; channels along axis 1.

    Within a renormalisation block, ``acc_k = acc_{k-1} + y_k`` (sequential cumsum),
    ``count_k = rint(acc_k / lsb)`` and the output is ``lsb (count_k - count_{k-1})``,
    which is the residual-carry quantizer ``q_k = lsb rint((y_k + res_{k-1}) / lsb)`` of
    Groves (2013) written on running sums. At every global sample index that is a
    multiple of ``QUANTIZATION_BLOCK`` both are shifted by the count
    (``acc -= lsb count``, ``count = 0``), keeping the accumulator small.
    """
    n = values.shape[0]
    out = np.empty_like(values)
    i = 0
    while i < n:
        g = start_index + i
        stop = min(n, i + QUANTIZATION_BLOCK - g % QUANTIZATION_BLOCK)
        sums = np.cumsum(np.concatenate((acc[None], values[i:stop]), axis=0), axis=0)[1:]
        counts = np.rint(sums / lsb)
        out[i:stop] = np.diff(np.concatenate((count[None], counts), axis=0), axis=0) * lsb
        acc, count = sums[-1], counts[-1]
        if (start_index + stop) % QUANTIZATION_BLOCK == 0:
            acc = acc - lsb * count
            count = np.zeros_like(count)
        i = stop
    return out, acc, count


def _check_truth_inputs(t_start: ArrayLike, dtheta_r: ArrayLike, dv_r: ArrayLike, omega_b: ArrayLike,
                        f_b: ArrayLike) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
    dtheta_r = np.asarray(dtheta_r, dtype=float)
    dv_r = np.asarray(dv_r, dtype=float)
    if dtheta_r.ndim != 3 or dtheta_r.shape[-1] != 3 or not 1 <= dtheta_r.shape[1] <= MAX_ORDER:
        raise ConfigError("dtheta_r", f"shape (n, R, 3) with 1 <= R <= {MAX_ORDER}", dtheta_r.shape)
    n = dtheta_r.shape[0]
    if dv_r.shape != dtheta_r.shape:
        raise ConfigError("dv_r", f"shape {dtheta_r.shape} like dtheta_r", dv_r.shape)
    t_start = np.asarray(t_start, dtype=float)
    if t_start.shape != (n,):
        raise ConfigError("t_start", f"shape ({n},)", t_start.shape)
    omega_b = np.asarray(omega_b, dtype=float)
    f_b = np.asarray(f_b, dtype=float)
    if omega_b.shape != (n, 3):
        raise ConfigError("omega_b", f"shape ({n}, 3)", omega_b.shape)
    if f_b.shape != (n, 3):
        raise ConfigError("f_b", f"shape ({n}, 3)", f_b.shape)
    return t_start, dtheta_r, dv_r, omega_b, f_b


def _bias(s_idx: int, sensor: SensorErrors, turn_on: NDArray, gm_start: NDArray, sigma_gm: NDArray,
          rrw_start: NDArray, rrw_gain: NDArray, varying: NDArray) -> NDArray | None:
    """Sensor ``s_idx``'s bias during each sample, (B, n, 3): constant + turn-on +
    Gauss-Markov + rate random walk (``varying``); ``None`` when every term is zero for
    every member (nothing to add)."""
    constant = sensor.bias + turn_on[:, s_idx]  # (B, 3)
    if np.any(constant) or np.any(gm_start[:, s_idx]) or np.any(sigma_gm[s_idx]) \
            or np.any(rrw_start[:, s_idx]) or np.any(rrw_gain[s_idx]):
        return constant[:, None] + varying[:, :, s_idx]
    return None


def _kernel_base(s_idx: int, sensor: SensorErrors, out: NDArray, rate: NDArray, order: int, turn_on: NDArray,
                 gm_start: NDArray, sigma_gm: NDArray, rrw_start: NDArray, rrw_gain: NDArray, varying: NDArray,
                 h_r_fact: NDArray, t_start: NDArray, t_end: NDArray, h: float) -> tuple[NDArray, NDArray]:
    """One sensor's noise-free outputs (1 or B, n, R, 3), (1 or B, n, 3) for the compiled passes.

    ``out`` (n, R, 3) and ``rate`` (n, 3) are the noise-free values shared by the members
    (after scale factor, misalignment and g-sensitivity). The bias and vibration terms are
    added in the order of the NumPy path (bias, then each harmonic), never in place
    (``out`` may be the caller's array).
    """
    base_r, base_rate = out[None], rate[None]
    bias = _bias(s_idx, sensor, turn_on, gm_start, sigma_gm, rrw_start, rrw_gain, varying)
    if bias is not None:
        base_r = base_r + bias[:, :, None, :] * h_r_fact[None, None, :, None]  # b h^r / r!
        base_rate = base_rate + bias
    for harm in sensor.vibration:
        integrals = harmonic_multiple_integrals(1.0, harm.frequency_hz, harm.phase_rad, t_start, h, order)
        base_r = base_r + (integrals[:, :, None] * harm.amplitude[None, None, :])[None]
        wave = np.sin(2.0 * math.pi * harm.frequency_hz * t_end + harm.phase_rad)
        base_rate = base_rate + (wave[:, None] * harm.amplitude[None, :])[None]
    return base_r, base_rate


def _kernel_sensor(kern: Callable[..., Any], s_idx: int, z: NDArray, order: int, members: int, base_r: NDArray,
                   base_rate: NDArray, h: float, noise_factor: NDArray, scale_density: NDArray,
                   dest: tuple[NDArray, NDArray] | None = None) -> tuple[NDArray, NDArray]:
    """One sensor's outputs (B, n, R, 3), (B, n, 3) with the compiled white-noise pass over
    the drawn block ``z``; ``base_*`` from :func:`_kernel_base`. ``dest``: (out_r, out_rate)
    to write into."""
    n = base_r.shape[1]
    out_r: np.ndarray
    out_rate: np.ndarray
    if dest is None:
        out_r, out_rate = np.empty((members, n, order, 3)), np.empty((members, n, 3))
    else:
        out_r, out_rate = dest
    kern(z.reshape(members, n, -1), s_idx * 3 * (order + 2), noise_factor, np.ascontiguousarray(scale_density), h,
         np.broadcast_to(base_r, out_r.shape), np.broadcast_to(base_rate, out_rate.shape), out_r, out_rate)
    return out_r, out_rate


def apply_imu_errors(
    t_start: ArrayLike,
    h: float,
    dtheta_r: ArrayLike,
    dv_r: ArrayLike,
    omega_b: ArrayLike,
    f_b: ArrayLike,
    model: ImuErrorModel,
    state: ImuState,
    rng: np.random.Generator,
) -> tuple[ImuOutput, ImuState]:
    """Apply the IMU error model to ``n`` consecutive samples of true data.

    Parameters
    ----------
    t_start : array_like, shape (n,)
        Start time of each sample, s (sample k covers ``[t_start[k], t_start[k] + h]``).
    h : float
        Sample length, s.
    dtheta_r, dv_r : array_like, shape (n, R, 3)
        True multiple integrals (1.14) of ``omega_ib_b`` (rad s^(r-1)) and of ``f_b``
        (m/s s^(r-1)), R <= ``MAX_ORDER``.
    omega_b, f_b : array_like, shape (n, 3)
        True angular rate (rad/s) and specific force (m/s^2) at ``t_start + h``.
    model : ImuErrorModel
    state : ImuState
        From :meth:`ImuState.initial` or the previous call.
    rng : numpy.random.Generator
        Draws exactly one ``(n, 6 (R + 2))`` block of standard normals.

    Returns
    -------
    output : ImuOutput
    new_state : ImuState

    See Also
    --------
    apply_imu_errors_batch : the same for B IMUs on one true motion (this function is
        its B = 1 case).
    """
    output, states = apply_imu_errors_batch(t_start, h, dtheta_r, dv_r, omega_b, f_b, model, [state], [rng])
    return ImuOutput(output.dtheta_r[0], output.dv_r[0], output.rate_b[0], output.accel_b[0]), states[0]


def apply_imu_errors_batch(
    t_start: ArrayLike,
    h: float,
    dtheta_r: ArrayLike,
    dv_r: ArrayLike,
    omega_b: ArrayLike,
    f_b: ArrayLike,
    model: ImuErrorModel,
    states: Sequence[ImuState],
    rngs: Sequence[np.random.Generator],
    out: ImuOutput | None = None,
) -> tuple[ImuOutput, list[ImuState]]:
    """Apply one error model to B IMUs that sense the same true motion, in one pass.

    Member j gets exactly the numbers of ``apply_imu_errors(..., states[j], rngs[j])``
    (the same draws from its own generator, the same floating-point operations, applied
    elementwise over a leading member axis). This is how the native vector environment
    simulates N episodes of a scenario in lockstep.

    Parameters
    ----------
    t_start, h, dtheta_r, dv_r, omega_b, f_b, model
        As :func:`apply_imu_errors`; the true data are shared by all members.
    states : sequence of B ImuState
        Their ``sample_index`` must be equal (lockstep).
    rngs : sequence of B numpy.random.Generator
        Generator j draws one ``(n, 6 (R + 2))`` block.
    out : ImuOutput, optional
        Arrays (views allowed) of the output shapes to write the result into; it is then
        the returned output (the simulator's chunk buffers, saving a copy).

    Returns
    -------
    output : ImuOutput
        Arrays with a leading member axis: ``dtheta_r`` (B, n, R, 3), ``rate_b`` (B, n, 3).
    new_states : list of B ImuState
    """
    states = list(states)
    state = BatchImuState.of(states)  # checks the states (ImuState, at least one, lockstep)
    output, new_state = apply_imu_errors_batch_state(t_start, h, dtheta_r, dv_r, omega_b, f_b, model, state, rngs,
                                                     out=out)
    return output, (states if new_state.sample_index == state.sample_index else new_state.members())


def apply_imu_errors_batch_state(
    t_start: ArrayLike,
    h: float,
    dtheta_r: ArrayLike,
    dv_r: ArrayLike,
    omega_b: ArrayLike,
    f_b: ArrayLike,
    model: ImuErrorModel,
    state: BatchImuState,
    rngs: Sequence[np.random.Generator],
    out: ImuOutput | None = None,
) -> tuple[ImuOutput, BatchImuState]:
    """:func:`apply_imu_errors_batch` on the members' states as one :class:`BatchImuState`
    (no per-member state objects; the simulator batch carries its states this way).

    The same numbers: :func:`apply_imu_errors_batch` stacks its states and calls this
    (the arguments are checked here, for both). ``rngs``: one generator per row of
    ``state``. Returns the output and the new state.
    """
    h = check_h(h)
    if not isinstance(model, ImuErrorModel):
        raise ConfigError("model", "an ImuErrorModel", type(model).__name__)
    rngs = list(rngs)
    members = state.size
    if len(rngs) != members:
        raise ConfigError("rngs", f"one generator per member ({members})", len(rngs))
    index = state.sample_index
    t_start, dtheta_r, dv_r, omega_b, f_b = _check_truth_inputs(t_start, dtheta_r, dv_r, omega_b, f_b)
    n, order = dtheta_r.shape[:2]

    if n == 0:
        empty = np.zeros((members, 0, order, 3))
        return ImuOutput(empty, empty.copy(), np.zeros((members, 0, 3)), np.zeros((members, 0, 3))), state

    sensors = (model.gyro, model.accel)
    sigma_gm = np.stack([s.bias_instability_sigma for s in sensors])
    rrw_gain = np.stack([s.rate_random_walk for s in sensors]) * math.sqrt(h)
    gm_start = state.bias_gauss_markov
    rrw_start = state.bias_random_walk
    gm_on = bool(sigma_gm.any() or gm_start.any())
    rrw_on = bool(rrw_gain.any() or rrw_start.any())
    density = np.stack([s.white_noise_density for s in sensors])  # (2, 3)
    lsb_levels = level_lsb(model, h, order)
    kern = _imu_kernel.kernel() if USE_KERNEL else None
    # One block per member and call; width fixed by R only. With numba the blocks are drawn
    # by one compiled loop (navsim.sensors.imu.kernel.draw_kernel: the same numbers).
    z: np.ndarray = np.empty((members, n, 2, order + 2, 3))
    draw = _imu_kernel.draw_kernel() if kern is not None else None
    if draw is not None:
        draw(rngs, z.reshape(members, n, -1))
    else:
        for j, rng in enumerate(rngs):
            rng.standard_normal(out=z[j].reshape(n, -1))
    # each slot used is copied once to a contiguous (member, sample, axis) array, so the
    # elementwise passes below run over long contiguous arrays (the numbers are those
    # of the draw order above)
    slots: dict[tuple[int, int], NDArray] = {}

    def slot(s_idx: int, k: int) -> NDArray:
        """Draw slot k of sensor s_idx as a contiguous (B, n, 3) array (copied once)."""
        if (s_idx, k) not in slots:
            slots[s_idx, k] = np.ascontiguousarray(z[:, :, s_idx, k])
        return slots[s_idx, k]

    r = np.arange(1, order + 1)
    h_r_fact = h**r / np.array([math.factorial(int(k)) for k in r], dtype=float)  # h^r / r!
    turn_on = state.turn_on_bias  # (B, 2, 3)

    # Gauss-Markov and rate-random-walk biases: exact discrete propagation between
    # samples, held constant within each sample (see the module docstring). Switched
    # off (zero sigma and state) they stay exactly zero and nothing is computed.
    tau = np.stack([s.bias_correlation_time_s for s in sensors])
    zero_bias = np.broadcast_to(0.0, (members, n, 2, 3))  # read-only zeros, not allocated (the states copy)
    if gm_on:
        phi = np.exp(-h / tau)
        gm_coef = sigma_gm * np.sqrt(-np.expm1(-2.0 * h / tau))  # (2, 3)
        gm_drive = gm_coef[None, None] * z[:, :, :, order]  # (B, n, 2, 3)
        gm_next = _first_order_recursion(phi, gm_drive, gm_start)  # b_1..b_n
    else:
        gm_next = zero_bias
    if rrw_on:
        rrw_drive = rrw_gain[None, None] * z[:, :, :, order + 1]
        rrw_next = _first_order_recursion(np.ones((2, 3)), rrw_drive, rrw_start)
    else:
        rrw_next = zero_bias
    if gm_next is zero_bias and rrw_next is zero_bias:
        varying = zero_bias  # both switched off: the sum below is exact zeros too
    else:
        varying = np.concatenate((gm_start[:, None], gm_next[:, :-1]), axis=1)
        varying += np.concatenate((rrw_start[:, None], rrw_next[:, :-1]), axis=1)

    noise_factor = unit_noise_factor(order)
    noise_scale = math.sqrt(h) * h ** (r - 1)  # white-noise integral r scales as h^(r - 1/2)
    rows = list(range(order)) + [MAX_ORDER]
    acc_new = state.quant_accumulator.copy()  # (B, 2, MAX_ORDER + 1, 3), updated by the quantizer
    count_new = state.quant_count.copy()
    t_end = t_start + h
    dest_output = out  # (the name ``out`` is reused below)
    dest_all = None if out is None else ((out.dtheta_r, out.rate_b), (out.dv_r, out.accel_b))
    outputs: list[tuple[np.ndarray, np.ndarray]] = []
    for s_idx, (sensor, true_r, true_rate) in enumerate(
        ((model.gyro, dtheta_r, omega_b), (model.accel, dv_r, f_b))
    ):
        # Scale factor and misalignment: linear, so exact on every order.
        transform = np.eye(3) + np.diag(sensor.scale_factor) + sensor.misalignment
        if np.array_equal(transform, np.eye(3)):
            out_r, rate = true_r, true_rate
        else:
            out_r, rate = _mat3_apply(transform, true_r), _mat3_apply(transform, true_rate)

        # Gyro g-sensitivity on the true specific force (exact on every order).
        if s_idx == 0 and np.any(model.g_sensitivity):
            out_r = out_r + _mat3_apply(model.g_sensitivity, dv_r)
            rate = rate + _mat3_apply(model.g_sensitivity, f_b)
        if kern is not None and np.any(density[s_idx]) and not lsb_levels[s_idx, 0] > 0.0:
            # compiled white-noise pass (navsim.sensors.imu.kernel): the same terms in the
            # same order as below, without repeating the shared values per member
            base = _kernel_base(s_idx, sensor, out_r, rate, order, turn_on, gm_start, sigma_gm, rrw_start, rrw_gain,
                                varying, h_r_fact, t_start, t_end, h)
            scale_density = noise_scale[:, None] * density[s_idx][None, :]
            dest = None if dest_all is None else dest_all[s_idx]
            outputs.append(_kernel_sensor(kern, s_idx, z, order, members, *base, h, noise_factor, scale_density, dest))
            continue
        # from here on the members differ; ``out_r`` in the layout (R, B, n, 3)
        out_r = np.repeat(out_r.transpose(1, 0, 2)[:, None], members, axis=1)
        rate = np.repeat(rate[None], members, axis=0)  # (B, n, 3)

        # Biases: constant + turn-on + Gauss-Markov + rate random walk (members without
        # a bias add exact zeros).
        bias = _bias(s_idx, sensor, turn_on, gm_start, sigma_gm, rrw_start, rrw_gain, varying)
        if bias is not None:
            out_r += bias[None] * h_r_fact[:, None, None, None]  # b h^r / r!
            rate += bias

        # Vibration harmonics: closed-form multiple integrals (seed 000, section 6).
        for harm in sensor.vibration:
            integrals = harmonic_multiple_integrals(
                1.0, harm.frequency_hz, harm.phase_rad, t_start, h, order
            )
            out_r += integrals.T[:, None, :, None] * harm.amplitude[None, None, None, :]
            wave = np.sin(2.0 * math.pi * harm.frequency_hz * t_end + harm.phase_rad)
            rate += wave[:, None] * harm.amplitude[None, :]

        # White noise: exact joint draw of the R integrals, Cov = q h^(i+j-1) / (...).
        if np.any(density[s_idx]):
            for i in range(order):  # lower-triangular Cholesky factor times the draws
                unit = noise_factor[i, 0] * slot(s_idx, 0)  # slots 0..R-1: white
                for p in range(1, i + 1):
                    unit += noise_factor[i, p] * slot(s_idx, p)
                noise_i = unit * (noise_scale[i] * density[s_idx])
                out_r[i] += noise_i
                if i == 0:
                    rate += noise_i / h  # sample average: sigma = sqrt(PSD / h)

        # Quantization with residual carry, per output level and axis (members side by
        # side as channels: the running sums are per column).
        if lsb_levels[s_idx, 0] > 0.0:
            width = 3 * (order + 1)
            values = np.concatenate((out_r, rate[None]), axis=0).transpose(2, 1, 0, 3)  # (n, B, R + 1, 3)
            quant, acc, count = _quantize(
                values.reshape(n, members * width),
                np.tile(np.repeat(lsb_levels[s_idx], 3), members),
                acc_new[:, s_idx, rows].reshape(-1),
                count_new[:, s_idx, rows].reshape(-1),
                index,
            )
            quant = quant.reshape(n, members, order + 1, 3)
            out_r, rate = quant[:, :, :order].transpose(1, 0, 2, 3), quant[:, :, order].transpose(1, 0, 2)
            acc_new[:, s_idx, rows] = acc.reshape(members, order + 1, 3)
            count_new[:, s_idx, rows] = count.reshape(members, order + 1, 3)
        else:
            out_r = out_r.transpose(1, 2, 0, 3)  # (B, n, R, 3)
        outputs.append((out_r, rate))

    new_states = BatchImuState._owned(index + n, turn_on, gm_next[:, -1], rrw_next[:, -1], acc_new, count_new)
    if dest_all is None:
        return ImuOutput(dtheta_r=outputs[0][0], dv_r=outputs[1][0], rate_b=outputs[0][1],
                         accel_b=outputs[1][1]), new_states
    assert dest_output is not None  # dest_all is built from it
    for (values, rate), (dest_r, dest_rate) in zip(outputs, dest_all):
        if values is not dest_r:  # the kernel wrote in place
            dest_r[...] = values
            dest_rate[...] = rate
    return dest_output, new_states
