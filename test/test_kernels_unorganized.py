"""The unorganized clouds' compiled kernels (core/kernels.py, the unorganized clouds block) against plain-numpy
references, on random inputs: each point's search node from its voxel, and the lidar joins across rings."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from test_kernels_graph import _cloud

from plane_validation.core import kernels
from plane_validation.core.regions import voxel_index

SETTINGS = settings(max_examples=60, deadline=None)


def _indexed(rng: np.random.Generator, others: bool) -> tuple:
    """A random cloud (:func:`_cloud`), queries (:func:`_queries`) and the voxel index over both (None: far-out
    coordinates)."""
    pts = _cloud(rng, 400)
    queries = np.ascontiguousarray(_queries(rng, pts, others))
    return pts, queries, voxel_index(pts, span=queries)


def _queries(rng: np.random.Generator, pts: np.ndarray, others: bool) -> np.ndarray:
    """The points themselves, or others across their span (some in empty voxels)."""
    if not others:
        return pts
    return pts[rng.integers(0, len(pts), int(rng.integers(1, 300)))] + rng.normal(scale=0.05, size=(1, 3)) * \
        np.ptp(pts, axis=0).max(initial=1.0)


def _voxels(index, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Voxel coordinates (q, 3) of points ``p`` by the hash's arithmetic, and their keys (-1 outside the grid)."""
    f = (p - index.origin) / index.cell
    inside = ((f >= 0) & (f < index.dims)).all(axis=1)
    c = np.where(inside[:, None], f, 0).astype(np.int64)
    return c, np.where(inside, c[:, 0] + index.dims[0] * (c[:, 1] + index.dims[1] * c[:, 2]), -1)


