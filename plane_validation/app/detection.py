"""Planes of one cloud with every index and a verdict: what ``plane-validation detect`` computes.

With a fixed tolerance this is :func:`detect_planes` then :func:`validity_indices` (both with
the same ``seed``) and :func:`judge`; without one it is :func:`tune_tolerance` (seeded the
same way), whose result already holds the planes at the chosen t, their indices and a verdict.
"""
from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..core.failures import Verdict
from ..core.geometry import ring_image
from ..core.indices import ValidityIndices, validity_indices
from ..core.noise import noise_coefficient
from ..core.params import SearchParams, TuneParams
from ..core.ransac import (
    Segmentation,
    Viewpoint,
    as_points,
    carried,
    detect_planes,
    finite_rows,
)
from ..core.tuning import noise_from_segmentation, tune_tolerance
from ..core.tuning_result import TuningResult
from ..core.verdict import judge
from .config import PipelineConfig

__all__ = ['Detection', 'detect', 'ring_layout', 'tune_scan']


@dataclass(frozen=True, eq=False)
class Detection:
    """points: (N, 3) as given (NaN rows included); tolerance: meters; tolerance_source: 'fixed'
    or 'auto'; noise_estimate: half-width e of uniform noise matching the planes' residuals (m);
    tuning: the sweep when auto-tuned; seconds: wall time of detection and scoring; verdict: whether the planes
    are reliable, and every test they fail."""

    points: np.ndarray
    segmentation: Segmentation
    indices: ValidityIndices
    tolerance: float
    tolerance_source: str
    verdict: Verdict
    noise_estimate: float
    seed: int
    seconds: float
    tuning: TuningResult | None = None
    ring_image: str | None = None  # a lidar scan laid out by its rings: 'HxW', or 'not used: why'

    @property
    def reliable(self) -> bool:
        return self.verdict.reliable


def ring_layout(points: np.ndarray, ring: np.ndarray | None, viewpoint: Viewpoint = None
                ) -> tuple[tuple[np.ndarray, tuple[int, int], np.ndarray] | None, str | None]:
    """An unorganized lidar scan (``points`` (N, 3) meters, NaN rows allowed) laid out by its ``ring``
    numbers (N,) as :func:`ring_image` does, and what to report of it: ((image (H * W, 3), (H, W), the
    pixel of each finite point), 'HxW'), or (None, 'not used: why') when the rings form no image (the
    scan is then searched on its neighbourhood graph), or (None, None) without ring numbers."""
    if ring is None:
        return None, None
    finite = finite_rows(points)
    try:
        if np.shape(ring) != (len(points),):
            raise ValueError(f'ring numbers of shape {np.shape(ring)} for {len(points)} points')
        laid = ring_image(np.compress(finite, points, axis=0), np.asarray(ring)[finite],
                          (0.0, 0.0, 0.0) if viewpoint is None else viewpoint)
    except ValueError as exc:
        return None, f'not used: {exc}'
    return laid, f'{laid[1][0]}x{laid[1][1]}'


def _laid(points: np.ndarray, ring: np.ndarray | None, shape: tuple[int, int] | None, organize_rings: bool,
          connectivity: bool, viewpoint: Viewpoint) -> tuple[tuple | None, str | None]:
    """:func:`ring_layout` where it applies: an unorganized scan, ``organize_rings`` and ``connectivity``."""
    return ring_layout(points, ring if shape is None and organize_rings and connectivity else None, viewpoint)


