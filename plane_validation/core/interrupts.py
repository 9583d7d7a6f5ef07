"""Ctrl-C through the compiled kernels.

numba calls back into Python while it hands a kernel's result back (it unpickles what boxing needs). A Ctrl-C
that lands in that callback comes out of the kernel call as a SystemError whose cause is the KeyboardInterrupt,
so a caller that stops quietly on KeyboardInterrupt would print a traceback instead. The public calls that run
kernels for long raise the KeyboardInterrupt itself."""
from __future__ import annotations

import functools
from typing import Callable, Iterable, TypeVar

__all__ = ['interrupt_of', 'keeps_interrupts', 'stop_at_signals', 'unignored']

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


def unignored(handlers: dict | None = None) -> tuple[int, ...]:
    """Of SIGINT, SIGTERM and SIGHUP, those whose handler (in ``handlers``, signal -> handler, else the current one)
    is not to ignore them."""
    import signal
    stops = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    return tuple(sig for sig in stops if (signal.getsignal(sig) if handlers is None else handlers[sig])
                 is not signal.SIG_IGN)


def stop_at_signals(status: Callable[[int], int], note: str, signals: tuple[int, ...], pending: Iterable[int] = ()
                    ) -> None:
    """From now on each of ``signals`` ends the process at once with ``status(signum)``, after killing the child
    processes that multiprocessing started (a cold compile's workers, which ignore those signals) and printing
    ``note`` on stderr; the first of ``pending`` (signals held until now) among them does so at once. For a process
    that is compiling the kernels before it does anything else: numba writes each cache file whole (a temporary file
    renamed), so what was compiled stays cached and the rest compiles next time, where holding the signal (numba's
    compiler swallows a KeyboardInterrupt) kept it for the minutes of the compile."""
    import multiprocessing
    import multiprocessing.util
    import os
    import signal
    import sys

    def stop(signum: int, _frame) -> None:
        for child in multiprocessing.active_children():
            child.kill()
        # what exiting would clean up, os._exit does not: the pool's semaphores are removed here, or multiprocessing's
        # resource tracker removes them and warns of "leaked semaphore objects" after the note
        multiprocessing.util._run_finalizers(0)
        print(note, file=sys.stderr, flush=True)
        os._exit(status(signum))
    for sig in signals:
        signal.signal(sig, stop)
    for signum in [sig for sig in pending if sig in signals][:1]:
        signal.raise_signal(signum)
