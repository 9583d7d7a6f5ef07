"""The plain graph's compiled kernels (core/kernels.py, the plain graph block, and the principal axes) against
plain-numpy references, on random graphs: a subgraph's edges, the pairs that join two regions, border settling."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from test_kernels_graph import _cloud

from plane_validation.core import kernels
from plane_validation.core.regions import _neighbours, _principal_axes
from plane_validation.core.search.neighbours import Neighbours, settle_numpy

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


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_subgraph_of_subgraph_matches_numpy(seed):
    """Removing points twice (as a search takes out one plane after another) keeps the numpy form's edges."""
    rng = np.random.default_rng(seed)
    graph = _graph(rng, int(rng.integers(1, 120)))
    first = np.flatnonzero(rng.random(graph.n) < 0.8)
    local = graph.subgraph(first)
    second = np.flatnonzero(rng.random(local.n) < 0.6)
    np.testing.assert_array_equal(local.subgraph(second).edges,
                                  graph.subgraph_numpy(first).subgraph_numpy(second).edges)


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


def _jacobi_reference(scatter: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cyclic Jacobi rotations on a full 3 x 3 array, one rotation as the products a J then J^T (a J): the
    computation the compiled kernel does in scalars, for a bit-for-bit comparison."""
    a, v = scatter.copy(), np.eye(3)
    scale = a[0, 0] * a[0, 0] + a[1, 1] * a[1, 1] + a[2, 2] * a[2, 2] + 2 * (a[0, 1] * a[0, 1] + a[0, 2] * a[0, 2] +
                                                                          a[1, 2] * a[1, 2])
    for _ in range(32):
        if not a[0, 1] ** 2 + a[0, 2] ** 2 + a[1, 2] ** 2 > 1e-32 * scale:
            break
        for p, q in ((0, 1), (0, 2), (1, 2)):
            if a[p, q] == 0.0:
                continue
            theta = (a[q, q] - a[p, p]) / (2.0 * a[p, q])
            t = 0.5 / theta if abs(theta) > 1e150 else 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
            if abs(theta) <= 1e150 and theta < 0:
                t = -t
            c = 1.0 / np.sqrt(t * t + 1.0)
            s = t * c
            for r in range(3):
                a[r, p], a[r, q] = c * a[r, p] - s * a[r, q], s * a[r, p] + c * a[r, q]
            for r in range(3):
                a[p, r], a[q, r] = c * a[p, r] - s * a[q, r], s * a[p, r] + c * a[q, r]
            a[p, q] = a[q, p] = 0.0
            for r in range(3):
                v[r, p], v[r, q] = c * v[r, p] - s * v[r, q], s * v[r, p] + c * v[r, q]
    order = np.argsort(np.diag(a), kind='stable')
    return np.diag(a)[order], v[:, order]


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(3, 12))
def test_principal_axes_match_a_jacobi_reference_bit_for_bit(seed, k):
    """The compiled Jacobi solve gives the eigenvalues and axes of the reference bit for bit."""
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(60, 3)) * rng.uniform(1e-4, 10, 3)
    pts[rng.random(60) < 0.2, 2] = 0.0
    idx = rng.integers(0, 60, (20, k))
    values, axes = _principal_axes(pts, idx)
    for i in range(len(idx)):
        nb = pts[idx[i]]
        mean = np.zeros(3)
        for p in nb:  # summed in the kernel's order
            mean += p
        mean /= k
        scatter = np.zeros((3, 3))
        for p in nb:
            d = p - mean
            scatter += np.outer(d, d)
        ref_values, ref_axes = _jacobi_reference(scatter)
        np.testing.assert_array_equal(values[i], ref_values)
        if np.all(np.diff(ref_values) > 0):  # distinct eigenvalues: no tie for the sorts to order otherwise
            np.testing.assert_array_equal(axes[i], ref_axes)


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
