"""Sequential RANSAC: the best plane, its points taken out, and again, until none is large enough."""
from __future__ import annotations

import numpy as np

from .. import kernels
from .fit import degeneracy, tolerance_at
from .hypotheses import best_plane
from .neighbours import Neighbours
from .types import Allows, Tolerance

__all__ = ['sequential_search']

_ORIGIN = np.zeros(3)


def sequential_search(cols: np.ndarray, tolerance: Tolerance, max_planes: int, min_count: int, probability: float,
                      max_iterations: int, rng: np.random.Generator, n_total: int,
                      neighbours: Neighbours | None = None, allows: Allows = None
                      ) -> tuple[list, str, np.ndarray | None, bool]:
    """Sequential RANSAC on the points ``cols`` (3, n): the planes [(normal, offset)] in
    extraction order, why the search stopped, with ``neighbours`` the region of each point
    (n,) (-1: none), and whether it stopped at ``max_planes`` with ``min_count`` points left."""
    n = cols.shape[1]
    rest = cols
    rest_idx = np.arange(n) if neighbours is None else neighbours.searchable()  # the points that can join a region
    if len(rest_idx) < n:
        rest = cols.take(rest_idx, axis=1)
        tolerance = tolerance_at(tolerance, rest_idx)
    region = None if neighbours is None else np.full(n, -1, dtype=np.int64)
    remaining = None if neighbours is None else neighbours.remaining(rest_idx)
    rest_normals = None if neighbours is None or neighbours.normals is None else \
        kernels.columns_at(kernels.c_array(neighbours.normals, np.float64), kernels.c_array(rest_idx, np.int64),
                           _ORIGIN)  # (3, r), kept in step with rest
    found: list[tuple[np.ndarray, float]] = []
    reason = f'reached max_planes={max_planes}'
    while len(found) < max_planes:
        why = degeneracy(rest)
        if why is not None:
            reason = why if rest.shape[1] < n or n_total < 3 else f'no plane: {why}'
            break
        sampler = None if neighbours is None else neighbours.sampler(rest_idx)
        best = best_plane(rest, tolerance, probability, max_iterations, rng, remaining, rest_normals, sampler,
                          allows)
        if best is None:
            reason = 'every sampled triple was degenerate (nearly collinear or duplicate points)' if allows is None \
                else 'no sampled plane satisfied the orientation constraint (or every triple was degenerate)'
            break
        normal, offset, inliers, taken = best
        count = int(np.count_nonzero(inliers))
        if count < min_count:
            reason = f'best remaining plane has {count} < min_inliers={min_count} points' + \
                ('' if n == n_total else f' (in a sample of {n} of {n_total} points)')
            break
        left = ~taken
        if region is not None:
            region[rest_idx[inliers]] = len(found)
            rest_idx = rest_idx[left]
            remaining = remaining.without(left)
        found.append((normal, offset))
        rest = np.compress(left, rest, axis=1)
        if rest_normals is not None:
            rest_normals = np.compress(left, rest_normals, axis=1)
        tolerance = tolerance_at(tolerance, left)
    return found, reason, region, len(found) == max_planes > 0 and rest.shape[1] >= min_count
