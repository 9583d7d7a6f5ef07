"""The connected-regions search (``connectivity=True``): sequential RANSAC over a neighbourhood, then each
region refitted, the borders between regions settled, touching regions of one surface merged (and coplanar ones
apart where the part between them is hidden, :mod:`.occluded`), regions holding a ridge split at it once, or a hip
roof's faces into them (:mod:`.folds`, :mod:`.tents`), groups of nearly parallel regions that cut across such a roof
in slabs replaced by its faces, the band along a shallow fold settled by side, and every valid
point labelled from the searched ones."""
from __future__ import annotations

import numpy as np

from .. import kernels
from ..noise import ray_share
from .checks import resolve_min_inliers
from .fit import allows_normal, canonical, fit_columns, plane_distances, plane_rows, refit_regions, tolerance_at
from .folds import settle_folds, split_folds, split_terraces
from .graph import SearchGraph, checked_search_graph, spread_nearest
from .grid import spread_grid
from .neighbours import NORMAL_MIN_COS, Neighbours
from .occluded import merge_occluded
from .sequential import sequential_search
from .types import Allows, Plane, Segmentation, Tolerance

__all__ = ['detect_regions', 'MERGE_KEEP', 'MERGE_SPREAD', 'GRAZING_DEG']

_NO_NORMALS = np.empty((0, 3))
#: A search stopped at max_planes whose regions then merged goes on over the points left, at most this many times
#: (28 indoor tuning seeds, auto-tuned: 130 -> 160 of 229 planes correct with 3).
RESUME_ROUNDS = 3


def detect_regions(pts: np.ndarray, finite: np.ndarray, tolerance: Tolerance, max_planes: int, min_inliers: int | float,
                   probability: float, max_iterations: int, rng: np.random.Generator,
                   ransac_points: int | None, shape: tuple[int, int] | None,
                   graph: SearchGraph | None, viewpoint: np.ndarray, grid_points: int | None,
                   allows: Allows = None, ray: np.ndarray = kernels.NO_RAY) -> Segmentation:
    """detect_planes with connected regions (see its docstring) on the checked points ``pts`` (N, 3) meters, whose
    finite rows are ``finite`` (N,); ``ray``: :func:`.noise.ray_band` (kernels.NO_RAY: the tolerance across each
    plane)."""
    n_valid = int(np.count_nonzero(finite))
    min_count = resolve_min_inliers(min_inliers, n_valid)
    graph = checked_search_graph(graph, pts, finite, shape, ransac_points, rng, viewpoint, grid_points)
    search_idx, step, center, neighbours = graph.search_idx, graph.step, graph.center, graph.neighbours
    search = kernels.columns_at(kernels.c_array(pts, np.float64), kernels.c_array(search_idx, np.int64),
                                kernels.c_array(center, np.float64))  # (3, m)
    search_min = max(3, int(np.ceil(min_count * len(search_idx) / max(n_valid, 1))))
    search_tolerance = tolerance_at(tolerance, search_idx)
    centred = _centred(ray, center)
    found, reason, region, capped = sequential_search(search, search_tolerance, max_planes, search_min, probability,
                                                      max_iterations, rng, n_total=n_valid, neighbours=neighbours,
                                                      allows=allows, ray=centred)
    if not found:
        return Segmentation(labels=np.full(len(pts), -1, dtype=np.int32), planes=(), tolerance=tolerance,
                            n_valid=n_valid, reason=reason)
    # each region's plane refitted on its own points, the borders settled by nearest plane, one surface's regions merged
    searched = len(found)
    region, found = _settled(search, region, found, search_tolerance, neighbours, viewpoint - center, allows,
                             centred)
    for _ in range(RESUME_ROUNDS):
        # the merges freed some of the max_planes: the search goes on over the points left, as a search that had not
        # spent them on pieces of one surface would have (a noisy far wall's pieces left a room's boxes unsearched)
        if not capped or len(found) >= max_planes:
            break
        more, more_reason, more_region, capped = sequential_search(
            search, search_tolerance, max_planes - len(found), search_min, probability, max_iterations, rng,
            n_total=n_valid, neighbours=neighbours, allows=allows, start=np.flatnonzero(region < 0), ray=centred)
        reason, searched = more_reason, searched + len(more)
        if not more:
            break
        region = np.where(more_region >= 0, more_region + len(found), region)
        region, found = _settled(search, region, found + more, search_tolerance, neighbours, viewpoint - center,
                                 allows, centred)
    if len(found) < searched:
        reason += f'; merged {searched - len(found)} region(s) into another region of the same surface'
    region, found, (ridges, tents) = split_folds(search, region, found, search_tolerance, max_planes, search_min,
                                                 allows)
    if ridges:
        reason += f'; split {ridges} region(s) at a ridge or fold into the two surfaces meeting there'
    if tents:
        reason += f'; split {tents} region(s) whose residuals form a tent into its faces'
    region, found, terraces = split_terraces(search, region, found, search_tolerance, max_planes, search_min, allows)
    if terraces:
        reason += f'; split {terraces} group(s) of regions cut across a fold or tent into its faces'
    region, found = settle_folds(search, region, found, search_tolerance, neighbours, allows)
    if step:
        uncentred = [(normal, offset - float(normal @ center)) for normal, offset in found]
        labels, rows, bounds, squares = spread_grid(pts, finite, shape, step, region, neighbours, uncentred, tolerance,
                                                    ray)
    elif len(search_idx) == n_valid:
        labels = np.full(len(pts), -1, dtype=np.int32)
        own = np.where(region >= 0, region, 0)
        normals = np.array([n for n, _ in found])
        offsets = np.array([d for _, d in found])
        near = np.abs(np.einsum('ji,ij->j', normals[own], search) + offsets[own]) <= search_tolerance
        labels[search_idx] = np.where((region >= 0) & near, region, -1)  # within t of the refitted plane
        rows, bounds, squares = _members(labels, len(found), None)
    else:
        valid_idx = np.flatnonzero(finite)
        nodes = graph.nearest.for_regions(region, pts, valid_idx, center)
        labels, residual = spread_nearest(pts, valid_idx, center, nodes, region, found,
                                          tolerance_at(tolerance, valid_idx))
        rows, bounds, squares = _members(labels, len(found), residual)
    counts = np.diff(bounds)
    kept = np.arange(len(found))
    small = np.flatnonzero(counts < min_count)
    if len(small):
        kept = np.flatnonzero(counts >= min_count)
        remap = np.full(len(found) + 1, -1, dtype=np.int32)
        remap[kept] = np.arange(len(kept))
        labels = remap[labels]  # -1 indexes the last entry, which is -1
        reason += (f'; dropped {len(small)} region(s) left with fewer than min_inliers={min_count} points '
                   'once every point was labelled')
    planes = []
    for j in kept:  # a kept region's rows (and squares) are those it had before the others were dropped
        normal, offset = found[j]
        members = rows[bounds[j]:bounds[j + 1]]
        square = squares[bounds[j]:bounds[j + 1]] if squares is not None else \
            ((pts[members] - center) @ normal + offset) ** 2
        normal, offset = canonical(normal, offset - float(normal @ center))
        planes.append(Plane(normal=normal, offset=offset, inliers=members,
                            rms=float(np.sqrt(np.mean(square))) if len(members) else 0.0))
    return Segmentation(labels=labels, planes=tuple(planes), tolerance=tolerance, n_valid=n_valid, reason=reason,
                        capped=capped)


