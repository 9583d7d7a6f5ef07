"""Worker processes for a tolerance sweep's calls: loky's reusable pool (joblib), the sweep's shared arguments
sent to each worker once, and Ctrl-C and termination handled so that no worker outlives or hangs its sweep.

:func:`parallel_calls` runs one function over many argument tuples in this process and ``jobs - 1`` workers;
:func:`stop_workers` ends the pool; :func:`workers_ignore_sigint` is the command line's choice for Ctrl-C.
"""
from __future__ import annotations

import collections
import contextlib
import contextvars
import os
import queue
import signal
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from concurrent.futures import BrokenExecutor, Future

from .allocator import reuse_freed_memory

__all__ = ['TuningWorkerError', 'parallel_calls', 'in_order', 'stop_workers', 'workers_ignore_sigint', 'WORKER_IDLE_S']


class TuningWorkerError(RuntimeError):
    """A worker process of a parallel sweep (``jobs`` != 1) died before it answered."""


#: Idle worker processes of a parallel sweep stay this long (joblib's default), so that a retune or
#: the next sweep within it does not start them again.
WORKER_IDLE_S = 300
#: One parallel sweep at a time per process: the shared worker pool cannot be resized for a sweep
#: with another worker count while one runs (the two would wait on each other).
_PARALLEL = threading.Lock()


@contextlib.contextmanager
def parallel_calls(jobs: int, shared: tuple = ()
             ) -> Iterator[Callable[[Callable, list[tuple]], Iterator[tuple[int, object]]]]:
    """``run(func, argument_tuples)``: an iterator of ``(i, func(*shared, *argument_tuples[i]))`` in the order
    the calls end. ``shared``: the arguments every call begins with (a sweep's points and graph), sent to each
    worker process once (:class:`_Carrier`). With ``jobs`` != 1 this process is one of ``jobs`` (0 = one per
    core, never more than the cores): loky's reusable worker processes take the calls one at a time from the
    last, and this process takes them from the first while the iterator is read. It works while the workers
    start, and the slow calls (a sweep's smallest tolerances come first) are not the last ones. With 1 the
    calls are made here, one by one, as the iterator is read."""
    if jobs != 1:
        from joblib import cpu_count  # imported only for a parallel sweep: a heavy import
        jobs = cpu_count() if jobs == 0 else min(jobs, cpu_count())
    if jobs == 1:
        yield lambda func, calls: ((i, func(*shared, *args)) for i, args in enumerate(calls))
        return
    from joblib.externals.loky import get_reusable_executor
    shares: list[_Shared] = []
    carrier = _Carrier(shared, jobs - 1)

    def run(func: Callable, calls: list[tuple]) -> Iterator[tuple[int, object]]:
        with _sigint_ignored():  # loky starts (or resizes) its worker processes with the first calls
            shares.append(_Shared(executor, func, calls, jobs - 1, carrier))
        return shares[-1].results()
    try:
        with _PARALLEL:
            with _sigint_ignored():
                executor = get_reusable_executor(max_workers=jobs - 1, timeout=WORKER_IDLE_S,
                                                  initializer=_worker_start)
            global _EXECUTOR
            _EXECUTOR = executor
            try:
                yield run
            except BaseException:  # an error, Ctrl-C: the calls running in a worker are not waited for
                busy = [future for share in shares for future in share.stop()]
                deadline = time.monotonic() + 1.0
                while not all(f.running() or f.done() for f in busy) and time.monotonic() < deadline:
                    time.sleep(0.001)  # loky fails when it kills its workers before it has handed them a call
                if busy:
                    executor.shutdown(wait=False, kill_workers=True)
                raise
            finally:  # no more calls to the workers (reruns of a cloud without planes are left unread)
                for share in shares:
                    share.stop()
    except BrokenExecutor as exc:  # a worker was killed (out of memory, a signal): not a bug of the cloud
        raise TuningWorkerError(f'a tuning worker process died ({type(exc).__name__})') from exc


#: The reusable executor of the last parallel sweep (None before the first): stop_workers ends it.
_EXECUTOR = None


