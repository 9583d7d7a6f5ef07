"""The organized search's per-plane kernels (core/kernels.py, the search loop block) against their plain-numpy
references, on random inputs: hypothesis scoring, the spread test, least-squares fits, and the best region of the
confirmed hypotheses with its refits on a sub-grid."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from plane_validation.core import kernels
from plane_validation.core.search import hypotheses
from plane_validation.core.search.fit import (
    degeneracy,
    degeneracy_numpy,
    fit_columns,
    refit_regions,
    refit_regions_numpy,
)
from plane_validation.core.search.neighbours import Remaining
from plane_validation.core.search.neighbours_grid import GridNeighbours, _GridRemaining, grid_region_numpy

SETTINGS = settings(max_examples=60, deadline=None)


def _planar_points(rng: np.random.Generator, n: int, planes: int = 3) -> np.ndarray:
    """(3, n) points on a few random planes with noise, and some clutter."""
    out = rng.normal(size=(3, n))
    which = rng.integers(0, planes + 1, n)
    for j in range(planes):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        u = np.cross(normal, rng.normal(size=3))
        u /= np.linalg.norm(u)
        v = np.cross(normal, u)
        on = which == j
        a, b = rng.uniform(-1, 1, (2, on.sum()))
        out[:, on] = (rng.normal(size=3)[:, None] * 0.3 + u[:, None] * a + v[:, None] * b
                      + normal[:, None] * rng.normal(scale=0.005, size=on.sum()))
    return out


def _scoring_case(rng: np.random.Generator, m: int, per_point: bool, with_normals: bool
                  ) -> tuple[float | np.ndarray, np.ndarray | None, np.ndarray, int]:
    """Random scoring arguments for m points: the tolerance (one, or per point), the points' normals (some unknown)
    or None, the subset scored and its head."""
    tolerance = rng.uniform(0.002, 0.05, m) if per_point else float(rng.uniform(0.002, 0.05))
    point_normals = None
    if with_normals:
        point_normals = rng.normal(size=(3, m))
        point_normals /= np.linalg.norm(point_normals, axis=0)
        point_normals[:, rng.random(m) < 0.2] = np.nan
    pick = rng.permutation(m)[:int(rng.integers(3, m + 1))]
    return tolerance, point_normals, pick, int(rng.integers(1, len(pick) + 1))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans(), st.booleans())
def test_score_hypotheses_matches_numpy(seed, with_normals, per_point):
    """Batches of hypotheses scored on a subset (first on its head, the rest only for those that could still reach
    the CONFIRM best) and merged into the best so far: the same hypotheses, counts and order as the numpy scoring in
    float64."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(20, 3000))
    cols = _planar_points(rng, m)
    tolerance, point_normals, pick, head = _scoring_case(rng, m, per_point, with_normals)
    ordered = kernels.c_array(cols, np.float64)
    compiled = hypotheses._CompiledScores(ordered, tolerance, point_normals, pick, head)
    reference = hypotheses._NumpyScores(cols, tolerance, point_normals, pick, head, np.float64)
    for _ in range(int(rng.integers(1, 5))):
        idx = rng.integers(0, m, (int(rng.integers(1, 40)), 3))
        normals, offsets = kernels.triple_planes(ordered, idx, 1e-6)
        if not len(normals):
            continue
        got, ref = compiled.add(normals, offsets), reference.add(normals, offsets)
        np.testing.assert_array_equal(got, ref)
        for a, b in zip(compiled.planes(), reference.planes()):
            np.testing.assert_array_equal(a, b)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.sampled_from(['plane', 'line', 'point', 'outlier', 'cloud', 'few']))
def test_spread_test_matches_numpy(seed, kind):
    """Why no plane fits (identical, almost identical, collinear points, or None) as the numpy test says, on planes,
    lines, repeated points, a line with one far outlier, clouds and a handful of points."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 60)) if kind == 'few' else int(rng.integers(3, 3000))
    t = rng.normal(size=n)
    if kind == 'plane':
        cols = np.array([t, rng.normal(size=n), np.zeros(n)])
    elif kind in ('line', 'outlier'):
        cols = np.array([t, 2 * t, -t])
        if kind == 'outlier':
            cols[:, int(rng.integers(0, n))] = [3e38, 0.0, 0.0]
    elif kind == 'point':
        cols = np.tile(rng.normal(size=(3, 1)), n)
        if rng.random() < 0.5:
            cols[:, int(rng.integers(0, n))] += 1.0
    else:
        cols = rng.normal(size=(3, n))
    assert degeneracy(cols) == degeneracy_numpy(cols)


def _same_plane(a: tuple, b: tuple) -> None:
    """Two fits (normal, offset) are one plane (the sign of an eigenvector is arbitrary)."""
    sign = np.sign(a[0] @ b[0])
    np.testing.assert_allclose(a[0], sign * b[0], atol=1e-9)
    np.testing.assert_allclose(a[1], sign * b[1], atol=1e-9)


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_fits_match_numpy(seed):
    """The compiled least-squares fits (of listed points, of a mask, of every region in one pass) give numpy's planes,
    to rounding."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(3, 2000))
    cols = _planar_points(rng, m, 1) + rng.normal(size=(3, 1)) * 10
    members = np.flatnonzero(rng.random(m) < 0.7)
    if len(members) >= 3:
        _same_plane(kernels.fit_members(cols, members), fit_columns(cols[:, members].copy()))
        mask = np.zeros(m, bool)
        mask[members] = True
        _same_plane(kernels.fit_mask(cols, mask), fit_columns(cols[:, members].copy()))
    k = int(rng.integers(1, 6))
    region = rng.integers(-1, k, m)
    found = [(np.array([0.0, 0.0, 1.0]), float(j)) for j in range(k)]
    refits = zip(refit_regions(cols, region, found), refit_regions_numpy(cols, region, found))
    for j, (got, ref) in enumerate(refits):
        if np.count_nonzero(region == j) >= 3:
            _same_plane(got, ref)
        else:  # too few points: the plane kept as it was
            assert got is found[j] and ref is found[j]


