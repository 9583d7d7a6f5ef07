"""Regions of one surface that do not touch because the part between them is hidden or out of the sensor's view.

A corridor's floor seen by a spinning lidar lies ahead of and behind the sensor, the part beside it below the lowest
ring; a wall behind a pole is cut in two. Their regions do not touch, so the merge of touching regions
(:func:`.connected._merge_coplanar`) leaves them apart. Two coplanar regions are one surface when, between them, no
ray of the sensor passes through their joint plane, and at least half of the plane there is hidden behind points in
front of it, holds other points on it, or lies outside the directions the sensor sees (beyond its lowest or highest
ray, or between two of a spinning lidar's rings, whose far floor is strips metres apart). Two tables of one height are
not: the floor seen between them lies behind their plane; nor are they when nothing tells why the part between them
is missing (a cropped cloud).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from .. import kernels
from .fit import allows_normal, tolerance_at
from .types import Allows, Tolerance

__all__ = ['merge_occluded', 'OCCLUDED_COS', 'CROSS_MARGIN', 'CROSS_CELLS', 'EXPLAINED', 'CELL_POINTS',
           'MAX_CELLS', 'MAX_TRIES', 'VIEW_MARGIN_DEG', 'HULL_POINTS', 'CROSS_POINTS', 'NEAR_SAMPLE', 'EVIDENCE_REACH']

#: Only regions whose planes' normals lie within this angle's cosine (5 degrees) are tried.
OCCLUDED_COS = float(np.cos(np.radians(5.0)))
#: A point at least this many t off the joint plane is seen through it (beyond it) or hides it (before it).
CROSS_MARGIN = 2.0
#: Rays crossing the joint plane in at least this many cells of the gap between the regions keep them apart
#: (fewer: stray points, such as mixed pixels at a depth edge).
CROSS_CELLS = 3
#: At least this share of the gap's cells must be hidden, hold other points on the plane, or be out of view.
EXPLAINED = 0.5
#: A cell where the plane is hidden or seen marks this many cells around it too (rays as sparse as a lidar's rings).
EVIDENCE_REACH = 2
#: The in-plane cells hold about this many of the two regions' points each ...
CELL_POINTS = 4.0
#: ... and are at most this many for a pair.
MAX_CELLS = 1 << 16
#: Pairs tested (after the cheap checks) per search: the cost stays bounded on many coplanar regions.
MAX_TRIES = 12
#: Directions this far (degrees) beyond the elevations (about z at the sensor) of every searched point are out of the
#: sensor's view (a spinning lidar's lowest ring; a camera's cone).
VIEW_MARGIN_DEG = 1.0
#: The convex hull of a pair is taken on every so many-th of its points, about this many ...
HULL_POINTS = 1024
#: ... and the rays seen through the plane are every so many-th of them, about this many.
CROSS_POINTS = 4096
#: Regions are first compared on about this many of their points.
NEAR_SAMPLE = 64


def merge_occluded(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance, viewpoint: np.ndarray,
                   keep: float, spread: float, allows: Allows = None) -> tuple[np.ndarray, list]:
    """Merge coplanar regions that do not touch, where nothing is seen through their joint plane between them and
    the plane there is hidden, seen or out of view (see the module's docstring).

    search: (3, m) searched points, meters (less the graph's centre); region: (m,) their regions (-1: none),
    relabelled in place; found: each region's (normal (3,), offset) in those coordinates; tolerance: t, scalar or
    (m,) meters; viewpoint: (3,) the sensor in those coordinates. A pair is coplanar when the joint least-squares
    plane keeps ``keep`` of their points within t with an RMS residual at most ``spread`` times that of their own
    planes (the rules of the touching merge). Regions renumbered in order; the earlier one's number is kept."""
    k = len(found)
    if k < 2:
        return region, found
    normals = np.array([n for n, _ in found])
    close = np.abs(normals @ normals.T) >= OCCLUDED_COS
    if not np.triu(close, 1).any():
        return region, found
    rows, bounds = kernels.group_by_label(kernels.c_array(region, np.int64), k)
    members = [rows[bounds[j]:bounds[j + 1]] for j in range(k)]
    sizes = np.diff(bounds)
    pairs = [(i, j) for i, j in zip(*np.nonzero(np.triu(close, 1))) if sizes[i] >= 3 and sizes[j] >= 3]
    pairs.sort(key=lambda p: -(sizes[p[0]] + sizes[p[1]]))
    found = list(found)
    root = np.arange(k)
    view = None  # the elevations the sensor sees: only once a pair gets that far
    tried = 0
    for i, j in pairs:
        i, j = root[i], root[j]
        if i == j:
            continue
        i, j = min(i, j), max(i, j)
        if not (_near(search, members[j], found[i], tolerance) and _near(search, members[i], found[j], tolerance)):
            continue  # parallel, apart (a table over the floor)
        joint = np.sort(np.concatenate([members[i], members[j]]))
        plane = _coplanar(search, joint, members[i], members[j], found[i], found[j], tolerance, keep, spread, allows)
        if plane is None:
            continue
        tried += 1
        if tried > MAX_TRIES:
            break
        if view is None:
            view = _view(search, viewpoint)
        if _apart(search, joint, plane, tolerance, viewpoint, view):
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


def _view(search: np.ndarray, viewpoint: np.ndarray) -> tuple[float, float, np.ndarray]:
    """The elevations (low, high), radians about z at ``viewpoint`` (3,), of the points ``search`` (3, m), widened
    by VIEW_MARGIN_DEG, and every point's elevation, sorted (m,): the directions the sensor sees."""
    rays = search - viewpoint[:, None]
    elevation = np.sort(np.arctan2(rays[2], np.hypot(rays[0], rays[1])))
    margin = np.radians(VIEW_MARGIN_DEG)
    return float(elevation[0]) - margin, float(elevation[-1]) + margin, elevation


def _unseen(elevation: np.ndarray, reach: np.ndarray, view: tuple[float, float, np.ndarray]) -> np.ndarray:
    """(c,) whether no ray of the sensor points at cells of elevations ``elevation`` (c,) radians, each spanning
    ``reach`` (c,) radians either side: outside ``view``'s (low, high), or no point's elevation within the span (between
    two rings of a spinning lidar)."""
    low, high, rays = view
    first = np.searchsorted(rays, elevation - reach)
    hit = (first < len(rays)) & (rays[np.minimum(first, len(rays) - 1)] <= elevation + reach)
    return (elevation < low) | (elevation > high) | ~hit


def _near(search: np.ndarray, rows: np.ndarray, plane: tuple[np.ndarray, float], tolerance: Tolerance) -> bool:
    """Whether most of a region's points (``rows``, every so many-th: NEAR_SAMPLE to 2 NEAR_SAMPLE of them) lie
    within t of ``plane``."""
    some = rows[::max(1, len(rows) // NEAR_SAMPLE)]
    return _median_at_most_zero(np.abs(plane[0] @ search[:, some] + plane[1]) - tolerance_at(tolerance, some))


def _median_at_most_zero(values: np.ndarray) -> bool:
    """``np.median(values) <= 0`` for a 1-D array, as numpy computes the median (the mean of the middle two of an
    even count; NaN with a NaN), without its overhead (tens of microseconds, thousands of calls a sweep)."""
    n = len(values)
    if n == 0:
        return False
    ordered = np.sort(values)
    if np.isnan(ordered[-1]):  # NaN sorts last
        return False
    mid = n // 2
    middle = ordered[mid] if n % 2 else (ordered[mid - 1] + ordered[mid]) / 2
    return bool(middle <= 0)


def _coplanar(search: np.ndarray, joint: np.ndarray, rows_i: np.ndarray, rows_j: np.ndarray, plane_i, plane_j,
              tolerance: Tolerance, keep: float, spread: float, allows: Allows) -> tuple[np.ndarray, float] | None:
    """The joint plane of two regions' rows (``joint``, ascending, = ``rows_i`` with ``rows_j``) when it fits them as
    well as the touching merge asks, else None."""
    normal, offset = kernels.fit_members(search, joint)
    if not allows_normal(allows, normal):
        return None
    cols = search[:, joint]
    dist = np.abs(normal @ cols + offset)
    if np.count_nonzero(dist <= tolerance_at(tolerance, joint)) < keep * len(joint):
        return None
    own = np.concatenate([plane_i[0] @ search[:, rows_i] + plane_i[1], plane_j[0] @ search[:, rows_j] + plane_j[1]])
    if np.mean(dist ** 2) > spread ** 2 * np.mean(own ** 2):
        return None
    return normal, offset


def _apart(search: np.ndarray, joint: np.ndarray, plane: tuple[np.ndarray, float], tolerance: Tolerance,
           viewpoint: np.ndarray, view: tuple[float, float, np.ndarray]) -> bool:
    """Whether two coplanar regions (their rows ``joint``) stay apart: the sensor at ``viewpoint`` (3,) lies on their
    ``plane``; or, in the cells of the plane inside the convex hull of their points and clear of both (the gap), rays
    cross the plane in CROSS_CELLS cells or more, or less than EXPLAINED of the gap is hidden behind points before
    the plane, holds other points on it, or is out of view (:func:`_unseen`: no ray of ``view`` at its elevation about
    z at the sensor)."""
    normal, offset = plane
    side = float(normal @ viewpoint + offset)
    if abs(side) <= float(np.min(tolerance_at(tolerance, joint))):
        return True  # the sensor lies on the plane: nothing can be told
    e1 = np.cross(normal, np.eye(3)[int(np.argmin(np.abs(normal)))])
    e1 /= np.linalg.norm(e1)
    basis = np.stack([e1, np.cross(normal, e1)])  # (2, 3): in-plane axes
    uv = basis @ search[:, joint]  # (2, n)
    try:
        facets = ConvexHull(uv[:, ::max(1, uv.shape[1] // HULL_POINTS)].T).equations  # (f, 3): outward normal, offset
    except (QhullError, ValueError):  # the points lie on a line: no area between them to judge
        return True
    inside = facets[:, :2], facets[:, 2:]  # a point x is inside where inside[0] @ x + inside[1] <= 0
    dq = normal @ search + offset
    off = np.abs(dq) > CROSS_MARGIN * np.asarray(tolerance)
    off[joint] = False
    behind = off & (np.sign(dq) != np.sign(side))
    crossing = _meeting(search, dq, side, behind, viewpoint, basis, CROSS_POINTS)
    crossing = crossing[:, np.all(inside[0] @ crossing + inside[1] <= 0, axis=0)]
    lo, hi = uv.min(axis=1), uv.max(axis=1)
    extent = np.maximum(hi - lo, 1e-9)
    floor = float(np.sqrt(extent[0] * extent[1] / MAX_CELLS))
    cell = max(float(np.sqrt(extent[0] * extent[1] / len(joint))), floor)  # as if the points filled their box
    filled = len(np.unique(_cell_of(uv, lo, cell, _grid(extent, cell))))
    cell = max(cell * float(np.sqrt(CELL_POINTS * filled / len(joint))), floor)  # about CELL_POINTS a cell
    shape = _grid(extent, cell)
    full = np.ones((3, 3), bool)
    occupied = np.zeros(int(shape.prod()), bool)
    occupied[_cell_of(uv, lo, cell, shape)] = True
    from scipy.ndimage import binary_dilation  # here: scipy.ndimage takes about 0.1 s to import
    occupied = binary_dilation(occupied.reshape(shape), full).reshape(-1)
    if crossing.shape[1] >= CROSS_CELLS:
        crossed = np.unique(_cell_of(crossing, lo, cell, shape))
        if np.count_nonzero(~occupied[crossed]) >= CROSS_CELLS:
            return True
    centres = lo[:, None] + cell * (np.stack(np.divmod(np.arange(shape.prod()), shape[1])) - 0.5)  # cell 1 at lo
    gap = ~occupied
    gap[gap] = np.all(inside[0] @ centres[:, gap] + inside[1] <= 0, axis=0)
    if not gap.any():
        return False
    # the plane is there where rays to points before it would have met it (hidden) or other points lie on it; both
    # come as sparse as the sensor's rays (a lidar's rings), so each marks the cells next to it too
    known = np.zeros_like(gap)
    known[_cell_of(_meeting(search, dq, side, off & ~behind, viewpoint, basis), lo, cell, shape, keep=False)] = True
    on = np.abs(dq) <= CROSS_MARGIN * np.asarray(tolerance)
    on[joint] = False
    known[_cell_of(basis @ search[:, on], lo, cell, shape, keep=False)] = True
    known = binary_dilation(known.reshape(shape), full, iterations=EVIDENCE_REACH).reshape(-1)
    at = basis.T @ centres[:, gap] - (offset * normal)[:, None] - viewpoint[:, None]  # the gap's cells, from the sensor
    elevation = np.arctan2(at[2], np.hypot(at[0], at[1]))
    unseen = _unseen(elevation, 0.5 * cell / np.maximum(np.linalg.norm(at, axis=0), cell), view)
    return np.count_nonzero(known[gap] | unseen) < EXPLAINED * np.count_nonzero(gap)


def _meeting(search: np.ndarray, dq: np.ndarray, side: float, rows: np.ndarray, viewpoint: np.ndarray,
             basis: np.ndarray, most: int | None = None) -> np.ndarray:
    """In-plane points (2, r) where the rays from ``viewpoint`` through the points ``rows`` (bool (m,)) meet the
    plane (signed distances ``dq`` (m,) of the points, ``side`` of the sensor; in-plane axes ``basis`` (2, 3)); of
    every so many-th of them when more than ``most``."""
    rows = np.flatnonzero(rows)
    if most is not None:
        rows = rows[::max(1, len(rows) // most)]
    s = side / (side - dq[rows])  # the meeting point's share of the way from the sensor to the point
    return basis @ (viewpoint[:, None] + s * (search[:, rows] - viewpoint[:, None]))


def _grid(extent: np.ndarray, cell: float) -> np.ndarray:
    """Cells (2,) along each in-plane axis of a grid of side ``cell`` over ``extent`` (2,) meters, one spare each
    side."""
    return np.floor(extent / cell).astype(np.int64) + 3


def _cell_of(uv: np.ndarray, lo: np.ndarray, cell: float, shape: np.ndarray, keep: bool = True) -> np.ndarray:
    """Flat cell index of in-plane points ``uv`` (2, n) on a grid of ``shape`` cells of side ``cell`` from one cell
    before ``lo``: (n,), those outside on its border cells; without ``keep``, only of the points inside."""
    ij = np.floor((uv - lo[:, None]) / cell).astype(np.int64) + 1
    if not keep:
        ij = ij[:, np.all((ij >= 0) & (ij < shape[:, None]), axis=0)]
    ij = np.clip(ij, 0, shape[:, None] - 1)
    return ij[0] * shape[1] + ij[1]
