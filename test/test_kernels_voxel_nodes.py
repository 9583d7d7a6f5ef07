"""Each point's search node from its voxel (core/kernels.py, the voxel nodes block) against a plain-numpy
reference, on random inputs."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from plane_validation.core import kernels
from plane_validation.core.regions import voxel_index

SETTINGS = settings(max_examples=60, deadline=None)


def _cloud(rng: np.random.Generator) -> np.ndarray:
    """Random (n, 3) points: a noisy plane, a line, grid-quantized ties, exact copies and sometimes a far outlier."""
    n = int(rng.integers(1, 400))
    kind = rng.integers(0, 4, n)
    pts = rng.uniform(-1, 1, (n, 3))
    pts[kind == 0, 2] = rng.normal(scale=0.01, size=int(np.sum(kind == 0)))
    pts[kind == 1, 1:] = 0.0
    pts[kind == 2] = np.round(pts[kind == 2] * 20) / 20  # equal distances
    if n > 3 and rng.random() < 0.3:
        pts[rng.integers(0, n, 3)] = pts[0]
    if n > 2 and rng.random() < 0.3:
        pts[-1] = rng.uniform(-50, 50, 3)
    return pts * rng.uniform(0.01, 100)


def _voxel_nodes_numpy(index, queries: np.ndarray) -> np.ndarray:
    """:func:`.kernels.voxel_nodes` by brute force: each query's voxel from the same arithmetic as the hash, the
    nearest hashed point with that voxel (equal distances: the first in the hash's order), -1 where none."""
    def keys(p):
        f = (p - index.origin) / index.cell
        inside = ((f >= 0) & (f < index.dims)).all(axis=1)
        c = np.where(inside[:, None], f, 0).astype(np.int64)
        return np.where(inside, c[:, 0] + index.dims[0] * (c[:, 1] + index.dims[1] * c[:, 2]), -1)
    own = keys(index.ordered)  # the hashed points, voxel by voxel
    e = index.ordered[None, :, :] - queries[:, None, :]
    d2 = e[..., 0] * e[..., 0] + e[..., 1] * e[..., 1] + e[..., 2] * e[..., 2]
    d2 = np.where(own[None, :] == keys(queries)[:, None], d2, np.inf)
    first = np.argmin(d2, axis=1)  # the first of equal minima: the first in the hash's order
    return np.where(np.isfinite(d2[np.arange(len(queries)), first]), index.grid[0][first], -1)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_voxel_nodes_match_numpy(seed, others):
    """The nearest hashed point within each query's own voxel, exactly as brute force finds it; -1 in an empty
    voxel."""
    rng = np.random.default_rng(seed)
    pts = _cloud(rng)
    queries = pts
    if others:  # queries other than the points, across the cloud's span (some in empty voxels)
        queries = pts[rng.integers(0, len(pts), int(rng.integers(1, 300)))] + rng.normal(scale=0.05, size=(1, 3)) * \
            np.ptp(pts, axis=0).max(initial=1.0)
    index = voxel_index(pts, span=queries)
    if index is None:
        return
    queries = np.ascontiguousarray(queries)
    node = kernels.voxel_nodes(index.ordered, *index.grid, index.origin, index.cell, index.dims, queries)
    np.testing.assert_array_equal(node, _voxel_nodes_numpy(index, queries))
    assert node.dtype == np.int64
    assert (node >= 0).any() or others


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_each_point_takes_the_nearest_searched_point_of_its_voxel_or_the_nearest_overall(seed):
    """A point's node is the nearest searched point in its voxel; where its voxel holds none (or the coordinates are
    too far out for voxels), the nearest searched point, as the kd-tree finds it."""
    from plane_validation.core.search.graph import _nearest_searched, _nearest_searched_tree
    rng = np.random.default_rng(seed)
    pts = _cloud(rng)
    if rng.random() < 0.1:
        pts[0] = 3e38  # a driver's FLT_MAX row: no voxel hash
    searched = pts[rng.random(len(pts)) < 0.3]
    if len(searched) == 0:
        searched = pts[:1]
    node, index = _nearest_searched(searched, pts)
    ref = _nearest_searched_tree(searched, pts)
    nearest = np.linalg.norm(searched[ref] - pts, axis=1)
    if index is None:
        np.testing.assert_allclose(np.linalg.norm(searched[node] - pts, axis=1), nearest, rtol=1e-12, atol=0)
        return
    own = _voxel_nodes_numpy(index, np.ascontiguousarray(pts))
    np.testing.assert_array_equal(node[own >= 0], own[own >= 0])
    alone = own < 0
    np.testing.assert_allclose(np.linalg.norm(searched[node[alone]] - pts[alone], axis=1), nearest[alone],
                               rtol=1e-12, atol=0)
