"""Stable plane ids: a depth camera slides and turns past a static furnished room (core/scenes.py);
the frames go through the node's FramePipeline, whose PlaneTracker numbers the planes.

Prints the share of (surface, consecutive frame pair) that keep their id: a surface is a rectangle
of the room, found in a frame when one plane holds most of its pixels and it holds most of that plane's;
a pair counts when the surface is found in both frames.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_tracking.py [--frames 40] [--width 320]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from plane_validation.app.pipeline import FramePipeline, PipelineConfig, limit_blas_threads
from plane_validation.core.scenes import depth_camera

#: A plane and a surface are one when each holds over this share of their common pixels' sets.
MAJORITY = 0.5


def trajectory(frames: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """(eye, target) per frame: 1.2 m sideways along the room while the gaze turns by about 25 degrees."""
    out = []
    for k in range(frames):
        s = k / max(frames - 1, 1)
        eye = np.array([4.6 - 1.2 * s, 0.4 + 0.2 * s, 1.5])
        target = np.array([1.5 + 1.5 * s, 3.6, 0.7])
        out.append((eye, target))
    return out


def surfaces_found(truth: np.ndarray, labels: np.ndarray, ids: tuple[int, ...]) -> dict[int, int]:
    """surface (rectangle index) -> track id of the plane that is it in this frame."""
    found = {}
    for s in np.unique(truth[truth >= 0]):
        on = truth == s
        planes, counts = np.unique(labels[on & (labels >= 0)], return_counts=True)
        if not len(planes):
            continue
        k = planes[np.argmax(counts)]
        if counts.max() > MAJORITY * on.sum() and counts.max() > MAJORITY * np.sum(labels == k):
            found[int(s)] = ids[k]
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--frames', type=int, default=40)
    parser.add_argument('--width', type=int, default=320)
    parser.add_argument('--seed', type=int, default=0)
    args = parser.parse_args()
    limit_blas_threads()
    height = args.width * 3 // 4
    pipeline = FramePipeline(PipelineConfig(seed=args.seed, noise_model='depth_quadratic'))
    kept = pairs = 0
    previous: dict[int, int] = {}
    start = time.perf_counter()
    for k, (eye, target) in enumerate(trajectory(args.frames)):
        scene = depth_camera('room', width=args.width, height=height, eye=eye, target=target, seed=args.seed + k)
        result = pipeline.process(scene.points, 1_000_000_000 + k * 100_000_000, shape=scene.shape)
        valid = np.isfinite(scene.points).all(axis=1)
        found = surfaces_found(scene.labels[valid], result.labels, result.plane_ids)
        both = previous.keys() & found.keys()
        pairs += len(both)
        kept += sum(previous[s] == found[s] for s in both)
        previous = found
    seconds = time.perf_counter() - start
    print(f'{args.frames} frames of {args.width}x{height}, t = {pipeline.tolerance:.4g} m, {seconds:.1f} s: '
          f'{kept} of {pairs} (surface, consecutive frame pair) kept their id = {100 * kept / max(pairs, 1):.1f} %')


if __name__ == '__main__':
    main()
