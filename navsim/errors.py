"""The one small error hierarchy of navsim.

Every error raised on bad input derives from :class:`NavsimError`, and the ones about
values also from :class:`ValueError`, so ``except ValueError`` keeps working for callers
that do not know navsim. Messages name the argument, what was expected and what came.

A setting navsim accepts but whose consequence a user may not intend (a documented default
filled in) is a :class:`NavsimWarning` (the CLI prints it as one ``navsim: warning:`` line).

Missing data (a GNSS outage, a satellite below the mask) is *not* an error: it is a value
with a validity mask.
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "NavsimError",
    "ConfigError",
    "TrackError",
    "DependencyNotInstalled",
    "NavsimWarning",
    "check_positive",
    "check_nonnegative",
    "check_multiple",
    "file_value",
]


class NavsimError(Exception):
    """Base class of every error navsim raises on purpose."""


class ConfigError(NavsimError, ValueError):
    """A configuration value is wrong.

    Parameters
    ----------
    field : str
        Dotted name of the offending field, e.g. ``"timing.imu_period_s"``.
    expected : str
        What a valid value looks like.
    got : Any
        The value that came.
    source : str, optional
        Where the value came from (a file name), prefixed to the message.
    """

    def __init__(self, field: str, expected: str, got: Any, source: str | None = None):
        self.field = field
        self.expected = expected
        self.got = got
        self.source = source
        where = f"{source}: " if source else ""
        super().__init__(f"{where}{field}: expected {expected}, got {got!r}")


class NavsimWarning(UserWarning):
    """An accepted input with a consequence worth a word (a documented default used)."""


class TrackError(NavsimError, ValueError):
    """A track cannot be built or cannot be written in the requested form."""


class DependencyNotInstalled(NavsimError, ImportError):
    """An optional dependency is missing; the message says which extra installs it."""

    def __init__(self, package: str, extra: str):
        super().__init__(
            f"{package} is not installed; install it with: pip install 'navsim-track[{extra}]'"
        )


def check_positive(field: str, value: float) -> float:
    """Return ``float(value)`` if it is finite and > 0, else raise :class:`ConfigError`."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ConfigError(field, "a positive number", value) from None
    if not (number > 0.0 and number < float("inf")):
        raise ConfigError(field, "a positive finite number", value)
    return number


def check_nonnegative(field: str, value: float) -> float:
    """Return ``float(value)`` if it is finite and >= 0, else raise :class:`ConfigError`."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ConfigError(field, "a non-negative number", value) from None
    if not (number >= 0.0 and number < float("inf")):
        raise ConfigError(field, "a non-negative finite number", value)
    return number


def check_multiple(field: str, value: float, base: float, base_name: str) -> int:
    """Return ``value / base`` as an int if it is a whole number >= 1, else raise.

    Used for every rate of the time base: each period must be a whole multiple of the
    base tick (relative tolerance 1e-9).
    """
    value = check_positive(field, value)
    ratio = value / base
    count = round(ratio)
    if count < 1 or abs(ratio - count) > 1e-9 * max(1.0, ratio):
        raise ConfigError(field, f"a whole multiple of {base_name}={base!r}", value)
    return int(count)


def file_value(value: Any) -> Any:
    """What an error may show of a value read from a data file: numbers as they are, any
    text or structure only by its kind and size (a file's contents are never echoed: the
    file may not be what the user thinks, e.g. a system file named by mistake)."""
    if isinstance(value, (bool, int, float)) or value is None:
        return value
    if isinstance(value, (str, bytes)):
        return _Described(f"<text of {len(value)} characters>")
    try:
        return _Described(f"<{type(value).__name__} of {len(value)} items>")
    except TypeError:
        return _Described(f"<{type(value).__name__}>")


class _Described(str):
    """A description shown as is (no quotes) in an error message."""

    def __repr__(self) -> str:
        return str(self)
