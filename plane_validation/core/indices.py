"""Cluster validity indices for detected planes (Lipnickas et al. 2014, sections 3.1-3.3).

numpy, scipy and the kernels of core/kernels.py; no ROS import. The planes found by sequential
RANSAC are treated as clusters: ``labels`` is an (N,) integer array with 0..k-1 for plane points
and -1 for unassigned points (any negative label counts as unassigned). Distances are Euclidean,
in the unit of ``points``.

Conventions shared by every public function here:

* Rows of ``points`` with a NaN or infinite coordinate are dropped first, together with their
  labels; ``n_points`` counts the remaining (finite) rows.
* Except for GS_planes, the unassigned points form ONE extra cluster. Per-cluster arrays
  (:func:`cluster_diameters`, :func:`cluster_distances`) list clusters in ascending label order,
  so the unassigned cluster, when present, comes first (the order of ``np.unique(labels)``).
* Degenerate input never raises: fewer than two clusters gives Dunn 0.0, Davies-Bouldin (paper)
  inf, Davies-Bouldin (classic) 0.0 and silhouette/GS 0.0; GS_planes with fewer than two planes
  is 0.0. Only badly shaped input raises ``ValueError``.
"""
from __future__ import annotations

import contextlib
import contextvars
import functools
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError, cKDTree
from scipy.spatial.distance import cdist, pdist

from . import kernels
from .blas import single_blas_thread
from .plane_silhouette import dense_codes, plane_silhouette_of
from .ransac import as_points, check_flag, check_integer, finite_rows, generator

__all__ = [
    'ValidityIndices', 'validity_indices', 'dunn_index', 'davies_bouldin_index', 'davies_bouldin_classic',
    'silhouette_samples', 'silhouette_score', 'global_silhouette', 'cluster_diameters', 'cluster_distances',
    'diameter',
]

#: Clusters with at most this many points get their diameter by brute force, without a hull.
BRUTE_DIAMETER = 64
#: Hull vertex sets up to this size are searched by brute force; larger ones use box pruning.
BRUTE_PAIRS = 2048
#: Points per bucket when pruning a large diameter search (at least), and most buckets.
BUCKET = 32
MAX_BUCKETS = 1024


# --------------------------------------------------------------------------------------------
# Input handling


@dataclass(frozen=True, eq=False)
class _Clusters:
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

    def planes_only(self) -> _Clusters:
        """The same clusters without the unassigned one (label -1)."""
        if self.k == 0 or self.ids[0] >= 0:
            return self
        cut = int(self.sizes[0])
        return _Clusters(self.points[cut:], self.codes[cut:] - 1, self.starts[1:] - cut, self.sizes[1:],
                         self.ids[1:], self.order[cut:])

    def subset(self, rows: np.ndarray) -> _Clusters:
        """Clusters restricted to the sorted rows ``rows`` (ascending); every cluster must keep a row."""
        codes = self.codes[rows]
        sizes = np.bincount(codes, minlength=self.k)
        starts = np.cumsum(sizes) - sizes
        return _Clusters(np.take(self.points, rows, axis=0), codes, starts, sizes, self.ids, self.order[rows])


def _check(points: np.ndarray, labels: np.ndarray, convert: bool = True) -> tuple[np.ndarray, np.ndarray]:
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
class _Coded:
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


def _coded(points: np.ndarray, labels: np.ndarray) -> _Coded:
    """Drop non-finite rows, merge negative labels into -1 and number the clusters."""
    return _code(*_check(points, labels))


def _code(pts: np.ndarray, lab: np.ndarray) -> _Coded:
    """_coded of checked input: pts (N, 3) float64, lab (N,) int64."""
    keep = np.flatnonzero(finite_rows(pts))
    ids, codes = dense_codes(np.maximum(lab[keep], -1)) if len(keep) else (np.empty(0, np.int64),) * 2
    grouped, bounds = kernels.group_by_label(codes, len(ids))
    return _Coded(pts, keep, codes, ids, np.diff(bounds), grouped, bounds)


@dataclass(frozen=True, eq=False)
class _Census:
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


