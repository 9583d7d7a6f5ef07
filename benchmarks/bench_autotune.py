"""Full auto-tuning against Open3D's 5-plane time on the same 640x480 frames, side by side in one run.

For each Kinect frame of ../shared/data: tune_tolerance with the library defaults as a user's script
calls it on a loaded file (organized: the shape load_cloud gives; and as an unorganized array),
the organized one again with tune_jobs 0 (one process per core: this one and workers started before the timing),
then Open3D's 5 x segment_plane at t = 1 cm. Medians over --repeat runs, interleaved.

Run: .venv/bin/python benchmarks/bench_autotune.py [PCD ...] [--repeat 5]
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

import plane_validation as pv  # noqa: E402
from plane_validation.formats.files import load_cloud  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / 'shared' / 'data'


def table(paths: list[str], repeat: int) -> list[str]:
    """The Markdown rows (header first) for the 640x480 frames among ``paths``."""
    rows = ['| frame | auto-tune, organized (s) | auto-tune, unorganized (s) | Open3D 5 planes (s) | '
            'organized / Open3D | unorganized / Open3D | tuned t (mm), planes | organized, tune_jobs 0 (s) | '
            'that / Open3D |', '|---|--:|--:|--:|--:|--:|---|--:|--:|']
    pv.tune_tolerance(np.random.default_rng(0).random((500, 3)), seed=0, jobs=0)  # start the workers untimed
    print(*rows, sep='\n', flush=True)
    for path in paths:
        points, shape = load_cloud(path)
        if shape != (480, 640):
            continue
        valid = points[np.isfinite(points).all(axis=1)]
        cloud = open3d_ref.to_cloud(valid) if open3d_ref.available() else None
        times: dict[str, list[float]] = {'organized': [], 'unorganized': [], 'open3d': [], 'parallel': []}
        result = None
        for i in range(repeat):
            start = time.perf_counter()
            result = pv.tune_tolerance(points, seed=i, shape=shape)
            times['organized'].append(time.perf_counter() - start)
            start = time.perf_counter()
            pv.tune_tolerance(valid, seed=i)
            times['unorganized'].append(time.perf_counter() - start)
            start = time.perf_counter()
            pv.tune_tolerance(points, seed=i, shape=shape, jobs=0)
            times['parallel'].append(time.perf_counter() - start)
            if cloud is not None:
                start = time.perf_counter()
                open3d_ref.sequential_planes(cloud, len(valid), 0.01, planes=5, seed=i)
                times['open3d'].append(time.perf_counter() - start)
        med = {k: statistics.median(v) if v else float('nan') for k, v in times.items()}
        rows.append(f'| {Path(path).name} | {med["organized"]:.2f} | {med["unorganized"]:.2f} | '
                    f'{med["open3d"]:.3f} | {med["organized"] / med["open3d"]:.1f} | '
                    f'{med["unorganized"] / med["open3d"]:.1f} | {1000 * result.tolerance:.3g}, '
                    f'{result.segmentation.n_planes} | {med["parallel"]:.2f} | {med["parallel"] / med["open3d"]:.1f} |')
        print(rows[-1], flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('clouds', nargs='*', default=[str(p) for p in sorted(DATA.glob('*.pcd'))])
    parser.add_argument('--repeat', type=int, default=5)
    args = parser.parse_args()
    table(args.clouds, args.repeat)


if __name__ == '__main__':
    main()