def tune_scan(points: np.ndarray, *, search: SearchParams | None = None, ring: np.ndarray | None = None,
              organize_rings: bool = True, shape: tuple[int, int] | None = None, seed: int | None = 0,
              **options) -> tuple[TuningResult, str | None]:
    """:func:`tune_tolerance` of (N, 3) ``points`` with ``search`` (None: the parameter table's defaults) and the
    sweep's ``options``, and what :func:`ring_layout` says: an unorganized lidar scan with ``ring`` numbers (with
    ``organize_rings`` and connectivity) is swept and detected on its ring image, as the node does, and the chosen
    planes are carried back to the points and scored and judged there (the sweep's rows stay the image's)."""
    search = PipelineConfig().search if search is None else search
    options = dict(search.kwargs(), **options)
    connectivity, viewpoint = search.connectivity, search.viewpoint
    laid, note = _laid(points, ring, shape, organize_rings, connectivity, viewpoint)
    if laid is None:
        return tune_tolerance(points, seed=seed, shape=shape, **options), note
    tuned = tune_tolerance(laid[0], seed=seed, shape=laid[1], **options)
    seg = carried(tuned.segmentation, points, laid[2])
    scores = validity_indices(points, seg.labels, seed=seed)
    verdict = judge(points, seg, scores, None if np.isnan(tuned.seed_agreement) else tuned.seed_agreement)
    return dataclasses.replace(
        tuned, segmentation=seg, indices=scores, verdict=verdict,
        noise_estimate=noise_from_segmentation(seg, points),
        noise_coefficient=noise_coefficient(points, seg.labels, seg.coefficients, seg.viewpoint)
        if seg.noise_model == 'depth_quadratic' else float('nan')), note


def detect(points: np.ndarray, tolerance: float | None = None, *, search: SearchParams | None = None, seed: int = 0,
           progress: Callable[[int, int], None] | None = None, shape: tuple[int, int] | None = None, jobs: int = 1,
           ring: np.ndarray | None = None, organize_rings: bool = True, tune: TuneParams | None = None) -> Detection:
    """Planes of (N, 3) ``points`` at ``tolerance`` meters, or at the auto-tuned t when None, searched with
    ``search`` (None: the parameter table's defaults); ``shape`` (H, W) for an organized cloud; ``jobs`` as in
    :func:`tune_tolerance`; ``tune``: how to sweep (criterion, range, candidates, and jobs instead of ``jobs``;
    None: :func:`tune_tolerance`'s defaults). ``ring`` (N,): each point's beam of an unorganized lidar scan, which
    is then searched (and tuned) on its ring image as the node does (:func:`ring_layout`; with ``organize_rings``
    and connectivity), and its planes carried back to the points.

    Equivalent Python API calls (same results without ``ring``): fixed t -> ``detect_planes(points, t,
    seed=seed, **search.at_tolerance())`` and ``validity_indices(points, labels, seed=seed)``; auto ->
    ``tune_tolerance(points, seed=seed, **search.kwargs())`` (and ``**tune.kwargs()`` when ``tune`` is given).
    """
    pts = as_points(points)
    start = time.perf_counter()
    search = PipelineConfig().search if search is None else search
    if tolerance is None:
        sweep = {'jobs': jobs} if tune is None else tune.kwargs()
        tuned, note = tune_scan(pts, search=search, ring=ring, organize_rings=organize_rings, shape=shape, seed=seed,
                                progress=progress, **sweep)
        return Detection(points=pts, segmentation=tuned.segmentation, indices=tuned.indices,
                         tolerance=tuned.tolerance, tolerance_source='auto',
                         verdict=tuned.verdict, noise_estimate=tuned.noise_estimate, seed=seed,
                         seconds=time.perf_counter() - start, tuning=tuned, ring_image=note)
    laid, note = _laid(pts, ring, shape, organize_rings, search.connectivity, search.viewpoint)
    cloud, cloud_shape = (laid[0], laid[1]) if laid else (pts, shape)
    seg = detect_planes(cloud, tolerance, seed=seed, shape=cloud_shape, **search.at_tolerance())
    if laid is not None:
        seg = carried(seg, pts, laid[2])
    scores = validity_indices(pts, seg.labels, seed=seed)
    return Detection(points=pts, segmentation=seg, indices=scores, tolerance=float(tolerance),
                     tolerance_source='fixed', verdict=judge(pts, seg, scores),
                     noise_estimate=noise_from_segmentation(seg, pts), seed=seed, seconds=time.perf_counter() - start,
                     ring_image=note)
