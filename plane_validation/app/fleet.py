"""Many bags in one run (``plane-validation batch``): which bags, what each one's folder holds, and the
index across them. No ROS import: the replay itself runs in :mod:`plane_validation.ros.batch`.

``OUT/<bag name>/`` holds the output bag, :data:`SUMMARY` and :data:`REPORT`; it appears in one rename once
all three are written, so a bag's folder is complete or absent. ``OUT/index.csv``, ``OUT/index.md`` and
``OUT/fleet.png`` have one row (bar) per bag.
"""
from __future__ import annotations

import csv
import dataclasses
import enum
import hashlib
import io
import json
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..formats.bags import BAG_SUFFIXES
from ..formats.outputs import atomic_output
from .config import PipelineConfig
from .diagnostics import Level
from .report import jsonable

__all__ = ['BagJob', 'Status', 'Row', 'SUMMARY', 'REPORT', 'INDEX_CSV', 'INDEX_MD', 'FLEET_PNG', 'STAGING',
           'find_bags', 'plan_jobs', 'frame_record', 'summary_document', 'comparable', 'settings_of',
           'done_summary', 'row_of', 'failed_row', 'write_index', 'format_table', 'staged_folder',
           'publish_folder', 'remove_staging']

SUMMARY = 'summary.json'
REPORT = 'report.png'
INDEX_CSV = 'index.csv'
INDEX_MD = 'index.md'
FLEET_PNG = 'fleet.png'
#: Suffix of a bag's folder while it is written (``OUT/.<name>.<random>.partial``).
STAGING = '.partial'
#: Folders a search of a source folder does not enter: replay's default outputs (``<bag>.planes``).
OUTPUT_SUFFIX = '.planes'
#: Keys of a summary that depend on the machine and the moment, not on the bag: :func:`comparable` drops them.
TIMING_KEYS = ('seconds', 'ms', 'median_frame_ms', 'worker')
#: The indices a summary keeps per frame (ValidityIndices fields).
FRAME_INDICES = ('plane_silhouette', 'gs_planes', 'gs', 'silhouette', 'dunn', 'davies_bouldin')


@dataclass(frozen=True)
class BagJob:
    """One bag of a batch: its path, its folder's name in the output folder (unique in the batch), and the
    replay's settings (topic None: the bag's only cloud topic; storage None: the input's)."""

    source: Path
    name: str
    out: Path
    config: PipelineConfig
    topic: str | None = None
    storage: str | None = None

    @property
    def folder(self) -> Path:
        return self.out / self.name

    @property
    def output_bag(self) -> str:
        """The output bag's folder name inside :attr:`folder`."""
        return f'{self.name}{OUTPUT_SUFFIX}'


class Status(enum.Enum):
    OK = 'ok'
    FAILED = 'failed'
    SKIPPED = 'skipped'


# -- which bags ------------------------------------------------------------------------------------


def _is_bag_file(path: Path) -> bool:
    return path.is_file() and path.suffix.lower() in BAG_SUFFIXES


def _search(folder: Path, skip: Path) -> Iterator[Path]:
    """The bags under ``folder``: rosbag2 directories (metadata.yaml; not entered) and bag files, in name
    order; hidden folders, ``*.planes`` outputs and ``skip`` (the batch's output folder) left out."""
    for entry in sorted(folder.iterdir()):
        if entry.name.startswith('.') or entry.resolve() == skip:
            continue
        if entry.is_dir():
            if (entry / 'metadata.yaml').is_file():
                if not entry.name.endswith(OUTPUT_SUFFIX):
                    yield entry
            else:
                yield from _search(entry, skip)
        elif _is_bag_file(entry):
            yield entry


def find_bags(sources: Iterable[str | Path], out: Path) -> list[Path]:
    """The bags ``sources`` name: bag directories and files as given, folders searched (see :func:`_search`);
    each once. ValueError for a source that does not exist, a file that is not a bag, or no bag at all."""
    found: dict[Path, Path] = {}
    skip = out.resolve()
    for source in map(Path, sources):
        if not source.exists():
            raise ValueError(f'source not found: {source}')
        if source.is_dir() and not (source / 'metadata.yaml').is_file():
            bags = list(_search(source, skip))
            if not bags:
                raise ValueError(f'{source}: no bags in it (rosbag2 folders with metadata.yaml, or '
                                 f'{", ".join(BAG_SUFFIXES)} files)')
        elif source.is_dir() or _is_bag_file(source):
            bags = [source]
        else:
            raise ValueError(f'{source}: not a bag (a rosbag2 folder, or a {", ".join(BAG_SUFFIXES)} file)')
        for bag in bags:
            found.setdefault(bag.resolve(), bag)
    return list(found.values())


