"""The ``navsim`` command (package form; the sub-commands: :mod:`.commands`)."""

from .commands import build_parser, expected_failure, main

__all__ = ["main", "build_parser", "expected_failure"]
