"""The entry point :func:`main` and the one-line messages of expected failures
(:func:`expected_failure`: bad input, I/O, a corrupt file; exit status 2). navsim's warnings
(:class:`~navsim.errors.NavsimWarning`) are printed as one `navsim: warning:` line each after a
command that succeeds; after a failure the error is the one line.
"""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path
from typing import TextIO

from ..errors import NavsimError, NavsimWarning
from .parser import build_parser


def expected_failure(exc: BaseException) -> str | None:
    """The one-line message of an expected failure (bad input, I/O, a corrupt file), or
    None for anything else (a bug: its traceback is kept). Messages name the file and the
    reason, never the file's contents."""
    import sqlite3
    import zipfile

    if isinstance(exc, NavsimError):
        return str(exc)
    if isinstance(exc, UnicodeDecodeError):
        return f"a file is not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at offset {exc.start})"
    if isinstance(exc, OSError):
        where = f": {Path(exc.filename).name}" if getattr(exc, "filename", None) else ""
        return f"{exc.strerror or type(exc).__name__}{where}"
    if isinstance(exc, sqlite3.DatabaseError):
        return f"a database cannot be used ({exc})"
    if isinstance(exc, (zipfile.BadZipFile, EOFError)):
        return f"a file is truncated or not the expected archive ({type(exc).__name__})"
    if isinstance(exc, MemoryError):
        return "not enough memory for these settings (fewer steps per chunk, a longer IMU period or a shorter episode)"
    return None


def _silence_stdout() -> None:
    """Point stdout at the null device, so that the interpreter's flush at exit does not
    fail again on the closed pipe (the recipe of Python's documentation, signal module,
    "Note on SIGPIPE")."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # no file descriptor behind stdout (captured): nothing to flush
        pass


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a bad argument (one line, status 2)
        return exc.code if isinstance(exc.code, int) else 2
    noted: list[str] = []  # navsim's warnings: printed after a command that succeeds (an error is the one line)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always", NavsimWarning)  # every time (deduplicated below), not once per place
            _show = warnings.showwarning

            def show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                     file: TextIO | None = None, line: str | None = None) -> None:
                if issubclass(category, NavsimWarning):
                    noted.append(" ".join(str(message).split()))
                else:
                    _show(message, category, filename, lineno, file, line)

            warnings.showwarning = show
            code = args.func(args)
        for text in dict.fromkeys(noted):  # each once, in order
            print(f"navsim: warning: {text}", file=sys.stderr)
        return code
    except KeyboardInterrupt:
        print("navsim: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader of stdout left (`navsim run --json | head`): stop quietly
        _silence_stdout()
        return 141  # 128 + SIGPIPE, as a shell reports a pipeline's writer killed by it
    except Exception as exc:
        message = expected_failure(exc)
        if message is None:
            raise
        print(f"navsim: error: {' '.join(message.split())}", file=sys.stderr)
        return 2
