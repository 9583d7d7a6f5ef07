"""Regions that hold the two sides of a shallow ridge or fold, split at its line.

Two surfaces meeting at a shallow angle (a gable roof of a few degrees, a ramp meeting a floor) can lie within t of
one plane and join one connected region, whose residuals across the line then form a V. A region whose lack of fit
is FOLD_LACK or more and that two planes meeting at a line bring down to FOLD_FIT, better than a quadric surface
(the verdict's ridge test, :func:`.verdict.is_ridge`, without its upper bound: a larger lack of fit, which the verdict
fails as surfaces merged, is split too), is split at that line: each side gets a plane, each of the region's points
goes to the nearer of the two, and both planes are refitted to their points.
"""
from __future__ import annotations

import numpy as np

from .fit import allows_normal, fit_columns, tolerance_at
from .types import Allows, Tolerance

__all__ = ['split_folds', 'FOLD_SIDE']

#: A region is split only where each side holds at least this share of its points (a fold near the region's edge is
#: a lip or a bent border, not a second surface).
FOLD_SIDE = 0.15


def split_folds(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance, max_planes: int,
                min_count: int, allows: Allows = None) -> tuple[np.ndarray, list]:
    """``region`` (m,) (-1: none) and ``found`` (normal, offset) planes of the centred points ``search`` (3, m)
    meters, with each region that holds a ridge split once in two (the new plane numbered last) while there are
    fewer than ``max_planes`` and each side keeps ``min_count`` searched points. ``tolerance``: t (m) at each
    searched point (m,) or for all; its median over a region sets the floor of the noise the ridge test measures
    (:func:`.verdict._patch_noise`). ``allows``: the normals a plane may have (None: any). Returns the new region
    labels and planes; the inputs are left as they were."""
    region, found = region.copy(), list(found)
    for j in range(len(found)):
        if len(found) >= max_planes:
            break
        rows = np.flatnonzero(region == j)
        halves = _fold_halves(search, rows, float(np.median(tolerance_at(tolerance, rows))) if len(rows) else 0.0,
                              min_count, allows)
        if halves is not None:
            (_, plane), (move, other) = halves
            region[move] = len(found)
            found[j] = plane
            found.append(other)
    return region, found


def _fold_halves(search: np.ndarray, rows: np.ndarray, tolerance: float, min_count: int, allows: Allows):
    """The two sides of the region of ``rows`` (r,) of ``search`` (3, m) at its best fold, each as (its rows (a,),
    its (normal, offset) plane), or None where the region holds no ridge (see the module), a side would keep fewer
    than ``min_count`` points or FOLD_SIDE of the region's, or ``allows`` refuses a side's normal. ``tolerance``: the
    region's t (m)."""
    from .. import verdict  # the verdict imports the search's types: importing it with the module is a cycle
    if len(rows) < max(2 * min_count, 2 * verdict.TILT_NEIGHBOURS):
        return None
    cols = search[:, rows]
    pca = verdict._pca(np.ascontiguousarray(cols.T[verdict._sample_rows(np.arange(len(rows)))]))
    local = verdict._patch_noise(pca, tolerance)
    lack = verdict._lack(pca, local)
    if not lack >= verdict.FOLD_LACK:  # NaN: not judged
        return None
    fold, quadric, theta, s0 = verdict.fold_line(pca, tolerance, local, ridge_only=True)
    if not verdict.is_ridge(lack, fold, quadric):
        return None
    across = (cols.T - pca[0]) @ (pca[3][:, 1] * np.cos(theta) + pca[3][:, 2] * np.sin(theta))
    least = max(min_count, FOLD_SIDE * len(rows), 3)
    first = _sides(cols, across > s0, least)
    if first is None:
        return None
    distance = [np.abs(normal @ cols + offset) for normal, offset in first]
    side = distance[1] < distance[0]  # each point to the nearer plane, both refitted
    planes = _sides(cols, side, least)
    if planes is None or not all(allows_normal(allows, normal) for normal, _ in planes):
        return None
    return (rows[~side], planes[0]), (rows[side], planes[1])


def _sides(cols: np.ndarray, side: np.ndarray, least: float) -> list | None:
    """The planes fitted to the points ``cols`` (3, r) off and on ``side`` (r,), or None where either has fewer than
    ``least``."""
    if min(np.count_nonzero(side), np.count_nonzero(~side)) < least:
        return None
    return [fit_columns(np.ascontiguousarray(cols[:, part])) for part in (~side, side)]
