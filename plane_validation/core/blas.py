"""One BLAS thread around the library's hot code, so a plain script runs as fast as the node.

The products here are small ((k, 3) @ (3, n)); OpenBLAS's spinning worker threads only slow
them down, several-fold when another busy thread or process shares the cores (benchmarks/README.md).
"""
from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from typing import TypeVar

__all__ = ['single_blas_thread']

F = TypeVar('F', bound=Callable)
_state = threading.local()
_controller = None


def _limiter():
    global _controller
    if _controller is None:
        from threadpoolctl import ThreadpoolController
        _controller = ThreadpoolController()
    return _controller.limit(limits=1, user_api='blas')


def single_blas_thread(func: F) -> F:
    """Run ``func`` with BLAS limited to one thread (restored afterwards; nested calls limit once)."""
    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        if getattr(_state, 'active', False):
            return func(*args, **kwargs)
        _state.active = True
        try:
            with _limiter():
                return func(*args, **kwargs)
        finally:
            _state.active = False
    return wrapper
