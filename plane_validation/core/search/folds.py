"""Regions that hold the two sides of a shallow ridge or fold, split at its line.

Two surfaces meeting at a shallow angle (a gable roof of a few degrees, a ramp meeting a floor) can lie within t of
one plane and join one connected region, whose residuals across the line then form a V. A region that the verdict's
ridge test fails (:func:`.verdict.plane_fold`: a lack of fit of FOLD_LACK or more that two planes meeting at a line,
:func:`.kernels.fold_line`, bring down to FOLD_FIT, better than a quadric) is split at that line, each side
refitted, and each of its points given to the nearer of the two planes.
"""
from __future__ import annotations

import numpy as np

from .. import kernels
from .fit import allows_normal, fit_columns
from .types import Allows

__all__ = ['split_folds', 'FOLD_SIDE', 'FOLD_DEPTH']

#: A region is split only where each side holds at least this share of its points (a fold near the region's edge is
#: a lip or a bent border, not a second surface).
FOLD_SIDE = 0.15
#: Each side is split again at most this many times in all.
FOLD_DEPTH = 2


def split_folds(search: np.ndarray, region: np.ndarray, found: list, tolerance: float, max_planes: int,
                min_count: int, allows: Allows = None) -> tuple[np.ndarray, list]:
    """``region`` (m,) (-1: none) and ``found`` (normal, offset) planes of the centred points ``search`` (3, m)
    meters, with each region that holds a fold split in two (the new one numbered last) while there are fewer than
    ``max_planes`` and each side keeps ``min_count`` searched points. Returns the new region labels and planes."""
    region, found = region.copy(), list(found)
    queue = [(j, FOLD_DEPTH) for j in range(len(found))]
    while queue and len(found) < max_planes:
        j, depth = queue.pop(0)
        rows = np.flatnonzero(region == j)
        halves = _fold_halves(search, rows, tolerance, min_count, allows) if depth > 0 else None
        if halves is None:
            continue
        (keep, plane), (move, other) = halves
        region[move] = len(found)
        found[j] = plane
        found.append(other)
        queue += [(j, depth - 1), (len(found) - 1, depth - 1)]
    return region, found


def _fold_halves(search: np.ndarray, rows: np.ndarray, tolerance: float, min_count: int, allows: Allows):
    """The two sides of the region of ``rows`` of ``search`` (3, m) at its best fold, each as (its rows, its plane),
    or None where the verdict would not call it a ridge, a side is too small, or a side's plane is not allowed."""
    from .. import verdict as V  # the verdict imports the search's types: importing it at the top is a cycle
    if len(rows) < max(2 * min_count, 2 * V.TILT_NEIGHBOURS):
        return None
    cols = search[:, rows]
    pca = V._pca(np.ascontiguousarray(cols.T[V._sample_rows(np.arange(len(rows)))]))
    local = V._patch_noise(pca, tolerance)
    if local is None:
        return None
    lack = np.sqrt(max(float(pca[2][0]), 0.0) / len(pca[1]) / local)
    if not lack >= V.FOLD_LACK:
        return None
    centred = pca[1][::-(-len(pca[1]) // V.FOLD_POINTS)]
    w, u, v = (centred @ pca[3]).T
    mse, theta, s0 = kernels.fold_line(np.ascontiguousarray(u), np.ascontiguousarray(v), np.ascontiguousarray(w),
                                       V.FOLD_ANGLES, V.FOLD_OFFSETS, V.FOLD_INNER)
    fold = np.sqrt(mse / local)
    if not fold <= V.FOLD_FIT:
        return None
    design = np.column_stack([u * u, u * v, v * v, u, v, np.ones_like(u)])
    coef, *_ = np.linalg.lstsq(design, w, rcond=None)
    if not fold < np.sqrt(float(np.mean((w - design @ coef) ** 2)) / local):
        return None
    across = (cols.T - pca[0]) @ (pca[3][:, 1] * np.cos(theta) + pca[3][:, 2] * np.sin(theta))
    side = across > s0
    least = max(min_count, FOLD_SIDE * len(rows), 3)
    planes = []
    for part in (~side, side):
        if np.count_nonzero(part) < least:
            return None
        planes.append(fit_columns(np.ascontiguousarray(cols[:, part])))
    distance = [np.abs(n @ cols + d) for n, d in planes]
    side = distance[1] < distance[0]  # each point to the nearer plane, then both refitted
    result = []
    for part in (~side, side):
        if np.count_nonzero(part) < least:
            return None
        plane = fit_columns(np.ascontiguousarray(cols[:, part]))
        if not allows_normal(allows, plane[0]):
            return None
        result.append((rows[part], plane))
    return result[0], result[1]
