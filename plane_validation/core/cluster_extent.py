"""How large clusters are and how far apart, exactly (for Dunn and Davies-Bouldin, :mod:`.indices`): each cluster's
diameter through its convex hull, and the least point-to-point distance between each pair of clusters through
kd-trees. Distances in the unit of the points (meters for sensors)."""
from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError, cKDTree
from scipy.spatial.distance import cdist, pdist

from .clusters import Clusters, as_clusters

__all__ = ['diameter', 'cluster_diameters', 'cluster_distances', 'diameters_of', 'distances_of']


#: Clusters with at most this many points get their diameter by brute force, without a hull.
BRUTE_DIAMETER = 64


#: Hull vertex sets up to this size are searched by brute force; larger ones use box pruning.
BRUTE_PAIRS = 2048


#: Points per bucket when pruning a large diameter search (at least), and most buckets.
BUCKET = 32


MAX_BUCKETS = 1024


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


def diameters_of(cl: Clusters) -> np.ndarray:
    return np.array([diameter(cl.members(c)) for c in range(cl.k)], dtype=np.float64)


def cluster_diameters(points: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """(K,) diameter of each cluster (max distance between two of its points), units of points.

    Clusters in ascending label order; all label -1 points form one cluster, listed first.
    A one-point cluster has diameter 0.
    """
    return diameters_of(as_clusters(points, labels))


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


def distances_of(cl: Clusters) -> np.ndarray:
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


def _all_point_distances(cl: Clusters) -> np.ndarray:
    """distances_of from each point's nearest neighbour in every earlier cluster: cluster c's kd-tree
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
    return distances_of(as_clusters(points, labels))