def _census(points: np.ndarray, labels: np.ndarray) -> _Census:
    """Check the input and count its clusters (see _Census)."""
    pts, lab = _check(points, labels, convert=False)
    pts = kernels.c_array(pts, np.float64)
    lab = kernels.c_array(lab, lab.dtype if lab.dtype in (np.int32, np.int64) else np.int64)
    compact = np.empty(len(lab), np.int32)
    n, n_assigned, low, count = kernels.label_census(pts, lab, compact)
    present = count > 0
    if n and not len(count):  # labels too far apart for a table: numbered by a sort
        ids, codes = dense_codes(np.maximum(lab[finite_rows(pts)], -1).astype(np.int64))
        return _Census(pts, lab, compact, n, n_assigned, ids, np.bincount(codes, minlength=len(ids)), low, count)
    return _Census(pts, lab, compact, n, n_assigned, np.flatnonzero(present) + low, count[present], low,
                   np.where(present, np.cumsum(present) - 1, -1))


def _stratified_census(census: _Census, total: int, rng: np.random.Generator) -> _Clusters:
    """The same sample as :func:`_stratified_coded` of the same input (same rows for the same generator
    state), picked in one streaming pass over the rows (needs ``census.table``)."""
    alloc = _allocate(census.sizes, total)
    ranks = np.concatenate([np.sort(rng.choice(int(size), int(take), replace=False))
                            for size, take in zip(census.sizes, alloc)])
    bounds = np.zeros(len(alloc) + 1, np.int64)
    bounds[1:] = np.cumsum(alloc)
    rows = kernels.rows_at_ranks(census.compact, census.low, census.table, ranks, bounds)
    return _Clusters(np.take(census.pts, rows, axis=0), np.repeat(np.arange(len(alloc)), alloc), bounds[:-1], alloc,
                     census.ids, rows)


def _sorted_by_cluster(coded: _Coded, positions: np.ndarray | None = None) -> _Clusters:
    """_Clusters of the rows ``positions`` (into ``coded.keep``; all when None), which must be
    grouped by cluster and ascending within each."""
    if positions is None:
        positions = coded.grouped
    codes = coded.codes[positions]
    sizes = np.bincount(codes, minlength=len(coded.ids))
    starts = (np.cumsum(sizes) - sizes).astype(np.int64)
    rows = coded.keep[positions]
    return _Clusters(np.take(coded.pts, rows, axis=0), codes, starts, sizes, coded.ids, rows)


def _clusters(points: np.ndarray, labels: np.ndarray) -> _Clusters:
    """Drop non-finite rows, merge negative labels into -1 and sort the rows by cluster."""
    return _sorted_by_cluster(_coded(points, labels))


# --------------------------------------------------------------------------------------------
# Diameters (exact, through convex hulls)


def _brute_max(p: np.ndarray) -> float:
    """Exact max pairwise distance of a small set p (m, 3), by pdist."""
    return float(pdist(p).max()) if len(p) > 1 else 0.0


