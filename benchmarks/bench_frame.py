"""The steady-state frame on real 640x480 frames, side by side in one run with Open3D's 5 x segment_plane:

- organized: PointCloud2 in (an organized rclpy message), planes with regions, indices on the 2,000-point sample,
  verdict, and the five output messages built (what the node does per frame);
- plain: the same points as an N x 3 array through ``detect_planes`` with regions (what an Open3D user passes);
- infinite: the paper's infinite planes (``connectivity=False``) through the pipeline.

Prints medians (ms) and the ratios to Open3D with the targets of the real-time work (organized <= 25 ms and
<= 0.10 x Open3D, plain <= 0.25 x Open3D).

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_frame.py [PCD ...] [--repeat 9]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pvbench import open3d_ref  # noqa: E402
from pvbench.frame_calls import frame_calls  # noqa: E402
from pvbench.node_e2e import cloud_message  # noqa: E402

from plane_validation.core.allocator import reuse_freed_memory  # noqa: E402
from plane_validation.core.blas import limit_blas_threads  # noqa: E402
from plane_validation.core.kernels import warm  # noqa: E402
from plane_validation.formats.files import load_cloud  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / 'shared' / 'data'
ORGANIZED_MS, ORGANIZED_RATIO, PLAIN_RATIO = 25.0, 0.10, 0.25


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('clouds', nargs='*', default=[str(p) for p in sorted(DATA.glob('*.pcd'))])
    parser.add_argument('--repeat', type=int, default=9)
    args = parser.parse_args()
    limit_blas_threads()
    reuse_freed_memory()  # as the node: a frame's arrays from the heap (core/allocator.py)
    print(f'kernels: {warm()}; Open3D {open3d_ref.version()}', flush=True)
    print('| frame | organized, PointCloud2 to messages (ms) | plain N x 3, regions (ms) | infinite planes (ms) '
          '| Open3D 5 planes (ms) | organized / Open3D | plain / Open3D |')
    print('|---|--:|--:|--:|--:|--:|--:|')
    for path in args.clouds:
        points, shape = load_cloud(path)
        if shape == (480, 640):
            _frame(path, points, shape, args.repeat)
    print(f'targets: organized <= {ORGANIZED_MS:g} ms and <= {ORGANIZED_RATIO:.2f} x Open3D; '
          f'plain <= {PLAIN_RATIO:.2f} x Open3D')


def _frame(path: str, points: np.ndarray, shape: tuple[int, int], repeat: int) -> None:
    """One table row: the medians of ``repeat`` runs of each, one after another, after a warm-up run."""
    msg = cloud_message(points, *shape)
    valid = points[np.isfinite(points).all(axis=1)]
    calls = frame_calls('plane_validation', msg, points, shape)
    cloud = open3d_ref.to_cloud(valid) if open3d_ref.available() else None
    if cloud is not None:
        calls['open3d'] = lambda i: open3d_ref.sequential_planes(cloud, len(valid), 0.01, planes=5, seed=i)
    times: dict[str, list[float]] = {name: [] for name in calls}
    for i in range(repeat + 1):
        msg.header.stamp.sec = i + 1
        for name, call in calls.items():
            start = time.perf_counter()
            call(i)
            if i:  # the first run of each is a warm-up
                times[name].append(1000 * (time.perf_counter() - start))
    med = {k: statistics.median(v) for k, v in times.items()}
    o3d = med.get('open3d', float('nan'))
    print(f'| {Path(path).name} | {med["organized"]:.1f} | {med["plain"]:.1f} | {med["infinite"]:.1f} | '
          f'{o3d:.1f} | {med["organized"] / o3d:.2f} | {med["plain"] / o3d:.2f} |', flush=True)


if __name__ == '__main__':
    main()
