"""One plane's shape, measured on a fixed sample of its inliers: its principal frame, its patches (the cells of a
grid along its in-plane axes), how much worse one plane fits it than its patches do (the lack of fit), and the fold
line and the tent that may fit it better. The verdict (:mod:`.verdict`) judges with these; the search's fold and
tent splits (:mod:`.search.folds`) use them too. Points are (m, 3) meters; a frame is :func:`principal_frame`'s tuple.
"""
from __future__ import annotations

import numpy as np

from . import kernels
from .noise import tolerance_scale
from .ransac import Segmentation, as_points

__all__ = ['inlier_samples', 'inlier_sample', 'sample_rows', 'principal_frame', 'frame_thickness', 'patch_cells',
           'patches_of', 'symmetric_eigenvalues', 'plane_tolerance', 'lack_of_fit', 'lack_from_noise', 'patch_noise',
           'fold_of', 'fold_line', 'fold_points', 'is_ridge', 'tent_of', 'quadric_fit', 'plane_lack_of_fit',
           'plane_fold', 'plane_tent', 'plane_thickness', 'THICKNESS_POINTS', 'TILT_NEIGHBOURS', 'TILT_MIN_PATCHES',
           'FOLD_LACK', 'FOLD_FIT', 'TENT_ANGLES']

#: A plane's shape is measured on a fixed random subset of this many of its inliers (when it has more).
THICKNESS_POINTS = 4096
#: A plane's patches: cells of a grid along its in-plane principal axes that hold about this many of its sampled
#: inliers on average (cells with half that or more count).
TILT_NEIGHBOURS = 32
#: A plane is judged on at least this many patches: the tilt on its patches with a determined normal
#: (verdict.plane_tilt), the lack of fit on its noisy ones (below).
TILT_MIN_PATCHES = 16
#: The lack of fit (plane_lack_of_fit) is judged on at least TILT_MIN_PATCHES patches, and on most of them, whose RMS
#: thickness is over this share of their spread: flatter ones are noise-free up to float32 rounding, or lie on one
#: depth step of a quantizing sensor without noise (a sensor's noise is 1e-2 of a patch's spread or more).
EXACT_PATCH = 1e-4
#: ... and the patches' RMS thickness counts as at least the plane's tolerance over this: deviations from one plane
#: far inside the band of +-t (a noise-free render's depth steps and warps, 0.3 mm against t = 13 mm on icl_office_0,
#: or a real wall's bow seen by a precise sensor) are not several surfaces. At a good t the noise is t / 2 or more.
LACK_OF_FIT_FLOOR = 8.0
#: A plane whose lack of fit is at least FOLD_LACK (below MAX_LACK_OF_FIT) and falls to FOLD_FIT or less with two
#: planes meeting at a line (kernels.fold_line: FOLD_ANGLES directions, FOLD_OFFSETS lines each within the middle
#: FOLD_INNER of the points), which fit it better than a quadric surface does, holds the two sides of a ridge or a
#: fold: the residuals of one in-plane direction form a V. Chosen on the tuning split of benchmarks/quality.py (its
#: scenes and 74 more tuning seeds; benchmarks/README.md): it fails 2 of 660 planes on one true plane and 31 % of the
#: planes holding two (a lack of fit of 2 or more alone: 15 %), measured with 18 directions on up to 4,096 points;
#: with these settings it judges the split's scenes alike: 5 merged 2-4 degree gables more are not reliable, and no
#: auto-tuned scene that is good. Real depth
#: frames, whose error is correlated across a surface, read a lack of fit of 1.2-2.0 on single walls, which a lower
#: MAX_LACK_OF_FIT would fail; a fold explains little of it there (1.58 -> 1.48 on the Kinect frame's floor).
FOLD_LACK = 1.3
FOLD_FIT = 1.1
FOLD_ANGLES = 12
FOLD_OFFSETS = 15
FOLD_INNER = 0.7
#: ... searched on at most this many of the plane's sampled inliers (every so many-th): about 0.2 ms a plane.
FOLD_POINTS = 1024
#: The tent (see plane_tent) is fitted with its box turned through this many directions.
TENT_ANGLES = 12


