"""The grid form of :class:`.neighbours.Neighbours`: the pixels of an image (or of its sub-grid), built by
:func:`.grid_build.grid_neighbours`, 4-connected where a pixel is usable (the far pixel of a depth jump is not).
Components come from ``scipy.ndimage.label``.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from .. import kernels
from .neighbours import (
    COMPETE_ROUNDS,
    NEARBY_SCALES,
    NORMAL_MIN_COS,
    REGION_RULES,
    Neighbours,
    Remaining,
    joined_components,
    settle_numpy,
)

__all__ = ['GridNeighbours', 'GridSampler', 'grid_region', 'grid_region_numpy', 'rest_positions', 'EIGHT']

#: The 8 image neighbours (row, column offsets).
EIGHT = kernels.EIGHT
_NO_BRIDGES = np.empty((0, 3), np.int64)
_SCALES = np.array(NEARBY_SCALES, np.int64)


@dataclass(frozen=True, eq=False, kw_only=True)
class GridNeighbours(Neighbours):
    """``shape`` (h, w) with point i at flat pixel ``pixel[i]``, ``node`` (h * w,) the point at each pixel (-1:
    none), ``usable`` (h * w,) the pixels that may join a region (valid, at no depth jump); ``wraps``: the last
    column is next to the first (a 360-degree lidar scan); ``bridges`` (b, 3): pixel pairs on either side of a run
    of pixels without a point that a region spans (:func:`.grid_build._bridges`), and whether the pair crosses the
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

    def sampler(self, rest_idx: np.ndarray) -> GridSampler:
        """The same draws as :meth:`.neighbours.Neighbours.sampler` (its reference), the triples from them in one
        compiled call (:func:`.kernels.grid_triples`)."""
        position = np.full(self.n + 1, -1, dtype=np.int64)  # [-1] stays -1
        position[rest_idx] = np.arange(len(rest_idx))
        h, w = self.shape
        return GridSampler((_SCALES, kernels.c_array(rest_idx, np.int64), position, self.pixel, self.node, h, w))

    def components(self, mask: np.ndarray) -> tuple[np.ndarray, int]:
        image = np.zeros(self.shape[0] * self.shape[1], bool)
        image[self.pixel[mask]] = True
        image &= self.usable
        from scipy import ndimage  # here: scipy.ndimage takes about 0.1 s to import, and few frames need it
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

    def contacts(self, region: np.ndarray, k: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """One compiled pass (:func:`.kernels.grid_contacts`; :meth:`.neighbours.Neighbours.contacts` is its
        reference)."""
        bridges = _NO_BRIDGES if self.bridges is None else kernels.c_array(self.bridges, np.int64)
        contacts = kernels.grid_contacts(self.node, self.usable, self.shape[1], self.wraps, bridges,
                                         kernels.c_array(region, np.int64), k)
        return contacts if len(contacts[0]) else None

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
        """:func:`.neighbours.settle_numpy` (the search settles by :meth:`settle_planes`)."""
        return settle_numpy(dist, region, self)

    def settle_planes(self, search: np.ndarray, planes: np.ndarray, tolerance: np.ndarray, viewpoint: np.ndarray,
                      min_cos: float, region: np.ndarray, ray: np.ndarray = kernels.NO_RAY) -> np.ndarray:
        """One compiled call (:func:`.kernels.grid_settle`, which works out only the distances it compares;
        :func:`.neighbours.settle_numpy` is its reference)."""
        region = kernels.grid_settle(search, planes, tolerance, viewpoint, min_cos, region, self.pixel, self.node,
                                         self.shape[1], EIGHT, COMPETE_ROUNDS, ray)
        return np.where(region < len(planes), region, -1)


@dataclass(frozen=True, eq=False)
class GridSampler:
    """Triples of nearby points among the points ``rest`` (ascending) of a sub-grid (a :data:`.types.Sampler`):
    ``grid`` holds the sub-grid as :func:`.kernels.grid_triples` takes it after the draws (scales, rest, each point's
    place in rest (n + 1,), pixel, node, height, width)."""

    grid: tuple

    def draws(self, rng: np.random.Generator, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The random draws of ``count`` triples: their first points (places in rest), and for the 2 * count nearby
        points a scale (index into NEARBY_SCALES) and row and column shares in [0, 1)."""
        first = rng.integers(0, len(self.grid[1]), count)
        scale_pick = rng.integers(0, len(NEARBY_SCALES), 2 * count)
        row_share, col_share = rng.random(2 * count), rng.random(2 * count)
        return first, scale_pick, row_share, col_share

    def __call__(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """(count, 3) positions in rest, -1 where a nearby point is not among them."""
        return kernels.grid_triples(*self.draws(rng, count), *self.grid)

    def scored_batch(self, cols: np.ndarray, spread: np.ndarray, rng: np.random.Generator, count: int,
                     *scoring) -> int:
        """The triples ``spread`` and ``count`` drawn near each other, fitted and scored in one compiled call
        (:func:`.kernels.grid_batch`; ``scoring`` as it takes it after the grid)."""
        return kernels.grid_batch(cols, spread, *self.draws(rng, count), *self.grid, *scoring)


@dataclass(frozen=True, eq=False)
class _GridRemaining(Remaining):
    """The region rule over the points ``rest_idx`` (ascending) of a grid."""

    neighbours: GridNeighbours
    rest_idx: np.ndarray
    #: the viewpoint and floor of a tolerance along the rays (:func:`.noise.ray_band`) in scoring hypotheses and in the
    #: region rule; kernels.NO_RAY: across the plane
    ray: np.ndarray = field(default_factory=lambda: kernels.NO_RAY)

    @functools.cached_property
    def position(self) -> np.ndarray:
        """(n,) each point's place in ``rest_idx``, -1 for none (shared by the calls for one plane)."""
        return rest_positions(self.neighbours.n, self.rest_idx)

    def keep(self, mask: np.ndarray, normal: np.ndarray, support: np.ndarray, above: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        rule = grid_region if self.neighbours.normals is not None else grid_region_numpy
        return rule(self.neighbours, self.rest_idx, mask, normal, support, above, self.position)

    def without(self, left: np.ndarray) -> Remaining:
        return _GridRemaining(self.neighbours, self.rest_idx[left], self.ray)

    def _compiled(self, point_normals: np.ndarray | None) -> tuple | None:
        """The sub-grid arguments of :func:`.kernels.grid_plane` and :func:`.kernels.grid_refit`, from the points'
        normals (3, r) (``point_normals``, or the grid's own at these points when None) to the region rules; None when
        the grid's normals or usable pixels are unknown."""
        nb = self.neighbours
        if nb.normals is None or nb.usable is None:
            return None
        if point_normals is None:
            point_normals = np.ascontiguousarray(nb.normals.take(self.rest_idx, axis=0).T)
        bridges = _NO_BRIDGES if nb.bridges is None else kernels.c_array(nb.bridges, np.int64)
        return (point_normals, nb.pixel.take(self.rest_idx), nb.usable, nb.shape[1], bridges, NORMAL_MIN_COS,
                REGION_RULES)

    def best(self, cols: np.ndarray, tolerances: np.ndarray, normals: np.ndarray, offsets: np.ndarray,
             point_normals: np.ndarray | None, support: float, bound_cos: float) -> tuple[int, np.ndarray, np.ndarray]:
        """One compiled call (:func:`.kernels.grid_plane` without refits)."""
        grid = self._compiled(point_normals)
        if grid is None:
            return super().best(cols, tolerances, normals, offsets, point_normals, support, bound_cos)
        winner, _, _, region, taken = kernels.grid_plane(cols, tolerances, normals, offsets, support, bound_cos, *grid,
                                                         0, self.ray, self.ray)
        return int(winner), region, taken

    def refitted(self, cols: np.ndarray, tolerances: np.ndarray, normals: np.ndarray, offsets: np.ndarray,
                 point_normals: np.ndarray | None, support: float, bound_cos: float, refits: int
                 ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray] | None:
        """One compiled call (:func:`.kernels.grid_plane`)."""
        grid = self._compiled(point_normals)
        if grid is None:
            return None
        return kernels.grid_plane(cols, tolerances, normals, offsets, support, bound_cos, *grid, refits, self.ray,
                                  self.ray)[1:]

    def refit(self, cols: np.ndarray, tolerances: np.ndarray, region: np.ndarray, support: float
              ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
        """One compiled call (:func:`.kernels.grid_refit`)."""
        grid = self._compiled(None)
        if grid is None:
            return super().refit(cols, tolerances, region, support)
        return kernels.grid_refit(cols, region, tolerances, support, *grid, self.ray)


def rest_positions(n: int, rest_idx: np.ndarray) -> np.ndarray:
    """(n,) int64: the place of each of n points in ``rest_idx`` (ascending), -1 for the others."""
    position = np.full(n, -1, dtype=np.int64)
    position[rest_idx] = np.arange(len(rest_idx))
    return position


def grid_region(neighbours: GridNeighbours, rest_idx: np.ndarray, mask: np.ndarray, normal: np.ndarray,
                support: np.ndarray, above: np.ndarray, position: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """(kept, taken) (r,) of the points ``rest_idx`` (r,) of a sub-grid for a plane of ``normal`` with inliers
    ``mask`` (r,), support band ``support`` (r,) and side ``above`` (r,) (``position``: :func:`rest_positions`, when
    already known): one compiled call (:func:`.kernels.grid_region`; :func:`grid_region_numpy` is its reference)."""
    bridges = _NO_BRIDGES if neighbours.bridges is None else kernels.c_array(neighbours.bridges, np.int64)
    if position is None:
        position = rest_positions(neighbours.n, rest_idx)
    return kernels.grid_region(neighbours.pixel, neighbours.node, neighbours.usable, neighbours.shape[1], bridges,
                               neighbours.normals, kernels.c_array(normal, np.float64), NORMAL_MIN_COS, rest_idx,
                               position, mask, support, above, REGION_RULES)


def grid_region_numpy(neighbours: GridNeighbours, rest_idx: np.ndarray, mask: np.ndarray, normal: np.ndarray,
                      support: np.ndarray, above: np.ndarray, position: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`grid_region` in numpy (:meth:`.neighbours.Neighbours.region`; ``position`` unused)."""
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
