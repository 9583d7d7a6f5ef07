"""The number of planes, chosen by validity indices over the first k planes of one segmentation (paper Fig. 2).

Pure numpy, no ROS import.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .blas import single_blas_thread
from .criteria import best_position, check_criterion, resolved_sampled_separation
from .indices import ValidityIndices, validity_indices
from .noise import NOISE_REFERENCE
from .orientation import Orientation
from .params import GRID_POINTS, MAX_ITERATIONS, MAX_PLANES, MIN_INLIERS, PROBABILITY, RANSAC_POINTS
from .ransac import Segmentation, Viewpoint, as_points, detect_planes, generator

__all__ = ['MIN_PLANE_SILHOUETTE', 'PlaneCountResult', 'select_plane_count']

#: A plane whose own mean silhouette S_j (eq. 5, among the planes) is below this is not a
#: well-assigned plane; select_plane_count keeps the largest k whose planes all reach it.
MIN_PLANE_SILHOUETTE = 0.05


@dataclass(frozen=True, eq=False)
class PlaneCountResult:
    """Result of :func:`select_plane_count`: indices[k-1] scores the first k planes."""

    counts: tuple[int, ...]
    indices: tuple[ValidityIndices, ...]
    criterion: str
    n_planes: int
    segmentation: Segmentation

    def best_by(self, criterion: str) -> int:
        """Plane count the given index would choose (one of :data:`CRITERIA`)."""
        check_criterion(criterion)
        return self.counts[best_position([getattr(x, criterion) for x in self.indices], criterion)]


@single_blas_thread
def select_plane_count(points: np.ndarray, tolerance: float, max_planes: int = MAX_PLANES,
                       criterion: str = 'gs_planes', *, min_inliers: int | float = MIN_INLIERS,
                       probability: float = PROBABILITY, max_iterations: int = MAX_ITERATIONS,
                       sample_size: int | None = 2000,
                       seed: int | None = None, shape: tuple[int, int] | None = None,
                       connectivity: bool = True, noise_model: str = 'constant',
                       noise_reference: float = NOISE_REFERENCE, viewpoint: Viewpoint = None,
                       sampled_separation: bool | None = None, ransac_points: int | None = RANSAC_POINTS,
                       grid_points: int | None = GRID_POINTS, orientation: Orientation | None = None
                       ) -> PlaneCountResult:
    """Score the first k planes (the rest unassigned) for k = 1..K and pick k (paper Fig. 2).

    One sequential RANSAC run with ``max_planes`` finds up to K planes at ``tolerance`` meters;
    labels of planes k.. are set to -1 before scoring. Returns every k's indices. For gs, dunn,
    silhouette and davies_bouldin k is the index's optimum (``best_by``); for gs_planes it is the
    largest k whose planes all keep a mean silhouette S_j >= MIN_PLANE_SILHOUETTE (see
    :func:`_well_assigned_count` for why not the plain argmax). shape, connectivity, noise_model,
    noise_reference, viewpoint, ransac_points, grid_points, orientation: to :func:`detect_planes`;
    sampled_separation: to :func:`validity_indices`, None meaning exact up to EXACT_SEPARATION_POINTS valid points
    (as in :func:`tune_tolerance`).
    """
    check_criterion(criterion)
    rng = generator(seed)
    ransac_seed, index_seed = rng.integers(0, 2**63, size=2)
    seg = detect_planes(points, tolerance, max_planes=max_planes, min_inliers=min_inliers,
                        probability=probability, max_iterations=max_iterations, seed=int(ransac_seed),
                        shape=shape, connectivity=connectivity, noise_model=noise_model,
                        noise_reference=noise_reference, viewpoint=viewpoint, ransac_points=ransac_points,
                        grid_points=grid_points, orientation=orientation)
    pts = as_points(points)
    sampled = resolved_sampled_separation(sampled_separation, seg.n_valid)
    counts, scores = [], []
    for k in range(1, seg.n_planes + 1):
        labels = np.where(seg.labels < k, seg.labels, -1)
        counts.append(k)
        scores.append(validity_indices(pts, labels, sample_size=sample_size, seed=int(index_seed),
                                       sampled_separation=sampled))
    if not counts:
        n_planes = 0
    elif criterion == 'gs_planes':
        n_planes = _well_assigned_count(scores)
    else:
        n_planes = counts[best_position([getattr(s, criterion) for s in scores], criterion)]
    return PlaneCountResult(counts=tuple(counts), indices=tuple(scores), criterion=criterion, n_planes=n_planes,
                            segmentation=seg)


def _well_assigned_count(scores: list[ValidityIndices]) -> int:
    """Largest k >= 2 whose k planes all have S_j >= MIN_PLANE_SILHOUETTE; 1 when none.

    The plain argmax of GSplanes over k is biased to k = 2: dropping a plane from the scored set
    also drops it as a competitor in every b_i, so GS over the first k planes shrinks as k grows
    even when every plane is real (noise-free corner: 0.38, 0.30 for k = 2, 3). A spurious plane
    (a sliver of an already found face) instead has S_j near or below 0.
    """
    good = [i + 1 for i, s in enumerate(scores)
            if i >= 1 and min(s.plane_silhouettes, default=0.0) >= MIN_PLANE_SILHOUETTE]
    return max(good) if good else 1
