"""The steady-state frame of another revision beside the working tree's, call by call in one process.

Whole-process timings on this VM spread by up to 1.5 x from run to run (the same code, minutes apart), more
than most changes; two versions interleaved call by call in one process see the same machine. The revision's
``plane_validation`` is extracted from git as a renamed package (its imports are relative) under
``--keep`` and imported beside the working tree's; its kernels compile there the first time (about 2.5 min)
and load from its ``__pycache__`` after. Per frame and call (benchmarks/pvbench/frame_calls.py), the CPU
medians (``process_time``, ms) of both and the median of the paired ratios new / old; the order alternates
from run to run. Process-wide settings (one BLAS thread, glibc's thresholds of core/allocator.py, as the node sets
them) hold for both: a change to them is measured in alternating processes instead.

With ``--lidar``, bench_lidar.py's four scans instead, through the pipeline on their ring image and on the graph
(``--calls ring,graph``).

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/ab_frame.py REV [PCD ...] [--repeat 15]
         [--calls organized,plain,infinite,tune,organized_tune]
     OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/ab_frame.py REV --lidar [--calls ring,graph]
"""
from __future__ import annotations

import argparse
import io
import statistics
import subprocess
import sys
import tarfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pvbench.frame_calls import frame_calls, scan_calls  # noqa: E402
from pvbench.node_e2e import cloud_message  # noqa: E402

from plane_validation.core.allocator import reuse_freed_memory  # noqa: E402
from plane_validation.core.blas import limit_blas_threads  # noqa: E402
from plane_validation.formats.files import load_cloud  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / 'shared' / 'data'
NEW = 'plane_validation'


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('rev', help='the git revision to compare the working tree with')
    parser.add_argument('clouds', nargs='*', default=[str(p) for p in sorted(DATA.glob('*.pcd'))])
    parser.add_argument('--repeat', type=int, default=15)
    parser.add_argument('--calls', default=None, help='default organized,plain,infinite (--lidar: ring,graph)')
    parser.add_argument('--lidar', action='store_true', help="bench_lidar.py's scans instead of the frames")
    parser.add_argument('--keep', type=Path, default=Path.home() / '.cache' / 'plane_validation_ab',
                        help='where the revision is extracted (kept, so its compiled kernels are too)')
    args = parser.parse_args()
    old = _extract(args.rev, args.keep)
    limit_blas_threads()
    reuse_freed_memory()  # as the node: a frame's arrays from the heap (core/allocator.py)
    for name in (old, NEW):
        start = time.perf_counter()
        try:
            warm = __import__(f'{name}.core.kernels', fromlist=['warm']).warm
        except ModuleNotFoundError as err:
            if err.name != f'{name}.core.kernels':
                raise
            continue  # a revision before the compiled kernels
        warm()
        print(f'{name}: kernels ready in {time.perf_counter() - start:.1f} s', flush=True)
    names = (args.calls or ('ring,graph' if args.lidar else 'organized,plain,infinite')).split(',')
    print(f'\nCPU medians (ms), {args.rev} -> working tree, and the median of the paired ratios\n')
    print('| frame | ' + ' | '.join(f'{n} old | {n} new | {n} new / old' for n in names) + ' |')
    print('|---|' + '--:|--:|--:|' * len(names))
    if args.lidar:
        from bench_lidar import SCANS, settings
        configs = {'ring': settings('regions, ring image'), 'graph': settings('regions, graph')}
        for label, make in SCANS.items():
            scene = make()
            _interleaved(label, {pkg: scan_calls(pkg, scene.points, scene.rings, configs) for pkg in (old, NEW)}, old,
                         names, args.repeat)
        return
    for path in args.clouds:
        points, shape = load_cloud(path)
        if shape == (480, 640):
            msg = cloud_message(points, *shape)
            _interleaved(Path(path).name, {pkg: frame_calls(pkg, msg, points, shape) for pkg in (old, NEW)}, old,
                         names, args.repeat, msg)


def _extract(rev: str, keep: Path) -> str:
    """The revision's package under ``keep``, importable as ``pv_ab_<sha>``; its name."""
    sha = subprocess.run(['git', '-C', str(ROOT), 'rev-parse', '--short=10', rev], check=True,
                         capture_output=True, text=True).stdout.strip()
    name = f'pv_ab_{sha}'
    target = keep / sha
    if not (target / name / '__init__.py').exists():
        partial = keep / f'{sha}.partial'
        partial.mkdir(parents=True, exist_ok=True)
        archive = subprocess.run(['git', '-C', str(ROOT), 'archive', sha, 'plane_validation'], check=True,
                                 capture_output=True).stdout
        with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
            tar.extractall(partial, filter='data')
        (partial / 'plane_validation').rename(partial / name)
        partial.rename(target)
    sys.path.insert(0, str(target))
    return name


def _interleaved(label: str, calls: dict, old: str, names: list[str], repeat: int, msg=None) -> None:
    """Print one row: ``calls`` per package (old and new) per name, run ``repeat`` + 1 times alternating (the first a
    warm-up); ``msg``: the frame's message, whose stamp advances from run to run."""
    times: dict[tuple[str, str], list[float]] = {(pkg, n): [] for pkg in calls for n in names}
    for i in range(repeat + 1):
        if msg is not None:
            msg.header.stamp.sec = i + 1
        for n in names:
            for pkg in ((old, NEW) if i % 2 else (NEW, old)):
                start = time.process_time()
                calls[pkg][n](i)
                if i:  # the first run of each is a warm-up
                    times[(pkg, n)].append(1000 * (time.process_time() - start))
    cells = []
    for n in names:
        a, b = times[(old, n)], times[(NEW, n)]
        ratio = statistics.median(y / x for x, y in zip(a, b))
        cells.append(f'{statistics.median(a):.1f} | {statistics.median(b):.1f} | {ratio:.3f}')
    print(f'| {label} | ' + ' | '.join(cells) + ' |', flush=True)


if __name__ == '__main__':
    main()
