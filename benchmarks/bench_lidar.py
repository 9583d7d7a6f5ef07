"""The steady-state frame on unorganized spinning-lidar scans (a height-1 PointCloud2, as
velodyne_pointcloud publishes without organize_cloud, with its ring field): the pipeline with connected
regions on the scan laid out as its ring image (organize_rings, the default), on the neighbourhood graph,
on a smaller search sample of the graph (ransac_points), with the paper's
infinite planes, and Open3D's sequential segment_plane, side by side in one run, each with its point F1
against the scene's labels.

Run: .venv/bin/python benchmarks/bench_lidar.py [--repeat 5]
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
from plane_validation.core import scenes  # noqa: E402
from plane_validation.core.blas import limit_blas_threads  # noqa: E402
from plane_validation.core.scoring import segmentation_quality  # noqa: E402

TOLERANCE = 0.05
PLANES = 10
SCANS = {
    '32-beam street': lambda: scenes.lidar(seed=1),
    '16-beam street': lambda: scenes.lidar(rings=16, seed=1),
    '16-beam room, 2 cm noise': lambda: scenes.lidar(**scenes.VLP16_ROOM, seed=1),
    '16-beam corridor, 2 cm noise': lambda: scenes.lidar(**scenes.VLP16_CORRIDOR, seed=1),
}
METHODS = {
    'regions, ring image': dict(),
    'regions, graph': dict(organize_rings=False),
    'regions, graph, ransac_points 8192': dict(organize_rings=False, ransac_points=8192),
    'infinite planes': dict(connectivity=False),
}


def settings(method: str) -> dict:
    """The PipelineConfig arguments of one of METHODS: a fixed t of TOLERANCE, up to PLANES planes."""
    return dict(auto_tune=False, tolerance=TOLERANCE, max_planes=PLANES, **METHODS[method])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeat', type=int, default=5)
    args = parser.parse_args()
    limit_blas_threads()
    table(args.repeat)


def table(repeat: int) -> None:
    """Print one row per scan: median ms over ``repeat`` frames (after a warm-up) and point F1 per method."""
    names = list(METHODS) + (['Open3D'] if open3d_ref.available() else [])
    print('| scan | points | ' + ' | '.join(f'{m}: ms, F1' for m in names) + ' |')
    print('|---|--:|' + '---|' * len(names))
    for scan, make in SCANS.items():
        scene = make()
        pipes = {m: FramePipeline(PipelineConfig(**settings(m))) for m in METHODS}
        times: dict[str, list[float]] = {m: [] for m in names}
        f1: dict[str, float] = {}
        cloud = open3d_ref.to_cloud(scene.points) if 'Open3D' in names else None
        for i in range(repeat + 1):  # the first run of each is a warm-up
            for m, pipe in pipes.items():
                start = time.perf_counter()
                result = pipe.process(scene.points, 10**9 * (i + 1), tune_inline=False, ring=scene.rings)
                if i:
                    times[m].append(1000 * (time.perf_counter() - start))
                f1[m] = segmentation_quality(result.labels, scene.labels).f1
            if cloud is not None:
                start = time.perf_counter()
                _, labels = open3d_ref.sequential_planes(cloud, len(scene.points), TOLERANCE, planes=PLANES, seed=i)
                if i:
                    times['Open3D'].append(1000 * (time.perf_counter() - start))
                f1['Open3D'] = segmentation_quality(np.asarray(labels), scene.labels).f1
        cells = [f'{statistics.median(times[m]):.0f}, {f1[m]:.3f}' for m in names]
        print(f'| {scan} | {len(scene.points)} | ' + ' | '.join(cells) + ' |', flush=True)


if __name__ == '__main__':
    main()
