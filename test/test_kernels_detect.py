"""The detect block's compiled kernels (core/kernels.py, ``# --- detect ---``) against their plain-numpy references,
on random inputs."""
from __future__ import annotations

import dataclasses

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from test_kernels import _graph_case, _grid_case

from plane_validation.core import kernels
from plane_validation.core.regions import _neighbours_numpy
from plane_validation.core.search.checks import finite_extent, finite_rows, largest_magnitude_numpy
from plane_validation.core.search.neighbours import Neighbours
from plane_validation.core.search.neighbours_grid import GridNeighbours

SETTINGS = settings(max_examples=150, deadline=None)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 60))
def test_finite_extent_matches_numpy(seed, n):
    """Finite rows, their count and the largest |coordinate| not NaN, with NaN, +-inf and huge values mixed in."""
    rng = np.random.default_rng(seed)
    points = rng.normal(scale=10.0 ** rng.integers(-3, 30), size=(n, 3))
    for value in (np.nan, np.inf, -np.inf, 1e300):
        points[rng.random((n, 3)) < rng.uniform(0, 0.3)] = value
    finite, count, largest = kernels.finite_extent(points)
    expected = np.isfinite(points).all(axis=1)
    np.testing.assert_array_equal(finite, expected)
    assert count == int(np.count_nonzero(expected))
    reference = largest_magnitude_numpy(points.reshape(-1)) if n else np.nan
    assert largest == reference or (np.isnan(largest) and np.isnan(reference))
    # the checked form: the same answer for a layout the kernel does not take (a column-ordered copy)
    rows, big = finite_extent(np.asfortranarray(points))
    np.testing.assert_array_equal(rows, finite_rows(points))
    assert big == reference or (np.isnan(big) and np.isnan(reference))


def _grid(seed: int) -> tuple[GridNeighbours, np.ndarray, int]:
    """test_kernels' random sub-grid (holes, unusable pixels, bridges some across the seam), maybe wrapping, and
    regions on it."""
    rng = np.random.default_rng(seed)
    neighbours = dataclasses.replace(_grid_case(seed)[0], wraps=bool(rng.random() < 0.3))
    k = int(rng.integers(1, 6))
    return neighbours, rng.integers(-1, k, neighbours.n), k


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_grid_contacts_match_numpy(seed):
    """The neighbour pairs joining two regions, in order, their regions and the touching pairs of regions."""
    neighbours, region, k = _grid(seed)
    got = neighbours.contacts(region, k)
    expected = Neighbours.contacts(neighbours, region, k)
    assert (got is None) == (expected is None)
    if expected is not None:
        for a, b in zip(got, expected):
            np.testing.assert_array_equal(a, b)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.sampled_from([np.int32, np.int64]))
def test_label_rows_match_numpy(seed, dtype):
    """Each label's rows ascending, where each starts, and the squared residuals in the same order: their mean is
    numpy's mean of the gathered squares to the bit."""
    rng = np.random.default_rng(seed)
    n, k = int(rng.integers(0, 500)), int(rng.integers(0, 6))
    labels = rng.integers(-1, k + 2, n).astype(dtype)  # labels beyond k-1 are left out
    residual = rng.random(n) * 0.01
    rows, bounds, squares = kernels.label_rows(labels, k, residual)
    order = np.argsort(labels, kind='stable')
    for j in range(k):
        members = order[labels[order] == j]
        np.testing.assert_array_equal(rows[bounds[j]:bounds[j + 1]], members)
        if len(members):
            assert np.mean(squares[bounds[j]:bounds[j + 1]]) == np.mean(residual[members] ** 2)
    assert bounds[k] == len(rows) == np.count_nonzero((labels >= 0) & (labels < k))


def _graph_with_walks(seed: int):
    case = _graph_case(seed)[0]
    return _neighbours_numpy(case.n, case.edges, case.normals)  # with its adjacency, which the walks take


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 70), st.sampled_from(['grid', 'graph']))
def test_samplers_match_numpy(seed, count, form):
    """The triples of nearby points of the grid (windows off the image or on holes: -1) and of the graph (walks; a
    point without neighbours stays put): the same draws from the generator, the same triples, as the numpy form
    (points no longer searched: -1)."""
    neighbours = _grid(seed)[0] if form == 'grid' else _graph_with_walks(seed)
    rng = np.random.default_rng(seed)
    rest_idx = np.flatnonzero(rng.random(neighbours.n) < 0.8)
    if len(rest_idx) == 0:
        return
    draws, reference = np.random.default_rng(seed + 1), np.random.default_rng(seed + 1)
    got = neighbours.sampler(rest_idx)(draws, count)
    expected = Neighbours.sampler(neighbours, rest_idx)(reference, count)
    np.testing.assert_array_equal(got, expected.reshape(-1, 3))
    assert draws.random() == reference.random()  # as many numbers drawn
