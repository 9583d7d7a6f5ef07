"""The sensor's noise from local plane residuals, before and independent of any segmentation.

Small neighbourhoods (5 x 5 pixels of an organized cloud, the nearest points otherwise) are nearly always on one
surface; their residuals about their own best plane are the sensor's noise, and the few that straddle an edge or lie
on clutter are outliers a low quantile ignores. The noise is fitted as sigma(r) = a + b r^2 over the range r from
the viewpoint, which covers both noise models of :mod:`.noise` (``constant``: b = 0).

Two kinds of residual:

* along the ray, when the viewpoint is the sensor (most neighbourhoods face it): 1 / r is linear in the unit ray
  direction on a plane (n . p + d = 0 gives 1 / r = -(n . u) / d), so each neighbourhood is a least-squares fit of
  1 / r on its exact ray directions; its residuals times r^2 are range residuals. Unlike a neighbourhood's
  thickness, this holds when the noise is as large as the neighbourhood (a depth camera's far pixels);
* perpendicular to the neighbourhood's plane (its smallest principal axis), when the viewpoint sees the surfaces
  edge-on (a roof centred on its mean): b is then 0, as a range from no sensor means nothing.

Pure numpy/scipy and the compiled kernels, no ROS import.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import kernels
from .noise import NOISE_MODELS, NOISE_REFERENCE
from .ransac import as_points, check_viewpoint, finite_rows, generator

__all__ = ['NoiseEstimate', 'estimate_noise', 'PATCHES', 'NEIGHBOURS']

#: Neighbourhoods sampled (at most), and about how many points a voxel of an unorganized cloud holds (at least
#: MIN_VOXEL_POINTS to count; its side refined up to VOXEL_REFINE times).
PATCHES = 1500
NEIGHBOURS = 24
MIN_VOXEL_POINTS, VOXEL_REFINE = 10, 4
#: An organized cloud's neighbourhood: PATCH_SIDE x PATCH_SIDE pixels, PATCH_STRIDE apart (wider than the
#: quantisation's and the sub-pixel structure's scale, still small against a surface).
PATCH_SIDE, PATCH_STRIDE = 5, 2
#: The viewpoint is taken as the sensor when the median |cos| between a neighbourhood's normal and its ray is at
#: least this (depth frames and lidar scans: 0.5-0.9; roofs seen from their own centre: under 0.2), or, in an
#: unorganized cloud, when at least MIN_BIN neighbourhoods face it that closely, enough for one range bin of the fit
#: along the rays: a lidar corridor's walls run away from the sensor at grazing angles, where a neighbourhood's
#: thickness is only the range noise times |cos| (tuning seeds: 36-49 % of a corridor's 83-145 neighbourhoods face
#: it, 47-71 of them, against 2-32 of a roof's 57-90 but steep hips', which face their centre by the median too).
#: Neighbourhoods seen at a smaller |cos| are then left out.
FACING_COS = 0.3
#: A neighbourhood is thin, its smallest principal axis its plane's normal, when the smallest eigenvalue of its
#: scatter is at most this share of the middle one (its thickness a third of its width).
FLAT = 1 / 9
#: ... and broad, not a strip, when the middle eigenvalue is at least this share of the largest (at most 4 times as
#: long as wide).
BROAD = 1 / 16
#: The quantile of the neighbourhoods' residual variances taken as the noise (corrected for the chi-square spread
#: of a variance estimated from a few points): below the median, as edges and clutter only inflate residuals.
QUANTILE = 0.3
#: Range bins the fit of a + b r^2 uses (equal counts), each of at least MIN_BIN neighbourhoods; a bin more than
#: OFF_FIT times off the first fits is left out of the last.
BINS, MIN_BIN = 8, 40
OFF_FIT = 2.0
#: A neighbourhood whose RMS residual is below this share of its range is on one quantisation step or noise-free
#: (float32 coordinates: 6e-8): not counted.
RESOLUTION = 1e-6
#: Without a residual above it on at least this share of the neighbourhoods (a Kinect frame as a plain array: 62 %),
#: the rest are edges: no estimate.
MEASURABLE = 0.5
#: ``auto`` takes a cloud as a depth camera's (``depth_quadratic``) when the part of sigma growing with range is at
#: least this share of sigma at the median range. On the tuning split the depth frames read 0.75-1.0 (a
#: Kinect-like b r^2 dominates), the lidar scans, roofs and SynPEB 0-0.02.
QUADRATIC_SHARE = 0.5
#: ... and only from a fit over at least this many range bins, twice the fit's parameters: a lidar corridor's
#: neighbourhoods fall in two bins, the far one grazing walls (lidar_scan_corridor_22 and _40 of the tuning seeds:
#: 11 and 167 mm, a range term from one outlier); the depth frames fill all BINS.
MODEL_BINS = 4
#: ... and only for a cloud whose median point is at least this factor's range beyond the reference range, where
#: depth_quadratic's tolerance is that many times constant's. Within it the two differ little, and the constant
#: sweep's range reaches the surfaces' own roughness where that is above the sensor's noise: milk_cartoon's carton
#: fronts (0.6-0.8 m, 1 mm of noise) became planes at 16 mm, and at no t0 within 5 sigmas.
MIN_FACTOR = 2.0
#: NoiseEstimate.level takes the ranges of about this many points.
LEVEL_POINTS = 20_000
#: At most this many points of an unorganized cloud are hashed into voxels (a random probe).
PROBE_POINTS = 20_000


@dataclass(frozen=True)
class NoiseEstimate:
    """The sensor noise sigma(r) = a + b r^2: standard deviation (meters) at range r (meters) from the viewpoint.

    a: m; b: 1/m (0 when not ``along_ray``); reference: the range (m) ``sigma_reference`` = a + b reference^2 is at;
    along_ray: the residuals are ranges along each ray (the viewpoint is the sensor), else perpendicular to the
    surfaces (isotropic noise); ranges, sigmas: each range bin's median range and robust sigma (m); patches: the
    neighbourhoods used. All NaN, with patches 0, when too few neighbourhoods were found or none has a residual
    above the coordinates' precision (a noise-free cloud)."""

    a: float
    b: float
    reference: float
    sigma_reference: float
    along_ray: bool
    ranges: tuple[float, ...]
    sigmas: tuple[float, ...]
    patches: int

    def sigma(self, r: np.ndarray | float) -> np.ndarray | float:
        """sigma (m) at range ``r`` (m), any shape."""
        return self.a + self.b * np.square(r)

    def model(self, points: np.ndarray, viewpoint=None) -> str:
        """The noise model (:mod:`.noise`) this estimate calls for: ``depth_quadratic`` when the residuals run along
        the rays, fitted over MODEL_BINS range bins or more, and at the median range r of ``points`` (N, 3) m from
        ``viewpoint`` the part growing with range, b r^2, is at least QUADRATIC_SHARE of sigma and r^2 is at least
        MIN_FACTOR reference^2; else ``constant`` (also without an estimate)."""
        fitted = self.patches and self.along_ray and self.b > 0 and len(self.ranges) >= MODEL_BINS
        ranges = _ranges(points, viewpoint) if fitted else np.empty(0)
        if not len(ranges):
            return NOISE_MODELS[0]
        r = float(np.median(ranges))
        beyond = r * r >= MIN_FACTOR * self.reference ** 2  # where depth_quadratic's t differs from constant's
        return NOISE_MODELS[1] if beyond and self.b * r * r >= QUADRATIC_SHARE * self.sigma(r) else NOISE_MODELS[0]

    def level(self, points: np.ndarray, viewpoint=None, quantile: float = 0.5) -> float:
        """The ``quantile`` of sigma over the finite rows of ``points`` (N, 3) m (every n-th of them beyond
        LEVEL_POINTS): the noise a constant tolerance meets (NaN without an estimate or points)."""
        ranges = _ranges(points, viewpoint) if self.patches else np.empty(0)
        return float(np.quantile(self.sigma(ranges), quantile)) if len(ranges) else float('nan')