def _name(bag: Path) -> str:
    return bag.name if bag.is_dir() else bag.stem


def plan_jobs(bags: list[Path], out: Path, config: PipelineConfig, topic: str | None = None,
              storage: str | None = None) -> list[BagJob]:
    """One job per bag, named after it; bags of the same name (``a/room``, ``b/room``) each get a suffix
    from their full path, the same in every run. Paths are made absolute."""
    names = [_name(bag) for bag in bags]
    jobs = []
    for bag, name in zip(bags, names):
        if names.count(name) > 1:
            name = f'{name}-{hashlib.sha1(str(bag.resolve()).encode()).hexdigest()[:6]}'
        # absolute: a worker (a Ray worker on another node) need not share this process's directory
        jobs.append(BagJob(bag.absolute(), name, out.absolute(), config, topic, storage))
    return jobs


# -- one bag's summary ------------------------------------------------------------------------------


def frame_record(frame, result) -> dict:
    """One frame of a summary from replay's FrameSummary and the pipeline's FrameResult."""
    indices = result.indices
    return {'index': frame.index, 'timestamp': frame.timestamp, 'planes': frame.n_planes,
            'tolerance': frame.tolerance, 'tolerance_source': result.tolerance_source,
            'level': Level(frame.level).name, 'message': frame.message, 'searched': frame.searched,
            **{name: None if indices is None else getattr(indices, name) for name in FRAME_INDICES},
            'ms': frame.ms}


def settings_of(job: BagJob) -> dict:
    """What a bag's folder was made from: a rerun with other settings does it again."""
    return jsonable({'source': job.source.resolve(), 'topic': job.topic, 'storage': job.storage,
                     'config': dataclasses.asdict(job.config)})


def summary_document(job: BagJob, topic: str, frames: list[dict], seconds: float, worker: str) -> dict:
    """summary.json: the frames and their figures. reliable_share: the share of frames whose status is OK
    (the verdict found the planes reliable and nothing went wrong); verdict_failures: the other frames."""
    levels = [f['level'] for f in frames]
    searched = [f for f in frames if f['searched']]
    ms = [f['ms'] for f in searched]
    return jsonable({
        'bag': job.name, 'source': job.source, 'topic': topic, 'output_bag': job.output_bag,
        'settings': settings_of(job), 'frame_count': len(frames),
        'reliable_share': levels.count('OK') / len(frames) if frames else 0.0,
        'planes_per_frame': [f['planes'] for f in frames],
        'tolerance_per_frame': [f['tolerance'] for f in frames],
        'verdict_failures': [{'index': f['index'], 'level': f['level'], 'message': f['message']}
                             for f in frames if f['level'] != 'OK'],
        'errors': [{'index': f['index'], 'message': f['message']} for f in frames if f['level'] == 'ERROR'],
        'frames': frames, 'seconds': seconds, 'median_frame_ms': float(np.median(ms)) if ms else None,
        'worker': worker,
    })


def comparable(document):
    """A summary without :data:`TIMING_KEYS` (at any depth): what must not depend on the executor."""
    if isinstance(document, dict):
        return {k: comparable(v) for k, v in document.items() if k not in TIMING_KEYS}
    if isinstance(document, list):
        return [comparable(v) for v in document]
    return document


def done_summary(job: BagJob) -> dict | None:
    """The summary of ``job``'s folder when it is complete and was made with ``job``'s settings, else None."""
    try:
        summary = json.loads((job.folder / SUMMARY).read_text(encoding='utf-8'))
    except (OSError, ValueError):
        return None
    complete = (job.folder / REPORT).is_file() and (job.folder / job.output_bag / 'metadata.yaml').is_file()
    return summary if complete and summary.get('settings') == settings_of(job) else None


# -- the index --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Row:
    """One bag in the index: status, why it failed, and its figures (NaN: no frames)."""

    name: str
    source: str
    status: Status
    reason: str = ''
    frames: int = 0
    reliable_share: float = float('nan')
    planes_median: float = float('nan')
    tolerance_median: float = float('nan')  # m
    tolerance_min: float = float('nan')
    tolerance_max: float = float('nan')
    not_ok: int = 0  # frames whose status is WARN or ERROR
    errors: int = 0
    seconds: float = float('nan')

    @property
    def status_text(self) -> str:
        return f'{self.status.value}: {self.reason}' if self.reason else self.status.value


