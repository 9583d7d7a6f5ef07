"""Where the steady-state organized frame's CPU time goes, stage by stage and kernel by kernel, on real frames.

Per frame (PointCloud2 in -> the five output messages built, t = 1 cm, up to 5 planes, indices on the 2,000-point
sample), the CPU medians (process_time, ms) of the whole frame, of the pipeline's stages (``process_cloud`` and
``frame_messages``, the search, indices, verdict, tracker, outlines, markers, the Qhull calls, the zeroed message
buffers) and of every compiled kernel the frame calls, with its calls per frame; what the kernels leave is Python,
numpy and the message classes. Nested stages overlap (the search holds its kernels): the rows are not a sum. Unlike
``profile_frame.py`` (pyinstrument, sampling) it wraps only these functions, so the frame runs at its usual speed.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/frame_stages.py [PCD ...] [--repeat 21] [--top 30]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections import defaultdict
from pathlib import Path

import numba

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_frame import DATA  # noqa: E402
from bench_frame_io import _timed, organized_frames  # noqa: E402

from plane_validation.app import pipeline, tracking  # noqa: E402
from plane_validation.core import geometry, kernels  # noqa: E402
from plane_validation.core.allocator import reuse_freed_memory  # noqa: E402
from plane_validation.core.blas import limit_blas_threads  # noqa: E402
from plane_validation.ros import messages  # noqa: E402

#: Stages by the module whose name for them is patched (the caller's own import of the function).
STAGES = {pipeline: ('frame_rows', 'detect_planes', 'validity_indices', 'judge', 'obstacle_mask', 'by_track_id'),
          pipeline.PlaneTracker: ('update',),
          messages: ('_frame_pass', 'outlines_from', 'plane_markers', 'plane_poses', 'diagnostics', 'cloud_buffer'),
          geometry: ('hull_vertices',)}
#: Kernels that modules import by name (not called as ``kernels.<name>``): timed under that module's name.
IMPORTED = {messages: ('frame_pass',), tracking: ('group_by_label', 'near_count')}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('clouds', nargs='*', default=[str(p) for p in sorted(DATA.glob('*.pcd'))])
    parser.add_argument('--repeat', type=int, default=21)
    parser.add_argument('--top', type=int, default=30, help='rows printed per frame')
    args = parser.parse_args()
    limit_blas_threads()
    reuse_freed_memory()  # as the node: a frame's arrays from the heap (core/allocator.py)
    kernels.warm()
    spent: dict[str, list[float]] = defaultdict(lambda: [0.0])
    calls: dict[str, int] = defaultdict(int)
    _install(spent, calls)
    for path, msg, frames in organized_frames(args.clouds):
        rows: dict[str, list[float]] = defaultdict(list)
        per_frame: dict[str, int] = {}
        for i in range(args.repeat + 1):
            msg.header.stamp.sec = i + 1
            for cell in spent.values():  # the wrappers hold these cells: zeroed, not replaced
                cell[0] = 0.0
            calls.clear()
            start = time.process_time()
            result = frames.process_cloud(msg)
            built = time.process_time()
            messages.frame_messages(msg.header, result, 'pv')
            end = time.process_time()
            if i:  # the first is a warm-up
                rows['whole frame'].append(end - start)
                rows['process_cloud'].append(built - start)
                rows['frame_messages'].append(end - built)
                rows['all kernels'].append(sum(cell[0] for name, cell in spent.items() if name.startswith('kernel ')))
                for name, cell in spent.items():
                    rows[name].append(cell[0])
                per_frame = dict(calls)
        print(f'\n## {Path(path).name} (CPU medians of {args.repeat} frames)\n\n| stage | ms | calls |\n|---|--:|--:|')
        ranked = sorted(rows.items(), key=lambda item: -statistics.median(item[1]))
        for name, values in ranked[:args.top]:
            print(f'| {name} | {1000 * statistics.median(values):.2f} | {per_frame.get(name, "")} |', flush=True)


def _install(spent: dict[str, list[float]], calls: dict[str, int]) -> None:
    """Time the stages and every compiled kernel called through ``kernels.<name>`` (counted per call)."""
    def wrap(owner, attr: str, name: str) -> None:
        timed = _timed(getattr(owner, attr), spent[name])

        def counted(*args, **kwargs):
            calls[name] += 1
            return timed(*args, **kwargs)
        setattr(owner, attr, counted)
    for owner, names in STAGES.items():
        for attr in names:
            wrap(owner, attr, f'{getattr(owner, "__name__", "").split(".")[-1]}.{attr}')
    for owner, names in IMPORTED.items():
        for attr in names:
            wrap(owner, attr, f'kernel {attr}')
    for attr in dir(kernels):
        if isinstance(getattr(kernels, attr), numba.core.registry.CPUDispatcher):
            wrap(kernels, attr, f'kernel {attr}')


if __name__ == '__main__':
    main()
