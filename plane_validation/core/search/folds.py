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

from .. import kernels

from .fit import allows_normal, fit_columns, tolerance_at
from .tents import tent_faces
from .types import Allows, Tolerance

__all__ = ['split_folds', 'settle_folds', 'FOLD_SIDE']

RULE = 1  # experiment switch

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
        tol = float(np.median(tolerance_at(tolerance, rows))) if len(rows) else 0.0
        faces = _tent_split(search, rows, tol, min_count, allows, max_planes - len(found) + 1) if RULE else None
        if faces is not None:
            face, planes = faces
            found[j] = planes[0]
            for k in range(1, len(planes)):
                region[rows[face == k]] = len(found)
                found.append(planes[k])
            continue
        halves = _fold_halves(search, rows, tol, min_count, allows)
        if halves is not None:
            (_, plane), (move, other) = halves
            region[move] = len(found)
            found[j] = plane
            found.append(other)
    return region, found


def _tent_split(search: np.ndarray, rows: np.ndarray, tolerance: float, min_count: int, allows: Allows,
                room: int) -> tuple[np.ndarray, list] | None:
    """The faces (:func:`.tents.tent_faces`) of the region of ``rows`` (r,) of ``search`` (3, m) where it reads as a
    tent (the verdict's tent test, TENT_LACK) that fits better than one fold, at most ``room`` of them; else None."""
    from .. import verdict
    if len(rows) < max(2 * min_count, 2 * verdict.TILT_NEIGHBOURS) or room < 2:
        return None
    cols = search[:, rows]
    pca = verdict._pca(np.ascontiguousarray(cols.T[verdict._sample_rows(np.arange(len(rows)))]))
    local = verdict._patch_noise(pca, tolerance)
    lack = verdict._lack(pca, local)
    if not lack >= verdict.TENT_LACK:
        return None
    tent, quadric = verdict._tent(pca, local, ridge_only=True)
    if not (tent <= verdict.FOLD_FIT and tent < quadric):
        return None
    fold = verdict.fold_line(pca, tolerance, local, ridge_only=True)[0]
    if fold <= tent:
        return None
    faces = tent_faces(cols, pca, local, max(min_count, 3), allows)
    return faces if faces is not None and len(faces[1]) <= room else None


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


#: Two touching regions are the two faces of one fold when at least this share of each one's points lies on its own
#: side of the plane through the line where their planes meet (see :func:`settle_folds`).
FOLD_SEPARATE = 0.75
#: Rounds of settle_folds (each pair's points moved, both refitted, the pairs again).
FOLD_ROUNDS = 3


def settle_folds(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance, neighbours,
                 viewpoint: np.ndarray, allows: Allows = None) -> tuple[np.ndarray, list]:
    """Each point near the line where two touching regions' planes meet given to the face on its side of that line.

    Near a shallow fold both planes lie within t of each other's points over a band of 2 t / sin(angle), and the
    nearer plane there is the one the noise favours. The plane the point lies on is the one its ray meets last
    (a ridge, seen from outside) or first (a valley): along the ray, noise moves a point by the same amount past
    both planes, so which one that is does not depend on it. A pair is a fold when FOLD_SEPARATE of each region's
    points lie on its own side; then each point of either region within t of the other's plane and on the other's
    side goes to it, and both planes are refitted. ``search`` (3, m) centred meters, ``region`` (m,) (-1: none),
    ``found`` [(normal, offset)], ``tolerance`` (1,) / scalar or (m,) meters, ``viewpoint`` (3,) centred as
    ``search``. Returns new (region, found)."""
    region, found = region.copy(), list(found)
    for _ in range(FOLD_ROUNDS):
        touching = neighbours.contacts(region, len(found))
        if touching is None:
            break
        rows, bounds = kernels.group_by_label(kernels.c_array(region, np.int64), len(found))
        moved = False
        for pair in touching[4]:
            i, j = divmod(int(pair), len(found))
            a = rows[bounds[i]:bounds[i + 1]]
            a = a[region[a] == i]
            b = rows[bounds[j]:bounds[j + 1]]
            b = b[region[b] == j]
            change = _fold_sides(search, a, b, found[i], found[j], tolerance, viewpoint)
            if change is None:
                continue
            to_j, to_i = change
            if not len(to_j) and not len(to_i):
                continue
            region[to_j], region[to_i] = j, i
            fits = [fit_columns(np.ascontiguousarray(search[:, region == r])) for r in (i, j)]
            if all(allows_normal(allows, f[0]) for f in fits):
                found[i], found[j] = fits
            moved = True
        if not moved:
            break
    return region, found


def _fold_sides(search, a, b, plane_a, plane_b, tolerance, viewpoint):
    """(points of ``a`` to move to b, points of ``b`` to move to a) or None where a, b are no fold."""
    if min(len(a), len(b)) < 3:
        return None
    (na, oa), (nb, ob) = plane_a, plane_b
    if na @ nb < 0:
        nb, ob = -nb, -ob
    both = np.concatenate([a, b])
    cols = search[:, both]
    rays = cols - viewpoint[:, None]
    rays /= np.maximum(np.linalg.norm(rays, axis=0), 1e-12)
    cap = np.cos(np.radians(75.0))
    da, db = na @ cols + oa, nb @ cols + ob
    la = da / np.maximum(np.abs(na @ rays), cap)
    lb = db / np.maximum(np.abs(nb @ rays), cap)
    side = la > lb  # True: on a's side when a's side is where la > lb
    on_a = side[:len(a)]
    share = float(np.mean(on_a))
    if share < 0.5:
        side, on_a, share = ~side, ~on_a, 1 - share
    on_b = ~side[len(a):]
    if share < FOLD_SEPARATE or float(np.mean(on_b)) < FOLD_SEPARATE:
        return None
    tol = tolerance_at(tolerance, both)
    near_a, near_b = np.abs(da) <= tol, np.abs(db) <= tol
    to_b = a[~on_a & near_b[:len(a)]]
    to_a = b[~on_b & near_a[len(a):]]
    return to_b, to_a
