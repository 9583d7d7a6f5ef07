"""The plain graph's compiled kernels (core/kernels.py, the plain graph block, and the principal axes) against
plain-numpy references, on random graphs: a subgraph's edges, the pairs that join two regions, border settling, a
RANSAC run's plane (the best confirmed hypothesis by its region, then its refits) from one call."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from test_kernels_graph import _cloud
from test_kernels_search_loop import _planar_points

from plane_validation.core import kernels
from plane_validation.core.regions import _neighbours, _principal_axes, graph_neighbours
from plane_validation.core.search import hypotheses
from plane_validation.core.search.neighbours import Neighbours, settle_numpy
from plane_validation.core.search.neighbours_graph import GraphNeighbours, _GraphRemaining, graph_region_numpy

SETTINGS = settings(max_examples=60, deadline=None)


def _graph(rng: np.random.Generator, n: int):
    """A random graph of n points (about 3 edges each, some points alone) with random normals."""
    pairs = rng.integers(0, n, (int(rng.integers(0, 3 * n + 1)), 2))
    return _neighbours(n, pairs, rng.normal(size=(n, 3)))


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_subgraph_matches_numpy(seed):
    """The edges among a random subset, renumbered, in the whole graph's order; the normals of the subset."""
    rng = np.random.default_rng(seed)
    graph = _graph(rng, int(rng.integers(1, 120)))
    keep = np.flatnonzero(rng.random(graph.n) < rng.random())
    got, ref = graph.subgraph(keep), graph.subgraph_numpy(keep)
    assert got.n == ref.n == len(keep)
    np.testing.assert_array_equal(got.edges, ref.edges)
    assert got.edges.dtype == np.int64 and got.edges.flags.c_contiguous
    np.testing.assert_array_equal(got.normals, ref.normals)
    assert got.edge_starts is not None and ref.edge_starts is None  # the kernel's row starts, numpy's worked out
    np.testing.assert_array_equal(got.edge_rows, ref.edge_rows)


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_subgraph_of_subgraph_matches_numpy(seed):
    """Removing points twice (as a search takes out one plane after another) keeps the numpy form's edges."""
    rng = np.random.default_rng(seed)
    graph = _graph(rng, int(rng.integers(1, 120)))
    first = np.flatnonzero(rng.random(graph.n) < 0.8)
    local = graph.subgraph(first)
    second = np.flatnonzero(rng.random(local.n) < 0.6)
    got, ref = local.subgraph(second), graph.subgraph_numpy(first).subgraph_numpy(second)
    np.testing.assert_array_equal(got.edges, ref.edges)
    np.testing.assert_array_equal(got.edge_rows, ref.edge_rows)


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_graph_contacts_match_numpy(seed):
    """The edges joining two regions, their regions and the touching region pairs, as the numpy form gives them;
    None when no two regions touch."""
    rng = np.random.default_rng(seed)
    graph = _graph(rng, int(rng.integers(1, 120)))
    k = int(rng.integers(1, 5))
    region = rng.integers(-1, k, graph.n)
    got, ref = graph.contacts(region, k), Neighbours.contacts(graph, region, k)
    assert (got is None) == (ref is None)
    if ref is not None:
        for a, b in zip(got, ref):
            np.testing.assert_array_equal(a, b)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_graph_settle_matches_numpy(seed, ties):
    """Border settling: the regions after COMPETE_ROUNDS rounds, equal offers decided as the numpy form's tie keys
    decide them (distances from a few values: many ties), points without a region and planes out of reach (inf)."""
    rng = np.random.default_rng(seed)
    graph = _graph(rng, int(rng.integers(1, 150)))
    k = int(rng.integers(1, 5))
    dist = rng.integers(0, 3, (k + 1, graph.n)).astype(float) if ties else rng.random((k + 1, graph.n))
    dist[rng.random(dist.shape) < 0.2] = np.inf
    dist[k] = np.inf  # no region
    region = rng.integers(0, k + 1, graph.n)
    got = graph.settle(dist, region.copy())
    np.testing.assert_array_equal(got, settle_numpy(dist, region.copy(), graph))
    assert got.dtype == np.int64


