"""The search's compiled kernels (core/kernels.py, the search block) against their plain-numpy references, on random
inputs."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from plane_validation.core.search.grid import grid_image, grid_image_numpy

SETTINGS = settings(max_examples=60, deadline=None)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_grid_sample_matches_numpy(seed, single):
    """The sub-grid's pixels and points: the block's valid pixel nearest to its centre, as the numpy search finds it
    (float32 points stay float32)."""
    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(1, 30, 2))
    step = int(rng.integers(1, 7))
    points = rng.normal(size=(h * w, 3)).astype(np.float32 if single else np.float64)
    finite = rng.random(h * w) < rng.uniform(0.0, 1.0)
    points[~finite] = np.nan
    image, pixels = grid_image(points, finite, (h, w), step)
    ref_image, ref_pixels = grid_image_numpy(points, finite, (h, w), step)
    np.testing.assert_array_equal(pixels, ref_pixels)
    np.testing.assert_array_equal(image, ref_image)
    assert image.dtype == ref_image.dtype


def _neighbours_fields(neighbours) -> dict:
    return {name: getattr(neighbours, name) for name in ('n', 'shape', 'pixel', 'node', 'usable', 'normals', 'wraps',
                                                         'bridges')}


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.sampled_from(['surfaces', 'noise', 'lidar']))
def test_grid_neighbours_match_numpy(seed, kind):
    """The sub-grid's ranges, depth jumps, usable pixels, pitch and normals (bends too) from the kernels, exactly as
    the numpy passes give them: on random surfaces with steps and holes, on noise, and on a lidar-like image (pixels
    coarser down than across: wider normals and the bend test)."""
    from plane_validation.core.search.grid_build import grid_neighbours, grid_neighbours_numpy
    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(1, 24, 2))
    if kind == 'lidar':
        elevation = np.radians(np.linspace(-15, 15, h))[:, None] + np.zeros((1, w))
        azimuth = np.linspace(0, 2 * np.pi, w, endpoint=False)[None, :] + np.zeros((h, 1))
        rays = np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth),
                         np.sin(elevation)], -1)
        image = rays * rng.uniform(2, 10, (h, w, 1)).round(rng.integers(0, 3))
    elif kind == 'surfaces':
        rows, cols = np.mgrid[0:h, 0:w]
        depth = 2.0 + 0.5 * (cols > rng.integers(0, w + 1)) + rng.normal(scale=rng.uniform(0, 0.02), size=(h, w))
        image = np.stack([(cols - w / 2) * 0.01 * depth, (rows - h / 2) * 0.01 * depth, depth], -1)
    else:
        image = rng.normal(size=(h, w, 3))
    valid = rng.random((h, w)) < rng.uniform(0.5, 1.0)
    image[~valid] = np.nan
    got = _neighbours_fields(grid_neighbours(image, valid))
    ref = _neighbours_fields(grid_neighbours_numpy(image, valid))
    for name in got:
        if isinstance(ref[name], np.ndarray):
            np.testing.assert_array_equal(got[name], ref[name], err_msg=name)
        else:
            assert got[name] == ref[name], name


def _stripes_case(seed: int):
    """A small organized image of vertical stripes on 2-3 planes (some stripes coplanar), with noise and holes; its
    searched points (3, m), grid neighbours, regions (a stripe each, some points none) and their fitted planes."""
    from plane_validation.core.search.fit import fit_columns
    from plane_validation.core.search.grid_build import grid_neighbours
    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(8, 30, 2))
    stripes = int(rng.integers(2, 5))
    edges = np.sort(rng.choice(np.arange(1, w), stripes - 1, replace=False)) if w > stripes else np.arange(1, stripes)
    stripe = np.searchsorted(edges, np.arange(w), side='right')
    surfaces = rng.normal(scale=0.3, size=(int(rng.integers(1, stripes + 1)), 2))
    surface = rng.integers(0, len(surfaces), stripes)
    rows, cols = np.mgrid[0:h, 0:w]
    x, y = (cols - w / 2) * 0.02, (rows - h / 2) * 0.02
    slope = surfaces[surface[stripe]]
    z = 2.0 + slope[..., 0] * x + slope[..., 1] * y + rng.normal(scale=rng.uniform(0, 0.01), size=(h, w))
    image = np.stack([x * z, y * z, z], -1)
    valid = rng.random((h, w)) < 0.95
    image[~valid] = np.nan
    neighbours = grid_neighbours(image, valid)
    search = np.ascontiguousarray(image[valid].T)
    region = np.broadcast_to(stripe, (h, w))[valid].astype(np.int64)
    region[rng.random(len(region)) < 0.05] = -1
    found = [fit_columns(np.compress(region == j, search, axis=1)) for j in range(stripes)]
    tolerance = float(rng.uniform(0.003, 0.03)) if rng.random() < 0.5 else rng.uniform(0.003, 0.03, search.shape[1])
    return search, region, found, tolerance, neighbours


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_merge_test_keeps_the_numpy_merges(seed, along_rays):
    """The coplanar merge with its fits and per-pair tests compiled (kernels.fit_members, kernels.merge_test) merges
    the same regions into the same planes as the numpy fits and tests (to the fits' rounding; an eigenvector's sign is
    arbitrary); with the tolerance across the planes, and along the rays (depth_quadratic: noise.ray_band)."""
    from plane_validation.core import kernels
    from plane_validation.core.search.connected import _merge_coplanar, _merge_coplanar_numpy
    search, region, found, tolerance, neighbours = _stripes_case(seed)
    rng = np.random.default_rng(seed)
    ray = np.append(rng.normal(size=3) * 5, rng.uniform(0.05, 0.9)) if along_rays else kernels.NO_RAY
    same_merges(_merge_coplanar(search, region.copy(), found, tolerance, neighbours, None, ray),
                _merge_coplanar_numpy(search, region.copy(), found, tolerance, neighbours, None, ray))


def same_merges(got: tuple, ref: tuple) -> None:
    """The same regions (m,) and planes [(normal, offset)] from a coplanar merge and its reference, the planes to
    the fits' rounding (an eigenvector's sign is arbitrary)."""
    np.testing.assert_array_equal(got[0], ref[0])
    assert len(got[1]) == len(ref[1])
    for (normal, offset), (ref_normal, ref_offset) in zip(got[1], ref[1]):
        sign = np.sign(normal @ ref_normal)
        np.testing.assert_allclose(normal, sign * ref_normal, rtol=0, atol=1e-12)
        np.testing.assert_allclose(offset, sign * ref_offset, rtol=0, atol=1e-12)


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_compete_distances_match_numpy(seed):
    """The distances along each point's ray for border settling: as numpy's (its BLAS products may round the last
    bit otherwise), inf beyond the tolerance and in the last row alike."""
    from plane_validation.core import kernels
    from plane_validation.core.search.connected import GRAZING_DEG, _compete_distances_numpy
    search, region, found, tolerance, neighbours = _stripes_case(seed)
    viewpoint = np.random.default_rng(seed).normal(scale=0.1, size=3)
    planes = np.array([np.append(n, d) for n, d in found])
    got = kernels.compete_distances(search, planes, np.reshape(tolerance, -1).astype(float), viewpoint,
                                    float(np.cos(np.radians(GRAZING_DEG))))
    ref = _compete_distances_numpy(search, found, tolerance, viewpoint)
    np.testing.assert_array_equal(np.isinf(got), np.isinf(ref))
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-13)  # meters: a dot product near 0 cancels


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_plane_bands_and_band_counts_match_numpy(seed, per_point):
    """The confirmation's distances, sides, inlier and support bands, counts and MSAC costs as numpy computes them
    (its BLAS product may round the last bit otherwise), far-out rows (inf, NaN distances) included."""
    from plane_validation.core import kernels
    from plane_validation.core.search.fit import signed_distances
    from plane_validation.core.search.hypotheses import SUPPORT
    rng = np.random.default_rng(seed)
    m, h = int(rng.integers(1, 300)), int(rng.integers(1, 6))
    cols = np.ascontiguousarray(rng.normal(size=(3, m)))
    cols[:, rng.random(m) < 0.05] = 1.5e308  # far-out rows: inf or NaN distances
    normals = rng.normal(size=(h, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offsets = rng.normal(scale=0.2, size=h)
    tolerance = rng.uniform(0.05, 0.5, m) if per_point else float(rng.uniform(0.05, 0.5))
    dist, above = kernels.plane_bands(cols, normals, offsets)
    inliers, support, counts, cost = kernels.band_counts(dist, np.reshape(tolerance, -1).astype(float), SUPPORT)
    with np.errstate(over='ignore', invalid='ignore'):
        signed = signed_distances(cols, normals, offsets)
        ref = np.abs(signed)
        np.testing.assert_allclose(dist, ref, rtol=1e-12, atol=1e-13)
        np.testing.assert_array_equal(above, signed > 0)
        np.testing.assert_array_equal(inliers, ref <= tolerance)
        np.testing.assert_array_equal(support, ref <= SUPPORT * tolerance)
        np.testing.assert_array_equal(counts, np.count_nonzero(ref <= tolerance, axis=1))
        clipped = np.minimum(ref, tolerance)
        np.testing.assert_allclose(cost, np.einsum('ij,ij->i', clipped, clipped), rtol=1e-12)


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_triple_planes_match_numpy(seed):
    """Hypotheses through random triples, degenerate ones (repeated, collinear points) dropped: bit for bit numpy's."""
    from plane_validation.core import kernels
    from plane_validation.core.search.fit import MIN_SINE
    from plane_validation.core.search.hypotheses import _triple_planes_numpy
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 200))
    cols = np.ascontiguousarray(rng.normal(size=(3, n)))
    cols[:, rng.random(n) < 0.2] = cols[:, :1]  # repeated points
    line = rng.random(n) < 0.2
    cols[:, line] = np.outer([1.0, 2.0, 3.0], rng.normal(size=int(line.sum())))  # collinear ones
    idx = rng.integers(0, n, size=(int(rng.integers(0, 300)), 3))
    normals, offsets = kernels.triple_planes(cols, idx, MIN_SINE)
    ref_normals, ref_offsets = _triple_planes_numpy(cols, idx)
    np.testing.assert_array_equal(normals, ref_normals)
    np.testing.assert_array_equal(offsets, ref_offsets)


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_coherent_inliers_match_numpy(seed):
    """The count of inliers whose local normal agrees with a plane's (unknown ones counted) that lets the
    confirmation skip a hypothesis: numpy's count."""
    from plane_validation.core import kernels
    rng = np.random.default_rng(seed)
    m = int(rng.integers(0, 300))
    normals = rng.normal(size=(3, m))
    normals /= np.linalg.norm(normals, axis=0)
    normals[:, rng.random(m) < 0.2] = np.nan
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    inliers = rng.random(m) < 0.5
    bound = float(rng.uniform(0, 1))
    ref = np.count_nonzero(inliers & ~(np.abs(normal @ normals) < bound))
    assert kernels.coherent_inliers(inliers, normal, np.ascontiguousarray(normals), bound) == ref


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 200))
def test_largest_magnitude_matches_numpy(seed, n):
    """The cloud check's largest |coordinate| (NaN skipped, inf counted, NaN when every value is): numpy's."""
    from plane_validation.core import kernels
    from plane_validation.core.search.checks import largest_magnitude_numpy
    rng = np.random.default_rng(seed)
    values = rng.normal(scale=10.0 ** rng.integers(-3, 30), size=n)
    values[rng.random(n) < rng.uniform(0, 1)] = np.nan
    values[rng.random(n) < 0.05] = np.inf * rng.choice([-1, 1])
    got, ref = kernels.largest_magnitude(values), largest_magnitude_numpy(values)
    assert got == ref or (np.isnan(got) and np.isnan(ref))
