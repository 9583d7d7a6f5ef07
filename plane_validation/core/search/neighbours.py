"""Which searched points touch: one interface, :class:`Neighbours`, with two forms chosen once, when the
search graph is built (:func:`.graph.search_graph`): :class:`.neighbours_grid.GridNeighbours` on an image's
(sub-)grid and :class:`.neighbours_graph.GraphNeighbours` on an unorganized cloud's nearest-neighbour graph
(built by :mod:`..regions`).

A plane is a connected planar region (after Schnabel, Wahl and Klein 2007, who score a candidate by its largest
connected component): the search asks a neighbourhood for the region a plane's inliers keep, for nearby points to
draw hypotheses from, for the pairs of points that touch and to settle the borders between regions.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, fields

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from .. import kernels
from .types import Sampler

try:  # the kernel behind csgraph.connected_components, without its per-call checks and transpose
    from scipy.sparse.csgraph._traversal import _connected_components_undirected
except ImportError:  # pragma: no cover - a SciPy that moved it: the public function below
    _connected_components_undirected = None

__all__ = ['Neighbours', 'Remaining', 'settle_numpy', 'fragmented', 'joined_components', 'row_starts',
           'NORMAL_ANGLE_DEG', 'NORMAL_MIN_COS', 'FRAGMENTED', 'FRAGMENT_PIECE', 'SUPPORT_BALANCE', 'NEARBY_SCALES',
           'COMPETE_ROUNDS']

#: A point whose local surface normal is farther than this from a candidate plane's normal does not
#: count towards that plane's region (a plane slanted across the nosings of a staircase keeps only
#: strips of the treads, not the risers that would join them into one region).
NORMAL_ANGLE_DEG = 25.0
#: ... its cosine.
NORMAL_MIN_COS = float(np.cos(np.radians(NORMAL_ANGLE_DEG)))
#: A region whose inliers fall apart (its largest piece holds less than this share of them, and a typical
#: inlier lies in a piece of less than FRAGMENT_PIECE of them) is connected through its support instead
#: (see hypotheses.SUPPORT and :func:`fragmented`).
FRAGMENTED = 0.5
FRAGMENT_PIECE = 0.05
#: ... and only when its support beyond t lies on both sides of the plane, the smaller side holding at least this
#: share of the larger: noise spreads a surface's points to both sides, while a recess or a panel behind separate
#: coplanar objects lies on one side (without this test 25 drawer fronts 1.8 cm before their cabinet, 2 mm noise,
#: t = 1 cm, are joined into one plane and the cabinet is taken out of the search, F1 0.03), and so does most of the
#: band of a plane offset from the surface it crosses (0.6 t off at noise t: 0.05 against 0.26 of the points;
#: without the test such a plane keeps more than the surface's own one, 3.8 mm off a wall with 1 cm noise).
SUPPORT_BALANCE = 0.5
#: What the compiled region kernels (:func:`.kernels.grid_region`, :func:`.kernels.graph_region`) need of these
#: rules, in their order.
REGION_RULES = np.array([FRAGMENTED, FRAGMENT_PIECE, SUPPORT_BALANCE])
#: Scales of :meth:`Neighbours.nearby`: a window of this many sub-grid pixels around the point
#: (organized) or a random walk of this many graph hops (unorganized), one drawn per sample.
NEARBY_SCALES = (1, 2, 4, 8)
#: Rounds of border settling (:meth:`Neighbours.settle`): a region can win back this many pixels (or graph hops)
#: of a strip that a plane found before it took.
COMPETE_ROUNDS = 6


class Remaining(ABC):
    """The region rule of a neighbourhood restricted to the points a sequential search has left
    (:meth:`Neighbours.remaining`)."""

    @abstractmethod
    def keep(self, mask: np.ndarray, normal: np.ndarray, support: np.ndarray, above: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        """(kept, taken) (r,) bool of the points left for a plane of unit ``normal`` (3,) with inliers ``mask``
        (r,), support band ``support`` (r,) and side ``above`` (r,): see :data:`.types.Keep`."""

    @abstractmethod
    def without(self, left: np.ndarray) -> Remaining:
        """The same for the points ``left`` (r,) bool of these."""

    def best(self, cols: np.ndarray, tolerances: np.ndarray, normals: np.ndarray, offsets: np.ndarray,
             point_normals: np.ndarray | None, support: float, bound_cos: float) -> tuple[int, np.ndarray, np.ndarray]:
        """Of the h confirmed hypotheses (``normals`` (h, 3), ``offsets`` (h,)) on these points ``cols`` (3, r)
        meters, the one whose region (:meth:`keep`) is largest (equals: the lower MSAC cost): (its number, region (r,),
        taken (r,)). ``tolerances`` (1,) or (r,) meters; the support band is ``support`` times it. Hypotheses are tried
        by inliers, then cost; none can keep more than its inliers, nor, with ``point_normals`` (3, r) (NaN:
        unknown), more than those whose normal lies within ``bound_cos`` of its own: such hypotheses are not
        labelled. A form may answer in one compiled call (:func:`.kernels.grid_plane` runs this loop)."""
        dist, above = kernels.plane_bands(cols, normals, offsets)
        inliers, band, counts, cost = kernels.band_counts(dist, tolerances, support)
        winner, region, taken, size = -1, None, None, -1
        for h in np.lexsort((cost, -counts)):  # a hypothesis cannot keep more than its inliers: skip
            if counts[h] <= size:
                break
            if size > 0 and point_normals is not None:  # nor more than its coherent inliers: skip without labelling
                bound = kernels.coherent_inliers(inliers[h], normals[h], point_normals, bound_cos)
                if bound < size or (bound == size and cost[h] >= cost[winner]):
                    continue
            candidate, took = self.keep(inliers[h], normals[h], band[h], above[h])
            found = int(np.count_nonzero(candidate))
            if found > size or (found == size and cost[h] < cost[winner]):
                winner, region, taken, size = int(h), candidate, took, found
        return winner, region, taken

    def refit(self, cols: np.ndarray, tolerances: np.ndarray, region: np.ndarray, support: float
              ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
        """The least-squares plane of the points ``region`` (r,) bool (at least one) of ``cols`` (3, r) meters and
        the region it keeps (see :meth:`best`): (normal (3,), offset meters, region (r,), taken (r,))."""
        normal, offset = kernels.fit_mask(cols, region)
        near, above = kernels.plane_bands(cols, normal[None, :], np.array([offset]))
        inliers, band = kernels.band_counts(near, tolerances, support)[:2]
        return (normal, offset) + self.keep(inliers[0], normal, band[0], above[0])

    def refitted(self, cols: np.ndarray, tolerances: np.ndarray, normals: np.ndarray, offsets: np.ndarray,
                 point_normals: np.ndarray | None, support: float, bound_cos: float, refits: int
                 ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray] | None:
        """:meth:`best`, then up to ``refits`` :meth:`refit` rounds as :func:`.hypotheses.best_region` runs them
        (without an orientation constraint), in one compiled call when a form has one: (normal, offset, region (r,),
        taken (r,)); None when it has none (the caller runs the rounds)."""
        return None


@dataclass(frozen=True, eq=False, kw_only=True)
class Neighbours(ABC):
    """Adjacency of n points, with ``normals`` (n, 3) their unit local surface normals (NaN where unknown; None:
    none known). The abstract methods are those each form answers its own way."""

    n: int
    normals: np.ndarray | None = None

    def __getstate__(self) -> dict:
        """The fields, without the cached properties: a parallel sweep pickles the graph for its workers while this
        process, searching too, may be filling those in (pickling the live __dict__ then failed: "dictionary
        changed size during iteration")."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)

    def coherent(self, normal: np.ndarray, at: np.ndarray | None = None) -> np.ndarray:
        """(n,) bool: points whose local normal is within NORMAL_ANGLE_DEG of ``normal`` (or unknown);
        only for the points ``at`` (m,) when given."""
        if self.normals is None:
            return np.ones(self.n if at is None else len(at), bool)
        cos = np.abs((self.normals if at is None else self.normals[at]) @ normal)
        return ~(cos < NORMAL_MIN_COS)  # NaN (unknown) counts as coherent

    def largest(self, mask: np.ndarray, support: np.ndarray | None = None, above: np.ndarray | None = None
                ) -> np.ndarray:
        """(n,) bool: the largest connected component of ``mask`` (empty when ``mask`` is); with
        ``support`` and ``above``, the region :meth:`region` keeps."""
        return self.region(mask, support, above)[0]

    def region(self, mask: np.ndarray, support: np.ndarray | None = None, above: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
        """(kept, taken), (n,) bool each: the largest connected component of ``mask``, twice. With ``support``
        (n,) bool, a superset of ``mask``, and ``above`` (n,) bool, the points on the side of the plane its
        normal points to, where the component of ``support`` around the inliers has its points beyond t on both
        sides of the plane (SUPPORT_BALANCE: the noise of a surface, not another surface) and the pieces of
        ``mask`` fall apart (see :func:`fragmented`; a surface's points within t do where its noise exceeds t):
        kept, the ``mask`` points of the component of ``support`` that holds the most of them; taken, that whole
        component (the surface's points beyond t, which are no plane of their own)."""
        out, sizes = self._component(mask)
        if support is None or above is None or not fragmented(sizes):
            return out, out
        whole, _ = self._component(support, mask)
        beyond = whole & ~mask
        up = int(np.count_nonzero(beyond & above))
        down = int(np.count_nonzero(beyond)) - up
        if min(up, down) < SUPPORT_BALANCE * max(up, down):  # a recess, a backing: not noise
            return out, out
        joined = whole & mask
        return (joined, whole) if np.count_nonzero(joined) > np.count_nonzero(out) else (out, out)

    def sampler(self, rest_idx: np.ndarray) -> Sampler:
        """Triples of nearby points among the points ``rest_idx`` (ascending), as positions in ``rest_idx``
        (-1: the nearby point is not among them)."""
        position = np.full(self.n + 1, -1, dtype=np.int64)  # [-1] stays -1
        position[rest_idx] = np.arange(len(rest_idx))

        def sample(rng: np.random.Generator, count: int) -> np.ndarray:
            first = rng.integers(0, len(rest_idx), count)
            near = position[self.nearby(np.tile(rest_idx[first], 2), rng)]
            return np.column_stack([first, near[:count], near[count:]])
        return sample

    @abstractmethod
    def nearby(self, nodes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A random point near each of ``nodes`` (m,), NEARBY_SCALES away; -1 where there is none."""

    @abstractmethod
    def components(self, mask: np.ndarray) -> tuple[np.ndarray, int]:
        """Connected components of the points where ``mask`` (n,) is True: (labels (n,) int, -1
        outside the mask, components 0..c-1; c)."""

    @abstractmethod
    def _component(self, within: np.ndarray, counted: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The component of ``within`` with the most points of ``counted`` (all when None), as (n,) bool,
        and those points per component."""

    @abstractmethod
    def searchable(self) -> np.ndarray:
        """The points (ascending) that may join a region."""

    @abstractmethod
    def remaining(self, rest_idx: np.ndarray) -> Remaining:
        """The region rule over the points ``rest_idx`` (ascending) of :meth:`searchable`."""

    @abstractmethod
    def touching(self) -> tuple[np.ndarray, np.ndarray]:
        """(src, dst) pairs of points that touch (see the forms)."""

    def contacts(self, region: np.ndarray, k: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """The :meth:`touching` pairs (src, dst) that join two of the ``k`` regions of ``region`` (n,) (-1: none),
        their regions (a, b), and each touching pair of regions once as i * k + j (i < j), ascending; None when no
        two regions touch. A form may answer in one compiled call (the grid's does; this is its reference)."""
        src, dst = self.touching()
        a, b = region[src], region[dst]
        touch = (a >= 0) & (b >= 0) & (a != b)
        if not touch.any():
            return None
        src, dst, a, b = src[touch], dst[touch], a[touch], b[touch]
        return src, dst, a, b, np.unique(np.minimum(a, b) * k + np.maximum(a, b))

    @abstractmethod
    def around(self, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every (node, neighbour) pair of the points ``nodes`` (c,), as two arrays, for border settling."""

    @abstractmethod
    def bordering(self, region: np.ndarray) -> np.ndarray:
        """The points (ascending) with a neighbour (as in :meth:`around`) in another region than theirs."""

    @abstractmethod
    def tie_keys(self, src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, ...]:
        """np.lexsort keys (the last one first) that order equal offers of neighbours ``src`` to points ``dst``
        in :func:`settle_numpy`: the first offer wins."""

    @abstractmethod
    def settle(self, dist: np.ndarray, region: np.ndarray) -> np.ndarray:
        """Border settling: ``region`` (m,) 0..k (k: none) after COMPETE_ROUNDS rounds in which each point takes,
        of its own and its neighbours' regions, the one nearest by ``dist`` (k + 1, m); -1 for none."""

    def settle_planes(self, search: np.ndarray, planes: np.ndarray, tolerance: np.ndarray, viewpoint: np.ndarray,
                      min_cos: float, region: np.ndarray, ray: np.ndarray = kernels.NO_RAY) -> np.ndarray:
        """:meth:`settle` by the distances :func:`.kernels.compete_distances` gives for the points ``search`` (3, m)
        meters, ``planes`` (k, 4), ``tolerance`` (1,) or (m,) meters, ``viewpoint`` (3,) and ``min_cos``; a form may
        work out only the distances it compares (the grid's does)."""
        return self.settle(kernels.compete_distances(search, planes, tolerance, viewpoint, min_cos), region)


def settle_numpy(dist: np.ndarray, region: np.ndarray, neighbours: Neighbours) -> np.ndarray:
    """:meth:`Neighbours.settle` in numpy (the graph form's, and the reference of the grid form's kernel):
    ``dist`` (k + 1, m), ``region`` (m,) 0..k (k: none). Only points next to another region can change, and after
    the first round only the neighbours of points that changed: only they are looked at."""
    k, m = dist.shape[0] - 1, dist.shape[1]
    flat = dist.reshape(-1)
    best = flat[region * m + np.arange(m)]  # row k (no region) is inf
    dst, src = neighbours.around(neighbours.bordering(region))
    for _ in range(COMPETE_ROUNDS):
        cand = region[src]
        d = flat[cand * m + dst]
        better = d < best[dst]
        if not better.any():
            break
        dst, src, cand, d = dst[better], src[better], cand[better], d[better]
        # per point its nearest offer; equal distances: by the form's tie keys
        order = np.lexsort(neighbours.tie_keys(src, dst) + (d, dst))
        first = order[np.r_[True, dst[order[1:]] != dst[order[:-1]]]]
        changed = dst[first]
        region[changed], best[changed] = cand[first], d[first]  # the offers above read the old labels
        src, dst = neighbours.around(changed)  # their neighbours, offered the new labels
    return np.where(region < k, region, -1)


def fragmented(sizes: np.ndarray) -> bool:
    """Whether pieces of ``sizes`` (points each) have fallen apart, as a surface's points within t do
    where its noise exceeds t: the largest holds less than FRAGMENTED of the points, and the piece that
    holds a typical point (the median point, pieces taken largest first) less than FRAGMENT_PIECE. A few
    separate coplanar objects (three drawer fronts) are large pieces, and stay apart."""
    total = int(sizes.sum())
    if total == 0:
        return False
    desc = np.sort(sizes)[::-1]
    if desc[0] >= FRAGMENTED * total:
        return False
    typical = desc[int(np.searchsorted(np.cumsum(desc), total / 2))]
    return bool(typical < FRAGMENT_PIECE * total)


def row_starts(rows: np.ndarray, n: int, dtype=np.int64) -> np.ndarray:
    """(n + 1,) CSR row pointers of entries whose rows are ``rows`` (e,), once sorted by row: where each row starts."""
    starts = np.zeros(n + 1, dtype)
    np.cumsum(np.bincount(rows, minlength=n), out=starts[1:])
    return starts


def joined_components(n: int, src: np.ndarray, dst: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of n points joined by the pairs (``src``, ``dst``) (e,), ``src`` ascending:
    (count, labels (n,) int32), components numbered in the order of their first point, as
    ``csgraph.connected_components(..., connection='weak')`` numbers them.

    Calls the kernel of that function directly with both directions of the pairs: the public function
    checks and converts its graph and builds the transpose on every call, which on the small masks of
    a search costs several times the labelling itself.
    """
    small = max(n, len(src)) < np.iinfo(np.int32).max  # the kernel counts in 32 bits
    index = np.int32 if small else np.int64
    src, dst = np.ascontiguousarray(src, index), np.ascontiguousarray(dst, index)
    indptr = row_starts(src, n, index)
    if _connected_components_undirected is None or not small:  # pragma: no cover
        graph = csr_matrix((np.ones(len(src)), dst, indptr), shape=(n, n))
        return connected_components(graph, directed=True, connection='weak')
    order = np.argsort(dst.astype(np.uint16) if n <= 1 << 16 else dst, kind='stable')  # 16 bits: a radix sort
    back = row_starts(dst, n, index)
    labels = np.empty(n, np.int32)
    count = _connected_components_undirected(dst, indptr, src[order], back, labels)
    return int(count), labels