def patch_cells(pca) -> tuple[np.ndarray, np.ndarray] | None:
    """(counts (p,), scatter (p, 3, 3)) of the patches of one plane's sampled inliers (its :func:`principal_frame`; see
    :func:`patches_of`); None for too few inliers."""
    if pca is None or len(pca[1]) < 2 * TILT_NEIGHBOURS:
        return None
    _, centred, _, vectors = pca
    return kernels.plane_patches(centred, np.ascontiguousarray(vectors[:, 1:]), TILT_NEIGHBOURS, TILT_NEIGHBOURS // 2)


def patches_of(pca, axes: bool = True, cells: tuple | None = None
             ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray] | None:
    """The patches of one plane's sampled inliers (its :func:`principal_frame`): the cells of a square grid along their
    in-plane principal axes, sized to hold TILT_NEIGHBOURS of them on average (cells with half that or more count). Per
    patch the eigenvalues (p, 3) ascending and, with ``axes``, eigenvectors (p, 3, 3) of its scatter (per point, m^2),
    and its points (p,); None for too few inliers. Without ``axes`` the eigenvalues come in closed form
    (:func:`.kernels.patch_eigenvalues`; :func:`symmetric_eigenvalues` is its numpy reference). ``cells``: its
    :func:`patch_cells` when known."""
    if cells is None:
        cells = patch_cells(pca)
    if cells is None:
        return None
    counts, scatter = cells
    if not len(counts):
        return None
    if axes:
        values, vectors = np.linalg.eigh(scatter)
        return values, vectors, counts
    return kernels.patch_eigenvalues(scatter), None, counts


def symmetric_eigenvalues(m: np.ndarray) -> np.ndarray:
    """The eigenvalues (p, 3), ascending, of symmetric 3 x 3 matrices ``m`` (p, 3, 3), by the trigonometric closed
    form (a tenth of np.linalg.eigvalsh's time on a few hundred small matrices)."""
    off = m[:, 0, 1] ** 2 + m[:, 0, 2] ** 2 + m[:, 1, 2] ** 2
    diag = np.stack([m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=1)
    q = diag.mean(axis=1)
    p = np.sqrt((((diag - q[:, None]) ** 2).sum(axis=1) + 2 * off) / 6)
    safe = np.where(p > 0, p, 1.0)
    b = (m - q[:, None, None] * np.eye(3)) / safe[:, None, None]
    det = (b[:, 0, 0] * (b[:, 1, 1] * b[:, 2, 2] - b[:, 1, 2] * b[:, 2, 1])
           - b[:, 0, 1] * (b[:, 1, 0] * b[:, 2, 2] - b[:, 1, 2] * b[:, 2, 0])
           + b[:, 0, 2] * (b[:, 1, 0] * b[:, 2, 1] - b[:, 1, 1] * b[:, 2, 0]))
    r = np.clip(det / 2, -1.0, 1.0)
    phi = np.arccos(r) / 3
    big = q + 2 * p * np.cos(phi)
    small = q + 2 * p * np.cos(phi + 2 * np.pi / 3)
    out = np.stack([small, 3 * q - big - small, big], axis=1)
    return np.where((off == 0)[:, None], np.sort(diag, axis=1), out)


def plane_lack_of_fit(points: np.ndarray, seg: Segmentation) -> np.ndarray:
    """Per plane the RMS distance of its inliers to their best-fit plane over the RMS thickness of its patches (see
    patches_of; each patch's own best-fit plane; at least t / LACK_OF_FIT_FLOOR): about 1 or less on one surface,
    whatever its noise and however the noise varies across it; larger where the surface bends away from one plane
    (a shallow gable roof, or a table top and the floor beside it, found as one plane). NaN where there are too few
    inliers. ``points`` (N, 3) meters."""
    return np.array([lack_of_fit(principal_frame(inl), plane_tolerance(inl, seg))
                     for inl in inlier_samples(as_points(points), seg)])


def plane_tolerance(inl: np.ndarray, seg: Segmentation, scale: np.ndarray | None | bool = False) -> float:
    """The tolerance (m) of ``seg`` at one plane's inliers ``inl`` (m, 3): its median under the noise model (its
    :func:`.noise.tolerance_scale` at them when known as ``scale``)."""
    if scale is False:
        scale = tolerance_scale(inl, seg.noise_model, seg.noise_reference, seg.viewpoint) if len(inl) else None
    return float(seg.tolerance * (1.0 if scale is None or not len(inl) else np.median(scale)))


def lack_of_fit(pca, tolerance: float, cells: tuple | None = None) -> float:
    """:func:`plane_lack_of_fit` of one plane from its sampled inliers' :func:`principal_frame` (and its
    :func:`patch_cells` when known) and its ``tolerance`` (m)."""
    return lack_from_noise(pca, patch_noise(pca, tolerance, cells))


def lack_from_noise(pca, local: float | None) -> float:
    """The lack of fit of one plane from its sampled inliers' :func:`principal_frame` and its :func:`patch_noise`
    ``local`` (m^2); NaN where not judged (``local`` None)."""
    return float(np.sqrt(max(float(pca[2][0]), 0.0) / len(pca[1]) / local)) if local is not None else float('nan')


def patch_noise(pca, tolerance: float, cells: tuple | None = None) -> float | None:
    """The mean squared thickness (m^2) of one plane's patches (see plane_lack_of_fit; at least (t /
    LACK_OF_FIT_FLOOR)^2), from its sampled inliers' :func:`principal_frame` (and its :func:`patch_cells` when known);
    None where not judged."""
    patches = patches_of(pca, axes=False, cells=cells)
    if patches is None:
        return None
    values, _, counts = patches
    # a patch exactly flat up to rounding lies on one step of a quantizing sensor: it tells nothing of the noise
    noisy = values[:, 0] > (EXACT_PATCH * values[:, 2]) ** 2
    if np.count_nonzero(noisy) < max(TILT_MIN_PATCHES, len(noisy) / 2):  # noise-free: only edge patches are thick
        return None
    values, counts = values[noisy], counts[noisy]
    weight = counts.sum(dtype=np.float64)  # both means weighted by the points, as np.average sums them
    local = float(np.multiply(values[:, 0], counts, dtype=np.float64).sum() / weight)
    # per-patch eigenvalues of a few dozen points underestimate their noise by about (n - 3) / n
    local *= float(np.multiply(counts / np.maximum(counts - 3, 1), counts, dtype=np.float64).sum() / weight)
    return max(local, (tolerance / LACK_OF_FIT_FLOOR) ** 2)


def plane_fold(points: np.ndarray, seg: Segmentation) -> np.ndarray:
    """Per plane its lack of fit (see plane_lack_of_fit) with two planes meeting at a line in place of one (the best
    of kernels.fold_line's lines) and with a quadric surface, (k, 2): about 1 and more on the two sides of a ridge
    found as one plane, whose lack of fit with one plane is larger; NaN where there are too few inliers. ``points``
    (N, 3) meters."""
    samples = inlier_samples(as_points(points), seg)
    return np.array([fold_of(principal_frame(inl), plane_tolerance(inl, seg)) for inl in samples]).reshape(-1, 2)


def fold_of(pca, tolerance: float, local: float | None = None, ridge_only: bool = False) -> tuple[float, float]:
    """:func:`plane_fold` of one plane from its sampled inliers' :func:`principal_frame` and its ``tolerance`` (m);
    ``local``: its :func:`patch_noise` when known. With ``ridge_only`` the quadric is fitted only where the fold could
    make a ridge (FOLD_FIT or less; judge compares the two only there), NaN elsewhere."""
    return fold_line(pca, tolerance, local, ridge_only)[:2]


def fold_line(pca, tolerance: float, local: float | None = None, ridge_only: bool = False
              ) -> tuple[float, float, float, float]:
    """:func:`fold_of` of one plane and the line of its best fold (:func:`.kernels.fold_line`): (fold, quadric, theta
    (rad), s0 (m)), the line at s0 along (cos theta, sin theta) in the plane's in-plane principal axes (``pca[3]``'s
    columns 1 and 2) from its sampled inliers' centre ``pca[0]``; NaN where not judged."""
    if local is None and pca is not None:
        local = patch_noise(pca, tolerance)
    if local is None:
        return float('nan'), float('nan'), float('nan'), float('nan')
    u, v, w = fold_points(pca)
    mse, theta, s0 = kernels.fold_line(u, v, w, FOLD_ANGLES, FOLD_OFFSETS, FOLD_INNER)
    fold = float(np.sqrt(mse / local))
    quadric = float('nan') if ridge_only and not fold <= FOLD_FIT else quadric_fit(u, v, w, local)
    return fold, quadric, float(theta), float(s0)


def fold_points(pca) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The points the fold and the tent are fitted to, every so many-th of one plane's sampled inliers (its
    :func:`principal_frame`; at most FOLD_POINTS): their in-plane coordinates u, v and residuals w (m,), meters,
    C-ordered."""
    w, u, v = (pca[1][::-(-len(pca[1]) // FOLD_POINTS)] @ pca[3]).T
    return np.ascontiguousarray(u), np.ascontiguousarray(v), np.ascontiguousarray(w)


def is_ridge(lack: float, fold: float, quadric: float) -> bool:
    """Whether a plane of lack of fit ``lack`` whose fold and quadric fit it to ``fold`` and ``quadric`` (see
    :func:`fold_line`) holds the two sides of a ridge: ``lack`` at least FOLD_LACK, the fold FOLD_FIT or less and
    better than the quadric (judge fails it below MAX_LACK_OF_FIT; above, as surfaces merged)."""
    return bool(lack >= FOLD_LACK and fold <= FOLD_FIT and fold < quadric)


def plane_tent(points: np.ndarray, seg: Segmentation) -> np.ndarray:
    """Per plane its lack of fit (see plane_lack_of_fit) with a tent in place of one plane (residuals rising evenly
    with the distance from the edges of its points' bounding box, the best of TENT_ANGLES turns of the box) and with a
    quadric surface, (k, 2): about 1 and more on the faces of a hip roof found as one plane, whose lack of fit with one
    plane is larger; NaN where there are too few inliers. ``points`` (N, 3) meters."""
    out = []
    for inl in inlier_samples(as_points(points), seg):
        pca = principal_frame(inl)
        out.append(tent_of(pca, None if pca is None else patch_noise(pca, plane_tolerance(inl, seg))))
    return np.array(out).reshape(-1, 2)


def tent_of(pca, local: float | None, quadric: float = np.nan, ridge_only: bool = False) -> tuple[float, float]:
    """:func:`plane_tent` of one plane from its sampled inliers' :func:`principal_frame` and its :func:`patch_noise`
    ``local`` (m^2); the ``quadric``'s lack of fit when known (else fitted). With ``ridge_only`` the quadric is fitted
    only where the tent fits FOLD_FIT or less (judge compares the two only there), NaN elsewhere."""
    if local is None:
        return float('nan'), float('nan')
    u, v, w = fold_points(pca)
    tent = float(np.sqrt(kernels.tent_fit(u, v, w, TENT_ANGLES) / local))
    if np.isnan(quadric) and not (ridge_only and not tent <= FOLD_FIT):
        quadric = quadric_fit(u, v, w, local)
    return tent, float(quadric)


def quadric_fit(u: np.ndarray, v: np.ndarray, w: np.ndarray, local: float) -> float:
    """The lack of fit of residuals ``w`` (m,) with a quadric surface over in-plane coordinates (u, v) (m,), all
    meters, against the patches' mean squared thickness ``local`` (m^2)."""
    design = np.column_stack([u * u, u * v, v * v, u, v, np.ones_like(u)])
    coef, *_ = np.linalg.lstsq(design, w, rcond=None)
    return float(np.sqrt(np.mean((w - design @ coef) ** 2) / local))


def plane_thickness(points: np.ndarray, seg: Segmentation) -> np.ndarray:
    """Per plane sqrt(l0 / l1) of its inlier scatter (smallest over middle eigenvalue): RMS
    thickness over in-plane spread, 0 for a perfect plane, ~0.15 for the paper's corner at e = 7.5,
    ~0.3 for a slab cut out of a sphere."""
    return np.array([frame_thickness(principal_frame(inl)) for inl in inlier_samples(points, seg)])


def inlier_samples(points: np.ndarray, seg: Segmentation) -> list[np.ndarray]:
    """Per plane the (m, 3) inliers its shape is judged on (:func:`inlier_sample`)."""
    return [inlier_sample(points, plane.inliers) for plane in seg.planes]


def principal_frame(inl: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """(centre (3,), centred (m, 3), eigenvalues (3,) ascending, eigenvectors (3, 3) as columns) of one plane's
    inliers ``inl`` (m, 3); None for fewer than 3."""
    if len(inl) < 3:
        return None
    centre = inl.mean(axis=0)
    centred = inl - centre
    values, vectors = np.linalg.eigh(centred.T @ centred)
    return centre, centred, values, vectors


def frame_thickness(pca) -> float:
    """:func:`plane_thickness` of one plane from its :func:`principal_frame`."""
    if pca is None:
        return np.inf
    ev = pca[2]
    return float(np.sqrt(max(ev[0], 0.0) / ev[1])) if ev[1] > 0 else np.inf


def inlier_sample(points: np.ndarray, rows: np.ndarray) -> np.ndarray:
    return np.take(points, sample_rows(rows), axis=0)  # (much faster than points[rows] on rows of 3)


def sample_rows(rows: np.ndarray) -> np.ndarray:
    """The rows (m,) of a plane's inlier ``rows`` its shape is judged on."""
    if len(rows) > THICKNESS_POINTS:  # a fixed random subset: the ratios are robust statistics
        rows = rows[kernels.seeded_draws(len(rows), THICKNESS_POINTS)]  # default_rng(m).integers(0, m, ...)
    return rows