def _axes_check(values: np.ndarray, axes: np.ndarray, sets: np.ndarray) -> None:
    """Each set's eigenvalues ascending and at least 0, its axes orthonormal, and scatter @ axis = value * axis (to
    1e-12 of the largest eigenvalue): the eigen-pairs hold whatever the basis of equal eigenvalues."""
    centred = sets - sets.mean(axis=1, keepdims=True)
    scatter = np.einsum('mki,mkj->mij', centred, centred)
    assert np.all(np.diff(values, axis=1) >= 0) and np.all(values >= 0)
    np.testing.assert_allclose(np.einsum('mij,mik->mjk', axes, axes), np.broadcast_to(np.eye(3), axes.shape),
                               atol=1e-12)
    scale = np.maximum(values[:, 2], 1e-300)[:, None, None]
    np.testing.assert_allclose(np.einsum('mij,mjk->mik', scatter, axes) / scale,
                               axes * values[:, None, :] / scale, atol=1e-12)


def test_principal_axes_of_degenerate_sets():
    """Equal eigenvalues (a cube's corners, a square, a line, one point repeated) and sets far from the origin:
    valid eigen-pairs; a flat set's normal and a line's direction exact."""
    cube = np.array([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)  # scatter 8 I
    square = np.array([(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0)], float)  # two equal, the third 0
    line = np.array([(t, 2 * t, -t) for t in (-2.0, -1.0, 0.5, 3.0)])  # two zero
    point = np.full((4, 3), 0.25)  # all zero
    sets = [cube, square, line, point, square + 1e4, line * 1e-5 + 7.0]
    k = 8
    pts = np.concatenate([np.resize(s, (k, 3)) for s in sets])
    idx = np.arange(len(pts)).reshape(-1, k)
    values, axes = _principal_axes(pts, idx)
    _axes_check(values, axes, pts[idx])
    np.testing.assert_allclose(values[0], 8.0 * 8 / 8, rtol=1e-12)  # np.resize repeats the cube once: k = 8 rows
    np.testing.assert_allclose(values[3], 0.0, atol=0)
    for i in (1, 4):  # a square: its normal is z
        np.testing.assert_allclose(abs(axes[i, 2, 0]), 1.0, atol=1e-9)
    for i in (2, 5):  # a line: its direction is (1, 2, -1) / sqrt(6)
        np.testing.assert_allclose(abs(axes[i, :, 2] @ np.array([1, 2, -1]) / np.sqrt(6)), 1.0, atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(3, 12), st.floats(-1e3, 1e3))
def test_principal_axes_are_eigen_pairs(seed, k, shift):
    """Flat, linear and round sets, some points on a plane, anywhere within a kilometre: eigen-pairs of the scatter."""
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(60, 3)) * rng.uniform(1e-4, 10, 3) + shift
    pts[rng.random(60) < 0.2, 2] = shift
    idx = rng.integers(0, 60, (20, k))
    values, axes = _principal_axes(pts, idx)
    _axes_check(values, axes, pts[idx])


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.floats(0.02, 2.0))
def test_voxel_count_matches_the_grid(seed, size):
    """The occupied voxels counted without building the grid: as many as the grid holds, and as numpy's distinct keys
    of the same voxel arithmetic."""
    rng = np.random.default_rng(seed)
    pts = _cloud(rng, 400)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    cell = size * float(np.ptp(pts, axis=0).max(initial=0.0) or 1.0) / 4
    dims = ((hi - lo) // cell).astype(np.int64) + 2
    count = kernels.voxel_count(pts, lo, cell, dims)
    assert count == len(kernels.voxel_grid(pts, lo, cell, dims)[1])
    cells = ((pts - lo) / cell).astype(np.int64)
    assert count == len(np.unique(cells[:, 0] + dims[0] * (cells[:, 1] + dims[1] * cells[:, 2])))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.floats(0.02, 2.0), st.booleans())
