"""Median time of detect_planes on a 307,200-point synthetic scene with 5 planes.

Run: .venv/bin/python benchmarks/bench_detect.py [--repeat 7] [--points 307200]
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import plane_validation as pv
from plane_validation import scenes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeat', type=int, default=7)
    parser.add_argument('--points', type=int, default=307_200)
    parser.add_argument('--tolerance', type=float, default=0.02, help='meters')
    args = parser.parse_args()
    scene = scenes.boxes(args.points, noise=0.005, outlier_fraction=0.05, seed=0)
    pts32 = scene.points.astype(np.float32)
    pv.detect_planes(pts32, args.tolerance, seed=0)  # warm-up
    times, found = [], []
    for i in range(args.repeat):
        start = time.perf_counter()
        seg = pv.detect_planes(pts32, args.tolerance, seed=i)
        times.append(time.perf_counter() - start)
        found.append(seg.n_planes)
    print(f'scene: boxes, {len(pts32)} points (float32), 5 true planes, noise 5 mm, 5 % outliers, '
          f't = {args.tolerance} m')
    print(f'detect_planes: median {1000 * statistics.median(times):.1f} ms, '
          f'min {1000 * min(times):.1f} ms, max {1000 * max(times):.1f} ms over {args.repeat} seeds; '
          f'planes found per run: {found}')


if __name__ == '__main__':
    main()
