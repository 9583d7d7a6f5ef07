"""Planes of one cloud with every index and a verdict: what ``plane-validation detect`` computes.

With a fixed tolerance this is :func:`detect_planes` then :func:`validity_indices` (both with
the same ``seed``) and :func:`judge`; without one it is :func:`tune_tolerance` (seeded the
same way), whose result already holds the planes at the chosen t, their indices and a verdict.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..core.indices import ValidityIndices, validity_indices
from ..core.noise import NOISE_REFERENCE
from ..core.ransac import RANSAC_POINTS, Segmentation, Viewpoint, as_points, detect_planes
from ..core.tuning import TuningResult, noise_from_segmentation, tune_tolerance
from ..core.verdict import judge

__all__ = ['Detection', 'detect']


@dataclass(frozen=True, eq=False)
class Detection:
    """points: (N, 3) as given (NaN rows included); tolerance: meters; tolerance_source: 'fixed'
    or 'auto'; noise_estimate: half-width e of uniform noise matching the planes' residuals (m);
    tuning: the sweep when auto-tuned; seconds: wall time of detection and scoring."""

    points: np.ndarray
    segmentation: Segmentation
    indices: ValidityIndices
    tolerance: float
    tolerance_source: str
    reliable: bool
    verdict: str
    noise_estimate: float
    seed: int
    seconds: float
    tuning: TuningResult | None = None


def detect(points: np.ndarray, tolerance: float | None = None, *, seed: int = 0, max_planes: int = 10,
           min_inliers: int | float = 0.02, progress: Callable[[int, int], None] | None = None,
           shape: tuple[int, int] | None = None, noise_model: str = 'constant',
           noise_reference: float = NOISE_REFERENCE, jobs: int = 1, connectivity: bool = True,
           ransac_points: int | None = RANSAC_POINTS, viewpoint: Viewpoint = None) -> Detection:
    """Planes of (N, 3) ``points`` at ``tolerance`` meters, or at the auto-tuned t when None;
    ``shape`` (H, W) for an organized cloud; ``noise_model``, ``connectivity``, ``ransac_points`` and
    ``viewpoint`` as in :func:`detect_planes`; ``jobs`` as in :func:`tune_tolerance`.

    Equivalent Python API calls (same results): fixed t -> ``detect_planes(points, t, seed=seed,
    max_planes=..., min_inliers=...)`` and ``validity_indices(points, labels, seed=seed)``; auto ->
    ``tune_tolerance(points, seed=seed, max_planes=..., min_inliers=...)``.
    """
    pts = as_points(points)
    start = time.perf_counter()
    if tolerance is None:
        tuned = tune_tolerance(pts, seed=seed, max_planes=max_planes, min_inliers=min_inliers, progress=progress,
                               shape=shape, noise_model=noise_model, noise_reference=noise_reference, jobs=jobs,
                               connectivity=connectivity, ransac_points=ransac_points, viewpoint=viewpoint)
        return Detection(points=pts, segmentation=tuned.segmentation, indices=tuned.indices,
                         tolerance=tuned.tolerance, tolerance_source='auto', reliable=tuned.reliable,
                         verdict=tuned.verdict, noise_estimate=tuned.noise_estimate, seed=seed,
                         seconds=time.perf_counter() - start, tuning=tuned)
    seg = detect_planes(pts, tolerance, seed=seed, max_planes=max_planes, min_inliers=min_inliers, shape=shape,
                        noise_model=noise_model, noise_reference=noise_reference, connectivity=connectivity,
                        ransac_points=ransac_points, viewpoint=viewpoint)
    scores = validity_indices(pts, seg.labels, seed=seed)
    reliable, verdict = judge(pts, seg, scores)
    return Detection(points=pts, segmentation=seg, indices=scores, tolerance=float(tolerance),
                     tolerance_source='fixed', reliable=reliable, verdict=verdict,
                     noise_estimate=noise_from_segmentation(seg, pts), seed=seed, seconds=time.perf_counter() - start)
