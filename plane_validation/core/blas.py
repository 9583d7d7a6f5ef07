"""One BLAS thread around the library's hot code, so a plain script runs as fast as the node.

The products here are small ((k, 3) @ (3, n)); OpenBLAS's spinning worker threads only slow
them down, several-fold when another busy thread or process shares the cores (benchmarks/README.md).
The BLAS thread count is process-wide: calls that overlap (from several threads, or nested) share
one limit, set by the first to enter and restored by the last to leave.
"""
from __future__ import annotations

import contextlib
import functools
import threading
from collections.abc import Callable, Iterator
from typing import TypeVar

__all__ = ['single_blas_thread', 'limit_blas_threads']

F = TypeVar('F', bound=Callable)
_lock = threading.Lock()
_active = 0
_restore = None


@functools.cache
def _controller():
    """The process's thread pools, found once: scanning the loaded libraries costs about as much as
    a small frame's RANSAC, and the BLAS libraries are loaded by the time the hot code runs."""
    from threadpoolctl import ThreadpoolController
    return ThreadpoolController()


@contextlib.contextmanager
def _limiter() -> Iterator[None]:
    global _active, _restore
    with _lock:
        if _active == 0:
            _restore = _controller().limit(limits=1, user_api='blas')
        _active += 1
    try:
        yield
    finally:
        with _lock:
            _active -= 1
            if _active == 0:
                _restore.restore_original_limits()
                _restore = None


def single_blas_thread(func: F) -> F:
    """Run ``func`` with BLAS limited to one thread (see the module docstring)."""
    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with _limiter():
            return func(*args, **kwargs)
    return wrapper


def limit_blas_threads(threads: int = 1) -> None:
    """Limit BLAS to ``threads`` threads for the rest of the process (the node and the command
    line call this at start; the library's own limit then has nothing left to do). The libraries found here are
    kept for that limit: a node's first frame does not scan them again (about 15 ms)."""
    _controller().limit(limits=threads, user_api='blas')
