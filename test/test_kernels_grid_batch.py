"""The organized detect block 5 (core/kernels.py, ``# --- organized detect 5 ---``) against plain-numpy references, on
random inputs: a RANSAC batch on a sub-grid (and on a graph's points) drawn, fitted and scored in one call, every
stride-th valid row, and rows gathered less a centre. (The full-resolution labelling and grouping,
:func:`.kernels.grid_spread`, is checked in test_kernels.py against :func:`.grid.spread_grid_numpy`.)"""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from test_kernels_detect import _graph_with_walks, _grid
from test_kernels_search_loop import _planar_points, _scoring_case

from plane_validation.core import kernels
from plane_validation.core.search import hypotheses
from plane_validation.core.search.neighbours import Neighbours

SETTINGS = settings(max_examples=80, deadline=None)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans(), st.booleans(), st.sampled_from(['grid', 'graph']))
def test_batches_match_numpy(seed, with_normals, per_point, form):
    """Batches drawn from the generator (triples from all the points and near them on the sub-grid, or along the
    graph's walks), their planes and scores merged into the best so far in one call: the same draws, hypotheses,
    counts and order as the numpy triples, planes and scoring in float64, batch after batch."""
    neighbours = _grid(seed)[0] if form == 'grid' else _graph_with_walks(seed)
    rng = np.random.default_rng(seed)
    rest_idx = np.flatnonzero(rng.random(neighbours.n) < rng.uniform(0.5, 1.0))
    m = len(rest_idx)
    if m < 3:
        return
    cols = kernels.c_array(_planar_points(rng, m), np.float64)
    if rng.random() < 0.2:  # repeated points: degenerate triples, maybe a batch without any plane
        cols[:, :] = cols[:, :1]
    tolerance, point_normals, pick, head = _scoring_case(rng, m, per_point, with_normals)
    compiled = hypotheses._CompiledScores(cols, tolerance, point_normals, pick, head)
    reference = hypotheses._NumpyScores(cols, tolerance, point_normals, pick, head, np.float64)
    sampler, numpy_sampler = neighbours.sampler(rest_idx), Neighbours.sampler(neighbours, rest_idx)
    draws, reference_draws = np.random.default_rng(seed + 1), np.random.default_rng(seed + 1)
    for _ in range(int(rng.integers(1, 5))):
        count = int(rng.integers(1, 60))
        got = compiled.add_drawn(cols, draws, count, sampler)
        normals, offsets = hypotheses._triple_planes_numpy(
            cols, hypotheses._triples(cols, reference_draws, count, numpy_sampler))
        expected = reference.add(normals, offsets) if len(normals) else reference.counts()
        np.testing.assert_array_equal(got, expected)
        for a, b in zip(compiled.planes(), reference.planes()):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
        assert draws.random() == reference_draws.random()  # as many numbers drawn


@SETTINGS
@given(st.lists(st.booleans(), max_size=300), st.integers(1, 40))
def test_strided_rows_are_every_stride_th_valid_row(flags, stride):
    flags = np.array(flags, dtype=bool)
    got = kernels.strided_rows(flags, int(np.count_nonzero(flags)), stride)
    np.testing.assert_array_equal(got, np.flatnonzero(flags)[::stride])
    assert got.dtype == np.int64


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 200))
def test_columns_at_and_rows_less_are_the_rows_less_the_centre(seed, m):
    """numpy's gather and subtraction, bit for bit (NaN and infinite rows; a zero centre keeps -0.0): as columns, a
    transposed copy (columns_at), or as rows (rows_less), each C-ordered."""
    rng = np.random.default_rng(seed)
    values = rng.normal(scale=10.0 ** rng.integers(-3, 4), size=(int(rng.integers(1, 300)), 3))
    values[rng.random(len(values)) < 0.1] = np.nan
    values[rng.random(len(values)) < 0.05] = -np.inf
    values[rng.random(len(values)) < 0.05] = -0.0
    rows = rng.integers(0, len(values), m)
    center = rng.normal(size=3) if seed % 2 else np.zeros(3)
    want = values[rows] - center
    got = kernels.columns_at(values, rows, center)
    np.testing.assert_array_equal(got, np.ascontiguousarray(want.T))
    assert got.shape == (3, m) and got.flags.c_contiguous
    got = kernels.rows_less(values, rows, center)
    np.testing.assert_array_equal(got, want)
    assert np.array_equal(np.signbit(got), np.signbit(want))
    assert got.shape == (m, 3) and got.flags.c_contiguous
