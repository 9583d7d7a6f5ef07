"""The unorganized neighbourhood's compiled kernels (core/kernels.py, the graph block) against their plain-numpy
references, on random inputs."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from plane_validation.core import kernels
from plane_validation.core.regions import VOXEL_RINGS, voxel_index
from plane_validation.core.search.neighbours import row_starts

SETTINGS = settings(max_examples=60, deadline=None)


def _cloud(rng: np.random.Generator, most: int = 500) -> np.ndarray:
    """Random (n, 3) points, n < ``most``: a noisy plane, a line, grid-quantized ties, exact copies and sometimes a
    far outlier."""
    n = int(rng.integers(1, most))
    kind = rng.integers(0, 4, n)
    pts = rng.uniform(-1, 1, (n, 3))
    pts[kind == 0, 2] = rng.normal(scale=0.01, size=int(np.sum(kind == 0)))
    pts[kind == 1, 1:] = 0.0
    pts[kind == 2] = np.round(pts[kind == 2] * 20) / 20  # equal distances
    if n > 3 and rng.random() < 0.3:
        pts[rng.integers(0, n, 3)] = pts[0]
    if n > 2 and rng.random() < 0.3:
        pts[-1] = rng.uniform(-50, 50, 3)  # beyond the rings searched: not exact
    return pts * rng.uniform(0.01, 100)


def _knn_numpy(ordered: np.ndarray, order: np.ndarray, queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest of the hashed points ``ordered`` (m, 3) (voxel by voxel; ``order`` their rows) to each query,
    by brute force: ascending squared distance, equal ones by position in the voxel order (as the kernels rank them);
    (distances (q, k), rows (q, k), -1 and inf past the m points)."""
    e = ordered[None, :, :] - queries[:, None, :]
    d2 = e[..., 0] * e[..., 0] + e[..., 1] * e[..., 1] + e[..., 2] * e[..., 2]
    position = np.broadcast_to(np.arange(len(ordered)), d2.shape)
    rank = np.lexsort((position, d2), axis=-1)[:, :k]
    dist = np.full((len(queries), k), np.inf)
    idx = np.full((len(queries), k), -1, np.int64)
    held = min(k, len(ordered))
    dist[:, :held] = np.sqrt(np.take_along_axis(d2, rank, axis=1))[:, :held]
    idx[:, :held] = order[rank[:, :held]]
    return dist, idx


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_voxel_nearest_matches_brute_force_and_voxel_knn(seed, others):
    """Each query certain within the rings gets exactly the brute-force nearest (ties by voxel order), and every
    answer, certain or not, is voxel_knn's (the query-by-query search it replaces)."""
    rng = np.random.default_rng(seed)
    pts = _cloud(rng)
    queries = pts
    if others:  # queries other than the points, across the cloud's span (some in empty voxels)
        queries = pts[rng.integers(0, len(pts), int(rng.integers(1, 300)))] + rng.normal(scale=0.05, size=(1, 3)) * \
            np.ptp(pts, axis=0).max(initial=1.0)
    index = voxel_index(pts, span=queries)
    if index is None:
        return
    args = (index.ordered, *index.grid, index.origin, index.cell, index.dims, np.ascontiguousarray(queries))
    dist, idx, exact = kernels.voxel_nearest(*args, VOXEL_RINGS)
    ref = kernels.voxel_knn(*args, 1, VOXEL_RINGS)
    np.testing.assert_array_equal(exact, ref[2])
    np.testing.assert_array_equal(dist[exact], ref[0][exact])
    np.testing.assert_array_equal(idx[exact], ref[1][exact])
    ref_dist, ref_idx = _knn_numpy(index.ordered, index.grid[0], queries, 1)
    np.testing.assert_array_equal(dist[exact], ref_dist[exact])
    np.testing.assert_array_equal(idx[exact], ref_idx[exact])
    assert exact.any() or others


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(2, 16))
def test_voxel_knn_points_matches_brute_force_and_voxel_knn(seed, k):
    """The hashed points' own k nearest, taken voxel by voxel: certain exactly where voxel_knn's query-by-query search
    is, then exactly its answer and the brute-force one (ties by voxel order); many k nearest lie beyond the 27 voxels
    around (k up to 16, about 4 points a voxel), some beyond the rings searched (a far outlier)."""
    pts = _cloud(np.random.default_rng(seed))
    index = voxel_index(pts)
    if index is None:
        return
    grid = (index.ordered, *index.grid, index.origin, index.cell, index.dims)
    dist, idx, exact = kernels.voxel_knn_points(*grid, k, VOXEL_RINGS)
    ref = kernels.voxel_knn(*grid, index.points, k, VOXEL_RINGS)
    np.testing.assert_array_equal(exact, ref[2])
    np.testing.assert_array_equal(dist[exact], ref[0][exact])
    np.testing.assert_array_equal(idx[exact], ref[1][exact])
    ref_dist, ref_idx = _knn_numpy(index.ordered, index.grid[0], index.points, k)
    np.testing.assert_array_equal(dist[exact], ref_dist[exact])
    np.testing.assert_array_equal(idx[exact], ref_idx[exact])
    assert exact.any() or len(pts) <= 2 * k  # at most one far outlier
    # VoxelIndex.query takes this path for the points themselves only: a copy of them goes query by query
    for got, want in zip(index.query(index.points, k), index.query(index.points.copy(), k)):
        np.testing.assert_array_equal(got, want)


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_voxel_nearest_in_empty_voxels_matches_brute_force(seed):
    """Queries in voxels holding no point (a plane's points, the queries off it and in its holes) are answered voxel by
    voxel as well: each certain one gets the brute-force nearest (ties by voxel order), and most are certain."""
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(0, 1, (400, 2)), np.zeros(400)])
    pts[:, :2] = np.round(pts[:, :2] * rng.choice([10, 20, 1000])) / 20  # sometimes equal distances
    index = voxel_index(pts, span=(np.array([0.0, 0.0, -1.0]), np.array([1.0, 1.0, 1.0])))
    queries = np.column_stack([rng.uniform(0, 1, (300, 2)), rng.uniform(-2, 2, 300) * index.cell])  # to 2 voxels off
    args = (index.ordered, *index.grid, index.origin, index.cell, index.dims, queries)
    voxel = ((queries - index.origin) // index.cell).astype(np.int64)
    keys = voxel[:, 0] + index.dims[0] * (voxel[:, 1] + index.dims[1] * voxel[:, 2])
    in_empty = ~np.isin(keys, index.grid[1])
    dist, idx, exact = kernels.voxel_nearest(*args, VOXEL_RINGS)
    ref_dist, ref_idx = _knn_numpy(index.ordered, index.grid[0], queries, 1)
    np.testing.assert_array_equal(dist[exact], ref_dist[exact])
    np.testing.assert_array_equal(idx[exact], ref_idx[exact])
    np.testing.assert_array_equal(exact, kernels.voxel_knn(*args, 1, VOXEL_RINGS)[2])
    assert np.count_nonzero(exact & in_empty) > 0.25 * np.count_nonzero(in_empty) > 0


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_spread_nearest_matches_numpy(seed, per_point):
    """Labels exactly as the numpy reference gives them, and each labelled point's distance to its plane."""
    from plane_validation.core.search.graph import spread_nearest, spread_nearest_numpy
    rng = np.random.default_rng(seed)
    n, m, k = int(rng.integers(1, 300)), int(rng.integers(1, 50)), int(rng.integers(1, 6))
    pts = rng.normal(size=(n, 3))
    pts[rng.random(n) < 0.1] = np.nan
    rows = np.flatnonzero(np.isfinite(pts).all(axis=1))
    center = rng.normal(size=3)
    nearest = rng.integers(0, m, len(rows))
    region = rng.integers(-1, k, m)
    normals = rng.normal(size=(k, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    found = [(normal, float(d)) for normal, d in zip(normals, rng.normal(size=k))]
    tolerance = rng.uniform(0.0, 1.5, len(rows)) if per_point else float(rng.uniform(0.0, 1.5))
    labels, residual = spread_nearest(pts, rows, center, nearest, region, found, tolerance)
    ref = np.full(n, -1, np.int32)
    ref[rows] = spread_nearest_numpy(pts[rows] - center, nearest, region, found, tolerance)
    np.testing.assert_array_equal(labels, ref)
    assert labels.dtype == np.int32
    on = labels >= 0
    own = np.array([np.append(*found[j]) for j in labels[on]]).reshape(-1, 4)
    np.testing.assert_allclose(residual[on], np.abs(np.einsum('ij,ij->i', pts[on] - center, own[:, :3]) + own[:, 3]),
                               rtol=1e-12, atol=1e-15)
    assert np.isinf(residual[~on]).all()


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_pair_graph_joins_the_knn_pairs_as_numpy(seed):
    """The graph of the pairs within reach, or among the ALWAYS_JOINED nearest at a finite distance, joined in the
    compiled pass with other pairs, is that of the numpy pairs joined with them."""
    from plane_validation.core.regions import _knn_edges_numpy, _neighbours, _neighbours_numpy
    rng = np.random.default_rng(seed)
    n, k = int(rng.integers(1, 200)), int(rng.integers(2, 13))
    dist = np.sort(rng.exponential(size=(n, k)), axis=1)
    dist[:, 0] = 0.0
    dist[rng.random((n, k)) < 0.05] = np.inf  # no neighbour found
    dist = np.sort(dist, axis=1)
    idx = rng.integers(0, n, (n, k))
    reach = rng.exponential(size=n)
    reach[::7] = dist[::7, k // 2]  # exactly at a neighbour's distance: joined
    other = rng.integers(0, n, (int(rng.integers(0, 20)), 2))
    graph = _neighbours(n, other, None, (dist, idx, reach))
    ref = _neighbours_numpy(n, np.concatenate([_knn_edges_numpy(dist, idx, reach).reshape(-1, 2), other]), None)
    np.testing.assert_array_equal(graph.edges, ref.edges)
    for part, ref_part in zip(graph.adjacency, ref.adjacency):
        np.testing.assert_array_equal(part, ref_part)
    assert graph.edges.flags.c_contiguous  # as the kernels that take them read them: no copy
    np.testing.assert_array_equal(graph.edge_rows, row_starts(ref.edges[:, 0], n))  # the kernel's, against numpy


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_spread_among_matches_numpy(seed):
    rng = np.random.default_rng(seed)
    m, n, k = int(rng.integers(1, 100)), int(rng.integers(0, 100)), int(rng.integers(1, 12))
    values = np.round(rng.normal(size=m), int(rng.integers(1, 4)))  # rounded: equal values
    idx = rng.integers(0, m, (n, k))
    np.testing.assert_array_equal(kernels.spread_among(values, idx),
                                  values[idx].max(axis=1, initial=-np.inf) - values[idx].min(axis=1, initial=np.inf))