def _kd_buckets(p: np.ndarray, size: int) -> np.ndarray:
    """Permutation of p's rows that groups them into spatially compact runs of ``size`` rows
    (median splits along the widest axis), so that run b is rows ``[b*size, (b+1)*size)``."""
    perm = np.arange(len(p))
    segments = [(0, len(p))]
    done = []
    while segments:
        nxt = []
        for lo, hi in segments:
            if hi - lo <= size:
                done.append((lo, hi))
                continue
            idx = perm[lo:hi]
            axis = int(np.argmax(np.ptp(p[idx], axis=0)))
            # split on a multiple of size so that every run but the last is full
            mid = lo + max(size, ((hi - lo) // 2) // size * size)
            part = np.argpartition(p[idx, axis], mid - lo - 1)
            perm[lo:hi] = idx[part]
            nxt += [(lo, mid), (mid, hi)]
        segments = nxt
    return perm


def _max_pair_distance(p: np.ndarray) -> float:
    """Exact diameter (max pairwise distance) of p (m, 3).

    Brute force up to ``BRUTE_PAIRS`` points; beyond, the points are bucketed (kd median splits)
    and only bucket pairs whose bounding boxes can be farther apart than the best pair found so
    far are compared, which keeps e.g. a 50k-point sphere (all points on the hull) fast.
    """
    m = len(p)
    if m <= BRUTE_PAIRS:
        return _brute_max(p)
    # lower bound by repeated farthest-point jumps (a double normal)
    best, i = 0.0, int(np.argmax(((p - p.mean(axis=0)) ** 2).sum(axis=1)))
    for _ in range(4):
        d = ((p - p[i]) ** 2).sum(axis=1)
        j = int(np.argmax(d))
        if d[j] <= best * best:
            break
        best, i = float(np.sqrt(d[j])), j
    size = max(BUCKET, -(-m // MAX_BUCKETS))
    q = p[_kd_buckets(p, size)]
    starts = np.arange(0, m, size)
    lo, hi = np.minimum.reduceat(q, starts), np.maximum.reduceat(q, starts)
    # farthest possible distance between two boxes, per pair of buckets
    span = np.maximum(hi[:, None, :] - lo[None, :, :], hi[None, :, :] - lo[:, None, :])
    upper = np.sqrt((span ** 2).sum(axis=2))
    for a in np.argsort(-upper.max(axis=1)):
        if upper[a].max() <= best:
            break
        cand = np.flatnonzero(upper[a] > best)
        cand = cand[cand >= a]  # each unordered pair once
        if len(cand) == 0:
            continue
        rows = (starts[cand][:, None] + np.arange(size)).ravel()
        rows = rows[rows < m]
        best = max(best, float(cdist(q[starts[a]:starts[a] + size], q[rows]).max()))
    return best


def _hull_vertices(p: np.ndarray) -> np.ndarray:
    """Indices of rows of p (m, 3) that include both ends of a diameter.

    3-D convex hull; when Qhull rejects the set as flat, the 2-D hull of its projection onto the
    two principal axes; when that is degenerate too (collinear), the two extremes along the main
    axis. Distances are later measured on the original 3-D rows.
    """
    try:
        return ConvexHull(p).vertices
    except (QhullError, ValueError):
        pass
    centred = p - p.mean(axis=0)
    _, sv, vt = np.linalg.svd(centred, full_matrices=False)
    if sv[0] == 0.0:  # all points coincide
        return np.array([0])
    if sv[1] > 1e-12 * sv[0]:
        try:
            return ConvexHull(centred @ vt[:2].T).vertices
        except (QhullError, ValueError):
            pass
    t = centred @ vt[0]
    return np.array([int(np.argmin(t)), int(np.argmax(t))])


def diameter(points: np.ndarray) -> float:
    """Exact diameter (max pairwise Euclidean distance) of one point set (m, 3); 0.0 for m < 2.

    Works in O(m log m) for typical clouds: only convex hull vertices can be diameter ends.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(p) <= BRUTE_DIAMETER:
        return _brute_max(p)
    return _max_pair_distance(p[_hull_vertices(p)])


def _diameters(cl: _Clusters) -> np.ndarray:
    return np.array([diameter(cl.members(c)) for c in range(cl.k)], dtype=np.float64)


def cluster_diameters(points: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """(K,) diameter of each cluster (max distance between two of its points), units of points.

    Clusters in ascending label order; all label -1 points form one cluster, listed first.
    A one-point cluster has diameter 0.
    """
    return _diameters(_clusters(points, labels))


# --------------------------------------------------------------------------------------------
# Distances between clusters (exact minimum point-to-point, through kd-trees)


def _box_distance(q: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(m,) distance of each row of q (m, 3) to the axis-aligned box [lo, hi]."""
    gap = np.maximum(lo - q, 0.0) + np.maximum(q - hi, 0.0)
    return np.sqrt((gap ** 2).sum(axis=1))


def _min_distance(small: np.ndarray, big: np.ndarray, t_small: cKDTree, t_big: cKDTree,
                  boxes: tuple[tuple[np.ndarray, np.ndarray], ...] | None = None) -> float:
    """Exact min distance between point sets ``small`` and ``big`` (both non-empty); ``boxes``:
    their (min, max) corners when known.

    A few alternating nearest-neighbour hops from spread-out seeds give an upper bound ``ub``
    achieved by a real pair; then only the points of ``small`` within ``ub`` of the bounding box
    of ``big`` are queried, with ``ub`` as the search radius.
    """
    seeds = small[np.linspace(0, len(small) - 1, min(len(small), 16)).astype(int)]
    ub = np.inf
    for _ in range(3):  # (an index == size: no neighbour at a finite distance, coordinates near 1e154+)
        d, j = t_big.query(seeds, k=1)
        ub = min(ub, float(d.min()))
        d, i = t_small.query(big[j[j < len(big)]], k=1)
        ub = min(ub, float(d.min(initial=np.inf)))
        seeds = small[np.unique(i[i < len(small)])]
        if len(seeds) == 0:
            break
    if ub == 0.0:
        return 0.0
    (s_lo, s_hi), (lo, hi) = boxes or ((small.min(axis=0), small.max(axis=0)), (big.min(axis=0), big.max(axis=0)))
    if np.linalg.norm(np.maximum(np.maximum(lo - s_hi, s_lo - hi), 0.0)) >= ub:  # boxes ub apart: no closer pair
        return ub
    near = small[_box_distance(small, lo, hi) < ub]
    if len(near):
        d, _ = t_big.query(near, k=1, distance_upper_bound=ub)
        ub = min(ub, float(d.min()))
    return ub


#: Up to this many points the cluster distances come from one kd-tree query per cluster of all the
#: points of the later clusters (instead of two kd-tree searches per cluster pair).
BRUTE_DISTANCES = 4096


def _distances(cl: _Clusters) -> np.ndarray:
    k = cl.k
    if cl.n <= BRUTE_DISTANCES:
        return _all_point_distances(cl)
    out = np.zeros((k, k))
    members = [cl.members(c) for c in range(k)]
    trees = [cKDTree(m) for m in members] if k > 1 else []
    boxes = [(m.min(axis=0), m.max(axis=0)) for m in members]
    for i in range(k):
        for j in range(i + 1, k):
            a, b = (i, j) if cl.sizes[i] <= cl.sizes[j] else (j, i)
            out[i, j] = out[j, i] = _min_distance(members[a], members[b], trees[a], trees[b],
                                                  (boxes[a], boxes[b]))
    return out


def _all_point_distances(cl: _Clusters) -> np.ndarray:
    """_distances from each point's nearest neighbour in every earlier cluster: cluster c's kd-tree
    is queried with all the points of the clusters after it (contiguous), and each cluster's
    minimum is read per cluster."""
    out = np.zeros((cl.k, cl.k))
    for c in range(cl.k - 1):
        later = cl.points[cl.starts[c + 1]:]
        nearest, _ = cKDTree(cl.members(c)).query(later, k=1)
        out[c, c + 1:] = out[c + 1:, c] = np.minimum.reduceat(nearest, cl.starts[c + 1:] - cl.starts[c + 1])
    return out


def cluster_distances(points: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """(K, K) symmetric matrix of minimum point-to-point distances between clusters (0 diagonal).

    Same cluster order as :func:`cluster_diameters`. Exact, via kd-tree nearest-neighbour queries.
    """
    return _distances(_clusters(points, labels))


# --------------------------------------------------------------------------------------------
# Dunn and Davies-Bouldin


def _dunn(diam: np.ndarray, dist: np.ndarray) -> float:
    k = len(diam)
    if k < 2:
        return 0.0
    sep = float(dist[np.triu_indices(k, 1)].min())
    spread = float(diam.max())
    if sep == 0.0:
        return 0.0
    return np.inf if spread == 0.0 else sep / spread


def _db_paper(diam: np.ndarray, dist: np.ndarray) -> float:
    k = len(diam)
    if k < 2:
        return np.inf
    with np.errstate(divide='ignore', invalid='ignore'):
        ratio = (diam[:, None] + diam[None, :]) / dist
    ratio[dist == 0.0] = np.inf  # coincident clusters, including 0/0
    np.fill_diagonal(ratio, -np.inf)
    return float(ratio.max(axis=1).mean())


def dunn_index(points: np.ndarray, labels: np.ndarray) -> float:
    """Dunn's index (eq. 2): min_{i != j} dist(c_i, c_j) / max_l diam(c_l); larger is better.

    dist = minimum point-to-point distance, diam = maximum within-cluster distance; label -1 points
    form one cluster; non-finite rows dropped. Defined values: 0.0 for fewer than two clusters or
    when two clusters touch (dist 0); inf when all clusters have diameter 0 but are apart.
    """
    cl = _clusters(points, labels)
    if cl.k < 2:
        return 0.0
    return _dunn(_diameters(cl), _distances(cl))


def davies_bouldin_index(points: np.ndarray, labels: np.ndarray) -> float:
    """Davies-Bouldin index as the paper writes it (eq. 3); smaller is better:
    (1/k) sum_i max_{j != i} (diam(c_i) + diam(c_j)) / dist(c_i, c_j).

    diam and dist as in :func:`dunn_index`; label -1 points form one cluster; non-finite rows
    dropped. Defined values: inf for fewer than two clusters, and a pair at distance 0 contributes
    inf (so coincident or touching clusters give inf).
    """
    cl = _clusters(points, labels)
    if cl.k < 2:
        return np.inf
    return _db_paper(_diameters(cl), _distances(cl))


def _db_classic(cl: _Clusters) -> float:
    if cl.k < 2:
        return 0.0
    centroids = np.add.reduceat(cl.points, cl.starts, axis=0) / cl.sizes[:, None]
    spread = np.sqrt(((cl.points - centroids[cl.codes]) ** 2).sum(axis=1))
    intra = np.add.reduceat(spread, cl.starts) / cl.sizes
    sep = cdist(centroids, centroids)
    # the same conventions as sklearn.metrics.davies_bouldin_score (np.allclose(x, 0): |x| <= its atol, 1e-8)
    if (np.abs(intra) <= 1e-8).all() or (np.abs(sep) <= 1e-8).all():
        return 0.0
    sep[sep == 0] = np.inf
    return float(np.max((intra[:, None] + intra[None, :]) / sep, axis=1).mean())


def davies_bouldin_classic(points: np.ndarray, labels: np.ndarray) -> float:
    """The usual centroid Davies-Bouldin index (equals ``sklearn.metrics.davies_bouldin_score``):
    mean over clusters of max_{j != i} (S_i + S_j) / |m_i - m_j|, S = mean distance to the centroid m.

    Label -1 points form one cluster; non-finite rows dropped. Defined values (as sklearn where it
    does not raise): 0.0 for fewer than two clusters, or when all S or all centroid distances are
    ~0; coinciding centroids are treated as infinitely far apart.
    """
    return _db_classic(_clusters(points, labels))


# --------------------------------------------------------------------------------------------
# Silhouettes


def _pair_pass(cl: _Clusters) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pair of rows of ``cl`` once (a compiled O(n^2) pass, O(n K) memory): (sums (n, K) summed
    distances from each row to each cluster, diameters (K,), distances (K, K) between clusters)."""
    return kernels.cluster_distance_pass(kernels.c_array(cl.points, np.float64), kernels.c_array(cl.starts, np.int64),
                                         kernels.c_array(cl.sizes, np.int64))


def _silhouettes(cl: _Clusters, sums: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Exact silhouettes of each (sorted) row among the rows of ``cl``: (s (n,), s_planes (n,)), as
    :func:`_silhouettes_numpy` gives them, in one compiled pass over the distance sums
    (:func:`.kernels.silhouettes`)."""
    if cl.k < 2:
        return _silhouettes_numpy(cl, sums)
    if sums is None:
        sums = _pair_pass(cl)[0]
    return kernels.silhouettes(kernels.c_array(sums, np.float64), kernels.c_array(cl.codes, np.int64),
                               kernels.c_array(cl.sizes, np.int64), bool(cl.ids[0] < 0))


def _silhouettes_numpy(cl: _Clusters, sums: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Exact silhouettes of each (sorted) row among the rows of ``cl``: (s (n,), s_planes (n,)).

    s_i = (b_i - a_i) / max(a_i, b_i); a_i mean distance to the other members of its cluster,
    b_i the smallest mean distance to another cluster; 0 for singleton clusters and for a = b = 0.
    s_planes is the same for the planes alone (the unassigned cluster is no candidate for b_i;
    NaN on its own rows): both come from the same distance sums, ``sums`` (n, K) of
    :func:`_pair_pass` (computed when None). The reference :func:`_silhouettes`' kernel is tested against.
    """
    n, k = cl.n, cl.k
    s, s_planes = np.zeros(n), np.zeros(n)
    has_rest = k > 0 and cl.ids[0] < 0
    if has_rest:
        s_planes[:cl.sizes[0]] = np.nan
    if k < 2:
        return s, s_planes
    if sums is None:
        sums = _pair_pass(cl)[0]
    rows, own = np.arange(n), cl.codes
    a = sums[rows, own] / np.maximum(cl.sizes[own] - 1, 1)
    means = sums / cl.sizes
    means[rows, own] = np.inf
    s = _ratio(a, means.min(axis=1))
    if has_rest and k >= 3:  # planes only: drop the unassigned column as a candidate
        plane_rows = own > 0
        s_planes[plane_rows] = _ratio(a[plane_rows], means[plane_rows, 1:].min(axis=1))
    if not has_rest:
        s_planes[:] = s
    elif k < 3:
        s_planes[cl.sizes[0]:] = 0.0  # a single plane has no silhouette
    single = cl.sizes[cl.codes] == 1
    s[single] = 0.0
    s_planes[single & ~np.isnan(s_planes)] = 0.0
    return s, s_planes


def _ratio(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    top = np.maximum(a, b)
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(top > 0, (b - a) / top, 0.0)


def silhouette_samples(points: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """(N,) exact silhouette s_i of every input row (eq. 4), aligned with the input.

    Label -1 points form one cluster. Rows with non-finite coordinates get NaN. All zeros when
    there are fewer than two clusters; 0 for a singleton cluster (as scikit-learn).
    Memory O(N K); time O(N^2).
    """
    pts, _ = _check(points, labels)
    cl = _clusters(points, labels)
    out = np.full(len(pts), np.nan)
    out[cl.order] = _silhouettes(cl)[0]
    return out


def _cluster_means(cl: _Clusters, s: np.ndarray) -> np.ndarray:
    return np.add.reduceat(s, cl.starts) / cl.sizes if cl.k else np.zeros(0)


def silhouette_score(points: np.ndarray, labels: np.ndarray) -> float:
    """Exact mean silhouette over all finite points (equals ``sklearn.metrics.silhouette_score``);
    label -1 points form one cluster; 0.0 for fewer than two clusters."""
    cl = _clusters(points, labels)
    return float(_silhouettes(cl)[0].mean()) if cl.k >= 2 else 0.0


def global_silhouette(points: np.ndarray, labels: np.ndarray, *, planes_only: bool = False) -> float:
    """Exact global silhouette GS (eq. 6): mean over clusters of each cluster's mean silhouette.

    planes_only=False: label -1 points form one cluster (GS). planes_only=True: they are dropped
    and the silhouettes are computed among the planes alone (GS_planes). 0.0 with fewer than two
    clusters (planes). Non-finite rows dropped.
    """
    cl = _clusters(points, labels)
    if planes_only:
        cl = cl.planes_only()
    return float(_cluster_means(cl, _silhouettes(cl)[0]).mean()) if cl.k >= 2 else 0.0


# --------------------------------------------------------------------------------------------
# Stratified sampling of silhouettes


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


def _stratified(cl: _Clusters, total: int, rng: np.random.Generator) -> _Clusters:
    """A stratified random sample (without replacement) of about ``total`` rows of ``cl``."""
    alloc = _allocate(cl.sizes, total)
    rows = np.concatenate([cl.starts[c] + rng.choice(int(cl.sizes[c]), int(alloc[c]), replace=False)
                           for c in range(cl.k)])
    return cl.subset(np.sort(rows))


def _stratified_coded(coded: _Coded, total: int, rng: np.random.Generator) -> _Clusters:
    """The same sample as ``_stratified(_sorted_by_cluster(coded), total, rng)`` (same rows for
    the same generator state), without gathering and sorting every row first."""
    alloc = _allocate(coded.sizes, total)
    positions = np.concatenate([coded.members(c)[np.sort(rng.choice(int(coded.sizes[c]), int(alloc[c]),
                                                                     replace=False))]
                                for c in range(len(coded.ids))])
    return _sorted_by_cluster(coded, positions)


@dataclass(frozen=True)
class _Estimate:
    silhouette: float
    gs: float
    silhouette_se: float
    gs_se: float
    size: int
    cluster_means: tuple[float, ...]


def _summarize(sizes: np.ndarray, sub: _Clusters, s: np.ndarray, exact: bool) -> _Estimate:
    """Silhouette (mean of s_i) and GS of a population of clusters with ``sizes`` (K,) from the
    silhouettes ``s`` of its rows ``sub``: exact (SE 0), or a stratified sample (stratified SE
    with finite-population correction)."""
    k, n = len(sizes), int(sizes.sum())
    if k < 2:
        return _Estimate(0.0, 0.0, 0.0, 0.0, n, (0.0,) * k)
    mean_h = _cluster_means(sub, s)
    if exact:
        return _Estimate(float(s.mean()), float(mean_h.mean()), 0.0, 0.0, sub.n, tuple(map(float, mean_h)))
    n_h, big_n = sub.sizes.astype(np.float64), sizes.astype(np.float64)
    dev = s - mean_h[sub.codes]
    var_h = np.add.reduceat(dev * dev, sub.starts) / np.maximum(n_h - 1, 1)
    var_mean_h = (1.0 - n_h / big_n) * var_h / n_h  # variance of each cluster's sample mean
    w = big_n / big_n.sum()
    return _Estimate(silhouette=float(w @ mean_h), gs=float(mean_h.mean()),
                     silhouette_se=float(np.sqrt(w ** 2 @ var_mean_h)),
                     gs_se=float(np.sqrt(var_mean_h.sum()) / k), size=sub.n,
                     cluster_means=tuple(map(float, mean_h)))


def _estimates(sizes: np.ndarray, ids: np.ndarray, sub: _Clusters, exact: bool,
               sums: np.ndarray | None) -> tuple[_Estimate, _Estimate]:
    """(all clusters, planes only) silhouette estimates for a population of clusters ``sizes``
    (K,) with labels ``ids`` from the distance sums ``sums`` (n, K) of its rows ``sub`` (all of
    them when ``exact``, else a stratified sample whose silhouettes are computed against the sample
    itself; the planes-only estimate uses the sample's plane rows)."""
    s, s_planes = _silhouettes(sub, sums)
    cut = int(sub.sizes[0]) if sub.k and sub.ids[0] < 0 else 0
    plane_sizes = sizes[1:] if len(ids) and ids[0] < 0 else sizes
    return _summarize(sizes, sub, s, exact), _summarize(plane_sizes, sub.planes_only(), s_planes[cut:], exact)


# --------------------------------------------------------------------------------------------
# All indices at once


@dataclass(frozen=True)
class ValidityIndices:
    """Validity indices of one labelling (see :func:`validity_indices`).

    dunn (eq. 2, larger better), davies_bouldin (eq. 3 with diam/dist, smaller better),
    davies_bouldin_classic (centroid form, = sklearn), silhouette (mean s_i, = sklearn),
    gs (eq. 6), gs_planes (GS without the unassigned points), plane_silhouette (PS, from
    point-to-plane distances, see :mod:`.plane_silhouette`); plane_silhouettes: per plane, in
    label order, its mean silhouette S_j (eq. 5) among the planes (the terms GS_planes averages);
    the *_se fields are standard errors
    of the sampled estimates (0.0 when exact). sample_size: points the silhouettes were computed
    on (n_points when exact); separation_size: points Dunn and Davies-Bouldin were computed on
    (n_points when exact, sample_size with ``sampled_separation``).
    """

    dunn: float
    davies_bouldin: float
    davies_bouldin_classic: float
    silhouette: float
    gs: float
    gs_planes: float
    silhouette_se: float
    gs_se: float
    gs_planes_se: float
    n_planes: int
    n_clusters: int
    n_points: int
    sample_size: int
    plane_silhouettes: tuple[float, ...] = ()
    separation_size: int = -1    # points Dunn and both DB forms were computed on (-1: n_points)
    plane_silhouette: float = 0.0  # PS, the point-to-plane index (core/plane_silhouette.py)

    def __post_init__(self) -> None:
        if self.separation_size < 0:
            object.__setattr__(self, 'separation_size', self.n_points)

    @property
    def sampled(self) -> bool:
        """True when the silhouette-based values are estimates from a sample."""
        return self.sample_size < self.n_points

    def as_dict(self) -> dict[str, float | int]:
        """Flat ``name -> value`` mapping of every scalar field plus ``sampled`` (as 0/1)."""
        out: dict[str, float | int] = asdict(self)
        del out['plane_silhouettes']
        out['sampled'] = int(self.sampled)
        return out


#: From this many points summed over on, the plane silhouette runs in a thread beside the other indices (numpy, the
#: kd-trees and the kernels release the GIL; below it the thread's start and the GIL cost more than they save). The
#: points summed over are the index sample's when there is one: on a sample of 2,000 the PS takes a few ms whatever
#: the cloud's size, and its thread cost a 640 x 480 frame about 1 ms more CPU time without saving wall time on two
#: busy cores (benchmarks/README.md).
THREADED_PS_POINTS = 50_000


def _started(pool: ThreadPoolExecutor, call: Callable[[], float]) -> Callable[[], float]:
    """``call`` started in ``pool``'s thread, under the caller's numpy error state (a context
    variable); a function that waits for its value. Where no thread can start (the interpreter is
    shutting down) it is ``call`` itself, run when asked."""
    try:
        return pool.submit(contextvars.copy_context().run, call).result
    except RuntimeError:
        return call


@single_blas_thread
def validity_indices(points: np.ndarray, labels: np.ndarray, *, sample_size: int | None = 2000,
                     seed: int | np.random.Generator | None = None,
                     sampled_separation: bool = False) -> ValidityIndices:
    """All validity indices of the planes ``labels`` (N,) on ``points`` (N, 3).

    Rows with NaN/inf coordinates are dropped first. Dunn and both Davies-Bouldin forms are exact
    (kd-trees and convex hulls, no O(N^2) step) unless ``sampled_separation``. The silhouette
    values are exact when ``sample_size`` is None or N <= sample_size; otherwise they are
    estimated from a stratified sample of about ``sample_size`` points (every cluster keeps at
    least min(its size, max(2, sample_size // (4k))) points, the rest is shared proportionally),
    each sampled point's silhouette computed against the sample; GS_planes uses the plane rows of
    the same sample (b_i then ranges over the planes only), so one pass over the distances serves
    both. The *_se fields give the stratified standard errors (with finite-population
    correction) of these estimates; they treat each sampled s_i as fixed, so they ignore the
    shared noise of estimating a_i and b_i from the same sample and run ~1.1-2x too small
    (measured on noisy corner/cube scenes: |error| <= 4 SE in >= 95% of seeds, <= 2 SE in ~80%).
    ``seed``: int, Generator or None (fresh entropy); results are deterministic for a fixed int
    seed.

    sampled_separation: compute Dunn and both Davies-Bouldin forms on the same sample (when
    the silhouettes are sampled). Much faster on large clouds (benchmarks/README.md), but
    biased: sampled clusters lie farther apart and are a little smaller than the full ones, so
    Dunn comes out larger and DB smaller than exact; compare such values only with values from
    the same sample size. GS values are unchanged (the same sample, rows and seed either way).

    Label -1 points (any negative label: unassigned) form one extra cluster for everything but GS_planes, which
    ignores them.
    Defined values, never exceptions: fewer than two clusters -> dunn 0.0, davies_bouldin inf,
    davies_bouldin_classic 0.0, silhouette and gs 0.0; fewer than two planes -> gs_planes 0.0;
    touching or coincident clusters (dist 0) -> dunn 0.0, davies_bouldin inf; every cluster a
    single point (all diameters 0) -> dunn inf, davies_bouldin 0.0; singleton clusters have
    s_i = 0. ValueError only for badly shaped input (points not (N, 3), labels not (N,) integers)
    or sample_size < 2.

    Cost: O(sample_size^2) for the sampled silhouettes; exact silhouettes are O(N^2).
    """
    if sample_size is not None:
        sample_size = check_integer('sample_size', sample_size, 2)
    sampled_separation = check_flag('sampled_separation', sampled_separation)
    census = _census(points, labels)
    rng = generator(seed)
    n, k = census.n, len(census.ids)
    sampled = sample_size is not None and n > int(sample_size) and k >= 2
    if sampled and sampled_separation:
        sub = _stratified_census(census, int(sample_size), rng) if len(census.table) else \
            _stratified_coded(_code(census.pts, census.lab.astype(np.int64)), int(sample_size), rng)
        sep = sub
    else:
        cl = _sorted_by_cluster(_code(census.pts, census.lab.astype(np.int64, copy=False)))
        sub = _stratified(cl, int(sample_size), rng) if sampled else cl
        sep = cl
    ps = functools.partial(plane_silhouette_of, census.pts, census.lab, census.compact,
                           (n, census.n_assigned, census.low, len(census.table)), sample_size=sample_size, rng=rng)
    summed = n if sample_size is None else min(n, int(sample_size))
    with ThreadPoolExecutor(1) if summed >= THREADED_PS_POINTS else contextlib.nullcontext() as pool:
        if pool is not None:
            ps = _started(pool, ps)
        sums = None
        if k >= 2:
            sums, diam, dist = _pair_pass(sub)  # on sep too when it is the same rows
            if sep is not sub:
                diam, dist = _diameters(sep), _distances(sep)
            dunn, db = _dunn(diam, dist), _db_paper(diam, dist)
        else:
            dunn, db = 0.0, np.inf
        full, planes = _estimates(census.sizes, census.ids, sub, exact=not sampled, sums=sums)
        ps = ps()
    return ValidityIndices(
        dunn=float(dunn), davies_bouldin=float(db), davies_bouldin_classic=_db_classic(sep),
        silhouette=full.silhouette, gs=full.gs, gs_planes=planes.gs,
        silhouette_se=full.silhouette_se, gs_se=full.gs_se, gs_planes_se=planes.gs_se,
        n_planes=int((census.ids >= 0).sum()), n_clusters=k, n_points=n, sample_size=full.size,
        plane_silhouettes=planes.cluster_means, separation_size=sep.n, plane_silhouette=ps)