def row_of(summary: dict, status: Status = Status.OK) -> Row:
    t = np.array([np.nan if v is None else v for v in summary['tolerance_per_frame']], dtype=float)
    finite = t[np.isfinite(t)]
    return Row(name=summary['bag'], source=str(summary['source']), status=status,
               reason='done' if status is Status.SKIPPED else '', frames=summary['frame_count'],
               reliable_share=summary['reliable_share'],
               planes_median=float(np.median(summary['planes_per_frame'])) if summary['frame_count'] else np.nan,
               tolerance_median=float(np.median(finite)) if finite.size else np.nan,
               tolerance_min=float(finite.min()) if finite.size else np.nan,
               tolerance_max=float(finite.max()) if finite.size else np.nan,
               not_ok=len(summary['verdict_failures']), errors=len(summary['errors']), seconds=summary['seconds'])


def failed_row(job: BagJob, reason: str) -> Row:
    return Row(name=job.name, source=str(job.source), status=Status.FAILED, reason=' '.join(reason.split()))


#: Index columns: header -> how a Row gives it.
COLUMNS = {'bag': lambda r: r.name, 'status': lambda r: r.status_text, 'frames': lambda r: r.frames,
           'reliable_share': lambda r: r.reliable_share, 'planes_median': lambda r: r.planes_median,
           't_median_m': lambda r: r.tolerance_median, 't_min_m': lambda r: r.tolerance_min,
           't_max_m': lambda r: r.tolerance_max, 'frames_not_ok': lambda r: r.not_ok,
           'frames_error': lambda r: r.errors, 'seconds': lambda r: r.seconds, 'source': lambda r: r.source}


def _cell(value) -> str:
    if isinstance(value, float):
        return '' if not np.isfinite(value) else f'{value:.4g}'
    return str(value)


def write_index(out: Path, rows: list[Row]) -> list[Path]:
    """index.csv, index.md and fleet.png in ``out``, each complete or absent; returns their paths."""
    from .plot import plot_fleet
    rows = sorted(rows, key=lambda r: r.name)
    csv_text = io.StringIO()
    writer = csv.writer(csv_text, lineterminator='\n')
    writer.writerow(COLUMNS)
    writer.writerows([[_cell(get(r)) for get in COLUMNS.values()] for r in rows])
    md = ['| ' + ' | '.join(COLUMNS) + ' |', '|' + '---|' * len(COLUMNS)]
    md += ['| ' + ' | '.join(_cell(get(r)).replace('|', '\\|') for get in COLUMNS.values()) + ' |' for r in rows]
    paths = [out / INDEX_CSV, out / INDEX_MD, out / FLEET_PNG]
    for path, text in zip(paths, (csv_text.getvalue(), '\n'.join(md) + f'\n\n![fleet]({FLEET_PNG})\n')):
        with atomic_output(path) as tmp:
            tmp.write_text(text, encoding='utf-8')
    plot_fleet(rows, paths[2])
    return paths


def format_table(rows: list[Row]) -> str:
    """The final table on the terminal: one line per bag."""
    lines = [f'{"bag":24s} {"frames":>6s} {"reliable":>8s} {"planes":>6s} {"t median":>9s} {"s":>6s}  status']
    for r in sorted(rows, key=lambda r: r.name):
        lines.append(f'{r.name[:24]:24s} {r.frames:6d} {_cell(r.reliable_share):>8s} {_cell(r.planes_median):>6s} '
                     f'{_cell(r.tolerance_median):>9s} {_cell(r.seconds):>6s}  {r.status_text}')
    return '\n'.join(lines)


# -- a bag's folder, complete or absent ----------------------------------------------------------------


@contextmanager
def staged_folder(out: Path, name: str) -> Iterator[Path]:
    """A hidden folder in ``out`` to write a bag's outputs into; deleted when the block raises."""
    stage = Path(tempfile.mkdtemp(dir=out, prefix=f'.{name}.', suffix=STAGING))
    try:
        yield stage
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise


def publish_folder(stage: Path, folder: Path) -> None:
    """Rename the complete ``stage`` to ``folder``; a folder already there (--force, other settings) is moved
    aside first and deleted after: one rename makes the new one appear."""
    umask = os.umask(0)
    os.umask(umask)
    stage.chmod(0o777 & ~umask)  # as a plain mkdir would have made it (mkdtemp makes 0700)
    old = None
    if folder.exists():
        old = Path(tempfile.mkdtemp(dir=folder.parent, prefix=f'.{folder.name}.', suffix=STAGING))
        os.replace(folder, old / folder.name)
    try:
        os.replace(stage, folder)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    finally:
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


def remove_staging(out: Path) -> None:
    """Delete what bags whose process was killed left in ``out`` (their hidden ``*.partial`` folders)."""
    for path in out.glob(f'.*{STAGING}'):
        with suppress(OSError):
            shutil.rmtree(path) if path.is_dir() else path.unlink()