def _voxel_nodes_numpy(index, queries: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`.kernels.voxel_nodes` by brute force: among the hashed points in the query's voxel, the first in the
    hash's order nearer than one voxel plus the query's gap to its nearest face, else the nearest (equal distances: the
    first in the hash's order); that voxel's number, the squared distance and whether the node is that near."""
    own = _voxels(index, index.ordered)[1]  # the hashed points, voxel by voxel
    cells, keys = _voxels(index, queries)
    e = index.ordered[None, :, :] - queries[:, None, :]
    d2 = e[..., 0] * e[..., 0] + e[..., 1] * e[..., 1] + e[..., 2] * e[..., 2]
    d2 = np.where(own[None, :] == keys[:, None], d2, np.inf)
    f = (queries - index.origin) / index.cell
    reach = index.cell + np.minimum(f - cells, cells + 1 - f).min(axis=1) * index.cell
    within = d2 < (reach * reach)[:, None]
    first = np.where(within.any(axis=1), np.argmax(within, axis=1), np.argmin(d2, axis=1))  # argmin: the first of
    best = d2[np.arange(len(queries)), first]  # equal minima, the first in the hash's order
    found = np.isfinite(best)
    return (np.where(found, index.grid[0][first], -1), np.where(found, np.searchsorted(index.grid[1], keys), -1),
            best, found & (best < reach * reach))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_voxel_nodes_match_numpy(seed, others):
    """The node within each query's own voxel (the first within reach, else the nearest), its voxel, its squared
    distance and the nearness flag, exactly as brute force finds them; -1 (inf) in an empty voxel. The queries are
    rows of a cloud less a center, as the search passes them."""
    rng = np.random.default_rng(seed)
    pts, queries, index = _indexed(rng, others)
    if index is None:
        return
    center = rng.normal(size=3) * rng.choice([0.0, 1.0])
    cloud = np.concatenate([queries, rng.normal(size=(5, 3))]) + center  # rows beyond the queries: not asked
    rows = rng.permutation(len(queries))
    got = kernels.voxel_nodes(index.ordered, *index.grid, index.origin, index.cell, index.dims, cloud, rows, center)
    for a, b in zip(got, _voxel_nodes_numpy(index, cloud[rows] - center)):
        np.testing.assert_array_equal(a, b)
    assert got[0].dtype == got[1].dtype == np.int64
    # some query found its node, unless the cloud is one point: (p + center) - center may then round out of its grid
    assert (got[0] >= 0).any() or others or len(pts) == 1


def _uncertain_numpy(index, region: np.ndarray, queries: np.ndarray, node: np.ndarray, d2: np.ndarray,
                     voxel: np.ndarray, near: np.ndarray, exact: np.ndarray) -> np.ndarray:
    """:func:`.kernels.uncertain_nodes` by brute force: a query not exact is uncertain when a point as near as its node
    may lie beyond the 27 voxels around its own; a near query whose own voxel holds several regions first takes the
    nearest hashed point there as its node, and when a hashed point in one of the 26 voxels around whose points are of
    another region than the node's (or of several) lies nearer than its voxel's nearest (as near: earlier in the hash's
    order), it takes the nearest hashed point (its own voxel's when nearer than any face of it, else the nearest of the
    27 voxels, equal distances: the first in the hash's order) and is exact (``node``, ``d2`` and ``exact``
    updated)."""
    order, keys, starts, _ = index.grid
    dims, cell = index.dims, index.cell
    own = _voxels(index, index.ordered)[1]
    coords = np.stack([own % dims[0], own // dims[0] % dims[1], own // (dims[0] * dims[1])], axis=1)
    labels = region[order]
    voxel_label = np.array([labels[lo] if len(np.unique(labels[lo:hi])) == 1 else -2
                            for lo, hi in zip(starts[:-1], starts[1:])])[np.searchsorted(keys, own)]  # per point
    out = np.zeros(len(voxel), bool)
    for q in np.flatnonzero(~exact):
        key = keys[voxel[q]]
        c = np.array([key % dims[0], key // dims[0] % dims[1], key // (dims[0] * dims[1])])
        f = (queries[q] - index.origin) / cell
        below, above = (f - c) * cell, (c + 1 - f) * cell
        assert near[q] == (d2[q] < (cell + min(below.min(), above.min())) ** 2)
        if not near[q]:
            out[q] = True
            continue
        lo, hi = starts[voxel[q]], starts[voxel[q] + 1]
        e = index.ordered - queries[q]
        e2 = e[:, 0] * e[:, 0] + e[:, 1] * e[:, 1] + e[:, 2] * e[:, 2]
        if len(np.unique(labels[lo:hi])) > 1:  # its voxel's nearest hashed point (the first of equals)
            node[q], d2[q] = order[lo + np.argmin(e2[lo:hi])], e2[lo:hi].min()
        offset = coords - c  # of each hashed point's voxel
        gap = np.where(offset < 0, below, np.where(offset > 0, above, 0.0))
        block = (np.abs(offset) <= 1).all(axis=1)
        b, bj = e2[lo:hi].min(), lo + int(np.argmin(e2[lo:hi]))
        within = block & (offset != 0).any(axis=1) & ((gap ** 2).sum(axis=1) <= b)
        other = within & (voxel_label != region[node[q]])  # of another region, or of several
        nearer = (e2 < b) | ((e2 == b) & (np.arange(len(e2)) < bj))
        if not (other & nearer).any():
            continue
        margin = min(below.min(), above.min())
        if e2[lo:hi].min() <= margin * margin:  # nearer than any face: its own voxel's
            best = lo + int(np.argmin(e2[lo:hi]))
        else:  # the first of the nearest in the 27 voxels
            best = int(np.argmin(np.where(block, e2, np.inf)))
        node[q], d2[q], exact[q] = order[best], e2[best], True
    return out


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans(), st.integers(1, 4))
def test_uncertain_nodes_match_numpy(seed, others, regions):
    rng = np.random.default_rng(seed)
    pts, queries, index = _indexed(rng, others)
    if index is None:
        return
    node, voxel, d2, near = kernels.voxel_nodes(index.ordered, *index.grid, index.origin, index.cell, index.dims,
                                                queries, np.arange(len(queries)), np.zeros(3))
    region = rng.integers(-1, regions, len(pts))
    if rng.random() < 0.5:  # regions in slabs, as planes have them: most voxels of one region
        region = np.minimum((pts[:, 0] > np.median(pts[:, 0])).astype(np.int64), regions - 1)
    exact = (rng.random(len(queries)) < 0.2) | (voxel < 0)  # a query in no voxel has its nearest already
    rows = np.arange(len(queries))
    got_node, got_d2, got_exact = node.copy(), d2.copy(), exact.copy()
    got = kernels.uncertain_nodes(region, got_node, got_d2, voxel, near, got_exact, queries, rows, np.zeros(3),
                                  index.ordered, *index.grid, index.origin, index.cell, index.dims)
    given_exact = exact.copy()
    np.testing.assert_array_equal(got, _uncertain_numpy(index, region, queries, node, d2, voxel, near, exact))
    np.testing.assert_array_equal(got_node, node)  # the reference updated its copies as the kernel did
    np.testing.assert_array_equal(got_d2, d2)
    np.testing.assert_array_equal(got_exact, exact)
    assert not got[got_exact].any() and not got[near].any()
    settled = got_exact & ~given_exact  # those it settled: the voxel hash's nearest (ties by its order)
    if settled.any():
        np.testing.assert_array_equal(got_node[settled], index.query(queries[settled], 1)[1][:, 0])


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 4))
def test_each_point_takes_the_region_of_its_nearest_searched_point(seed, regions):
    """Whatever node a point keeps, its region is that of the searched point nearest to it (the voxel hash's exact
    answer, ties by its order), for any regions, again after other regions (a tolerance sweep reusing the graph);
    where the coordinates are too far out for voxels every node is the kd-tree's nearest."""
    from plane_validation.core.search.graph import _nearest_searched, _nearest_searched_tree
    rng = np.random.default_rng(seed)
    pts = _cloud(rng, 400)
    if rng.random() < 0.1:
        pts[0] = 3e38  # a driver's FLT_MAX row: no voxel hash
    pick = rng.random(len(pts)) < 0.3
    searched = pts[pick] if pick.any() else pts[:1]
    nodes, index = _nearest_searched(searched, pts, np.arange(len(pts)), np.zeros(3))
    rows = np.arange(len(pts))
    if index is None:
        ref = _nearest_searched_tree(searched, pts)
        np.testing.assert_allclose(np.linalg.norm(searched[nodes.node] - pts, axis=1),
                                   np.linalg.norm(searched[ref] - pts, axis=1), rtol=1e-12, atol=0)
        return
    nearest = index.query(pts, 1)[1][:, 0]
    for _ in range(2):
        region = rng.integers(-1, regions, len(searched))
        if rng.random() < 0.5:
            region = np.minimum((searched[:, 0] > np.median(searched[:, 0])).astype(np.int64), regions - 1)
        node = nodes.for_regions(region, pts, rows, np.zeros(3))
        np.testing.assert_array_equal(region[node], region[nearest])


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.sampled_from([None, False, True]))
def test_first_across_matches_numpy(seed, off_plane):
    """The first candidate across (on another ring; or off a line or plane, and for a point of one ring on another
    ring too), as the numpy test and argmax give it; none across: the first candidate."""
    from plane_validation.core.regions import _Across
    rng = np.random.default_rng(seed)
    n, m, c = int(rng.integers(1, 200)), int(rng.integers(0, 60)), int(rng.integers(1, 20))
    points = np.round(rng.normal(size=(n, 3)), int(rng.integers(0, 3)))  # rounded: zero offsets, copies
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    direction[rng.random(n) < 0.1] = np.nan  # unknown normals
    elevation = np.round(rng.normal(scale=0.01, size=n), 3)
    rows = rng.integers(0, n, m)
    near = rng.integers(0, n, (m, c))
    itself = rng.random((m, c)) < 0.1  # no neighbour found: the point itself
    near[itself] = np.broadcast_to(rows[:, None], (m, c))[itself]
    test = _Across(elevation) if off_plane is None else \
        _Across(elevation, points, direction, off_plane, rng.random(n) < 0.5)
    found, target = test.first(rows, near)
    across = test.numpy(rows, near)
    first = np.argmax(across, axis=1) if m else np.zeros(0, np.int64)
    np.testing.assert_array_equal(found, across[np.arange(m), first])
    np.testing.assert_array_equal(target, near[np.arange(m), first])
    assert found.dtype == bool and target.dtype == np.int64
