"""The compiled kernels (core/kernels.py) against their plain-numpy references, on random inputs."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from plane_validation.core import kernels
from plane_validation.core.ransac import finite_rows
from plane_validation.core.search.grid import spread_grid, spread_grid_numpy
from plane_validation.core.search.neighbours import row_starts
from plane_validation.core.search.neighbours_graph import GraphNeighbours
from plane_validation.core.search.neighbours_grid import GridNeighbours

SETTINGS = settings(max_examples=60, deadline=None)


def _image_case(seed: int, per_point: bool):
    """A random H x W image with NaN holes, a sub-grid of regions on it and k random planes."""
    rng = np.random.default_rng(seed)
    h, w = rng.integers(3, 40, 2)
    step = int(rng.integers(1, 5))
    gh, gw = len(range(step // 2, h, step)), len(range(step // 2, w, step))
    pts = rng.normal(size=(h * w, 3))
    pts[rng.random(h * w) < 0.2] = np.nan
    valid = np.isfinite(pts).all(axis=1)
    pixel = np.flatnonzero(rng.random(gh * gw) < 0.8)
    node = np.full(gh * gw, -1)
    node[pixel] = np.arange(len(pixel))
    neighbours = GridNeighbours(n=len(pixel), shape=(gh, gw), pixel=pixel, node=node)
    k = int(rng.integers(1, 6))
    region = rng.integers(-1, k, len(pixel))
    normals = rng.normal(size=(k, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    planes = [(n, float(d)) for n, d in zip(normals, rng.normal(size=k))]
    tolerance = rng.uniform(0.05, 1.0, h * w) if per_point else float(rng.uniform(0.05, 1.0))
    return pts, valid, (int(h), int(w)), step, region, neighbours, planes, tolerance


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans(), st.booleans())
def test_spread_grid_matches_numpy(seed, per_point, along_rays):
    """The labels, and each region's rows (ascending) with their squared distances to its plane, one after another;
    with a tolerance across each plane, and along each ray (depth_quadratic: noise.ray_band)."""
    case = _image_case(seed, per_point)
    rng = np.random.default_rng(seed + 1)
    ray = np.append(rng.normal(size=3), rng.uniform(0.05, 0.9)) if along_rays else kernels.NO_RAY
    labels, rows, bounds, squares = spread_grid(*case, ray)
    ref_labels, ref_best = spread_grid_numpy(*case, ray)
    np.testing.assert_array_equal(labels, ref_labels)
    assert labels.dtype == np.int32
    k = len(case[6])
    assert len(bounds) == k + 1 and bounds[0] == 0 and bounds[k] == len(rows) == len(squares)
    for j in range(k):
        np.testing.assert_array_equal(rows[bounds[j]:bounds[j + 1]], np.flatnonzero(ref_labels == j))
    np.testing.assert_allclose(np.sqrt(squares), ref_best[rows], rtol=1e-12, atol=1e-12)


@SETTINGS
@given(st.lists(st.integers(-3, 7), max_size=300), st.integers(0, 8))
def test_group_by_label_is_a_stable_counting_sort(values, k):
    labels = np.array(values, dtype=np.int32)
    rows, bounds = kernels.group_by_label(labels, k)
    assert len(bounds) == k + 1 and bounds[0] == 0
    for j in range(k):
        np.testing.assert_array_equal(rows[bounds[j]:bounds[j + 1]], np.flatnonzero(labels == j))
    assert bounds[k] == np.count_nonzero((labels >= 0) & (labels < k))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 200))
def test_finite_mask_matches_numpy(seed, n):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3))
    bad = rng.random((n, 3)) < 0.1
    pts[bad] = rng.choice([np.nan, np.inf, -np.inf], size=int(bad.sum()))
    mask, count = kernels.finite_mask(pts)
    ref = np.isfinite(pts).all(axis=1)
    np.testing.assert_array_equal(mask, ref)
    assert count == ref.sum()
    np.testing.assert_array_equal(finite_rows(pts), ref)
    np.testing.assert_array_equal(finite_rows(pts[:, ::-1]), ref)  # not C-ordered: the numpy path


def test_read_only_input_is_copied_not_recompiled():
    pts = np.zeros((5, 3))
    pts.flags.writeable = False
    arr = kernels.c_array(pts, np.float64)
    assert arr.flags.writeable and arr.flags.c_contiguous and arr is not pts
    same = np.zeros((5, 3))
    assert kernels.c_array(same, np.float64) is same


def test_c_array_gives_back_a_kernels_output_itself_and_converts_the_rest():
    """A compiled kernel's output (numpy would wrap it in a new view) is returned itself, so an identity test on it
    (VoxelIndex.query's of the indexed points) holds; another dtype, a strided view, a subclass or a 0-d value is
    converted to a C-ordered ndarray of the dtype."""
    out = kernels.rows_less(np.arange(12.0).reshape(4, 3), np.array([2, 0], np.int64), np.zeros(3))
    assert np.ascontiguousarray(out, dtype=np.float64) is not out  # what the identity path is for
    assert kernels.c_array(out, np.float64) is out
    for values in (np.zeros((4, 3), np.float32), np.zeros((3, 4)).T, np.ma.zeros((4, 3)), np.float64(2.0)):
        arr = kernels.c_array(values, np.float64)
        assert type(arr) is np.ndarray and arr.dtype == np.float64 and arr.flags.c_contiguous and arr.ndim >= 1
        assert arr is not values


def test_warm_loads_every_kernel_and_says_whether_it_compiled():
    first = kernels.warm()
    again = kernels.warm()
    assert first.seconds >= 0 and again.compiled is False  # in one process the second call compiles nothing
    for kernel in kernels._KERNELS:
        assert kernel.signatures, kernel  # each has a compiled signature


def test_warm_probe_tells_a_warm_cache_and_warm_takes_a_cold_probe_s_word():
    kernels.warm()
    probe = kernels.warm_probe()
    assert probe.compiled is False and probe.seconds >= 0
    assert kernels.warm(cold=True).compiled is True  # after a probe that compiled: the others compile in jobs


def test_cache_dir_is_used_and_a_second_process_loads_from_it(tmp_path):
    """With NUMBA_CACHE_DIR (what a read-only install sets; numba otherwise falls back from an unwritable
    package folder to its user-wide cache by itself) the first process compiles into it and the next loads."""
    package = tmp_path / 'site' / 'plane_validation'
    shutil.copytree(Path(kernels.__file__).resolve().parents[1], package,
                    ignore=shutil.ignore_patterns('__pycache__'))
    cache = tmp_path / 'cache'
    env = dict(os.environ, PYTHONPATH=str(package.parent), NUMBA_CACHE_DIR=str(cache))
    # one kernel stands for all (warm() compiles every one of them: 25 s on a cold cache)
    script = ('import numpy as np; from plane_validation.core import kernels; kernels.finite_mask(np.zeros((2, 3))); '
              'print(len(kernels.finite_mask.stats.cache_misses) > 0)')
    runs = [subprocess.run([sys.executable, '-c', script], env=env, capture_output=True, text=True, timeout=300)
            for _ in range(2)]
    assert [r.returncode for r in runs] == [0, 0], [r.stderr for r in runs]
    assert [r.stdout.strip() for r in runs] == ['True', 'False']
    assert list(cache.rglob('*.nbi')), 'no cache index in NUMBA_CACHE_DIR'
    assert not list(package.rglob('*.nbi')), 'the package folder was written to'


def test_warmup_command():
    run = subprocess.run([sys.executable, '-m', 'plane_validation', 'warmup'], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith('kernels ready in ')


def _grid_case(seed: int):
    """A random sub-grid graph (holes, unusable pixels, bridges, unknown normals) and a random plane's bands."""
    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(2, 25, 2))
    valid = rng.random(h * w) < rng.uniform(0.5, 1.0)
    pixel = np.flatnonzero(valid)
    node = np.full(h * w, -1, np.int64)
    node[pixel] = np.arange(len(pixel))
    usable = valid & (rng.random(h * w) < 0.9)
    normals = rng.normal(size=(len(pixel), 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    normals[rng.random(len(pixel)) < 0.1] = np.nan
    b = int(rng.integers(0, 6))
    bridges = np.column_stack([rng.integers(0, h * w, b), rng.integers(0, h * w, b), rng.integers(0, 2, b)])
    neighbours = GridNeighbours(n=len(pixel), shape=(h, w), pixel=pixel, node=node, usable=usable, normals=normals,
                            bridges=bridges.astype(np.int64) if b else None)
    rest = np.flatnonzero(rng.random(len(pixel)) < 0.9)
    support = rng.random(len(rest)) < rng.uniform(0.3, 1.0)
    mask = support & (rng.random(len(rest)) < rng.uniform(0.05, 1.0))  # scattered pieces: often fragmented
    above = rng.random(len(rest)) < 0.5
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    if rng.random() < 0.5:  # a surface: normals that agree with the plane's, noise points scattered within t
        normals[:] = normal + rng.normal(scale=0.1, size=normals.shape)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        mask = support & (rng.random(len(rest)) < rng.uniform(0.1, 0.5))
    return neighbours, rest, mask, normal, support, above


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_grid_region_matches_numpy(seed):
    from plane_validation.core.search.neighbours_grid import grid_region, grid_region_numpy
    case = _grid_case(seed)
    kept, taken = grid_region(*case)
    ref_kept, ref_taken = grid_region_numpy(*case)
    np.testing.assert_array_equal(kept, ref_kept)
    np.testing.assert_array_equal(taken, ref_taken)


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_grid_components_match_the_numpy_labelling(seed):
    neighbours, _, _, _, _, _ = _grid_case(seed)
    member = np.random.default_rng(seed).random(neighbours.n) < 0.6
    bridges = np.empty((0, 3), np.int64) if neighbours.bridges is None else neighbours.bridges
    component, count = kernels.grid_components(neighbours.pixel, neighbours.node, neighbours.usable,
                                               neighbours.shape[1], bridges, member)
    ref, ref_count = neighbours.components(member)
    assert count == ref_count
    np.testing.assert_array_equal(component, ref)


def _graph_case(seed: int):
    """A random graph (as Neighbours' graph form: each pair once, smaller index first, sorted) with local normals
    (some unknown, or none at all) and a plane's bands."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 300))
    pairs = rng.integers(0, n, (int(rng.integers(0, 4 * n)), 2))
    pairs = np.unique(np.sort(pairs[pairs[:, 0] != pairs[:, 1]], axis=1), axis=0).reshape(-1, 2)
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    normals = normal + rng.normal(scale=rng.choice([0.1, 1.0]), size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    normals[rng.random(n) < 0.1] = np.nan
    local = GraphNeighbours(n=n, edges=pairs.astype(np.int64), normals=None if rng.random() < 0.2 else normals)
    support = rng.random(n) < rng.uniform(0.3, 1.0)
    mask = support & (rng.random(n) < rng.uniform(0.1, 0.7))
    return local, mask, normal, support, rng.random(n) < 0.5


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_graph_region_matches_numpy(seed):
    from plane_validation.core.search.neighbours_graph import _NO_NORMALS, graph_region, graph_region_numpy
    local, mask, normal, support, above = _graph_case(seed)
    normals = _NO_NORMALS if local.normals is None else local.normals
    kept, taken = graph_region(local.edge_ends, local.edge_rows, normals, mask, normal, support, above)
    ref_kept, ref_taken = graph_region_numpy(local, mask, normal, support, above)
    np.testing.assert_array_equal(kept, ref_kept)
    np.testing.assert_array_equal(taken, ref_taken)


def _cloud_case(seed: int) -> np.ndarray:
    """Random (n, 3) points: a noisy plane, a line, clusters, exact copies, grid-quantized ties and far outliers."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    kind = rng.integers(0, 4, n)
    pts = rng.uniform(-1, 1, (n, 3))
    pts[kind == 0, 2] = rng.normal(scale=0.01, size=int(np.sum(kind == 0)))  # a plane
    pts[kind == 1, 1:] = 0.0  # a line
    pts[kind == 2] = np.round(pts[kind == 2] * 20) / 20  # quantized: equal distances
    if n > 3 and rng.random() < 0.3:
        pts[rng.integers(0, n, 3)] = pts[0]  # exact copies
    if n > 2 and rng.random() < 0.3:
        pts[-1] = rng.uniform(-1e3, 1e3, 3)  # far from the rest
    return pts * rng.uniform(0.01, 100)


def _same_neighbours(points, queries, dist, idx, ref_dist, ref_idx, next_dist):
    """Equal distances and, where not tied (``next_dist``: the reference's next nearest), equal indices; each index at
    its stated distance."""
    np.testing.assert_allclose(dist, ref_dist, rtol=1e-12, atol=0)
    found = idx < len(points)
    np.testing.assert_array_equal(found, ref_idx < len(points))
    at = np.where(found, idx, 0)
    np.testing.assert_allclose(np.where(found, np.linalg.norm(points[at] - queries[:, None], axis=-1), np.inf), dist,
                               rtol=1e-12, atol=1e-15)
    tied = np.zeros_like(found)
    tied[:, 1:] |= dist[:, 1:] == dist[:, :-1]
    tied[:, :-1] |= dist[:, 1:] == dist[:, :-1]
    tied[:, -1] |= dist[:, -1] == next_dist
    np.testing.assert_array_equal(np.where(tied, 0, idx), np.where(tied, 0, ref_idx))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 12))
