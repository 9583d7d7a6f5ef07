"""The verdict's calibration table: every labelled and synthetic cloud of quality.py, plane-free clouds
and the Kinect frames of ../shared/data, auto-tuned with the library defaults (quality.py's
max_planes/min_inliers for the labelled ones), with the indices the verdict reads and its answer
(seed agreement: mean point F1 of the planes at the chosen t against 3 other RANSAC seeds).

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/verdict.py
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import quality  # noqa: E402

import plane_validation as pv  # noqa: E402
from plane_validation.core import scenes  # noqa: E402
from plane_validation.core.plane_shape import plane_thickness  # noqa: E402
from plane_validation.core.scoring import segmentation_quality  # noqa: E402
from plane_validation.core.verdict import (  # noqa: E402
    MAX_FILL,
    MAX_THICKNESS,
    plane_beyond,
    plane_curvature,
    plane_fill,
    plane_layering,
)
from plane_validation.formats.files import load_cloud  # noqa: E402

DATA = quality.GT.parent
KINECT = ('kinect_frame_142255', 'milk_cartoon_all_small_clorox', 'five_people', 'office1',
          'table_scene_mug_stereo_textured')


def row(name: str, kind: str, points: np.ndarray, result, truth: np.ndarray | None) -> str:
    seg = result.segmentation
    thickness = plane_thickness(points, seg)
    curved = [plane_curvature(points, p.inliers) for p, t in zip(seg.planes, thickness) if t > MAX_THICKNESS]
    fill = plane_fill(points, seg)
    layering = plane_layering(points, seg)[fill >= MAX_FILL]
    beyond = plane_beyond(points, seg)
    f1 = f'{segmentation_quality(seg.labels, truth).f1:.3f}' if truth is not None else '—'
    x = result.indices
    return (f'| {name} | {kind} | {f1} | {1000 * result.tolerance:.3g} | {seg.n_planes} | {x.plane_silhouette:.2f} | '
            f'{x.gs_planes:.2f} | {max(thickness, default=0):.2f} | {max(curved, default=0):.2f} | '
            f'{max(beyond, default=0):.2f} | {max(fill, default=0):.2f} | {max(layering, default=0):.2f} | '
            f'{result.seed_agreement:.2f} | '
            f'{"**reliable**" if result.reliable else "not reliable"} | {result.verdict} |')


def main() -> None:
    from plane_validation.core.blas import limit_blas_threads
    limit_blas_threads()
    table()


def table() -> None:
    """Print the calibration table."""
    print('| cloud | kind | F1 | t (mm) | planes | PS | GSplanes | max thickness | max curvature of a thick plane | '
          'max beyond | max fill | max layering of a filled plane | seed agreement | verdict | why |')
    print('|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|---|---|')
    for c in quality.load_clouds():
        result = pv.tune_tolerance(c.points, seed=0, shape=c.shape, **quality._params(c))
        print(row(c.name, 'labelled', c.points, result, c.labels), flush=True)
    free = {'sphere, e = 1 cm': scenes.sphere(5000, 0.01, seed=0).points,
            'sphere, noise-free': scenes.sphere(20000, 0.0, seed=0).points,
            'uniform cube': np.random.default_rng(0).uniform(0, 1, (5000, 3))}
    for name in ('bun_zipper.ply', 'bunny.pcd'):
        if (DATA / name).exists():
            free[name] = load_cloud(DATA / name)[0]
    for name, points in free.items():
        print(row(name, 'plane-free', points, pv.tune_tolerance(points, seed=0), None), flush=True)
    probe = {'floor with a bush': scenes.clutter('bush', seed=1), 'plane, 30% outliers': scenes.clutter(
        'outliers', share=0.3, seed=3), 'plane, 50% outliers': scenes.clutter('outliers', share=0.5, seed=3),
        'two sheets 5 cm apart': scenes.clutter('sheets', seed=3)}  # an outside probe's scenes
    for name, scene in probe.items():
        print(row(name, 'clutter', scene.points, pv.tune_tolerance(scene.points, seed=0), scene.labels), flush=True)
    for name in KINECT:
        if (DATA / f'{name}.pcd').exists():
            points, shape = load_cloud(DATA / f'{name}.pcd')
            print(row(name, 'Kinect, unlabelled', points, pv.tune_tolerance(points, seed=0, shape=shape), None),
                  flush=True)


if __name__ == '__main__':
    main()
