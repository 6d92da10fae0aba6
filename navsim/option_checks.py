"""Checks of estimator options: one wording for every filter, and nothing of the truth side.

The checks the estimators' option classes share (re-exported by :mod:`navsim.validation`):

* :func:`check_choice` / :func:`check_auto_none`: a name from a fixed set (the switches
  ``lever_arm``, ``atmosphere``, ``clock`` and one per optional sensor: ``"auto"`` uses what
  the context provides, ``"none"`` leaves the aid out);
* :func:`check_positive_finite`: a real number ``0 < x < inf`` (periods, sigmas, factors);
* :func:`check_optional_positive_finite`: the same, or None (a default taken from the context);
* :func:`check_nonnegative_finite`: a real number ``0 <= x < inf`` (power spectral densities);
* :func:`check_time_constant`: the correlation time ``tau`` of a first-order Gauss-Markov
  process, ``0 < tau <= inf`` (``inf``: the random constant, ``phi = exp(-dt / tau) = 1``);
* :func:`check_integer`: a whole number ``>= minimum`` (counts: satellites, epochs);
* :func:`check_probability`: a probability ``0 < p < 1``.

A "real number" is an ``int`` or ``float`` (NumPy's float64 is a float; NumPy integers are
accepted through :class:`numbers.Real`), never a ``bool`` nor a string; the value comes
back as a ``float``. NaN fails every comparison and is refused. A "whole number" is an
``int`` (or a NumPy integer) or a float with an integral value (``4.0``, as TOML and JSON
option files may give it), never a ``bool``; it comes back as an ``int``.
"""

from __future__ import annotations

import math
import numbers
from typing import Collection

from .errors import ConfigError

__all__ = ["check_choice", "check_auto_none", "check_positive_finite", "check_optional_positive_finite",
           "check_nonnegative_finite", "check_time_constant", "check_integer", "check_probability"]


def check_choice(field: str, value: object, choices: Collection[str]) -> str:
    """``value`` if it is one of the names ``choices``, else :class:`ConfigError`.

    >>> check_choice("update", "joint", ("joint", "sequential"))
    'joint'
    """
    if not isinstance(value, str) or value not in choices:
        expected = " or ".join(repr(c) for c in choices) if len(choices) <= 2 else f"one of {sorted(choices)}"
        raise ConfigError(field, expected, value)
    return value


def check_auto_none(field: str, value: object) -> str:
    """An aid switch: ``"auto"`` (use what the context provides) or ``"none"`` (leave it out).

    >>> check_auto_none("lever_arm", "none")
    'none'
    """
    return check_choice(field, value, ("auto", "none"))


def _real(value: object) -> float | None:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return None
    return float(value)


def check_positive_finite(field: str, value: object, expected: str = "a positive finite number") -> float:
    """``float(value)`` for a real number with ``0 < value < inf``, else :class:`ConfigError`
    (``expected`` is the wording of the message, e.g. ``"a positive finite time, s"``).

    >>> check_positive_finite("odometer_period_s", 1)
    1.0
    """
    number = _real(value)
    if number is None or not (0.0 < number < math.inf):
        raise ConfigError(field, expected, value)
    return number


def check_optional_positive_finite(field: str, value: object,
                                   expected: str = "None or a positive finite number") -> float | None:
    """None, or ``float(value)`` for a real number with ``0 < value < inf``."""
    if value is None:
        return None
    return check_positive_finite(field, value, expected)


def check_nonnegative_finite(field: str, value: object, expected: str = "a non-negative finite number") -> float:
    """``float(value)`` for a real number with ``0 <= value < inf``, else :class:`ConfigError`.

    >>> check_nonnegative_finite("accel_psd", 0)
    0.0
    """
    number = _real(value)
    if number is None or not (0.0 <= number < math.inf):
        raise ConfigError(field, expected, value)
    return number


def check_time_constant(field: str, value: object,
                        expected: str = "a positive time constant, s (inf: a random constant)") -> float:
    """A first-order Gauss-Markov correlation time: ``float(value)`` for ``0 < value <= inf``
    (``inf`` is the random constant), else :class:`ConfigError`.

    >>> check_time_constant("ionosphere_tau_s", float("inf"))
    inf
    """
    number = _real(value)
    if number is None or not number > 0.0:
        raise ConfigError(field, expected, value)
    return number


def check_integer(field: str, value: object, minimum: int, expected: str | None = None) -> int:
    """``int(value)`` for a whole number ``>= minimum`` (module docstring), else
    :class:`ConfigError` (``expected`` defaults to "an integer >= minimum").

    >>> check_integer("min_satellites", 4.0, 4)
    4
    """
    number = _real(value)
    if number is None or not (math.isfinite(number) and number == int(number) and number >= minimum):
        raise ConfigError(field, expected or f"an integer >= {minimum}", value)
    return int(number)


def check_probability(field: str, value: object, expected: str = "a probability in (0, 1)") -> float:
    """``float(value)`` for a real number with ``0 < value < 1``, else :class:`ConfigError`.

    >>> check_probability("divergence_probability", 1e-6)
    1e-06
    """
    number = _real(value)
    if number is None or not (0.0 < number < 1.0):
        raise ConfigError(field, expected, value)
    return number
