"""Seed 001 (Kononenko 2007), Table 1 and figure 2: matrizant vs reversible quaternion algorithms.

The experiment of the paper: gyro increments every h = 5 ms of the body rates (12)

    omega_x = C_x sin(2 pi F_x t),  omega_y = C_y sin(2 pi F_y t),  omega_z = 0,
    C_x = C_y = 0.174,  F_x = 0.8 Hz,  F_y = 1 Hz,

are integrated by the matrizant algorithm (8)-(9) (P, double step 2h) and by the
reversible algorithm (11) (M); the reference Lambda is RK4 on (2) with a 1 ms step. The
errors are the small angles of ``conj(Lambda) o P`` and ``conj(Lambda) o M`` (13)-(14);
Table 1 prints their mean and mean-square deviation in degrees.

Choices where the paper is silent or ambiguous
----------------------------------------------
* **Units of C.** The paper prints "C_x = C_y = 0.174 rad", but in (12) C multiplies a
  sine to give a *rate*: navsim takes C = 0.174 rad/s (10 deg/s). Read as an angle
  amplitude (rate amplitude 2 pi F C, about 1 rad/s) the reversible algorithm's errors
  in 20 s are already 10-20 times the printed ones, and the printed ratio of deviation
  to mean (about 0.6, that of a linear drift) would need runs of about a second.
* **Run length.** Not printed. The reversible algorithm's pitch and roll errors drift
  linearly (deviation / mean = 1/sqrt(3) = 0.58, printed 0.62 and 0.59), so the means
  scale with the run length T; the least-squares fit of the printed pitch and roll means
  gives T = 220 s. navsim uses the round T = 200 s (20 s in ``quick`` mode).
* **"Mean-square error".** Read as the standard deviation about the mean: the printed
  values are smaller than the means, which a root-mean-square about zero cannot be.
* **Input of the reversible algorithm.** (11) writes ``h omega(t0 + h)``; navsim feeds
  the gyro increment over the step (what a strapdown system measures). The end-point
  rate sample adds a lag error of O(h) with a large oscillating part; it is reported as
  an extra row.
* **Printed typos** in (8) are corrected (see :mod:`navsim.strapdown.quaternion`); with
  C_z = 0 they do not change P here except through the literal f0 (extra row).

What agrees and what does not
-----------------------------
The reversible algorithm (M) reproduces Table 1's magnitudes: pitch and roll means of
about 0.0015 and 0.0019 deg and deviations of 0.0009 and 0.0011 deg at T = 200 s
(printed 0.00183/0.00189 and 0.00109/0.00116), with the opposite sign (the paper's sign
convention for the rates or for Delta cannot be recovered from the text). Its heading
error is smaller than printed (mean 1.6e-5 against 2.4e-4 deg, deviation 6e-5 against
1.7e-4 deg). The matrizant algorithm (P), correctly
implemented, is about five orders of magnitude more accurate (errors ~1e-9 deg), so the
printed near-equality of the P and M columns, and the claim that the reversible method's
error is O(h^5), are not reproduced: the reversible algorithm is first order (its global
error halves with h, :mod:`navsim.strapdown.quaternion`).

References
----------
.. [1] Kononenko V.A. (2007), seed 001: eqs. (2), (8)-(9), (11)-(14), Table 1, fig. 2.
"""

from __future__ import annotations

import os
from typing import Iterable

import numpy as np
from numpy.typing import ArrayLike

from ..strapdown.quaternion import (
    error_angles,
    matrizant_integrate,
    reversible_integrate,
    rk4_integrate,
)

__all__ = ["run", "rates", "increments", "TABLE1", "STEP_S", "REFERENCE_STEP_S", "DURATION_S"]

STEP_S = 0.005
"""Gyro sampling step h (s)."""
REFERENCE_STEP_S = 0.001
"""RK4 reference step (s)."""
DURATION_S = 200.0
"""Run length (s) used by navsim; not printed in the paper (see the module notes)."""

_AMPLITUDE = np.array([0.174, 0.174, 0.0])  # C_x, C_y, C_z, rad/s
_FREQUENCY = np.array([0.8, 1.0, 0.0])  # F_x, F_y, F_z, Hz

#: Table 1 as printed, degrees: (angle, statistic) -> (Delta P, Delta M)
TABLE1 = {
    ("heading", "mean"): (0.00023, 0.00024),
    ("pitch", "mean"): (-0.00176, -0.00183),
    ("roll", "mean"): (-0.00198, -0.00189),
    ("heading", "std"): (0.00016, 0.00017),
    ("pitch", "std"): (0.00109, 0.00109),
    ("roll", "std"): (0.00116, 0.00116),
}


def rates(t: ArrayLike) -> np.ndarray:
    """Body rates (12) with the paper's constants, rad/s, shape (..., 3)."""
    t = np.asarray(t, dtype=float)[..., None]
    return _AMPLITUDE * np.sin(2.0 * np.pi * _FREQUENCY * t)  # (12), A = B = phi = 0


