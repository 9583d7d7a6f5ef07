"""What the search asks of a neighbourhood: regions of a plane's inliers, nearby points, touching pairs and
border settling."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .. import kernels
from ..regions import FRAGMENT_PIECE, FRAGMENTED, NORMAL_MIN_COS, SUPPORT_BALANCE, Neighbours
from .types import Sampler

__all__: list[str] = []


#: What :func:`.kernels.grid_region` needs of :mod:`.regions`' rules, in its order.
_REGION_RULES = np.array([FRAGMENTED, FRAGMENT_PIECE, SUPPORT_BALANCE])


_NO_BRIDGES = np.empty((0, 3), np.int64)


def _grid_region(neighbours: Neighbours, rest_idx: np.ndarray, mask: np.ndarray, normal: np.ndarray,
                 support: np.ndarray, above: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(kept, taken) (r,) of the points ``rest_idx`` (r,) of a sub-grid for a plane of ``normal`` with inliers
    ``mask`` (r,), support band ``support`` (r,) and side ``above`` (r,): one compiled call
    (:func:`.kernels.grid_region`; :func:`_grid_region_numpy` is its reference)."""
    bridges = _NO_BRIDGES if neighbours.bridges is None else kernels.c_array(neighbours.bridges, np.int64)
    return kernels.grid_region(neighbours.pixel, neighbours.node, neighbours.usable, neighbours.shape[1], bridges,
                               neighbours.normals, kernels.c_array(normal, np.float64), NORMAL_MIN_COS, rest_idx,
                               mask, support, above, _REGION_RULES)


_NO_NORMALS = np.empty((0, 3))


