"""Ctrl-C through the compiled kernels.

numba calls back into Python while it hands a kernel's result back (it unpickles what boxing needs). A Ctrl-C
that lands in that callback comes out of the kernel call as a SystemError whose cause is the KeyboardInterrupt,
so a caller that stops quietly on KeyboardInterrupt would print a traceback instead. The public calls that run
kernels for long raise the KeyboardInterrupt itself."""
from __future__ import annotations

import functools
from typing import Callable, TypeVar

__all__ = ['interrupt_of', 'keeps_interrupts']

F = TypeVar('F', bound=Callable)


def interrupt_of(error: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt among ``error``'s causes and contexts (None: none)."""
    seen: set[int] = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, KeyboardInterrupt):
            return error
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return None


def keeps_interrupts(func: F) -> F:
    """``func``, raising the KeyboardInterrupt where a SystemError out of a kernel call was caused by one."""
    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except SystemError as error:
            interrupt = interrupt_of(error)
            if interrupt is None:
                raise
            raise KeyboardInterrupt from interrupt
    return wrapper