def stop_workers() -> None:
    """End and reap the worker processes parallel sweeps started (loky's reusable executor; a running call is
    killed). A process that ends (a node that shuts down) calls it: left alone the workers outlive it for
    WORKER_IDLE_S, or forever when it dies abruptly. The resource trackers they shared end on their own once
    no process holds their pipe. The next parallel sweep starts new workers."""
    global _EXECUTOR
    executor, _EXECUTOR = _EXECUTOR, None
    if executor is not None:
        # a signal's exception between loky making its manager thread and starting it raises RuntimeError
        with contextlib.suppress(RuntimeError):
            executor.shutdown(wait=True, kill_workers=True)
    # an earlier shutdown(wait=False) (an error or a signal during a sweep) leaves the killing to loky's thread
    # and nothing joins the workers: they are killed and reaped here, or a container's PID 1 inherits zombies
    import multiprocessing
    import sys
    if 'joblib.externals.loky.backend.process' not in sys.modules:  # no sweep ever ran in parallel here
        return
    from joblib.externals.loky.backend.process import LokyProcess
    for process in multiprocessing.active_children():
        if isinstance(process, LokyProcess):
            with contextlib.suppress(ProcessLookupError):
                os.kill(process.pid, signal.SIGKILL)  # loky's Popen has no kill()
            process.join()


class _NotCarried(Exception):
    """A worker process was handed a call without the shared arguments, which it does not hold."""


#: In a worker process: (token, shared arguments) of the last sweep that sent them.
_CARRIED: tuple[str, tuple] | None = None


def _call_carried(token: str, shared: tuple | None, func: Callable, args: tuple):
    """In a worker: ``func(*shared, *args)``, ``shared`` kept for the next calls of the same ``token``
    (None: the ones kept, or _NotCarried)."""
    global _CARRIED
    if shared is not None:
        _CARRIED = (token, shared)
    elif _CARRIED is None or _CARRIED[0] != token:
        raise _NotCarried(token)
    return func(*_CARRIED[1], *args)


class _Carrier:
    """The shared arguments of one parallel sweep: sent with the first call to each of ``workers`` worker
    processes only (the graph of a large cloud is megabytes, whose pickling through a pipe took a tenth of a
    call). A worker handed a call without them (loky may give two of the first calls to one worker)
    raises _NotCarried; that call is then made in this process, and the later ones carry them again. An idle worker
    holds the last sweep's shared arguments until the next sweep replaces them or it ends (WORKER_IDLE_S)."""

    def __init__(self, shared: tuple, workers: int) -> None:
        self.shared, self.token = shared, uuid.uuid4().hex
        self.first = workers  # calls that still carry them
        self.lock = threading.Lock()

    def submit(self, executor, func: Callable, args: tuple) -> Future:
        with self.lock:
            carry = self.first > 0
            self.first -= carry
        return executor.submit(_call_carried, self.token, self.shared if carry else None, func, args)

    def carry_always(self) -> None:
        with self.lock:
            self.first = 1 << 62

    def result(self, future: Future, func: Callable, args: tuple):
        """The result of a call ``submit`` made; made here if its worker lacked the shared arguments."""
        try:
            return future.result()
        except _NotCarried:
            self.carry_always()
            return func(*self.shared, *args)