def _centred(ray: np.ndarray, center: np.ndarray) -> np.ndarray:
    """The ``ray`` of :func:`.noise.ray_band` (4,) with its viewpoint in the coordinates of points less ``center``
    (3,); kernels.NO_RAY as is."""
    if len(ray) == 0:
        return ray
    return np.append(ray[:3] - center, ray[3])


def _members(labels: np.ndarray, k: int, residual: np.ndarray | None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The rows of each of the ``k`` regions of ``labels`` (N,), ascending, one after another, and where each
    starts (:func:`.kernels.group_by_label`); with the distances ``residual`` (N,) meters, also their squares in that
    order (:func:`.kernels.label_rows`), else None."""
    if residual is None:
        return kernels.group_by_label(labels, k) + (None,)
    return kernels.label_rows(labels, k, residual)


#: Two touching regions whose joint plane keeps at least this share of their points within t, with
#: an RMS residual at most MERGE_SPREAD times that of their own planes, are one surface (split by
#: the order of the search or by points whose local normals disagreed; a step or a ledge within t
#: of the joint plane fits it much worse than its own plane).
MERGE_KEEP = 0.95


MERGE_SPREAD = 1.5


def _settled(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance, neighbours: Neighbours,
             viewpoint: np.ndarray, allows: Allows, ray: np.ndarray = kernels.NO_RAY) -> tuple[np.ndarray, list]:
    """(region, found) of the searched points ``search`` (3, m) m after each region's plane is refitted on its own
    points, the borders settled by nearest plane (``viewpoint`` (3,) m, centred as ``search``) and the regions of
    one surface merged, touching or apart (:func:`_merge_coplanar`, :func:`.occluded.merge_occluded`)."""
    found = refit_regions(search, region, found, allows)
    region = _compete(search, region, found, tolerance, neighbours, viewpoint, ray)
    found = refit_regions(search, region, found, allows)
    region, found = _merge_coplanar(search, region, found, tolerance, neighbours, allows, ray)
    return merge_occluded(search, region, found, tolerance, viewpoint, MERGE_KEEP, MERGE_SPREAD, allows)


def _merge_coplanar(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance,
                    neighbours: Neighbours, allows: Allows = None, ray: np.ndarray = kernels.NO_RAY
                    ) -> tuple[np.ndarray, list]:
    """Merge touching regions of one surface: a pair of regions joined by a neighbour pair whose
    joint least-squares plane has MERGE_KEEP of their points (3, m) within ``tolerance`` becomes one
    region (the earlier one's number), with that plane. Regions renumbered in order. Each pair's points, fit and tests
    come from one compiled call (:func:`.kernels.merge_pair`; :func:`_merge_coplanar_numpy` is the reference)."""
    touching = neighbours.contacts(region, len(found))
    if touching is None:
        return region, found
    src, dst, a, b, pairs = touching
    k = len(found)
    root = np.arange(k)  # the region each region is now part of (a, b: the regions at src, dst before any merge)
    found = list(found)
    normals = _NO_NORMALS if neighbours.normals is None else kernels.c_array(neighbours.normals, np.float64)
    tol = kernels.c_array(np.reshape(tolerance, -1), np.float64)  # (1,) or (m,)
    src, dst = kernels.c_array(src, np.int64), kernels.c_array(dst, np.int64)
    a, b = kernels.c_array(a, np.int64), kernels.c_array(b, np.int64)
    cols = kernels.c_array(search, np.float64)
    region = kernels.c_array(region, np.int64)
    for i, j in zip(*np.divmod(pairs, k)):
        i, j = root[i], root[j]
        if i == j:
            continue
        i, j = int(min(i, j)), int(max(i, j))
        own = plane_rows([found[i], found[j]])
        # one call finds their points, fits them and tests the fit; with an orientation constraint, the test waits
        # for it
        same, normal, offset, members = kernels.merge_pair(cols, region, i, j, own, tol, src, dst, a, b, root, normals,
                                                           NORMAL_MIN_COS, MERGE_KEEP, MERGE_SPREAD, allows is None,
                                                           ray)
        if allows is not None:
            if not allows_normal(allows, normal):
                continue  # their joint plane leaves the orientation constraint
            same = kernels.merge_test(cols, members, region, i, j, plane_rows([(normal, offset)])[0], own, tol, src,
                                      dst, a, b, root, normals, NORMAL_MIN_COS, MERGE_KEEP, MERGE_SPREAD, ray)
        if not same:
            continue
        region[members] = i
        root[root == j] = i
        found[i] = (normal, offset)
    return _renumbered(region, found, root)


def _renumbered(region: np.ndarray, found: list, root: np.ndarray) -> tuple[np.ndarray, list]:
    """The regions (m,) and planes after merges (``root`` (k,): the region each is now part of), numbered 0.. in
    order."""
    keep = np.unique(root)
    if len(keep) == len(found):
        return region, found
    renumber = np.full(len(found) + 1, -1, dtype=np.int64)
    renumber[keep] = np.arange(len(keep))
    return renumber[region], [found[j] for j in keep]


def _merge_coplanar_numpy(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance,
                          neighbours: Neighbours, allows: Allows = None, ray: np.ndarray = kernels.NO_RAY
                          ) -> tuple[np.ndarray, list]:
    """Merge touching regions of one surface: a pair of regions joined by a neighbour pair whose
    joint least-squares plane has MERGE_KEEP of their points (3, m) within ``tolerance`` becomes one
    region (the earlier one's number), with that plane. Regions renumbered in order. The reference of
    :func:`_merge_coplanar` (its tests in numpy)."""
    touching = Neighbours.contacts(neighbours, region, len(found))  # the numpy form
    if touching is None:
        return region, found
    src, dst, a, b, pairs = touching
    k = len(found)
    root = np.arange(k)
    found = list(found)
    # the points of each region, ascending, kept up to date as regions merge (as are a, b: the regions at src, dst)
    order = np.argsort(region, kind='stable')
    bounds = np.searchsorted(region[order], np.arange(k + 1))
    points_of = [order[bounds[r]:bounds[r + 1]] for r in range(k)]
    for i, j in zip(*np.divmod(pairs, k)):
        i, j = root[i], root[j]
        if i == j:
            continue
        i, j = min(i, j), max(i, j)
        members = np.sort(np.concatenate([points_of[i], points_of[j]]), kind='stable')  # two sorted runs: merged
        cols = search[:, members]
        normal, offset = fit_columns(cols.copy())
        if not allows_normal(allows, normal):
            continue  # their joint plane leaves the orientation constraint
        contact = (a == i) & (b == j) | (a == j) & (b == i)
        if not (neighbours.coherent(normal, src[contact]) & neighbours.coherent(normal, dst[contact])).any():
            continue  # they touch where normals disagree only
        joint = plane_distances(cols, normal[None, :], np.array([offset]))[0]
        on_i = region[members] == i
        own = np.where(on_i, found[i][0] @ cols + found[i][1], found[j][0] @ cols + found[j][1])
        near = joint <= tolerance_at(tolerance, members) * ray_share(cols.T, normal[None, :], ray)[0]
        if len(ray) and not (np.count_nonzero(near[on_i]) >= MERGE_KEEP * np.count_nonzero(on_i) and
                             np.count_nonzero(near[~on_i]) >= MERGE_KEEP * np.count_nonzero(~on_i)):
            continue  # along the rays, each region's own points must lie on the joint plane
        if np.count_nonzero(near) >= MERGE_KEEP * cols.shape[1] and \
                np.mean(joint ** 2) <= MERGE_SPREAD ** 2 * np.mean(own ** 2):
            region[points_of[j]] = i
            points_of[i], points_of[j] = members, members[:0]
            a[a == j], b[b == j] = i, i
            root[root == j] = i
            found[i] = (normal, offset)
    keep = np.unique(root)
    if len(keep) == len(found):
        return region, found
    renumber = np.full(len(found) + 1, -1, dtype=np.int64)
    renumber[keep] = np.arange(len(keep))
    return renumber[region], [found[j] for j in keep]


#: Border settling compares planes by the distance along each point's viewing ray (a range sensor's
#: noise lies along the ray, so a wall's point near a corner is nearer in meters to the other face,
#: seen at a grazing angle, but not along its ray); a ray farther than this from a plane's normal
#: counts as this far (degrees), so that the planes a ray nearly grazes still compete.
GRAZING_DEG = 75.0


def _compete(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance,
             neighbours: Neighbours, viewpoint: np.ndarray, ray: np.ndarray = kernels.NO_RAY) -> np.ndarray:
    """Settle the borders between regions: each searched point (3, m) takes, of its own region and
    its neighbours' regions (8 image neighbours, or graph neighbours), the one whose plane within
    ``tolerance`` its ray from ``viewpoint`` (3,) meets nearest (see GRAZING_DEG), so a strip that
    an earlier plane took along an edge goes back to the surface it lies on, and unassigned points
    next to a region join it when they fit its plane; repeated COMPETE_ROUNDS times. Only points next
    to another region can change, and after the first round only the neighbours of points that
    changed: only they are looked at (:meth:`.neighbours.Neighbours.settle`). The distances come from one compiled
    pass (:func:`.kernels.compete_distances`; :func:`_compete_distances_numpy` is its reference)."""
    planes = plane_rows(found)
    tol = kernels.c_array(np.reshape(tolerance, -1), np.float64)  # (1,) or (m,)
    return neighbours.settle_planes(kernels.c_array(search, np.float64), planes, tol,
                                    kernels.c_array(viewpoint, np.float64), float(np.cos(np.radians(GRAZING_DEG))),
                                    np.where(region >= 0, region, len(found)), ray)


def _compete_distances_numpy(search: np.ndarray, found: list, tolerance: Tolerance, viewpoint: np.ndarray
                             ) -> np.ndarray:
    """:func:`.kernels.compete_distances` in numpy: (k + 1, m) each point's distance to each region's plane along
    its ray, inf beyond ``tolerance`` and in row k (no region)."""
    k, m = len(found), search.shape[1]
    normals = np.array([n for n, _ in found])
    dist = np.empty((k + 1, m))
    dist[:k] = plane_distances(search, normals, np.array([d for _, d in found]))
    dist[k] = np.inf
    dist[dist > tolerance] = np.inf  # only planes within t can be taken
    rays = search - viewpoint[:, None]
    with np.errstate(invalid='ignore', divide='ignore'):  # a point at the viewpoint: NaN, never nearer
        rays /= np.linalg.norm(rays, axis=0)
        dist[:k] /= np.maximum(np.abs(normals @ rays), np.cos(np.radians(GRAZING_DEG)))
    return dist