def increments(t_start: ArrayLike, t_end: ArrayLike) -> np.ndarray:
    """Exact integrals of the rates (12) over [t_start, t_end], rad, shape (..., 3)."""
    t0 = np.asarray(t_start, dtype=float)[..., None]
    t1 = np.asarray(t_end, dtype=float)[..., None]
    w = 2.0 * np.pi * _FREQUENCY
    safe = np.where(w > 0.0, w, 1.0)
    return np.where(w > 0.0, _AMPLITUDE / safe * (np.cos(safe * t0) - np.cos(safe * t1)), _AMPLITUDE * (t1 - t0))


_ALGORITHM = {"P": "matrizant (8)-(9)", "M": "reversible (11)"}


def _stats(angles_rad: Iterable[np.ndarray]) -> dict[str, tuple[float, float]]:
    names = ("heading", "pitch", "roll")
    return {name: (float(np.degrees(a).mean()), float(np.degrees(a).std())) for name, a in zip(names, angles_rad)}


def run(plot_dir: str | None = None, quick: bool = False) -> list[dict]:
    """Run the Table 1 experiment and return rows beside the printed values.

    Parameters
    ----------
    plot_dir : str, optional
        Directory for ``seed001_fig2.png`` (the error quaternions in time, as figure 2).
    quick : bool
        20 s instead of 200 s (the means then are a tenth of the printed ones).

    Returns
    -------
    list of dict
        Rows ``{"ref", "quantity", "paper", "navsim", "unit"}``; ``paper`` is None for
        rows without a printed counterpart.
    """
    duration = 20.0 if quick else DURATION_S
    h = STEP_S
    n = int(round(duration / h))
    ratio = int(round(h / REFERENCE_STEP_S))
    reference = rk4_integrate(rates, [1.0, 0.0, 0.0, 0.0], 0.0, REFERENCE_STEP_S, n * ratio)
    ref_h = reference[::ratio]  # Lambda at the multiples of h
    t = h * np.arange(n)
    theta = increments(t, t + h)
    quat0 = [1.0, 0.0, 0.0, 0.0]
    p = matrizant_integrate(quat0, theta)  # (8)-(9), at multiples of 2h
    m = reversible_integrate(quat0, theta)  # (11)
    p_printed = matrizant_integrate(quat0, theta, variant="printed")
    m_end_rate = reversible_integrate(quat0, h * rates(t + h))  # (11) literally: h omega(t0 + h)

    err_p = error_angles(ref_h[::2], p)
    err_m = error_angles(ref_h, m)
    stats = {"P": _stats(err_p), "M": _stats(err_m)}
    rows: list[dict] = []
    for (angle, stat), printed in TABLE1.items():
        for column, value in zip(("P", "M"), printed):
            mean, std = stats[column][angle]
            rows.append(
                {
                    "ref": "001 Table 1",
                    "quantity": f"{stat} {angle} error, {_ALGORITHM[column]}",
                    "paper": value,
                    "navsim": mean if stat == "mean" else std,
                    "unit": "deg",
                }
            )
    extras = {
        # at C_z = 0 only the literal f0 of the printed typos acts
        "matrizant as printed (renormalised)": _stats(
            error_angles(ref_h[::2], p_printed / np.linalg.norm(p_printed, axis=1, keepdims=True))
        ),
        "reversible fed h*omega(t0+h)": _stats(error_angles(ref_h, m_end_rate)),
    }
    for label, st in extras.items():
        for angle in ("pitch", "roll"):
            for k, stat in enumerate(("mean", "std")):
                rows.append(
                    {"ref": "001 Table 1", "quantity": f"{stat} {angle} error, {label}", "paper": None,
                     "navsim": st[angle][k], "unit": "deg"}
                )
    rows.append(
        {"ref": "001 (8)", "quantity": "norm of P at the end, printed f0", "paper": None,
         "navsim": float(np.linalg.norm(p_printed[-1])), "unit": "1"}
    )
    rows.append(
        {"ref": "001", "quantity": "run length used (not printed)", "paper": None, "navsim": duration, "unit": "s"}
    )

    if plot_dir is not None:
        _plot(plot_dir, ref_h, p, m, h)
    return rows


def _plot(plot_dir: str, ref_h: np.ndarray, p: np.ndarray, m: np.ndarray, h: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..strapdown.quaternion import error_quaternion

    os.makedirs(plot_dir, exist_ok=True)
    dp = error_quaternion(ref_h[::2], p)
    dm = error_quaternion(ref_h, m)
    tp = 2.0 * h * np.arange(len(dp))
    tm = h * np.arange(len(dm))
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for ax, t, d, name in ((axes[0], tp, dp, "Delta P (matrizant)"), (axes[1], tm, dm, "Delta M (reversible)")):
        for i in range(1, 4):
            ax.plot(t, d[:, i], lw=0.8, label=f"component {i}")
        ax.set_ylabel(name)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    axes[1].set_xlabel("t, s")
    fig.suptitle("Seed 001 fig. 2: error quaternions, h = 5 ms, RK4 reference at 1 ms")
    fig.tight_layout()
    from ..io import save_figure

    save_figure(fig, os.path.join(plot_dir, "seed001_fig2.png"), dpi=120)
    plt.close(fig)
