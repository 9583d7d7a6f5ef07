"""CPU time of detect_planes alone on real 640x480 frames, at the steady-state settings of bench_frame.py (t = 1 cm,
up to 5 planes, min_inliers 1 %): organized (``shape=(480, 640)``, the sub-grid search) and the same points as a
plain N x 3 array. Prints the median and the fastest of ``--repeat`` runs (process CPU time, ms) and the planes
found with their inlier counts (seed 0), to compare checkouts side by side (PYTHONPATH=<checkout>).

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_search.py [PCD ...] [--repeat 15] [--plain]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from plane_validation import detect_planes
from plane_validation.core.blas import limit_blas_threads
from plane_validation.core.kernels import warm
from plane_validation.formats.files import load_cloud

DATA = Path(__file__).resolve().parents[2] / 'shared' / 'data'
SETTINGS = dict(max_planes=5, min_inliers=0.01)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('clouds', nargs='*', default=[str(p) for p in sorted(DATA.glob('*.pcd'))])
    parser.add_argument('--repeat', type=int, default=15)
    parser.add_argument('--plain', action='store_true', help='also the plain N x 3 array')
    args = parser.parse_args()
    limit_blas_threads()
    print(f'kernels: {warm()}; {sys.modules["plane_validation"].__file__}', flush=True)
    print('| frame | form | median CPU (ms) | fastest (ms) | planes (inliers), seed 0 |')
    print('|---|---|--:|--:|---|')
    for path in args.clouds:
        points, shape = load_cloud(path)
        if shape != (480, 640):
            continue
        forms = [('organized', points, shape)]
        if args.plain:
            forms.append(('plain', points[np.isfinite(points).all(axis=1)], None))
        for form, pts, grid in forms:
            seg = detect_planes(pts, 0.01, shape=grid, seed=0, **SETTINGS)  # also the warm-up
            times = []
            for i in range(args.repeat):
                start = time.process_time()
                detect_planes(pts, 0.01, shape=grid, seed=i, **SETTINGS)
                times.append(1000 * (time.process_time() - start))
            counts = ', '.join(str(len(p.inliers)) for p in seg.planes)
            print(f'| {Path(path).name} | {form} | {statistics.median(times):.1f} | {min(times):.1f} | '
                  f'{seg.n_planes} ({counts}) |', flush=True)


if __name__ == '__main__':
    main()
