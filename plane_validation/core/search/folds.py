"""Regions that hold the two sides of a shallow ridge or fold, split at its line; the faces of a shallow hip roof
(:mod:`.tents`); and the points near such a line settled on its sides.

Two surfaces meeting at a shallow angle (a gable roof of a few degrees, a ramp meeting a floor) can lie within t of
one plane and join one connected region, whose residuals across the line then form a V. A region whose lack of fit
is FOLD_LACK or more and that two planes meeting at a line bring down to FOLD_FIT, better than a quadric surface
(the verdict's ridge test, :func:`.plane_shape.is_ridge`, without its upper bound: a larger lack of fit, which the
verdict fails as surfaces merged, is split too), is split at that line: each side gets a plane, each of the region's
points goes to the nearer of the two, and both planes are refitted. A region that reads better as a tent than as one
fold is split into the tent's faces instead (:func:`.tents.tent_faces`).

At t of a few noise sigmas a shallow roof can instead be found as level slabs, each cutting across its faces at one
height: :func:`split_terraces` judges such a group of nearly parallel regions as one region, and replaces it by the
faces or sides the same tests find.

Near a shallow fold found as two regions, both planes lie within t of the points of a band along the line, where
the nearer plane is the one the noise favours: :func:`settle_folds` gives each such point to the face on its side.
"""
from __future__ import annotations

import numpy as np

from .. import kernels
from .fit import allows_normal, fit_columns, plane_distances, plane_rows, tolerance_at
from .neighbours import NORMAL_MIN_COS, Neighbours
from .tents import tent_faces
from .types import Allows, Tolerance

__all__ = ['split_folds', 'split_terraces', 'settle_folds', 'FOLD_SIDE', 'TERRACE_ANGLE_DEG', 'TERRACE_STEP',
           'TERRACE_SAME']

#: A region is split only where each side holds at least this share of its points (a fold near the region's edge is
#: a lip or a bent border, not a second surface).
FOLD_SIDE = 0.15


def split_folds(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance, max_planes: int,
                min_count: int, allows: Allows = None) -> tuple[np.ndarray, list, tuple[int, int]]:
    """``region`` (m,) (-1: none) and ``found`` (normal, offset) planes of the centred points ``search`` (3, m)
    meters, with each region that holds a ridge split once in two, or that holds a tent into its faces (the new planes
    numbered last), while there are fewer than ``max_planes`` and each side or face keeps ``min_count`` searched
    points. ``tolerance``: t (m) at each searched point (m,) or for all; its median over a region sets the floor of the
    noise the ridge and tent tests measure (:func:`.plane_shape.patch_noise`). ``allows``: the normals a plane may have
    (None: any). Returns the new region labels and planes, and how many regions were split (at a ridge, into a tent's
    faces); the inputs are left as they were."""
    region, found = region.copy(), list(found)
    ridges = tents = 0
    for j in range(len(found)):
        if len(found) >= max_planes:
            break
        members = np.flatnonzero(region == j)
        if len(members) < _judged(min_count):
            continue
        rows = _within(search, members, [found[j]], region, tolerance)
        tol = float(np.median(tolerance_at(tolerance, rows))) if len(rows) else 0.0
        shape = _region_shape(search, rows, tol, min_count)
        if shape is None:
            continue
        faces = _tent_split(shape, min_count, allows, max_planes - len(found) + 1)
        if faces is not None:
            face, planes = faces
            labels = [j] + list(range(len(found), len(found) + len(planes) - 1))
            found[j] = planes[0]
            for k in range(1, len(planes)):
                region[rows[face == k]] = len(found)
                found.append(planes[k])
            _to_nearest(search, region, np.setdiff1d(members, rows), labels, planes)
            tents += 1
            continue
        halves = _fold_halves(shape, rows, min_count, allows)
        if halves is not None:
            (_, plane), (move, other) = halves
            region[move] = len(found)
            found[j] = plane
            found.append(other)
            _to_nearest(search, region, np.setdiff1d(members, rows), [j, len(found) - 1], [plane, other])
            ridges += 1
    return region, found, (ridges, tents)


