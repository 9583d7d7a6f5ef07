"""Labelled points as clusters, for the validity indices (:mod:`.indices`): the input checked, the points sorted
by cluster (the unassigned points, any negative label, one cluster), per-cluster censuses and stratified samples.
Points (N, 3) in any one unit (meters for sensors); labels (N,) integers, -1 unassigned."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import kernels
from .plane_silhouette import dense_codes
from .ransac import as_points, finite_rows

__all__ = ['Clusters', 'Coded', 'Census', 'as_clusters', 'check_labelled', 'coded', 'code_labels', 'take_census',
           'sorted_by_cluster', 'stratified', 'stratified_census', 'stratified_coded']


@dataclass(frozen=True, eq=False)
class Clusters:
    """Finite points grouped by cluster, contiguous in ``points``.

    points: (n, 3) float64 sorted by cluster; codes: (n,) cluster index 0..K-1 of each row;
    starts, sizes: (K,) first row and row count of each cluster; ids: (K,) label of each cluster
    (-1 for the unassigned one, which is cluster 0 when present); order: (n,) input row of each
    sorted row (an index into the original, unfiltered input).
    """

    points: np.ndarray
    codes: np.ndarray
    starts: np.ndarray
    sizes: np.ndarray
    ids: np.ndarray
    order: np.ndarray

    @property
    def k(self) -> int:
        return len(self.sizes)

    @property
    def n(self) -> int:
        return len(self.points)

    def members(self, c: int) -> np.ndarray:
        """(n_c, 3) points of cluster ``c``."""
        return self.points[self.starts[c]:self.starts[c] + self.sizes[c]]

    def planes_only(self) -> Clusters:
        """The same clusters without the unassigned one (label -1)."""
        if self.k == 0 or self.ids[0] >= 0:
            return self
        cut = int(self.sizes[0])
        return Clusters(self.points[cut:], self.codes[cut:] - 1, self.starts[1:] - cut, self.sizes[1:],
                         self.ids[1:], self.order[cut:])

    def subset(self, rows: np.ndarray) -> Clusters:
        """Clusters restricted to the sorted rows ``rows`` (ascending); every cluster must keep a row."""
        codes = self.codes[rows]
        sizes = np.bincount(codes, minlength=self.k)
        starts = np.cumsum(sizes) - sizes
        return Clusters(np.take(self.points, rows, axis=0), codes, starts, sizes, self.ids, self.order[rows])


def check_labelled(points: np.ndarray, labels: np.ndarray, convert: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Validate shapes: points (N, 3) real, labels (N,) integer-valued. Returns them as float64 and
    int64 (``convert`` False: signed integer labels as they are)."""
    pts = np.asarray(points)
    if pts.dtype.kind not in 'fiu' or pts.ndim != 2 or pts.shape[1] != 3:  # as detect_planes takes them
        raise ValueError(f'points must be a real array of shape (N, 3), got {pts.dtype} {pts.shape}')
    if isinstance(points, np.ma.MaskedArray):
        pts = as_points(points)  # its masked rows NaN
    lab = np.asarray(labels)
    if lab.ndim != 1 or len(lab) != len(pts):
        raise ValueError(f'labels must have shape ({len(pts)},), got {lab.shape}')
    if lab.dtype.kind == 'f':
        if not np.all(np.isfinite(lab) & (lab == np.round(lab))):
            raise ValueError('labels must be integers')
    elif lab.dtype.kind not in 'iub':
        raise ValueError(f'labels must be integers, got dtype {lab.dtype}')
    if lab.dtype.kind in 'uf' and len(lab) and lab.max() > np.iinfo(np.int64).max:  # would wrap to negative
        raise ValueError(f'labels must fit in 64-bit signed integers, got {lab.max()}')
    return pts.astype(np.float64, copy=False), lab if lab.dtype.kind == 'i' and not convert else lab.astype(np.int64)


@dataclass(frozen=True, eq=False)
class Coded:
    """Finite rows in input order with their cluster code: pts (N, 3) float64 all input rows; keep
    (n,) finite row numbers; codes (n,) cluster 0..K-1 of each; ids (K,) ascending labels; sizes
    (K,); grouped (n,) positions in ``keep`` cluster by cluster, ascending within each, cluster c's
    being ``grouped[bounds[c]:bounds[c + 1]]``; bounds (K + 1,)."""

    pts: np.ndarray
    keep: np.ndarray
    codes: np.ndarray
    ids: np.ndarray
    sizes: np.ndarray
    grouped: np.ndarray
    bounds: np.ndarray

    def members(self, c: int) -> np.ndarray:
        """Positions in ``keep`` of cluster c, ascending."""
        return self.grouped[self.bounds[c]:self.bounds[c + 1]]


def coded(points: np.ndarray, labels: np.ndarray) -> Coded:
    """Drop non-finite rows, merge negative labels into -1 and number the clusters."""
    return code_labels(*check_labelled(points, labels))


def code_labels(pts: np.ndarray, lab: np.ndarray) -> Coded:
    """coded of checked input: pts (N, 3) float64, lab (N,) int64."""
    keep = np.flatnonzero(finite_rows(pts))
    ids, codes = dense_codes(np.maximum(lab[keep], -1)) if len(keep) else (np.empty(0, np.int64),) * 2
    grouped, bounds = kernels.group_by_label(codes, len(ids))
    return Coded(pts, keep, codes, ids, np.diff(bounds), grouped, bounds)


