"""Cluster validity indices for detected planes (Lipnickas et al. 2014, sections 3.1-3.3).

numpy, scipy and the kernels of core/kernels.py; no ROS import. The planes found by sequential
RANSAC are treated as clusters: ``labels`` is an (N,) integer array with 0..k-1 for plane points
and -1 for unassigned points (any negative label counts as unassigned). Distances are Euclidean,
in the unit of ``points``.

Conventions shared by every public function here:

* Rows of ``points`` with a NaN or infinite coordinate are dropped first, together with their
  labels; ``n_points`` counts the remaining (finite) rows.
* Except for GS_planes, the unassigned points form ONE extra cluster. Per-cluster arrays
  (:func:`.cluster_extent.cluster_diameters`, :func:`.cluster_extent.cluster_distances`) list clusters in ascending
  label order, so the unassigned cluster, when present, comes first (the order of ``np.unique(labels)``).
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
from scipy.spatial.distance import cdist

from . import kernels
from .blas import single_blas_thread
from .cluster_extent import cluster_diameters, cluster_distances, diameter, diameters_of, distances_of
from .clusters import (
    Clusters,
    as_clusters,
    check_labelled,
    code_labels,
    sorted_by_cluster,
    stratified,
    stratified_census,
    stratified_coded,
    take_census,
)
from .plane_silhouette import plane_silhouette_of
from .ransac import check_flag, check_integer, generator

__all__ = [
    'ValidityIndices', 'validity_indices', 'dunn_index', 'davies_bouldin_index', 'davies_bouldin_classic',
    'silhouette_samples', 'silhouette_score', 'global_silhouette', 'cluster_diameters', 'cluster_distances',
    'diameter',
]


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
    cl = as_clusters(points, labels)
    if cl.k < 2:
        return 0.0
    return _dunn(diameters_of(cl), distances_of(cl))


def davies_bouldin_index(points: np.ndarray, labels: np.ndarray) -> float:
    """Davies-Bouldin index as the paper writes it (eq. 3); smaller is better:
    (1/k) sum_i max_{j != i} (diam(c_i) + diam(c_j)) / dist(c_i, c_j).

    diam and dist as in :func:`dunn_index`; label -1 points form one cluster; non-finite rows
    dropped. Defined values: inf for fewer than two clusters, and a pair at distance 0 contributes
    inf (so coincident or touching clusters give inf).
    """
    cl = as_clusters(points, labels)
    if cl.k < 2:
        return np.inf
    return _db_paper(diameters_of(cl), distances_of(cl))


def _db_classic(cl: Clusters) -> float:
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
    return _db_classic(as_clusters(points, labels))


def _pair_pass(cl: Clusters) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pair of rows of ``cl`` once (a compiled O(n^2) pass, O(n K) memory): (sums (n, K) summed
    distances from each row to each cluster, diameters (K,), distances (K, K) between clusters)."""
    return kernels.cluster_distance_pass(kernels.c_array(cl.points, np.float64), kernels.c_array(cl.starts, np.int64),
                                         kernels.c_array(cl.sizes, np.int64))


def _silhouettes(cl: Clusters, sums: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Exact silhouettes of each (sorted) row among the rows of ``cl``: (s (n,), s_planes (n,)), as
    :func:`_silhouettes_numpy` gives them, in one compiled pass over the distance sums
    (:func:`.kernels.silhouettes`)."""
    if cl.k < 2:
        return _silhouettes_numpy(cl, sums)
    if sums is None:
        sums = _pair_pass(cl)[0]
    return kernels.silhouettes(kernels.c_array(sums, np.float64), kernels.c_array(cl.codes, np.int64),
                               kernels.c_array(cl.sizes, np.int64), bool(cl.ids[0] < 0))


def _silhouettes_numpy(cl: Clusters, sums: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
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
    pts, _ = check_labelled(points, labels)
    cl = as_clusters(points, labels)
    out = np.full(len(pts), np.nan)
    out[cl.order] = _silhouettes(cl)[0]
    return out


def _cluster_means(cl: Clusters, s: np.ndarray) -> np.ndarray:
    return np.add.reduceat(s, cl.starts) / cl.sizes if cl.k else np.zeros(0)


def silhouette_score(points: np.ndarray, labels: np.ndarray) -> float:
    """Exact mean silhouette over all finite points (equals ``sklearn.metrics.silhouette_score``);
    label -1 points form one cluster; 0.0 for fewer than two clusters."""
    cl = as_clusters(points, labels)
    return float(_silhouettes(cl)[0].mean()) if cl.k >= 2 else 0.0


def global_silhouette(points: np.ndarray, labels: np.ndarray, *, planes_only: bool = False) -> float:
    """Exact global silhouette GS (eq. 6): mean over clusters of each cluster's mean silhouette.

    planes_only=False: label -1 points form one cluster (GS). planes_only=True: they are dropped
    and the silhouettes are computed among the planes alone (GS_planes). 0.0 with fewer than two
    clusters (planes). Non-finite rows dropped.
    """
    cl = as_clusters(points, labels)
    if planes_only:
        cl = cl.planes_only()
    return float(_cluster_means(cl, _silhouettes(cl)[0]).mean()) if cl.k >= 2 else 0.0


@dataclass(frozen=True)
class _Estimate:
    silhouette: float
    gs: float
    silhouette_se: float
    gs_se: float
    size: int
    cluster_means: tuple[float, ...]


def _summarize(sizes: np.ndarray, sub: Clusters, s: np.ndarray, exact: bool) -> _Estimate:
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


def _estimates(sizes: np.ndarray, ids: np.ndarray, sub: Clusters, exact: bool,
               sums: np.ndarray | None) -> tuple[_Estimate, _Estimate]:
    """(all clusters, planes only) silhouette estimates for a population of clusters ``sizes``
    (K,) with labels ``ids`` from the distance sums ``sums`` (n, K) of its rows ``sub`` (all of
    them when ``exact``, else a stratified sample whose silhouettes are computed against the sample
    itself; the planes-only estimate uses the sample's plane rows)."""
    s, s_planes = _silhouettes(sub, sums)
    cut = int(sub.sizes[0]) if sub.k and sub.ids[0] < 0 else 0
    plane_sizes = sizes[1:] if len(ids) and ids[0] < 0 else sizes
    return _summarize(sizes, sub, s, exact), _summarize(plane_sizes, sub.planes_only(), s_planes[cut:], exact)


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
                     sampled_separation: bool = False, finite: bool = False) -> ValidityIndices:
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

    finite: the caller knows every row of ``points`` to be finite (the valid rows a frame's read kept); the count of
    the clusters then reads only the labels. The same values as without it on such rows.

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
    census = take_census(points, labels, check_flag('finite', finite))
    rng = generator(seed)
    n, k = census.n, len(census.ids)
    sampled = sample_size is not None and n > int(sample_size) and k >= 2
    if sampled and sampled_separation:
        sub = stratified_census(census, int(sample_size), rng) if len(census.table) else \
            stratified_coded(code_labels(census.pts, census.lab.astype(np.int64)), int(sample_size), rng)
        sep = sub
    else:
        cl = sorted_by_cluster(code_labels(census.pts, census.lab.astype(np.int64, copy=False)))
        sub = stratified(cl, int(sample_size), rng) if sampled else cl
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
                diam, dist = diameters_of(sep), distances_of(sep)
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
