"""The per-frame verdict and index kernels (core/kernels.py, the 'verdict and indices per frame', 'verdict',
'verdict 5' and 'verdict: tent' blocks) against plain-numpy references: each must give numpy's values exactly, as the
verdict's and the indices' figures depend on them bit for bit (the tent's least squares up to rounding: the verdict
compares it with a limit only)."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from plane_validation.core import kernels
from plane_validation.core.leftover import _row_args, leftover_best_numpy, leftover_rows_numpy
from plane_validation.core.ransac import Plane, Segmentation

SETTINGS = settings(max_examples=80, deadline=None)


def _values(seed: int, n: int, kind: int) -> np.ndarray:
    """n float64 values: spread over many magnitudes, rounded (many ties), signed zeros and infinities, or small
    integers."""
    rng = np.random.default_rng(seed)
    if kind == 0:
        return rng.normal(size=n) * 10.0 ** rng.integers(-300, 300)
    if kind == 1:
        return np.round(rng.normal(size=n), 1)
    if kind == 2:
        return rng.choice([-0.0, 0.0, 1.0, -1.0, np.inf, -np.inf, 5e-324, -5e-324, 1e308], n)
    return rng.integers(-3, 3, n).astype(np.float64)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 2500), st.integers(0, 3))
def test_sorted_order_is_the_stable_argsort(seed, n, kind):
    values = _values(seed, n, kind)
    np.testing.assert_array_equal(kernels.sorted_order(values), np.argsort(values, kind='stable'))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 2500), st.integers(0, 40), st.integers(0, 3))
def test_sorted_order_keeps_ties_in_order_within_buckets(seed, n, copies, nans):
    """Spread values with a few copies of one (up to the buckets' limit and past it): ties stay in input order. A NaN
    is outside the contract, but must not be written outside the buckets: then a permutation, the numbers sorted."""
    rng = np.random.default_rng(seed)
    values = rng.uniform(-1.0, 1.0, n)
    values[rng.integers(0, n, copies)] = values[rng.integers(0, n)]  # copies of one value, scattered
    values[rng.integers(0, n, nans)] = np.nan
    order = kernels.sorted_order(values)
    if not nans:
        np.testing.assert_array_equal(order, np.argsort(values, kind='stable'))
    np.testing.assert_array_equal(np.sort(order), np.arange(n))
    numbers = values[order][~np.isnan(values[order])]
    assert (np.diff(numbers) >= 0).all()


@SETTINGS
@given(st.floats(1e-12, 1e6), st.integers(0, 10**6), st.integers(-3, 3))
def test_floor_quotient_is_floor_division(b, k, ulps):
    """Quotients at and a few units in the last place around whole numbers, where the rounded quotient's floor and
    Python's floor division part."""
    a = float(k) * b
    for _ in range(abs(ulps)):
        a = np.nextafter(a, np.inf if ulps > 0 else -np.inf)
    a = max(a, 0.0)
    assert kernels._floor_quotient(a, b) == a // b


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 3000), st.integers(0, 3), st.floats(0, 1), st.floats(0, 1))
def test_order_statistics_are_those_of_a_partition(seed, n, kind, low, high):
    values = _values(seed, n, kind)
    if kind == 3 and seed % 5 == 0:
        values[seed % n] = np.nan  # a NaN: the buffers step aside for np.partition
    a0 = int(low * 0.05 * (n - 1))
    b0 = n - 1 - int(high * 0.05 * (n - 1))
    a0, b0 = min(a0, b0), max(a0, b0)
    a1, b1 = min(a0 + 1, n - 1), min(b0 + 1, n - 1)
    ordered = np.sort(values)  # NaN last, as np.partition puts it
    got = kernels.order_statistics(values, a0, a1, b0, b1)
    np.testing.assert_array_equal(np.array(got), ordered[[a0, a1, b0, b1]])


def test_order_statistics_far_from_the_ends_partition():
    values = np.random.default_rng(0).normal(size=1000)
    ordered = np.sort(values)
    assert kernels.order_statistics(values, 100, 101, 500, 900) == tuple(ordered[[100, 101, 500, 900]])


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 6), st.integers(0, 3000))
def test_plane_samples_gather_and_centre_as_numpy(seed, k, n):
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(n + 1, 3)) * 10 ** rng.uniform(-3, 6) + rng.normal(size=3) * 1e3
    parts = [rng.integers(0, n + 1, rng.integers(0, 500)) for _ in range(k)]
    bounds = np.concatenate([[0], np.cumsum([len(p) for p in parts])]).astype(np.int64)
    rows = np.concatenate(parts).astype(np.int64) if parts else np.zeros(0, np.int64)
    gathered, centres, centred = kernels.plane_samples(points, rows, bounds)
    np.testing.assert_array_equal(gathered, points[rows])
    for j, part in enumerate(parts):
        if len(part) == 0:
            np.testing.assert_array_equal(centres[j], 0.0)
            continue
        inl = np.take(points, part, axis=0)
        mean = inl.mean(axis=0)
        np.testing.assert_array_equal(centres[j], mean)  # bit for bit: numpy sums the first axis row by row
        np.testing.assert_array_equal(centred[bounds[j]:bounds[j + 1]], inl - mean)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 300), st.integers(1, 40), st.floats(0, 1))
def test_beyond_rows_are_numpys_strided_finite_rows(seed, n, step, holes):
    """beyond_rows against the strided rows numpy keeps: NaN and inf coordinates, and sums too large for a float."""
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3))
    pts[rng.random(n) < holes, rng.integers(0, 3)] = rng.choice([np.nan, np.inf, -np.inf])
    pts[rng.random(n) < 0.05] = 1e308  # finite coordinates whose sum is not
    labels = rng.integers(-1, 5, n).astype(np.int32)
    cloud, kept = kernels.beyond_rows(pts, step, labels)
    with np.errstate(over='ignore'):  # the sums too large for a float are the point
        finite = np.isfinite(pts[::step].sum(axis=1))
    np.testing.assert_array_equal(cloud, pts[::step][finite])
    np.testing.assert_array_equal(kept, labels[::step][finite])


