"""The steady-state frame on real 640x480 frames: the pipeline with connected regions (organized),
with the paper's infinite planes, and Open3D's 5 x segment_plane, side by side in one run.

Run: .venv/bin/python benchmarks/bench_frame.py [PCD ...] [--repeat 9]
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

from plane_validation.app.pipeline import FramePipeline, PipelineConfig  # noqa: E402
from plane_validation.core.blas import limit_blas_threads  # noqa: E402
from plane_validation.formats.files import load_cloud  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / 'shared' / 'data'


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('clouds', nargs='*', default=[str(p) for p in sorted(DATA.glob('*.pcd'))])
    parser.add_argument('--repeat', type=int, default=9)
    args = parser.parse_args()
    limit_blas_threads()
    print('| frame | regions (ms) | infinite planes (ms) | Open3D 5 planes (ms) | regions / Open3D |')
    print('|---|--:|--:|--:|--:|')
    for path in args.clouds:
        points, shape = load_cloud(path)
        if shape != (480, 640):
            continue
        times: dict[str, list[float]] = {'regions': [], 'infinite': [], 'open3d': []}
        pipes = {name: FramePipeline(PipelineConfig(auto_tune=False, tolerance=0.01, max_planes=5,
                                                    connectivity=name == 'regions'))
                 for name in ('regions', 'infinite')}
        valid = points[np.isfinite(points).all(axis=1)]
        cloud = open3d_ref.to_cloud(valid) if open3d_ref.available() else None
        for i in range(args.repeat + 1):  # the first run of each is a warm-up
            for name, pipe in pipes.items():
                start = time.perf_counter()
                pipe.process(points, 10**9 * (i + 1), shape=shape, tune_inline=False)
                if i:
                    times[name].append(1000 * (time.perf_counter() - start))
            if cloud is not None:
                start = time.perf_counter()
                open3d_ref.sequential_planes(cloud, len(valid), 0.01, planes=5, seed=i)
                if i:
                    times['open3d'].append(1000 * (time.perf_counter() - start))
        med = {k: statistics.median(v) if v else float('nan') for k, v in times.items()}
        print(f'| {Path(path).name} | {med["regions"]:.1f} | {med["infinite"]:.1f} | {med["open3d"]:.1f} | '
              f'{med["regions"] / med["open3d"]:.2f} |', flush=True)


if __name__ == '__main__':
    main()