def test_voxel_grid_matches_a_stable_sort_of_the_keys(seed, size, hashed):
    """The points voxel by voxel as a stable sort of their keys orders them, the occupied keys ascending, where each
    voxel starts, and the table of each key's voxel: direct (counted placement), or hashed for a sparse grid (dims
    made large enough)."""
    rng = np.random.default_rng(seed)
    pts = _cloud(rng, 400)
    pts[rng.random(len(pts)) < 0.1] = pts[0]  # several points in one voxel
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    cell = size * float(np.ptp(pts, axis=0).max(initial=0.0) or 1.0) / 4
    dims = ((hi - lo) // cell).astype(np.int64) + 2
    if hashed:
        dims[2] = max(int(dims[2]), 2 * kernels.DENSE_VOXELS // int(dims[0] * dims[1]) + 1)
    order, cell_keys, starts, table = kernels.voxel_grid(pts, lo, cell, dims)
    cells = ((pts - lo) / cell).astype(np.int64)
    keys = cells[:, 0] + dims[0] * (cells[:, 1] + dims[1] * cells[:, 2])
    np.testing.assert_array_equal(order, np.argsort(keys, kind='stable'))
    distinct, first = np.unique(keys, return_index=True)
    np.testing.assert_array_equal(cell_keys, distinct)
    np.testing.assert_array_equal(starts, np.append(np.searchsorted(keys[order], distinct), len(pts)))
    total = int(np.prod(dims))
    dense = total <= max(kernels.DENSE_VOXELS, 8 * len(pts))
    assert not (hashed and dense)  # a grid made sparse: a hashed table
    assert (len(table) == total) == dense
    if dense:
        expected = np.full(total, -1, np.int64)
        expected[distinct] = np.arange(len(distinct))
        np.testing.assert_array_equal(table, expected)
    assert [kernels._voxel(cell_keys, table, int(key), dense) for key in distinct] == list(range(len(distinct)))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 200))
def test_sensor_rays_match_numpy(seed, n):
    """The rays, elevations and unit directions of the graph's lidar tests bit for bit as numpy's; a point at the
    viewpoint keeps a zero direction."""
    from plane_validation.core.regions import _sensor_rays, _sensor_rays_numpy
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3)) * rng.uniform(0.1, 30.0)
    viewpoint = rng.normal(size=3)
    if n:
        pts[rng.random(n) < 0.1] = viewpoint
    for got, ref in zip(_sensor_rays(pts, viewpoint), _sensor_rays_numpy(pts, viewpoint)):
        np.testing.assert_array_equal(got, ref)


class _NumpyGraphRemaining(_GraphRemaining):
    """The graph's region rule by its numpy reference, run through the generic loops of Remaining (no compiled whole
    plane)."""

    def keep(self, mask, normal, support, above):
        return graph_region_numpy(self.local, mask, normal, support, above)

    def refitted(self, *args):
        return None


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_graph_plane_matches_the_numpy_loop(seed, per_point):
    """The plane, region and taken points of one compiled call (kernels.graph_plane) are those of
    hypotheses.best_region's loop over the numpy region rule (Remaining.best, then Remaining.refit while the region
    grows), on the nearest-neighbour graph of a share of points on a few noisy planes, some normals unknown, the
    tolerance from below the noise (regions fall apart and are joined through their support) to well above it."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(10, 800))
    cols = _planar_points(rng, m)
    graph = graph_neighbours(np.ascontiguousarray(cols.T))
    normals = graph.normals.copy()
    normals[rng.random(m) < 0.1] = np.nan
    rest = np.flatnonzero(rng.random(m) < rng.uniform(0.5, 1.0))
    if len(rest) < 3:
        return
    local = GraphNeighbours(n=m, edges=graph.edges, normals=normals).subgraph(rest)
    search = np.ascontiguousarray(cols[:, rest])
    idx = rng.integers(0, len(rest), (int(rng.integers(1, 6)), 3))
    planes, offsets = kernels.triple_planes(search, idx, 1e-6)
    if not len(planes):
        return
    scale = float(rng.uniform(0.001, 0.05))
    tolerance = scale * rng.uniform(0.5, 1.5, len(rest)) if per_point else scale
    point_normals = np.ascontiguousarray(local.normals.T)
    got = hypotheses.best_region(search, tolerance, planes, offsets, _GraphRemaining.of(local), point_normals)
    ref = hypotheses.best_region(search, tolerance, planes, offsets, _NumpyGraphRemaining.of(local), point_normals)
    np.testing.assert_array_equal(got[0], ref[0])
    assert got[1] == ref[1]
    np.testing.assert_array_equal(got[2], ref[2])
    np.testing.assert_array_equal(got[3], ref[3])