class _NumpyGridRemaining(_GridRemaining):
    """The grid's region rule with its numpy reference: the generic loops of :class:`Remaining` over it."""

    def keep(self, mask, normal, support, above):
        return grid_region_numpy(self.neighbours, self.rest_idx, mask, normal, support, above)


def two_planes_grid(rng: np.random.Generator, most: int, kept: float, noise: float) -> tuple:
    """A random h x w image (3 to ``most`` pixels each way, a share of at least ``kept`` valid) of points on two
    planes meeting along a column, noise up to ``noise`` meters, with local normals (a tenth unknown): h, w, the valid
    flags (h * w,), their flat pixels (n,), each pixel's point (h * w,; -1: none), the points (n, 3), the normals."""
    h, w = (int(v) for v in rng.integers(3, most, 2))
    valid = rng.random(h * w) < rng.uniform(kept, 1.0)
    pixel = np.flatnonzero(valid)
    n = len(pixel)
    node = np.full(h * w, -1, np.int64)
    node[pixel] = np.arange(n)
    r, c = np.divmod(pixel, w)
    split = int(rng.integers(0, w + 1))
    z = np.where(c < split, 1.0 + 0.01 * r, 1.5 - 0.02 * c) + rng.normal(scale=rng.uniform(0.0, noise), size=n)
    points = np.column_stack([c * 0.05, r * 0.05, z])
    normals = np.where((c < split)[:, None], [0.0, -0.2, 1.0], [0.4, 0.0, 1.0]) + rng.normal(scale=0.2, size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    normals[rng.random(n) < 0.1] = np.nan
    return h, w, valid, pixel, node, points, normals


def _grid_search(seed: int):
    """A random sub-grid of points on a few planes with holes, unusable pixels and bridges, its region rule over a
    random share of its points, those points (3, r) and a few plane hypotheses through them."""
    rng = np.random.default_rng(seed)
    h, w, valid, pixel, node, points, normals = two_planes_grid(rng, 30, 0.6, 0.02)
    n = len(pixel)
    b = int(rng.integers(0, 6))
    bridges = np.column_stack([rng.integers(0, h * w, b), rng.integers(0, h * w, b), rng.integers(0, 2, b)])
    neighbours = GridNeighbours(n=n, shape=(h, w), pixel=pixel, node=node, usable=valid & (rng.random(h * w) < 0.95),
                                normals=normals, bridges=bridges.astype(np.int64) if b else None)
    rest = np.flatnonzero(rng.random(n) < 0.9)
    cols = np.ascontiguousarray(points[rest].T)
    idx = rng.integers(0, len(rest), (int(rng.integers(1, 6)), 3)) if len(rest) else np.zeros((0, 3), np.int64)
    planes = kernels.triple_planes(cols, idx, 1e-6)
    tolerance = np.array([rng.uniform(0.005, 0.05)])
    return neighbours, rest, cols, planes, tolerance, np.ascontiguousarray(normals[rest].T)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_grid_best_and_refit_match_numpy(seed, bound):
    """The confirmed hypothesis whose region is largest, with its region and the points it takes, from one compiled
    call (kernels.grid_plane without refits), and a refit on that region (kernels.grid_refit): as the generic loops
    find them over the numpy region rule (with and without the coherent-inlier bound)."""
    neighbours, rest, cols, (normals, offsets), tolerance, point_normals = _grid_search(seed)
    if not len(normals):
        return
    compiled = _GridRemaining(neighbours, rest)
    reference = _NumpyGridRemaining(neighbours, rest)
    point_normals = point_normals if bound else None
    args = (cols, tolerance, normals, offsets, point_normals, hypotheses.SUPPORT, hypotheses._COHERENT_BOUND)
    winner, region, taken = compiled.best(*args)
    ref_winner, ref_region, ref_taken = Remaining.best(reference, *args)
    assert winner == ref_winner
    np.testing.assert_array_equal(region, ref_region)
    np.testing.assert_array_equal(taken, ref_taken)
    if np.count_nonzero(region):
        got = compiled.refit(cols, tolerance, region, hypotheses.SUPPORT)
        ref = Remaining.refit(reference, cols, tolerance, region, hypotheses.SUPPORT)
        np.testing.assert_array_equal(got[0], ref[0])
        assert got[1] == ref[1]
        np.testing.assert_array_equal(got[2], ref[2])
        np.testing.assert_array_equal(got[3], ref[3])