def _tent_fit_numpy(u, v, w, angles):
    """tent_fit by np.linalg.lstsq: w = a + b d, d the distance to the nearest edge of the turned bounding box."""
    best = np.inf
    for k in range(angles):
        theta = 0.5 * np.pi * k / angles
        a, b = u * np.cos(theta) + v * np.sin(theta), v * np.cos(theta) - u * np.sin(theta)
        d = np.minimum(np.minimum(a - a.min(), a.max() - a), np.minimum(b - b.min(), b.max() - b))
        design = np.column_stack([np.ones_like(d), d])
        coef, *_ = np.linalg.lstsq(design, w, rcond=None)
        best = min(best, float(np.mean((w - design @ coef) ** 2)))
    return best


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(3, 400), st.integers(1, 16), st.booleans())
def test_tent_fit_matches_least_squares(seed, n, angles, tent):
    rng = np.random.default_rng(seed)
    u, v = rng.uniform(-6, 6, n), rng.uniform(-4, 4, n)
    w = rng.normal(0, 0.02, n) + (0.05 * np.minimum(6 - np.abs(u), 4 - np.abs(v)) if tent else 0.0)
    np.testing.assert_allclose(kernels.tent_fit(u, v, w, angles), _tent_fit_numpy(u, v, w, angles), rtol=1e-7,
                               atol=1e-14)


def test_tent_fit_finds_a_hip_roof_and_not_a_ridge_or_a_plane():
    """A hip roof turned by 30 degrees (a box direction the fit tries) is a tent up to its noise; a gable (one ridge)
    and a plane are not: their fit explains little more than their mean."""
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-6, 6, 2000), rng.uniform(-4, 4, 2000)
    noise = rng.normal(0, 0.01, 2000)
    hip = 0.05 * np.minimum(6 - np.abs(x), 4 - np.abs(y)) + noise
    turn = np.radians(30.0)
    u, v = x * np.cos(turn) - y * np.sin(turn), x * np.sin(turn) + y * np.cos(turn)
    assert kernels.tent_fit(u, v, hip, 12) < 1.1 * np.var(noise) < 0.2 * np.var(hip)
    gable = 0.05 * (4 - np.abs(y)) + noise
    assert kernels.tent_fit(x, y, gable, 12) > 0.3 * np.var(gable)
    assert kernels.tent_fit(x, y, noise, 12) > 0.99 * np.var(noise)
    assert np.isnan(kernels.tent_fit(u[:2], v[:2], hip[:2], 12))


def _segmentation(rng: np.random.Generator, n: int, k: int, quadratic: bool) -> Segmentation:
    """k random planes (unit normals) labelling random rows of n (others -1), t 0.05-0.5 m, either noise model."""
    normals = rng.normal(size=(k, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    labels = rng.integers(-1, k, n).astype(np.int32) if k else np.full(n, -1, np.int32)
    planes = tuple(Plane(normal=normals[j], offset=float(rng.normal()), inliers=np.flatnonzero(labels == j), rms=0.0)
                   for j in range(k))
    return Segmentation(labels, planes, float(rng.uniform(0.05, 0.5)), n, 'test',
                        noise_model='depth_quadratic' if quadratic else 'constant',
                        noise_reference=float(rng.uniform(0.5, 2.0)), viewpoint=tuple(rng.normal(size=3)))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 400), st.integers(1, 30), st.integers(0, 4), st.booleans(),
       st.booleans(), st.floats(0, 1))
def test_leftover_rows_are_numpys(seed, n, stride, k, quadratic, boxed, holes):
    """The strided finite rows in no plane and not within COVER t of a plane (inside its box when given), as numpy."""
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(n, 3)) * 2.0
    points[rng.random(n) < holes * 0.3] = np.nan
    seg = _segmentation(rng, n, k, quadratic)
    extents = None
    if boxed:
        centre = rng.normal(size=2 * k)
        extents = (rng.normal(size=(3, 2 * k)), centre - rng.uniform(0, 2, 2 * k), centre + rng.uniform(-0.5, 2, 2 * k))
    want = leftover_rows_numpy(points, seg.labels, stride, seg, extents)
    got = kernels.leftover_rows(points, seg.labels, stride, *_row_args(seg, extents))
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_allclose(got[1], want[1], rtol=1e-14)  # the squared range summed in one order or einsum's
    assert got[2:] == want[2:]


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(3, 300), st.integers(1, 40), st.integers(1, 12), st.booleans())
def test_leftover_best_is_numpys(seed, m, hypotheses, neighbours, rounded):
    """The best plane through nearby triples, as numpy's stable argsort picks the neighbours (rounded coordinates: many
    ties of distance, and degenerate triples)."""
    rng = np.random.default_rng(seed)
    sample = rng.normal(size=(m, 3))
    sample[:, 2] *= rng.uniform(0, 0.2)
    if rounded:
        sample = np.round(sample * 2) / 2
    t = rng.uniform(0, 0.3, m)
    size = min(neighbours + 1, m)
    first = rng.integers(0, m, hypotheses)
    picks = rng.integers(0, size, (hypotheses, 2))
    normal, offset, count = kernels.leftover_best(sample, t, first, picks, neighbours)
    want = leftover_best_numpy(sample, t, first, picks, neighbours)
    assert count == want[2]
    np.testing.assert_array_equal(normal, want[0])
    np.testing.assert_array_equal(offset, want[1])