def test_voxel_knn_matches_the_kd_tree(seed, k):
    from plane_validation.core.regions import _knn, _knn_tree
    pts = _cloud_case(seed)
    dist, idx = _knn(pts, k)
    ref_dist, ref_idx = _knn_tree(pts, k)
    next_dist = _knn_tree(pts, k + 1)[0].reshape(len(pts), -1)[:, -1]
    _same_neighbours(pts, pts, dist.reshape(len(pts), -1), idx.reshape(len(pts), -1),
                     ref_dist.reshape(len(pts), -1), ref_idx.reshape(len(pts), -1), next_dist)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 60))
def test_brute_knn_matches_numpy_and_the_kd_tree(seed, k):
    """Every distance, ranked (equal ones by index), as numpy's lexsort ranks them; as the kd-tree answers, ties
    aside; fewer than k points: the rest at inf with index m."""
    from scipy.spatial import cKDTree
    rng = np.random.default_rng(seed)
    pts = _cloud_case(seed)
    queries = np.concatenate([pts[rng.integers(0, len(pts), 3)], rng.normal(size=(3, 3)) * 100.0])
    dist, idx = kernels.brute_knn(pts, queries, k)
    e = pts[None, :, :] - queries[:, None, :]
    d2 = e[..., 0] * e[..., 0] + e[..., 1] * e[..., 1] + e[..., 2] * e[..., 2]
    for q in range(len(queries)):
        ranked = np.lexsort((np.arange(len(pts)), d2[q]))[:k]
        np.testing.assert_array_equal(idx[q, :len(ranked)], ranked)
        np.testing.assert_array_equal(dist[q, :len(ranked)], np.sqrt(d2[q, ranked]))
        assert (idx[q, len(ranked):] == len(pts)).all() and np.isinf(dist[q, len(ranked):]).all()
    ref_dist, ref_idx = cKDTree(pts).query(queries, k=k)
    next_dist = cKDTree(pts).query(queries, k=k + 1)[0].reshape(len(queries), -1)[:, -1]
    _same_neighbours(pts, queries, dist, idx, ref_dist.reshape(len(queries), -1), ref_idx.reshape(len(queries), -1),
                     next_dist)


