"""Auto-tuning a large many-plane scan: 250,000 unorganized points on 38 planes (issue 13's speed
figure for a SynPEB-sized scan, which we do not ship), tune_tolerance with library defaults but
max_planes=60 and min_inliers=0.002, against the best fixed t over a grid.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_many_planes.py [--repeat 3] [--jobs 0]

Prints the tune's times in one process (workers already started) and, in new processes, of a first call.
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

import numpy as np

import plane_validation as pv
from plane_validation.core import scenes
from plane_validation.core.scoring import segmentation_quality

#: tune_tolerance's arguments beside the library defaults (issue 13's call).
PARAMS = dict(max_planes=60, min_inliers=0.002)


def warehouse(n_points: int = 250_000, noise: float = 0.003, seed: int = 0) -> scenes.Scene:
    """A 12 x 8 x 4 m hall (6 faces), six crates (5 faces each) and two hanging panels: 38 planes."""
    rects = scenes._box_faces((0, 0, 0), (12.0, 8.0, 4.0))
    for k in range(6):
        x0, y0 = 1.0 + 1.8 * k, 1.0 + (k % 3) * 2.0
        rects += scenes._box_faces((x0, y0, 0.0), (x0 + 1.2, y0 + 0.9 + 0.1 * k, 0.6 + 0.2 * k), bottom=False)
    rects += [scenes._Rect((2.0, 7.0, 2.5), scenes.X, scenes.Y, 3.0, 0.6),
              scenes._Rect((7.0, 7.0, 3.0), scenes.X, scenes.Y, 3.0, 0.6)]
    return scenes._compose('warehouse', rects, n_points, noise, 0.02, 1.0, seed)


def measure(repeat: int, jobs: int = 0) -> list[str]:
    """Time tune_tolerance on the warehouse ``repeat`` times in this process (the default) and with
    ``jobs`` worker processes (0: one per core; same result), interleaved, and compare with the best
    fixed t; the lines printed. The workers are started before the timing (a first parallel call
    also pays their start-up, reported on its own)."""
    scene = warehouse()
    lines = [f'{scene.name}: {len(scene.points)} points, {len(scene.planes)} planes, '
             f'noise ±{1000 * scene.noise:.0f} mm']
    start = time.perf_counter()
    pv.tune_tolerance(scenes.corner(2000, 1.0, seed=0).points, seed=0, jobs=jobs)
    lines.append(f'worker start-up and a 2,000-point tune (jobs={jobs}): {time.perf_counter() - start:.2f} s')
    times: dict[int, list[float]] = {1: [], jobs: []}
    result = None
    for i in range(repeat):
        for j in times:
            start = time.perf_counter()
            result = pv.tune_tolerance(scene.points, seed=i, jobs=j, **PARAMS)
            times[j].append(time.perf_counter() - start)
    q = segmentation_quality(result.segmentation.labels, scene.labels)
    for j, runs in times.items():
        lines.append(f'tune_tolerance, jobs={j}: median {statistics.median(runs):.2f} s (min {min(runs):.2f}, '
                     f'max {max(runs):.2f}) over {repeat} runs')
    lines.append(f'jobs={jobs} / jobs=1: {statistics.median(times[jobs]) / statistics.median(times[1]):.2f}; '
                 f'last run: t = {1000 * result.tolerance:.3g} mm, {q.correct}/{q.true_planes} correct, '
                 f'F1 {q.f1:.3f}, {"reliable" if result.reliable else "not reliable"} '
                 f'(PS {result.indices.plane_silhouette:.2f})')
    best = None
    for t in np.geomspace(0.001, 0.05, 10):
        seg = pv.detect_planes(scene.points, t, seed=0, **PARAMS)
        qt = segmentation_quality(seg.labels, scene.labels)
        if best is None or (qt.correct, qt.f1) > (best[1].correct, best[1].f1):
            best = (t, qt)
    lines.append(f'best fixed t over 10 from 1 to 50 mm: {1000 * best[0]:.3g} mm, {best[1].correct}/'
                 f'{best[1].true_planes} correct, F1 {best[1].f1:.3f}; auto / best F1 = {q.f1 / best[1].f1:.3f}')
    print(*lines, sep='\n', flush=True)
    return lines


def first_call(jobs: int) -> float:
    """Seconds of one tune_tolerance in a new process (what a script sees: worker start-up included)."""
    scene = warehouse()
    start = time.perf_counter()
    pv.tune_tolerance(scene.points, seed=0, jobs=jobs, **PARAMS)
    return time.perf_counter() - start


def measure_first_calls(repeat: int, jobs: int) -> list[str]:
    """first_call with ``jobs`` and with 1, each ``repeat`` times in new processes, alternating."""
    times: dict[int, list[float]] = {1: [], jobs: []}
    for _ in range(repeat):
        for j in times:
            out = subprocess.run([sys.executable, __file__, '--first-call', str(j)], check=True, capture_output=True,
                                 text=True).stdout
            times[j].append(float(out))
    lines = [f'first call in a new process, jobs={j}: median {statistics.median(runs):.2f} s (min {min(runs):.2f}, '
             f'max {max(runs):.2f}) over {repeat}' for j, runs in times.items()]
    print(*lines, sep='\n', flush=True)
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeat', type=int, default=3)
    parser.add_argument('--jobs', type=int, default=0, help='processes of the parallel runs (0: one per core)')
    parser.add_argument('--first-call', type=int, metavar='JOBS', help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.first_call is not None:
        print(first_call(args.first_call))
        return
    measure(args.repeat, args.jobs)
    measure_first_calls(args.repeat, args.jobs)


if __name__ == '__main__':
    main()