def _worker_start() -> None:
    """A worker process's first step: a Ctrl-C reaches the sweep's process, which stops the workers (a
    worker interrupted while it sends a result leaves loky's pipe unreadable: the process then hangs); a candidate's
    arrays come from the heap, as in the process that started the sweep (:mod:`.allocator`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    reuse_freed_memory()


class _Shared:
    """The calls of one ``run``: the workers take them from the last (the next one when one ends, so
    none waits in a queue for them), this process from the first (:meth:`results`). The calls after the
    first ones are handed out by a thread of their own: loky's thread, which reports a call's end, must
    not wait for loky's lock (another thread that resizes the pool holds it while it waits for that one)."""

    def __init__(self, executor, func: Callable, calls: list[tuple], workers: int, carrier: _Carrier) -> None:
        self.executor, self.func, self.calls, self.carrier = executor, func, calls, carrier
        self.left = collections.deque(range(len(calls)))
        self.lock = threading.Lock()
        self.ended: queue.SimpleQueue = queue.SimpleQueue()  # (i, future) of the workers' calls
        self.free: queue.SimpleQueue = queue.SimpleQueue()  # a worker is free (or stop)
        self.sent, self.stopped = 0, False
        self.busy: dict[int, Future] = {}  # the workers' calls not ended
        for _ in range(workers):
            self._send()
        threading.Thread(target=self._feed, name='tuning-feed', daemon=True).start()

    def _send(self) -> bool:
        """Hands a worker the last call left; False when there is none (or after stop)."""
        with self.lock:
            if self.stopped or not self.left:
                return False
            i = self.left.pop()
            self.sent += 1
        try:
            future = self.carrier.submit(self.executor, self.func, self.calls[i])
        except Exception as exc:  # a broken or shut-down pool: the error reaches the reader
            future = Future()
            future.set_exception(exc)
        with self.lock:
            self.busy[i] = future
        future.add_done_callback(lambda f: self._ended(i, f))
        return True

    def _feed(self) -> None:
        while True:
            self.free.get()
            if not self._send():
                return

    def _ended(self, i: int, future: Future) -> None:
        with self.lock:
            self.busy.pop(i, None)
        if not future.cancelled() and isinstance(future.exception(), _NotCarried):
            self.carrier.carry_always()  # before the next call is handed out (a new worker, e.g. a restarted one)
        self.ended.put((i, future))
        self.free.put(None)

    def results(self) -> Iterator[tuple[int, object]]:
        received = 0
        while True:
            while not self.ended.empty():
                i, future = self.ended.get()
                received += 1
                yield i, self.carrier.result(future, self.func, self.calls[i])
            with self.lock:
                i = self.left.popleft() if self.left else None
            if i is None:
                break
            yield i, self.func(*self.carrier.shared, *self.calls[i])
        while received < self.sent:
            i, future = self.ended.get()
            received += 1
            yield i, self.carrier.result(future, self.func, self.calls[i])

    def stop(self) -> list[Future]:
        """No more calls to the workers; the calls not ended there."""
        with self.lock:
            self.stopped = True
            busy = list(self.busy.values())
        self.free.put(None)  # the feeding thread ends
        return busy


def in_order(results: Iterator[tuple[int, object]]) -> Iterator:
    """The results of ``run`` in the order of their calls (read when the first is asked for)."""
    yield from (result for _, result in sorted(results, key=lambda pair: pair[0]))


#: Set by :func:`workers_ignore_sigint` (a command line's choice, not the library's: a process with
#: rclpy has its SIGINT handler in C, which Python cannot save and put back).
_QUIET_WORKERS: contextvars.ContextVar[bool] = contextvars.ContextVar('quiet_workers', default=False)


@contextlib.contextmanager
def workers_ignore_sigint() -> Iterator[None]:
    """Within this block (in the main thread of a process without rclpy), parallel sweeps start their
    worker processes with SIGINT ignored: Ctrl-C, which a terminal sends to the whole process group,
    then reaches only this process, which stops them, instead of interrupting them mid-import or
    mid-task with tracebacks of their own. A Ctrl-C that lands while numba loads a kernel from its cache
    leaves it as a SystemError caused by the KeyboardInterrupt: it leaves the block as the
    KeyboardInterrupt it is. The command line uses it."""
    token = _QUIET_WORKERS.set(True)
    try:
        yield
    except SystemError as exc:
        if isinstance(exc.__cause__, KeyboardInterrupt):
            raise exc.__cause__ from None
        raise
    finally:
        _QUIET_WORKERS.reset(token)


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """While joblib starts worker processes, when the caller asked for it (:func:`workers_ignore_sigint`): SIGINT
    ignored (they inherit it), a Ctrl-C in that moment (milliseconds) being lost; SIGTERM and SIGHUP, when Python
    handles them, held until the workers are started and known to loky (a handler's exception in between left a
    started worker that nothing ends)."""
    if threading.current_thread() is not threading.main_thread():
        yield  # only the main thread may set handlers
        return
    if not _QUIET_WORKERS.get():
        yield  # not asked for: a process with rclpy keeps its handlers as they are
        return
    held: list[int] = []
    deferred = {sig: signal.getsignal(sig) for sig in (signal.SIGTERM, signal.SIGHUP)}
    deferred = {sig: handler for sig, handler in deferred.items() if callable(handler)}
    previous = signal.getsignal(signal.SIGINT)
    quiet = previous is not None  # None: a handler set outside Python
    try:
        for sig in deferred:
            signal.signal(sig, lambda signum, _frame: held.append(signum))
        if quiet:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        yield
    finally:
        if quiet:
            signal.signal(signal.SIGINT, previous)
        for sig, handler in deferred.items():
            signal.signal(sig, handler)
        for signum in held[:1]:
            signal.raise_signal(signum)