def test_far_queries_are_answered_without_a_kd_tree():
    """A query beyond the voxel rings (far from every point) gets the kd-tree's neighbours from every distance; the
    tree is built only for many such queries."""
    from scipy.spatial import cKDTree

    from plane_validation.core.regions import BRUTE_PAIRS, voxel_index
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(2000, 3))
    far = np.array([[40.0, 0.0, 0.0], [0.0, -35.0, 3.0]])
    index = voxel_index(pts, span=far)
    dist, idx = index.query(far, 5)
    ref_dist, ref_idx = cKDTree(pts).query(far, k=5)
    np.testing.assert_allclose(dist, ref_dist, rtol=1e-12)
    np.testing.assert_array_equal(idx, ref_idx)
    assert '_tree' not in index.__dict__
    many = np.tile(far, (BRUTE_PAIRS // (2 * len(pts)) + 1, 1))
    np.testing.assert_array_equal(index.query(many, 5)[1], np.tile(ref_idx, (len(many) // 2, 1)))
    assert '_tree' in index.__dict__


def test_voxel_index_declines_far_out_coordinates():
    from plane_validation.core.regions import voxel_index
    pts = np.random.default_rng(0).normal(size=(1000, 3))
    pts[0] = 3e38  # a driver's FLT_MAX row: 2^20 voxels would not reach it
    assert voxel_index(pts) is None
    assert voxel_index(pts[1:]) is not None


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 200))
def test_coordinate_bounds_match_numpy(seed, n):
    pts = np.random.default_rng(seed).normal(size=(n + 1, 3))
    lo, hi = kernels.coordinate_bounds(pts)
    np.testing.assert_array_equal(lo, pts.min(axis=0))
    np.testing.assert_array_equal(hi, pts.max(axis=0))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(3, 16))
def test_principal_axes_match_numpy_eigh(seed, k):
    from plane_validation.core.regions import _principal_axes, _principal_axes_numpy
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(200, 3)) * rng.uniform(1e-4, 10, 3)  # anisotropic: flat, linear and round sets
    pts[rng.random(200) < 0.2, 2] = 0.0
    idx = rng.integers(0, 200, (50, k))
    idx[:5] = idx[:5, :1]  # a set of one point repeated: all eigenvalues zero
    values, axes = _principal_axes(pts, idx)
    ref_values, ref_axes = _principal_axes_numpy(pts[idx])
    scale = np.abs(ref_values).max(axis=1, keepdims=True)
    np.testing.assert_allclose(values, ref_values, rtol=0, atol=1e-12 * float(scale.max()) + 1e-300)
    np.testing.assert_allclose(np.einsum('mij,mik->mjk', axes, axes), np.broadcast_to(np.eye(3), axes.shape),
                               atol=1e-12)  # orthonormal
    gap = np.diff(ref_values, axis=1) > 1e-6 * scale  # a well-separated eigenvalue: the same axis up to sign
    for j in range(3):
        separate = (gap[:, j - 1] if j > 0 else True) & (gap[:, j] if j < 2 else True)
        dots = np.abs(np.einsum('mi,mi->m', axes[:, :, j], ref_axes[:, :, j]))
        np.testing.assert_allclose(dots[separate], 1.0, atol=1e-6)


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_pair_graph_matches_numpy(seed):
    from plane_validation.core.regions import _neighbours, _neighbours_numpy
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 200))
    pairs = rng.integers(0, n, (int(rng.integers(0, 5 * n)), 2))
    graph, ref = _neighbours(n, pairs, None), _neighbours_numpy(n, pairs, None)
    np.testing.assert_array_equal(graph.edges, ref.edges)
    for part, ref_part in zip(graph.adjacency, ref.adjacency):
        np.testing.assert_array_equal(part, ref_part)
    assert graph.edges.flags.c_contiguous  # as the kernels that take them read them: no copy
    np.testing.assert_array_equal(graph.edge_rows, row_starts(ref.edges[:, 0], n))  # the kernel's, against numpy


