"""BLAS thread limit for the core's small matrix products.

The truth generator applies precomputed matrices to blocks of node values (a block of
``b`` samples fitted with ``N`` Chebyshev nodes: ``(b, N) @ (N, 18)`` per block, with
``b = 1000`` at 1 kHz) and the GNSS model rotates a few vectors per epoch. These products
are far too small for a multi-threaded BLAS to pay: OpenBLAS splits a product above a
fixed size over all cores, and waking and joining the threads costs more than the
product, worst when the cores are busy with other work. The core therefore runs its
generation passes (:meth:`navsim.truthgen.TruthGenerator.samples`, the simulator's chunk
generation) with the BLAS libraries limited to :data:`CORE_BLAS_THREADS` thread(s),
locally: the limit is set on entry and the previous setting restored on exit, so the
caller's own BLAS work keeps its threads.

The limit uses threadpoolctl [1]_ (one controller, made on first use, for the BLAS
libraries loaded by then - NumPy's is always among them). Threading does not change a
product's numbers in OpenBLAS's GEMM (it splits the result's rows and columns over the
threads, never the inner dimension, so each element is the same dot product in the same
order; ``tests/test_threads.py`` checks the truth generator bit for bit both ways), so
the limit is a speed setting only.

    from navsim import threads
    threads.set_core_blas_threads(None)   # leave BLAS threading alone (as before)
    threads.set_core_blas_threads(1)      # the default

References
----------
.. [1] threadpoolctl, https://github.com/joblib/threadpoolctl (``ThreadpoolController.limit``).
"""

from __future__ import annotations

import contextlib
import functools
import threading
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

__all__ = ["CORE_BLAS_THREADS", "blas_limit", "core_blas_threads", "set_core_blas_threads", "limited"]

CORE_BLAS_THREADS: int | None = 1
"""BLAS threads for the core's generation passes (None: no limit). See :func:`set_core_blas_threads`."""

_controller = None
_lock = threading.Lock()
_local = threading.local()  # nesting depth per thread: only the outermost call sets the limit

F = TypeVar("F", bound=Callable)


def set_core_blas_threads(n: int | None) -> None:
    """Set the BLAS thread limit of the core's generation passes (None: no limit)."""
    global CORE_BLAS_THREADS
    if n is not None and (not isinstance(n, int) or n < 1):
        raise ValueError(f"core BLAS threads must be a positive int or None, got {n!r}")
    CORE_BLAS_THREADS = n


def core_blas_threads() -> int | None:
    """The current limit (None: no limit)."""
    return CORE_BLAS_THREADS


def _get_controller() -> Any:
    global _controller
    if _controller is None:
        with _lock:
            if _controller is None:
                from threadpoolctl import ThreadpoolController

                _controller = ThreadpoolController()
    return _controller


@contextlib.contextmanager
def blas_limit() -> Iterator[None]:
    """Limit the BLAS libraries to :data:`CORE_BLAS_THREADS` inside the block (nests)."""
    depth = getattr(_local, "depth", 0)
    if depth or CORE_BLAS_THREADS is None:
        _local.depth = depth + 1
        try:
            yield
        finally:
            _local.depth = depth
        return
    _local.depth = 1
    try:
        with _get_controller().limit(limits=CORE_BLAS_THREADS, user_api="blas"):
            yield
    finally:
        _local.depth = 0


def limited(fn: F) -> F:
    """Decorator: run ``fn`` inside :func:`blas_limit`."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with blas_limit():
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
