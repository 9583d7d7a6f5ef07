"""The ``plane-validation`` process: parse, run the command, and turn its end (an error, Ctrl-C, SIGTERM, SIGHUP, a
closed stdout) into one line and an exit status (see :mod:`.commands`)."""
from __future__ import annotations

import argparse
import sys
import threading
from collections.abc import Iterable, Iterator
from contextlib import contextmanager, suppress

from .commands import EXIT_BROKEN_PIPE, EXIT_USAGE, cmd_scene, cmd_warmup
from .parser import build_parser

__all__ = ['main', 'Terminated']


def _resolve_seed(args: argparse.Namespace) -> None:
    """A seed < 0 (fresh entropy) becomes a fresh non-negative one, which the output reports: the run
    can be repeated with it."""
    if getattr(args, 'seed', None) is not None and args.seed < 0:
        import secrets
        args.seed = secrets.randbits(31)  # within the seed parameter's range
        print(f'plane-validation: seed {args.seed} (--seed {args.seed} repeats this run)', file=sys.stderr)


class Terminated(BaseException):
    """SIGTERM or SIGHUP arrived: unwind like KeyboardInterrupt (partial outputs are removed)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _raise_terminated(signum: int, _frame) -> None:
    import signal
    for sig in (signal.SIGTERM, signal.SIGHUP):  # a second signal must not interrupt the clean-up
        signal.signal(sig, signal.SIG_IGN)
    raise Terminated(signum)


@contextmanager
def _terminate_cleanly() -> Iterator[None]:
    """SIGTERM and SIGHUP (timeout, systemd, docker stop, a closed terminal) raise Terminated in
    the main thread, so every ``with``/``finally`` cleans up as for Ctrl-C. A signal the process was started
    ignoring (SIGHUP under nohup) stays ignored."""
    import signal
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    from ..core.interrupts import unignored
    previous = {sig: signal.signal(sig, _raise_terminated) for sig in unignored() if sig != signal.SIGINT}
    previous_hook = sys.unraisablehook

    def redeliver(unraisable) -> None:
        """A signal's exception raised inside a finalizer (``__del__``) is printed and dropped by Python: the
        command would go on and exit 0. The signal is raised again, to land in the main thread's code."""
        previous_hook(unraisable)
        if isinstance(unraisable.exc_value, Terminated):  # once this hook has returned (raised here, it is dropped
            # again); the handler runs in the main thread, and a timer is another thread
            signal.signal(unraisable.exc_value.signum, _raise_terminated)
            later = threading.Timer(0.01, signal.raise_signal, args=(unraisable.exc_value.signum,))
            later.daemon = True
            later.start()

    sys.unraisablehook = redeliver
    try:
        yield
    finally:
        sys.unraisablehook = previous_hook
        for sig, handler in previous.items():
            signal.signal(sig, handler)


#: What a command says before it compiles the kernels on a cold cache (the first run on a machine).
COLD_CACHE_NOTE = ('plane-validation: compiling the kernels for this machine, once (about 1-2 minutes on an idle '
                   '2-core machine; Ctrl-C stops it, keeping what is compiled); later runs load them from the cache')


def _stop_at_signals(handlers: dict | None = None, pending: Iterable[int] = ()) -> None:
    """From now on SIGINT, SIGTERM and SIGHUP stop the command at once, with the signal's exit status: while it
    compiles the kernels, before it has started (:func:`~..core.interrupts.stop_at_signals`; the first of
    ``pending``, held so far, at once). Not one whose handler (in ``handlers``, else the current one) is to ignore
    it: a script's background job starts with SIGINT ignored."""
    from ..core.interrupts import stop_at_signals, unignored
    stop_at_signals(lambda signum: 128 + signum, 'plane-validation: stopped while compiling the kernels',
                    unignored(handlers), pending)


def _load_kernels() -> None:
    """Load (or compile) the compiled kernels with SIGINT, SIGTERM and SIGHUP held, then deliver the first one
    held: an exception raised inside numba's loader or compiler is dropped, or crashes it in a callback. Once a cold
    cache is found (minutes of compiling) a signal stops the command at once instead (:func:`_stop_at_signals`)."""
    import os
    import signal

    from ..core.kernels import warm, warm_probe
    caught: list[int] = []
    held = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    previous = {sig: signal.signal(sig, lambda signum, _frame: caught.append(signum)) for sig in held}
    try:
        cold = warm_probe().compiled
        if cold:  # minutes without a word would look like a hang, and minutes of a held Ctrl-C too
            print(COLD_CACHE_NOTE, file=sys.stderr, flush=True)
            _stop_at_signals(previous, caught)  # and at once for one held while the first kernels compiled
        warm(jobs=os.cpu_count() or 1, cold=cold)  # a cold cache compiles on every core
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    for signum in caught[:1]:
        signal.raise_signal(signum)


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
        _resolve_seed(args)
        from ..app.pipeline import limit_blas_threads, reuse_freed_memory
        from ..core.workers import TuningWorkerError, stop_workers, workers_ignore_sigint
        limit_blas_threads()  # small matrix products; spinning BLAS threads only slow a busy machine down
        reuse_freed_memory()  # a frame's arrays from the heap, not fresh pages (core/allocator.py)
    except KeyboardInterrupt:  # while they load (threadpoolctl opens the BLAS libraries)
        return 130
    try:
        with _terminate_cleanly(), workers_ignore_sigint():
            if args.func not in (cmd_scene, cmd_warmup):
                _load_kernels()
            elif args.func is cmd_warmup:  # all it does is compile or load the kernels: a signal stops it at once
                _stop_at_signals()
            return args.func(args)
    except KeyboardInterrupt:
        return 130
    except Terminated as exc:
        return 128 + exc.signum
    except SystemError as exc:  # a signal's exception raised while a compiled kernel ran comes wrapped in one or more
        cause = exc
        while isinstance(cause, SystemError) and cause.__cause__ is not None:
            cause = cause.__cause__
        if isinstance(cause, Terminated):
            return 128 + cause.signum
        if isinstance(cause, KeyboardInterrupt):
            return 130
        raise
    except BrokenPipeError:  # stdout closed early (piped into head): quiet, as a tool killed by SIGPIPE
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # nothing left to flush at exit
        return EXIT_BROKEN_PIPE
    except (ValueError, OSError, TuningWorkerError) as exc:
        message = ' '.join(str(exc).split()) or type(exc).__name__
        print(f'plane-validation: error: {message}', file=sys.stderr)
        return 1 if isinstance(exc, TuningWorkerError) else EXIT_USAGE
    finally:  # a parallel sweep's workers end with the command, whatever ended it; left to the interpreter's exit,
        # a signal while they started could leave it waiting for loky's threads for ever
        with suppress(KeyboardInterrupt):
            stop_workers()


if __name__ == '__main__':
    sys.exit(main())