#: Regions whose normals lie within this angle of each other (degrees) ...
TERRACE_ANGLE_DEG = 10.0
#: ... and where one's points' mean lies within this many t of the other's plane are terraces of one surface group (see
#: :func:`split_terraces`): at t of 2-3 noise sigmas, horizontal slabs 2 t thick, each cutting across every face of a
#: shallow hip roof at its own height, hold more points than any face (tuning seeds aerial_roof 18, 31, 64, 70: up to
#: four such slabs, about 2 t apart).
TERRACE_STEP = 3.0
#: A group's split leaves its regions as they were where each face shares at least this share of its points with one
#: region and that region this share of its points with the face (Hoover's overlap): the split found the regions again.
TERRACE_SAME = 0.8


def split_terraces(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance, max_planes: int,
                   min_count: int, allows: Allows = None) -> tuple[np.ndarray, list, int]:
    """``region`` (m,) (-1: none) and ``found`` (normal, offset) planes of the centred points ``search`` (3, m)
    meters, with each group of terraces (regions of nearly parallel planes, TERRACE_ANGLE_DEG, one's mean within
    TERRACE_STEP t of the other's plane, chained) whose joint points read as a tent or a ridge (the tests of
    :func:`split_folds`) replaced by the tent's faces or the ridge's two sides, unless those are the regions again
    (TERRACE_SAME). A shallow roof cut into slabs across its faces comes back as its faces. ``tolerance``: t (m) at
    each searched point (m,) or for all; ``max_planes``, ``min_count``, ``allows`` as for :func:`split_folds`.
    Returns the new region labels and planes (renumbered: the groups' regions replaced by their faces, numbered
    last) and how many groups were split; the inputs are left as they were."""
    k = len(found)
    if k < 2:
        return region, found, 0
    groups = _terrace_groups(search, region, found, tolerance, _judged(min_count))
    if not groups:
        return region, found, 0
    region, found = region.copy(), list(found)
    gone: list[int] = []
    split = 0
    for group in groups:
        members = np.flatnonzero(np.isin(region, group))
        rows = _within(search, members, found, region, tolerance)
        tol = float(np.median(tolerance_at(tolerance, rows))) if len(rows) else 0.0
        if not _bent(search, rows, found, region, tol):
            continue
        shape = _region_shape(search, rows, tol, min_count)
        if shape is None:
            continue
        room = max_planes - len(found) + len(gone) + len(group)
        faces = _tent_split(shape, min_count, allows, room)
        if faces is None:
            halves = _fold_halves(shape, rows, min_count, allows) if room >= 2 else None
            if halves is None:
                continue
            (first, plane), (second, other) = halves
            face = np.isin(rows, second).astype(np.int64)
            faces = face, [plane, other]
        face, planes = faces
        if _same_regions(region[rows], face, group, len(planes)):
            continue
        region[rows] = face + len(found)
        _to_nearest(search, region, np.setdiff1d(members, rows), range(len(found), len(found) + len(planes)), planes)
        found += planes
        gone += group
        split += 1
    if not split:
        return region, found, 0
    keep = np.setdiff1d(np.arange(len(found)), gone)
    renumber = np.full(len(found) + 1, -1, dtype=np.int64)
    renumber[keep] = np.arange(len(keep))
    return renumber[region], [found[j] for j in keep], split


def _bent(search: np.ndarray, rows: np.ndarray, found: list, region: np.ndarray, tolerance: float) -> bool:
    """Whether the points ``rows`` of a group of regions (``region`` (m,) numbers the ``found`` planes) of
    ``search`` (3, m) fit one plane through them all FOLD_FIT times worse (RMS) than their own regions' planes or
    more, which the ridge and tent tests need (their lack of fit FOLD_FIT or more against a noise their own planes
    match), and within TERRACE_STEP t (``tolerance``, m) RMS of it, as slabs 2 t thick across one shallow roof lie:
    a cheap test before theirs. Pieces of one surface apart (a lidar's floor beyond an obstacle) fail the first; the
    table tops, shelves and floor of a room, chained into one group by their steps, the second."""
    from .. import plane_shape
    if len(rows) < 3:
        return False
    own = float(np.mean(_distances(search, rows, found, region) ** 2))
    cols = np.ascontiguousarray(search[:, rows])
    normal, offset = fit_columns(cols)
    joint = float(np.mean((normal @ cols + offset) ** 2))
    return plane_shape.FOLD_FIT ** 2 * own <= joint <= (TERRACE_STEP * tolerance) ** 2