def _plane_patches_numpy(centred, axes, per_patch, min_count):
    """plane_patches in numpy: cells numbered from the in-plane coordinates, each cell's scatter about its mean."""
    x, y, z = centred.T
    uv = np.column_stack([x * axes[0, i] + y * axes[1, i] + z * axes[2, i] for i in range(2)])  # the kernel's sums
    lo, extent = uv.min(axis=0), np.ptp(uv, axis=0)
    side = np.sqrt(np.prod(extent) * per_patch / len(uv))
    width = int(extent[1] // side) + 1
    cells = ((uv[:, 0] - lo[0]) // side).astype(np.int64) * width + ((uv[:, 1] - lo[1]) // side).astype(np.int64)
    numbers, inverse, sizes = np.unique(cells, return_inverse=True, return_counts=True)
    kept = np.flatnonzero(sizes >= min_count)
    scatter = []
    for c in kept:
        members = centred[inverse.reshape(-1) == c]
        d = members - members.mean(axis=0)
        scatter.append(d.T @ d / len(members))
    return sizes[kept], np.array(scatter).reshape(-1, 3, 3)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 400), st.integers(1, 40), st.integers(1, 20), st.booleans())
def test_plane_patches_match_numpy(seed, n, per_patch, min_count, strip):
    rng = np.random.default_rng(seed)
    axes = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    spread = rng.uniform(0.1, 10, 3) * ([1.0, 1.0, 0.01] if not strip else [1.0, 1e-3, 1e-5])
    pts = rng.normal(size=(n, 3)) * spread @ axes.T
    centred = np.ascontiguousarray(pts - pts.mean(axis=0))
    in_plane = np.ascontiguousarray(axes[:, :2])
    counts, scatter = kernels.plane_patches(centred, in_plane, per_patch, min_count)
    if n < 2:  # a single point spans no area
        assert len(counts) == 0
        return
    want_counts, want_scatter = _plane_patches_numpy(centred, in_plane, per_patch, min_count)
    assert np.array_equal(counts, want_counts)
    np.testing.assert_allclose(scatter, want_scatter, rtol=1e-9, atol=1e-15 * float(np.abs(centred).max()) ** 2)


