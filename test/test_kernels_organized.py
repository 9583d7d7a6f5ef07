"""The organized detect kernels (core/kernels.py, the organized detect block) against their plain-numpy references, on
random sub-grids: a RANSAC run's plane (the best confirmed hypothesis by its region, then its refits) from one call,
border settling that works out only the distances it compares, a pair of touching regions tried as one surface in one
call, and the sub-grid's median from one selection."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from test_kernels_search import _stripes_case, same_merges
from test_kernels_search_loop import _NumpyGridRemaining, two_planes_grid

from plane_validation.core import kernels
from plane_validation.core.orientation import orientation
from plane_validation.core.search import hypotheses
from plane_validation.core.search.connected import GRAZING_DEG, _merge_coplanar, _merge_coplanar_numpy
from plane_validation.core.search.grid_build import median
from plane_validation.core.search.neighbours import settle_numpy
from plane_validation.core.search.neighbours_grid import GridNeighbours, _GridRemaining

SETTINGS = settings(max_examples=80, deadline=None)


class _NumpyLoops(_NumpyGridRemaining):
    """The grid's region rule by its numpy reference, run through the generic loops (no compiled whole plane)."""

    def refitted(self, *args):
        return None


def _sub_grid(rng: np.random.Generator, lidar: bool) -> tuple[GridNeighbours, np.ndarray, np.ndarray]:
    """A random sub-grid of points (n, 3) meters on two planes meeting along a column, with holes, unusable pixels,
    noise from none to several tolerances (so that regions fall apart into pieces and are joined through their
    support), local normals (some unknown) and, for a lidar-like image, bridges over runs of holes; and its points."""
    h, w, valid, pixel, node, points, normals = two_planes_grid(rng, 60, 0.5, 0.03)
    n = len(pixel)
    bridges = None
    if lidar:  # pairs of pixels, some across the seam, some without a point or repeated
        b = int(rng.integers(1, 3 * h))
        bridges = np.column_stack([rng.integers(0, h * w, b), rng.integers(0, h * w, b),
                                   (rng.random(b) < 0.2).astype(np.int64)]).astype(np.int64)
    neighbours = GridNeighbours(n=n, shape=(h, w), pixel=pixel, node=node, usable=valid & (rng.random(h * w) < 0.95),
                                normals=normals, bridges=bridges, wraps=lidar)
    return neighbours, points, normals


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans(), st.booleans())
def test_grid_plane_matches_the_numpy_loop(seed, per_point, lidar):
    """The plane, region and taken points of one compiled call are those of hypotheses.best_region's loop over the
    numpy region rule (Remaining.best, then Remaining.refit while the region grows)."""
    rng = np.random.default_rng(seed)
    neighbours, points, normals = _sub_grid(rng, lidar)
    rest = np.flatnonzero(rng.random(neighbours.n) < rng.uniform(0.5, 1.0))
    if len(rest) < 3:
        return
    cols = np.ascontiguousarray(points[rest].T)
    idx = rng.integers(0, len(rest), (int(rng.integers(1, 5)), 3))
    planes, offsets = kernels.triple_planes(cols, idx, 1e-6)
    if not len(planes):
        return
    scale = float(rng.uniform(0.005, 0.05))
    tolerance = scale * rng.uniform(0.5, 1.5, len(rest)) if per_point else scale
    point_normals = np.ascontiguousarray(normals[rest].T)
    got = hypotheses.best_region(cols, tolerance, planes, offsets, _GridRemaining(neighbours, rest), point_normals)
    ref = hypotheses.best_region(cols, tolerance, planes, offsets, _NumpyLoops(neighbours, rest),
                                 point_normals)
    np.testing.assert_array_equal(got[0], ref[0])
    assert got[1] == ref[1]
    np.testing.assert_array_equal(got[2], ref[2])
    np.testing.assert_array_equal(got[3], ref[3])


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2**32 - 1), st.booleans(), st.booleans())
def test_grid_settle_matches_the_numpy_settling(seed, per_point, ties):
    """Border settling with the distances worked out on demand gives the regions of the numpy settling over every
    distance (kernels.compete_distances), points at the viewpoint (NaN distances) included; with ``ties``, parallel
    planes at whole-number offsets from whole-number points, so that equal offers occur (the smaller index wins)."""
    rng = np.random.default_rng(seed)
    neighbours, points, _ = _sub_grid(rng, False)
    m = neighbours.n
    k = int(rng.integers(1, 5))
    if ties:
        points[:, 0] = rng.integers(0, 4, m)
    search = np.ascontiguousarray(points.T)
    viewpoint = np.array([0.5, 0.5, -1.0])
    search[:, rng.random(m) < 0.02] = viewpoint[:, None]
    planes = np.empty((k, 4))
    for j in range(k):  # planes near the points, so that many are within the tolerance of several
        normal = np.array([1.0, 0.0, 0.0]) if ties else np.array([0.0, 0.0, 1.0]) + rng.normal(scale=0.3, size=3)
        planes[j, :3] = normal / np.linalg.norm(normal)
        planes[j, 3] = -float(rng.integers(0, 4)) if ties else -planes[j, :3] @ points[rng.integers(0, m)]
    tolerance = rng.uniform(0.01, 0.2, m) if per_point else np.array([rng.uniform(0.01, 0.2)])
    if ties:
        tolerance *= 20.0
    region = rng.integers(0, k + 1, m)
    min_cos = float(np.cos(np.radians(GRAZING_DEG)))
    got = neighbours.settle_planes(search, planes, tolerance, viewpoint, min_cos, region.copy())
    dist = kernels.compete_distances(search, planes, tolerance, viewpoint, min_cos)
    np.testing.assert_array_equal(got, settle_numpy(dist, region.copy(), neighbours))


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 300))
def test_median_is_numpys(seed, n):
    """The sub-grid's median is np.median's number, with repeated values, infinities and NaN."""
    rng = np.random.default_rng(seed)
    values = rng.normal(size=n)
    if seed % 3 == 0:
        values = np.round(values, 1)
    if seed % 5 == 0:
        values[rng.integers(0, n)] = np.inf
    if seed % 7 == 0:
        values[rng.integers(0, n)] = np.nan
    expected = np.median(values)
    assert median(values) == expected or (np.isnan(expected) and np.isnan(median(values)))


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_merge_pair_is_its_parts(seed):
    """One call gives the pair's points (those of either region, ascending), their least-squares plane
    (kernels.fit_members) and merge_test's answer on it; without the test, the same points and plane."""
    search, region, found, tolerance, neighbours = _stripes_case(seed)
    touching = neighbours.contacts(region, len(found))
    if touching is None:
        return
    src, dst, a, b, pairs = touching
    i, j = (int(v) for v in np.divmod(pairs[0], len(found)))
    own = np.array([np.append(*found[i]), np.append(*found[j])])
    tol = np.reshape(tolerance, -1).astype(float)
    root = np.arange(len(found))
    normals = kernels.c_array(neighbours.normals, np.float64)
    args = (own, tol, src, dst, a, b, root, normals, 0.9, 0.95, 1.5)
    same, normal, offset, members = kernels.merge_pair(search, region, i, j, *args, True, kernels.NO_RAY)
    expected = np.flatnonzero((region == i) | (region == j))
    np.testing.assert_array_equal(members, expected)
    ref_normal, ref_offset = kernels.fit_members(search, expected)
    np.testing.assert_array_equal(normal, ref_normal)
    assert offset == ref_offset
    assert same == kernels.merge_test(search, expected, region, i, j, np.append(normal, offset), *args, kernels.NO_RAY)
    untested = kernels.merge_pair(search, region, i, j, *args, False, kernels.NO_RAY)
    assert untested[0] is False
    np.testing.assert_array_equal(untested[3], expected)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.sampled_from(['parallel', 'perpendicular']))
def test_merge_with_an_orientation_keeps_the_numpy_merges(seed, mode):
    """With an orientation constraint (tested between the fit and the merge test) the coplanar merge merges the same
    regions into the same planes as its numpy reference."""
    search, region, found, tolerance, neighbours = _stripes_case(seed)
    allows = orientation((0.0, 0.0, 1.0), 30.0, mode).allows
    same_merges(_merge_coplanar(search, region.copy(), found, tolerance, neighbours, allows),
                _merge_coplanar_numpy(search, region.copy(), found, tolerance, neighbours, allows))
