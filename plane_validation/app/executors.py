"""Where the bags of a batch run: a local process pool (loky, as the tuning sweep uses) or an existing Ray
cluster through Ray's own API. Both yield ``(i, func(tasks[i]))`` as the tasks end, or ``(i, Lost(why))``
for a task whose worker process died more often than it is retried; stopping the iteration (Ctrl-C, SIGTERM)
stops the workers. No ROS import: ``func`` is any module-level function.
"""
from __future__ import annotations

import re
import signal
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

__all__ = ['Lost', 'RAY_RETRIES', 'LOCAL_ATTEMPTS', 'RAY_INSTALL', 'run_local', 'run_ray', 'ray_connection',
           'import_ray']

#: Times Ray runs a task again after its worker died (a node lost, out of memory): Ray's max_retries.
RAY_RETRIES = 3
#: Times the local pool runs a task whose worker process died (each death also stops the tasks beside it).
LOCAL_ATTEMPTS = 2
#: How long an interrupted batch waits for Ray to stop its running tasks (s).
CANCEL_WAIT_S = 10.0
#: What to do without Ray.
RAY_INSTALL = ("--ray needs Ray, in the package's fleet extra: pip install '.[fleet]' in the checkout "
               "(or pip install 'ray>=2.9')")


@dataclass(frozen=True)
class Lost:
    """A task that did not return: its worker process died, or it raised (``why``)."""

    why: str


def _worker_start() -> None:
    """A local worker's first step: one BLAS thread (the pool is the parallelism), freed memory reused, and Ctrl-C for
    the parent only, which stops the workers (a terminal sends it to the whole process group)."""
    from ..core.allocator import reuse_freed_memory
    from ..core.blas import limit_blas_threads
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    limit_blas_threads()
    reuse_freed_memory()


def run_local(func: Callable, tasks: list, workers: int) -> Iterator[tuple[int, object]]:
    """``func`` over ``tasks`` in ``workers`` processes, at most one task per worker at a time (so a worker
    that dies takes only its own task with it: that one is run again, up to LOCAL_ATTEMPTS times)."""
    from concurrent.futures import FIRST_COMPLETED, wait

    from joblib.externals.loky import BrokenProcessPool, ProcessPoolExecutor

    waiting = list(range(len(tasks)))[::-1]
    attempts = [0] * len(tasks)
    running: dict = {}
    executor = None
    finished = False
    try:
        while waiting or running:
            if executor is None:
                executor = ProcessPoolExecutor(max_workers=workers, initializer=_worker_start)
            while waiting and len(running) < workers:
                i = waiting.pop()
                attempts[i] += 1
                running[executor.submit(func, tasks[i])] = i, executor
            done, _ = wait(list(running), return_when=FIRST_COMPLETED)
            for future in done:
                i, pool = running.pop(future)
                try:
                    result = future.result()
                except BrokenProcessPool as exc:
                    if pool is executor:  # a new pool for the next ones
                        executor.shutdown(wait=False, kill_workers=True)
                        executor = None
                    if attempts[i] < LOCAL_ATTEMPTS:
                        waiting.append(i)
                        continue
                    result = Lost(f'its worker process died {attempts[i]} times ({type(exc).__name__}: {exc})')
                except Exception as exc:  # it raised (its result could not be sent back, say)
                    result = Lost(f'{type(exc).__name__}: {exc}')
                yield i, result
        finished = True
    finally:
        if executor is not None:
            if not finished:  # loky fails when it kills its workers before it has handed them their calls
                deadline = time.monotonic() + 1.0
                while not all(f.running() or f.done() for f in running) and time.monotonic() < deadline:
                    time.sleep(0.01)
            # waited for: no worker may go on writing once the caller cleans up
            executor.shutdown(wait=True, kill_workers=not finished)


def _last_line(exc: BaseException) -> str:
    """The last line of an exception's text (a traceback's is the error), without terminal colours."""
    lines = re.sub(r'\x1b\[[0-9;]*m', '', str(exc)).strip().splitlines()
    return lines[-1].strip() if lines else type(exc).__name__


def import_ray():
    """The ray module, or ValueError saying how to install it."""
    try:
        import ray
    except ImportError as exc:
        raise ValueError(RAY_INSTALL) from exc
    return ray


@contextmanager
def ray_connection(address: str | None) -> Iterator[None]:
    """Connected to the Ray cluster at ``address`` ('auto', 'host:port' or 'ray://host:port') for the block;
    nothing to do for None, or in a process already connected to Ray. ValueError when there is no such cluster."""
    if address is None:
        yield
        return
    ray = import_ray()
    if ray.is_initialized():
        yield
        return
    try:  # the workers' output is not ours to print (a Ray Client connection takes no such option)
        ray.init(address=address, **({} if address.startswith('ray://') else {'log_to_driver': False}))
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise ValueError(f'cannot connect to the Ray cluster at {address!r}: {" ".join(str(exc).split())} '
                         '(start one with `ray start --head`, give its address, or "auto" on one of its '
                         'nodes)') from exc
    try:
        yield
    finally:
        ray.shutdown()


def run_ray(func: Callable, tasks: list) -> Iterator[tuple[int, object]]:
    """``func`` over ``tasks`` on the Ray cluster this process is connected to (:func:`ray_connection`), one Ray
    task each (one CPU, retried RAY_RETRIES times when its worker is lost)."""
    ray = import_ray()
    remote = ray.remote(num_cpus=1, max_retries=RAY_RETRIES, retry_exceptions=False)(func)
    pending = {}
    try:
        pending = {remote.remote(task): i for i, task in enumerate(tasks)}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                i = pending.pop(ref)
                try:
                    result = ray.get(ref)
                except ray.exceptions.RayTaskError as exc:  # not retried: it would fail again (no such module?)
                    result = Lost(f'the Ray task failed: {_last_line(exc.cause or exc)}')
                except ray.exceptions.RayError as exc:
                    result = Lost(f'its Ray worker was lost {RAY_RETRIES + 1} times (Ray retries a task '
                                  f'{RAY_RETRIES} times): {type(exc).__name__}: {_last_line(exc)}')
                yield i, result
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if pending:  # their workers are killed: wait for that (a while), as the caller cleans up next
            ray.wait(list(pending), num_returns=len(pending), timeout=CANCEL_WAIT_S)
