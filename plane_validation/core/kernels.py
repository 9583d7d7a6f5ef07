"""Every compiled (numba) kernel of the package, and nothing else.

Each kernel is a loop over arrays that numpy would do in several full passes; each has a plain-numpy
reference in the module that calls it, and ``test/test_kernels.py`` checks the two agree on random
inputs. Kernels see only checked input: the checks stay in the public functions.

Compiled code is cached on disk (``cache=True``): in ``__pycache__`` beside this file when that is
writable, else in numba's user-wide cache (``~/.cache/numba``, or ``$NUMBA_CACHE_DIR`` when set), so
an apt or colcon install on a read-only prefix still keeps its compiled kernels. :func:`warm` compiles
or loads them all; the node calls it before it answers its first frame.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numba
import numpy as np

__all__ = ['EIGHT', 'c_array', 'group_by_label', 'centroids_and_extremes', 'grid_components',
           'grid_region', 'graph_components', 'graph_region', 'finite_mask',
           'coordinate_bounds', 'voxel_grid', 'voxel_knn', 'voxel_knn_points', 'brute_knn', 'principal_axes',
           'patch_fits',
           'pair_graph', 'widen_xyz', 'valid_rows', 'frame_pass', 'plane_patches', 'fold_line',
           'grid_sample', 'grid_edges', 'grid_usable', 'grid_normals', 'grid_chords', 'merge_test',
           'compete_distances', 'plane_bands', 'band_counts', 'triple_planes',
           'coherent_inliers', 'largest_magnitude', 'label_census', 'rows_at_ranks', 'cluster_distance_pass',
           'region_scatter', 'region_extents', 'plane_silhouette_sum', 'marked_rows', 'near_count', 'beyond_counts',
           'beyond_rows',
           'distinct_rows', 'coordinate_extent', 'silhouettes', 'patch_eigenvalues', 'voxel_nearest',
           'spread_nearest', 'spread_among', 'sensor_rays', 'score_hypotheses', 'spread_test', 'fit_members',
           'fit_mask',
           'fit_regions', 'plane_samples', 'sorted_order', 'order_statistics',
           'finite_extent', 'grid_contacts', 'label_rows', 'grid_triples', 'read_rows', 'outside_polygon',
           'voxel_nodes',
           'uncertain_nodes', 'first_across', 'grid_plane', 'grid_refit', 'grid_settle', 'merge_pair', 'relabel_rows',
           'labels_where', 'graph_triples',
           'grid_spread', 'strided_rows', 'columns_at', 'rows_less', 'grid_batch', 'graph_batch', 'kept_edges',
           'graph_contacts', 'graph_settle',
           'graph_plane',
           'voxel_count', 'tent_fit', 'leftover_rows', 'leftover_best', 'seeded_draws', 'polygon_distances',
           'ring_steps', 'ring_turns', 'ring_scatter', 'warm',
           'warm_probe',
           'Warmup']

_JIT = dict(cache=True, nogil=True)

#: A voxel grid of up to this many voxels is indexed by a direct table (an int64 each), a larger one by a hash.
DENSE_VOXELS = 1 << 22

#: The 8 image neighbours (row, column offsets), in the order a tie goes to the first.
EIGHT = np.array([(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc], dtype=np.int64)


def c_array(values, dtype) -> np.ndarray:
    """``values`` as a C-ordered, writeable array of ``dtype``, copied only when it is not one already: the
    layout and flags the kernels are compiled for (another would compile them again, at a frame's cost). Such an array
    comes back itself, a kernel's output too (np.ascontiguousarray gives a new view of that one: an identity test
    such as VoxelIndex.query's of the indexed points would then fail)."""
    if type(values) is np.ndarray and values.dtype == dtype and values.ndim and values.flags.c_contiguous and \
            values.flags.writeable:
        return values
    arr = np.ascontiguousarray(values, dtype=dtype)
    return arr if arr.flags.writeable else arr.copy()


@numba.njit(**_JIT)
def finite_mask(points: np.ndarray) -> tuple[np.ndarray, int]:
    """(N,) bool: rows of ``points`` (N, 3) with three finite coordinates; and how many."""
    n = points.shape[0]
    out = np.empty(n, np.bool_)
    count = 0
    for i in range(n):
        ok = np.isfinite(points[i, 0]) and np.isfinite(points[i, 1]) and np.isfinite(points[i, 2])
        out[i] = ok
        count += ok
    return out, count


@numba.njit(**_JIT)
def group_by_label(labels: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The rows of each label 0..k-1 of ``labels`` (N,), ascending, one after another (a stable counting
    sort; rows labelled outside 0..k-1 are left out): (rows (m,) int64, bounds (k + 1,) int64), label j's
    rows being rows[bounds[j]:bounds[j + 1]]."""
    bounds = np.zeros(k + 1, np.int64)
    for i in range(labels.shape[0]):
        lab = labels[i]
        if 0 <= lab < k:
            bounds[lab + 1] += 1
    for j in range(k):
        bounds[j + 1] += bounds[j]
    fill = bounds[:-1].copy()
    rows = np.empty(bounds[k], np.int64)
    for i in range(labels.shape[0]):
        lab = labels[i]
        if 0 <= lab < k:
            rows[fill[lab]] = i
            fill[lab] += 1
    return rows, bounds


@numba.njit(**_JIT)
def centroids_and_extremes(points: np.ndarray, rows: np.ndarray, bounds: np.ndarray, directions: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Per label of :func:`group_by_label` (``rows``, ``bounds``) over ``points`` (N, 3) meters: the mean point
    (k, 3) (NaN for a label without rows) and, for each of its ``directions`` (k, d, 3), the position among
    the label's rows of the point farthest along it (k, d) (the first of equals; -1 without rows)."""
    k, d = directions.shape[0], directions.shape[1]
    centroid = np.full((k, 3), np.nan)
    extreme = np.full((k, d), -1, np.int64)
    best = np.empty(d)
    for j in range(k):
        start, stop = bounds[j], bounds[j + 1]
        if stop == start:
            continue
        sx = sy = sz = 0.0
        best[:] = -np.inf
        for q in range(start, stop):
            i = rows[q]
            x, y, z = points[i, 0], points[i, 1], points[i, 2]
            sx += x
            sy += y
            sz += z
            for e in range(d):
                v = directions[j, e, 0] * x + directions[j, e, 1] * y + directions[j, e, 2] * z
                if v > best[e] or extreme[j, e] < 0:
                    best[e] = v
                    extreme[j, e] = q - start
        m = stop - start
        centroid[j, 0], centroid[j, 1], centroid[j, 2] = sx / m, sy / m, sz / m
    return centroid, extreme


@numba.njit(**_JIT)
def _root(parent: np.ndarray, i: int) -> int:
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@numba.njit(**_JIT)
def _join(parent: np.ndarray, i: int, j: int) -> None:
    a, b = _root(parent, i), _root(parent, j)
    if a != b:
        parent[max(a, b)] = min(a, b)


@numba.njit(**_JIT)
def _numbered(parent: np.ndarray, inside: np.ndarray) -> tuple[np.ndarray, int]:
    """The components of the union-find ``parent`` (n,) among the points ``inside`` (n,), numbered in the order of
    their first point: (component (n,) int64, -1 outside; count)."""
    n = parent.shape[0]
    component = np.full(n, -1, np.int64)
    number = np.full(n, -1, np.int64)
    count = 0
    for i in range(n):
        if inside[i]:
            r = _root(parent, i)
            if number[r] < 0:
                number[r] = count
                count += 1
            component[i] = number[r]
    return component, count


@numba.njit(**_JIT)
def grid_components(pixel: np.ndarray, node: np.ndarray, usable: np.ndarray, width: int, bridges: np.ndarray,
                    member: np.ndarray) -> tuple[np.ndarray, int]:
    """Connected components of the points ``member`` (n,) bool of a sub-grid image (point i at flat pixel
    ``pixel[i]``, ascending; ``node`` (h * w,): the point at each pixel, -1 none; ``usable`` (h * w,): pixels
    that may join) through their 4 image neighbours and the ``bridges`` (b, 3) (pixel, pixel, across the
    seam) that do not cross the seam. Returns (component (n,) int64, -1 outside; count), components
    numbered in the order of their first point (as scipy.ndimage.label numbers an image's)."""
    n = pixel.shape[0]
    parent = np.arange(n)
    inside = np.zeros(n, np.bool_)
    for i in range(n):
        inside[i] = member[i] and usable[pixel[i]]
    for i in range(n):
        if not inside[i]:
            continue
        p = pixel[i]
        if p % width > 0:
            j = node[p - 1]
            if j >= 0 and inside[j]:
                _join(parent, i, j)
        if p >= width:
            j = node[p - width]
            if j >= 0 and inside[j]:
                _join(parent, i, j)
    for b in range(bridges.shape[0]):
        if bridges[b, 2] != 0:
            continue
        i, j = node[bridges[b, 0]], node[bridges[b, 1]]
        if i >= 0 and j >= 0 and inside[i] and inside[j]:
            _join(parent, i, j)
    return _numbered(parent, inside)


@numba.njit(**_JIT)
def _fragmented(sizes: np.ndarray, largest_share: float, piece_share: float) -> bool:
    total = sizes.sum()
    if total == 0:
        return False
    desc = np.sort(sizes)[::-1]
    if desc[0] >= largest_share * total:
        return False
    typical = desc[np.searchsorted(np.cumsum(desc), total / 2)]
    return typical < piece_share * total


@numba.njit(**_JIT)
def grid_region(pixel: np.ndarray, node: np.ndarray, usable: np.ndarray, width: int, bridges: np.ndarray,
                normals: np.ndarray, normal: np.ndarray, min_cos: float, rest: np.ndarray, position: np.ndarray,
                mask: np.ndarray, support: np.ndarray, above: np.ndarray, rules: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """The region a plane of unit ``normal`` (3,) keeps among the points ``rest`` (r,) of a sub-grid (see
    :func:`grid_components`; ``position`` (n,): each point's place in ``rest``, -1 for none), as
    :meth:`.search.neighbours.Neighbours.region` gives it: its inliers ``mask`` (r,) and the points within the
    support band ``support`` (r,), both cut to the points whose ``normals`` (n, 3) lie within ``min_cos`` of it (NaN:
    unknown, kept); ``above`` (r,): on the side its normal points to. ``rules``: (FRAGMENTED, FRAGMENT_PIECE,
    SUPPORT_BALANCE). Returns (kept (r,), taken (r,)) bool. Only the points of the support band are visited after
    one pass over ``rest``: a plane's band is mostly a small share of the points left."""
    r = rest.shape[0]
    wide = np.zeros(r, np.bool_)
    full = np.zeros(r, np.bool_)
    up = np.zeros(r, np.bool_)
    band = np.empty(r, np.int64)  # the points of the support band that may join a region, ascending
    inliers = np.empty(r, np.int64)  # ... and of those, the inliers
    n_band = n_in = 0
    for q in range(r):
        if support[q]:
            i = rest[q]
            cos = abs(normals[i, 0] * normal[0] + normals[i, 1] * normal[1] + normals[i, 2] * normal[2])
            up[q] = above[q]
            if not cos < min_cos and usable[pixel[i]]:
                wide[q] = True
                band[n_band] = q
                n_band += 1
                if mask[q]:
                    full[q] = True
                    inliers[n_in] = q
                    n_in += 1
    return _band_region(pixel, node, width, bridges, rest, position, wide, full, up, band[:n_band], inliers[:n_in],
                        rules)


@numba.njit(**_JIT)
def _band_region(pixel: np.ndarray, node: np.ndarray, width: int, bridges: np.ndarray, rest: np.ndarray,
                 position: np.ndarray, wide: np.ndarray, full: np.ndarray, up: np.ndarray, band: np.ndarray,
                 inliers: np.ndarray, rules: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`grid_region` from its support band ``wide`` (r,) (its points ``band``, ascending), inliers ``full``
    (r,) (``inliers``) and side ``up`` (r,)."""
    parent = np.empty(rest.shape[0], np.int64)
    out, sizes = _band_largest(pixel, node, width, bridges, rest, position, full, inliers, full, parent)
    if _fragmented(sizes, rules[0], rules[1]):
        whole = _band_largest(pixel, node, width, bridges, rest, position, wide, band, full, parent)[0]
        return _surface(whole, full, up, out, rules[2])
    return out, out


@numba.njit(**_JIT)
def _band_largest(pixel: np.ndarray, node: np.ndarray, width: int, bridges: np.ndarray, rest: np.ndarray,
                  position: np.ndarray, inside: np.ndarray, members: np.ndarray, counted: np.ndarray,
                  parent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The component of the points ``members`` (c,) ascending (their places in ``rest``; ``inside`` (r,): the same as
    a mask) with the most ``counted`` (r,) points (the first of equals, components numbered in the order of their
    first point, as :func:`grid_components` numbers them), as (r,) bool, and those counts per component; ``parent``
    (r,): scratch."""
    r = rest.shape[0]
    for q in members:
        parent[q] = q
    row = 0
    for q in members:
        p = pixel[rest[q]]
        if p >= row + width:
            row = p - p % width
        if p > row:
            j = node[p - 1]
            if j >= 0 and position[j] >= 0 and inside[position[j]]:
                _join(parent, q, position[j])
        if p >= width:
            j = node[p - width]
            if j >= 0 and position[j] >= 0 and inside[position[j]]:
                _join(parent, q, position[j])
    for b in range(bridges.shape[0]):
        if bridges[b, 2] != 0:
            continue
        i, j = node[bridges[b, 0]], node[bridges[b, 1]]
        if i >= 0 and j >= 0 and position[i] >= 0 and position[j] >= 0 and inside[position[i]] and \
                inside[position[j]]:
            _join(parent, position[i], position[j])
    return _member_largest(parent, members, counted, r)


@numba.njit(**_JIT)
def _member_largest(parent: np.ndarray, members: np.ndarray, counted: np.ndarray, n: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The component of the union-find ``parent`` (n,) (joined by :func:`_join`: each root its component's smallest
    point) among the points ``members`` (c,) ascending, with the most ``counted`` (n,) points (the first of equals,
    components numbered in the order of their first point), as (n,) bool, and those counts per component."""
    number = np.empty(n, np.int64)  # read only at roots, each written when its first point is met
    component = np.empty(members.shape[0], np.int64)
    count = 0
    for c in range(members.shape[0]):
        root = _root(parent, members[c])
        if root == members[c]:  # a root is its component's smallest point: met first
            number[root] = count
            count += 1
        component[c] = number[root]
    sizes = np.zeros(count, np.int64)
    for c in range(members.shape[0]):
        if counted[members[c]]:
            sizes[component[c]] += 1
    out = np.zeros(n, np.bool_)
    if count == 0:
        return out, sizes
    best = np.argmax(sizes)
    for c in range(members.shape[0]):
        if component[c] == best:
            out[members[c]] = True
    return out, sizes


@numba.njit(**_JIT)
def _surface(whole: np.ndarray, full: np.ndarray, up: np.ndarray, out: np.ndarray, balance: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """(kept, taken) of a fragmented region ``out``: the inliers ``full`` of the support band's component ``whole``
    and that component when its points beyond t lie on both sides of the plane (``up``: above it; ``balance``) and
    it keeps more inliers than ``out``; else ``out`` twice."""
    beyond = above_count = joined = kept_count = 0
    for i in range(whole.shape[0]):
        if whole[i] and not full[i]:
            beyond += 1
            above_count += up[i]
        joined += whole[i] and full[i]
        kept_count += out[i]
    below = beyond - above_count
    if min(above_count, below) >= balance * max(above_count, below) and joined > kept_count:
        return whole & full, whole
    return out, out


@numba.njit(**_JIT)
def graph_components(n: int, edges: np.ndarray, member: np.ndarray) -> tuple[np.ndarray, int]:
    """Connected components of the points ``member`` (n,) bool of a graph of n points joined by ``edges`` (e, 2):
    (component (n,) int64, -1 outside; count), numbered in the order of their first point."""
    parent = np.arange(n)
    for q in range(edges.shape[0]):
        i, j = edges[q, 0], edges[q, 1]
        if member[i] and member[j]:
            _join(parent, i, j)
    return _numbered(parent, member)


@numba.njit(**_JIT)
def graph_region(ends: np.ndarray, edge_rows: np.ndarray, normals: np.ndarray, normal: np.ndarray, min_cos: float,
                 mask: np.ndarray, support: np.ndarray, above: np.ndarray, rules: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`grid_region` on a graph of n points joined by edges (each pair once, the smaller index first, sorted),
    point i's from ``edge_rows[i]`` ((n + 1,)) to the larger ends ``ends`` (e,) (all n points searched): ``mask``,
    ``support`` and ``above`` (n,); ``normals`` (n, 3), or (0, 3) when none is known. Only the points of the support
    band and the inliers are visited after one pass over the flags."""
    n = mask.shape[0]
    known = normals.shape[0] > 0
    wide = np.zeros(n, np.bool_)
    full = np.zeros(n, np.bool_)
    band = np.empty(n, np.int64)  # the points of the support band that may join a region, ascending
    inliers = np.empty(n, np.int64)  # ... and the inliers that may
    n_band = n_in = 0
    for i in range(n):
        if support[i] or mask[i]:
            if known:
                cos = abs(normals[i, 0] * normal[0] + normals[i, 1] * normal[1] + normals[i, 2] * normal[2])
                if cos < min_cos:
                    continue
            if support[i]:
                wide[i] = True
                band[n_band] = i
                n_band += 1
            if mask[i]:
                full[i] = True
                inliers[n_in] = i
                n_in += 1
    return _graph_band(ends, edge_rows, wide, full, above, band[:n_band], inliers[:n_in], rules)


@numba.njit(**_JIT)
def _graph_band(ends: np.ndarray, edge_rows: np.ndarray, wide: np.ndarray, full: np.ndarray, up: np.ndarray,
                band: np.ndarray, inliers: np.ndarray, rules: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`graph_region` from its support band ``wide`` (n,) (its points ``band``, ascending), inliers ``full``
    (n,) (``inliers``) and side ``up`` (n,)."""
    parent = np.empty(wide.shape[0], np.int64)
    out, sizes = _graph_largest(ends, edge_rows, full, inliers, full, parent)
    if _fragmented(sizes, rules[0], rules[1]):
        whole = _graph_largest(ends, edge_rows, wide, band, full, parent)[0]
        return _surface(whole, full, up, out, rules[2])
    return out, out


@numba.njit(**_JIT)
def _graph_largest(ends: np.ndarray, edge_rows: np.ndarray, inside: np.ndarray, members: np.ndarray,
                   counted: np.ndarray, parent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_member_largest` of the points ``members`` (c,) ascending (``inside`` (n,): the same as a mask) of a
    graph (``ends``, ``edge_rows`` as :func:`graph_region` takes them), joined through the members' own edges
    (components as :func:`graph_components` numbers them: :func:`_join`'s roots); ``parent`` (n,): scratch."""
    for i in members:
        parent[i] = i
    for i in members:
        a = _root(parent, i)  # i's root, followed through its row rather than found again at each edge
        for q in range(edge_rows[i], edge_rows[i + 1]):
            j = ends[q]
            if inside[j]:
                b = _root(parent, j)
                if b < a:
                    parent[a] = b
                    a = b
                elif b > a:
                    parent[b] = a
    return _member_largest(parent, members, counted, inside.shape[0])


@numba.njit(**_JIT)
def coordinate_bounds(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The smallest and the largest coordinates (3,) each of ``points`` (n, 3), n >= 1."""
    lo0, lo1, lo2 = points[0, 0], points[0, 1], points[0, 2]
    hi0, hi1, hi2 = lo0, lo1, lo2
    for i in range(1, points.shape[0]):  # on scalars, without branches: about half the time of a loop over the axes
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        lo0, hi0 = x if x < lo0 else lo0, x if x > hi0 else hi0
        lo1, hi1 = y if y < lo1 else lo1, y if y > hi1 else hi1
        lo2, hi2 = z if z < lo2 else lo2, z if z > hi2 else hi2
    return np.array([lo0, lo1, lo2]), np.array([hi0, hi1, hi2])


@numba.njit(**_JIT)
def _slot(key: int, mask: int) -> int:
    """The first slot of ``key`` in a hash table of mask + 1 slots (a power of two)."""
    h = key * 0x9E3779B1
    return (h ^ (h >> 17)) & mask


@numba.njit(**_JIT)
def voxel_grid(points: np.ndarray, origin: np.ndarray, cell: float, dims: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Hash ``points`` (m, 3) meters into cubic voxels of side ``cell`` (meters) from ``origin`` (3,), ``dims`` (3,)
    voxels along each axis (every point inside them). Returns (order (m,): the points voxel by voxel, in the order of
    their voxel's key; keys (c,) of the occupied voxels, ascending; starts (c + 1,): voxel j holds
    order[starts[j]:starts[j + 1]]; table: the voxel of each key (-1: empty), directly ((dims.prod(),), when that is
    at most DENSE_VOXELS or 8 m) or as an open-addressing hash (2^b,))."""
    m = points.shape[0]
    keys = np.empty(m, np.int64)
    for i in range(m):
        ix = int((points[i, 0] - origin[0]) / cell)
        iy = int((points[i, 1] - origin[1]) / cell)
        iz = int((points[i, 2] - origin[2]) / cell)
        keys[i] = ix + dims[0] * (iy + dims[1] * iz)
    total = dims[0] * dims[1] * dims[2]
    if total <= max(DENSE_VOXELS, 8 * m):  # few enough voxels for a direct table: no hashing
        return _counted_grid(keys, total)
    order = np.argsort(keys, kind='mergesort')
    c = 0
    for q in range(m):
        if q == 0 or keys[order[q]] != keys[order[q - 1]]:
            c += 1
    cell_keys = np.empty(c, np.int64)
    starts = np.empty(c + 1, np.int64)
    c = 0
    for q in range(m):
        key = keys[order[q]]
        if q == 0 or key != keys[order[q - 1]]:
            cell_keys[c] = key
            starts[c] = q
            c += 1
    starts[c] = m
    size = 1
    while size < 2 * c + 2:
        size *= 2
    table = np.full(size, -1, np.int64)
    for j in range(c):
        s = _slot(cell_keys[j], size - 1)
        while table[s] >= 0:
            s = (s + 1) & (size - 1)
        table[s] = j
    return order, cell_keys, starts, table


@numba.njit(**_JIT)
def _counted_grid(keys: np.ndarray, total: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`voxel_grid`'s output with a direct table, from the points' voxel ``keys`` (m,), each below ``total``: the
    points placed by a count per key (the table holds the counts first), in the order a stable sort of the keys gives,
    in about half the time of that sort."""
    m = keys.shape[0]
    table = np.zeros(total, np.int64)
    for i in range(m):
        table[keys[i]] += 1
    cell_keys = np.empty(m, np.int64)
    starts = np.empty(m + 1, np.int64)
    c = q = 0
    for key in range(total):
        n = table[key]
        if n:
            cell_keys[c], starts[c], table[key] = key, q, c
            q += n
            c += 1
        else:
            table[key] = -1
    starts[c] = m
    fill = starts[:c].copy()
    order = np.empty(m, np.int64)
    for i in range(m):
        v = table[keys[i]]
        order[fill[v]] = i
        fill[v] += 1
    return order, cell_keys[:c].copy(), starts[:c + 1].copy(), table


@numba.njit(**_JIT)
def _voxel(cell_keys: np.ndarray, table: np.ndarray, key: int, dense: bool) -> int:
    """The occupied voxel of ``key`` in :func:`voxel_grid`'s table (``dense``: a direct one), -1 when none."""
    if dense:
        return table[key]
    mask = table.shape[0] - 1
    s = _slot(key, mask)
    while table[s] >= 0:
        if cell_keys[table[s]] == key:
            return table[s]
        s = (s + 1) & mask
    return -1


@numba.njit(**_JIT)
def _gap(f: float, c: int, d: int) -> float:
    """How far (in voxels) a query at ``f`` along an axis, in voxel ``c``, lies from voxel c + ``d``."""
    if d < 0:
        return f - (c + d + 1)
    if d > 0:
        return (c + d) - f
    return 0.0


@numba.njit(**_JIT)
def _take(e: float, j: int, d2: np.ndarray, best: np.ndarray, found: int, k: int) -> int:
    """Insert the hashed point ``j`` at squared distance ``e`` into the ``found`` nearest so far, ``d2`` (k,) and
    ``best`` (k,), ascending (equal distances: the first in the hash's order first), when it is among the k nearest;
    returns how many they are then."""
    if found == k and not (e < d2[k - 1] or (e == d2[k - 1] and j < best[k - 1])):
        return found
    p = min(found, k - 1)
    while p > 0 and (e < d2[p - 1] or (e == d2[p - 1] and j < best[p - 1])):
        d2[p] = d2[p - 1]
        best[p] = best[p - 1]
        p -= 1
    d2[p] = e
    best[p] = j
    return found + 1 if found < k else found


@numba.njit(**_JIT)
def _ring(points: np.ndarray, cell_keys: np.ndarray, starts: np.ndarray, table: np.ndarray, dims: np.ndarray,
          dense: bool, x: float, y: float, z: float, fx: float, fy: float, fz: float, cx: int, cy: int, cz: int,
          cell: float, r: int, d2: np.ndarray, best: np.ndarray, found: int) -> int:
    """:func:`_take` the points of the voxels in ring ``r`` around the voxel (cx, cy, cz) of the query (x, y, z)
    meters ((fx, fy, fz): in voxels), skipping voxels no nearer than the k-th nearest so far; returns how many are
    found then."""
    k = d2.shape[0]
    for dz in range(-r, r + 1):
        iz = cz + dz
        if iz < 0 or iz >= dims[2]:
            continue
        gz = _gap(fz, cz, dz) * cell
        for dy in range(-r, r + 1):
            iy = cy + dy
            if iy < 0 or iy >= dims[1]:
                continue
            gy = _gap(fy, cy, dy) * cell
            gyz = gy * gy + gz * gz
            if found == k and gyz > d2[k - 1]:
                continue
            edge = abs(dz) == r or abs(dy) == r
            dx = -r
            while dx <= r:
                ix = cx + dx
                gx = _gap(fx, cx, dx) * cell
                if 0 <= ix < dims[0] and not (found == k and gx * gx + gyz > d2[k - 1]):
                    v = _voxel(cell_keys, table, ix + dims[0] * (iy + dims[1] * iz), dense)
                    if v >= 0:
                        for j in range(starts[v], starts[v + 1]):
                            ex, ey, ez = points[j, 0] - x, points[j, 1] - y, points[j, 2] - z
                            found = _take(ex * ex + ey * ey + ez * ez, j, d2, best, found, k)
                dx += 1 if edge or dx == r else 2 * r  # inside the ring: only its two ends
    return found


@numba.njit(**_JIT)
def voxel_knn(points: np.ndarray, order: np.ndarray, cell_keys: np.ndarray, starts: np.ndarray, table: np.ndarray,
              origin: np.ndarray, cell: float, dims: np.ndarray, queries: np.ndarray, k: int, max_ring: int
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``k`` nearest of the points hashed by :func:`voxel_grid` (``points`` (m, 3): those points voxel by voxel,
    in its ``order``) to each of ``queries`` (q, 3), inside the grid, nearest first (equal distances: the first in
    ``order`` first; indices into the points as hashed), searched ring by ring of voxels around the query's
    own up to ``max_ring`` rings. Returns (distances (q, k) meters, indices (q, k), exact (q,) bool): a query whose k
    nearest are not certain within those rings has exact False (its other rows are then meaningless)."""
    nq = queries.shape[0]
    dist = np.full((nq, k), np.inf)
    idx = np.full((nq, k), -1, np.int64)
    exact = np.zeros(nq, np.bool_)
    d2 = np.empty(k)
    total = dims[0] * dims[1] * dims[2]
    dense = table.shape[0] == total and total <= max(DENSE_VOXELS, 8 * points.shape[0])
    for q in range(nq):
        x, y, z = queries[q, 0], queries[q, 1], queries[q, 2]
        fx, fy, fz = (x - origin[0]) / cell, (y - origin[1]) / cell, (z - origin[2]) / cell
        cx, cy, cz = int(fx), int(fy), int(fz)
        margin = min(fx - cx, cx + 1 - fx, fy - cy, cy + 1 - fy, fz - cz, cz + 1 - fz) * cell
        d2[:] = np.inf
        found = 0
        best = idx[q]
        for r in range(max_ring + 1):
            found = _ring(points, cell_keys, starts, table, dims, dense, x, y, z, fx, fy, fz, cx, cy, cz, cell, r, d2,
                          best, found)
            reach = r * cell + margin
            if found == k and d2[k - 1] <= reach * reach:
                exact[q] = True
                break
        for p in range(found):
            dist[q, p] = np.sqrt(d2[p])
            best[p] = order[best[p]]
    return dist, idx, exact


#: The 27 voxels of a block (offsets from its middle one, x, y, z): the middle one first, then those across a face, an
#: edge, a corner (the nearer first: fewer of their points displace others among a query's nearest).
_BLOCK = np.array(sorted([(dx, dy, dz) for dz in (-1, 0, 1) for dy in (-1, 0, 1) for dx in (-1, 0, 1)],
                         key=lambda o: abs(o[0]) + abs(o[1]) + abs(o[2])), dtype=np.int64)
#: voxel_knn_points first looks among the points nearer than this many times the previous query's k-th nearest
#: squared distance (neighbouring queries have about the same): where at least k are, its k nearest are among them.
_GUESS = 1.5


@numba.njit(**_JIT)
def _block(points: np.ndarray, cell_keys: np.ndarray, starts: np.ndarray, table: np.ndarray, dims: np.ndarray,
           dense: bool, key: int, xyz: np.ndarray, rows: np.ndarray) -> int:
    """The points of the occupied voxels of the 3 x 3 x 3 block around the voxel of ``key`` (in :data:`_BLOCK`'s
    order): their coordinates into ``xyz`` (3, b) and positions in the hash into ``rows`` (b,); returns how many."""
    vx, vy, vz = key % dims[0], (key // dims[0]) % dims[1], key // (dims[0] * dims[1])
    m = 0
    for b in range(27):
        ix, iy, iz = vx + _BLOCK[b, 0], vy + _BLOCK[b, 1], vz + _BLOCK[b, 2]
        if 0 <= ix < dims[0] and 0 <= iy < dims[1] and 0 <= iz < dims[2]:
            u = _voxel(cell_keys, table, ix + dims[0] * (iy + dims[1] * iz), dense)
            if u >= 0:
                for j in range(starts[u], starts[u + 1]):
                    xyz[0, m], xyz[1, m], xyz[2, m] = points[j, 0], points[j, 1], points[j, 2]
                    rows[m] = j
                    m += 1
    return m


@numba.njit(**_JIT)
def _in_block(xyz: np.ndarray, rows: np.ndarray, m: int, query: np.ndarray, guess: float, e2: np.ndarray,
              chosen: np.ndarray, d2: np.ndarray, best: np.ndarray) -> int:
    """The k nearest ``d2``, ``best`` (k,) to ``query`` (3,) of the ``m`` block points of :func:`_block` (``xyz``,
    ``rows``): only those within ``guess`` (squared, m^2) when at least k are (then no other is among the k nearest),
    else all; returns how many are found. ``e2``, ``chosen`` (b,): room for the squared distances and the points
    looked at."""
    k = d2.shape[0]
    x, y, z = query[0], query[1], query[2]
    for a in range(m):  # all distances first: a loop without branches
        ex, ey, ez = xyz[0, a] - x, xyz[1, a] - y, xyz[2, a] - z
        e2[a] = ex * ex + ey * ey + ez * ez
    n = 0
    for a in range(m):
        chosen[n] = a
        n += e2[a] <= guess
    if n < k:
        n = m
        for a in range(m):
            chosen[a] = a
    found = 0
    d2[:] = np.inf
    for t in range(n):
        a = chosen[t]
        found = _take(e2[a], rows[a], d2, best, found, k)
    return found


@numba.njit(**_JIT)
def voxel_knn_points(points: np.ndarray, order: np.ndarray, cell_keys: np.ndarray, starts: np.ndarray,
                     table: np.ndarray, origin: np.ndarray, cell: float, dims: np.ndarray, k: int, max_ring: int
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`voxel_knn` of the hashed points themselves (``points`` (m, 3) voxel by voxel; the queries: the points in
    their order before hashing), the same answer, max_ring >= 1. The queries are taken voxel by voxel: the points of
    the 27 voxels around each are gathered once for all its queries, which mostly find their k nearest among them
    (the others go on ring by ring)."""
    m = points.shape[0]
    dist = np.empty((m, k))  # every row is written below: not filled first
    idx = np.empty((m, k), np.int64)
    exact = np.zeros(m, np.bool_)
    total = dims[0] * dims[1] * dims[2]
    dense = table.shape[0] == total and total <= max(DENSE_VOXELS, 8 * m)
    most = 0
    for v in range(cell_keys.shape[0]):
        most = max(most, starts[v + 1] - starts[v])
    xyz = np.empty((3, 27 * most))
    rows = np.empty(27 * most, np.int64)
    e2 = np.empty(27 * most)
    chosen = np.empty(27 * most, np.int64)
    d2 = np.empty(k)
    best = np.empty(k, np.int64)
    guess = np.inf
    for v in range(cell_keys.shape[0]):
        b = _block(points, cell_keys, starts, table, dims, dense, cell_keys[v], xyz, rows)
        for g in range(starts[v], starts[v + 1]):
            found = _in_block(xyz, rows, b, points[g], guess, e2, chosen, d2, best)
            if found == k:
                guess = _GUESS * d2[k - 1]
            q = order[g]
            x, y, z = points[g, 0], points[g, 1], points[g, 2]
            fx, fy, fz = (x - origin[0]) / cell, (y - origin[1]) / cell, (z - origin[2]) / cell
            cx, cy, cz = int(fx), int(fy), int(fz)
            margin = min(fx - cx, cx + 1 - fx, fy - cy, cy + 1 - fy, fz - cz, cz + 1 - fz) * cell
            r, reach = 1, cell + margin  # the block is ring 1; the few not certain there go on ring by ring
            while not (found == k and d2[k - 1] <= reach * reach) and r < max_ring:
                r += 1
                found = _ring(points, cell_keys, starts, table, dims, dense, x, y, z, fx, fy, fz, cx, cy, cz, cell, r,
                              d2, best, found)
                reach = r * cell + margin
            exact[q] = found == k and d2[k - 1] <= reach * reach
            for p in range(found):
                dist[q, p] = np.sqrt(d2[p])
                idx[q, p] = order[best[p]]
            for p in range(found, k):
                dist[q, p], idx[q, p] = np.inf, -1
    return dist, idx, exact


@numba.njit(**_JIT)
def brute_knn(points: np.ndarray, queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest of ``points`` (m, 3) to each of ``queries`` (q, 3), by every distance: (distances (q, k)
    meters, nearest first, equal ones by index; indices (q, k), m where fewer than k points exist, at inf), as a
    kd-tree answers them. For a few queries the voxel rings do not settle (far from every point): a kd-tree built for
    them costs about as much as the whole frame's kNN."""
    m, nq = points.shape[0], queries.shape[0]
    dist = np.empty((nq, k))
    idx = np.empty((nq, k), np.int64)
    d2 = np.empty(k)
    best = np.empty(k, np.int64)
    for q in range(nq):
        x, y, z = queries[q, 0], queries[q, 1], queries[q, 2]
        found = 0
        for j in range(m):
            ex, ey, ez = points[j, 0] - x, points[j, 1] - y, points[j, 2] - z
            found = _take(ex * ex + ey * ey + ez * ez, j, d2, best, found, k)
        for p in range(found):
            dist[q, p], idx[q, p] = np.sqrt(d2[p]), best[p]
        for p in range(found, k):
            dist[q, p], idx[q, p] = np.inf, m
    return dist, idx


@numba.njit(**_JIT)
def _longest_cross(r0x: float, r0y: float, r0z: float, r1x: float, r1y: float, r1z: float, r2x: float, r2y: float,
                   r2z: float) -> tuple[float, float, float]:
    """The longest of the pairwise cross products of three rows, as a unit vector; (1, 0, 0) when all vanish (the
    rows span at most a line: then any axis serves)."""
    ax, ay, az = r0y * r1z - r0z * r1y, r0z * r1x - r0x * r1z, r0x * r1y - r0y * r1x
    bx, by, bz = r0y * r2z - r0z * r2y, r0z * r2x - r0x * r2z, r0x * r2y - r0y * r2x
    cx, cy, cz = r1y * r2z - r1z * r2y, r1z * r2x - r1x * r2z, r1x * r2y - r1y * r2x
    a, b, c = ax * ax + ay * ay + az * az, bx * bx + by * by + bz * bz, cx * cx + cy * cy + cz * cz
    if b > a:
        ax, ay, az, a = bx, by, bz, b
    if c > a:
        ax, ay, az, a = cx, cy, cz, c
    if not a > 0.0:
        return 1.0, 0.0, 0.0
    s = 1.0 / np.sqrt(a)
    return ax * s, ay * s, az * s


@numba.njit(**_JIT)
def _eigen2(m00: float, m01: float, m11: float) -> tuple[float, float, float, float]:
    """The eigenvalues (smaller, larger) of the symmetric 2 x 2 matrix [[m00, m01], [m01, m11]] and the smaller one's
    unit eigenvector (c0, c1), each from the row without cancellation; (1, 0) for a multiple of the identity."""
    mean, half = 0.5 * (m00 + m11), 0.5 * (m00 - m11)
    r = np.sqrt(half * half + m01 * m01)
    if not r > 0.0:
        return mean, mean, 1.0, 0.0
    if half >= 0.0:  # the row (half + r, m01) of M - smaller I sends (-m01, half + r) to zero
        c0, c1 = -m01, half + r
    else:  # the row (m01, r - half)
        c0, c1 = r - half, -m01
    n = 1.0 / np.sqrt(c0 * c0 + c1 * c1)
    return mean - r, mean + r, c0 * n, c1 * n


@numba.njit(**_JIT)
def _eigen3(a00: float, a01: float, a02: float, a11: float, a12: float, a22: float
            ) -> tuple[float, float, float, float, float, float, float, float, float, float, float, float]:
    """Eigenvalues, ascending and at least 0, and unit eigenvectors (x, y, z of the smallest's, the middle one's and the
    largest's axis) of a positive semi-definite symmetric 3 x 3 matrix, in closed form: the eigenvalue farthest from
    the other two (a simple root) by the trigonometric solution of the characteristic cubic, its axis as the longest
    cross product of two rows of (A - lambda I) and its value as that axis' Rayleigh quotient; the other two, close
    or not, from the 2 x 2 problem in the plane normal to it (accurate where the cubic's angle is not). Scaled by the
    largest entry first (no overflow or underflow); an identity basis for a multiple of the identity."""
    big = max(abs(a00), abs(a01), abs(a02), abs(a11), abs(a12), abs(a22))
    if not big > 0.0:
        return 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
    inv = 1.0 / big
    a00, a01, a02, a11, a12, a22 = a00 * inv, a01 * inv, a02 * inv, a11 * inv, a12 * inv, a22 * inv
    q = (a00 + a11 + a22) / 3.0
    b00, b11, b22 = a00 - q, a11 - q, a22 - q
    p2 = (b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * (a01 * a01 + a02 * a02 + a12 * a12)) / 6.0
    if not p2 > 0.0:
        v = max(q * big, 0.0)
        return v, v, v, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
    p = np.sqrt(p2)
    half_det = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) + a02 * (a01 * a12 - b11 * a02)) \
        / (2.0 * p2 * p)
    cos_a = np.cos(np.arccos(min(1.0, max(-1.0, half_det))) / 3.0)  # the angle in [0, pi / 3]
    if half_det >= 0.0:  # the largest lies farther from the middle one than the smallest does
        first = q + 2.0 * p * cos_a
    else:  # 2 p cos(angle + 2 pi / 3)
        first = q + p * (-cos_a - np.sqrt(3.0) * np.sqrt(max(0.0, 1.0 - cos_a * cos_a)))
    ux, uy, uz = _longest_cross(a00 - first, a01, a02, a01, a11 - first, a12, a02, a12, a22 - first)
    if abs(ux) > abs(uy):  # (s, t): an orthonormal basis of the plane normal to u
        n = 1.0 / np.sqrt(ux * ux + uz * uz)
        sx, sy, sz = -uz * n, 0.0, ux * n
    else:
        n = 1.0 / np.sqrt(uy * uy + uz * uz)
        sx, sy, sz = 0.0, uz * n, -uy * n
    tx, ty, tz = uy * sz - uz * sy, uz * sx - ux * sz, ux * sy - uy * sx
    asx, asy, asz = a00 * sx + a01 * sy + a02 * sz, a01 * sx + a11 * sy + a12 * sz, a02 * sx + a12 * sy + a22 * sz
    atx, aty, atz = a00 * tx + a01 * ty + a02 * tz, a01 * tx + a11 * ty + a12 * tz, a02 * tx + a12 * ty + a22 * tz
    low, high, c0, c1 = _eigen2(sx * asx + sy * asy + sz * asz, sx * atx + sy * aty + sz * atz,
                                tx * atx + ty * aty + tz * atz)
    lx, ly, lz = c0 * sx + c1 * tx, c0 * sy + c1 * ty, c0 * sz + c1 * tz  # the smaller one's axis, then the larger's
    hx, hy, hz = c0 * tx - c1 * sx, c0 * ty - c1 * sy, c0 * tz - c1 * sz
    ru = (ux * (a00 * ux + a01 * uy + a02 * uz) + uy * (a01 * ux + a11 * uy + a12 * uz) +
          uz * (a02 * ux + a12 * uy + a22 * uz))
    if half_det >= 0.0:  # u the largest's axis
        return (max(low * big, 0.0), max(high * big, 0.0), max(max(ru, high) * big, 0.0), lx, ly, lz, hx, hy, hz,
                ux, uy, uz)
    return max(min(ru, low) * big, 0.0), max(low * big, 0.0), max(high * big, 0.0), ux, uy, uz, lx, ly, lz, hx, hy, hz


@numba.njit(**_JIT)
def principal_axes(points: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (m, 3), ascending, and unit principal axes (m, 3, 3), as columns, of the scatter about their mean
    of the point sets ``points[idx[i]]`` (``points`` (n, 3) meters, ``idx`` (m, k)), in closed form (:func:`_eigen3`;
    an axis' sign is arbitrary, as is the basis of equal eigenvalues): the eigenvalues within about 1e-14 of the
    largest of those of a Jacobi solve, at about half its time."""
    m, k = idx.shape
    values = np.empty((m, 3))
    axes = np.empty((m, 3, 3))
    for i in range(m):
        mx = my = mz = 0.0
        for j in range(k):
            p = idx[i, j]
            mx += points[p, 0]
            my += points[p, 1]
            mz += points[p, 2]
        mx, my, mz = mx / k, my / k, mz / k
        xx = xy = xz = yy = yz = zz = 0.0
        for j in range(k):
            p = idx[i, j]
            x, y, z = points[p, 0] - mx, points[p, 1] - my, points[p, 2] - mz
            xx += x * x
            xy += x * y
            xz += x * z
            yy += y * y
            yz += y * z
            zz += z * z
        (values[i, 0], values[i, 1], values[i, 2], axes[i, 0, 0], axes[i, 1, 0], axes[i, 2, 0], axes[i, 0, 1],
         axes[i, 1, 1], axes[i, 2, 1], axes[i, 0, 2], axes[i, 1, 2], axes[i, 2, 2]) = _eigen3(xx, xy, xz, yy, yz, zz)
    return values, axes


@numba.njit(**_JIT)
def _scatter_sums(points: np.ndarray, members: np.ndarray, lo: int, hi: int, cx: float, cy: float, cz: float
                  ) -> tuple[float, float, float, float, float, float]:
    """Sums (xx, xy, xz, yy, yz, zz) of the products of ``points[members[lo:hi]]``' offsets from (cx, cy, cz), m^2."""
    xx = xy = xz = yy = yz = zz = 0.0
    for q in range(lo, hi):
        p = members[q]
        x, y, z = points[p, 0] - cx, points[p, 1] - cy, points[p, 2] - cz
        xx += x * x
        xy += x * y
        xz += x * z
        yy += y * y
        yz += y * z
        zz += z * z
    return xx, xy, xz, yy, yz, zz


@numba.njit(**_JIT)
def _scatter_shape(points: np.ndarray, members: np.ndarray, lo: int, hi: int, cx: float, cy: float, cz: float
                   ) -> tuple[float, float, float, float]:
    """Of the points ``points[members[lo:hi]]`` about their mean (cx, cy, cz): (the scatter's smallest eigenvalue,
    |cos| between its axis and the mean (NaN when undefined), smallest / middle eigenvalue, middle / largest one), in
    closed form (trigonometric eigenvalues; the axis as the longest cross product of two rows of scatter - smallest I).
    """
    xx, xy, xz, yy, yz, zz = _scatter_sums(points, members, lo, hi, cx, cy, cz)
    mean = (xx + yy + zz) / 3.0
    spread = np.sqrt(((xx - mean) ** 2 + (yy - mean) ** 2 + (zz - mean) ** 2 + 2.0 * (xy * xy + xz * xz + yz * yz))
                     / 6.0)
    if not spread > 0.0:
        return max(mean, 0.0), np.nan, 1.0, 0.0 if not mean > 0.0 else 1.0
    b00, b11, b22 = (xx - mean) / spread, (yy - mean) / spread, (zz - mean) / spread
    b01, b02, b12 = xy / spread, xz / spread, yz / spread
    det = b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02) + b02 * (b01 * b12 - b11 * b02)
    angle = np.arccos(min(1.0, max(-1.0, det / 2.0))) / 3.0
    largest = mean + 2.0 * spread * np.cos(angle)
    smallest = mean + 2.0 * spread * np.cos(angle + 2.0 * np.pi / 3.0)
    middle = 3.0 * mean - largest - smallest
    rows = np.array([[xx - smallest, xy, xz], [xy, yy - smallest, yz], [xz, yz, zz - smallest]])
    best, nx, ny, nz = 0.0, 0.0, 0.0, 0.0
    for a, b in ((0, 1), (0, 2), (1, 2)):
        vx = rows[a, 1] * rows[b, 2] - rows[a, 2] * rows[b, 1]
        vy = rows[a, 2] * rows[b, 0] - rows[a, 0] * rows[b, 2]
        vz = rows[a, 0] * rows[b, 1] - rows[a, 1] * rows[b, 0]
        size = vx * vx + vy * vy + vz * vz
        if size > best:
            best, nx, ny, nz = size, vx, vy, vz
    rc = np.sqrt(cx * cx + cy * cy + cz * cz)
    facing = abs(nx * cx + ny * cy + nz * cz) / (np.sqrt(best) * rc) if best > 0.0 and rc > 0.0 else np.nan
    return (max(smallest, 0.0), facing, max(smallest, 0.0) / middle if middle > 0.0 else 1.0,
            max(middle, 0.0) / largest if largest > 0.0 else 0.0)


@numba.njit(**_JIT)
def _ray_fit(points: np.ndarray, members: np.ndarray, lo: int, hi: int, cx: float, cy: float, cz: float
             ) -> tuple[float, float]:
    """(sum of squared range residuals m^2, |cos| between the plane's normal and the mean ray) of the least-squares
    fit of 1 / r to the unit ray directions of ``points[members[lo:hi]]``; NaN, NaN when the directions do not span
    3-D or a point is at the viewpoint. Solved in a frame about the mean ray (cx, cy, cz): well-conditioned normal
    equations."""
    rc = np.sqrt(cx * cx + cy * cy + cz * cz)
    if not rc > 0.0:
        return np.nan, np.nan
    e = np.empty((3, 3))
    e[0, 0], e[0, 1], e[0, 2] = cx / rc, cy / rc, cz / rc
    side = np.array([1.0, 0.0, 0.0]) if abs(e[0, 0]) < 0.6 else np.array([0.0, 1.0, 0.0])
    e[1, 0], e[1, 1], e[1, 2] = (e[0, 1] * side[2] - e[0, 2] * side[1], e[0, 2] * side[0] - e[0, 0] * side[2],
                                 e[0, 0] * side[1] - e[0, 1] * side[0])
    e[1] /= np.sqrt(e[1, 0] ** 2 + e[1, 1] ** 2 + e[1, 2] ** 2)
    e[2, 0], e[2, 1], e[2, 2] = (e[0, 1] * e[1, 2] - e[0, 2] * e[1, 1], e[0, 2] * e[1, 0] - e[0, 0] * e[1, 2],
                                 e[0, 0] * e[1, 1] - e[0, 1] * e[1, 0])
    a = np.zeros((3, 4))  # normal equations [M | c]
    g = np.empty(3)
    for q in range(lo, hi):
        p = members[q]
        r = np.sqrt(points[p, 0] ** 2 + points[p, 1] ** 2 + points[p, 2] ** 2)
        if not r > 0.0:  # a point at the viewpoint has no ray
            return np.nan, np.nan
        for s in range(3):
            g[s] = (points[p, 0] * e[s, 0] + points[p, 1] * e[s, 1] + points[p, 2] * e[s, 2]) / r
        for s in range(3):
            for t in range(3):
                a[s, t] += g[s] * g[t]
            a[s, 3] += g[s] / r
    scale = max(a[0, 0], a[1, 1], a[2, 2])
    for s in range(3):  # Gaussian elimination with partial pivoting
        best = s
        for t in range(s + 1, 3):
            if abs(a[t, s]) > abs(a[best, s]):
                best = t
        if not abs(a[best, s]) > 1e-13 * scale:
            return np.nan, np.nan
        for c in range(4):
            a[s, c], a[best, c] = a[best, c], a[s, c]
        for t in range(s + 1, 3):
            f = a[t, s] / a[s, s]
            for c in range(s, 4):
                a[t, c] -= f * a[s, c]
    w2 = a[2, 3] / a[2, 2]
    w1 = (a[1, 3] - a[1, 2] * w2) / a[1, 1]
    w0 = (a[0, 3] - a[0, 1] * w1 - a[0, 2] * w2) / a[0, 0]
    sq = 0.0
    for q in range(lo, hi):
        p = members[q]
        r = np.sqrt(points[p, 0] ** 2 + points[p, 1] ** 2 + points[p, 2] ** 2)
        fitted = 0.0
        for s, w in ((0, w0), (1, w1), (2, w2)):
            fitted += w * (points[p, 0] * e[s, 0] + points[p, 1] * e[s, 1] + points[p, 2] * e[s, 2]) / r
        d = (1.0 / r - fitted) * r * r  # d(1/r) = -dr / r^2
        sq += d * d
    return sq, abs(w0) / np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)


@numba.njit(**_JIT)
def patch_fits(points: np.ndarray, members: np.ndarray, starts: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per neighbourhood j, the points ``points[members[starts[j]:starts[j + 1]]]`` ((n, 3) meters from the viewpoint,
    at least 4 each): (range variance (m,) m^2 of the least-squares fit of 1 / r to the unit ray directions u, its
    residuals times r^2, over k - 3 (NaN when the directions do not span 3-D); facing (m,): |cos| between that fit's
    plane normal and the mean ray; thickness variance (m,) m^2, the scatter's smallest eigenvalue over k - 3;
    plane facing (m,): |cos| between the scatter's smallest axis and the mean ray (NaN when undefined); flatness (m,):
    the smallest eigenvalue over the middle one; breadth (m,): the middle one over the largest; range (m,) m of the
    mean point)."""
    m = starts.shape[0] - 1
    out = np.empty((7, m))
    for j in range(m):
        lo, hi = starts[j], starts[j + 1]
        k = hi - lo
        cx = cy = cz = 0.0
        for q in range(lo, hi):
            p = members[q]
            cx += points[p, 0]
            cy += points[p, 1]
            cz += points[p, 2]
        cx, cy, cz = cx / k, cy / k, cz / k
        smallest, out[3, j], out[4, j], out[5, j] = _scatter_shape(points, members, lo, hi, cx, cy, cz)
        out[2, j] = smallest / (k - 3)
        sq, out[1, j] = _ray_fit(points, members, lo, hi, cx, cy, cz)
        out[0, j] = sq / (k - 3)
        out[6, j] = np.sqrt(cx * cx + cy * cy + cz * cz)
    return out[0], out[1], out[2], out[3], out[4], out[5], out[6]


@numba.njit(**_JIT)
def _pair_rows(n: int, pairs: np.ndarray, dist: np.ndarray, idx: np.ndarray, reach: np.ndarray, always: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`pair_graph`'s pairs by their smaller end: (count (n + 1,): row i's larger ends are
    larger[count[i]:count[i + 1]], in no order; larger)."""
    e = pairs.shape[0]
    m, k = idx.shape
    count = np.zeros(n + 1, np.int64)
    for q in range(e):
        count[min(pairs[q, 0], pairs[q, 1]) + 1] += 1
    for i in range(m):  # the nearest neighbours' pairs are counted and filled where they are, not gathered first
        for j in range(1, k):
            if dist[i, j] <= reach[i] or (j <= always and np.isfinite(dist[i, j])):
                count[min(i, idx[i, j]) + 1] += 1
    for i in range(n):
        count[i + 1] += count[i]
    fill = count[:-1].copy()
    larger = np.empty(count[n], np.int64)
    for q in range(e):
        a, b = pairs[q, 0], pairs[q, 1]
        larger[fill[min(a, b)]] = max(a, b)
        fill[min(a, b)] += 1
    for i in range(m):
        for j in range(1, k):
            if dist[i, j] <= reach[i] or (j <= always and np.isfinite(dist[i, j])):
                a, b = i, idx[i, j]
                larger[fill[min(a, b)]] = max(a, b)
                fill[min(a, b)] += 1
    return count, larger


@numba.njit(**_JIT)
def pair_graph(n: int, pairs: np.ndarray, dist: np.ndarray, idx: np.ndarray, reach: np.ndarray, always: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The graph of n points joined by ``pairs`` (e, 2) (any order, repeats allowed) and each point i to its nearest
    neighbours ``idx[i, 1:]`` (``dist`` (n, k) meters, nearest first; the first column the point itself; (0, k): none)
    that lie within ``reach[i]`` meters, or among its first ``always`` at a finite distance: (edges (u, 2) each joined
    pair once, smaller index first, sorted by it then by the other, C-ordered as the kernels that take them read them;
    indptr (n + 1,) and indices: each point's neighbours, first the larger ones ascending, then the smaller ones
    ascending; starts (n + 1,): where each point's edges to larger indices start in edges)."""
    count, larger = _pair_rows(n, pairs, dist, idx, reach, always)
    unique = 0
    degree = np.zeros(n, np.int64)
    stop = 0
    for i in range(n):  # each row's larger ends sorted, repeats dropped, in place
        start, stop = stop, count[i + 1]
        if stop - start > 16:
            larger[start:stop].sort()
        else:  # a few: insertion sort
            for q in range(start + 1, stop):
                b = larger[q]
                p = q
                while p > start and larger[p - 1] > b:
                    larger[p] = larger[p - 1]
                    p -= 1
                larger[p] = b
        last = -1
        for q in range(start, stop):
            b = larger[q]
            if b != last:
                larger[unique] = b
                unique += 1
                degree[i] += 1
                degree[b] += 1
                last = b
        count[i + 1] = unique  # now the bounds of the deduplicated rows
    edges = np.empty((unique, 2), np.int64)
    indptr = np.zeros(n + 1, np.int64)
    for i in range(n):
        indptr[i + 1] = indptr[i] + degree[i]
    at = indptr[:-1].copy()
    indices = np.empty(2 * unique, np.int64)
    for i in range(n):
        for q in range(count[i], count[i + 1]):
            b = larger[q]
            edges[q, 0], edges[q, 1] = i, b
            indices[at[i]] = b
            at[i] += 1
    for i in range(n):
        for q in range(count[i], count[i + 1]):
            b = larger[q]
            indices[at[b]] = i
            at[b] += 1
    return edges, indptr, indices, count


# --- frame pass ---


@numba.njit(**_JIT)
def widen_xyz(words: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """(N, 3) float64: the float32 ``words`` (N, w) at ``columns`` (3,) of each row (the x, y, z of N records of w
    four-byte words: a PointCloud2's points)."""
    out = np.empty((words.shape[0], 3))
    a, b, c = columns[0], columns[1], columns[2]
    for i in range(words.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = words[i, a], words[i, b], words[i, c]
    return out


@numba.njit(**_JIT)
def valid_rows(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """The rows of ``points`` (N, 3) with three finite coordinates: which (N,) bool and they themselves, in order
    ((n, 3), the start of an (N, 3) buffer); and how many other rows have an infinite coordinate."""
    n = points.shape[0]
    finite = np.empty(n, np.bool_)
    valid = np.empty((n, 3))
    m = infinite = 0
    for i in range(n):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        ok = np.isfinite(x) and np.isfinite(y) and np.isfinite(z)
        finite[i] = ok
        if ok:
            valid[m, 0], valid[m, 1], valid[m, 2] = x, y, z
            m += 1
        elif np.isinf(x) or np.isinf(y) or np.isinf(z):
            infinite += 1
    return finite, valid[:m], infinite


@numba.njit(**_JIT)
def frame_pass(points: np.ndarray, labels: np.ndarray, keep: np.ndarray, plane_ids: np.ndarray, palette: np.ndarray,
               directions: np.ndarray, segmented: np.ndarray, obstacles: np.ndarray, compact: bool
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool, bool, float]:
    """One pass over the rows of a processed frame, ``points`` (N, 3) meters (NaN or inf in rows that hold no
    point) with plane ``labels`` (N,) in -1..k-1: the records of both output clouds and each plane's statistics.

    ``segmented`` (N * 20,) uint8 gets little-endian records x, y, z (float32; NaN where a row is not finite),
    plane_id (int32) and rgb: a label j in 0..k-1 writes ``plane_ids[j]`` and ``palette[j]`` (uint32), any other
    the last entries ((k + 1,) each). ``obstacles`` gets records x, y, z (float32) of the finite rows that
    ``keep`` (n,) bool, one per finite row in order, marks: (N * 12,) with NaN where a row is not kept or not
    finite, or with ``compact`` only the kept rows, one after another ((kept * 12,)). Returns per label, as
    :func:`centroids_and_extremes` over its rows in order: the count (k,), the mean point (k, 3) (NaN without
    rows) and the position among its rows of the point farthest along each of its ``directions`` (k, d, 3)
    (k, d) (the first of equals; -1 without rows); whether each cloud is dense (no NaN coordinate written); and
    the largest magnitude of a finite coordinate (0 without one)."""
    n = points.shape[0]
    k, d = directions.shape[0], directions.shape[1]
    last = palette.shape[0] - 1
    seg_f = segmented.view(np.float32)
    seg_i = segmented.view(np.int32)
    obs_f = obstacles.view(np.float32)
    count = np.zeros(k, np.int64)
    sums = np.zeros((k, 3))
    extreme = np.full((k, d), -1, np.int64)
    best = np.full((k, d), -np.inf)
    seg_dense = obs_dense = True
    big_x = big_y = big_z = 0.0  # a running maximum per coordinate: no chain through one
    kept = valid = 0  # obstacle records written, finite rows passed
    nan = np.float32(np.nan)
    # the statistics of the label of the current run of rows in locals (labels come in runs), kept in the arrays
    # between runs: the arrays' loads and stores (which the compiler cannot keep in registers, as they might share
    # memory with the records written) then happen once a run instead of once a row; the same sums in the same order
    run = -1
    q = 0  # rows of the run's label so far
    sx = sy = sz = 0.0
    run_best = np.empty(d)
    run_extreme = np.empty(d, np.int64)
    ax, ay, az = np.empty(d), np.empty(d), np.empty(d)  # the run's directions, component by component
    for i in range(n):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        finite = np.isfinite(x) & np.isfinite(y) & np.isfinite(z)  # no branch per coordinate
        lab = labels[i]
        j = lab if 0 <= lab < last else last
        base = 5 * i
        if finite:  # a finite coordinate is never NaN as float32 (at most inf)
            fx, fy, fz = np.float32(x), np.float32(y), np.float32(z)
            big_x, big_y, big_z = max(big_x, abs(x)), max(big_y, abs(y)), max(big_z, abs(z))
        else:
            for v in (x, y, z):  # a row's finite coordinates count too
                if np.isfinite(v):
                    big_x = max(big_x, abs(v))
            fx = fy = fz = nan
            seg_dense = False
        seg_f[base], seg_f[base + 1], seg_f[base + 2] = fx, fy, fz
        seg_i[base + 3] = plane_ids[j]
        seg_i[base + 4] = np.int32(palette[j])
        kept_here = False
        if finite:
            kept_here = valid < keep.shape[0] and keep[valid]
            valid += 1
        if compact:
            if kept_here:
                obs_f[3 * kept], obs_f[3 * kept + 1], obs_f[3 * kept + 2] = fx, fy, fz
                kept += 1
        elif kept_here:
            obs_f[3 * i], obs_f[3 * i + 1], obs_f[3 * i + 2] = fx, fy, fz
        else:
            obs_f[3 * i] = obs_f[3 * i + 1] = obs_f[3 * i + 2] = nan
            obs_dense = False
        if 0 <= lab < k:
            if lab != run:
                if run >= 0:
                    _keep_run(run, q, sx, sy, sz, run_best, run_extreme, count, sums, best, extreme)
                run = lab
                q, sx, sy, sz = _start_run(lab, count, sums, best, extreme, directions, run_best, run_extreme,
                                           ax, ay, az)
            sx += x
            sy += y
            sz += z
            beyond = q == 0  # a label's first point is its first extreme in every direction
            for e in range(d):
                beyond |= ax[e] * x + ay[e] * y + az[e] * z > run_best[e]
            if beyond:  # rare after a label's first points: the projections again, the same products and sums
                for e in range(d):
                    value = ax[e] * x + ay[e] * y + az[e] * z
                    if value > run_best[e] or q == 0:
                        run_best[e] = value
                        run_extreme[e] = q
            q += 1
    if run >= 0:
        _keep_run(run, q, sx, sy, sz, run_best, run_extreme, count, sums, best, extreme)
    centroid = np.full((k, 3), np.nan)
    for j in range(k):
        if count[j]:
            for a in range(3):
                centroid[j, a] = sums[j, a] / count[j]
    return count, centroid, extreme, seg_dense, obs_dense, max(big_x, max(big_y, big_z))


@numba.njit(**_JIT)
def _start_run(lab: int, count: np.ndarray, sums: np.ndarray, best: np.ndarray, extreme: np.ndarray,
               directions: np.ndarray, run_best: np.ndarray, run_extreme: np.ndarray, ax: np.ndarray, ay: np.ndarray,
               az: np.ndarray) -> tuple[int, float, float, float]:
    """:func:`frame_pass`' statistics of label ``lab`` so far, as a run of its rows starts: its extremes and directions
    into the run's arrays; returns (its rows so far, its sums of x, y, z)."""
    for e in range(run_best.shape[0]):
        run_best[e], run_extreme[e] = best[lab, e], extreme[lab, e]
        ax[e], ay[e], az[e] = directions[lab, e, 0], directions[lab, e, 1], directions[lab, e, 2]
    return count[lab], sums[lab, 0], sums[lab, 1], sums[lab, 2]


@numba.njit(**_JIT)
def _keep_run(lab: int, q: int, sx: float, sy: float, sz: float, run_best: np.ndarray, run_extreme: np.ndarray,
              count: np.ndarray, sums: np.ndarray, best: np.ndarray, extreme: np.ndarray) -> None:
    """:func:`frame_pass`' statistics of label ``lab`` at the end of a run of its rows, back into its arrays."""
    count[lab] = q
    sums[lab, 0], sums[lab, 1], sums[lab, 2] = sx, sy, sz
    for e in range(run_best.shape[0]):
        best[lab, e], extreme[lab, e] = run_best[e], run_extreme[e]


# --- verdict ---


@numba.njit(**_JIT)
def _floor_quotient(a: float, b: float) -> float:
    """``a // b`` for a >= 0, b > 0 (Python's floor division, whose fmod costs several times more): the rounded
    quotient's floor is the exact quotient's unless the rounding reached a whole number, which is then settled by
    ``//`` itself."""
    q = a / b
    whole = np.floor(q)
    return whole if whole != q else a // b


@numba.njit(**_JIT)
def plane_patches(centred: np.ndarray, axes: np.ndarray, per_patch: int, min_count: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The patches of a plane's points ``centred`` (m, 3) (about their mean, meters): the cells of a square grid along
    its in-plane ``axes`` (3, 2, unit columns), sized to hold ``per_patch`` points on average. Per cell holding at
    least ``min_count``, in the order of its number (row along the first axis, then column): (counts (p,), scatter
    (p, 3, 3): the mean outer product of its points about their own mean, m^2). Empty when the points span no area."""
    m = centred.shape[0]
    u = np.empty(m)
    v = np.empty(m)
    for i in range(m):
        x, y, z = centred[i, 0], centred[i, 1], centred[i, 2]
        u[i] = x * axes[0, 0] + y * axes[1, 0] + z * axes[2, 0]
        v[i] = x * axes[0, 1] + y * axes[1, 1] + z * axes[2, 1]
    empty = (np.zeros(0, np.int64), np.zeros((0, 3, 3)))
    if m == 0:
        return empty
    lo_u, lo_v = u.min(), v.min()
    side = np.sqrt((u.max() - lo_u) * (v.max() - lo_v) * per_patch / m)
    if not side > 0.0:
        return empty
    width = int(_floor_quotient(v.max() - lo_v, side)) + 1
    height = int(_floor_quotient(u.max() - lo_u, side)) + 1
    cells = np.empty(m, np.int64)
    for i in range(m):
        cells[i] = int(_floor_quotient(u[i] - lo_u, side)) * width + int(_floor_quotient(v[i] - lo_v, side))
    if width * height <= 4 * m:  # a counting sort by cell
        start = np.zeros(width * height + 1, np.int64)
        for i in range(m):
            start[cells[i] + 1] += 1
        for c in range(width * height):
            start[c + 1] += start[c]
        at = start[:-1].copy()
        order = np.empty(m, np.int64)
        for i in range(m):
            order[at[cells[i]]] = i
            at[cells[i]] += 1
    else:  # a strip thin for its length: most cells are empty
        order = np.argsort(cells, kind='mergesort')
    counts = np.empty(m, np.int64)
    scatter = np.empty((m, 3, 3))
    p = 0
    lo = 0
    while lo < m:
        hi = lo + 1
        while hi < m and cells[order[hi]] == cells[order[lo]]:
            hi += 1
        k = hi - lo
        if k >= min_count:
            cx = cy = cz = 0.0
            for q in range(lo, hi):
                i = order[q]
                cx += centred[i, 0]
                cy += centred[i, 1]
                cz += centred[i, 2]
            cx, cy, cz = cx / k, cy / k, cz / k
            xx, xy, xz, yy, yz, zz = _scatter_sums(centred, order, lo, hi, cx, cy, cz)
            s = scatter[p]
            s[0, 0], s[0, 1], s[0, 2] = xx / k, xy / k, xz / k
            s[1, 0], s[1, 1], s[1, 2] = xy / k, yy / k, yz / k
            s[2, 0], s[2, 1], s[2, 2] = xz / k, yz / k, zz / k
            counts[p] = k
            p += 1
        lo = hi
    return counts[:p].copy(), scatter[:p].copy()


@numba.njit(**_JIT)
def _solve4(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, bool]:
    """x of a x = b for a (4, 4), b (4,) by Gaussian elimination with partial pivoting; False when singular."""
    a, b = a.copy(), b.copy()
    scale = max(abs(a[0, 0]), abs(a[1, 1]), abs(a[2, 2]), abs(a[3, 3]))
    for s in range(4):
        best = s
        for t in range(s + 1, 4):
            if abs(a[t, s]) > abs(a[best, s]):
                best = t
        if not abs(a[best, s]) > 1e-12 * scale:
            return b, False
        for c in range(4):
            a[s, c], a[best, c] = a[best, c], a[s, c]
        b[s], b[best] = b[best], b[s]
        for t in range(s + 1, 4):
            f = a[t, s] / a[s, s]
            for c in range(s, 4):
                a[t, c] -= f * a[s, c]
            b[t] -= f * b[s]
    x = np.empty(4)
    for s in range(3, -1, -1):
        acc = b[s]
        for c in range(s + 1, 4):
            acc -= a[s, c] * x[c]
        x[s] = acc / a[s, s]
    return x, True


@numba.njit(**_JIT)
def fold_line(u: np.ndarray, v: np.ndarray, w: np.ndarray, angles: int, offsets: int, inner: float
              ) -> tuple[float, float, float]:
    """The best least-squares fit w = a + b u + c v + d |s - s0| to points at in-plane coordinates (u, v) (m,) with
    residuals ``w`` (m,), all meters: two planes meeting at a line (a ridge or a fold), s = u cos(theta) + v sin(theta)
    across it, over ``angles`` directions theta in [0, pi) and ``offsets`` lines s0 per direction at evenly spaced
    quantiles of s within its middle ``inner`` share. Returns (its mean squared residual (m^2), theta (rad), s0 (m, in
    the same coordinates as u and v)): (NaN, NaN, NaN) for fewer than 5 points, (inf, NaN, NaN) where no line's fit
    could be solved."""
    m = u.shape[0]
    if m < 5:
        return np.nan, np.nan, np.nan
    # sums over all points of 1, u, v and their products with w: the plane part of every fit
    su = sv = sw = suu = suv = svv = suw = svw = sww = 0.0
    for i in range(m):
        su += u[i]
        sv += v[i]
        sw += w[i]
        suu += u[i] * u[i]
        suv += u[i] * v[i]
        svv += v[i] * v[i]
        suw += u[i] * w[i]
        svw += v[i] * w[i]
        sww += w[i] * w[i]
    best, best_theta, best_s0 = np.inf, np.nan, np.nan
    s = np.empty(m)
    a = np.empty((4, 4))
    rhs = np.empty(4)
    for k in range(angles):
        theta = np.pi * k / angles
        c, d = np.cos(theta), np.sin(theta)
        for i in range(m):
            s[i] = u[i] * c + v[i] * d
        order = sorted_order(s)
        # running sums over the points left of the line, in order of s: 1, s, u, v, w and s times each
        l1 = ls = lu = lv = lw = lss = lsu = lsv = lsw = 0.0
        ts = tu = tv = tw = tss = tsu = tsv = tsw = 0.0
        for i in range(m):
            p = order[i]
            ts += s[p]
            tss += s[p] * s[p]
            tsu += s[p] * u[p]
            tsv += s[p] * v[p]
            tsw += s[p] * w[p]
        tu, tv, tw = su, sv, sw
        done = 0
        for j in range(offsets):
            q = (1.0 - inner) / 2.0 + inner * j / max(offsets - 1, 1)
            split = min(m - 1, max(1, int(q * (m - 1) + 0.5)))
            while done < split:
                p = order[done]
                l1 += 1.0
                ls += s[p]
                lu += u[p]
                lv += v[p]
                lw += w[p]
                lss += s[p] * s[p]
                lsu += s[p] * u[p]
                lsv += s[p] * v[p]
                lsw += s[p] * w[p]
                done += 1
            s0 = s[order[split]]
            # h = |s - s0|: s0 - s on the left, s - s0 on the right
            h1 = (s0 * l1 - ls) + ((ts - ls) - s0 * (m - l1))
            hu = (s0 * lu - lsu) + ((tsu - lsu) - s0 * (tu - lu))
            hv = (s0 * lv - lsv) + ((tsv - lsv) - s0 * (tv - lv))
            hw = (s0 * lw - lsw) + ((tsw - lsw) - s0 * (tw - lw))
            hh = tss - 2.0 * s0 * ts + s0 * s0 * m
            a[0, 0], a[0, 1], a[0, 2], a[0, 3] = m, su, sv, h1
            a[1, 0], a[1, 1], a[1, 2], a[1, 3] = su, suu, suv, hu
            a[2, 0], a[2, 1], a[2, 2], a[2, 3] = sv, suv, svv, hv
            a[3, 0], a[3, 1], a[3, 2], a[3, 3] = h1, hu, hv, hh
            rhs[0], rhs[1], rhs[2], rhs[3] = sw, suw, svw, hw
            x, ok = _solve4(a, rhs)
            if ok:
                rss = sww - (x[0] * rhs[0] + x[1] * rhs[1] + x[2] * rhs[2] + x[3] * rhs[3])
                mse = max(rss, 0.0) / m
                if mse < best:
                    best, best_theta, best_s0 = mse, theta, s0
    return best, best_theta, best_s0


# --- search ---

#: The search kernels divide as numpy does (inf or NaN, no exception), as their numpy references do.
_NUMPY_JIT = dict(_JIT, error_model='numpy')


#: An empty ray (``ray`` argument of the search kernels): the tolerance is measured across the plane as given.
NO_RAY = np.empty(0)


@numba.njit(**_NUMPY_JIT)
def _facing(x: float, y: float, z: float, nx: float, ny: float, nz: float, ray: np.ndarray) -> float:
    """The share of a tolerance measured along the viewing ray that lies across the plane of unit normal (nx, ny, nz)
    at the point (x, y, z): max(|n . u|, floor), u the unit ray from the viewpoint ``ray[:3]`` to the point and floor
    ``ray[3]``; 1 for an empty ``ray`` (:data:`NO_RAY`). Range noise moves a point along its ray, so it moves it
    |n . u| times as far from the plane."""
    if ray.shape[0] == 0:
        return 1.0
    dx, dy, dz = x - ray[0], y - ray[1], z - ray[2]
    along = abs(nx * dx + ny * dy + nz * dz) / np.sqrt(dx * dx + dy * dy + dz * dz)
    return along if along > ray[3] else ray[3]  # NaN (a point at the viewpoint): the floor


@numba.njit(**_NUMPY_JIT)
def grid_sample(points: np.ndarray, finite: np.ndarray, width: int, step: int, offsets: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """The regular sub-grid of step ``step`` of an image of ``points`` (h * w, 3) meters, ``width`` w, whose finite
    rows are ``finite`` (h * w,): for each step x step block, from pixel (step // 2, step // 2) on, the first of the
    block's pixels at ``offsets`` (s, 2) (row, column within the block, in the order tried) that is valid. Returns
    (image (gh, gw, 3) of those pixels' points, NaN for a block without one, or (0, 0, 3) when ``points`` has no
    rows (the pixels only); pixels (gh, gw) int64, -1 for none)."""
    h = finite.shape[0] // width
    copy = points.shape[0] > 0
    c = step // 2
    gh, gw = (h - c + step - 1) // step if h > c else 0, (width - c + step - 1) // step if width > c else 0
    image = np.full((gh, gw, 3) if copy else (0, 0, 3), np.nan)
    pixels = np.full((gh, gw), -1, np.int64)
    for br in range(gh):
        for bc in range(gw):
            for o in range(offsets.shape[0]):
                r, col = br * step + offsets[o, 0], bc * step + offsets[o, 1]
                if r < h and col < width and finite[r * width + col]:
                    p = r * width + col
                    pixels[br, bc] = p
                    if copy:
                        image[br, bc, 0], image[br, bc, 1], image[br, bc, 2] = points[p, 0], points[p, 1], points[p, 2]
                    break
    return image, pixels


@numba.njit(**_NUMPY_JIT)
def _length(x: float, y: float, z: float) -> float:
    """The Euclidean length of (x, y, z) as np.linalg.norm sums a length-3 axis (in order)."""
    return np.sqrt(x * x + y * y + z * z)


@numba.njit(**_NUMPY_JIT)
def _dot(a0: float, a1: float, a2: float, b0: float, b1: float, b2: float) -> float:
    """a . b as np.einsum('...i,...i->...') sums a length-3 axis (its two-lane loop: the first and last products
    first), so that the results stay bit-identical to the numpy references."""
    return (a0 * b0 + a2 * b2) + a1 * b1


@numba.njit(**_NUMPY_JIT)
def grid_edges(points: np.ndarray, valid: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Of an image of ``points`` (h, w, 3) meters with valid pixels ``valid`` (h, w): each pixel's range (h, w)
    (NaN where a coordinate is), the 3-D gap to its right neighbour (h, w - 1) and the nearer of the two ranges
    (NaN gap unless both pixels are valid), the same down (h - 1, w) twice, and the finite gaps over their range
    (right ones first, row by row, then down ones)."""
    h, w = valid.shape
    ranges = np.empty((h, w))
    for r in range(h):
        for c in range(w):
            x, y, z = points[r, c, 0], points[r, c, 1], points[r, c, 2]
            ranges[r, c] = np.sqrt(_dot(x, y, z, x, y, z))
    right = np.full((h, max(w - 1, 0)), np.nan)
    right_reach = np.empty((h, max(w - 1, 0)))
    down = np.full((max(h - 1, 0), w), np.nan)
    down_reach = np.empty((max(h - 1, 0), w))
    angular = np.empty(right.size + down.size)
    count = 0
    for r in range(h):
        for c in range(w - 1):
            right_reach[r, c] = _nan_min(ranges[r, c], ranges[r, c + 1])
            if valid[r, c] and valid[r, c + 1]:
                x, y, z = (points[r, c, 0] - points[r, c + 1, 0], points[r, c, 1] - points[r, c + 1, 1],
                           points[r, c, 2] - points[r, c + 1, 2])
                right[r, c] = np.sqrt(_dot(x, y, z, x, y, z))
                if np.isfinite(right[r, c]):
                    angular[count] = right[r, c] / right_reach[r, c]
                    count += 1
    for r in range(h - 1):
        for c in range(w):
            down_reach[r, c] = _nan_min(ranges[r, c], ranges[r + 1, c])
            if valid[r, c] and valid[r + 1, c]:
                x, y, z = (points[r, c, 0] - points[r + 1, c, 0], points[r, c, 1] - points[r + 1, c, 1],
                           points[r, c, 2] - points[r + 1, c, 2])
                down[r, c] = np.sqrt(_dot(x, y, z, x, y, z))
                if np.isfinite(down[r, c]):
                    angular[count] = down[r, c] / down_reach[r, c]
                    count += 1
    return ranges, right, right_reach, down, down_reach, angular[:count]


@numba.njit(**_NUMPY_JIT)
def _nan_min(a: float, b: float) -> float:
    """np.minimum of two numbers: NaN when either is."""
    if np.isnan(a) or np.isnan(b):
        return np.nan
    return min(a, b)


@numba.njit(**_NUMPY_JIT)
def _jump(gap: float, before: float, after: float, reach: float, typical: float, jump: float) -> bool:
    """Whether an edge's ``gap`` is a depth jump: more than ``jump`` times the larger of the gaps ``before`` and
    ``after`` it along its line (NaN: none; the gap itself when neither is) and than ``jump`` typical spacings at
    its ``reach``."""
    if not np.isfinite(gap):
        return False
    local = after if np.isnan(before) else (before if np.isnan(after) else max(before, after))
    if np.isnan(local):
        local = gap
    floor = typical * reach
    if np.isnan(floor):
        return False
    return gap > jump * max(local, floor)


@numba.njit(**_NUMPY_JIT)
def grid_usable(valid: np.ndarray, ranges: np.ndarray, right: np.ndarray, right_reach: np.ndarray, down: np.ndarray,
                down_reach: np.ndarray, typical: float, jump: float) -> np.ndarray:
    """(h, w) the valid pixels (``valid`` (h, w)) of :func:`grid_edges`' image that are not the far pixel of a depth
    jump (an edge whose gap exceeds ``jump`` times the gaps beside it along its line and ``jump`` times ``typical``
    spacings per meter of range): they may join a region."""
    h, w = valid.shape
    usable = valid.copy()
    for r in range(h):
        for c in range(w - 1):
            before = right[r, c - 1] if c > 0 else np.nan
            after = right[r, c + 1] if c + 1 < w - 1 else np.nan
            if _jump(right[r, c], before, after, right_reach[r, c], typical, jump):
                near = ranges[r, c] if valid[r, c] else 0.0
                far = ranges[r, c + 1] if valid[r, c + 1] else 0.0
                if far > near:
                    usable[r, c + 1] = False
                else:
                    usable[r, c] = False
    for r in range(h - 1):
        for c in range(w):
            before = down[r - 1, c] if r > 0 else np.nan
            after = down[r + 1, c] if r + 1 < h - 1 else np.nan
            if _jump(down[r, c], before, after, down_reach[r, c], typical, jump):
                near = ranges[r, c] if valid[r, c] else 0.0
                far = ranges[r + 1, c] if valid[r + 1, c] else 0.0
                if far > near:
                    usable[r + 1, c] = False
                else:
                    usable[r, c] = False
    return usable


@numba.njit(**_NUMPY_JIT)
def grid_normals(points: np.ndarray, valid: np.ndarray, down_reach: int, across_reach: int, bend: float
                 ) -> np.ndarray:
    """(h, w, 3) unit normals of an image of ``points`` (h, w, 3) meters with valid pixels ``valid`` (h, w): the
    cross product of (right - left) and (down - up), the pixels ``across_reach`` and ``down_reach`` away (NaN where
    one is off the image or invalid); with ``bend`` > 0 also NaN where the pixel lies off the middle of those two
    pairs, along the normal, by more than ``bend`` times their distance."""
    h, w = valid.shape
    dr, ar = down_reach, across_reach
    pad = np.full((h + 2 * dr, w + 2 * ar, 3), np.nan)  # NaN off the image and at invalid pixels: no branches
    for r in range(h):
        for c in range(w):
            if valid[r, c]:
                pad[r + dr, c + ar, 0] = points[r, c, 0]
                pad[r + dr, c + ar, 1] = points[r, c, 1]
                pad[r + dr, c + ar, 2] = points[r, c, 2]
    out = np.empty((h, w, 3))
    for r in range(h):
        pr = r + dr
        for c in range(w):
            pc = c + ar
            ax, ay, az = pad[pr, pc + ar, 0], pad[pr, pc + ar, 1], pad[pr, pc + ar, 2]
            bx, by, bz = pad[pr, pc - ar, 0], pad[pr, pc - ar, 1], pad[pr, pc - ar, 2]
            dx, dy, dz = pad[pr + dr, pc, 0], pad[pr + dr, pc, 1], pad[pr + dr, pc, 2]
            ex, ey, ez = pad[pr - dr, pc, 0], pad[pr - dr, pc, 1], pad[pr - dr, pc, 2]
            ux, uy, uz = ax - bx, ay - by, az - bz
            vx, vy, vz = dx - ex, dy - ey, dz - ez
            n0 = uy * vz - uz * vy
            n1 = uz * vx - ux * vz
            n2 = ux * vy - uy * vx
            size = np.sqrt(_dot(n0, n1, n2, n0, n1, n2))
            n0, n1, n2 = n0 / size, n1 / size, n2 / size
            if bend > 0:
                cx, cy, cz = pad[pr, pc, 0], pad[pr, pc, 1], pad[pr, pc, 2]
                bend_u = abs(_dot(ax + bx - 2 * cx, ay + by - 2 * cy, az + bz - 2 * cz, n0, n1, n2)) / \
                    _length(ux, uy, uz)
                bend_v = abs(_dot(dx + ex - 2 * cx, dy + ey - 2 * cy, dz + ez - 2 * cz, n0, n1, n2)) / \
                    _length(vx, vy, vz)
                if bend_u > bend or bend_v > bend:
                    n0 = n1 = n2 = np.nan
            out[r, c, 0], out[r, c, 1], out[r, c, 2] = n0, n1, n2
    return out


@numba.njit(**_NUMPY_JIT)
def grid_chords(points: np.ndarray, valid: np.ndarray, ranges: np.ndarray, across: bool, every: int) -> np.ndarray:
    """The distances between the unit rays (``points`` (h, w, 3) over ``ranges`` (h, w)) of neighbouring valid
    pixels (``valid`` (h, w)): along every ``every``-th row (``across``), else down every ``every``-th column; row by
    row."""
    h, w = valid.shape
    out = np.empty(h * w)
    count = 0
    for r in range(0, h, every if across else 1):
        for c in range(0, w, 1 if across else every):
            r2, c2 = (r, c + 1) if across else (r + 1, c)
            if r2 >= h or c2 >= w or not (valid[r, c] and valid[r2, c2]):
                continue
            out[count] = _length(points[r2, c2, 0] / ranges[r2, c2] - points[r, c, 0] / ranges[r, c],
                                 points[r2, c2, 1] / ranges[r2, c2] - points[r, c, 1] / ranges[r, c],
                                 points[r2, c2, 2] / ranges[r2, c2] - points[r, c, 2] / ranges[r, c])
            count += 1
    return out[:count]


@numba.njit(**_NUMPY_JIT)
def _coherent(normals: np.ndarray, p: int, nx: float, ny: float, nz: float, min_cos: float) -> bool:
    """Whether point ``p``'s local normal (``normals`` (m, 3), NaN: unknown; (0, 3): none known) lies within
    ``min_cos`` of (nx, ny, nz)."""
    if normals.shape[0] == 0:
        return True
    return not abs(normals[p, 0] * nx + normals[p, 1] * ny + normals[p, 2] * nz) < min_cos


@numba.njit(**_NUMPY_JIT)
def merge_test(search: np.ndarray, members: np.ndarray, region: np.ndarray, i: int, j: int, plane: np.ndarray,
               own: np.ndarray, tolerance: np.ndarray, src: np.ndarray, dst: np.ndarray, region_src: np.ndarray,
               region_dst: np.ndarray, root: np.ndarray, normals: np.ndarray, min_cos: float, keep: float,
               spread: float, ray: np.ndarray) -> bool:
    """Whether the touching regions ``i`` < ``j`` are one surface with the joint ``plane`` (4,) (a, b, c, d) of their
    points ``members`` (c,) of ``search`` (3, m) meters: they touch (a pair ``src``, ``dst`` (e,) of points first in
    regions ``region_src``, ``region_dst`` (e,), now in ``root`` of those) where both points' ``normals`` (m, 3) agree
    with it (within ``min_cos``; (0, 3): none known); at least ``keep`` of the points lie within ``tolerance``
    ((1,) or (m,) meters) of it (times :func:`_facing` of ``ray``; with a ray, also at least ``keep`` of each
    region's own); and their mean squared distance to it is at most ``spread`` squared times that to their own
    region's plane (``own`` (2, 4): i's, j's; ``region`` (m,): each point's region)."""
    nx, ny, nz, d = plane[0], plane[1], plane[2], plane[3]
    touch = False
    for q in range(src.shape[0]):
        a, b = root[region_src[q]], root[region_dst[q]]
        if ((a == i and b == j) or (a == j and b == i)) and _coherent(normals, src[q], nx, ny, nz, min_cos) and \
                _coherent(normals, dst[q], nx, ny, nz, min_cos):
            touch = True
            break
    if not touch:
        return False
    per_point = tolerance.shape[0] > 1
    near = 0
    near_i = count_i = 0
    joint = mine = 0.0
    for q in range(members.shape[0]):
        p = members[q]
        x, y, z = search[0, p], search[1, p], search[2, p]
        e = abs(nx * x + ny * y + nz * z + d)
        within = e <= (tolerance[p] if per_point else tolerance[0]) * _facing(x, y, z, nx, ny, nz, ray)
        near += within
        joint += e * e
        o = 0 if region[p] == i else 1
        near_i += within and o == 0
        count_i += o == 0
        e = own[o, 0] * x + own[o, 1] * y + own[o, 2] * z + own[o, 3]
        mine += e * e
    c = members.shape[0]
    if ray.shape[0] > 0 and not (near_i >= keep * count_i and near - near_i >= keep * (c - count_i)):
        return False  # along the rays, a region's own points must lie on the joint plane, however small it is
    return near >= keep * c and joint / c <= spread * spread * (mine / c)


@numba.njit(**_NUMPY_JIT)
def compete_distances(search: np.ndarray, planes: np.ndarray, tolerance: np.ndarray, viewpoint: np.ndarray,
                      min_cos: float) -> np.ndarray:
    """(k + 1, m) the distance of each point of ``search`` (3, m) meters to each of the ``planes`` (k, 4) along its
    ray from ``viewpoint`` (3,): the distance over the ray's |cos| with the normal, at least ``min_cos``; inf beyond
    ``tolerance`` ((1,) or (m,) meters) and in row k (no region); NaN for a point at the viewpoint."""
    k, m = planes.shape[0], search.shape[1]
    per_point = tolerance.shape[0] > 1
    dist = np.empty((k + 1, m))
    for p in range(m):
        x, y, z = search[0, p], search[1, p], search[2, p]
        rx, ry, rz = x - viewpoint[0], y - viewpoint[1], z - viewpoint[2]
        size = _length(rx, ry, rz)
        rx, ry, rz = rx / size, ry / size, rz / size
        tol = tolerance[p] if per_point else tolerance[0]
        for j in range(k):
            e = abs(planes[j, 0] * x + planes[j, 1] * y + planes[j, 2] * z + planes[j, 3])
            if e > tol:
                e = np.inf
            facing = abs(planes[j, 0] * rx + planes[j, 1] * ry + planes[j, 2] * rz)
            dist[j, p] = e / (facing if np.isnan(facing) or facing > min_cos else min_cos)
        dist[k, p] = np.inf
    return dist


@numba.njit(**_NUMPY_JIT)
def plane_bands(cols: np.ndarray, normals: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Of the points ``cols`` (3, m) meters and h planes (``normals`` (h, 3), ``offsets`` (h,)): the distances
    (h, m) meters (inf or NaN for a far-out point) and whether each point lies on the side the normal points to."""
    h, m = normals.shape[0], cols.shape[1]
    dist = np.empty((h, m))
    above = np.empty((h, m), np.bool_)
    for j in range(h):
        nx, ny, nz, d = normals[j, 0], normals[j, 1], normals[j, 2], offsets[j]
        for p in range(m):
            e = nx * cols[0, p] + ny * cols[1, p] + nz * cols[2, p] + d
            dist[j, p] = abs(e)
            above[j, p] = e > 0
    return dist, above


@numba.njit(**_NUMPY_JIT)
def band_counts(dist: np.ndarray, tolerance: np.ndarray, support: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Of the distances ``dist`` (h, m) meters of m points to h planes: the inliers (h, m) (within ``tolerance``,
    (1,) or (m,) meters), the support band (h, m) (within ``support`` times it), the inliers per plane (h,) and the
    MSAC cost (h,): the sum of the squared distances, each at most the tolerance (NaN with a NaN distance)."""
    h, m = dist.shape
    per_point = tolerance.shape[0] > 1
    inliers = np.empty((h, m), np.bool_)
    band = np.empty((h, m), np.bool_)
    counts = np.zeros(h, np.int64)
    cost = np.zeros(h)
    for j in range(h):
        for p in range(m):
            t = tolerance[p] if per_point else tolerance[0]
            e = dist[j, p]
            inliers[j, p] = e <= t
            band[j, p] = e <= support * t
            counts[j] += e <= t
            if e > t:
                e = t
            cost[j] += e * e
    return inliers, band, counts, cost


@numba.njit(**_NUMPY_JIT)
def triple_planes(cols: np.ndarray, idx: np.ndarray, min_sine: float) -> tuple[np.ndarray, np.ndarray]:
    """The planes through the triples ``idx`` (h, 3) of the points ``cols`` (3, n) meters, in order, without the
    degenerate ones (the cross product of the two edges from the first point at most ``min_sine`` times the product
    of their lengths: nearly collinear or repeated points): (unit normals (g, 3), offsets (g,) meters). Rounded as
    numpy's np.cross, norms and einsum round them."""
    h = idx.shape[0]
    normals = np.empty((h, 3))
    offsets = np.empty(h)
    g = 0
    for q in range(h):
        a, b, c = idx[q, 0], idx[q, 1], idx[q, 2]
        x0, y0, z0 = cols[0, a], cols[1, a], cols[2, a]
        ux, uy, uz = cols[0, b] - x0, cols[1, b] - y0, cols[2, b] - z0
        vx, vy, vz = cols[0, c] - x0, cols[1, c] - y0, cols[2, c] - z0
        nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        size = _length(nx, ny, nz)
        if not size > min_sine * (_length(ux, uy, uz) * _length(vx, vy, vz)):
            continue
        nx, ny, nz = nx / size, ny / size, nz / size
        normals[g, 0], normals[g, 1], normals[g, 2] = nx, ny, nz
        offsets[g] = -_dot(nx, ny, nz, x0, y0, z0)
        g += 1
    return normals[:g], offsets[:g]


@numba.njit(**_NUMPY_JIT)
def coherent_inliers(inliers: np.ndarray, normal: np.ndarray, normals: np.ndarray, min_cos: float) -> int:
    """How many of the points ``inliers`` (m,) bool have a local normal (``normals`` (3, m), NaN: unknown) within
    ``min_cos`` of the plane's ``normal`` (3,), or an unknown one."""
    count = 0
    for p in range(inliers.shape[0]):
        if inliers[p] and not abs(normal[0] * normals[0, p] + normal[1] * normals[1, p]
                                   + normal[2] * normals[2, p]) < min_cos:
            count += 1
    return count


@numba.njit(**_NUMPY_JIT)
def largest_magnitude(values: np.ndarray) -> float:
    """The largest |v| of the ``values`` (n,) that are not NaN (inf counts); NaN when none is."""
    a = b = c = d = -1.0  # four running maxima (NaN never compares greater): no branch in the loop
    blocks = values.shape[0] // 4
    for q in range(blocks):
        i = 4 * q
        v, w, x, y = abs(values[i]), abs(values[i + 1]), abs(values[i + 2]), abs(values[i + 3])
        a = v if v > a else a
        b = w if w > b else b
        c = x if x > c else c
        d = y if y > d else d
    largest = max(max(a, b), max(c, d))
    for i in range(4 * blocks, values.shape[0]):
        v = abs(values[i])
        largest = v if v > largest else largest
    return largest if largest >= 0 else np.nan


# --- indices ---


#: Labels from -1 to this bound are counted in one pass; a cloud with others takes a second pass.
_TABLE_LABELS = 4096
#: The mark of a row with a non-finite coordinate in :func:`label_census`'s compact labels.
NOT_FINITE = -2


@numba.njit(**_JIT)
def label_census(points: np.ndarray, labels: np.ndarray, compact: np.ndarray, finite: bool = False
                 ) -> tuple[int, int, int, np.ndarray]:
    """Of the rows of ``points`` (N, 3) with three finite coordinates and their ``labels`` (N,) (every negative one
    counting as -1): (n such rows, m of them labelled >= 0, the smallest label, count (span,) rows per label from
    it on). Fills ``compact`` (N,) int32 with each row's label, NOT_FINITE where a coordinate is not finite, for
    :func:`rows_at_ranks` to read instead of the points and labels (a sixteenth of the memory). The count is
    empty when n = 0, when the labels span more than 4 n + 1024 values (a table that large is the caller's to
    avoid) or when a label does not fit in int32 (then ``compact`` is not to be used). With ``finite`` the caller
    knows every row to be finite (rows a frame's read kept): the points are not read, only the labels (a
    seventh of the memory)."""
    count = np.zeros(_TABLE_LABELS + 1, np.int64)  # labels -1 .. _TABLE_LABELS - 1
    n = 0
    low = high = np.int64(0)
    current, run, outside = np.int64(-2), 0, False
    i, rows = 0, labels.shape[0]
    if finite:
        for q in range(rows):  # no branch: a copy the compiler vectorizes
            compact[q] = max(labels[q], -1)
    while i < rows:
        step = 1  # rows of this row's label taken at once: with finite, its whole run (found eight at a time)
        if finite:
            step = _run_end(labels, i + 1, labels[i]) - i
        else:
            x, y, z = points[i, 0], points[i, 1], points[i, 2]
            if not (x - x) + (y - y) + (z - z) == 0.0:  # NaN unless all three are finite
                compact[i] = NOT_FINITE
                i += 1
                continue
        lab = np.int64(max(labels[i], -1))
        if not finite:
            compact[i] = lab
        if lab != current:  # runs of one label are the rule: a count kept in a register, not one in memory per row
            if n == 0 or lab < low:
                low = lab
            if n == 0 or lab > high:
                high = lab
            if -1 <= current < _TABLE_LABELS:
                count[current + 1] += run
            current, run = lab, 0
            outside |= lab >= _TABLE_LABELS
        n += step
        run += step
        i += step
    if -1 <= current < _TABLE_LABELS:
        count[current + 1] += run
    m = n - count[0]
    if n == 0 or high - low >= 4 * n + 1024 or high > np.iinfo(np.int32).max:
        return n, m, low, np.zeros(0, np.int64)
    if not outside:
        return n, m, low, count[low + 1:high + 2].copy()
    count = np.zeros(high - low + 1, np.int64)
    for i in range(labels.shape[0]):
        if compact[i] != NOT_FINITE:
            count[compact[i] - low] += 1
    return n, m, low, count


@numba.njit(**_JIT)
def _run_end(values: np.ndarray, start: int, value) -> int:
    """The first index from ``start`` on where ``values`` (n,) is not ``value`` (n when there is none): eight values
    compared at a time, a fixed count the compiler turns into vector compares (labels come in runs of hundreds)."""
    n = values.shape[0]
    end = start
    while end + 8 <= n:
        same = True
        for t in range(8):
            same &= values[end + t] == value
        if not same:
            break
        end += 8
    while end < n and values[end] == value:
        end += 1
    return end


@numba.njit(**_JIT)
def rows_at_ranks(compact: np.ndarray, low: int, cluster: np.ndarray, ranks: np.ndarray, bounds: np.ndarray
                  ) -> np.ndarray:
    """Input rows of chosen members of clusters, in one streaming pass over the ``compact`` labels (N,) of
    :func:`label_census`: a row labelled l belongs to cluster ``cluster[l - low]`` (-1: none); cluster c's members
    in row order are numbered from 0, and ``ranks[bounds[c]:bounds[c + 1]]`` (ascending, repeats allowed) are the
    ones wanted. Returns (len(ranks),) int64: the row of each wanted rank, in the order of ``ranks``."""
    k, n = bounds.shape[0] - 1, compact.shape[0]
    out = np.empty(ranks.shape[0], np.int64)
    seen = np.zeros(k, np.int64)
    at = bounds[:-1].copy()
    left = ranks.shape[0]
    i = 0
    while i < n and left > 0:  # run by run: labels come in runs, and a run's wanted rows follow from its start
        lab = compact[i]
        end = _run_end(compact, i + 1, lab)
        c = cluster[lab - low] if lab != NOT_FINITE else -1
        if c >= 0:
            first, stop = seen[c], seen[c] + (end - i)  # the run holds cluster c's members first .. stop - 1
            while at[c] < bounds[c + 1] and ranks[at[c]] < stop:
                out[at[c]] = i + (ranks[at[c]] - first)
                at[c] += 1
                left -= 1
            seen[c] = stop
        i = end
    return out


@numba.njit(**_JIT)
def _sum_max_min(d: np.ndarray) -> tuple[float, float, float]:
    """Sum, largest and smallest of ``d`` (m,) (m > 0), in four interleaved lanes: a fixed order, so the same on
    every machine, and independent lanes keep the pipeline full where one running sum would wait on each add."""
    m = d.shape[0]
    s0 = s1 = s2 = s3 = 0.0
    big = small = d[0]
    for q in range(m // 4):  # indices counted from 0 (a slice): numba's negative-index wrap needs no check
        a, b, c, e = d[4 * q], d[4 * q + 1], d[4 * q + 2], d[4 * q + 3]
        s0 += a
        s1 += b
        s2 += c
        s3 += e
        big = max(big, max(max(a, b), max(c, e)))
        small = min(small, min(min(a, b), min(c, e)))
    for q in range(m - m % 4, m):
        s0 += d[q]
        big = max(big, d[q])
        small = min(small, d[q])
    return (s0 + s1) + (s2 + s3), big, small


@numba.njit(**_JIT)
def cluster_distance_pass(points: np.ndarray, starts: np.ndarray, sizes: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One pass over every pair of ``points`` (n, 3), grouped by cluster (cluster c is rows ``starts[c]`` to
    ``starts[c] + sizes[c]``, each non-empty, in order): (sums (n, K): summed Euclidean distances from each row
    to the rows of each cluster, itself included at 0; diameters (K,): the largest distance within each cluster,
    0 for one row; gaps (K, K): the smallest distance between two clusters, 0 on the diagonal). Units of points.
    Each pair's distance is computed once: O(n^2) time, O(n K) memory."""
    n, k = points.shape[0], starts.shape[0]
    xs, ys, zs = points[:, 0].copy(), points[:, 1].copy(), points[:, 2].copy()
    earlier = np.zeros((k, n))  # earlier[c, j]: summed distances from row j to the rows of cluster c before it
    sums = np.empty((n, k))
    diameters = np.zeros(k)
    gaps = np.full((k, k), np.inf)
    dist = np.empty(n)
    for c in range(k):
        gaps[c, c] = 0.0
        for i in range(starts[c], starts[c] + sizes[c]):
            x, y, z = xs[i], ys[i], zs[i]
            # the rows after i through slices indexed from 0, so that the loops vectorize (see _sum_max_min)
            xr, yr, zr, d, acc = xs[i + 1:], ys[i + 1:], zs[i + 1:], dist[i + 1:], earlier[c, i + 1:]
            for j in range(d.shape[0]):
                dx, dy, dz = xr[j] - x, yr[j] - y, zr[j] - z
                d[j] = np.sqrt(dx * dx + dy * dy + dz * dz)
                acc[j] += d[j]
            for e in range(k):
                if e < c:
                    sums[i, e] = earlier[e, i]
                    continue
                lo, hi = max(i + 1, starts[e]), starts[e] + sizes[e]
                later, big, small = _sum_max_min(dist[lo:hi]) if lo < hi else (0.0, 0.0, np.inf)
                if e == c:
                    sums[i, e] = earlier[e, i] + later
                    diameters[c] = max(diameters[c], big)
                else:
                    sums[i, e] = later
                    if small < gaps[c, e]:
                        gaps[c, e] = gaps[e, c] = small
    return sums, diameters, gaps


@numba.njit(**_JIT)
def region_scatter(points: np.ndarray, origin: np.ndarray, members: np.ndarray, bounds: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Per region j, the points ``points[members[bounds[j]:bounds[j + 1]]] - origin`` ((N, 3), (3,) meters):
    (centroids (k, 3), scatter matrices (k, 3, 3) about them, m^2); zeros for a region without points."""
    k = bounds.shape[0] - 1
    centroids = np.zeros((k, 3))
    scatter = np.zeros((k, 3, 3))
    for j in range(k):
        lo, hi = bounds[j], bounds[j + 1]
        if hi == lo:
            continue
        sx = sy = sz = 0.0
        for q in range(lo, hi):
            p = members[q]
            sx += points[p, 0] - origin[0]
            sy += points[p, 1] - origin[1]
            sz += points[p, 2] - origin[2]
        cx, cy, cz = sx / (hi - lo), sy / (hi - lo), sz / (hi - lo)
        xx = xy = xz = yy = yz = zz = 0.0
        for q in range(lo, hi):
            p = members[q]
            x, y, z = points[p, 0] - origin[0] - cx, points[p, 1] - origin[1] - cy, points[p, 2] - origin[2] - cz
            xx += x * x
            xy += x * y
            xz += x * z
            yy += y * y
            yz += y * z
            zz += z * z
        centroids[j, 0], centroids[j, 1], centroids[j, 2] = cx, cy, cz
        scatter[j, 0, 0], scatter[j, 0, 1], scatter[j, 0, 2] = xx, xy, xz
        scatter[j, 1, 0], scatter[j, 1, 1], scatter[j, 1, 2] = xy, yy, yz
        scatter[j, 2, 0], scatter[j, 2, 1], scatter[j, 2, 2] = xz, yz, zz
    return centroids, scatter


@numba.njit(**_JIT)
def _quantile_at(m: int, q: float) -> tuple[int, int, float]:
    """Where the ``q`` quantile (0 <= q <= 1) of m > 0 sorted values lies, by linear interpolation in numpy's
    arithmetic (np.percentile's default method): (the index below, the one above, the weight of the one above)."""
    virtual = (m - 1) * q
    if virtual >= m - 1:
        return m - 1, m - 1, 0.0
    if virtual < 0.0:
        return 0, 0, 0.0
    below = np.floor(virtual)
    return np.int64(below), np.int64(below) + 1, virtual - below


@numba.njit(**_JIT)
def _lerp(a: float, b: float, gamma: float) -> float:
    """numpy's interpolation between a and b at weight ``gamma`` of b (the same rounding as np.percentile)."""
    diff = b - a
    return b - diff * (1.0 - gamma) if gamma >= 0.5 else a + diff * gamma


@numba.njit(**_JIT)
def region_extents(points: np.ndarray, origin: np.ndarray, members: np.ndarray, bounds: np.ndarray,
                   centroids: np.ndarray, axes: np.ndarray, low_q: float, high_q: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per region j (its points as in :func:`region_scatter`, ``centroids`` (k, 3) and ``axes`` (k, 3, 3) rows u, v,
    normal): the ``low_q`` and ``high_q`` quantiles (0..1) of its points along u and v (lo, hi (k, 2) meters) and
    their RMS distance from the centroid in the plane (k,) meters; zeros for a region without points."""
    k = bounds.shape[0] - 1
    lo_out, hi_out, radius = np.zeros((k, 2)), np.zeros((k, 2)), np.zeros(k)
    for j in range(k):
        start, stop = bounds[j], bounds[j + 1]
        m = stop - start
        if m == 0:
            continue
        uv = np.empty((2, m))
        square = 0.0
        for q in range(m):
            p = members[start + q]
            x = points[p, 0] - origin[0] - centroids[j, 0]
            y = points[p, 1] - origin[1] - centroids[j, 1]
            z = points[p, 2] - origin[2] - centroids[j, 2]
            u = x * axes[j, 0, 0] + y * axes[j, 0, 1] + z * axes[j, 0, 2]
            v = x * axes[j, 1, 0] + y * axes[j, 1, 1] + z * axes[j, 1, 2]
            uv[0, q], uv[1, q] = u, v
            square += u * u + v * v
        a0, a1, ga = _quantile_at(m, low_q)
        b0, b1, gb = _quantile_at(m, high_q)
        for axis in range(2):
            va0, va1, vb0, vb1 = order_statistics(uv[axis], a0, a1, b0, b1)
            lo_out[j, axis] = _lerp(va0, va1, ga)
            hi_out[j, axis] = _lerp(vb0, vb1, gb)
        radius[j] = np.sqrt(square / m)
    return lo_out, hi_out, radius


@numba.njit(**_JIT)
def _nan_max(a: float, b: float) -> float:
    """The larger of a and b, NaN when either is (as np.maximum)."""
    return a if a > b or a != a else b


@numba.njit(**_JIT)
def _nan_min(a: float, b: float) -> float:
    """The smaller of a and b, NaN when either is (as np.minimum)."""
    return a if a < b or a != a else b


@numba.njit(**_JIT)
def plane_silhouette_sum(x: np.ndarray, own: np.ndarray, centroids: np.ndarray, axes: np.ndarray, lo: np.ndarray,
                         hi: np.ndarray, radius: np.ndarray) -> float:
    """Sum of the plane silhouettes s_i of the points ``x`` (m, 3) meters on the regions ``own`` (m,) (0..k-1),
    given each region's frame: ``centroids`` (k, 3), ``axes`` (k, 3, 3) rows u, v, normal, in-plane extents ``lo``,
    ``hi`` (k, 2) and RMS radii ``radius`` (k,). a_i: distance to its own region's infinite plane; b_i: distance to
    the nearest other region's plane clipped to its extent, at most its own radius; s_i = (b_i - a_i) / max(a_i,
    b_i), 0 where both are 0 or either is NaN (an overflow)."""
    m, k = x.shape[0], centroids.shape[0]
    total = 0.0
    for i in range(m):
        j = own[i]
        a = 0.0
        nearest = np.inf
        for r in range(k):
            rx, ry, rz = x[i, 0] - centroids[r, 0], x[i, 1] - centroids[r, 1], x[i, 2] - centroids[r, 2]
            perp = abs(rx * axes[r, 2, 0] + ry * axes[r, 2, 1] + rz * axes[r, 2, 2])
            if r == j:
                a = perp
                continue
            u = rx * axes[r, 0, 0] + ry * axes[r, 0, 1] + rz * axes[r, 0, 2]
            v = rx * axes[r, 1, 0] + ry * axes[r, 1, 1] + rz * axes[r, 1, 2]
            ou = _nan_max(_nan_max(lo[r, 0] - u, u - hi[r, 0]), 0.0)
            ov = _nan_max(_nan_max(lo[r, 1] - v, v - hi[r, 1]), 0.0)
            nearest = _nan_min(nearest, np.sqrt(perp * perp + (ou * ou + ov * ov)))
        b = _nan_min(nearest, radius[j])
        top = _nan_max(a, b)
        if top > 0.0:
            total += (b - a) / top
    return total


# --- frame outside the search ---


@numba.njit(**_JIT)
def marked_rows(points: np.ndarray, view: np.ndarray, within: float) -> int:
    """How many rows of ``points`` (N, 3) lie at a driver's "no return" mark: exactly (0, 0, 0) when ``view`` (3,)
    is the origin, else within ``within`` (meters, in each coordinate) of ``view``."""
    count = 0
    if view[0] == 0.0 and view[1] == 0.0 and view[2] == 0.0:
        for i in range(points.shape[0]):
            if points[i, 0] == 0.0 and points[i, 1] == 0.0 and points[i, 2] == 0.0:
                count += 1
        return count
    for i in range(points.shape[0]):
        if (abs(points[i, 0] - view[0]) <= within and abs(points[i, 1] - view[1]) <= within
                and abs(points[i, 2] - view[2]) <= within):
            count += 1
    return count


@numba.njit(**_JIT)
def near_count(a: np.ndarray, b: np.ndarray, radius: float) -> int:
    """How many rows of ``a`` (m, 3) have a row of ``b`` (p, 3) closer than ``radius`` (meters; squared distances
    compared with radius ** 2, as a kd-tree query bounded by it). A row's scan of ``b`` starts at the row that was near
    the row before it (a sample's neighbouring rows lie near each other), and a row farther than ``radius`` from the
    box around ``b`` in a coordinate is not scanned: the same count in a fraction of the pairs."""
    bound = radius * radius
    p = b.shape[0]
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for j in range(p):
        for c in range(3):
            if b[j, c] < lo[c]:
                lo[c] = b[j, c]
            if b[j, c] > hi[c]:
                hi[c] = b[j, c]
    count = start = 0
    for i in range(a.shape[0]):
        x, y, z = a[i, 0], a[i, 1], a[i, 2]
        outside = False
        for c in range(3):  # (a margin above radius: no pair that passes the test below is left out by rounding)
            v = a[i, c]
            reach = radius * 1.000001 + 1e-9 * abs(v)
            outside |= v < lo[c] - reach or v > hi[c] + reach
        if outside:
            continue
        for s in range(p):
            j = start + s if start + s < p else start + s - p
            dx, dy, dz = x - b[j, 0], y - b[j, 1], z - b[j, 2]
            if dx * dx + dy * dy + dz * dz < bound:
                count += 1
                start = j
                break
    return count


@numba.njit(**_JIT)
def beyond_counts(box: np.ndarray, d: np.ndarray, labels: np.ndarray, t: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                  surface: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per plane j, among the m points inside its in-plane box (``box`` (m, 2k): their coordinates along its two
    in-plane axes, columns 2j and 2j + 1, between ``lo`` and ``hi`` (2k,)): how many lie within ``t`` of it (``d``
    (m, k): their distances to each plane, meters), and how many at t..2t that are not labelled (``labels`` (m,))
    with a plane l that ``surface`` (k, k) bool [j, l] excuses. ``t``: (1,) one tolerance, or (m,) one per point."""
    m, k = d.shape[0], d.shape[1]
    within = np.zeros(k, np.int64)
    beyond = np.zeros(k, np.int64)
    for i in range(m):
        tol = t[i] if t.shape[0] > 1 else t[0]
        lab = labels[i]
        for j in range(k):
            u, v = box[i, 2 * j], box[i, 2 * j + 1]
            if not (u >= lo[2 * j] and u <= hi[2 * j] and v >= lo[2 * j + 1] and v <= hi[2 * j + 1]):
                continue
            if d[i, j] <= tol:
                within[j] += 1
            elif d[i, j] <= 2 * tol and not (lab >= 0 and surface[j, lab]):
                beyond[j] += 1
    return within, beyond


@numba.njit(**_JIT)
def distinct_rows(points: np.ndarray, rows: np.ndarray) -> int:
    """How many distinct points (equal in all three coordinates) the ``rows`` (m,) of ``points`` (N, 3) are: each
    against the earlier ones, O(m^2)."""
    count = 0
    for a in range(rows.shape[0]):
        i = rows[a]
        seen = False
        for b in range(a):
            j = rows[b]
            if points[i, 0] == points[j, 0] and points[i, 1] == points[j, 1] and points[i, 2] == points[j, 2]:
                seen = True
                break
        if not seen:
            count += 1
    return count


@numba.njit(**_JIT)
def coordinate_extent(points: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, bool, bool]:
    """Over the ``rows`` of ``points`` (N, 3) with three finite coordinates: the largest magnitude of each coordinate
    (3,), whether every one of their coordinates is a float32 number, and whether there was such a row."""
    largest = np.zeros(3)
    single = True
    seen = False
    for r in range(rows.shape[0]):
        i = rows[r]
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
            continue
        seen = True
        for a, v in enumerate((x, y, z)):
            largest[a] = max(largest[a], abs(v))
            single = single and np.float64(np.float32(v)) == v
    return largest, single, seen


@numba.njit(**_JIT)
def _silhouette(a: float, b: float) -> float:
    top = max(a, b)
    return (b - a) / top if top > 0.0 else 0.0


@numba.njit(**_JIT)
def silhouettes(sums: np.ndarray, codes: np.ndarray, sizes: np.ndarray, has_rest: bool
                ) -> tuple[np.ndarray, np.ndarray]:
    """Each row's silhouette among all K clusters and among the planes alone, (n,) each, from its summed distances
    to each cluster ``sums`` (n, K) (K >= 2), its cluster ``codes`` (n,) and the clusters' ``sizes`` (K,): a the
    mean distance to the others of its own, b the smallest mean distance to another (``has_rest``: cluster 0 is the
    unassigned points, no plane: NaN on its rows, no candidate for b among the planes; with one plane, 0); 0 on a
    cluster of one row."""
    n, k = sums.shape
    s = np.zeros(n)
    s_planes = np.zeros(n)
    for i in range(n):
        c = codes[i]
        a = sums[i, c] / max(sizes[c] - 1, 1)
        b = b_planes = np.inf
        for e in range(k):
            if e != c:
                mean = sums[i, e] / sizes[e]
                b = min(b, mean)
                if e > 0:
                    b_planes = min(b_planes, mean)
        single = sizes[c] == 1
        s[i] = 0.0 if single else _silhouette(a, b)
        if not has_rest:
            s_planes[i] = s[i]
        elif c == 0:
            s_planes[i] = np.nan
        elif k >= 3 and not single:
            s_planes[i] = _silhouette(a, b_planes)
    return s, s_planes


@numba.njit(**_JIT)
def patch_eigenvalues(m: np.ndarray) -> np.ndarray:
    """The eigenvalues (p, 3), ascending, of symmetric 3 x 3 matrices ``m`` (p, 3, 3), by the trigonometric closed
    form, the same steps as ``plane_shape.symmetric_eigenvalues`` (its numpy reference)."""
    out = np.empty((m.shape[0], 3))
    for i in range(m.shape[0]):
        a = m[i]
        off = a[0, 1] ** 2 + a[0, 2] ** 2 + a[1, 2] ** 2
        d0, d1, d2 = a[0, 0], a[1, 1], a[2, 2]
        if off == 0:  # diagonal: its entries, sorted
            lo, hi = min(d0, d1), max(d0, d1)
            out[i, 0], out[i, 1], out[i, 2] = min(lo, d2), max(lo, min(hi, d2)), max(hi, d2)
            continue
        q = (d0 + d1 + d2) / 3
        p = np.sqrt((((d0 - q) ** 2 + (d1 - q) ** 2) + (d2 - q) ** 2 + 2 * off) / 6)
        safe = p if p > 0 else 1.0
        b00, b11, b22 = (d0 - q) / safe, (d1 - q) / safe, (d2 - q) / safe
        b01, b02, b12 = a[0, 1] / safe, a[0, 2] / safe, a[1, 2] / safe
        b10, b20, b21 = a[1, 0] / safe, a[2, 0] / safe, a[2, 1] / safe
        det = (b00 * (b11 * b22 - b12 * b21) - b01 * (b10 * b22 - b12 * b20) + b02 * (b10 * b21 - b11 * b20))
        phi = np.arccos(min(max(det / 2, -1.0), 1.0)) / 3
        big = q + 2 * p * np.cos(phi)
        small = q + 2 * p * np.cos(phi + 2 * np.pi / 3)
        out[i, 0], out[i, 1], out[i, 2] = small, 3 * q - big - small, big
    return out


# --- graph ---


@numba.njit(**_JIT)
def _by_voxel(queries: np.ndarray, cell_keys: np.ndarray, table: np.ndarray, origin: np.ndarray, cell: float,
              dims: np.ndarray, dense: bool) -> tuple[np.ndarray, np.ndarray]:
    """The ``queries`` (q, 3) grouped by the occupied voxel of :func:`voxel_grid` they lie in: (rows (q,), voxel by
    voxel, in their order within one; bounds (c + 2,): voxel v's from bounds[v] to bounds[v + 1], those in no occupied
    voxel last, from bounds[c])."""
    nq, c = queries.shape[0], cell_keys.shape[0]
    home = np.empty(nq, np.int64)  # each query's occupied voxel, c where none
    count = np.zeros(c + 2, np.int64)
    for q in range(nq):
        fx = (queries[q, 0] - origin[0]) / cell
        fy = (queries[q, 1] - origin[1]) / cell
        fz = (queries[q, 2] - origin[2]) / cell
        v = c
        if 0.0 <= fx < dims[0] and 0.0 <= fy < dims[1] and 0.0 <= fz < dims[2]:
            v = _voxel(cell_keys, table, int(fx) + dims[0] * (int(fy) + dims[1] * int(fz)), dense)
            if v < 0:
                v = c
        home[q] = v
        count[v + 2] += 1
    for v in range(c + 1):
        count[v + 2] += count[v + 1]
    grouped = np.empty(nq, np.int64)
    for q in range(nq):
        grouped[count[home[q] + 1]] = q
        count[home[q] + 1] += 1
    return grouped, count


@numba.njit(**_JIT)
def _occupied_around(cell_keys: np.ndarray, table: np.ndarray, dims: np.ndarray, dense: bool, vx: int, vy: int,
                     vz: int, around: np.ndarray, offset: np.ndarray) -> int:
    """How many of the 26 voxels next to (vx, vy, vz) are occupied; those voxels into ``around``, their offsets into
    ``offset`` (0, 1, 2: below, level with, above it along each axis), in :data:`_BLOCK`'s order: those across a face
    first, whose points most often bound a query's nearest distance so that the farther voxels are skipped."""
    m = 0
    for b in range(1, 27):
        dx, dy, dz = _BLOCK[b, 0], _BLOCK[b, 1], _BLOCK[b, 2]
        ix, iy, iz = vx + dx, vy + dy, vz + dz
        if 0 <= ix < dims[0] and 0 <= iy < dims[1] and 0 <= iz < dims[2]:
            u = _voxel(cell_keys, table, ix + dims[0] * (iy + dims[1] * iz), dense)
            if u >= 0:
                around[m] = u
                offset[m, 0], offset[m, 1], offset[m, 2] = dx + 1, dy + 1, dz + 1
                m += 1
    return m


@numba.njit(**_JIT)
def _faces(face: np.ndarray, f: np.ndarray, c: np.ndarray, cell: float) -> float:
    """Into ``face`` (3, 3): the squared gaps (m^2) from a query at voxel coordinates ``f`` (3,) in voxel ``c`` (3,)
    to the voxels below (column 0) and above (column 2) along each axis, as :func:`_gap` gives them; returns how far
    (meters) it lies inside its voxel."""
    margin = np.inf
    for axis in range(3):
        below, above = (f[axis] - c[axis]) * cell, (c[axis] + 1 - f[axis]) * cell
        face[axis, 0], face[axis, 2] = below * below, above * above
        margin = min(margin, f[axis] - c[axis], c[axis] + 1 - f[axis])
    return margin * cell


@numba.njit(**_JIT)
def _nearest_in_voxel(points: np.ndarray, starts: np.ndarray, v: int, around: np.ndarray, offset: np.ndarray, m: int,
                      queries: np.ndarray, rows: np.ndarray, origin: np.ndarray, cell: float, c: np.ndarray,
                      found: np.ndarray, d2: np.ndarray) -> None:
    """:func:`voxel_nearest` for the queries ``rows`` in the voxel at ``c`` (3,), the occupied voxel ``v`` (-1: an empty
    one), with the ``m`` occupied voxels ``around`` it at ``offset``: each one's nearest point (position in the hashed
    order) into ``found`` and its squared distance into ``d2``, -1 where it is not certain within them."""
    face = np.zeros((3, 3))
    f = np.empty(3)
    for g in range(rows.shape[0]):
        q = rows[g]
        x, y, z = queries[q, 0], queries[q, 1], queries[q, 2]
        f[0], f[1], f[2] = (x - origin[0]) / cell, (y - origin[1]) / cell, (z - origin[2]) / cell
        margin = _faces(face, f, c, cell)
        b, bj = np.inf, -1
        # its own voxel's points (none in an empty one) ascending: the first of equal distances stays
        for j in range(starts[v] if v >= 0 else 0, starts[v + 1] if v >= 0 else 0):
            ex, ey, ez = points[j, 0] - x, points[j, 1] - y, points[j, 2] - z
            e = ex * ex + ey * ey + ez * ez
            if e < b:
                b, bj = e, j
        reach = margin
        if not b <= margin * margin:
            for a in range(m):
                if face[0, offset[a, 0]] + (face[1, offset[a, 1]] + face[2, offset[a, 2]]) > b:
                    continue
                u = around[a]
                for j in range(starts[u], starts[u + 1]):
                    ex, ey, ez = points[j, 0] - x, points[j, 1] - y, points[j, 2] - z
                    e = ex * ex + ey * ey + ez * ez
                    if e < b or (e == b and j < bj):
                        b, bj = e, j
            reach = cell + margin
        found[g], d2[g] = (bj, b) if b <= reach * reach else (-1, np.inf)


@numba.njit(**_JIT)
def _nearest_of_voxel(points: np.ndarray, order: np.ndarray, cell_keys: np.ndarray, starts: np.ndarray,
                      table: np.ndarray, origin: np.ndarray, cell: float, dims: np.ndarray, dense: bool,
                      queries: np.ndarray, rows: np.ndarray, key: int, v: int, rest: np.ndarray, left: int,
                      found: np.ndarray, d2: np.ndarray, dist: np.ndarray, idx: np.ndarray, exact: np.ndarray,
                      around: np.ndarray, offset: np.ndarray, c: np.ndarray) -> int:
    """:func:`voxel_nearest` for its queries ``rows`` in the voxel of ``key`` (the occupied voxel ``v``, -1: an empty
    one): each certain one's distance, point and True into ``dist``, ``idx``, ``exact``; the others appended to
    ``rest`` from ``left``. Returns how many ``rest`` holds then. ``around`` (26,), ``offset`` (26, 3), ``c`` (3,):
    room for :func:`_occupied_around`'s answer and the voxel's coordinates."""
    c[0], c[1], c[2] = key % dims[0], (key // dims[0]) % dims[1], key // (dims[0] * dims[1])
    m = _occupied_around(cell_keys, table, dims, dense, c[0], c[1], c[2], around, offset)
    _nearest_in_voxel(points, starts, v, around, offset, m, queries, rows, origin, cell, c, found, d2)
    for g in range(rows.shape[0]):
        q = rows[g]
        if found[g] < 0:
            rest[left] = q
            left += 1
        else:
            exact[q] = True
            dist[q, 0], idx[q, 0] = np.sqrt(d2[g]), order[found[g]]
    return left


@numba.njit(**_JIT)
def voxel_nearest(points: np.ndarray, order: np.ndarray, cell_keys: np.ndarray, starts: np.ndarray, table: np.ndarray,
                  origin: np.ndarray, cell: float, dims: np.ndarray, queries: np.ndarray, max_ring: int
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`voxel_knn` with k = 1, the same answer, with the queries taken voxel by voxel (an occupied voxel's, then
    an empty one's): the occupied voxels around each query voxel are looked up once for all its queries, which mostly
    find their nearest within them; the others (outside the grid, or with the nearest farther out) are answered by
    :func:`voxel_knn`. (For more than the nearest, the k-th often lies beyond the voxels around: query by query is as
    fast.)"""
    nq, n_voxels = queries.shape[0], cell_keys.shape[0]
    total = dims[0] * dims[1] * dims[2]
    dense = table.shape[0] == total and total <= max(DENSE_VOXELS, 8 * points.shape[0])
    grouped, bounds = _by_voxel(queries, cell_keys, table, origin, cell, dims, dense)
    dist = np.full((nq, 1), np.inf)
    idx = np.full((nq, 1), -1, np.int64)
    exact = np.zeros(nq, np.bool_)
    found = np.empty(max(1, int(np.max(np.diff(bounds)))) if nq else 1, np.int64)
    d2 = np.empty(found.shape[0])
    around = np.empty(26, np.int64)
    offset = np.empty((26, 3), np.int64)
    c = np.empty(3, np.int64)
    left = 0  # the queries not answered here, moved to the front of grouped
    for v in range(n_voxels):
        if bounds[v + 1] > bounds[v]:
            left = _nearest_of_voxel(points, order, cell_keys, starts, table, origin, cell, dims, dense, queries,
                                     grouped[bounds[v]:bounds[v + 1]], cell_keys[v], v, grouped, left, found, d2, dist,
                                     idx, exact, around, offset, c)
    empty = grouped[bounds[n_voxels]:nq].copy()  # in no occupied voxel: grouped by their empty voxel's key
    keys = np.full(empty.shape[0], -1, np.int64)
    for g in range(empty.shape[0]):
        q = empty[g]
        fx = (queries[q, 0] - origin[0]) / cell
        fy = (queries[q, 1] - origin[1]) / cell
        fz = (queries[q, 2] - origin[2]) / cell
        if 0.0 <= fx < dims[0] and 0.0 <= fy < dims[1] and 0.0 <= fz < dims[2]:
            keys[g] = int(fx) + dims[0] * (int(fy) + dims[1] * int(fz))
    by_key = np.argsort(keys, kind='mergesort')
    empty, keys = empty[by_key], keys[by_key]
    found = np.empty(max(1, empty.shape[0]), np.int64)
    d2 = np.empty(found.shape[0])
    lo = 0
    while lo < empty.shape[0]:
        key = keys[lo]
        hi = lo + 1
        while hi < empty.shape[0] and keys[hi] == key:
            hi += 1
        if key >= 0:
            left = _nearest_of_voxel(points, order, cell_keys, starts, table, origin, cell, dims, dense, queries,
                                     empty[lo:hi], key, -1, grouped, left, found, d2, dist, idx, exact, around,
                                     offset, c)
        else:  # outside the grid: voxel_knn's
            grouped[left:left + hi - lo] = empty[lo:hi]
            left += hi - lo
        lo = hi
    if left:
        rest = grouped[:left]
        far_dist, far_idx, far_exact = voxel_knn(points, order, cell_keys, starts, table, origin, cell, dims,
                                                 queries[rest], 1, max_ring)
        for g in range(left):
            q = rest[g]
            exact[q], dist[q, 0], idx[q, 0] = far_exact[g], far_dist[g, 0], far_idx[g, 0]
    return dist, idx, exact


@numba.njit(**_JIT)
def spread_nearest(points: np.ndarray, rows: np.ndarray, center: np.ndarray, nearest: np.ndarray, region: np.ndarray,
                   planes: np.ndarray, tolerance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Labels (N,) int32 of ``points`` (N, 3) meters: each of ``rows`` (n,) takes the region (``region`` (m,), -1: none)
    of its nearest searched point (``nearest`` (n,): its position among the m) when it lies within ``tolerance`` ((1,)
    or (n,) meters) of that region's plane (``planes`` (k, 4): normal, offset, about ``center`` (3,)); -1 otherwise and
    off ``rows``. Also each point's distance (N,) to the plane of its label, inf where none."""
    labels = np.full(points.shape[0], -1, np.int32)
    residual = np.full(points.shape[0], np.inf)
    cx, cy, cz = center[0], center[1], center[2]
    per_point = tolerance.shape[0] > 1
    for q in range(rows.shape[0]):
        lab = region[nearest[q]]
        if lab < 0:
            continue
        i = rows[q]
        x, y, z = points[i, 0] - cx, points[i, 1] - cy, points[i, 2] - cz
        d = abs(x * planes[lab, 0] + y * planes[lab, 1] + z * planes[lab, 2] + planes[lab, 3])
        if d <= tolerance[q if per_point else 0]:
            labels[i] = lab
            residual[i] = d
    return labels, residual


@numba.njit(**_JIT)
def sensor_rays(points: np.ndarray, viewpoint: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rays from ``viewpoint`` (3,) to ``points`` (n, 3) meters, (n, 3), their elevations about the z axis (n,),
    radians, and their directions (n, 3), unit (a zero ray as is), in one pass."""
    n = points.shape[0]
    rays = np.empty((n, 3))
    elevation = np.empty(n)
    unit = np.empty((n, 3))
    for i in range(n):
        x, y, z = points[i, 0] - viewpoint[0], points[i, 1] - viewpoint[1], points[i, 2] - viewpoint[2]
        rays[i, 0], rays[i, 1], rays[i, 2] = x, y, z
        elevation[i] = np.arctan2(z, np.hypot(x, y))
        length = np.sqrt(x * x + y * y + z * z)
        if not length > 0.0:
            length = 1.0
        unit[i, 0], unit[i, 1], unit[i, 2] = x / length, y / length, z / length
    return rays, elevation, unit


@numba.njit(**_JIT)
def spread_among(values: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """(n,) the largest minus the smallest of ``values[idx[i]]`` (``values`` (m,), ``idx`` (n, k), k >= 1)."""
    n, k = idx.shape
    out = np.empty(n)
    for i in range(n):
        lo = hi = values[idx[i, 0]]
        for j in range(1, k):
            v = values[idx[i, j]]
            if v > hi:
                hi = v
            if v < lo:
                lo = v
        out[i] = hi - lo
    return out


# --- search loop ---


@numba.njit(**_NUMPY_JIT)
def _inliers_on(subset: np.ndarray, tolerance: np.ndarray, point_normals: np.ndarray, nx: float, ny: float, nz: float,
                d: float, lo: int, hi: int, min_cos: float, ray: np.ndarray) -> int:
    """How many of the points ``lo``..``hi`` of ``subset`` (3, s) meters lie within ``tolerance`` ((1,) or (s,)
    meters) of the plane (nx, ny, nz, d) with a local normal (``point_normals`` (3, s), NaN: unknown; (3, 0): none
    known) within ``min_cos`` of its normal; each tolerance times :func:`_facing` of ``ray``."""
    # loops from 0 over views: an index from a variable start could be negative, and its wraparound test
    # keeps the loop from being vectorized (about 15 times slower)
    x, y, z = subset[0, lo:hi], subset[1, lo:hi], subset[2, lo:hi]
    count = 0
    if ray.shape[0] > 0:  # the tolerance along each ray: a loop of its own, the others stay vectorized
        per_point = tolerance.shape[0] > 1
        known = point_normals.shape[1] > 0
        for p in range(x.shape[0]):
            t = (tolerance[lo + p] if per_point else tolerance[0]) * _facing(x[p], y[p], z[p], nx, ny, nz, ray)
            near = abs(nx * x[p] + ny * y[p] + nz * z[p] + d) <= t
            coherent = not known or not abs(nx * point_normals[0, lo + p] + ny * point_normals[1, lo + p] +
                                            nz * point_normals[2, lo + p]) < min_cos
            count += np.int64(near) * np.int64(coherent)
        return count
    if point_normals.shape[1] == 0:
        if tolerance.shape[0] > 1:
            tol = tolerance[lo:hi]
            for p in range(x.shape[0]):
                count += np.int64(abs(nx * x[p] + ny * y[p] + nz * z[p] + d) <= tol[p])
        else:
            t = tolerance[0]
            for p in range(x.shape[0]):
                count += np.int64(abs(nx * x[p] + ny * y[p] + nz * z[p] + d) <= t)
        return count
    a, b, c = point_normals[0, lo:hi], point_normals[1, lo:hi], point_normals[2, lo:hi]
    if tolerance.shape[0] > 1:
        tol = tolerance[lo:hi]
        for p in range(x.shape[0]):
            near = abs(nx * x[p] + ny * y[p] + nz * z[p] + d) <= tol[p]
            coherent = not abs(nx * a[p] + ny * b[p] + nz * c[p]) < min_cos  # NaN: unknown, coherent
            count += np.int64(near) * np.int64(coherent)
        return count
    t = tolerance[0]
    for p in range(x.shape[0]):
        near = abs(nx * x[p] + ny * y[p] + nz * z[p] + d) <= t
        coherent = not abs(nx * a[p] + ny * b[p] + nz * c[p]) < min_cos
        count += np.int64(near) * np.int64(coherent)
    return count


@numba.njit(**_NUMPY_JIT)
def _low_count(count: float, n: int, sigmas: float) -> float:
    """``sigmas`` binomial standard deviations below ``count`` of ``n`` points."""
    return count - sigmas * np.sqrt(count * (1 - count / n))


@numba.njit(**_NUMPY_JIT)
def score_hypotheses(subset: np.ndarray, tolerance: np.ndarray, point_normals: np.ndarray, normals: np.ndarray,
                     offsets: np.ndarray, head: int, min_cos: float, sigmas: float, best_normals: np.ndarray,
                     best_offsets: np.ndarray, best_counts: np.ndarray, n_best: int, ray: np.ndarray) -> int:
    """One batch of RANSAC hypotheses (``normals`` (h, 3), ``offsets`` (h,)) scored on the points ``subset`` (3, s)
    meters (see :func:`_inliers_on`) and merged into the best so far: ``best_normals`` (c, 3), ``best_offsets`` (c,),
    ``best_counts`` (c,), the first ``n_best`` of them held, most inliers first (equals: the earlier), updated in
    place; returns how many are held now. A hypothesis is first scored on the ``head`` first points; only one whose
    count there is at least ``sigmas`` binomial standard deviations (less one point) below the share the c-th best
    holds (before there are c of them: a bound from the c-th best count of this batch on the head) is scored on the
    rest, the others are dropped."""
    s, h, confirm = subset.shape[1], normals.shape[0], best_counts.shape[0]
    counts = np.empty(h, np.int64)
    for j in range(h):
        counts[j] = _inliers_on(subset, tolerance, point_normals, normals[j, 0], normals[j, 1], normals[j, 2],
                                offsets[j], 0, head, min_cos, ray)
    if head < s:
        share = 0.0
        if n_best == confirm:
            share = best_counts[confirm - 1] / s
        elif h >= confirm:
            share = max(0.0, _low_count(float(np.sort(counts)[h - confirm]), head, sigmas)) / head
        bar = _low_count(head * share, head, sigmas) - 1
        for j in range(h):
            if counts[j] >= bar:
                counts[j] += _inliers_on(subset, tolerance, point_normals, normals[j, 0], normals[j, 1],
                                         normals[j, 2], offsets[j], head, s, min_cos, ray)
            else:
                counts[j] = -1
    for j in range(h):
        c = counts[j]
        place = n_best
        while place > 0 and best_counts[place - 1] < c:
            place -= 1
        if c < 0 or place >= confirm:
            continue
        for q in range(min(n_best, confirm - 1), place, -1):
            best_normals[q, 0], best_normals[q, 1], best_normals[q, 2] = \
                best_normals[q - 1, 0], best_normals[q - 1, 1], best_normals[q - 1, 2]
            best_offsets[q], best_counts[q] = best_offsets[q - 1], best_counts[q - 1]
        best_normals[place, 0], best_normals[place, 1], best_normals[place, 2] = \
            normals[j, 0], normals[j, 1], normals[j, 2]
        best_offsets[place], best_counts[place] = offsets[j], c
        n_best = min(n_best + 1, confirm)
    return n_best


@numba.njit(**_NUMPY_JIT)
def spread_test(cols: np.ndarray, idx: np.ndarray, trim: bool, min_sine: float) -> int:
    """Whether the points ``cols`` (3, n) meters span a plane, judged on the points ``idx`` (c,) (a random subset;
    with ``trim``, without the 2 % farthest from their coordinate-wise median by the largest coordinate
    difference): 0 they do; 1 all points are identical; 2 almost all (the judged ones, no spread); 3 collinear (the
    second principal spread at most ``min_sine`` squared times the first)."""
    c = idx.shape[0]
    same = True
    for q in range(c):
        p = idx[q]
        if cols[0, p] != cols[0, idx[0]] or cols[1, p] != cols[1, idx[0]] or cols[2, p] != cols[2, idx[0]]:
            same = False
            break
    if same:
        for p in range(cols.shape[1]):
            if cols[0, p] != cols[0, 0] or cols[1, p] != cols[1, 0] or cols[2, p] != cols[2, 0]:
                same = False
                break
        if same:
            return 1
    keep = np.ones(c, np.bool_)
    if trim:
        median = np.empty(3)
        for a in range(3):
            values = np.partition(cols[a][idx], c // 2)  # order statistics, as a sort gives them
            upper = values[c // 2]
            median[a] = (values[:c // 2].max() + upper) / 2 if c % 2 == 0 else (upper + upper) / 2
        dist = np.empty(c)
        for q in range(c):
            p = idx[q]
            dist[q] = max(abs(cols[0, p] - median[0]), abs(cols[1, p] - median[1]), abs(cols[2, p] - median[2]))
        k = int(0.98 * (c - 1))
        limit = np.partition(dist, k)[k]
        for q in range(c):
            keep[q] = dist[q] <= limit
    kept = 0
    mean = np.zeros(3)
    for q in range(c):
        if keep[q]:
            kept += 1
            for a in range(3):
                mean[a] += cols[a, idx[q]]
    mean /= kept
    scatter = np.zeros((3, 3))
    for q in range(c):
        if keep[q]:
            x, y, z = cols[0, idx[q]] - mean[0], cols[1, idx[q]] - mean[1], cols[2, idx[q]] - mean[2]
            scatter[0, 0] += x * x
            scatter[0, 1] += x * y
            scatter[0, 2] += x * z
            scatter[1, 1] += y * y
            scatter[1, 2] += y * z
            scatter[2, 2] += z * z
    scatter[1, 0], scatter[2, 0], scatter[2, 1] = scatter[0, 1], scatter[0, 2], scatter[1, 2]
    eig = np.linalg.eigvalsh(scatter)  # ascending
    if eig[2] <= 0:
        return 2
    if eig[1] <= min_sine * min_sine * eig[2]:
        return 3
    return 0


@numba.njit(**_NUMPY_JIT)
def _eigen_plane(sxx: float, sxy: float, sxz: float, syy: float, syz: float, szz: float, cx: float, cy: float,
                 cz: float) -> tuple[np.ndarray, float]:
    """The plane through the centroid (cx, cy, cz) meters normal to the eigenvector of the smallest eigenvalue of the
    centred scatter (sxx .. szz): (unit normal (3,), offset meters)."""
    scatter = np.array([[sxx, sxy, sxz], [sxy, syy, syz], [sxz, syz, szz]])
    normal = np.ascontiguousarray(np.linalg.eigh(scatter)[1][:, 0])
    return normal, -(normal[0] * cx + normal[1] * cy + normal[2] * cz)


@numba.njit(**_NUMPY_JIT)
def fit_members(cols: np.ndarray, members: np.ndarray) -> tuple[np.ndarray, float]:
    """The least-squares plane of the points ``members`` (c,) of ``cols`` (3, m) meters, c >= 1: (unit normal (3,),
    offset meters), from the scatter about their centroid."""
    c = members.shape[0]
    cx = cy = cz = 0.0
    for q in range(c):
        p = members[q]
        cx += cols[0, p]
        cy += cols[1, p]
        cz += cols[2, p]
    cx, cy, cz = cx / c, cy / c, cz / c
    sxx = sxy = sxz = syy = syz = szz = 0.0
    for q in range(c):
        p = members[q]
        x, y, z = cols[0, p] - cx, cols[1, p] - cy, cols[2, p] - cz
        sxx += x * x
        sxy += x * y
        sxz += x * z
        syy += y * y
        syz += y * z
        szz += z * z
    return _eigen_plane(sxx, sxy, sxz, syy, syz, szz, cx, cy, cz)


@numba.njit(**_NUMPY_JIT)
def fit_mask(cols: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, float]:
    """:func:`fit_members` of the points ``mask`` (m,) bool, at least one."""
    return fit_members(cols, np.flatnonzero(mask))


@numba.njit(**_NUMPY_JIT)
def fit_regions(cols: np.ndarray, region: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The least-squares plane of each of the regions 0..k-1 of the points ``cols`` (3, m) meters (``region`` (m,),
    -1 for none): unit normals (k, 3), offsets (k,) meters and the points of each (k,) (a region of none: NaN)."""
    m = cols.shape[1]
    count = np.zeros(k, np.int64)
    centre = np.zeros((k, 3))
    # regions come in runs: a run's sums are kept in locals, each added in the order of the points
    p = 0
    while p < m:
        j = region[p]
        if j < 0:
            p += 1
            continue
        start = p
        sx, sy, sz = centre[j, 0], centre[j, 1], centre[j, 2]
        while p < m and region[p] == j:
            sx += cols[0, p]
            sy += cols[1, p]
            sz += cols[2, p]
            p += 1
        centre[j, 0], centre[j, 1], centre[j, 2] = sx, sy, sz
        count[j] += p - start
    for j in range(k):
        centre[j] /= count[j]
    scatter = np.zeros((k, 6))
    p = 0
    while p < m:
        j = region[p]
        if j < 0:
            p += 1
            continue
        cx, cy, cz = centre[j, 0], centre[j, 1], centre[j, 2]
        s0, s1, s2 = scatter[j, 0], scatter[j, 1], scatter[j, 2]
        s3, s4, s5 = scatter[j, 3], scatter[j, 4], scatter[j, 5]
        while p < m and region[p] == j:
            x, y, z = cols[0, p] - cx, cols[1, p] - cy, cols[2, p] - cz
            s0 += x * x
            s1 += x * y
            s2 += x * z
            s3 += y * y
            s4 += y * z
            s5 += z * z
            p += 1
        scatter[j, 0], scatter[j, 1], scatter[j, 2] = s0, s1, s2
        scatter[j, 3], scatter[j, 4], scatter[j, 5] = s3, s4, s5
    normals = np.full((k, 3), np.nan)
    offsets = np.full(k, np.nan)
    for j in range(k):
        if count[j]:
            s = scatter[j]
            normal, offset = _eigen_plane(s[0], s[1], s[2], s[3], s[4], s[5], centre[j, 0], centre[j, 1], centre[j, 2])
            normals[j] = normal
            offsets[j] = offset
    return normals, offsets, count


@numba.njit(**_NUMPY_JIT)
def _ahead(a: int, b: int, counts: np.ndarray, cost: np.ndarray) -> bool:
    """Whether hypothesis ``a`` ranks before ``b``: more inliers, then a lower cost (NaN last), as np.lexsort
    ((cost, -counts)) orders them."""
    if counts[a] != counts[b]:
        return counts[a] > counts[b]
    if np.isnan(cost[a]):
        return False
    return np.isnan(cost[b]) or cost[a] < cost[b]


@numba.njit(**_NUMPY_JIT)
def _coherent_near(cols: np.ndarray, tolerance: np.ndarray, normal: np.ndarray, offset: float,
                   point_normals: np.ndarray, min_cos: float, ray: np.ndarray) -> int:
    """:func:`coherent_inliers` of the inliers of the plane (``normal`` (3,), ``offset``) among ``cols`` (3, r)
    meters (within ``tolerance``, (1,) or (r,) meters)."""
    per_point = tolerance.shape[0] > 1
    nx, ny, nz = normal[0], normal[1], normal[2]
    count = 0
    for q in range(cols.shape[1]):
        e = abs(nx * cols[0, q] + ny * cols[1, q] + nz * cols[2, q] + offset)
        if e <= (tolerance[q] if per_point else tolerance[0]) * _facing(cols[0, q], cols[1, q], cols[2, q], nx, ny, nz,
                                                                        ray) and \
                not abs(nx * point_normals[0, q] + ny * point_normals[1, q] + nz * point_normals[2, q]) < min_cos:
            count += 1
    return count


@numba.njit(**_NUMPY_JIT)
def _msac_cost(cols: np.ndarray, tolerance: np.ndarray, normals: np.ndarray, offsets: np.ndarray, j: int,
               cost: np.ndarray, known: np.ndarray, ray: np.ndarray) -> float:
    """Hypothesis ``j``'s MSAC cost on ``cols`` (3, r) meters (see :func:`band_counts`), summed into ``cost`` (h,)
    the first time (``known`` (h,))."""
    if not known[j]:
        per_point = tolerance.shape[0] > 1
        nx, ny, nz, d = normals[j, 0], normals[j, 1], normals[j, 2], offsets[j]
        total = 0.0
        for q in range(cols.shape[1]):
            t = (tolerance[q] if per_point else tolerance[0]) * _facing(cols[0, q], cols[1, q], cols[2, q], nx, ny, nz,
                                                                        ray)
            e = abs(nx * cols[0, q] + ny * cols[1, q] + nz * cols[2, q] + d)
            if e > t:
                e = t
            total += e * e
        cost[j], known[j] = total, True
    return cost[j]


@numba.njit(**_NUMPY_JIT)
def _ranked(cols: np.ndarray, tolerance: np.ndarray, normals: np.ndarray, offsets: np.ndarray, ray: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The h hypotheses (``normals`` (h, 3), ``offsets`` (h,)) on the points ``cols`` (3, r) meters in the order the
    region kernels try them: by inliers (within ``tolerance``, (1,) or (r,) meters), then MSAC cost, as np.lexsort
    ((cost, -counts)) orders them. Returns (inliers (h,), costs (h,), which costs are summed (h,), the order (h,));
    the costs only decide between equal counts: each is summed (as band_counts sums it) when first compared."""
    h, r = normals.shape[0], cols.shape[1]
    per_point = tolerance.shape[0] > 1
    counts = np.zeros(h, np.int64)
    x, y, z = cols[0], cols[1], cols[2]
    for j in range(h):  # band_counts' counts, without its masks
        nx, ny, nz, d = normals[j, 0], normals[j, 1], normals[j, 2], offsets[j]
        near = 0
        if ray.shape[0] > 0:
            for q in range(r):
                t = (tolerance[q] if per_point else tolerance[0]) * _facing(x[q], y[q], z[q], nx, ny, nz, ray)
                near += np.int64(abs(nx * x[q] + ny * y[q] + nz * z[q] + d) <= t)
        elif per_point:
            for q in range(r):
                near += np.int64(abs(nx * x[q] + ny * y[q] + nz * z[q] + d) <= tolerance[q])
        else:
            t = tolerance[0]
            for q in range(r):
                near += np.int64(abs(nx * x[q] + ny * y[q] + nz * z[q] + d) <= t)
        counts[j] = near
    cost = np.full(h, np.nan)
    known = np.zeros(h, np.bool_)
    for j in range(h):
        for i in range(h):
            if i != j and counts[i] == counts[j]:
                _msac_cost(cols, tolerance, normals, offsets, j, cost, known, ray)
    order = np.arange(h)
    for i in range(1, h):  # an insertion sort: stable, and h is a handful
        k = order[i]
        q = i
        while q > 0 and _ahead(k, order[q - 1], counts, cost):
            order[q] = order[q - 1]
            q -= 1
        order[q] = k
    return counts, cost, known, order


# --- verdict and indices per frame ---


#: order_statistics keeps up to this many of the smallest and of the largest values in sorted buffers; farther in,
#: it partitions.
_ENDS = 64


@numba.njit(**_JIT)
def order_statistics(values: np.ndarray, a0: int, a1: int, b0: int, b1: int) -> tuple[float, float, float, float]:
    """The values at the positions a0 <= a1 (near the start) and b0 <= b1 (near the end) of ``values`` (m,) sorted
    ascending, as np.partition finds them: in one pass with two short sorted buffers (the a1 + 1 smallest, the m - b0
    largest) when both are at most _ENDS long and no value is NaN, else by np.partition."""
    m = values.shape[0]
    low, high = a1 + 1, m - b0
    if low <= _ENDS and high <= _ENDS:
        small = np.empty(low)
        big = np.empty(high)  # descending: big[0] the largest
        n_small = n_big = 0
        clean = True
        for i in range(m):
            x = values[i]
            if x != x:
                clean = False
                break
            if n_small < low or x < small[n_small - 1]:
                q = min(n_small, low - 1)  # the slot freed (the largest kept drops out when full)
                while q > 0 and small[q - 1] > x:
                    small[q] = small[q - 1]
                    q -= 1
                small[q] = x
                n_small = min(n_small + 1, low)
            if n_big < high or x > big[n_big - 1]:
                q = min(n_big, high - 1)
                while q > 0 and big[q - 1] < x:
                    big[q] = big[q - 1]
                    q -= 1
                big[q] = x
                n_big = min(n_big + 1, high)
        if clean:
            return small[a0], small[a1], big[m - 1 - b0], big[m - 1 - b1]
    part = np.partition(values, np.array([a0, a1, b0, b1]))
    return part[a0], part[a1], part[b0], part[b1]


#: sorted_order spreads m values over m buckets, evenly between the smallest and the largest, and sorts them by radix
#: instead when a bucket holds more than this many (clustered values, many copies).
_BUCKET_MOST = 32


@numba.njit(**_JIT)
def sorted_order(values: np.ndarray) -> np.ndarray:
    """The order (m,) int64 that sorts ``values`` (m,) float64 without NaN ascending, equal values in their order
    (as np.argsort's stable sort). Spread evenly over buckets by value (a monotone map: no bucket holds a value larger
    than a later bucket's), each bucket insertion-sorted: a few passes where values spread out, as fold_line's do.
    Where a bucket would hold more than _BUCKET_MOST values: an LSD radix sort of the floats' bits, a byte a pass,
    skipping the bytes all keys share (both several times faster than a comparison sort on a thousand values)."""
    m = values.shape[0]
    order = np.empty(m, np.int64)
    if m == 0:
        return order
    low = high = values[0]
    number = True
    for i in range(m):
        low = min(low, values[i])
        high = max(high, values[i])
        number &= values[i] == values[i]
    buckets = m
    scale = buckets / (high - low) if high > low else 0.0
    if number and 0.0 < scale < np.inf:  # (a NaN would have no bucket: the radix sort gives it a place)
        start = np.zeros(buckets + 1, np.int64)
        bucket = np.empty(m, np.int64)
        for i in range(m):
            b = min(int((values[i] - low) * scale), buckets - 1)
            bucket[i] = b
            start[b + 1] += 1
        if start.max() <= _BUCKET_MOST:
            for b in range(buckets):
                start[b + 1] += start[b]
            for i in range(m):  # in input order: equal values keep it
                order[start[bucket[i]]] = i
                start[bucket[i]] += 1
            first = 0  # start[b] is now where bucket b ends
            for b in range(buckets):
                for q in range(first + 1, start[b]):
                    i = order[q]
                    x = values[i]
                    r = q
                    while r > first and values[order[r - 1]] > x:  # strictly larger: stable
                        order[r] = order[r - 1]
                        r -= 1
                    order[r] = i
                first = start[b]
            return order
    keys = np.empty(m, np.uint64)
    raw = np.ascontiguousarray(values).view(np.uint64)
    top = np.uint64(1) << np.uint64(63)
    for i in range(m):
        bits = raw[i] if raw[i] != top else np.uint64(0)  # -0.0 as 0.0: equal values
        keys[i] = ~bits if bits & top else bits | top  # ordered as unsigned integers
    for i in range(m):
        order[i] = i
    spare = np.empty(m, np.int64)
    count = np.empty(257, np.int64)
    for shift in range(0, 64, 8):
        count[:] = 0
        for i in range(m):
            count[np.int64((keys[i] >> np.uint64(shift)) & np.uint64(255)) + 1] += 1
        if count.max() == m:  # one digit for all: the pass would keep the order
            continue
        for d in range(256):
            count[d + 1] += count[d]
        for q in range(m):
            i = order[q]
            d = np.int64((keys[i] >> np.uint64(shift)) & np.uint64(255))
            spare[count[d]] = i
            count[d] += 1
        order, spare = spare, order
    return order


@numba.njit(**_JIT)
def plane_samples(points: np.ndarray, rows: np.ndarray, bounds: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per plane j, its sampled rows ``rows[bounds[j]:bounds[j + 1]]`` of ``points`` (N, 3) meters: (the rows
    gathered (M, 3), each plane's mean (k, 3), zeros for none, and the gathered rows minus their plane's mean (M, 3)).
    The means are summed row by row, as numpy sums over the first axis: the same values as ``mean(axis=0)``."""
    k, total = bounds.shape[0] - 1, rows.shape[0]
    gathered = np.empty((total, 3))
    centred = np.empty((total, 3))
    centres = np.zeros((k, 3))
    for j in range(k):
        lo, hi = bounds[j], bounds[j + 1]
        sx = sy = sz = 0.0
        for q in range(lo, hi):
            p = rows[q]
            x, y, z = points[p, 0], points[p, 1], points[p, 2]
            gathered[q, 0], gathered[q, 1], gathered[q, 2] = x, y, z
            sx += x
            sy += y
            sz += z
        if hi == lo:
            continue
        cx, cy, cz = sx / (hi - lo), sy / (hi - lo), sz / (hi - lo)
        centres[j, 0], centres[j, 1], centres[j, 2] = cx, cy, cz
        for q in range(lo, hi):
            centred[q, 0], centred[q, 1], centred[q, 2] = gathered[q, 0] - cx, gathered[q, 1] - cy, gathered[q, 2] - cz
    return gathered, centres, centred


# --- detect ---


@numba.njit(**_JIT)
def finite_extent(points: np.ndarray) -> tuple[np.ndarray, int, float]:
    """:func:`finite_mask` of ``points`` (N, 3) and, in the same pass, :func:`largest_magnitude` of its coordinates:
    (finite rows (N,) bool, how many, the largest |coordinate| that is not NaN (inf counts), NaN when none is)."""
    n = points.shape[0]
    out = np.empty(n, np.bool_)
    count = 0
    big_x = big_y = big_z = -1.0  # a running maximum per coordinate (no chain through one); NaN never compares greater
    for i in range(n):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(z)  # no branch per coordinate
        out[i] = ok
        count += ok
        ax, ay, az = abs(x), abs(y), abs(z)
        big_x = ax if ax > big_x else big_x
        big_y = ay if ay > big_y else big_y
        big_z = az if az > big_z else big_z
    largest = max(big_x, max(big_y, big_z))
    return out, count, (largest if largest >= 0 else np.nan)


@numba.njit(**_JIT)
def grid_contacts(node: np.ndarray, usable: np.ndarray, width: int, wraps: bool, bridges: np.ndarray,
                  region: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The neighbour pairs of a sub-grid image (``node`` (h * w,): the point at each pixel, -1 none; ``usable``
    (h * w,)) that join two of the ``k`` regions ``region`` (m,) (-1: none), in the order of
    ``GridNeighbours.touching``: right neighbours, down neighbours (row-major), the last and first pixels of each row
    when the image ``wraps``, then the ``bridges`` (b, 3). Returns (src, dst, their regions a, b, each touching pair
    of regions once as i * k + j (i < j), ascending)."""
    height = node.shape[0] // width
    cap = 2 * node.shape[0] + height + bridges.shape[0]
    src = np.empty(cap, np.int64)
    dst = np.empty(cap, np.int64)
    n = 0
    for kind in range(4):
        count = (height * (width - 1) if kind == 0 else (height - 1) * width if kind == 1 else
                 (height if wraps else 0) if kind == 2 else bridges.shape[0])
        p = col = 0  # right neighbours: p steps along the rows (col its column), no division per pair
        for q in range(count):
            if kind == 0:
                o = p + 1
            elif kind == 1:
                p = q
                o = q + width
            elif kind == 2:
                p = q * width + width - 1
                o = q * width
            else:
                p = bridges[q, 0]
                o = bridges[q, 1]
            i = node[p] if usable[p] else -1
            j = node[o] if usable[o] else -1
            if i >= 0 and j >= 0:
                ri, rj = region[i], region[j]
                if ri >= 0 and rj >= 0 and ri != rj:
                    src[n], dst[n] = i, j
                    n += 1
            if kind == 0:
                p += 1
                col += 1
                if col == width - 1:  # past the row's last pair: the next row's first pixel
                    col = 0
                    p += 1
    src, dst = src[:n], dst[:n]
    a = np.empty(n, np.int64)
    b = np.empty(n, np.int64)
    codes = np.empty(n, np.int64)
    for q in range(n):
        a[q], b[q] = region[src[q]], region[dst[q]]
        codes[q] = min(a[q], b[q]) * k + max(a[q], b[q])
    return src, dst, a, b, np.unique(codes)


@numba.njit(**_JIT)
def label_rows(labels: np.ndarray, k: int, residual: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`group_by_label` of ``labels`` (N,) into 0..k-1, and the squared ``residual`` (N,) meters of its rows in
    the same order (each label's squares one run: its mean square is numpy's mean of that run)."""
    n = labels.shape[0]
    # labels come in runs (an image's regions): a run is counted and filled through a local counter, not through
    # the label's entry in memory at every row
    bounds = np.zeros(k + 1, np.int64)
    i = 0
    while i < n:
        lab = labels[i]
        start = i
        i += 1
        while i < n and labels[i] == lab:
            i += 1
        if 0 <= lab < k:
            bounds[lab + 1] += i - start
    for j in range(k):
        bounds[j + 1] += bounds[j]
    rows, squares = _filled_runs(labels, bounds, residual)
    return rows, bounds, squares


@numba.njit(**_JIT)
def _filled_runs(labels: np.ndarray, bounds: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows (M,) int64 of each label 0..k-1 of ``labels`` (N,) in turn, from ``bounds`` (k + 1,) (label j's
    between bounds[j] and bounds[j + 1]; other labels skipped), and the squares of ``values`` (N,) at them, run by
    run of one label."""
    k = bounds.shape[0] - 1
    n = labels.shape[0]
    fill = bounds[:-1].copy()
    rows = np.empty(bounds[k], np.int64)
    squares = np.empty(bounds[k])
    i = 0
    while i < n:
        lab = labels[i]
        if not 0 <= lab < k:
            i += 1
            continue
        at = fill[lab]
        while i < n and labels[i] == lab:
            rows[at] = i
            squares[at] = values[i] * values[i]
            at += 1
            i += 1
        fill[lab] = at
    return rows, squares


@numba.njit(**_JIT)
def grid_triples(first: np.ndarray, scale_pick: np.ndarray, row_share: np.ndarray, col_share: np.ndarray,
                 scales: np.ndarray, rest: np.ndarray, position: np.ndarray, pixel: np.ndarray, node: np.ndarray,
                 height: int, width: int) -> np.ndarray:
    """(c, 3) triples of nearby points of a sub-grid image (``pixel`` (n,), ``node`` (height * width,) as in
    :func:`grid_components`) as positions among its points ``rest`` (r,) (``position`` (n + 1,): each point's, -1
    for none and at [-1]): each of ``first`` (c,) (positions) with two points drawn near it, the 2c draws being
    ``scales[scale_pick]`` (2c,) pixels wide and ``row_share`` and ``col_share`` (2c,) in [0, 1) the row and column
    offsets as shares of that (the first c for the second point, the next c for the third; -1 where the window falls
    off the image or on no point left), as ``GridNeighbours.nearby`` draws them."""
    c = first.shape[0]
    out = np.empty((c, 3), np.int64)
    for q in range(2 * c):
        f = first[q % c]
        scale = np.float64(scales[scale_pick[q]])
        r, col = divmod(pixel[rest[f]], width)
        r += np.int64(np.rint((2 * row_share[q] - 1) * scale))
        col += np.int64(np.rint((2 * col_share[q] - 1) * scale))
        near = node[r * width + col] if 0 <= r < height and 0 <= col < width else -1
        out[q % c, 1 + q // c] = position[near]
    for q in range(c):
        out[q, 0] = first[q]
    return out



@numba.njit(**_JIT)
def graph_triples(first: np.ndarray, scale_pick: np.ndarray, steps: np.ndarray, scales: np.ndarray, rest: np.ndarray,
                  position: np.ndarray, indptr: np.ndarray, indices: np.ndarray, degrees: np.ndarray) -> np.ndarray:
    """(c, 3) triples of nearby points of a graph (adjacency ``indptr`` (n + 1,), ``indices``, with ``degrees`` (n,)
    >= 1: a loop at a point without neighbours) as positions among its points ``rest`` (r,) (``position`` (n,):
    each point's, -1 for none): each of ``first`` (c,) (positions) with the ends of two random walks from it, the 2c
    walks ``scales[scale_pick]`` (2c,) hops long, hop h of walk q to the neighbour at share ``steps[h, q]`` in [0, 1)
    of the point's list (the first c walks give the second point, the next c the third), as
    ``GraphNeighbours.nearby`` walks them."""
    c = first.shape[0]
    out = np.empty((c, 3), np.int64)
    for q in range(2 * c):
        at = rest[first[q % c]]
        for hop in range(scales[scale_pick[q]]):
            at = indices[indptr[at] + np.int64(steps[hop, q] * degrees[at])]
        out[q % c, 1 + q // c] = position[at]
    for q in range(c):
        out[q, 0] = first[q]
    return out

# --- frame input and outlines ---


@numba.njit(**_JIT)
def outside_polygon(local: np.ndarray, directions: np.ndarray, margin: float) -> np.ndarray:
    """The positions (ascending) of the points ``local`` (2, m), m > 0, not inside the polygon of their extreme
    points along ``directions`` (d, 2) (the first of equals; at increasing angles: the polygon counter-clockwise, a
    corner repeated next to itself making no side): a point is inside when it lies left of every side by more than
    ``margin`` times the side's larger coordinate span and the points' largest |coordinate|. The numbers as
    :func:`.geometry.outside_polygon_numpy` computes them."""
    m, c = local.shape[1], directions.shape[0]
    scale = 0.0
    for i in range(m):
        scale = max(scale, max(abs(local[0, i]), abs(local[1, i])))
    cx, cy = np.empty(c), np.empty(c)
    for e in range(c):
        best, at = -np.inf, 0
        for i in range(m):
            value = directions[e, 0] * local[0, i] + directions[e, 1] * local[1, i]
            if value > best:
                best, at = value, i
        cx[e], cy[e] = local[0, at], local[1, at]
    sx, sy, limit = np.empty(c), np.empty(c), np.empty(c)
    for e in range(c):
        f = e + 1 if e + 1 < c else 0
        sx[e], sy[e] = cx[f] - cx[e], cy[f] - cy[e]
        limit[e] = margin * max(abs(sx[e]), abs(sy[e])) * scale
    out = np.empty(m, np.int64)
    q = 0
    for i in range(m):
        x, y = local[0, i], local[1, i]
        inside = True
        for e in range(c):
            if sx[e] == 0.0 and sy[e] == 0.0:
                continue
            if not sx[e] * (y - cy[e]) - sy[e] * (x - cx[e]) > limit[e]:
                inside = False
                break
        if not inside:
            out[q] = i
            q += 1
    return out[:q]


@numba.njit(**_JIT)
def read_rows(words: np.ndarray, columns: np.ndarray, view: np.ndarray, within: float, marks: bool
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int, float]:
    """One pass over a PointCloud2's points, the float32 ``words`` (N, w) with x, y, z at ``columns`` (3,): the rows
    (N, 3) float64, with NaN where ``marks`` and a row lies at a driver's "no return" mark (as :func:`marked_rows`
    finds it: exactly (0, 0, 0) when ``view`` (3,) is the origin, else within ``within`` meters of ``view`` in each
    coordinate); which rows have three finite coordinates (N,) bool and they themselves, in order ((n, 3), the
    start of an (N, 3) buffer); how many other rows have an infinite coordinate, how many were marked, and the
    rows' largest |coordinate| that is not NaN (inf counts; NaN when none is), as :func:`finite_extent` gives it:
    the search then needs no pass of its own over the rows."""
    n = words.shape[0]
    points = np.empty((n, 3))
    finite = np.empty(n, np.bool_)
    valid = np.empty((n, 3))
    a, b, c = columns[0], columns[1], columns[2]
    origin = view[0] == 0.0 and view[1] == 0.0 and view[2] == 0.0
    m = infinite = marked = 0
    big_x = big_y = big_z = -1.0  # as finite_extent: a running maximum per coordinate; NaN never compares greater
    for i in range(n):
        x, y, z = np.float64(words[i, a]), np.float64(words[i, b]), np.float64(words[i, c])
        if marks:
            if origin:
                at = x == 0.0 and y == 0.0 and z == 0.0
            else:
                at = abs(x - view[0]) <= within and abs(y - view[1]) <= within and abs(z - view[2]) <= within
            if at:
                x = y = z = np.nan
                marked += 1
        points[i, 0], points[i, 1], points[i, 2] = x, y, z
        ax, ay, az = abs(x), abs(y), abs(z)
        big_x = ax if ax > big_x else big_x
        big_y = ay if ay > big_y else big_y
        big_z = az if az > big_z else big_z
        ok = np.isfinite(x) and np.isfinite(y) and np.isfinite(z)
        finite[i] = ok
        if ok:
            valid[m, 0], valid[m, 1], valid[m, 2] = x, y, z
            m += 1
        elif np.isinf(x) or np.isinf(y) or np.isinf(z):
            infinite += 1
    largest = max(big_x, max(big_y, big_z))
    return points, finite, valid[:m], infinite, marked, (largest if largest >= 0 else np.nan)


# --- unorganized clouds ---

#: :func:`uncertain_nodes`' mark of a voxel whose hashed points lie in more than one region (regions are >= -1).
_MIXED = -2


@numba.njit(**_JIT)
def voxel_nodes(points: np.ndarray, order: np.ndarray, cell_keys: np.ndarray, starts: np.ndarray, table: np.ndarray,
                origin: np.ndarray, cell: float, dims: np.ndarray, cloud: np.ndarray, rows: np.ndarray,
                center: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For each query, the rows ``rows`` (q,) of ``cloud`` (N, 3) meters less ``center`` (3,), in one pass: (node (q,):
    a hashed point of :func:`voxel_grid` (``points`` (m, 3): those points voxel by voxel, in its ``order``) in its own
    voxel, the first in ``order`` nearer than one voxel plus the query's gap to its voxel's nearest face, else the
    nearest there (equal distances: the first in ``order``), as an index into the points as hashed, -1 where its voxel
    holds none or it lies outside the grid; voxel (q,): that occupied voxel, -1 where none; d2 (q,): the node's squared
    distance, m^2, inf where none; near (q,) bool: the node is that near, so every hashed point at least as near lies in
    the 27 voxels around the query's own)."""
    nq = rows.shape[0]
    node = np.full(nq, -1, np.int64)
    voxel = np.full(nq, -1, np.int64)
    d2 = np.full(nq, np.inf)
    near = np.zeros(nq, np.bool_)
    total = dims[0] * dims[1] * dims[2]
    dense = table.shape[0] == total and total <= max(DENSE_VOXELS, 8 * points.shape[0])
    for q in range(nq):
        r = rows[q]
        x, y, z = cloud[r, 0] - center[0], cloud[r, 1] - center[1], cloud[r, 2] - center[2]
        fx, fy, fz = (x - origin[0]) / cell, (y - origin[1]) / cell, (z - origin[2]) / cell
        if not (0.0 <= fx < dims[0] and 0.0 <= fy < dims[1] and 0.0 <= fz < dims[2]):
            continue
        cx, cy, cz = int(fx), int(fy), int(fz)
        v = _voxel(cell_keys, table, cx + dims[0] * (cy + dims[1] * cz), dense)
        if v < 0:
            continue
        # a point outside those voxels lies farther than one voxel plus the gap to the nearest face
        reach = cell + min(fx - cx, cx + 1 - fx, fy - cy, cy + 1 - fy, fz - cz, cz + 1 - fz) * cell
        within = reach * reach
        b, bj = np.inf, -1
        for j in range(starts[v], starts[v + 1]):
            ex, ey, ez = points[j, 0] - x, points[j, 1] - y, points[j, 2] - z
            e = ex * ex + ey * ey + ez * ez
            if e < within:  # near enough: uncertain_nodes looks for the nearest only where regions meet
                b, bj = e, j
                break
            if e < b:
                b, bj = e, j
        node[q], voxel[q], d2[q] = order[bj], v, b
        near[q] = b < within
    return node, voxel, d2, near


@numba.njit(**_JIT)
def uncertain_nodes(region: np.ndarray, node: np.ndarray, d2: np.ndarray, voxel: np.ndarray, near: np.ndarray,
                    exact: np.ndarray, points: np.ndarray, rows: np.ndarray, center: np.ndarray, ordered: np.ndarray,
                    order: np.ndarray, cell_keys: np.ndarray, starts: np.ndarray, table: np.ndarray,
                    origin: np.ndarray, cell: float, dims: np.ndarray) -> np.ndarray:
    """(q,) bool: the queries of :func:`voxel_nodes` (its ``node``, ``d2``, ``voxel`` and ``near``; the rows ``rows``
    of ``points`` (N, 3) meters less ``center`` (3,); ``ordered`` its hashed points voxel by voxel) whose nearest
    hashed point may lie in another region than their node (``region`` (m,), by the hashed points' rows before
    hashing) and beyond the 27 voxels around their own: not ``exact`` (the node known to be the nearest) and not
    ``near``. A near query whose own voxel holds several regions first takes the nearest point there as its node; when
    one of the 26 voxels around its own holds points of another region than the node's (or of several) and one of them
    lies nearer than its own voxel's nearest point (as near: earlier in the hash's order), it takes the nearest hashed
    point (as :func:`voxel_nearest` finds it; near, that lies in those 27 voxels) and becomes ``exact`` (``node``,
    ``d2`` and ``exact`` updated)."""
    total = dims[0] * dims[1] * dims[2]
    dense = table.shape[0] == total and total <= max(DENSE_VOXELS, 8 * order.shape[0])
    label, around, uniform = _voxel_regions(region, order, cell_keys, starts, table, dims, dense)
    out = np.zeros(voxel.shape[0], np.bool_)
    gap = np.empty((3, 3))  # squared gaps to the voxels below, level with and above along each axis
    for q in range(voxel.shape[0]):
        v = voxel[q]
        if exact[q] or (near[q] and uniform[v]):
            continue
        if not near[q]:
            out[q] = True
            continue
        x, y, z = points[rows[q], 0] - center[0], points[rows[q], 1] - center[1], points[rows[q], 2] - center[2]
        b, bj = np.inf, -1  # the nearest of its own voxel (the first of equals)
        for j in range(starts[v], starts[v + 1]):
            ex, ey, ez = ordered[j, 0] - x, ordered[j, 1] - y, ordered[j, 2] - z
            e = ex * ex + ey * ey + ez * ez
            if e < b:
                b, bj = e, j
        if label[v] == _MIXED:  # the node is one near point of its voxel: the nearest there instead
            node[q], d2[q] = order[bj], b
        margin = _query_gaps(points, rows[q], center, origin, cell, cell_keys[v], dims, gap)
        own = region[node[q]]  # its own voxel's nearest point's: the nearest lies no farther
        for a in range(27):
            u = around[v, a]
            if u >= 0 and u != v and label[u] != own and \
                    gap[0, a % 3] + gap[1, (a // 3) % 3] + gap[2, a // 9] <= b and \
                    _nearer_in(ordered, starts, u, x, y, z, b, bj):
                b, bj = _nearest_around(ordered, starts, around[v], v, x, y, z, gap, margin, b, bj)
                node[q], d2[q], exact[q] = order[bj], b, True
                break
    return out


@numba.njit(**_JIT)
def _nearer_in(ordered: np.ndarray, starts: np.ndarray, u: int, x: float, y: float, z: float, b: float, bj: int
               ) -> bool:
    """Whether a point of the occupied voxel ``u`` (``ordered`` the hashed points voxel by voxel) lies nearer to (x, y,
    z) meters than the squared distance ``b`` (as near: earlier in the hash's order than ``bj``)."""
    for j in range(starts[u], starts[u + 1]):
        ex, ey, ez = ordered[j, 0] - x, ordered[j, 1] - y, ordered[j, 2] - z
        e = ex * ex + ey * ey + ez * ez
        if e < b or (e == b and j < bj):
            return True
    return False


@numba.njit(**_JIT)
def _voxel_regions(region: np.ndarray, order: np.ndarray, cell_keys: np.ndarray, starts: np.ndarray, table: np.ndarray,
                   dims: np.ndarray, dense: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For :func:`uncertain_nodes`, per occupied voxel of :func:`voxel_grid`: (label (c,): the region (``region`` (m,),
    by the hashed points' rows before hashing) of its points, _MIXED where they differ; around (c, 27): the occupied
    voxels around it, by offset (dz, dy, dx) + 1 in base 3, -1 where none; uniform (c,): those 27 hold one region)."""
    nv = cell_keys.shape[0]
    label = np.empty(nv, np.int64)
    for v in range(nv):
        first = region[order[starts[v]]]
        for j in range(starts[v] + 1, starts[v + 1]):
            if region[order[j]] != first:
                first = _MIXED
                break
        label[v] = first
    around = np.full((nv, 27), -1, np.int64)
    uniform = label != _MIXED
    for v in range(nv):
        key = cell_keys[v]
        vx, vy, vz = key % dims[0], (key // dims[0]) % dims[1], key // (dims[0] * dims[1])
        for a in range(27):
            ix, iy, iz = vx + a % 3 - 1, vy + (a // 3) % 3 - 1, vz + a // 9 - 1
            if 0 <= ix < dims[0] and 0 <= iy < dims[1] and 0 <= iz < dims[2]:
                u = _voxel(cell_keys, table, ix + dims[0] * (iy + dims[1] * iz), dense)
                around[v, a] = u
                if u >= 0 and label[u] != label[v]:
                    uniform[v] = False
    return label, around, uniform


@numba.njit(**_JIT)
def _query_gaps(points: np.ndarray, r: int, center: np.ndarray, origin: np.ndarray, cell: float, key: int,
                dims: np.ndarray, gap: np.ndarray) -> float:
    """Into ``gap`` (3, 3): the squared gaps (m^2) from the row ``r`` of ``points`` less ``center`` to the voxels below,
    level with (0) and above its voxel (of ``key``) along each axis, as :func:`_faces` gives them; returns how far
    (meters) it lies inside its voxel."""
    margin = np.inf
    for axis in range(3):
        f = (points[r, axis] - center[axis] - origin[axis]) / cell
        c = key % dims[0] if axis == 0 else (key // dims[0]) % dims[1] if axis == 1 else key // (dims[0] * dims[1])
        below, above = (f - c) * cell, (c + 1 - f) * cell
        gap[axis, 0], gap[axis, 1], gap[axis, 2] = below * below, 0.0, above * above
        margin = min(margin, f - c, c + 1 - f)
    return margin * cell


@numba.njit(**_JIT)
def _nearest_around(ordered: np.ndarray, starts: np.ndarray, around: np.ndarray, v: int, x: float, y: float, z: float,
                    gap: np.ndarray, margin: float, b: float, bj: int) -> tuple[float, int]:
    """:func:`voxel_nearest`'s answer for a query at (x, y, z) meters in the occupied voxel ``v`` whose nearest point
    there is ``bj`` at squared distance ``b`` (the first of equals), ``margin`` meters inside it, with the occupied
    voxels ``around`` (27,) it (as :func:`_voxel_regions` gives them) at squared gaps ``gap`` (3, 3): that point when it
    is nearer than any face, else the nearest of the 27 voxels (equal distances: the first in the hash's order), as
    (squared distance, position in the hash). Exact when some point lies within one voxel plus ``margin``."""
    if b <= margin * margin:
        return b, bj
    for t in range(1, 27):  # in _BLOCK's order, as _occupied_around
        a = _BLOCK[t, 0] + 1 + 3 * (_BLOCK[t, 1] + 1) + 9 * (_BLOCK[t, 2] + 1)
        u = around[a]
        if u < 0 or u == v or gap[0, a % 3] + (gap[1, (a // 3) % 3] + gap[2, a // 9]) > b:
            continue
        for j in range(starts[u], starts[u + 1]):
            ex, ey, ez = ordered[j, 0] - x, ordered[j, 1] - y, ordered[j, 2] - z
            e = ex * ex + ey * ey + ez * ez
            if e < b or (e == b and j < bj):
                b, bj = e, j
    return b, bj


@numba.njit(**_JIT)
def first_across(rows: np.ndarray, near: np.ndarray, points: np.ndarray, direction: np.ndarray,
                 elevation: np.ndarray, one_ring: np.ndarray, kind: int, off_cos: float, another_ring: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """For each of the points ``rows`` (m,) the first of its candidates ``near`` (m, c) (nearest first) across from
    it: (found (m,) bool, that candidate (m,); the first one where none is). Across: ``kind`` 0, on another lidar ring
    (``elevation`` (n,) radians differs by more than ``another_ring``); 1, off the line along ``direction`` (n, 3)
    (the offset between the ``points`` (n, 3) makes a cosine below ``off_cos`` with it), 2, off the plane of that
    normal (cosine with it above ``off_cos``), and for a point of ``one_ring`` (n,) also on another ring. An offset
    of zero, or an unknown (NaN) direction, is never across."""
    m, c = near.shape
    found = np.zeros(m, np.bool_)
    target = np.empty(m, np.int64)
    for i in range(m):
        r = rows[i]
        target[i] = near[i, 0] if c else r
        for j in range(c):
            p = near[i, j]
            another = abs(elevation[p] - elevation[r]) > another_ring
            if kind == 0:
                across = another
            else:
                ox, oy, oz = points[p, 0] - points[r, 0], points[p, 1] - points[r, 1], points[p, 2] - points[r, 2]
                length = np.sqrt(ox * ox + oy * oy + oz * oz)
                if not length > 0.0:
                    continue
                cos = abs(ox * direction[r, 0] + oy * direction[r, 1] + oz * direction[r, 2]) / length
                across = (cos > off_cos if kind == 2 else cos < off_cos) and (not one_ring[r] or another)
            if across:
                found[i], target[i] = True, p
                break
    return found, target


# --- organized detect ---
# A RANSAC run's plane on an image's sub-grid (the best confirmed hypothesis by its region, then its refits) in one
# call, its regions labelled along runs of the image rows; and border settling that works out only the distances it
# compares.


@numba.njit(**_NUMPY_JIT)
def _pixel_place(pixels: np.ndarray, p: int) -> int:
    """The place of pixel ``p`` in ``pixels`` (ascending), -1 when it is not there."""
    lo, hi = 0, pixels.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if pixels[mid] < p:
            lo = mid + 1
        else:
            hi = mid
    return lo if lo < pixels.shape[0] and pixels[lo] == p else -1


@numba.njit(**_NUMPY_JIT)
def _run_holding(starts: np.ndarray, n_runs: int, c: int) -> int:
    """The run (``starts`` (n_runs + 1,): where each begins) that holds place ``c``."""
    lo, hi = 0, n_runs - 1
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if starts[mid] <= c:
            lo = mid
        else:
            hi = mid - 1
    return lo


@numba.njit(**_NUMPY_JIT)
def _row_run_components(pixels: np.ndarray, width: int, bridges: np.ndarray, counted: np.ndarray
                        ) -> tuple[int, np.ndarray, np.ndarray, int, np.ndarray]:
    """Connected components of the points at ``pixels`` (c,) (flat, ascending) of a sub-grid ``width`` wide through
    their 4 image neighbours and the ``bridges`` (b, 3) that do not cross the seam, labelled by runs along the image
    rows (a run touches the runs of the row above that overlap it): (the component with the most ``counted`` (c,)
    points, the first of equals, -1 when there is none; the component of each run; where each run starts (runs + 1,);
    the number of runs; the ``counted`` points of each component), components numbered in the order of their first
    point (as :func:`grid_components`)."""
    count = pixels.shape[0]
    starts = np.empty(count + 1, np.int64)
    n_runs = 0
    previous = -2
    row_end = 0  # where the row of the previous point ends
    for c in range(count):
        p = pixels[c]
        if not (p == previous + 1 and p < row_end):
            starts[n_runs] = c
            n_runs += 1
            if p >= row_end:
                row_end = p - p % width + width
        previous = p
    starts[n_runs] = count
    parent = np.arange(n_runs)
    low = 0  # the first run that may lie above the current one: the runs before it end before its row does
    for k in range(n_runs):
        first, last = pixels[starts[k]], pixels[starts[k + 1] - 1]
        if first < width:
            continue
        while pixels[starts[low + 1] - 1] < first - width:
            low += 1
        j = low
        while j < k and pixels[starts[j]] <= last - width:
            _join(parent, k, j)
            j += 1
    for b in range(bridges.shape[0]):
        if bridges[b, 2] != 0:
            continue
        u, v = _pixel_place(pixels, bridges[b, 0]), _pixel_place(pixels, bridges[b, 1])
        if u >= 0 and v >= 0:
            _join(parent, _run_holding(starts, n_runs, u), _run_holding(starts, n_runs, v))
    component = np.empty(n_runs, np.int64)
    n_components = 0
    for k in range(n_runs):
        root = _root(parent, k)
        if root == k:  # a root is its component's first run: met first
            component[k] = n_components
            n_components += 1
        else:
            component[k] = component[root]
    sizes = np.zeros(n_components, np.int64)
    for k in range(n_runs):
        size = 0
        for c in range(starts[k], starts[k + 1]):
            size += counted[c]
        sizes[component[k]] += size
    best = np.argmax(sizes) if n_components else -1
    return best, component, starts, n_runs, sizes


@numba.njit(**_NUMPY_JIT)
def _grid_band_region(cols: np.ndarray, tolerance: np.ndarray, support: float, nx: float, ny: float, nz: float,
                      offset: float, point_normals: np.ndarray, rest_pixel: np.ndarray, rest_usable: np.ndarray,
                      width: int, bridges: np.ndarray, min_cos: float, rules: np.ndarray, ray: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """(kept, taken) (r,) bool: the region the plane (nx, ny, nz, ``offset``) keeps among the r points ``cols`` (3, r)
    meters of a sub-grid (``rest_pixel`` (r,) their pixels, ascending; ``rest_usable`` (r,) whether each may join a
    region; ``point_normals`` (3, r)), as :func:`grid_region` gives it; each tolerance times :func:`_facing` of
    ``ray``."""
    r = cols.shape[1]
    per_point = tolerance.shape[0] > 1
    band = np.empty(r, np.int64)  # the band's points (places in cols) that may join a region, ascending
    pixels = np.empty(r, np.int64)  # ... their pixels
    inlier = np.empty(r, np.bool_)  # ... within t
    above = np.empty(r, np.bool_)  # ... on the side the normal points to
    n_band = 0
    for q in range(r):  # written for every point, kept for those in the band: no branch
        e = nx * cols[0, q] + ny * cols[1, q] + nz * cols[2, q] + offset
        t = (tolerance[q] if per_point else tolerance[0]) * _facing(cols[0, q], cols[1, q], cols[2, q], nx, ny, nz, ray)
        cos = abs(point_normals[0, q] * nx + point_normals[1, q] * ny + point_normals[2, q] * nz)
        band[n_band] = q
        pixels[n_band] = rest_pixel[q]
        inlier[n_band] = abs(e) <= t
        above[n_band] = e > 0
        n_band += (abs(e) <= support * t) & (not cos < min_cos) & rest_usable[q]
    in_place = np.empty(n_band, np.int64)  # the inliers' places in cols
    in_pixels = np.empty(n_band, np.int64)  # ... and pixels
    n_in = 0
    for b in range(n_band):
        in_place[n_in] = band[b]
        in_pixels[n_in] = pixels[b]
        n_in += inlier[b]
    in_pixels = in_pixels[:n_in]
    best, component, starts, n_runs, sizes = _row_run_components(in_pixels, width, bridges, np.ones(n_in, np.bool_))
    kept = np.zeros(r, np.bool_)
    kept_count = 0
    for k in range(n_runs):
        if component[k] == best:
            kept_count += starts[k + 1] - starts[k]
            for c in range(starts[k], starts[k + 1]):
                kept[in_place[c]] = True
    if not _fragmented(sizes, rules[0], rules[1]):
        return kept, kept.copy()
    best, component, starts, n_runs, _ = _row_run_components(pixels[:n_band], width, bridges, inlier[:n_band])
    beyond = above_count = joined = 0
    for k in range(n_runs):
        if component[k] == best:
            for b in range(starts[k], starts[k + 1]):
                if inlier[b]:
                    joined += 1
                else:
                    beyond += 1
                    above_count += above[b]
    below = beyond - above_count
    if min(above_count, below) >= rules[2] * max(above_count, below) and joined > kept_count:
        taken = np.zeros(r, np.bool_)
        joint = np.zeros(r, np.bool_)
        for k in range(n_runs):
            if component[k] == best:
                for b in range(starts[k], starts[k + 1]):
                    taken[band[b]] = True
                    joint[band[b]] = inlier[b]
        return joint, taken
    return kept, kept.copy()


@numba.njit(**_NUMPY_JIT)
def _next_candidate(cols: np.ndarray, tolerance: np.ndarray, normals: np.ndarray, offsets: np.ndarray,
                    point_normals: np.ndarray, bound_cos: float, counts: np.ndarray, cost: np.ndarray,
                    known: np.ndarray, order: np.ndarray, i: int, winner: int, size: int, ray: np.ndarray) -> int:
    """The step of :func:`grid_plane`'s and :func:`graph_plane`'s search over the hypotheses ranked by
    :func:`_ranked` (``counts``, ``cost``, ``known``, ``order``) that decides on the i-th: its number when its region
    is to be found, -1 when it cannot beat the ``winner`` so far (a region of ``size`` points; by
    :func:`_coherent_near`'s bound, ``bound_cos``), -2 when neither it nor any after it can."""
    j = order[i]
    if counts[j] <= size:
        return -2
    if size > 0:
        bound = _coherent_near(cols, tolerance, normals[j], offsets[j], point_normals, bound_cos, ray)
        if bound < size or (bound == size and _msac_cost(cols, tolerance, normals, offsets, j, cost, known, ray) >=
                            _msac_cost(cols, tolerance, normals, offsets, winner, cost, known, ray)):
            return -1
    return j


@numba.njit(**_NUMPY_JIT)
def _beats(cols: np.ndarray, tolerance: np.ndarray, normals: np.ndarray, offsets: np.ndarray, cost: np.ndarray,
           known: np.ndarray, kept: np.ndarray, j: int, winner: int, size: int, ray: np.ndarray) -> bool:
    """Whether hypothesis j's region ``kept`` (r,) beats the ``winner``'s of ``size`` points: larger, or as large
    at a lower MSAC cost (:func:`_msac_cost`)."""
    found = np.count_nonzero(kept)
    return found > size or (found == size and _msac_cost(cols, tolerance, normals, offsets, j, cost, known, ray) <
                            _msac_cost(cols, tolerance, normals, offsets, winner, cost, known, ray))


@numba.njit(**_NUMPY_JIT)
def _refit_kept(normal: np.ndarray, offset: float, region: np.ndarray, taken: np.ndarray, new_normal: np.ndarray,
                new_offset: float, new_region: np.ndarray, new_taken: np.ndarray
                ) -> tuple[bool, np.ndarray, float, np.ndarray, np.ndarray]:
    """One refit's outcome in :func:`grid_plane` and :func:`graph_plane` (``hypotheses.best_region``): the refitted
    plane and its region replace the old ones unless the region shrinks; refitting goes on while it changes. Returns
    (go on, normal (3,), offset meters, region (r,), taken (r,))."""
    if np.count_nonzero(new_region) < np.count_nonzero(region):
        return False, normal, offset, region, taken
    return not np.array_equal(new_region, region), new_normal, new_offset, new_region, new_taken


@numba.njit(**_NUMPY_JIT)
def _grid_best(cols: np.ndarray, tolerance: np.ndarray, normals: np.ndarray, offsets: np.ndarray, support: float,
               bound_cos: float, point_normals: np.ndarray, rest_pixel: np.ndarray, rest_usable: np.ndarray,
               width: int, bridges: np.ndarray, min_cos: float, rules: np.ndarray, ray: np.ndarray,
               rank_ray: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """Of the confirmed hypotheses, the one whose region is largest (see :func:`grid_plane`; ``rest_usable`` (r,):
    whether each point may join a region): (its number, region (r,), taken (r,)). Hypotheses are tried by inliers,
    then cost; none can keep more than its inliers, nor more than those whose normal lies within ``bound_cos`` of its
    own: such hypotheses are not labelled (a bound, so it changes no answer)."""
    h, r = normals.shape[0], cols.shape[1]
    counts, cost, known, order = _ranked(cols, tolerance, normals, offsets, rank_ray)
    winner, size = -1, -1
    region = taken = np.zeros(r, np.bool_)
    for i in range(h):
        j = _next_candidate(cols, tolerance, normals, offsets, point_normals, bound_cos, counts, cost, known, order,
                            i, winner, size, rank_ray)
        if j == -2:
            break
        if j < 0:
            continue
        kept, took = _grid_band_region(cols, tolerance, support, normals[j, 0], normals[j, 1], normals[j, 2],
                                       offsets[j], point_normals, rest_pixel, rest_usable, width, bridges, min_cos,
                                       rules, ray)
        if _beats(cols, tolerance, normals, offsets, cost, known, kept, j, winner, size, rank_ray):
            winner, region, taken, size = j, kept, took, np.count_nonzero(kept)
    return winner, region, taken


@numba.njit(**_NUMPY_JIT)
def _usable_at(usable: np.ndarray, rest_pixel: np.ndarray) -> np.ndarray:
    """(r,) whether the pixel ``rest_pixel`` (r,) of each point may join a region (``usable`` (h * w,))."""
    out = np.empty(rest_pixel.shape[0], np.bool_)
    for q in range(rest_pixel.shape[0]):
        out[q] = usable[rest_pixel[q]]
    return out


@numba.njit(**_NUMPY_JIT)
def _grid_refit(cols: np.ndarray, region: np.ndarray, tolerance: np.ndarray, support: float,
                point_normals: np.ndarray, rest_pixel: np.ndarray, rest_usable: np.ndarray, width: int,
                bridges: np.ndarray, min_cos: float, rules: np.ndarray, ray: np.ndarray
                ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """:func:`grid_refit` with the usable flags of the points (r,)."""
    normal, offset = fit_members(cols, np.flatnonzero(region))
    kept, took = _grid_band_region(cols, tolerance, support, normal[0], normal[1], normal[2], offset, point_normals,
                                   rest_pixel, rest_usable, width, bridges, min_cos, rules, ray)
    return normal, offset, kept, took


@numba.njit(**_NUMPY_JIT)
def grid_refit(cols: np.ndarray, region: np.ndarray, tolerance: np.ndarray, support: float, point_normals: np.ndarray,
               rest_pixel: np.ndarray, usable: np.ndarray, width: int, bridges: np.ndarray, min_cos: float,
               rules: np.ndarray, ray: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """The least-squares plane of the points ``region`` (r,) bool (at least one) of ``cols`` (3, r) meters and the
    region it keeps among them (the sub-grid arguments as :func:`grid_plane` takes them): (normal (3,), offset meters,
    region (r,), taken (r,))."""
    return _grid_refit(cols, region, tolerance, support, point_normals, rest_pixel, _usable_at(usable, rest_pixel),
                       width, bridges, min_cos, rules, ray)


@numba.njit(**_NUMPY_JIT)
def grid_plane(cols: np.ndarray, tolerance: np.ndarray, normals: np.ndarray, offsets: np.ndarray, support: float,
               bound_cos: float, point_normals: np.ndarray, rest_pixel: np.ndarray, usable: np.ndarray, width: int,
               bridges: np.ndarray, min_cos: float, rules: np.ndarray, refits: int, ray: np.ndarray,
               rank_ray: np.ndarray) -> tuple[int, np.ndarray, float, np.ndarray, np.ndarray]:
    """A RANSAC run's plane on a sub-grid's points ``cols`` (3, r) meters (their pixels ``rest_pixel`` (r,),
    ascending, on an image ``width`` wide with ``usable`` pixels and ``bridges`` (b, 3), as :func:`grid_components`
    takes them; their local normals ``point_normals`` (3, r), NaN where unknown): of the confirmed hypotheses
    (``normals`` (h, 3), ``offsets`` (h,)) the one whose region (``Neighbours.region``: its inliers within
    ``tolerance``, (1,) or (r,) meters, whose normals lie within ``min_cos`` of its own, their largest connected
    component, or through the support band ``support`` times as wide by ``rules`` (FRAGMENTED, FRAGMENT_PIECE,
    SUPPORT_BALANCE)) is largest, equals by the lower MSAC cost (``bound_cos``: see :func:`_grid_best`); then up to
    ``refits`` least-squares refits on its region (:func:`grid_refit`), each kept while the region does not shrink,
    until it stays the same (``hypotheses.best_region`` without an orientation constraint). Each tolerance is times
    :func:`_facing` of ``ray`` in the regions and of ``rank_ray`` in ranking the hypotheses. Returns (the winner, the
    plane's normal (3,), offset meters, region (r,), taken (r,))."""
    rest_usable = _usable_at(usable, rest_pixel)
    winner, region, taken = _grid_best(cols, tolerance, normals, offsets, support, bound_cos, point_normals,
                                       rest_pixel, rest_usable, width, bridges, min_cos, rules, ray, rank_ray)
    normal, offset = normals[winner].copy(), offsets[winner]
    for _ in range(refits):
        if np.count_nonzero(region) < 3:
            break
        new_normal, new_offset, new_region, new_taken = _grid_refit(cols, region, tolerance, support, point_normals,
                                                                    rest_pixel, rest_usable, width, bridges, min_cos,
                                                                    rules, ray)
        more, normal, offset, region, taken = _refit_kept(normal, offset, region, taken, new_normal, new_offset,
                                                          new_region, new_taken)
        if not more:
            break
    return winner, normal, offset, region, taken


@numba.njit(**_NUMPY_JIT)
def _ray_distance(search: np.ndarray, p: int, planes: np.ndarray, j: int, tolerance: np.ndarray,
                  viewpoint: np.ndarray, min_cos: float, ray: np.ndarray) -> float:
    """:func:`compete_distances`' entry (j, p): point ``p``'s distance to plane ``j`` along its ray (inf for j = k, no
    region), the same arithmetic."""
    if j >= planes.shape[0]:
        return np.inf
    x, y, z = search[0, p], search[1, p], search[2, p]
    rx, ry, rz = x - viewpoint[0], y - viewpoint[1], z - viewpoint[2]
    size = _length(rx, ry, rz)
    rx, ry, rz = rx / size, ry / size, rz / size
    tol = (tolerance[p] if tolerance.shape[0] > 1 else tolerance[0]) * \
        _facing(x, y, z, planes[j, 0], planes[j, 1], planes[j, 2], ray)
    e = abs(planes[j, 0] * x + planes[j, 1] * y + planes[j, 2] * z + planes[j, 3])
    if e > tol:
        e = np.inf
    facing = abs(planes[j, 0] * rx + planes[j, 1] * ry + planes[j, 2] * rz)
    return e / (facing if np.isnan(facing) or facing > min_cos else min_cos)


@numba.njit(**_NUMPY_JIT)
def grid_settle(search: np.ndarray, planes: np.ndarray, tolerance: np.ndarray, viewpoint: np.ndarray, min_cos: float,
                region: np.ndarray, pixel: np.ndarray, node: np.ndarray, width: int, eight: np.ndarray, rounds: int,
                ray: np.ndarray) -> np.ndarray:
    """Border settling on a sub-grid (``Neighbours.settle``) by the distances along each point's ray of
    :func:`compete_distances` (``search`` (3, m) meters, ``planes`` (k, 4), ``tolerance`` (1,) or (m,) meters,
    ``viewpoint`` (3,), ``min_cos``), each worked out only where an offer compares it: ``region`` (m,) 0..k (k:
    none). Each round every point takes the region of an 8-neighbour (``eight``) whose plane is nearer than its own
    (the nearest; equals: the neighbour with the smaller index), all from the labels before the round; the first round
    looks at the points with a neighbour in another region, the next ones at the neighbours of the points that
    changed. A plane is within reach when within the tolerance times :func:`_facing` of ``ray``. Returns the regions
    (m,), k for none."""
    m = region.shape[0]
    height = node.shape[0] // width
    region = region.copy()
    padded = width + 2
    at = np.full((height + 2) * padded, -1, np.int64)
    place = np.empty(m, np.int64)
    r = 0
    for i in range(m):
        if i == 0 or pixel[i] >= (r + 1) * width:
            r = pixel[i] // width
        place[i] = (r + 1) * padded + pixel[i] - r * width + 1
        at[place[i]] = i
    n_eight = eight.shape[0]
    step = np.empty(n_eight, np.int64)
    for e in range(n_eight):
        step[e] = eight[e, 0] * padded + eight[e, 1]
    best = np.empty(m)
    known = np.zeros(m, np.bool_)  # best worked out (the distance to its region's plane, until it changes)
    offer_d = np.empty(m)
    offer_src = np.full(m, -1, np.int64)
    offer_region = np.empty(m, np.int64)
    touched = np.empty(m, np.int64)
    changed = np.empty(m, np.int64)
    n_changed = -1
    for _ in range(rounds):
        n_touched = 0
        first = n_changed < 0
        for q in range(m if first else n_changed):
            if first:
                centre = q
                bordering = False
                for e in range(n_eight):
                    j = at[place[centre] + step[e]]
                    if j >= 0 and region[j] != region[centre]:
                        bordering = True
                        break
                if not bordering:
                    continue
            else:
                centre = changed[q]
            for e in range(n_eight):
                other = at[place[centre] + step[e]]
                if other < 0:
                    continue
                dst, src = (centre, other) if first else (other, centre)
                cand = region[src]
                if cand == region[dst]:
                    continue  # its own plane is never nearer than itself
                if not known[dst]:
                    best[dst] = _ray_distance(search, dst, planes, region[dst], tolerance, viewpoint, min_cos, ray)
                    known[dst] = True
                d = _ray_distance(search, dst, planes, cand, tolerance, viewpoint, min_cos, ray)
                if not d < best[dst]:
                    continue
                if offer_src[dst] < 0:
                    touched[n_touched] = dst
                    n_touched += 1
                elif not (d < offer_d[dst] or (d == offer_d[dst] and src < offer_src[dst])):
                    continue
                offer_d[dst], offer_src[dst], offer_region[dst] = d, src, cand
        if n_touched == 0:
            break
        for q in range(n_touched):
            i = touched[q]
            region[i], best[i] = offer_region[i], offer_d[i]
            offer_src[i] = -1
            changed[q] = i
        n_changed = n_touched
    return region


@numba.njit(**_NUMPY_JIT)
def merge_pair(search: np.ndarray, region: np.ndarray, i: int, j: int, own: np.ndarray, tolerance: np.ndarray,
               src: np.ndarray, dst: np.ndarray, region_src: np.ndarray, region_dst: np.ndarray, root: np.ndarray,
               normals: np.ndarray, min_cos: float, keep: float, spread: float, test: bool, ray: np.ndarray
               ) -> tuple[bool, np.ndarray, float, np.ndarray]:
    """Two touching regions ``i`` < ``j`` of ``region`` (m,) of the points ``search`` (3, m) meters tried as one
    surface in one call: their points (ascending), their joint least-squares plane (:func:`fit_members`) and, with
    ``test``, :func:`merge_test` of it (``own`` (2, 4): their own planes; the other arguments are merge_test's).
    Returns (whether they are one surface: False without ``test``, the joint normal (3,), its offset meters, their
    points)."""
    m = region.shape[0]
    members = np.empty(m, np.int64)
    c = 0
    for p in range(m):  # written for every point, kept for the pair's: no branch
        members[c] = p
        c += (region[p] == i) | (region[p] == j)
    members = members[:c]
    normal, offset = fit_members(search, members)
    if not test:
        return False, normal, offset, members
    plane = np.empty(4)
    plane[:3] = normal
    plane[3] = offset
    same = merge_test(search, members, region, i, j, plane, own, tolerance, src, dst, region_src, region_dst, root,
                      normals, min_cos, keep, spread, ray)
    return same, normal, offset, members


# --- frame: planes renumbered by track id ---


@numba.njit(**_JIT)
def relabel_rows(labels: np.ndarray, finite: np.ndarray, rank: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``rank[labels]`` for the labels (N,) in -1..k-1 of an organized frame's rows (-1, and any label outside
    0..k-1, takes the last entry of ``rank`` (k + 1,) int32), (N,) int32, and the same at the rows ``finite`` (N,)
    bool marks, in order ((n,)): the renumbered labels of the rows and of the valid points in one pass."""
    n = labels.shape[0]
    last = rank.shape[0] - 1
    rows = np.empty(n, np.int32)
    points = np.empty(n, np.int32)
    m = 0
    for i in range(n):
        lab = labels[i]
        value = rank[lab] if 0 <= lab < last else rank[last]
        rows[i] = value
        if finite[i]:
            points[m] = value
            m += 1
    return rows, points[:m]



@numba.njit(**_JIT)
def labels_where(labels: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """np.compress(keep, labels): the int32 ``labels`` (N,) at the rows ``keep`` (N,) bool marks, in order ((n,), the
    start of an (N,) buffer). Each row is written and the end moves on by its flag, without a branch: the marks of an
    image's valid pixels come in runs, but a branch per row still costs more than numpy's copy."""
    out = np.empty(labels.shape[0], np.int32)
    m = 0
    for i in range(labels.shape[0]):
        out[m] = labels[i]
        m += keep[i]
    return out[:m]

# --- verdict: the beyond test's rows ---


@numba.njit(**_JIT)
def beyond_rows(points: np.ndarray, step: int, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every ``step``-th row of ``points`` (N, 3) whose coordinates sum to a finite value (m, 3), and its entry of
    ``labels`` (N,) (m,): in one pass, without a strided copy of every such row first."""
    n = points.shape[0]
    cloud = np.empty(((n + step - 1) // step, 3))
    kept = np.empty((n + step - 1) // step, labels.dtype)
    m = 0
    for i in range(0, n, step):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        total = x + y + z
        if total - total == 0.0:  # NaN for a coordinate not finite, or a sum too large
            cloud[m, 0], cloud[m, 1], cloud[m, 2] = x, y, z
            kept[m] = labels[i]
            m += 1
    return cloud[:m], kept[:m]


# --- organized detect: labelling, batches, gathers ---
# Every pixel of an image labelled from its sub-grid's regions and grouped by region in one pass; a RANSAC batch drawn
# on a sub-grid, its planes and their scores in one call.


@numba.njit(**_NUMPY_JIT)
def _cell_regions(sub: np.ndarray, cell: int, k: int, steps: np.ndarray, cand: np.ndarray, n_cand: np.ndarray
                  ) -> None:
    """The regions of the 8 neighbours (``steps`` from ``cell`` in the padded sub-grid regions ``sub``, k: none) of
    ``cell`` other than its own, each once, in the order met, into ``cand[cell]`` and their number into
    ``n_cand[cell]``: a neighbour of the cell's own region, or of one met before, is no nearer."""
    own = sub[cell]
    n = 0
    for e in range(steps.shape[0]):
        lab = sub[cell + steps[e]]
        if lab >= k or lab == own:
            continue
        seen = False
        for q in range(n):
            seen |= cand[cell, q] == lab
        if not seen:
            cand[cell, n] = lab
            n += 1
    n_cand[cell] = n


@numba.njit(**_NUMPY_JIT)
def _grouped(labels: np.ndarray, best: np.ndarray, counts: np.ndarray, k: int
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`label_rows` of ``labels`` (N,) in -1..k-1 with ``counts`` (k + 1,) rows of each already known, squaring
    the distances ``best`` (N,) (read at labelled rows only)."""
    bounds = np.zeros(k + 1, np.int64)
    for j in range(k):
        bounds[j + 1] = bounds[j] + counts[j]
    rows, squares = _filled_runs(labels, bounds, best)
    return rows, bounds, squares


@numba.njit(**_NUMPY_JIT)
def grid_spread(points: np.ndarray, valid: np.ndarray, pixel: np.ndarray, region: np.ndarray, gh: int, gw: int,
                near_r: np.ndarray, near_c: np.ndarray, planes: np.ndarray, tolerance: np.ndarray, eight: np.ndarray,
                ray: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Labels (N,) int32 of the pixels of an H x W image ``points`` (N, 3) meters from the regions ``region`` (m,)
    (-1: none) of the points at ``pixel`` (m,) of its gh x gw sub-grid, ``planes`` (k, 4) rows (a, b, c, d) in the
    coordinates of ``points``: a pixel takes the region of its nearest sub-grid pixel (``near_r`` (H,), ``near_c``
    (W,)) when within tolerance of its plane, else of the 8 sub-grid pixels around that one (``eight``, in order) the
    region whose plane is nearest within tolerance (a strictly nearer one wins a tie); -1 otherwise. ``valid`` (N,)
    bool: finite rows; ``tolerance``: (1,) or (N,) meters, times :func:`_facing` of ``ray``. Also each region's
    rows, ascending, one after another (rows (c,) int64, bounds (k + 1,) int64: region j's are
    rows[bounds[j]:bounds[j + 1]]) and their squared distances to its plane (c,) m^2 in the same order
    (:func:`label_rows` of the labels and those distances)."""
    h, w = near_r.shape[0], near_c.shape[0]
    k = planes.shape[0]
    per_point = tolerance.shape[0] > 1
    wide = gw + 2  # the sub-grid padded by a cell of no region all round: no bounds tests
    sub = np.full((gh + 2) * wide, k, np.int64)
    for q in range(pixel.shape[0]):
        if region[q] >= 0:
            sub[(pixel[q] // gw + 1) * wide + pixel[q] % gw + 1] = region[q]
    steps = np.empty(eight.shape[0], np.int64)
    for e in range(eight.shape[0]):
        steps[e] = eight[e, 0] * wide + eight[e, 1]
    cand = np.empty((sub.shape[0], eight.shape[0]), np.int64)
    n_cand = np.full(sub.shape[0], -1, np.int64)  # -1: not worked out yet (most cells never need them)
    labels = np.empty(h * w, np.int32)
    best = np.empty(h * w)  # the distance of each labelled pixel to its plane
    counts = np.zeros(k + 1, np.int64)
    run, run_length = -1, 0  # labels come in runs: counted through a local counter
    # the plane of the last nearest sub-grid region in locals (neighbouring pixels share it): loaded again only when
    # that region changes, not after each store of a label (which, for all the compiler knows, might change it)
    held, pa, pb, pc, pd = -1, 0.0, 0.0, 0.0, 0.0
    tol = tolerance[0]
    for r in range(h):
        row_cell = (near_r[r] + 1) * wide + 1
        for c in range(w):
            i = r * w + c
            out = -1
            if valid[i]:
                x, y, z = points[i, 0], points[i, 1], points[i, 2]
                if per_point:
                    tol = tolerance[i]
                cell = row_cell + near_c[c]
                lab = sub[cell]
                nearest = np.inf
                if lab < k:
                    if lab != held:
                        held, pa, pb, pc, pd = lab, planes[lab, 0], planes[lab, 1], planes[lab, 2], planes[lab, 3]
                    d = abs(pa * x + pb * y + pc * z + pd)
                    if d <= tol * _facing(x, y, z, pa, pb, pc, ray):
                        out, nearest = lab, d
                if out < 0:
                    if n_cand[cell] < 0:
                        _cell_regions(sub, cell, k, steps, cand, n_cand)
                    for q in range(n_cand[cell]):
                        lab = cand[cell, q]
                        d = abs(planes[lab, 0] * x + planes[lab, 1] * y + planes[lab, 2] * z + planes[lab, 3])
                        if d <= tol * _facing(x, y, z, planes[lab, 0], planes[lab, 1], planes[lab, 2], ray) and \
                                d < nearest:
                            out, nearest = lab, d
                best[i] = nearest
            labels[i] = out
            if out != run:
                counts[run] += run_length  # run -1 counts into counts[k], never read
                run, run_length = out, 0
            run_length += 1
    counts[run] += run_length
    rows, bounds, squares = _grouped(labels, best, counts, k)
    return labels, rows, bounds, squares


@numba.njit(**_NUMPY_JIT)
def strided_rows(flags: np.ndarray, count: int, stride: int) -> np.ndarray:
    """The rows of every ``stride``-th True of ``flags`` (N,), from the first, which holds ``count`` of them:
    np.flatnonzero(flags)[::stride] without the rows in between."""
    out = np.empty((count + stride - 1) // stride, np.int64)
    seen = taken = 0
    for i in range(flags.shape[0]):
        if flags[i]:
            if seen == 0:
                if taken == out.shape[0]:  # more Trues than ``count``: the rows of the first ``count`` only
                    break
                out[taken] = i
                taken += 1
                seen = stride
            seen -= 1
    return out[:taken]


@numba.njit(**_NUMPY_JIT)
def columns_at(values: np.ndarray, rows: np.ndarray, center: np.ndarray) -> np.ndarray:
    """(3, m) the rows ``rows`` (m,) of ``values`` (N, 3) less ``center`` (3,), as columns: numpy's
    (values.take(rows, axis=0) - center).T made C-ordered, in one pass."""
    m = rows.shape[0]
    out = np.empty((3, m))
    cx, cy, cz = center[0], center[1], center[2]
    for q in range(m):
        i = rows[q]
        out[0, q] = values[i, 0] - cx
        out[1, q] = values[i, 1] - cy
        out[2, q] = values[i, 2] - cz
    return out


@numba.njit(**_JIT)
def rows_less(values: np.ndarray, rows: np.ndarray, center: np.ndarray) -> np.ndarray:
    """(m, 3) the rows ``rows`` (m,) of ``values`` (N, 3) less ``center`` (3,): numpy's values[rows] - center in one
    pass (numpy's gather of 3-wide rows is several times slower)."""
    m = rows.shape[0]
    out = np.empty((m, 3))
    cx, cy, cz = center[0], center[1], center[2]
    for q in range(m):
        i = rows[q]
        out[q, 0] = values[i, 0] - cx
        out[q, 1] = values[i, 1] - cy
        out[q, 2] = values[i, 2] - cz
    return out


@numba.njit(**_NUMPY_JIT)
def grid_batch(cols: np.ndarray, spread: np.ndarray, first: np.ndarray, scale_pick: np.ndarray, row_share: np.ndarray,
               col_share: np.ndarray, scales: np.ndarray, rest: np.ndarray, position: np.ndarray, pixel: np.ndarray,
               node: np.ndarray, height: int, width: int, min_sine: float, subset: np.ndarray, tolerance: np.ndarray,
               point_normals: np.ndarray, head: int, min_cos: float, sigmas: float, best_normals: np.ndarray,
               best_offsets: np.ndarray, best_counts: np.ndarray, n_best: int, ray: np.ndarray) -> int:
    """One batch of RANSAC hypotheses on a sub-grid's points ``cols`` (3, r) meters, scored: the triples ``spread``
    (c, 3) drawn from all of them and those drawn near ``first`` (:func:`grid_triples`, the draws and the sub-grid as
    it takes them), without those with a point it did not find, then their planes (:func:`triple_planes`,
    ``min_sine``), merged into the best so far (:func:`score_hypotheses`, the scoring arguments as it takes them).
    Returns how many of the best are held now (unchanged when every triple was degenerate)."""
    near = grid_triples(first, scale_pick, row_share, col_share, scales, rest, position, pixel, node, height, width)
    return _scored_batch(cols, spread, near, min_sine, subset, tolerance, point_normals, head, min_cos, sigmas,
                         best_normals, best_offsets, best_counts, n_best, ray)


@numba.njit(**_JIT)
def graph_batch(cols: np.ndarray, spread: np.ndarray, first: np.ndarray, scale_pick: np.ndarray, steps: np.ndarray,
                scales: np.ndarray, rest: np.ndarray, position: np.ndarray, indptr: np.ndarray, indices: np.ndarray,
                degrees: np.ndarray, min_sine: float, subset: np.ndarray, tolerance: np.ndarray,
                point_normals: np.ndarray, head: int, min_cos: float, sigmas: float, best_normals: np.ndarray,
                best_offsets: np.ndarray, best_counts: np.ndarray, n_best: int, ray: np.ndarray) -> int:
    """:func:`grid_batch` on a graph's points: the triples near ``first`` are :func:`graph_triples`' walks (the
    draws and the graph as it takes them)."""
    near = graph_triples(first, scale_pick, steps, scales, rest, position, indptr, indices, degrees)
    return _scored_batch(cols, spread, near, min_sine, subset, tolerance, point_normals, head, min_cos, sigmas,
                         best_normals, best_offsets, best_counts, n_best, ray)


@numba.njit(**_JIT)
def _scored_batch(cols: np.ndarray, spread: np.ndarray, near: np.ndarray, min_sine: float, subset: np.ndarray,
                  tolerance: np.ndarray, point_normals: np.ndarray, head: int, min_cos: float, sigmas: float,
                  best_normals: np.ndarray, best_offsets: np.ndarray, best_counts: np.ndarray, n_best: int,
                  ray: np.ndarray) -> int:
    """The triples ``spread`` then ``near`` ((c, 3) each) without those holding a -1, their planes, scored into the
    best so far: the rest of :func:`grid_batch` and :func:`graph_batch`."""
    idx = np.empty((spread.shape[0] + near.shape[0], 3), np.int64)
    g = 0
    for source in (spread, near):
        for q in range(source.shape[0]):
            if source[q, 0] >= 0 and source[q, 1] >= 0 and source[q, 2] >= 0:
                idx[g, 0], idx[g, 1], idx[g, 2] = source[q, 0], source[q, 1], source[q, 2]
                g += 1
    normals, offsets = triple_planes(cols, idx[:g], min_sine)
    if normals.shape[0] == 0:
        return n_best
    return score_hypotheses(subset, tolerance, point_normals, normals, offsets, head, min_cos, sigmas, best_normals,
                            best_offsets, best_counts, n_best, ray)


# --- plain graph: subgraphs and border settling ---


@numba.njit(**_JIT)
def kept_edges(edges: np.ndarray, keep: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The pairs (e', 2) of ``edges`` (e, 2) of a graph of n points whose both ends are among ``keep`` (ascending
    point indices), renumbered to positions in ``keep``, in their order, and where each kept point's pairs start
    among them ((len(keep) + 1,); the rows of pairs sorted by their first end, as ``edges`` are). One pass: the
    pairs are the first rows of an array of e (a view)."""
    position = np.full(n, -1, np.int64)
    for i in range(keep.shape[0]):
        position[keep[i]] = i
    starts = np.zeros(keep.shape[0] + 1, np.int64)
    out = np.empty((edges.shape[0], 2), np.int64)
    count = 0
    for q in range(edges.shape[0]):
        a, b = position[edges[q, 0]], position[edges[q, 1]]
        if a >= 0 and b >= 0:
            out[count, 0], out[count, 1] = a, b
            starts[a + 1] += 1
            count += 1
    for i in range(keep.shape[0]):
        starts[i + 1] += starts[i]
    return out[:count], starts


@numba.njit(**_JIT)
def graph_contacts(edges: np.ndarray, region: np.ndarray, k: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pairs of ``edges`` (e, 2) that join two of the ``k`` regions ``region`` (m,) (-1: none), in their order:
    (src, dst, their regions a, b, each touching pair of regions once as i * k + j (i < j), ascending)."""
    n = 0
    for q in range(edges.shape[0]):
        ri, rj = region[edges[q, 0]], region[edges[q, 1]]
        if ri >= 0 and rj >= 0 and ri != rj:
            n += 1
    src = np.empty(n, np.int64)
    dst = np.empty(n, np.int64)
    a = np.empty(n, np.int64)
    b = np.empty(n, np.int64)
    codes = np.empty(n, np.int64)
    n = 0
    for q in range(edges.shape[0]):
        i, j = edges[q, 0], edges[q, 1]
        ri, rj = region[i], region[j]
        if ri >= 0 and rj >= 0 and ri != rj:
            src[n], dst[n], a[n], b[n] = i, j, ri, rj
            codes[n] = min(ri, rj) * k + max(ri, rj)
            n += 1
    return src, dst, a, b, np.unique(codes)


@numba.njit(**_JIT)
def voxel_count(points: np.ndarray, origin: np.ndarray, cell: float, dims: np.ndarray) -> int:
    """How many voxels :func:`voxel_grid` would find occupied by ``points`` (m, 3) with the same ``origin``, ``cell``
    and ``dims``, counted in a hash set (no sort)."""
    m = points.shape[0]
    size = 1
    while size < 2 * m + 2:
        size *= 2
    table = np.full(size, -1, np.int64)
    count = 0
    for i in range(m):
        ix = int((points[i, 0] - origin[0]) / cell)
        iy = int((points[i, 1] - origin[1]) / cell)
        iz = int((points[i, 2] - origin[2]) / cell)
        key = ix + dims[0] * (iy + dims[1] * iz)
        s = _slot(key, size - 1)
        while table[s] >= 0 and table[s] != key:
            s = (s + 1) & (size - 1)
        if table[s] < 0:
            table[s] = key
            count += 1
    return count


@numba.njit(**_JIT)
def _offer(dst: int, src: int, d: float, cand: int, offer_d: np.ndarray, offer_src: np.ndarray,
           offer_region: np.ndarray, offered: np.ndarray, count: int) -> int:
    """Record the offer of region ``cand`` from ``src`` to ``dst`` at distance ``d`` when it beats the one ``dst``
    holds (nearer; equal: from a smaller index than ``dst``, then from the largest index); returns how many points
    hold an offer (``offered`` lists them)."""
    held = offer_src[dst]
    if held < 0:
        offered[count] = dst
        count += 1
    elif not (d < offer_d[dst] or (d == offer_d[dst] and ((src < dst and held > dst) or
                                                          ((src < dst) == (held < dst) and src > held)))):
        return count
    offer_d[dst], offer_src[dst], offer_region[dst] = d, src, cand
    return count


@numba.njit(**_NUMPY_JIT)
def graph_plane(cols: np.ndarray, tolerance: np.ndarray, normals: np.ndarray, offsets: np.ndarray, support: float,
                bound_cos: float, point_normals: np.ndarray, ends: np.ndarray, edge_rows: np.ndarray, min_cos: float,
                rules: np.ndarray, refits: int) -> tuple[int, np.ndarray, float, np.ndarray, np.ndarray]:
    """:func:`grid_plane` on a graph of the points ``cols`` (3, r) meters joined by edges (``ends`` (e,),
    ``edge_rows`` (r + 1,), as :func:`graph_region` takes them): the confirmed hypothesis whose region is
    largest, then up to ``refits`` least-squares refits on its region. Returns (the winner, the plane's normal (3,),
    offset meters, region (r,), taken (r,))."""
    h, r = normals.shape[0], cols.shape[1]
    rank_ray = np.empty(0)
    counts, cost, known, order = _ranked(cols, tolerance, normals, offsets, rank_ray)
    winner, size = -1, -1
    region = taken = np.zeros(r, np.bool_)
    for i in range(h):  # Remaining.best's loop
        j = _next_candidate(cols, tolerance, normals, offsets, point_normals, bound_cos, counts, cost, known, order,
                            i, winner, size, rank_ray)
        if j == -2:
            break
        if j < 0:
            continue
        kept, took = _graph_plane_region(cols, tolerance, support, normals[j], offsets[j], point_normals, ends,
                                         edge_rows, min_cos, rules)
        if _beats(cols, tolerance, normals, offsets, cost, known, kept, j, winner, size, rank_ray):
            winner, region, taken, size = j, kept, took, np.count_nonzero(kept)
    normal, offset = normals[winner].copy(), offsets[winner]
    for _ in range(refits):  # hypotheses.best_region's
        if np.count_nonzero(region) < 3:
            break
        new_normal, new_offset = fit_members(cols, np.flatnonzero(region))
        new_region, new_taken = _graph_plane_region(cols, tolerance, support, new_normal, new_offset, point_normals,
                                                    ends, edge_rows, min_cos, rules)
        more, normal, offset, region, taken = _refit_kept(normal, offset, region, taken, new_normal, new_offset,
                                                          new_region, new_taken)
        if not more:
            break
    return winner, normal, offset, region, taken


@numba.njit(**_NUMPY_JIT)
def _graph_plane_region(cols: np.ndarray, tolerance: np.ndarray, support: float, normal: np.ndarray, offset: float,
                        point_normals: np.ndarray, ends: np.ndarray, edge_rows: np.ndarray, min_cos: float,
                        rules: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(kept, taken) (r,) of the plane (``normal`` (3,), ``offset`` meters) among the points of :func:`graph_plane`:
    :func:`graph_region` of its inliers and support band (:func:`plane_bands` and :func:`band_counts`' arithmetic),
    the points' normals (3, r) as its (r, 3)."""
    r = cols.shape[1]
    per_point = tolerance.shape[0] > 1
    nx, ny, nz = normal[0], normal[1], normal[2]
    wide = np.zeros(r, np.bool_)
    full = np.zeros(r, np.bool_)
    up = np.empty(r, np.bool_)
    band = np.empty(r, np.int64)
    inliers = np.empty(r, np.int64)
    n_band = n_in = 0
    for q in range(r):
        e = nx * cols[0, q] + ny * cols[1, q] + nz * cols[2, q] + offset
        t = tolerance[q] if per_point else tolerance[0]
        up[q] = e > 0
        d = abs(e)
        near, within = d <= support * t, d <= t
        if (near or within) and not abs(point_normals[0, q] * nx + point_normals[1, q] * ny
                                        + point_normals[2, q] * nz) < min_cos:
            if near:
                wide[q] = True
                band[n_band] = q
                n_band += 1
            if within:
                full[q] = True
                inliers[n_in] = q
                n_in += 1
    return _graph_band(ends, edge_rows, wide, full, up, band[:n_band], inliers[:n_in], rules)


@numba.njit(**_JIT)
def graph_settle(dist: np.ndarray, region: np.ndarray, indptr: np.ndarray, indices: np.ndarray, rounds: int
                 ) -> np.ndarray:
    """Border settling on a graph (adjacency ``indptr`` (m + 1,), ``indices``): ``region`` (m,) 0..k (k: none) after
    up to ``rounds`` rounds in which each point takes, of its own region and the regions its neighbours held at the
    round's start, the one nearest by ``dist`` (k + 1, m) (row k: inf); equal distances go to a neighbour of smaller
    index than the point, then to the largest. Returns the regions, -1 for none (updates ``region``)."""
    k, m = dist.shape[0] - 1, dist.shape[1]
    best = np.empty(m)
    for i in range(m):
        best[i] = dist[region[i], i]
    offer_d = np.empty(m)
    offer_src = np.full(m, -1, np.int64)
    offer_region = np.empty(m, np.int64)
    offered = np.empty(m, np.int64)
    count = 0
    for i in range(m):  # the first round: every point, from each neighbour (only those across a border can win)
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            cand = region[j]
            if cand != region[i]:
                d = dist[cand, i]
                if d < best[i]:
                    count = _offer(i, j, d, cand, offer_d, offer_src, offer_region, offered, count)
    changed = np.empty(m, np.int64)
    for _ in range(rounds):
        if count == 0:
            break
        for g in range(count):  # the offers above read the regions at the round's start
            i = offered[g]
            region[i], best[i] = offer_region[i], offer_d[i]
            offer_src[i] = -1
            changed[g] = i
        n_changed, count = count, 0
        for g in range(n_changed):  # their neighbours are offered the new regions
            c = changed[g]
            cand = region[c]
            for q in range(indptr[c], indptr[c + 1]):
                j = indices[q]
                d = dist[cand, j]
                if d < best[j]:
                    count = _offer(j, c, d, cand, offer_d, offer_src, offer_region, offered, count)
    out = np.empty(m, np.int64)
    for i in range(m):
        out[i] = region[i] if region[i] < k else -1
    return out


# --- verdict: tent ---


@numba.njit(**_JIT)
def tent_fit(u: np.ndarray, v: np.ndarray, w: np.ndarray, angles: int) -> float:
    """The smallest mean squared residual (m^2) of least-squares fits w = a + b d to points at in-plane coordinates
    (u, v) (m,) with residuals ``w`` (m,), all meters, where d is a point's distance to the nearest edge of the points'
    bounding box (a tent: the faces of a hip roof rising evenly from its eaves), the box turned through ``angles``
    directions theta = (pi / 2) k / angles. NaN for fewer than 3 points."""
    m = u.shape[0]
    if m < 3:
        return np.nan
    mw = w.mean()
    sww = 0.0
    for i in range(m):
        sww += (w[i] - mw) * (w[i] - mw)
    best = np.inf
    d = np.empty(m)
    for k in range(angles):
        theta = 0.5 * np.pi * k / angles
        c, s = np.cos(theta), np.sin(theta)
        lo_a = lo_b = np.inf
        hi_a = hi_b = -np.inf
        for i in range(m):
            a, b = u[i] * c + v[i] * s, v[i] * c - u[i] * s
            lo_a, hi_a, lo_b, hi_b = min(lo_a, a), max(hi_a, a), min(lo_b, b), max(hi_b, b)
        md = 0.0
        for i in range(m):
            a, b = u[i] * c + v[i] * s, v[i] * c - u[i] * s
            d[i] = min(min(a - lo_a, hi_a - a), min(b - lo_b, hi_b - b))
            md += d[i]
        md /= m
        sdd = sdw = 0.0
        for i in range(m):
            sdd += (d[i] - md) * (d[i] - md)
            sdw += (d[i] - md) * (w[i] - mw)
        rest = sww - sdw * sdw / sdd if sdd > 0.0 else sww
        best = min(best, max(rest, 0.0) / m)
    return best


# --- verdict: leftover ---


@numba.njit(**_JIT)
def leftover_rows(points: np.ndarray, labels: np.ndarray, stride: int, coefficients: np.ndarray, tolerance: float,
                  quadratic: bool, reference: float, viewpoint: np.ndarray, max_scale: float, cover: float,
                  axes: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Every ``stride``-th row of ``points`` (N, 3) meters that is finite, in no plane (``labels`` (N,) < 0) and not
    within ``cover`` t of a plane of ``coefficients`` (k, 4) whose extent holds it (its in-plane coordinates along
    ``axes`` (3, 2k) columns 2j, 2j + 1 within ``lo``, ``hi`` (2k,)): (those points (m, 3), their t (m,): ``tolerance``
    times, when ``quadratic``, the squared range from ``viewpoint`` (3,) over ``reference`` squared clipped to [1,
    ``max_scale``]; and how many of the rows read were finite, and of those in no plane)."""
    n, k = points.shape[0], coefficients.shape[0]
    size = (n + stride - 1) // stride
    out, out_t = np.empty((size, 3)), np.empty(size)
    m = valid = free = 0
    for i in range(0, n, stride):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
            continue
        valid += 1
        if labels[i] >= 0:
            continue
        free += 1
        t = tolerance
        if quadratic:
            dx, dy, dz = x - viewpoint[0], y - viewpoint[1], z - viewpoint[2]
            t = tolerance * min(max((dx * dx + dy * dy + dz * dz) / (reference * reference), 1.0), max_scale)
        covered = False
        for j in range(k):
            if abs(x * coefficients[j, 0] + y * coefficients[j, 1] + z * coefficients[j, 2]
                   + coefficients[j, 3]) <= cover * t:
                u = x * axes[0, 2 * j] + y * axes[1, 2 * j] + z * axes[2, 2 * j]
                v = x * axes[0, 2 * j + 1] + y * axes[1, 2 * j + 1] + z * axes[2, 2 * j + 1]
                if lo[2 * j] <= u <= hi[2 * j] and lo[2 * j + 1] <= v <= hi[2 * j + 1]:
                    covered = True
                    break
        if not covered:
            out[m, 0], out[m, 1], out[m, 2] = x, y, z
            out_t[m] = t
            m += 1
    return out[:m], out_t[:m], valid, free


@numba.njit(**_JIT)
def leftover_best(sample: np.ndarray, t: np.ndarray, first: np.ndarray, picks: np.ndarray,
                  neighbours: int) -> tuple[np.ndarray, float, int]:
    """The plane through each point ``first`` (h,) of ``sample`` (m, 3) meters and two of its ``neighbours`` + 1
    nearest (itself among them; ties by row), those at ``picks`` (h, 2) in their order by distance, that most points
    of ``sample`` lie within ``t`` (m,) of: (unit normal (3,), offset m, its count); (NaN, NaN, 0) when every
    triple is degenerate."""
    m = sample.shape[0]
    size = min(neighbours + 1, m)
    near, dist = np.empty(size, np.int64), np.empty(size)
    best_normal, best_offset, best = np.full(3, np.nan), np.nan, 0
    for q in range(first.shape[0]):
        s = first[q]
        filled = 0
        for j in range(m):
            dx, dy, dz = sample[j, 0] - sample[s, 0], sample[j, 1] - sample[s, 1], sample[j, 2] - sample[s, 2]
            d2 = dx * dx + dy * dy + dz * dz
            if filled == size and not d2 < dist[size - 1]:
                continue
            pos = filled if filled < size else size - 1
            while pos > 0 and d2 < dist[pos - 1]:  # after equal distances: the earlier row stays first
                near[pos], dist[pos] = near[pos - 1], dist[pos - 1]
                pos -= 1
            near[pos], dist[pos] = j, d2
            filled = min(filled + 1, size)
        a, b = near[picks[q, 0]], near[picks[q, 1]]
        ax, ay, az = sample[a, 0] - sample[s, 0], sample[a, 1] - sample[s, 1], sample[a, 2] - sample[s, 2]
        bx, by, bz = sample[b, 0] - sample[s, 0], sample[b, 1] - sample[s, 1], sample[b, 2] - sample[s, 2]
        nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
        length = np.sqrt(nx * nx + ny * ny + nz * nz)
        if not length > 0.0:
            continue
        nx, ny, nz = nx / length, ny / length, nz / length
        offset = -(nx * sample[s, 0] + ny * sample[s, 1] + nz * sample[s, 2])
        count = 0
        for j in range(m):
            if abs(nx * sample[j, 0] + ny * sample[j, 1] + nz * sample[j, 2] + offset) <= t[j]:
                count += 1
        if count > best:
            best_normal[0], best_normal[1], best_normal[2] = nx, ny, nz
            best_offset, best = offset, count
    return best_normal, best_offset, best


@dataclass(frozen=True)
class Warmup:
    """How long :func:`warm` took, seconds, and whether any kernel had to be compiled (a cold cache)."""

    seconds: float
    compiled: bool


def _warm_frame() -> None:
    pts = np.zeros((4, 3))
    labels = np.array([0, -1, 0, 1], np.int32)
    flags = np.ones(4, np.bool_)
    finite_mask(pts)
    rows, bounds = group_by_label(labels, 2)
    group_by_label(labels.astype(np.int64), 2)  # a search's regions
    centroids_and_extremes(pts, rows, bounds, np.zeros((2, 8, 3)))
    coordinate_bounds(pts)
    widen_xyz(np.zeros((4, 5), np.float32), np.arange(3))
    valid_rows(pts)
    read_rows(np.zeros((4, 5), np.float32), np.arange(3), np.zeros(3), 1e-6, True)
    outside_polygon(np.zeros((2, 4)), np.zeros((8, 2)), 1e-9)
    frame_pass(pts, labels, flags, np.zeros(3, np.int32), np.zeros(3, np.uint32), np.zeros((2, 8, 3)),
               np.empty(80, np.uint8), np.empty(48, np.uint8), False)


def _warm_regions() -> None:
    pts, flags, index = np.zeros((4, 3)), np.ones(4, np.bool_), np.arange(4, dtype=np.int64)
    grid_components(index, index, flags, 2, np.zeros((1, 3), np.int64), flags)
    grid_region(index, index, flags, 2, np.zeros((1, 3), np.int64), pts, np.ones(3), 0.5, index, index, flags, flags,
                flags, np.ones(3))
    graph_components(4, np.zeros((1, 2), np.int64), flags)
    graph_region(np.zeros(1, np.int64), np.zeros(5, np.int64), pts, np.ones(3), 0.5, flags, flags, flags, np.ones(3))
    pair_graph(4, np.zeros((1, 2), np.int64), np.zeros((4, 2)), np.zeros((4, 2), np.int64), np.ones(4), 1)


def _warm_voxel_knn() -> None:
    pts, dims = np.zeros((4, 3)), np.ones(3, np.int64)
    grid = voxel_grid(pts, np.zeros(3), 1.0, dims)
    voxel_knn(pts, *grid, np.zeros(3), 1.0, dims, pts, 2, 1)
    voxel_knn_points(pts, *grid, np.zeros(3), 1.0, dims, 2, 1)
    brute_knn(pts, pts, 2)
    principal_axes(pts, np.zeros((4, 3), np.int64))


def _warm_voxel_nearest() -> None:
    pts, dims, index = np.zeros((4, 3)), np.ones(3, np.int64), np.arange(4, dtype=np.int64)
    grid = voxel_grid(pts, np.zeros(3), 1.0, dims)
    voxel_nearest(pts, *grid, np.zeros(3), 1.0, dims, pts, 1)
    spread_nearest(pts, index, np.zeros(3), index, index, np.zeros((1, 4)), np.ones(1))
    spread_among(np.zeros(4), np.zeros((4, 2), np.int64))
    sensor_rays(pts, np.zeros(3))


def _warm_patches() -> None:
    pts, index = np.zeros((4, 3)), np.arange(4, dtype=np.int64)
    patch_fits(pts, index, np.array([0, 4]))
    plane_patches(pts, np.eye(3)[:, :2].copy(), 2, 1)
    fold_line(np.arange(6.0), np.ones(6), np.ones(6), 2, 2, 0.5)
    patch_eigenvalues(np.zeros((1, 3, 3)))


def _warm_grid_search() -> None:
    pts, flags = np.zeros((4, 3)), np.ones(4, np.bool_)
    grid_sample(pts, flags, 2, 1, np.zeros((1, 2), np.int64))
    image, valid = np.zeros((2, 2, 3)), np.ones((2, 2), np.bool_)
    ranges, right, right_reach, down, down_reach, _ = grid_edges(image, valid)
    grid_usable(valid, ranges, right, right_reach, down, down_reach, 1.0, 4.0)
    grid_normals(image, valid, 1, 1, 0.0)
    grid_chords(image, valid, ranges, True, 1)


def _warm_planes() -> None:
    pts, flags, index = np.zeros((4, 3)), np.ones(4, np.bool_), np.arange(4, dtype=np.int64)
    cols, plane, edges = np.zeros((3, 4)), np.zeros(4), np.zeros(1, np.int64)
    merge_test(cols, index, index, 0, 1, plane, np.zeros((2, 4)), np.ones(1), edges, edges, edges, edges, index, pts,
               0.5, 0.95, 1.5, NO_RAY)
    compete_distances(cols, np.zeros((1, 4)), np.ones(1), np.zeros(3), 0.25)
    band_counts(plane_bands(cols, np.ones((2, 3)), np.zeros(2))[0], np.ones(1), 2.0)
    triple_planes(cols, np.zeros((2, 3), np.int64), 1e-6)
    coherent_inliers(flags, np.ones(3), cols, 0.5)
    largest_magnitude(pts.reshape(-1))


def _warm_indices() -> None:
    pts = np.zeros((4, 3))
    codes = np.array([0, -1, 0, 1], np.int64)
    group_by_label(codes, 2)
    compact = np.empty(4, np.int32)
    for ints in (codes, codes.astype(np.int32)):  # the label types the package passes
        for finite in (False, True):
            n, m, low, count = label_census(pts, ints, compact, finite)
    rows_at_ranks(compact, low, np.arange(len(count)) - 1, np.zeros(2, np.int64), np.array([0, 1, 2]))
    sizes = np.array([2, 2], np.int64)
    cluster_distance_pass(pts, np.array([0, 2], np.int64), sizes)
    silhouettes(np.ones((4, 2)), codes[[0, 0, 2, 2]] // 2, sizes, True)


def _warm_silhouette() -> None:
    pts, index = np.zeros((4, 3)), np.arange(4, dtype=np.int64)
    codes = np.array([0, -1, 0, 1], np.int64)
    centroids, scatter = region_scatter(pts, np.zeros(3), index, np.array([0, 2, 4]))
    region_extents(pts, np.zeros(3), index, np.array([0, 2, 4]), centroids, scatter, 0.005, 0.995)
    plane_silhouette_sum(pts, codes[[0, 2, 3, 3]], centroids, scatter, np.zeros((2, 2)), np.zeros((2, 2)), np.ones(2))
    polygon_distances(np.zeros((1, 2)), np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))


# -- numpy's default_rng(m).integers(0, m, count), compiled (SeedSequence, PCG64, Lemire's bounded draws) --------
# A fixed subset of m rows seeded by m, drawn as numpy draws it, without building a Generator (about 90 us a call)

_MASK32 = np.uint64(0xFFFFFFFF)
_U32 = np.uint64(32)
_U16 = np.uint64(16)
_SEED_INIT_A, _SEED_MULT_A = np.uint64(0x43b0d7e5), np.uint64(0x931e8875)
_SEED_INIT_B, _SEED_MULT_B = np.uint64(0x8b51f9dd), np.uint64(0x58f38ded)
_MIX_L, _MIX_R = np.uint64(0xca01f9dd), np.uint64(0x4973f715)
_PCG_MULT_HIGH, _PCG_MULT_LOW = np.uint64(2549297995355413924), np.uint64(4865540595714422341)


@numba.njit(**_JIT)
def _hashmix(value: np.uint64, const: np.ndarray) -> np.uint64:
    """SeedSequence's hashmix of a 32-bit ``value`` (in a uint64); ``const`` (1,) uint64 its running constant."""
    value = (value ^ const[0]) & _MASK32
    const[0] = (const[0] * _SEED_MULT_A) & _MASK32
    value = (value * const[0]) & _MASK32
    return value ^ (value >> _U16)


@numba.njit(**_JIT)
def _mix(x: np.uint64, y: np.uint64) -> np.uint64:
    result = ((_MIX_L * x) - (_MIX_R * y)) & _MASK32
    return result ^ (result >> _U16)


@numba.njit(**_JIT)
def _mul_high(a: np.uint64, b: np.uint64) -> np.uint64:
    """The high 64 bits of the 128-bit product a * b."""
    a_lo, a_hi, b_lo, b_hi = a & _MASK32, a >> _U32, b & _MASK32, b >> _U32
    cross = (a_lo * b_lo >> _U32) + (a_hi * b_lo & _MASK32) + (a_lo * b_hi)
    return a_hi * b_hi + (a_hi * b_lo >> _U32) + (cross >> _U32)


@numba.njit(**_JIT)
def _pcg_step(state: np.ndarray) -> None:
    """PCG64's step of ``state`` (4,) uint64 (high, low, inc high, inc low): state * multiplier + inc, mod 2^128."""
    high, low = state[0], state[1]
    product_low = low * _PCG_MULT_LOW
    product_high = _mul_high(low, _PCG_MULT_LOW) + low * _PCG_MULT_HIGH + high * _PCG_MULT_LOW
    new_low = product_low + state[3]
    state[0] = product_high + state[2] + (np.uint64(1) if new_low < product_low else np.uint64(0))
    state[1] = new_low


@numba.njit(**_JIT)
def _pcg_next64(state: np.ndarray) -> np.uint64:
    """PCG64's next output (XSL RR of the stepped state)."""
    _pcg_step(state)
    turn = state[0] >> np.uint64(58)
    value = state[0] ^ state[1]
    return (value >> turn) | (value << ((np.uint64(64) - turn) & np.uint64(63)))


@numba.njit(**_JIT)
def seeded_draws(m: int, count: int) -> np.ndarray:
    """(count,) int64 equal to ``np.random.default_rng(m).integers(0, m, count)`` for 1 <= m < 2^63: numpy's
    SeedSequence(m), PCG64 seeded from it and Lemire's bounded draws (32-bit ones, low half of an output first,
    while m <= 2^32), in one compiled call."""
    entropy = np.empty(2, np.uint64)
    entropy[0], entropy[1] = np.uint64(m) & _MASK32, np.uint64(m) >> _U32
    words = 1 if entropy[1] == 0 else 2
    const = np.full(1, _SEED_INIT_A, np.uint64)
    pool = np.empty(4, np.uint64)
    for i in range(4):
        pool[i] = _hashmix(entropy[i] if i < words else np.uint64(0), const)
    for source in range(4):
        for target in range(4):
            if source != target:
                pool[target] = _mix(pool[target], _hashmix(pool[source], const))
    seed = np.empty(8, np.uint64)  # generate_state(4, uint64): 8 words, paired low word first
    hash_b = _SEED_INIT_B
    for i in range(8):
        value = (pool[i % 4] ^ hash_b) & _MASK32
        hash_b = (hash_b * _SEED_MULT_B) & _MASK32
        value = (value * hash_b) & _MASK32
        seed[i] = value ^ (value >> _U16)
    state = np.zeros(4, np.uint64)  # srandom(initstate, initseq): inc = initseq << 1 | 1, step, += initstate, step
    state[2] = ((seed[5] << _U32 | seed[4]) << np.uint64(1)) | ((seed[7] << _U32 | seed[6]) >> np.uint64(63))
    state[3] = ((seed[7] << _U32 | seed[6]) << np.uint64(1)) | np.uint64(1)
    _pcg_step(state)
    init_high, init_low = seed[1] << _U32 | seed[0], seed[3] << _U32 | seed[2]
    low = state[1] + init_low
    state[0] = state[0] + init_high + (np.uint64(1) if low < init_low else np.uint64(0))
    state[1] = low
    _pcg_step(state)
    out = np.zeros(count, np.int64)
    span = np.uint64(m)  # rng + 1 of numpy's bounded draws
    if m == 1:
        return out
    if m <= 0xFFFFFFFF + 1:
        threshold = ((_MASK32 - (span - np.uint64(1))) & _MASK32) % span
        spare, has_spare = np.uint64(0), False
        for i in range(count):
            while True:
                if has_spare:
                    word, has_spare = spare, False
                else:
                    full = _pcg_next64(state)
                    word, spare, has_spare = full & _MASK32, full >> _U32, True
                product = word * span
                if (product & _MASK32) >= threshold:
                    break
            out[i] = np.int64(product >> _U32)
        return out
    threshold = (np.uint64(0) - span) % span  # (2^64 - 1 - rng) % span
    for i in range(count):
        while True:
            word = _pcg_next64(state)
            if word * span >= threshold:
                break
        out[i] = np.int64(_mul_high(word, span))
    return out


# -- the verdict's second look at PS (plane_silhouette.hull_silhouette) --------------------------------------------

@numba.njit(**_JIT)
def polygon_distances(p: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """(m,) distance (meters) of points ``p`` (m, 2) to the convex ``polygon`` (e, 2), its corners counter-clockwise:
    0 inside (:func:`.plane_silhouette.polygon_distances_numpy` is its reference)."""
    m, e = p.shape[0], polygon.shape[0]
    tiny = np.finfo(np.float64).tiny
    out = np.empty(m)
    for i in range(m):
        inside = True
        nearest = np.inf  # squared: the square root is monotone, so one at the end gives the same minimum
        for j in range(e):
            k = j + 1 if j + 1 < e else 0
            ex, ey = polygon[k, 0] - polygon[j, 0], polygon[k, 1] - polygon[j, 1]
            rx, ry = p[i, 0] - polygon[j, 0], p[i, 1] - polygon[j, 1]
            if ex * ry - ey * rx < 0.0:
                inside = False
            f = min(max((rx * ex + ry * ey) / max(ex * ex + ey * ey, tiny), 0.0), 1.0)
            gx, gy = rx - f * ex, ry - f * ey
            nearest = min(nearest, gx * gx + gy * gy)
        out[i] = 0.0 if inside else np.sqrt(nearest)
    return out


# -- a spinning lidar's ring image (geometry.ring_image) -------------------------------------------------------------

@numba.njit(**_JIT)
def ring_steps(row: np.ndarray, azimuth: np.ndarray, elevation: np.ndarray, rings: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per ring ``row`` (n,) 0..rings-1 of the points' ``azimuth`` and ``elevation`` (n,) radians: the positive steps
    between azimuths neighbouring in the ring (g,), ring by ring; each ring's median elevation and median absolute
    deviation from it (rings,) (:func:`.geometry.ring_steps_numpy` is its reference)."""
    n = row.shape[0]
    bounds = np.zeros(rings + 1, np.int64)
    for i in range(n):
        bounds[row[i] + 1] += 1
    for r in range(rings):
        bounds[r + 1] += bounds[r]
    fill = bounds[:-1].copy()
    az = np.empty(n)
    el = np.empty(n)
    for i in range(n):
        at = fill[row[i]]
        az[at] = azimuth[i]
        el[at] = elevation[i]
        fill[row[i]] = at + 1
    gaps = np.empty(n)
    count = 0
    middle = np.empty(rings)
    spread = np.empty(rings)
    for r in range(rings):
        a, b = bounds[r], bounds[r + 1]
        ordered = np.sort(az[a:b])
        for k in range(1, b - a):
            gap = ordered[k] - ordered[k - 1]
            if gap > 0:
                gaps[count] = gap
                count += 1
        middle[r] = np.median(el[a:b])
        spread[r] = np.median(np.abs(el[a:b] - middle[r]))
    return gaps[:count], middle, spread


@numba.njit(**_JIT)
def ring_turns(azimuth: np.ndarray, row: np.ndarray, rings: int, turn: float, per_step: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Per ring ``row`` (n,) 0..rings-1 the sums of cos and sin (rings,) of ``turn * azimuth * per_step`` (``azimuth``
    (n,) radians; ``per_step`` 1 / the azimuth step): each ring's phase (:func:`.geometry.ring_turns_numpy` is its
    reference)."""
    cos_sum = np.zeros(rings)
    sin_sum = np.zeros(rings)
    for i in range(row.shape[0]):
        angle = (turn * azimuth[i]) * per_step
        cos_sum[row[i]] += np.cos(angle)
        sin_sum[row[i]] += np.sin(angle)
    return cos_sum, sin_sum


@numba.njit(**_JIT)
def ring_scatter(points: np.ndarray, pixel: np.ndarray, size: int) -> tuple[np.ndarray, int]:
    """The image (size, 3) of ``points`` (n, 3) on their ``pixel`` (n,) 0..size-1, NaN where none, the first point
    standing for a pixel several fall on; and how many pixels hold a point (:func:`.geometry.ring_scatter_numpy` is
    its reference)."""
    image = np.full((size, 3), np.nan)
    taken = np.zeros(size, np.bool_)
    count = 0
    for i in range(pixel.shape[0]):
        p = pixel[i]
        if not taken[p]:
            taken[p] = True
            count += 1
            image[p, 0], image[p, 1], image[p, 2] = points[i, 0], points[i, 1], points[i, 2]
    return image, count


def _warm_rings() -> None:
    row, values = np.array([0, 1, 0, 1], np.int64), np.zeros(4)
    ring_steps(row, values, values, 2)
    ring_turns(values, row, 2, 1.0, 1.0)
    ring_scatter(np.zeros((4, 3)), row, 2)


def _warm_outside() -> None:
    pts, index = np.zeros((4, 3)), np.arange(4, dtype=np.int64)
    labels = np.array([0, -1, 0, 1], np.int32)
    marked_rows(pts, np.zeros(3), 1e-6)
    near_count(pts, pts, 0.3)
    beyond_counts(np.zeros((4, 4)), np.zeros((4, 2)), labels, np.ones(1), np.zeros(4), np.zeros(4),
                  np.zeros((2, 2), np.bool_))
    distinct_rows(pts, index)
    coordinate_extent(pts, index)


def _warm_fits() -> None:
    flags, index = np.ones(4, np.bool_), np.arange(4, dtype=np.int64)
    cols, codes = np.zeros((3, 4)), np.array([0, -1, 0, 1], np.int64)
    best = np.zeros((2, 3)), np.zeros(2), np.zeros(2, np.int64)
    score_hypotheses(cols, np.ones(1), np.empty((3, 0)), np.ones((2, 3)), np.zeros(2), 2, 0.5, 3.0, *best, 0, NO_RAY)
    spread_test(cols, index, True, 1e-6)
    fit_members(cols, index)
    fit_mask(cols, flags)
    fit_regions(cols, codes, 2)


def _warm_judge() -> None:
    pts, index = np.zeros((4, 3)), np.arange(4, dtype=np.int64)
    plane_samples(pts, index, np.array([0, 4]))
    sorted_order(np.zeros(4))
    order_statistics(np.zeros(4), 0, 1, 2, 3)


def _warm_unorganized() -> None:
    pts, dims = np.zeros((4, 3)), np.ones(3, np.int64)
    order, cell_keys, starts, table = voxel_grid(pts, np.zeros(3), 1.0, dims)
    flags, index = np.zeros(4, np.bool_), np.arange(4, dtype=np.int64)
    node, voxel, d2, near = voxel_nodes(pts, order, cell_keys, starts, table, np.zeros(3), 1.0, dims, pts, index,
                                        np.zeros(3))
    uncertain_nodes(index, node, d2, voxel, near, flags, pts, index, np.zeros(3), pts, order, cell_keys, starts,
                    table, np.zeros(3), 1.0, dims)
    first_across(index, index.reshape(2, 2), pts, pts, np.zeros(4), flags, 1, 0.5, 0.01)


def _warm_detect() -> None:
    pts, flags, index = np.zeros((4, 3)), np.ones(4, np.bool_), np.arange(4, dtype=np.int64)
    labels = np.array([0, -1, 0, 1], np.int32)
    finite_extent(pts)
    grid_contacts(index, flags, 2, True, np.zeros((1, 3), np.int64), index, 4)
    label_rows(labels, 2, np.zeros(4))
    grid_triples(index[:2], index[:4] % 2, np.zeros(4), np.zeros(4), np.ones(2, np.int64), index, index, index, index,
                 2, 2)


def _warm_organized_detect() -> None:
    flags, index, cols = np.ones(4, np.bool_), np.arange(4, dtype=np.int64), np.zeros((3, 4))
    bridges = np.zeros((1, 3), np.int64)
    plane = grid_plane(cols, np.ones(1), np.ones((2, 3)), np.zeros(2), 2.0, 0.5, cols, index, flags, 2, bridges, 0.5,
                       np.ones(3), 3, NO_RAY, NO_RAY)
    grid_refit(cols, plane[3], np.ones(1), 2.0, cols, index, flags, 2, bridges, 0.5, np.ones(3), NO_RAY)
    grid_settle(cols, np.zeros((1, 4)), np.ones(1), np.zeros(3), 0.25, np.zeros(4, np.int64), index, index, 2, EIGHT,
                2, NO_RAY)
    edges = np.zeros(1, np.int64)
    for known in (np.zeros((4, 3)), np.empty((0, 3))):  # the grid's normals, and none known
        merge_pair(cols, index, 0, 1, np.zeros((2, 4)), np.ones(1), edges, edges, edges, edges, index, known, 0.5, 0.95,
                   1.5, True, NO_RAY)


def _warm_frame_ids() -> None:
    relabel_rows(np.array([0, -1, 0, 1], np.int32), np.ones(4, np.bool_), np.array([1, 0, -1], np.int32))
    labels_where(np.array([0, -1, 0, 1], np.int32), np.ones(4, np.bool_))


def _warm_beyond_rows() -> None:
    beyond_rows(np.zeros((4, 3)), 2, np.array([0, -1, 0, 1], np.int32))


def _warm_tent() -> None:
    tent_fit(np.zeros(4), np.zeros(4), np.zeros(4), 2)


def _warm_leftover() -> None:
    leftover_rows(np.zeros((4, 3)), np.array([0, -1, 0, 1], np.int32), 1, np.zeros((1, 4)), 1.0, True, 1.0, np.zeros(3),
                  100.0, 2.0, np.zeros((3, 2)), np.zeros(2), np.zeros(2))
    leftover_best(np.zeros((4, 3)), np.ones(4), np.zeros(1, np.int64), np.ones((1, 2), np.int64), 2)
    seeded_draws(5, 2)


def _warm_organized_batch() -> None:
    pts, flags, index = np.zeros((4, 3)), np.ones(4, np.bool_), np.arange(4, dtype=np.int64)
    lines = np.zeros(2, np.int64)
    grid_spread(pts, flags, index[:1], index[:1], 1, 1, lines, lines, np.zeros((1, 4)), np.ones(1), EIGHT, NO_RAY)
    strided_rows(flags, 4, 2)
    columns_at(pts, index, np.zeros(3))
    cols, best = np.zeros((3, 4)), (np.zeros((2, 3)), np.zeros(2), np.zeros(2, np.int64))
    grid_batch(cols, index.reshape(-1, 2)[:, :1].repeat(3, axis=1), index[:2], index % 2, np.zeros(4), np.zeros(4),
               np.ones(2, np.int64), index, index, index, index, 2, 2, 1e-6, cols, np.ones(1), cols, 2, 0.5, 3.0, *best,
               0, NO_RAY)


def _warm_plain_graph() -> None:
    edges, index = np.zeros((1, 2), np.int64), np.arange(4, dtype=np.int64)
    kept_edges(edges, index, 4)
    graph_contacts(edges, index, 2)
    voxel_count(np.zeros((4, 3)), np.zeros(3), 1.0, np.ones(3, np.int64))
    rows_less(np.zeros((4, 3)), index, np.zeros(3))
    graph_settle(np.zeros((3, 4)), np.zeros(4, np.int64), np.zeros(5, np.int64), np.zeros(0, np.int64), 6)
    graph_triples(index[:2], index % 2, np.zeros((1, 4)), np.ones(2, np.int64), index, index, index, index, index)
    cols = np.zeros((3, 4))
    graph_batch(cols, index.reshape(-1, 2)[:, :1].repeat(3, axis=1), index[:2], index % 2, np.zeros((1, 4)),
                np.ones(2, np.int64), index, index, index, index, index, 1e-6, cols, np.ones(1), cols, 2, 0.5, 3.0,
                np.zeros((2, 3)), np.zeros(2), np.zeros(2, np.int64), 0, NO_RAY)
    graph_plane(cols, np.ones(1), np.ones((2, 3)), np.zeros(2), 2.0, 0.5, cols, edges[:, 1].copy(),
                np.zeros(5, np.int64), 0.5, np.ones(3), 3)


#: What :func:`warm` runs: each step calls some kernels with the argument types the package calls them with. The
#: first is short: it tells whether the cache is cold. The longest compiles come next, so that processes compiling
#: the rest in parallel end together.
_WARM_STEPS = (_warm_outside, _warm_fits, _warm_regions, _warm_voxel_nearest, _warm_voxel_knn, _warm_patches,
               _warm_frame, _warm_silhouette, _warm_grid_search, _warm_indices, _warm_planes,
               _warm_judge, _warm_detect, _warm_unorganized, _warm_organized_detect, _warm_frame_ids,
               _warm_beyond_rows, _warm_organized_batch, _warm_plain_graph, _warm_tent, _warm_leftover,
               _warm_rings)


def _compiles() -> int:
    return sum(len(kernel.stats.cache_misses) for kernel in _KERNELS)


def _run(step) -> bool:
    """Run a warm-up step (in this or a worker process); whether it compiled anything."""
    before = _compiles()
    step()
    return _compiles() > before


def _hold_signals() -> None:
    """A warm-up worker leaves Ctrl-C, SIGTERM and SIGHUP to the process that started it, which stops at once and
    kills its workers (:func:`.interrupts.stop_at_signals`)."""
    import signal
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_IGN)


def _warm(steps: tuple, jobs: int, cold: bool = False) -> bool:
    """Run ``steps``, the first alone and, when it compiled or ``cold`` (a cold cache), the others first in ``jobs``
    processes; whether anything was compiled."""
    compiled = _run(steps[0]) or cold
    if compiled and jobs > 1 and len(steps) > 2:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor
        # spawn: a fork of a process that has started threads (rclpy, BLAS) may hang
        with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context('spawn'),
                                 initializer=_hold_signals) as pool:
            list(pool.map(_run, steps[1:]))
    for step in steps[1:]:  # here they load what the workers compiled
        compiled |= _run(step)
    return compiled


def warm_probe() -> Warmup:
    """Run :func:`warm`'s first, short step alone: how long it took and whether it compiled (a cold cache; else the
    other kernels load from the cache in about 0.5 s). The node starts with it: a cold cache is compiled whole before
    the node appears on the graph, a warm one loads while its subscription is being discovered."""
    start = time.perf_counter()
    compiled = _run(_WARM_STEPS[0])
    return Warmup(time.perf_counter() - start, compiled)


def warm(jobs: int = 1, *, cold: bool = False) -> Warmup:
    """Compile (or load from the cache) every kernel for the argument types the package calls it with.

    jobs: processes to compile in when the cache is cold (the first step compiled something, or ``cold``: the
    caller's :func:`warm_probe` did); a warm cache loads in this process alone. A cold compile takes about
    1 / jobs of its time on as many cores."""
    start = time.perf_counter()
    compiled = _warm(_WARM_STEPS, jobs, cold)
    return Warmup(time.perf_counter() - start, compiled)


#: Every kernel named in __all__ (what warm() and its probe count the compiles of).
_KERNELS = tuple(globals()[name] for name in __all__ if isinstance(globals()[name], numba.core.dispatcher.Dispatcher))
