"""The graph form of :class:`.neighbours.Neighbours`: an unorganized cloud's points joined to their nearest
neighbours (and across lidar rings), built by :func:`..regions.graph_neighbours`."""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .. import kernels
from .checks import gathered_rows
from .neighbours import (
    COMPETE_ROUNDS,
    NEARBY_SCALES,
    NORMAL_MIN_COS,
    REGION_RULES,
    Neighbours,
    Remaining,
    joined_components,
    row_starts,
    settle_numpy,
)
from .neighbours_grid import rest_positions
from .types import Sampler

__all__ = ['GraphNeighbours', 'GraphSampler', 'graph_region', 'graph_region_numpy', 'COMPACT_SHARE']

#: Components of a mask of up to this share of the points come from the graph of its points alone;
#: of a larger one, from the whole graph with the edges leaving it cut (faster then).
COMPACT_SHARE = 0.5
_NO_NORMALS = np.empty((0, 3))
_SCALES = np.array(NEARBY_SCALES, np.int64)


@dataclass(frozen=True, eq=False, kw_only=True)
class GraphNeighbours(Neighbours):
    """``edges`` (e, 2) point pairs, each pair once with the smaller index first, sorted; ``adjacency``: the same
    as CSR (indptr, indices), both ways (None: no edges); ``edge_starts``: :attr:`edge_rows` when its builder has
    them (None: worked out when first asked for)."""

    edges: np.ndarray
    adjacency: tuple[np.ndarray, np.ndarray] | None = None
    edge_starts: np.ndarray | None = None

    def nearby(self, nodes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The end of a random walk of NEARBY_SCALES hops from each of ``nodes`` (m,); the node itself where the
        walk cannot leave it."""
        scale = np.asarray(NEARBY_SCALES)[rng.integers(0, len(NEARBY_SCALES), len(nodes))]
        at = np.array(nodes, dtype=np.int64)
        if self.adjacency is None:  # no edges
            return at
        indptr, indices, degrees = self._walk
        hops = int(scale.max(initial=0))
        draws = rng.random((hops, len(at)))  # the numbers of one draw per hop, in the same order
        walking = scale > np.arange(hops)[:, None]
        for hop in range(hops):
            step = indptr[at] + (draws[hop] * degrees[at]).astype(np.int64)
            at = np.where(walking[hop], indices[step], at)
        return at

    def sampler(self, rest_idx: np.ndarray) -> Sampler:
        """The same draws and triples as :meth:`.neighbours.Neighbours.sampler` (its reference), the walks in one
        compiled call (:func:`.kernels.graph_triples`)."""
        if self.adjacency is None:  # no edges: every walk stays where it starts
            return super().sampler(rest_idx)
        indptr, indices, degrees = (kernels.c_array(a, np.int64) for a in self._walk)
        return GraphSampler((kernels.c_array(rest_idx, np.int64), rest_positions(self.n, rest_idx), indptr, indices,
                             degrees))

    @functools.cached_property
    def _walk(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The adjacency (indptr, indices) and degrees (n,) with a loop at each point without
        neighbours, so that a walk's step from it stays there."""
        indptr, indices = self.adjacency
        alone = self.degrees == 0
        if not alone.any():
            return indptr, indices, self.degrees
        degrees = np.maximum(self.degrees, 1)
        looped = np.zeros(self.n + 1, np.int64)
        np.cumsum(degrees, out=looped[1:])
        loop = np.zeros(looped[-1], bool)
        loop[looped[:-1][alone]] = True
        walk = np.empty(looped[-1], indices.dtype)
        walk[~loop], walk[loop] = indices, np.flatnonzero(alone)
        return looped, walk, degrees

    @functools.cached_property
    def degrees(self) -> np.ndarray:
        """(n,) neighbours of each point."""
        return np.diff(self.adjacency[0])

    @functools.cached_property
    def edge_rows(self) -> np.ndarray:
        """(n + 1,) where each point's edges to larger indices start in ``edges``."""
        return row_starts(self.edges[:, 0], self.n) if self.edge_starts is None else self.edge_starts

    @functools.cached_property
    def edge_ends(self) -> np.ndarray:
        """(e,) int64 the larger end of each edge, contiguous: what the region kernels read (a column of ``edges``
        read in place costs them about a quarter more)."""
        return np.ascontiguousarray(self.edges[:, 1], np.int64)

    @functools.cached_property
    def c_edges(self) -> np.ndarray:
        """``edges`` as a C-ordered (e, 2) int64 array, what the compiled kernels take."""
        return kernels.c_array(self.edges, np.int64)

    def subgraph(self, keep: np.ndarray) -> GraphNeighbours:
        """The neighbourhood of the points ``keep`` (ascending indices), renumbered 0..len(keep)-1, in one compiled
        pass (:func:`.kernels.kept_edges`; :meth:`subgraph_numpy` is its reference). Components of points among
        them are the same as in the whole graph."""
        edges, starts = kernels.kept_edges(self.c_edges, kernels.c_array(keep, np.int64), self.n)
        normals = None if self.normals is None else \
            gathered_rows(self.normals, keep)
        return GraphNeighbours(n=len(keep), edges=edges, normals=normals, edge_starts=starts)

    def subgraph_numpy(self, keep: np.ndarray) -> GraphNeighbours:
        """:meth:`subgraph` in numpy."""
        position = np.full(self.n, -1, dtype=np.int64)
        position[keep] = np.arange(len(keep))
        pairs = position[self.edges.T]  # (2, e)
        edges = np.compress((pairs >= 0).all(axis=0), pairs, axis=1)  # still sorted: keep ascends
        return GraphNeighbours(n=len(keep), edges=edges.T,
                               normals=None if self.normals is None else self.normals[keep])

    def components(self, mask: np.ndarray) -> tuple[np.ndarray, int]:
        members, labels, sizes = self._graph_components(mask)
        out = np.full(self.n, -1, dtype=np.int64)
        out[members] = labels
        return out, len(sizes)

    def _graph_components(self, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The masked points (ascending), the component of each (numbered in the order of their first point)
        and the points per component, from the graph of the masked points alone."""
        members = np.flatnonzero(mask)
        m = len(members)
        if m == 0:
            return members, members, members
        if m > COMPACT_SHARE * self.n:  # most points: gathering their edges costs more than masking all
            return self._components_of_whole(mask, members)
        # the edges from the masked points (the rows of the source-sorted edge list) to masked points
        first = self.edge_rows[members]
        counts = self.edge_rows[members + 1] - first
        total = int(counts.sum())
        ends = np.cumsum(counts)
        at = np.arange(total) + np.repeat(first - (ends - counts), counts)
        dst = self.edges[at, 1]
        inside = mask[dst]
        position = np.empty(self.n, np.int32)
        position[members] = np.arange(m, dtype=np.int32)
        count, labels = joined_components(m, np.repeat(np.arange(m, dtype=np.int32), counts)[inside],
                                          position[dst[inside]])
        return members, labels, np.bincount(labels, minlength=count)

    def _components_of_whole(self, mask: np.ndarray, members: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_graph_components` from the whole graph with the edges that leave the mask cut."""
        src, dst = self.edges.T  # sorted by source (graph_neighbours): the CSR rows need no sort
        inside = mask[src] & mask[dst]
        count, labels = joined_components(self.n, src[inside], dst[inside])
        sizes = np.bincount(labels[members], minlength=count)
        used = np.flatnonzero(sizes)  # the other labels are unmasked points
        dense = np.full(count, -1, dtype=np.int64)
        dense[used] = np.arange(len(used))
        return members, dense[labels[members]], sizes[used]

    def _component(self, within: np.ndarray, counted: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        members, labels, sizes = self._graph_components(within)
        out = np.zeros(self.n, bool)
        if len(members):
            if counted is not None:
                sizes = np.bincount(labels[counted[members]], minlength=len(sizes))
            out[members[labels == int(np.argmax(sizes))]] = True
        return out, sizes

    def searchable(self) -> np.ndarray:
        return np.arange(self.n)

    def remaining(self, rest_idx: np.ndarray) -> Remaining:
        return _GraphRemaining.of(self.subgraph(rest_idx))

    def touching(self) -> tuple[np.ndarray, np.ndarray]:
        """The graph's edges."""
        return self.edges[:, 0], self.edges[:, 1]

    def around(self, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Graph neighbours."""
        indptr, indices = self.adjacency if self.adjacency is not None else \
            (np.zeros(self.n + 1, np.int64), np.empty(0, np.int64))
        degree = indptr[nodes + 1] - indptr[nodes]
        start = np.repeat(indptr[nodes] - np.cumsum(degree) + degree, degree)
        return np.repeat(nodes, degree), indices[start + np.arange(len(start))]

    def contacts(self, region: np.ndarray, k: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """One compiled pass (:func:`.kernels.graph_contacts`; :meth:`.neighbours.Neighbours.contacts` is its
        reference)."""
        contacts = kernels.graph_contacts(self.c_edges, kernels.c_array(region, np.int64), k)
        return contacts if len(contacts[0]) else None

    def bordering(self, region: np.ndarray) -> np.ndarray:
        src, dst = self.edges.T
        differ = region[src] != region[dst]
        out = np.zeros(self.n, bool)
        out[src[differ]] = out[dst[differ]] = True
        return np.flatnonzero(out)

    def tie_keys(self, src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, ...]:
        """A smaller-index neighbour, then the largest one."""
        return (-src, src > dst)

    def settle(self, dist: np.ndarray, region: np.ndarray) -> np.ndarray:
        """:func:`.neighbours.settle_numpy` (its reference) in one compiled call (:func:`.kernels.graph_settle`)."""
        if self.adjacency is None:  # no edges: nothing to settle
            return settle_numpy(dist, region, self)
        return kernels.graph_settle(kernels.c_array(dist, np.float64), kernels.c_array(region, np.int64),
                                    *self.adjacency, COMPETE_ROUNDS)


@dataclass(frozen=True)
class GraphSampler:
    """Triples of nearby points among the points ``rest`` (ascending) of a graph (a :data:`.types.Sampler`):
    ``graph`` holds it as :func:`.kernels.graph_triples` takes it after the draws (rest, each point's place in rest
    (n,), the walk's indptr, indices and degrees)."""

    graph: tuple

    def draws(self, rng: np.random.Generator, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The random draws of ``count`` triples, :meth:`.neighbours.Neighbours.sampler`'s: the first points (places
        in rest), each of the 2 * count walks' scale (index into NEARBY_SCALES), then one share a hop."""
        first = rng.integers(0, len(self.graph[0]), count)
        scale_pick = rng.integers(0, len(NEARBY_SCALES), 2 * count)
        steps = rng.random((int(_SCALES[scale_pick].max(initial=0)), 2 * count))
        return first, scale_pick, steps

    def __call__(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """(count, 3) positions in rest, -1 where a walk ends on a point not among them."""
        return kernels.graph_triples(*self.draws(rng, count), _SCALES, *self.graph)

    def scored_batch(self, cols: np.ndarray, spread: np.ndarray, rng: np.random.Generator, count: int,
                     *scoring) -> int:
        """The triples ``spread`` and ``count`` drawn near each other, fitted and scored in one compiled call
        (:func:`.kernels.graph_batch`; ``scoring`` as it takes it after the graph)."""
        return kernels.graph_batch(cols, spread, *self.draws(rng, count), _SCALES, *self.graph, *scoring)


@dataclass(frozen=True, eq=False)
class _GraphRemaining(Remaining):
    """The region rule over the graph ``local`` of the points left: one compiled call per region."""

    local: GraphNeighbours
    ends: np.ndarray
    edge_rows: np.ndarray
    normals: np.ndarray

    @classmethod
    def of(cls, local: GraphNeighbours) -> _GraphRemaining:
        return cls(local, local.edge_ends, local.edge_rows, _NO_NORMALS if local.normals is None else local.normals)

    def keep(self, mask: np.ndarray, normal: np.ndarray, support: np.ndarray, above: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        return graph_region(self.ends, self.edge_rows, self.normals, mask, normal, support, above)

    def refitted(self, cols: np.ndarray, tolerances: np.ndarray, normals: np.ndarray, offsets: np.ndarray,
                 point_normals: np.ndarray | None, support: float, bound_cos: float, refits: int
                 ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray] | None:
        """One compiled call (:func:`.kernels.graph_plane`) when the points' normals are known."""
        if point_normals is None:
            return None
        return kernels.graph_plane(cols, tolerances, normals, offsets, support, bound_cos,
                                   kernels.c_array(point_normals, np.float64), self.ends, self.edge_rows,
                                   NORMAL_MIN_COS, REGION_RULES, refits)[1:]

    def without(self, left: np.ndarray) -> Remaining:
        return _GraphRemaining.of(self.local.subgraph(np.flatnonzero(left)))


def graph_region(ends: np.ndarray, edge_rows: np.ndarray, normals: np.ndarray, mask: np.ndarray, normal: np.ndarray,
                 support: np.ndarray, above: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(kept, taken) (n,) of a graph of n points joined by edges (``GraphNeighbours.edge_ends`` (e,), point i's from
    ``edge_rows[i]``, (n + 1,)) with local ``normals`` (n, 3) ((0, 3): none known) for a plane of ``normal`` with
    inliers ``mask`` (n,), support band ``support`` and side ``above``: :func:`.kernels.graph_region`
    (:func:`graph_region_numpy` is its reference)."""
    return kernels.graph_region(ends, edge_rows, normals, kernels.c_array(normal, np.float64), NORMAL_MIN_COS, mask,
                                support, above, REGION_RULES)


def graph_region_numpy(local: GraphNeighbours, mask: np.ndarray, normal: np.ndarray, support: np.ndarray,
                       above: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`graph_region` in numpy (:meth:`.neighbours.Neighbours.region` of the graph ``local``)."""
    coherent = local.coherent(normal)
    return local.region(mask & coherent, support & coherent, above)