def _ranges(points: np.ndarray, viewpoint) -> np.ndarray:
    """Ranges (m) from ``viewpoint`` of the finite rows of ``points`` (N, 3) m, every n-th of them beyond
    LEVEL_POINTS."""
    pts = as_points(points)
    pts = pts[::max(1, len(pts) // LEVEL_POINTS)]
    pts = pts[finite_rows(pts)] - check_viewpoint(viewpoint)
    return np.sqrt(np.einsum('ij,ij->i', pts, pts))


def _image_patches(valid: np.ndarray, shape: tuple[int, int], count: int, rng: np.random.Generator
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(members, starts) of up to ``count`` fully valid patches of PATCH_SIDE^2 pixels, PATCH_STRIDE apart, centred
    on random pixels of an H x W image (``valid`` (H W,) its finite rows)."""
    h, w = shape
    half = (PATCH_SIDE // 2) * PATCH_STRIDE
    k = PATCH_SIDE ** 2
    if h <= 2 * half or w <= 2 * half:
        return np.empty(0, np.int64), np.zeros(1, np.int64)
    offsets = np.arange(-half, half + 1, PATCH_STRIDE)
    flat = (offsets[:, None] * w + offsets[None, :]).ravel()
    # more centres than wanted: patches over a hole or the image border are dropped
    centres = rng.integers(half, h - half, 2 * count) * w + rng.integers(half, w - half, 2 * count)
    idx = centres[:, None] + flat[None, :]
    idx = idx[valid[idx].all(axis=1)][:count]
    return idx.ravel(), np.arange(0, len(idx) * k + 1, k, dtype=np.int64)


def _voxel_patches(pts: np.ndarray, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(members, starts) of up to ``count`` voxels of the finite ``pts`` (n, 3) holding at least MIN_VOXEL_POINTS
    each, the voxel side chosen so that an occupied voxel holds about NEIGHBOURS (the points of a larger one: its
    first 2 NEIGHBOURS)."""
    lo, hi = kernels.coordinate_bounds(pts)
    extent = hi - lo
    size = float(extent.max())
    if not size > 0:
        return np.empty(0, np.int64), np.zeros(1, np.int64)
    cell = size / np.sqrt(max(len(pts) / NEIGHBOURS, 1.0))  # as if the points covered one square sheet
    for _ in range(VOXEL_REFINE):
        if np.prod(extent / cell + 2) > 2.0 ** 60:  # the voxel keys would overflow (a far-out point): none
            return np.empty(0, np.int64), np.zeros(1, np.int64)
        order, _, bounds, _ = kernels.voxel_grid(pts, lo, cell, (extent // cell).astype(np.int64) + 2)
        sizes = np.diff(bounds)
        typical = float(np.median(sizes[sizes >= MIN_VOXEL_POINTS])) if np.any(sizes >= MIN_VOXEL_POINTS) else 1.0
        if 0.7 * NEIGHBOURS <= typical <= 1.5 * NEIGHBOURS:
            break
        cell *= float(np.clip(np.sqrt(NEIGHBOURS / typical), 0.25, 4.0))  # points on surfaces: count ~ side^2
    else:
        order, _, bounds, _ = kernels.voxel_grid(pts, lo, cell, (extent // cell).astype(np.int64) + 2)
    sizes = np.diff(bounds)
    full = np.flatnonzero(sizes >= MIN_VOXEL_POINTS)
    if len(full) > count:
        full = np.sort(rng.choice(full, count, replace=False))
    take = np.minimum(sizes[full], 2 * NEIGHBOURS)
    starts = np.concatenate([[0], np.cumsum(take)]).astype(np.int64)
    members = order[np.repeat(bounds[full], take) + np.arange(starts[-1]) - np.repeat(starts[:-1], take)]
    return members.astype(np.int64), starts


def _patch_fits_numpy(points: np.ndarray, members: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, ...]:
    """Plain-numpy reference of :func:`.kernels.patch_fits` (one neighbourhood at a time)."""
    out = np.full((7, len(starts) - 1), np.nan)
    for j in range(len(starts) - 1):
        p = points[members[starts[j]:starts[j + 1]]]
        k, centre = len(p), p.mean(axis=0)
        values, axes = np.linalg.eigh((p - centre).T @ (p - centre))
        rc = float(np.linalg.norm(centre))
        out[2:, j] = (max(values[0], 0.0) / (k - 3), abs(axes[:, 0] @ centre) / rc if rc > 0 else np.nan,
                      max(values[0], 0.0) / values[1] if values[1] > 0 else 1.0,
                      max(values[1], 0.0) / values[2] if values[2] > 0 else 0.0, rc)
        r = np.linalg.norm(p, axis=1)
        if rc > 0 and np.all(r > 0):
            u = p / r[:, None]
            w, _, rank, _ = np.linalg.lstsq(u, 1 / r, rcond=None)
            if rank == 3:
                out[0, j] = np.sum(((1 / r - u @ w) * r ** 2) ** 2) / (k - 3)
                out[1, j] = abs(w @ centre) / (np.linalg.norm(w) * rc)
    return tuple(out)


def _fit(ranges: np.ndarray, sigmas: np.ndarray, counts: np.ndarray) -> tuple[float, float]:
    """a, b >= 0 of sigma = a + b r^2 through the bins' (ranges, sigmas) m: least squares in error relative to the
    model (each bin's sigma has about the same relative spread; relative to the data a bin of near zero, a wall on one
    depth step, would pull the fit to it), twice, then again without bins off the model by more than OFF_FIT."""
    from scipy.optimize import nnls  # here: a node answers its first frame without scipy.optimize (0.1-0.2 s)
    keep = np.ones(len(ranges), bool)
    model = np.full(len(ranges), float(np.median(sigmas)))
    for step in range(3):
        weight = np.sqrt(counts) / np.maximum(model, 1e-12 * max(float(sigmas.max()), 1e-300))
        design = np.column_stack([weight, weight * ranges ** 2])
        (a, b), _ = nnls(design[keep], (weight * sigmas)[keep])
        model = a + b * ranges ** 2
        if step == 1:
            with np.errstate(divide='ignore', invalid='ignore'):
                keep = np.abs(np.log(sigmas / model)) <= np.log(OFF_FIT)
            if keep.sum() < 2:
                break
    return float(a), float(b)


def _empty(reference: float, along_ray: bool = False) -> NoiseEstimate:
    nan = float('nan')
    return NoiseEstimate(nan, nan, reference, nan, along_ray, (), (), 0)


def estimate_noise(points: np.ndarray, shape: tuple[int, int] | None = None, *, viewpoint=None,
                   reference: float = NOISE_REFERENCE, patches: int = PATCHES, seed=None) -> NoiseEstimate:
    """The sensor noise of a cloud, sigma(r) = a + b r^2, from the residuals of small neighbourhoods about their own
    planes (module docstring).

    points: (N, 3) meters, NaN rows allowed; shape (H, W): the rows are an image (neighbourhoods of PATCH_SIDE^2
    pixels), else NEIGHBOURS nearest points; viewpoint (3,) m: the sensor (default the origin); reference: the range
    (m) of ``sigma_reference``; patches: neighbourhoods sampled at most; seed: which ones.
    """
    pts = as_points(points)
    view = check_viewpoint(viewpoint)
    rng = generator(seed)
    valid = finite_rows(pts)
    if shape is not None:
        if len(shape) != 2 or shape[0] * shape[1] != len(pts):
            raise ValueError(f'shape {tuple(shape)} does not hold {len(pts)} rows')
        searched = pts
        members, starts = _image_patches(valid, (int(shape[0]), int(shape[1])), patches, rng)
    else:
        searched = pts[valid]
        if len(searched) > PROBE_POINTS:
            searched = searched[rng.choice(len(searched), PROBE_POINTS, replace=False)]
        members, starts = _voxel_patches(kernels.c_array(searched, np.float64), patches, rng) \
            if len(searched) >= MIN_VOXEL_POINTS else (np.empty(0, np.int64), np.zeros(1, np.int64))
    if len(starts) - 1 < MIN_BIN:
        return _empty(reference)
    ray_var, ray_facing, perp_var, plane_facing, flatness, breadth, ranges = kernels.patch_fits(
        kernels.c_array(searched[members] - view, np.float64), np.arange(len(members), dtype=np.int64), starts)
    dof = np.diff(starts) - 3
    # a thin, broad neighbourhood's own axis says how it faces the viewpoint; of one thicker than wide (noise along
    # the ray beyond its width) or a strip (a lidar ring: flat across whatever the noise) only the ray fit can say
    plate = (flatness <= FLAT) & (breadth >= BROAD)
    facing = np.where(plate, plane_facing, ray_facing)
    faced = facing >= FACING_COS
    along_ray = bool(np.nanmedian(facing) >= FACING_COS) if np.any(np.isfinite(facing)) else False
    # a minority facing the viewpoint tells only of an unorganized cloud's nearest points: an image's window spans a
    # lidar ring image's rings (8 of 16: no one surface), and depth frames face their camera by the median
    grazing = not along_ray and shape is None and int(faced.sum()) >= MIN_BIN
    along_ray = along_ray or grazing
    variances = ray_var if along_ray else np.where(plate, perp_var, np.nan)
    # residuals at the coordinates' own precision say nothing about the noise: one step of a quantized depth (a
    # Kinect's at 3 m is 2.6 cm: a third of the voxels of a frame lie on one), a noise-free render
    ok = variances > (RESOLUTION * ranges) ** 2
    if along_ray:  # at a grazing angle a range residual is the thickness over |cos|: of noise across the surface too
        ok &= faced
    if ok.sum() < max(MIN_BIN, MEASURABLE * (faced.sum() if grazing else len(ok))):  # what is left is edges: the
        return _empty(reference, along_ray)                                            # noise is below the precision
    variances, ranges = variances[ok], ranges[ok]
    nu = int(np.median(dof[ok])) if ok.any() else 1
    # the quantile of a variance over nu dof, over its mean: the chi-square quantile, 2 P^-1(nu / 2, q) (scipy.special,
    # not scipy.stats: importing that took a second of a node's start)
    from scipy.special import gammaincinv  # here: as nnls (_fit)
    correction = 2 * gammaincinv(nu / 2, QUANTILE) / nu
    if not along_ray or len(variances) < 2 * MIN_BIN:
        if not len(variances):
            return _empty(reference, along_ray)
        sigma = float(np.sqrt(np.quantile(variances, QUANTILE) / correction))
        return NoiseEstimate(sigma, 0.0, reference, sigma, along_ray, (float(np.median(ranges)),), (sigma,),
                             int(len(variances)))
    bins = min(BINS, len(variances) // MIN_BIN)
    order = np.argsort(ranges)
    centres, sigmas, counts = [], [], []
    for part in np.array_split(order, bins):
        centres.append(float(np.median(ranges[part])))
        sigmas.append(float(np.sqrt(np.quantile(variances[part], QUANTILE) / correction)))
        counts.append(len(part))
    a, b = _fit(np.array(centres), np.array(sigmas), np.array(counts))
    return NoiseEstimate(float(a), float(b), reference, float(a + b * reference ** 2), True, tuple(centres),
                         tuple(sigmas), int(len(variances)))