def _graph_region(edges: np.ndarray, normals: np.ndarray, mask: np.ndarray, normal: np.ndarray, support: np.ndarray,
                  above: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(kept, taken) (n,) of a graph of n points joined by ``edges`` (e, 2) with local ``normals`` (n, 3) ((0, 3):
    none known) for a plane of ``normal`` with inliers ``mask`` (n,), support band ``support`` and side ``above``:
    :func:`.kernels.graph_region` (:func:`_graph_region_numpy` is its reference)."""
    return kernels.graph_region(edges, normals, kernels.c_array(normal, np.float64), NORMAL_MIN_COS, mask, support,
                                above, _REGION_RULES)


def _graph_region_numpy(local: Neighbours, mask: np.ndarray, normal: np.ndarray, support: np.ndarray,
                        above: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_graph_region` in numpy (:meth:`.regions.Neighbours.region` of the graph ``local``)."""
    coherent = local.coherent(normal)
    return local.region(mask & coherent, support & coherent, above)


def _grid_region_numpy(neighbours: Neighbours, rest_idx: np.ndarray, mask: np.ndarray, normal: np.ndarray,
                       support: np.ndarray, above: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_grid_region` in numpy (:meth:`.regions.Neighbours.region`)."""
    n = neighbours.n
    wide = np.zeros(n, bool)
    wide[rest_idx[support]] = True
    wide &= neighbours.coherent(normal)  # an edge's normals cut the support as they cut the region
    full = np.zeros(n, bool)
    full[rest_idx[mask]] = True
    up = np.zeros(n, bool)
    up[rest_idx[support & above]] = True  # only the support's side is read: a far smaller scatter
    kept, taken = neighbours.region(full & wide, wide, up)
    return kept[rest_idx], taken[rest_idx]


def _nearby_sampler(neighbours: Neighbours, rest_idx: np.ndarray) -> Sampler:
    """Triples of nearby points among the points ``rest_idx`` (ascending) of ``neighbours``, as
    positions in ``rest_idx`` (-1: the nearby point is not among them)."""
    position = np.full(neighbours.n + 1, -1, dtype=np.int64)  # [-1] stays -1
    position[rest_idx] = np.arange(len(rest_idx))

    def sample(rng: np.random.Generator, count: int) -> np.ndarray:
        first = rng.integers(0, len(rest_idx), count)
        near = position[neighbours.nearby(np.tile(rest_idx[first], 2), rng)]
        return np.column_stack([first, near[:count], near[count:]])
    return sample


def _adjacent(neighbours: Neighbours) -> tuple[np.ndarray, np.ndarray]:
    """(src, dst) point pairs of the searched points that touch: graph edges, or right and down
    neighbours on the sub-grid that may both join a region (no depth jump between them), and the last
    and first pixels of each row when the image wraps around (a 360-degree scan); then the pixels on
    either side of a short run of pixels without a point (Neighbours.bridges)."""
    if neighbours.shape is None:
        return neighbours.edges[:, 0], neighbours.edges[:, 1]
    node = np.where(neighbours.usable, neighbours.node, -1).reshape(neighbours.shape)
    src = [node[:, :-1].ravel(), node[:-1].ravel()] + ([node[:, -1]] if neighbours.wraps else [])
    dst = [node[:, 1:].ravel(), node[1:].ravel()] + ([node[:, 0]] if neighbours.wraps else [])
    if neighbours.bridges is not None and len(neighbours.bridges):
        src.append(node.reshape(-1)[neighbours.bridges[:, 0]])
        dst.append(node.reshape(-1)[neighbours.bridges[:, 1]])
    src, dst = np.concatenate(src), np.concatenate(dst)
    both = (src >= 0) & (dst >= 0)
    return src[both], dst[both]


#: Rounds of border settling in _compete: a region can win back this many pixels (or graph hops)
#: of a strip that a plane found before it took.
COMPETE_ROUNDS = 6


def _settle(dist: np.ndarray, region: np.ndarray, neighbours: Neighbours) -> np.ndarray:
    """The rounds of :func:`_compete` in numpy (graph form; on a sub-grid the reference of
    :func:`.kernels.grid_compete`): ``dist`` (k + 1, m), ``region`` (m,) 0..k (k: none)."""
    k, m = dist.shape[0] - 1, dist.shape[1]
    flat = dist.reshape(-1)
    best = flat[region * m + np.arange(m)]  # row k (no region) is inf
    around = _around(neighbours)
    dst, src = around(_bordering(neighbours, region))
    for _ in range(COMPETE_ROUNDS):
        cand = region[src]
        d = flat[cand * m + dst]
        better = d < best[dst]
        if not better.any():
            break
        dst, src, cand, d = dst[better], src[better], cand[better], d[better]
        # per point its nearest offer; equal distances: on a grid the first image direction (the
        # order of _EIGHT, which is ascending src), on a graph a smaller-index neighbour, then the
        # largest one
        ties = (src,) if neighbours.shape is not None else (-src, src > dst)
        order = np.lexsort(ties + (d, dst))
        first = order[np.r_[True, dst[order[1:]] != dst[order[:-1]]]]
        changed = dst[first]
        region[changed], best[changed] = cand[first], d[first]  # the offers above read the old labels
        src, dst = around(changed)  # their neighbours, offered the new labels
    return np.where(region < k, region, -1)


#: The 8 image neighbours (row, column offsets).
_EIGHT = kernels.EIGHT


def _around(neighbours: Neighbours) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """A function of points ``nodes`` (c,) giving every (node, neighbour) pair as two arrays: the 8
    image neighbours on a grid (whatever their depth), graph neighbours otherwise."""
    if neighbours.shape is not None:
        gh, gw = neighbours.shape

        def on_grid(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            r, c = np.divmod(neighbours.pixel[nodes], gw)
            r, c = r[:, None] + _EIGHT[:, 0], c[:, None] + _EIGHT[:, 1]
            inside = (r >= 0) & (r < gh) & (c >= 0) & (c < gw)
            near = np.where(inside, neighbours.node[np.where(inside, r * gw + c, 0)], -1)
            ok = near >= 0
            return np.broadcast_to(nodes[:, None], near.shape)[ok], near[ok]
        return on_grid
    indptr, indices = neighbours.adjacency if neighbours.adjacency is not None else \
        (np.zeros(neighbours.n + 1, np.int64), np.empty(0, np.int64))

    def on_graph(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        degree = indptr[nodes + 1] - indptr[nodes]
        start = np.repeat(indptr[nodes] - np.cumsum(degree) + degree, degree)
        return np.repeat(nodes, degree), indices[start + np.arange(len(start))]
    return on_graph


def _bordering(neighbours: Neighbours, region: np.ndarray) -> np.ndarray:
    """The points (ascending) with a neighbour (as in :func:`_around`) in another region than theirs."""
    if neighbours.shape is None:
        src, dst = neighbours.edges.T
        differ = region[src] != region[dst]
        out = np.zeros(neighbours.n, bool)
        out[src[differ]] = out[dst[differ]] = True
        return np.flatnonzero(out)
    gh, gw = neighbours.shape
    image = np.full(gh * gw, -1, dtype=np.int64)  # -1: no point
    image[neighbours.pixel] = region
    pad = np.pad(image.reshape(gh, gw), 1, constant_values=-1)
    centre = pad[1:-1, 1:-1]
    out = np.zeros((gh, gw), bool)
    for dr, dc in _EIGHT:
        other = pad[1 + dr:gh + 1 + dr, 1 + dc:gw + 1 + dc]
        out |= (other != centre) & (other >= 0)
    out &= centre >= 0
    return neighbours.node[np.flatnonzero(out)]
