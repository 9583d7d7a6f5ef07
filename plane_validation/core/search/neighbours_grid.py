"""The grid form of :class:`.neighbours.Neighbours`: the pixels of an image (or of its sub-grid), 4-connected
except across a depth jump, built by :func:`..regions.grid_neighbours`."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from .. import kernels
from .neighbours import (
    COMPETE_ROUNDS,
    NEARBY_SCALES,
    NORMAL_MIN_COS,
    REGION_RULES,
    Neighbours,
    Remaining,
    joined_components,
)

__all__ = ['GridNeighbours']

#: The 8 image neighbours (row, column offsets).
EIGHT = kernels.EIGHT
_NO_BRIDGES = np.empty((0, 3), np.int64)


@dataclass(frozen=True, eq=False, kw_only=True)
class GridNeighbours(Neighbours):
    """``shape`` (h, w) with point i at flat pixel ``pixel[i]``, ``node`` (h * w,) the point at each pixel (-1:
    none), ``usable`` (h * w,) the pixels that may join a region (valid, at no depth jump); ``wraps``: the last
    column is next to the first (a 360-degree lidar scan); ``bridges`` (b, 3): pixel pairs on either side of a run
    of pixels without a point that a region spans (:func:`..regions._bridges`), and whether the pair crosses the
    image's seam (1)."""

    shape: tuple[int, int]
    pixel: np.ndarray
    node: np.ndarray
    usable: np.ndarray | None = None
    wraps: bool = False
    bridges: np.ndarray | None = None

    def nearby(self, nodes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A random point within a window of NEARBY_SCALES pixels around each of ``nodes`` (m,); -1 where the
        window falls on no point."""
        scale = np.asarray(NEARBY_SCALES)[rng.integers(0, len(NEARBY_SCALES), len(nodes))]
        h, w = self.shape
        r, c = np.divmod(self.pixel[nodes], w)
        r = r + np.rint((2 * rng.random(len(nodes)) - 1) * scale).astype(np.int64)
        c = c + np.rint((2 * rng.random(len(nodes)) - 1) * scale).astype(np.int64)
        inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        return np.where(inside, self.node[np.where(inside, r * w + c, 0)], -1)

    def components(self, mask: np.ndarray) -> tuple[np.ndarray, int]:
        image = np.zeros(self.shape[0] * self.shape[1], bool)
        image[self.pixel[mask]] = True
        image &= self.usable
        labelled, count = ndimage.label(image.reshape(self.shape))
        labelled = labelled.reshape(-1)
        if count > 1 and self.bridges is not None and len(self.bridges):
            a, b = labelled[self.bridges[:, 0]], labelled[self.bridges[:, 1]]
            # a bridge across the seam only joins regions in the coplanar merge (touching), as the seam itself does
            joined = (a > 0) & (b > 0) & (a != b) & ~self.bridges[:, 2].astype(bool)
            if joined.any():  # components of the components joined by bridges; 0 (background) stays alone
                a, b = a[joined], b[joined]
                order = np.argsort(a, kind='stable')
                total, merged = joined_components(count + 1, a[order], b[order])
                renumber = np.full(total, -1, dtype=np.int64)
                renumber[np.arange(total) != merged[0]] = np.arange(total - 1)
                return renumber[merged[labelled[self.pixel]]], total - 1
        return labelled[self.pixel] - 1, count

    def _component(self, within: np.ndarray, counted: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        labels, count = self.components(within)
        if count == 0:
            return np.zeros(self.n, bool), np.zeros(0, np.int64)
        inside = labels >= 0 if counted is None else counted & (labels >= 0)
        sizes = np.bincount(labels[inside], minlength=count)
        return labels == int(np.argmax(sizes)), sizes

    def searchable(self) -> np.ndarray:
        return np.arange(self.n) if self.usable is None else np.flatnonzero(self.usable[self.pixel])

    def remaining(self, rest_idx: np.ndarray) -> Remaining:
        return _GridRemaining(self, rest_idx)

    def touching(self) -> tuple[np.ndarray, np.ndarray]:
        """Right and down neighbours that may both join a region (no depth jump between them), the last and first
        pixels of each row when the image wraps around, then the pixels on either side of a bridged run."""
        node = np.where(self.usable, self.node, -1).reshape(self.shape)
        src = [node[:, :-1].ravel(), node[:-1].ravel()] + ([node[:, -1]] if self.wraps else [])
        dst = [node[:, 1:].ravel(), node[1:].ravel()] + ([node[:, 0]] if self.wraps else [])
        if self.bridges is not None and len(self.bridges):
            src.append(node.reshape(-1)[self.bridges[:, 0]])
            dst.append(node.reshape(-1)[self.bridges[:, 1]])
        src, dst = np.concatenate(src), np.concatenate(dst)
        both = (src >= 0) & (dst >= 0)
        return src[both], dst[both]

    def around(self, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The 8 image neighbours, whatever their depth."""
        gh, gw = self.shape
        r, c = np.divmod(self.pixel[nodes], gw)
        r, c = r[:, None] + EIGHT[:, 0], c[:, None] + EIGHT[:, 1]
        inside = (r >= 0) & (r < gh) & (c >= 0) & (c < gw)
        near = np.where(inside, self.node[np.where(inside, r * gw + c, 0)], -1)
        ok = near >= 0
        return np.broadcast_to(nodes[:, None], near.shape)[ok], near[ok]

    def bordering(self, region: np.ndarray) -> np.ndarray:
        gh, gw = self.shape
        image = np.full(gh * gw, -1, dtype=np.int64)  # -1: no point
        image[self.pixel] = region
        pad = np.pad(image.reshape(gh, gw), 1, constant_values=-1)
        centre = pad[1:-1, 1:-1]
        out = np.zeros((gh, gw), bool)
        for dr, dc in EIGHT:
            other = pad[1 + dr:gh + 1 + dr, 1 + dc:gw + 1 + dc]
            out |= (other != centre) & (other >= 0)
        out &= centre >= 0
        return self.node[np.flatnonzero(out)]

    def tie_keys(self, src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, ...]:
        """The first image direction (the order of EIGHT, which is ascending src)."""
        return (src,)

    def settle(self, dist: np.ndarray, region: np.ndarray) -> np.ndarray:
        """One compiled call (:func:`.kernels.grid_compete`; :func:`.neighbours.settle_numpy` is its reference)."""
        region = kernels.grid_compete(dist, region, self.pixel, self.node, self.shape[1], EIGHT, COMPETE_ROUNDS)
        return np.where(region < dist.shape[0] - 1, region, -1)


@dataclass(frozen=True, eq=False)
class _GridRemaining(Remaining):
    """The region rule over the points ``rest_idx`` (ascending) of a grid."""

    neighbours: GridNeighbours
    rest_idx: np.ndarray

    def keep(self, mask: np.ndarray, normal: np.ndarray, support: np.ndarray, above: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        rule = grid_region if self.neighbours.normals is not None else grid_region_numpy
        return rule(self.neighbours, self.rest_idx, mask, normal, support, above)

    def without(self, left: np.ndarray) -> Remaining:
        return _GridRemaining(self.neighbours, self.rest_idx[left])


def grid_region(neighbours: GridNeighbours, rest_idx: np.ndarray, mask: np.ndarray, normal: np.ndarray,
                support: np.ndarray, above: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(kept, taken) (r,) of the points ``rest_idx`` (r,) of a sub-grid for a plane of ``normal`` with inliers
    ``mask`` (r,), support band ``support`` (r,) and side ``above`` (r,): one compiled call
    (:func:`.kernels.grid_region`; :func:`grid_region_numpy` is its reference)."""
    bridges = _NO_BRIDGES if neighbours.bridges is None else kernels.c_array(neighbours.bridges, np.int64)
    return kernels.grid_region(neighbours.pixel, neighbours.node, neighbours.usable, neighbours.shape[1], bridges,
                               neighbours.normals, kernels.c_array(normal, np.float64), NORMAL_MIN_COS, rest_idx,
                               mask, support, above, REGION_RULES)


def grid_region_numpy(neighbours: GridNeighbours, rest_idx: np.ndarray, mask: np.ndarray, normal: np.ndarray,
                      support: np.ndarray, above: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`grid_region` in numpy (:meth:`.neighbours.Neighbours.region`)."""
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