def _fold_line_numpy(u, v, w, angles, offsets, inner):
    """fold_line by np.linalg.lstsq over the same lines: (mean squared residual, theta, s0) of the best."""
    best = (np.inf, np.nan, np.nan)
    for k in range(angles):
        theta = np.pi * k / angles
        s = u * np.cos(theta) + v * np.sin(theta)
        ordered = np.sort(s)
        for j in range(offsets):
            q = (1 - inner) / 2 + inner * j / max(offsets - 1, 1)
            s0 = ordered[min(len(u) - 1, max(1, int(q * (len(u) - 1) + 0.5)))]
            design = np.column_stack([np.ones_like(u), u, v, np.abs(s - s0)])
            coef, *_ = np.linalg.lstsq(design, w, rcond=None)
            mse = float(np.mean((w - design @ coef) ** 2))
            if mse < best[0]:
                best = (mse, theta, s0)
    return best


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(5, 300), st.integers(1, 12), st.integers(1, 9), st.booleans())
def test_fold_line_matches_least_squares(seed, n, angles, offsets, ridge):
    rng = np.random.default_rng(seed)
    u, v = rng.uniform(-5, 5, n), rng.uniform(-3, 3, n)
    w = rng.normal(0, 0.02, n) + (0.05 * np.abs(u - 1) if ridge else 0.0)
    mse, theta, s0 = kernels.fold_line(u, v, w, angles, offsets, 0.7)
    want = _fold_line_numpy(u, v, w, angles, offsets, 0.7)
    np.testing.assert_allclose(mse, want[0], rtol=1e-6, atol=1e-12)
    # the line given fits as well as the best (lines whose fits tie within rounding may be taken either way)
    design = np.column_stack([np.ones_like(u), u, v, np.abs(u * np.cos(theta) + v * np.sin(theta) - s0)])
    coef, *_ = np.linalg.lstsq(design, w, rcond=None)
    np.testing.assert_allclose(np.mean((w - design @ coef) ** 2), want[0], rtol=1e-6, atol=1e-12)
    assert 0 <= theta < np.pi


def test_fold_line_finds_a_ridge_and_not_a_plane():
    rng = np.random.default_rng(0)
    u, v = rng.uniform(-4, 4, 2000), rng.uniform(0, 8, 2000)
    noise = rng.normal(0, 0.01, 2000)
    ridge = -0.05 * np.abs(u) + noise
    mse, theta, s0 = kernels.fold_line(u, v, ridge - ridge.mean(), 18, 15, 0.7)
    assert mse < 1.1 * np.var(noise) < np.var(ridge)
    assert theta == 0.0 and abs(s0) < 0.3  # the ridge runs along v at u = 0
    assert np.isnan(kernels.fold_line(u[:4], v[:4], noise[:4], 18, 15, 0.7)).all()


@SETTINGS
@given(st.one_of(st.integers(1, 5000), st.integers(1, 2**32 + 5), st.integers(2**32 - 5, 2**63 - 1)),
       st.integers(0, 3000))
def test_seeded_draws_are_numpys_draws_seeded_by_m(m, count):
    expected = np.random.default_rng(m).integers(0, m, count)
    got = kernels.seeded_draws(m, count)
    assert got.dtype == np.int64
    np.testing.assert_array_equal(got, expected)
