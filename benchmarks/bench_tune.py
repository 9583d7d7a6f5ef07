"""The paper's experiments as a table, and the time of a full tolerance sweep on a 50k-point scene.

Run: .venv/bin/python benchmarks/bench_tune.py [--points 50000] [--repeat 3]
"""
from __future__ import annotations

import argparse
import statistics
import time

import plane_validation as pv
from plane_validation import scenes


def paper_table() -> None:
    print('scene        e     chosen t  planes  noise est.  k by GSplanes  argmax k by GS / DB / Dunn / GSplanes')
    cases = [('corner', 0.0), ('corner', 2.5), ('corner', 7.5), ('cube', 0.0), ('cube', 2.5), ('cube', 7.5)]
    for name, e in cases:
        scene = scenes.SCENES[name](3000 if name == 'corner' else 6000, e, seed=1)
        result = pv.tune_tolerance(scene.points, seed=0)
        counts = pv.select_plane_count(scene.points, result.tolerance, max_planes=8, seed=0)
        others = ' / '.join(str(counts.best_by(c)) for c in ('gs', 'davies_bouldin', 'dunn', 'gs_planes'))
        print(f'{name:8s} {e:5.1f} {result.tolerance:10.3f} {result.segmentation.n_planes:7d} '
              f'{result.noise_estimate:11.3f} {counts.n_planes:14d}  {others}')


def sweep_time(points: int, repeat: int) -> None:
    scene = scenes.boxes(points, noise=0.005, outlier_fraction=0.05, seed=0)
    for tune_points in (None, 20000):
        times = []
        for i in range(repeat):
            result = pv.tune_tolerance(scene.points, seed=i, tune_points=tune_points)
            times.append(result.seconds)
        label = 'all points' if tune_points is None else f'{tune_points}-point subsample'
        print(f'sweep of {len(result.rows)} candidates on {points} points ({label}): median '
              f'{statistics.median(times):.2f} s over {repeat} runs; chosen t = {result.tolerance:.4g} m, '
              f'{result.segmentation.n_planes} planes')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--points', type=int, default=50_000)
    parser.add_argument('--repeat', type=int, default=3)
    args = parser.parse_args()
    start = time.perf_counter()
    paper_table()
    sweep_time(args.points, args.repeat)
    print(f'total {time.perf_counter() - start:.1f} s')


if __name__ == '__main__':
    main()
