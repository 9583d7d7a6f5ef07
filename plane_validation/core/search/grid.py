"""An organized cloud's image sub-grid: which pixels a large image is searched on, and every pixel labelled
afterwards from the regions found on it."""
from __future__ import annotations

import functools

import numpy as np

from .. import kernels
from ..noise import ray_share
from .fit import plane_rows
from .neighbours_grid import EIGHT, GridNeighbours
from .types import Tolerance

__all__ = ['grid_step', 'grid_pixels', 'grid_image', 'grid_image_numpy', 'spread_grid', 'spread_grid_numpy',
           'MIN_GRID_SIDE']


#: An image whose (sub-)grid would have fewer rows or columns than this is searched as an unorganized
#: cloud: a line of pixels has no 2-D neighbourhood.
MIN_GRID_SIDE = 3


def grid_step(shape: tuple[int, int], n_valid: int, limit: int | None) -> int:
    """The step of the regular sub-grid of an H x W image (``shape``) with ``n_valid`` valid pixels that
    keeps about ``limit`` of them (1: every pixel; ``limit`` None: 1), taking rows and columns from
    step // 2 on; 0 when that grid would have fewer than MIN_GRID_SIDE rows or columns."""
    h, w = shape
    step = 1 if limit is None or n_valid <= limit else int(np.ceil(np.sqrt(n_valid / limit)))
    return step if min(len(range(step // 2, h, step)), len(range(step // 2, w, step))) >= MIN_GRID_SIDE else 0


def grid_pixels(finite: np.ndarray, shape: tuple[int, int], step: int) -> np.ndarray:
    """(gh, gw) the pixel (row-major index into the H x W image ``shape``) that stands for each
    step x step block of the sub-grid of :func:`grid_step`: the block's centre pixel (step // 2,
    step // 2) when valid (``finite`` (H * W,) bool), else its valid pixel nearest to the centre;
    -1 for a block without one. A depth camera's scattered lost pixels then leave no holes in the
    sub-grid, which would cut its 4-connected regions apart (from about 40 % lost on)."""
    return grid_image(np.empty((0, 3)), finite, shape, step)[1]


@functools.lru_cache(maxsize=16)
def _block_offsets(step: int) -> np.ndarray:
    """(step * step, 2) the (row, column) offsets within a block in the order :func:`grid_pixels` tries them: nearest
    to the centre first (ties by offset). Read-only."""
    c = step // 2
    offsets = np.array(sorted(((dr, dc) for dr in range(step) for dc in range(step)),
                              key=lambda o: ((o[0] - c) ** 2 + (o[1] - c) ** 2, o)), dtype=np.int64)
    offsets.flags.writeable = False
    return offsets


def grid_image(points: np.ndarray, finite: np.ndarray, shape: tuple[int, int], step: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """The sub-grid image of ``points`` (H * W, 3): (its (gh, gw, 3) points, NaN for blocks without a
    valid pixel, and their :func:`grid_pixels`). One compiled pass (:func:`.kernels.grid_sample`;
    :func:`grid_image_numpy` is its reference)."""
    image, pixels = kernels.grid_sample(kernels.c_array(points, np.float64), kernels.c_array(finite, bool), shape[1],
                                        step, kernels.c_array(_block_offsets(step), np.int64))
    return image.astype(points.dtype, copy=False), pixels


def grid_image_numpy(points: np.ndarray, finite: np.ndarray, shape: tuple[int, int], step: int
                     ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`grid_image` in numpy: the reference its kernel is tested against."""
    h, w = shape
    c = step // 2
    gh, gw = len(range(c, h, step)), len(range(c, w, step))
    valid = finite.reshape(h, w)
    pixels = np.full(gh * gw, -1, dtype=np.int64)
    block_r, block_c = np.divmod(np.arange(gh * gw), gw)
    missing = np.arange(gh * gw)
    for dr, dc in _block_offsets(step):  # the centre first, then ever farther pixels, for the blocks still without one
        r, col = block_r[missing] * step + dr, block_c[missing] * step + dc
        ok = (r < h) & (col < w)
        ok[ok] = valid[r[ok], col[ok]]
        pixels[missing[ok]] = r[ok] * w + col[ok]
        missing = missing[~ok]
        if len(missing) == 0:
            break
    pixels = pixels.reshape(gh, gw)
    image = np.full(pixels.shape + (3,), np.nan, dtype=points.dtype)
    image[pixels >= 0] = points[pixels[pixels >= 0]]
    return image, pixels


def spread_grid(pts: np.ndarray, valid: np.ndarray, shape: tuple[int, int], step: int, region: np.ndarray,
                neighbours: GridNeighbours, planes: list, tolerance: Tolerance, ray: np.ndarray = kernels.NO_RAY
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Labels (N,) of every pixel of the image ``pts`` (N, 3; ``valid`` (N,): its finite rows) from
    the regions of the searched sub-grid: the region of the nearest sub-grid pixel when the pixel is
    within ``tolerance`` of its plane (``planes`` in the coordinates of ``pts``), else, of the 3 x 3
    sub-grid pixels around it, the region whose plane is nearest within ``tolerance``; -1 otherwise.
    Also each region's rows, ascending, one after another (rows (c,), bounds (k + 1,)) and their squared distances
    to its plane (c,) m^2 in that order. One compiled pass (:func:`.kernels.grid_spread`; :func:`spread_grid_numpy`
    gives its labels and distances)."""
    near_r, near_c = _nearest_lines(shape, step, neighbours.shape)
    tol = kernels.c_array(np.reshape(tolerance, -1), np.float64)  # (1,) or (N,)
    return kernels.grid_spread(kernels.c_array(pts, np.float64), kernels.c_array(valid, bool),
                               kernels.c_array(neighbours.pixel, np.int64), kernels.c_array(region, np.int64),
                               *neighbours.shape, near_r, near_c, plane_rows(planes), tol, kernels.EIGHT, ray)


def _nearest_lines(shape: tuple[int, int], step: int, grid_shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """The nearest sub-grid row of each image row (H,) and column of each image column (W,), int64."""
    (h, w), (gh, gw) = shape, grid_shape
    near_r = np.clip(np.round((np.arange(h) - step // 2) / step).astype(np.int64), 0, gh - 1)
    near_c = np.clip(np.round((np.arange(w) - step // 2) / step).astype(np.int64), 0, gw - 1)
    return near_r, near_c


def _sub_regions(shape: tuple[int, int], step: int, region: np.ndarray, neighbours: GridNeighbours, k: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sub-grid's regions as an image (gh, gw) int64 (k: no region), and the nearest sub-grid row of each
    image row (H,) and column of each image column (W,)."""
    gh, gw = neighbours.shape
    sub = np.full(gh * gw, k, dtype=np.int64)
    sub[neighbours.pixel] = np.where(region >= 0, region, k)
    return (sub.reshape(gh, gw),) + _nearest_lines(shape, step, neighbours.shape)


def spread_grid_numpy(pts: np.ndarray, valid: np.ndarray, shape: tuple[int, int], step: int, region: np.ndarray,
                      neighbours: GridNeighbours, planes: list, tolerance: Tolerance, ray: np.ndarray = kernels.NO_RAY
                      ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`spread_grid`'s labels in numpy, and each pixel's distance to its label's plane (N,) meters (inf for
    none): the reference its kernel is tested against."""
    h, w = shape
    gh, gw = neighbours.shape
    k, n = len(planes), len(pts)
    sub, near_r, near_c = _sub_regions(shape, step, region, neighbours, k)
    dist = np.empty((k + 1, n))  # row k: no region; NaN rows compare False
    np.matmul(np.array([p[0] for p in planes]), pts.T, out=dist[:k])
    dist[:k] += np.array([p[1] for p in planes])[:, None]
    np.abs(dist[:k], out=dist[:k])
    dist[k] = np.inf
    flat = dist.reshape(-1)
    share = np.ones((k + 1, n))  # the share of each pixel's tolerance across each plane (row k: no region)
    share[:k] = ray_share(pts, np.array([p[0] for p in planes]), ray)
    band = (share * np.reshape(tolerance, (1, -1))).reshape(-1)  # (k + 1) * n: each pixel's tolerance for each plane
    # the nearest sub-grid pixel first, as whole images: most pixels take its region
    lab = sub.take(near_r, axis=0).take(near_c, axis=1).reshape(-1)
    d = flat[lab * n + np.arange(n)]
    take = d <= band[lab * n + np.arange(n)]
    out = np.where(take, lab, -1).astype(np.int32)
    best = np.where(take, d, np.inf)
    todo = np.flatnonzero(~take & valid)  # valid pixels left
    r, c = np.divmod(todo, w)
    around = np.pad(sub, 1, constant_values=k).reshape(-1)  # off the image: no region
    centre = (near_r[r] + 1) * (gw + 2) + near_c[c] + 1
    for dr, dc in EIGHT:  # the rest: the eight sub-grid pixels around the nearest one
        lab = around[centre + dr * (gw + 2) + dc]
        d = flat[lab * n + todo]
        better = (d <= band[lab * n + todo]) & (d < best[todo])
        out[todo[better]], best[todo[better]] = lab[better], d[better]
    return out, best
