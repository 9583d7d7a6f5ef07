"""Regions of one surface that do not touch because something in front of it hides the part between them.

A corridor's floor seen by a spinning lidar lies ahead of and behind the sensor, joined only under the walls that
hide it; a wall behind a pole is cut in two. Their regions do not touch, so the merge of touching regions
(:func:`.connected._merge_coplanar`) leaves them apart. Two coplanar regions are one surface when no ray of the
sensor passes through their joint plane between them: every point seen there lies in front of the plane, or
nothing is seen there. Two tables of one height are not: the floor seen between them lies behind their plane.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import binary_dilation
from scipy.spatial import ConvexHull, QhullError

from .. import kernels
from .fit import allows_normal, tolerance_at
from .types import Allows, Tolerance

__all__ = ['merge_occluded', 'OCCLUDED_COS', 'CROSS_MARGIN', 'CROSS_CELLS', 'CELL_POINTS']

#: Only regions whose planes' normals lie within this angle's cosine (5 degrees) are tried.
OCCLUDED_COS = float(np.cos(np.radians(5.0)))
#: A point at least this many t behind the joint plane (on the far side from the sensor) is seen through it.
CROSS_MARGIN = 2.0
#: Rays crossing the joint plane in at least this many cells of the gap between the regions keep them apart
#: (fewer: stray points, such as mixed pixels at a depth edge).
CROSS_CELLS = 3
#: Regions are first compared on about this many of their points.
NEAR_SAMPLE = 64
#: The in-plane cells hold about this many of the two regions' points each.
CELL_POINTS = 4.0


def merge_occluded(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance, viewpoint: np.ndarray,
                   keep: float, spread: float, allows: Allows = None) -> tuple[np.ndarray, list]:
    """Merge coplanar regions that do not touch, where nothing is seen through their joint plane between them.

    search: (3, m) searched points, meters (less the graph's centre); region: (m,) their regions (-1: none);
    found: each region's (normal (3,), offset) in those coordinates; tolerance: t, scalar or (m,) meters;
    viewpoint: (3,) the sensor in those coordinates. A pair is coplanar when the joint least-squares plane keeps
    ``keep`` of their points within t with an RMS residual at most ``spread`` times that of their own planes (the
    rules of the touching merge). Regions renumbered in order; the earlier one's number is kept."""
    k = len(found)
    if k < 2:
        return region, found
    found = list(found)
    members = [np.flatnonzero(region == j) for j in range(k)]
    root = np.arange(k)
    sizes = np.array([len(m) for m in members])
    normals = np.array([n for n, _ in found])
    pairs = [(i, j) for i in range(k) for j in range(i + 1, k) if abs(normals[i] @ normals[j]) >= OCCLUDED_COS]
    pairs.sort(key=lambda p: -(sizes[p[0]] + sizes[p[1]]))
    for i, j in pairs:
        i, j = root[i], root[j]
        if i == j:
            continue
        i, j = min(i, j), max(i, j)
        if not (_near(search, members[j], found[i], tolerance) and _near(search, members[i], found[j], tolerance)):
            continue  # parallel, apart (a table over the floor)
        joint = np.sort(np.concatenate([members[i], members[j]]))
        plane = _coplanar(search, joint, members[i], members[j], found[i], found[j], tolerance, keep, spread, allows)
        if plane is None or _seen_through(search, joint, members[i], members[j], plane, tolerance, viewpoint):
            continue
        region[members[j]] = i
        members[i], members[j] = joint, joint[:0]
        root[root == j] = i
        found[i] = plane
    kept = np.unique(root)
    if len(kept) == k:
        return region, found
    renumber = np.full(k + 1, -1, dtype=np.int64)
    renumber[kept] = np.arange(len(kept))
    return renumber[region], [found[j] for j in kept]


def _coplanar(search: np.ndarray, joint: np.ndarray, rows_i: np.ndarray, rows_j: np.ndarray, plane_i, plane_j,
              tolerance: Tolerance, keep: float, spread: float, allows: Allows) -> tuple[np.ndarray, float] | None:
    """The joint plane of two regions' rows (``joint``, ascending, = ``rows_i`` with ``rows_j``) when it fits them as
    well as the touching merge asks, else None."""
    if len(rows_i) < 3 or len(rows_j) < 3:
        return None
    normal, offset = kernels.fit_members(search, joint)
    cols = search[:, joint]
    if not allows_normal(allows, normal):
        return None
    dist = np.abs(normal @ cols + offset)
    if np.count_nonzero(dist <= tolerance_at(tolerance, joint)) < keep * len(joint):
        return None
    own = np.concatenate([plane_i[0] @ search[:, rows_i] + plane_i[1], plane_j[0] @ search[:, rows_j] + plane_j[1]])
    if np.mean(dist ** 2) > spread ** 2 * np.mean(own ** 2):
        return None
    return normal, offset


def _near(search: np.ndarray, rows: np.ndarray, plane: tuple[np.ndarray, float], tolerance: Tolerance) -> bool:
    """Whether most of a region's points (``rows``, a sample of about NEAR_SAMPLE) lie within t of ``plane``."""
    some = rows[::max(1, len(rows) // NEAR_SAMPLE)]
    return bool(np.median(np.abs(plane[0] @ search[:, some] + plane[1]) - tolerance_at(tolerance, some)) <= 0)


def _seen_through(search: np.ndarray, joint: np.ndarray, rows_i: np.ndarray,
                  rows_j: np.ndarray, plane: tuple[np.ndarray, float], tolerance: Tolerance,
                  viewpoint: np.ndarray) -> bool:
    """Whether rays from ``viewpoint`` (3,) cross ``plane`` between the two regions (rows ``rows_i``, ``rows_j``,
    ``joint`` both): in CROSS_CELLS or more in-plane cells inside the convex hull of their points and clear of
    both; also True where the sensor lies on the plane (nothing can be told)."""
    normal, offset = plane
    side = float(normal @ viewpoint + offset)
    if abs(side) <= float(np.max(tolerance_at(tolerance, joint))):
        return True
    e1 = np.cross(normal, np.eye(3)[int(np.argmin(np.abs(normal)))])
    e1 /= np.linalg.norm(e1)
    basis = np.stack([e1, np.cross(normal, e1)])  # (2, 3): in-plane axes
    uv = basis @ search[:, joint]  # (2, n)
    lo, hi = uv.min(axis=1), uv.max(axis=1)
    # where the rays to the points seen beyond the plane cross it, inside the box of the two regions
    dq = normal @ search + offset
    behind = (np.sign(dq) != np.sign(side)) & (np.abs(dq) > CROSS_MARGIN * np.asarray(tolerance))
    behind[joint] = False
    rows = np.flatnonzero(behind)
    if not len(rows):
        return False
    s = side / (side - dq[rows])  # the crossing's share of the way from the sensor to the point
    crossing = basis @ (viewpoint[:, None] + s * (search[:, rows] - viewpoint[:, None]))
    crossing = crossing[:, np.all((crossing >= lo[:, None]) & (crossing <= hi[:, None]), axis=0)]
    if crossing.shape[1] < CROSS_CELLS:
        return False
    # in-plane cells of about CELL_POINTS of the regions' points each; the cells next to their points are theirs
    extent = np.maximum(hi - lo, 1e-9)
    cell = float(np.sqrt(extent[0] * extent[1] / len(joint)))  # as if the points filled their box
    cell = max(cell, float(extent.max()) / 2048)  # at most 2048 cells along the longer side
    shape = np.floor(extent / cell).astype(np.int64) + 3
    filled = np.count_nonzero(np.bincount(_cell_of(uv, lo, cell, shape), minlength=int(shape.prod())))
    cell = max(cell * float(np.sqrt(CELL_POINTS * filled / len(joint))), float(extent.max()) / 2048)
    shape = np.floor(extent / cell).astype(np.int64) + 3
    occupied = np.zeros(int(shape.prod()), bool)
    occupied[_cell_of(uv, lo, cell, shape)] = True
    occupied = binary_dilation(occupied.reshape(shape)).reshape(-1)
    flat = _cell_of(crossing, lo, cell, shape)
    gap = ~occupied[flat]
    if np.count_nonzero(gap) < CROSS_CELLS:
        return False
    cells = np.unique(flat[gap])
    centres = lo[:, None] + cell * (np.stack(np.divmod(cells, shape[1])) - 0.5)  # cell 1 starts at lo
    try:  # only between the regions: inside the convex hull of their points
        facets = ConvexHull(uv.T).equations  # (f, 3): outward normal, offset
    except (QhullError, ValueError):  # the points lie on a line: no area between them
        return False
    within = np.all(facets[:, :2] @ centres + facets[:, 2:] <= 0, axis=0)
    return np.count_nonzero(within) >= CROSS_CELLS


def _cell_of(uv: np.ndarray, lo: np.ndarray, cell: float, shape: np.ndarray) -> np.ndarray:
    """Flat cell index (n,) of in-plane points ``uv`` (2, n) on a grid of ``shape`` cells of side ``cell`` from
    one cell before ``lo``."""
    ij = np.floor((uv - lo[:, None]) / cell).astype(np.int64) + 1
    ij = np.clip(ij, 0, shape[:, None] - 1)
    return ij[0] * shape[1] + ij[1]