@dataclass(frozen=True, eq=False)
class Census:
    """Checked input and its clusters, counted in one streaming pass: pts (N, 3) C-ordered float64; lab
    (N,) integers; compact (N,) int32 each row's label (see kernels.label_census), to be used only with
    a table; n finite rows, n_assigned of them labelled >= 0; ids (K,)
    ascending cluster labels (negative ones merged into -1); sizes (K,) finite rows per cluster;
    table (span,) the cluster of each label from ``low`` on, -1 for none (empty when the labels
    lie too far apart for a table)."""

    pts: np.ndarray
    lab: np.ndarray
    compact: np.ndarray
    n: int
    n_assigned: int
    ids: np.ndarray
    sizes: np.ndarray
    low: int
    table: np.ndarray


def take_census(points: np.ndarray, labels: np.ndarray, finite: bool = False) -> Census:
    """Check the input and count its clusters (see Census); ``finite``: every row of ``points`` is known to be
    finite (a frame's valid rows), so that the count reads only the labels."""
    pts, lab = check_labelled(points, labels, convert=False)
    pts = kernels.c_array(pts, np.float64)
    lab = kernels.c_array(lab, lab.dtype if lab.dtype in (np.int32, np.int64) else np.int64)
    compact = np.empty(len(lab), np.int32)
    n, n_assigned, low, count = kernels.label_census(pts, lab, compact, bool(finite))
    present = count > 0
    if n and not len(count):  # labels too far apart for a table: numbered by a sort
        ids, codes = dense_codes(np.maximum(lab[finite_rows(pts)], -1).astype(np.int64))
        return Census(pts, lab, compact, n, n_assigned, ids, np.bincount(codes, minlength=len(ids)), low, count)
    return Census(pts, lab, compact, n, n_assigned, np.flatnonzero(present) + low, count[present], low,
                   np.where(present, np.cumsum(present) - 1, -1))


def stratified_census(census: Census, total: int, rng: np.random.Generator) -> Clusters:
    """The same sample as :func:`stratified_coded` of the same input (same rows for the same generator
    state), picked in one streaming pass over the rows (needs ``census.table``)."""
    alloc = _allocate(census.sizes, total)
    ranks = np.concatenate([np.sort(rng.choice(int(size), int(take), replace=False))
                            for size, take in zip(census.sizes, alloc)])
    bounds = np.zeros(len(alloc) + 1, np.int64)
    bounds[1:] = np.cumsum(alloc)
    rows = kernels.rows_at_ranks(census.compact, census.low, census.table, ranks, bounds)
    return Clusters(np.take(census.pts, rows, axis=0), np.repeat(np.arange(len(alloc)), alloc), bounds[:-1], alloc,
                     census.ids, rows)


def sorted_by_cluster(coded: Coded, positions: np.ndarray | None = None) -> Clusters:
    """Clusters of the rows ``positions`` (into ``coded.keep``; all when None), which must be
    grouped by cluster and ascending within each."""
    if positions is None:
        positions = coded.grouped
    codes = coded.codes[positions]
    sizes = np.bincount(codes, minlength=len(coded.ids))
    starts = (np.cumsum(sizes) - sizes).astype(np.int64)
    rows = coded.keep[positions]
    return Clusters(np.take(coded.pts, rows, axis=0), codes, starts, sizes, coded.ids, rows)


def as_clusters(points: np.ndarray, labels: np.ndarray) -> Clusters:
    """Drop non-finite rows, merge negative labels into -1 and sort the rows by cluster."""
    return sorted_by_cluster(coded(points, labels))


def _allocate(sizes: np.ndarray, total: int) -> np.ndarray:
    """(K,) sample size per cluster: a floor of min(N_h, max(2, total // (4K))) points, the rest
    of ``total`` shared in proportion to what each cluster has left (largest remainders).
    Requires total < sizes.sum()."""
    k = len(sizes)
    floor = np.minimum(sizes, max(2, total // (4 * k)))
    rest = total - int(floor.sum())
    if rest <= 0:
        return floor
    room = sizes - floor
    raw = rest * room / room.sum()
    take = np.floor(raw).astype(np.int64)
    short = rest - int(take.sum())
    if short > 0:
        take[np.argsort(take - raw, kind='stable')[:short]] += 1
    return floor + np.minimum(take, room)


def stratified(cl: Clusters, total: int, rng: np.random.Generator) -> Clusters:
    """A stratified random sample (without replacement) of about ``total`` rows of ``cl``."""
    alloc = _allocate(cl.sizes, total)
    rows = np.concatenate([cl.starts[c] + rng.choice(int(cl.sizes[c]), int(alloc[c]), replace=False)
                           for c in range(cl.k)])
    return cl.subset(np.sort(rows))


def stratified_coded(coded: Coded, total: int, rng: np.random.Generator) -> Clusters:
    """The same sample as ``stratified(sorted_by_cluster(coded), total, rng)`` (same rows for
    the same generator state), without gathering and sorting every row first."""
    alloc = _allocate(coded.sizes, total)
    positions = np.concatenate([coded.members(c)[np.sort(rng.choice(int(coded.sizes[c]), int(alloc[c]),
                                                                     replace=False))]
                                for c in range(len(coded.ids))])
    return sorted_by_cluster(coded, positions)
