"""``plane-validation batch``: offline replay of many bags, on a local process pool or a Ray cluster.

Each bag is :func:`~.replay.replay_offline` (the same output bag as ``replay``) plus a summary and a report,
made by :func:`process_bag` in a worker process; :func:`run_batch` plans the bags, skips those already done,
runs the others and writes the index (:mod:`plane_validation.app.fleet`).

Where outputs are written: the driver puts a marker file in the output folder; a worker that sees it (the same
machine, or a file system shared at the same path) writes the bag's folder there itself; one that does not
returns the files to the driver, which writes them.
"""
from __future__ import annotations

import os
import shutil
import socket
import sys
import tempfile
import time
import uuid
from collections.abc import Callable, Iterable, Iterator
from contextlib import closing, contextmanager
from dataclasses import dataclass
from pathlib import Path

from ..app.config import PipelineConfig
from ..app.executors import Lost, ray_connection, run_local, run_ray
from ..app.fleet import (
    REPORT,
    SUMMARY,
    BagJob,
    Row,
    Status,
    done_summary,
    failed_row,
    find_bags,
    frame_record,
    plan_jobs,
    publish_folder,
    remove_staging,
    row_of,
    staged_folder,
    summary_document,
    write_index,
)
from ..app.report import dumps
from .replay import replay_offline

__all__ = ['Outcome', 'process_bag', 'run_batch', 'default_workers']

#: The lock file that keeps two batches out of one output folder.
LOCK = '.batch.lock'


@dataclass(frozen=True)
class Outcome:
    """What a worker returns for one bag: its summary, or why it failed; ``files`` (path in the bag's folder ->
    bytes) when the worker could not write into the output folder itself."""

    summary: dict | None
    error: str | None = None
    files: dict[str, bytes] | None = None


def process_bag(task: tuple[BagJob, str]) -> Outcome:
    """In a worker: replay one bag into a hidden folder and rename it to ``OUT/<name>`` once complete.
    ``task``: the job and the name of the driver's marker file in OUT. Never raises for a bad bag: any
    failure is the Outcome's error."""
    from ..app.pipeline import limit_blas_threads, reuse_freed_memory
    from ..app.plot import plot_bag_report

    job, marker = task
    limit_blas_threads()  # on any executor: the parallelism is one bag per worker
    reuse_freed_memory()
    start = time.perf_counter()
    shared = (job.out / marker).is_file()
    base = job.out if shared else Path(tempfile.mkdtemp(prefix='plane-validation-batch-'))
    try:
        with staged_folder(base, job.name) as stage:
            frames: list[dict] = []
            replayed = replay_offline(job.source, topic=job.topic, out=stage / job.output_bag, config=job.config,
                                      echo=None, progress=False, storage=job.storage,
                                      on_frame=lambda frame, result: frames.append(frame_record(frame, result)))
            summary = summary_document(job, replayed.topic, frames, time.perf_counter() - start,
                                       worker=f'{socket.gethostname()}:{os.getpid()}')
            (stage / SUMMARY).write_text(dumps(summary) + '\n', encoding='utf-8')
            plot_bag_report(summary, stage / REPORT)
            if shared:
                publish_folder(stage, job.folder)
                return Outcome(summary)
            files = {str(p.relative_to(stage)): p.read_bytes() for p in sorted(stage.rglob('*')) if p.is_file()}
            return Outcome(summary, files=files)
    except Exception as exc:  # the bag's row says why; the other bags go on
        text = ' '.join(str(exc).split())
        return Outcome(None, error=text if isinstance(exc, ValueError) and text else f'{type(exc).__name__}: {text}')
    finally:
        if not shared:
            shutil.rmtree(base, ignore_errors=True)


def _write_returned(job: BagJob, files: dict[str, bytes]) -> None:
    """Write the files a worker returned as ``job``'s folder, complete or absent."""
    with staged_folder(job.out, job.name) as stage:
        for name, data in files.items():
            path = stage / name
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
        publish_folder(stage, job.folder)


def _row(job: BagJob, outcome: Outcome | Lost) -> Row:
    if isinstance(outcome, Lost):
        return failed_row(job, outcome.why)
    if outcome.summary is None:
        return failed_row(job, outcome.error or 'no summary')
    if outcome.files is not None:
        try:
            _write_returned(job, outcome.files)
        except OSError as exc:
            return failed_row(job, f'cannot write its folder {job.folder}: {exc}')
    return row_of(outcome.summary)


@contextmanager
def _only_batch(out: Path) -> Iterator[None]:
    """Hold ``out``'s lock file: ValueError when another batch holds it."""
    import fcntl
    with open(out / LOCK, 'a') as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise ValueError(f'{out}: another batch is writing into it; wait for it or give another --out') from None
        yield


def default_workers() -> int:
    """One local worker per CPU core this process may use."""
    from joblib import cpu_count
    return max(1, cpu_count())


def _progress(total: int, enabled: bool | None):
    from tqdm import tqdm
    return tqdm(total=total, unit='bag', disable=None if enabled is None else not enabled, file=sys.stderr)


def run_batch(sources: Iterable[str | Path], out: str | Path, *, config: PipelineConfig | None = None,
              topic: str | None = None, storage: str | None = None, workers: int | None = None,
              ray: str | None = None, force: bool = False, progress: bool | None = None,
              echo: Callable[[str], None] | None = print) -> list[Row]:
    """Replay every bag ``sources`` name into ``out/<bag name>/`` and write the index; one Row per bag, in the
    index's order. workers: local processes (default :func:`default_workers`); ray: a Ray cluster's address
    instead. A bag whose folder is complete with the same settings is skipped unless ``force``.
    ValueError for bad sources or output folder."""
    out = Path(out)
    config = (config or PipelineConfig()).validate()
    bags = find_bags(sources, out)
    if out.exists() and not out.is_dir():
        raise ValueError(f'--out {out} is a file: give a folder')
    with ray_connection(ray):  # before the output folder: no cluster, no folder
        out.mkdir(parents=True, exist_ok=True)
        return _run(plan_jobs(bags, out, config, topic, storage), out, workers, ray, force, progress, echo)


def _run(jobs: list[BagJob], out: Path, workers: int | None, ray: str | None, force: bool, progress: bool | None,
         echo: Callable[[str], None] | None) -> list[Row]:
    """run_batch's work once the output folder exists (and Ray is connected when ``ray``)."""
    rows: dict[str, Row] = {}
    with _only_batch(out):
        remove_staging(out)  # what a killed batch left
        todo = []
        for job in jobs:
            done = None if force else done_summary(job)
            if done is not None:
                rows[job.name] = row_of(done, Status.SKIPPED)
            else:
                todo.append(job)
        marker = out / f'.batch-{uuid.uuid4().hex}'
        marker.touch()
        try:
            tasks = [(job, marker.name) for job in todo]
            run = run_ray(process_bag, tasks) if ray else \
                run_local(process_bag, tasks, min(workers or default_workers(), max(len(tasks), 1)))
            with closing(run), _progress(len(todo), progress) as bar:
                for i, outcome in run:
                    job = todo[i]
                    row = rows[job.name] = _row(job, outcome)
                    bar.update(1)
                    if echo is not None:
                        line = f'{job.name}: {row.status_text}' + (
                            f', {row.frames} frames, {row.reliable_share:.0%} reliable, {row.seconds:.1f} s'
                            if row.status is Status.OK else '')
                        bar.write(line, file=sys.stdout) if not bar.disable else echo(line)
        finally:
            marker.unlink(missing_ok=True)
            remove_staging(out)
        ordered = [rows[job.name] for job in jobs]
        write_index(out, ordered)
    return ordered