def _terrace_groups(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance, least: int
                    ) -> list[list[int]]:
    """The groups (two regions or more, each a list of region numbers) of terraces among the ``found`` planes of the
    regions ``region`` (m,) of ``search`` (3, m) (see :func:`split_terraces`), each region of ``least`` points or more:
    a smaller one is too small to judge as a surface (a clutter blob above a roof, whose points would raise the
    group's noise and fail its tests)."""
    k = len(found)
    normals = np.array([normal for normal, _ in found]).reshape(k, 3)
    offsets = np.array([offset for _, offset in found])
    parallel = np.abs(normals @ normals.T) >= np.cos(np.radians(TERRACE_ANGLE_DEG))
    np.fill_diagonal(parallel, False)
    if not parallel.any():
        return []
    counts = np.bincount(region[region >= 0], minlength=k)
    # the means and t on about FOLD_SAMPLE points (every so many-th): the test is coarse, and most frames have none
    stride = max(1, len(region) // FOLD_SAMPLE)
    sample = region[::stride]
    labelled = sample >= 0
    label = sample[labelled]
    weights = [search[axis, ::stride][labelled] for axis in range(3)] + \
        ([tolerance[::stride][labelled]] if np.ndim(tolerance) else [])
    sums = np.stack([np.bincount(label, weights=w, minlength=k) for w in weights], axis=1)
    sampled = np.bincount(label, minlength=k)
    sums /= np.maximum(sampled, 1)[:, None]
    means = sums[:, :3]  # (k, 3)
    tol = sums[:, 3] if np.ndim(tolerance) else np.full(k, float(tolerance))  # each region's mean t
    counts = np.where(sampled > 0, counts, 0)  # a region the sample missed is not judged
    # [i, j]: how far region j's mean lies from plane i, in the larger of the two regions' t
    apart = np.abs(normals @ means.T + offsets[:, None]) / np.maximum(np.maximum.outer(tol, tol), 1e-12)
    near = parallel & (np.minimum(apart, apart.T) <= TERRACE_STEP) & (counts[:, None] >= least) & (counts >= least)
    root = np.arange(k)
    for i, j in zip(*np.nonzero(np.triu(near, 1))):
        a, b = _root(root, i), _root(root, j)
        root[max(a, b)] = min(a, b)
    roots = np.array([_root(root, j) for j in range(k)])
    return [list(np.flatnonzero(roots == r)) for r in np.unique(roots) if np.count_nonzero(roots == r) > 1]


def _root(root: np.ndarray, j: int) -> int:
    """The root of ``j`` in the union-find ``root`` (k,)."""
    while root[j] != j:
        j = root[j]
    return int(j)


def _same_regions(old: np.ndarray, face: np.ndarray, group: list[int], faces: int) -> bool:
    """Whether the ``faces`` faces ``face`` (r,) of a group's points are its regions ``group`` again: each face
    matched one to one to a region of ``old`` (r,) that shares TERRACE_SAME of both's points."""
    if faces != len(group):
        return False
    counts = np.array([[np.count_nonzero((face == f) & (old == g)) for g in group] for f in range(faces)], float)
    ok = (counts >= TERRACE_SAME * counts.sum(axis=1, keepdims=True)) & \
        (counts >= TERRACE_SAME * counts.sum(axis=0, keepdims=True))
    return bool(np.all(ok.any(axis=1)) and np.all(ok.any(axis=0)))


def _region_shape(search: np.ndarray, rows: np.ndarray, tolerance: float, min_count: int) -> tuple | None:
    """What the ridge and tent tests need of the region of ``rows`` (r,) of ``search`` (3, m) at its t ``tolerance``
    (m): (its points (3, r), its sample's :func:`.plane_shape.principal_frame`, the patches' noise (m^2), its lack of
    fit, t); None where it is too small to judge or its noise unknown."""
    if len(rows) < _judged(min_count):
        return None
    from .. import plane_shape  # it imports ransac, which imports the search: with the module, a cycle
    cols = search[:, rows]
    pca = plane_shape.principal_frame(np.ascontiguousarray(cols.T[plane_shape.sample_rows(np.arange(len(rows)))]))
    local = plane_shape.patch_noise(pca, tolerance)
    if local is None:
        return None
    return cols, pca, local, plane_shape.lack_from_noise(pca, local), tolerance


def _within(search: np.ndarray, rows: np.ndarray, found: list, region: np.ndarray, tolerance: Tolerance
            ) -> np.ndarray:
    """Those of ``rows`` (r,) of ``search`` (3, m) within t (``tolerance``) of their region's plane (``region`` (m,)
    numbers ``found``; a single plane: theirs): the points the region keeps once labelled. A region's search took in
    the points within t of its first plane, and clutter among them (a blob above a roof) raised the noise the tests
    measure. The points beyond go to the nearest of the planes the region is split into (:func:`_to_nearest`)."""
    return rows[_distances(search, rows, found, region) <= tolerance_at(tolerance, rows)]


def _distances(search: np.ndarray, rows: np.ndarray, found: list, region: np.ndarray) -> np.ndarray:
    """(r,) distances (m) of ``rows`` of ``search`` (3, m) to their region's plane (see :func:`_within`)."""
    if len(found) == 1:
        normal, offset = found[0]
        return np.abs(normal @ search[:, rows] + offset)
    planes = plane_rows(found)[region[rows]]  # (r, 4)
    return np.abs(np.einsum('ij,ji->i', planes[:, :3], search[:, rows]) + planes[:, 3])


def _to_nearest(search: np.ndarray, region: np.ndarray, rows: np.ndarray, labels, planes: list) -> None:
    """``region`` (m,) with each of ``rows`` (indices into ``search`` (3, m)) given the label (of ``labels``) of the
    nearest of ``planes`` (normal, offset): the points of a split region the tests did not judge (:func:`_within`)."""
    if len(rows):
        rows_of = plane_rows(planes)
        distance = plane_distances(search[:, rows], rows_of[:, :3], rows_of[:, 3])
        region[rows] = np.asarray(list(labels))[np.argmin(distance, axis=0)]


def _judged(min_count: int) -> int:
    """The fewest points a region of ``min_count`` searched points at least is judged on (:func:`_region_shape`)."""
    from .. import plane_shape
    return max(2 * min_count, 2 * plane_shape.TILT_NEIGHBOURS)


def _tent_split(shape: tuple, min_count: int, allows: Allows, room: int) -> tuple[np.ndarray, list] | None:
    """The faces (:func:`.tents.tent_faces`) of a region of :func:`_region_shape` ``shape`` where it reads as a tent
    (the verdict's tent test, but from a lack of fit of FOLD_FIT, the fit the faces must reach, rather than TENT_LACK:
    the tent FOLD_FIT or less and better than a quadric) that fits better than one fold, each of ``min_count``
    points, at most ``room`` of them; else None. The lower bound takes the part of a 2-degree hip roof with 4.5 cm
    noise that RANSAC finds at 8 cm (tuning seed aerial_roof 14: lack of fit 1.14; the faces at 19 cm: 0 -> 4 of 4
    planes correct auto-tuned)."""
    from .. import plane_shape
    cols, pca, local, lack, tolerance = shape
    if not lack >= plane_shape.FOLD_FIT or room < 2:
        return None
    tent, quadric = plane_shape.tent_of(pca, local, ridge_only=True)
    if not (tent <= plane_shape.FOLD_FIT and tent < quadric):
        return None
    if plane_shape.fold_line(pca, tolerance, local, ridge_only=True)[0] <= tent:
        return None
    faces = tent_faces(cols, pca, local, max(min_count, 3), allows)
    return faces if faces is not None and len(faces[1]) <= room else None


def _fold_halves(shape: tuple, rows: np.ndarray, min_count: int, allows: Allows):
    """The two sides of the region of ``rows`` (r,) (its :func:`_region_shape` ``shape``) at its best fold, each as
    (its rows (a,), its (normal, offset) plane), or None where the region holds no ridge (see the module), a side
    would keep fewer than ``min_count`` points or FOLD_SIDE of the region's, or ``allows`` refuses a side's normal."""
    from .. import plane_shape
    cols, pca, local, lack, tolerance = shape
    if not lack >= plane_shape.FOLD_LACK:  # NaN: not judged
        return None
    fold, quadric, theta, s0 = plane_shape.fold_line(pca, tolerance, local, ridge_only=True)
    if not plane_shape.is_ridge(lack, fold, quadric):
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


#: Two touching regions are the two faces of one fold when at least this share of each one's points lies on its own side
#: of the plane through the line where their planes meet (see :func:`settle_folds`; chance gives about half). On the
#: tuning roofs (aerial_roof 0-99) the faces of shallow gables found by RANSAC read 0.88-0.99 before their band is
#: settled.
FOLD_SEPARATE = 0.75
#: ... and when at most this share of each one's points lies within t of the other's plane: two pieces of one surface
#: lie within t of each other's planes, the two faces of a fold part beyond t over most of them.
FOLD_BAND = 0.5
#: Rounds of settle_folds (each pair's band moved and both planes refitted, then the pairs again): the refitted planes
#: move the line, and the band with it; on the tuning roofs the moves stop after two.
FOLD_ROUNDS = 3


def settle_folds(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance, neighbours: Neighbours,
                 allows: Allows = None) -> tuple[np.ndarray, list]:
    """``region`` (m,) (-1: none) and ``found`` (normal, offset) planes of the centred points ``search`` (3, m)
    meters after each point near a shallow fold between two touching regions goes to the face on its side.

    Near a fold of angle a, both planes lie within t of the points of a band 2 t / sin(a) wide, and the nearer plane
    there is the one the noise favours. The face a point lies on is the one whose plane is farther on the point's
    outer side: the lower envelope of a ridge's two faces, the upper of a valley's. Noise moves a point across both
    planes alike where their normals are close, so which face that is does not depend on it. A pair of regions whose
    normals lie within NORMAL_ANGLE_DEG of each other (steeper folds have a band about t wide, which border settling
    handles), each holding FOLD_SIDE of their points, is a fold when each keeps FOLD_SEPARATE of its points on its own
    side of the line and at most FOLD_BAND of them within ``tolerance`` (m, one or (m,)) of the other's plane (judged
    first on about FOLD_SAMPLE points, then on all); then each point of either within t of the other's plane, on the
    other's side and beside the part of the line where they touch (``neighbours``) goes to the other, and both planes
    are refitted (kept where ``allows`` refuses a normal), FOLD_ROUNDS times. The inputs are left as they were."""
    region, found = region.copy(), list(found)
    folds = _fold_pairs(search, region, found, tolerance)
    if not len(folds):
        return region, found  # (most frames: walls, floors and table tops; no neighbours looked up)
    for _ in range(FOLD_ROUNDS):
        touching = neighbours.contacts(region, len(found))
        if touching is None:
            break
        src, dst, at_src, at_dst, pairs = touching
        rows, bounds = kernels.group_by_label(kernels.c_array(region, np.int64), len(found))
        members = [rows[bounds[j]:bounds[j + 1]] for j in range(len(found))]  # kept up to date as points move
        moved = False
        for i, j in zip(*np.divmod(np.intersect1d(pairs, folds), len(found))):
            a, b = members[i], members[j]
            touch = (at_src == i) & (at_dst == j) | (at_src == j) & (at_dst == i)
            moves = _fold_moves(search, a, b, found[i], found[j], tolerance, np.concatenate([src[touch], dst[touch]]))
            if moves is None:
                continue
            to_b, to_a = moves
            a, b = np.union1d(np.setdiff1d(a, to_b), to_a), np.union1d(np.setdiff1d(b, to_a), to_b)
            fits = [fit_columns(np.ascontiguousarray(search[:, part])) for part in (a, b)]
            if not all(allows_normal(allows, normal) for normal, _ in fits):
                continue
            region[to_b], region[to_a] = j, i
            members[i], members[j] = a, b
            found[i], found[j] = fits
            moved = True
        if not moved:
            break
    return region, found


#: settle_folds first judges the pairs of regions on about this many of the searched points (every so many-th), and
#: looks up which touch only where a pair reads as a fold there (a depth frame's 30,000 sub-grid points: every 14th).
FOLD_SAMPLE = 2048


def _fold_pairs(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance) -> np.ndarray:
    """The pairs i < j (as i * k + j, ascending) of the k ``found`` planes of the regions ``region`` (m,) of ``search``
    (3, m) that read as the two faces of a fold (:func:`_fold_sides`) on about FOLD_SAMPLE of the points. Each region's
    mean must lie on the same side of the other's plane first (both under it: a ridge; over it: a valley; a step
    between parallel surfaces has one over, the other under), which most pairs fail."""
    k = len(found)
    normals = np.array([normal for normal, _ in found]).reshape(k, 3)
    cosines = normals @ normals.T
    shallow = np.triu(np.abs(cosines) >= NORMAL_MIN_COS, 1)
    if not shallow.any():
        return np.flatnonzero(shallow)
    stride = max(1, len(region) // FOLD_SAMPLE)
    label, cols = region[::stride], search[:, ::stride]
    members = (label == np.arange(k)[:, None]).astype(np.float64)  # (k, s)
    # [i, j]: how far region j's sampled points lie over plane i, summed
    over = (normals @ cols + np.array([offset for _, offset in found])[:, None]) @ members.T
    shallow &= np.sign(cosines) * over * over.T > 0
    if not shallow.any():
        return np.flatnonzero(shallow)
    members = members.astype(bool)
    tol = tolerance_at(tolerance, slice(None, None, stride))
    return np.array([i * k + j for i, j in zip(*np.nonzero(shallow))
                     if _fold_sides(cols, np.flatnonzero(members[i]), np.flatnonzero(members[j]), found[i], found[j],
                                    tol) is not None], dtype=np.int64)


def _fold_sides(cols: np.ndarray, a: np.ndarray, b: np.ndarray, plane_a: tuple, plane_b: tuple, tolerance: Tolerance
                ) -> tuple | None:
    """Whether the points ``a`` and ``b`` (indices into ``cols`` (3, n) meters) with planes ``plane_a``, ``plane_b``
    (normal, offset) are the two faces of a fold (see :func:`settle_folds`; ``tolerance``: t, one or (n,)): (the
    points of a, then b, (len(a) + len(b),) bool, on their own side; within t of a's plane; of b's), else None."""
    if min(len(a), len(b)) < max(3, FOLD_SIDE * (len(a) + len(b))):
        return None
    (na, oa), (nb, ob) = plane_a, plane_b
    if na @ nb < 0:
        nb, ob = -nb, -ob
    if na @ nb < NORMAL_MIN_COS:
        return None
    both = np.concatenate([a, b])
    pts = cols[:, both]
    da, db = na @ pts + oa, nb @ pts + ob
    side = da > db  # a's side of the line: where a's plane lies farther, or nearer, on the points' side
    if np.count_nonzero(side[:len(a)]) < len(a) / 2:
        side = ~side
    side[len(a):] = ~side[len(a):]
    if np.mean(side[:len(a)]) < FOLD_SEPARATE or np.mean(side[len(a):]) < FOLD_SEPARATE:
        return None
    tol = tolerance_at(tolerance, both)
    near_a, near_b = np.abs(da) <= tol, np.abs(db) <= tol
    if np.mean(near_b[:len(a)]) > FOLD_BAND or np.mean(near_a[len(a):]) > FOLD_BAND:
        return None
    return side, near_a, near_b


def _fold_moves(search: np.ndarray, a: np.ndarray, b: np.ndarray, plane_a: tuple, plane_b: tuple,
                tolerance: Tolerance, contact: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(the points of ``a`` (indices into ``search`` (3, m)) that go to b, those of ``b`` that go to a) where the two
    regions with planes ``plane_a``, ``plane_b`` (normal, offset) are the faces of a fold (see :func:`settle_folds`;
    ``contact``: their points where they touch), else None."""
    sides = _fold_sides(search, a, b, plane_a, plane_b, tolerance)
    if sides is None:
        return None
    own, near_a, near_b = sides
    line = np.cross(plane_a[0], plane_b[0])
    along, reach = line @ search[:, np.concatenate([a, b])], line @ search[:, contact]
    beside = (along >= reach.min()) & (along <= reach.max())
    moves = (a[~own[:len(a)] & near_b[:len(a)] & beside[:len(a)]], b[~own[len(a):] & near_a[len(a):] & beside[len(a):]])
    return moves if len(moves[0]) or len(moves[1]) else None
