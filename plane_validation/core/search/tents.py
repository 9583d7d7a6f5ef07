"""Regions that hold the faces of a shallow hip roof or pyramid (a tent), split into those faces.

A hip roof of a few degrees lies within t of one plane at any t that holds a face of it, and its residuals then rise
evenly from the edges of its points' bounding box (the verdict's tent test, :func:`.plane_shape.plane_tent`). Where a
region reads so, and better than as a quadric surface or as one fold (:mod:`.folds`), its faces are found by
piecewise-planar refinement from the tent: the tent's four faces are the start, each point goes to the face of the
roof's envelope above it (the lowest face for a roof, the highest for a pit: noise along the residual moves a point
past every face alike, so the face does not depend on it), each face is refitted to its points, and again
(Magnani and Boyd's convex piecewise-linear fitting). The split is kept only where the faces bring the region's
residuals down to its noise (FOLD_FIT of the patches' thickness, as the tent test) and each face keeps enough points.
"""
from __future__ import annotations

import numpy as np

from .fit import allows_normal, fit_columns
from .types import Allows

__all__ = ['tent_faces', 'TENT_ROUNDS']

#: At most this many rounds of the refinement (each point to its face of the envelope, each face refitted); it stops
#: sooner where no point changes face.
TENT_ROUNDS = 10


def tent_faces(cols: np.ndarray, pca, local: float, least: float, allows: Allows = None
               ) -> tuple[np.ndarray, list] | None:
    """The faces of the tent in the region's points ``cols`` (3, r) meters (its sample's
    :func:`.plane_shape.principal_frame` ``pca``, the patches' mean squared thickness ``local`` m^2): (each point's
    face (r,) 0..f-1, the f >= 2 faces' (normal, offset) planes), or None where the faces fit no better than FOLD_FIT
    of the noise, a face keeps fewer than ``least`` points (those left out along the way: fewer than two faces left),
    or ``allows`` refuses one's normal."""
    from .. import plane_shape  # it imports ransac, which imports the search: with the module, a cycle
    centre, axes = pca[0], pca[3]
    w, u, v = ((cols.T - centre) @ axes).T
    design = np.column_stack([np.ones_like(u), u, v])  # (r, 3): a face is w = design @ c
    coef, sign = _tent_start(u, v, w, plane_shape.TENT_ANGLES)
    face = None
    for _ in range(TENT_ROUNDS):
        heights = design @ coef.T  # (r, f)
        new = np.argmin(sign * heights, axis=1)  # the envelope's face over each point
        if face is not None and np.array_equal(new, face):
            break
        face = new
        counts = np.bincount(face, minlength=len(coef))
        keep = counts >= max(least, 3)
        if np.count_nonzero(keep) < 2:
            return None
        coef = np.array([np.linalg.lstsq(design[face == k], w[face == k], rcond=None)[0]
                         for k in np.flatnonzero(keep)])
    face = np.argmin(sign * (design @ coef.T), axis=1)
    residual = w - np.take_along_axis(design @ coef.T, face[:, None], axis=1)[:, 0]
    counts = np.bincount(face, minlength=len(coef))
    if not np.sqrt(np.mean(residual ** 2) / local) <= plane_shape.FOLD_FIT or len(coef) < 2 or counts.min() < least:
        return None
    planes = [fit_columns(np.ascontiguousarray(cols[:, face == k])) for k in range(len(coef))]
    if not all(allows_normal(allows, normal) for normal, _ in planes):
        return None
    return face, planes


def _tent_start(u: np.ndarray, v: np.ndarray, w: np.ndarray, angles: int) -> tuple[np.ndarray, float]:
    """The best tent w = a + b d over (u, v, w) (r,) meters (d: the distance to the nearest edge of the points'
    bounding box turned through ``angles`` directions; :func:`.kernels.tent_fit`) as its four faces' coefficients
    (4, 3) of w = c0 + c1 u + c2 v, and the envelope's sign: 1 where the tent rises from its edges (each point on the
    lowest face), -1 where it falls."""
    best = None
    for k in range(angles):
        theta = 0.5 * np.pi * k / angles
        c, s = np.cos(theta), np.sin(theta)
        along, across = u * c + v * s, v * c - u * s
        # each edge's distance as an affine function of (u, v): (constant, du, dv)
        edges = np.array([[-along.min(), c, s], [along.max(), -c, -s], [-across.min(), -s, c], [across.max(), s, -c]])
        d = np.min(edges[:, :1].T + np.outer(u, edges[:, 1]) + np.outer(v, edges[:, 2]), axis=1)
        slope, intercept = np.polyfit(d, w, 1)
        mse = float(np.mean((w - intercept - slope * d) ** 2))
        if best is None or mse < best[0]:
            best = (mse, edges, slope, intercept)
    _, edges, slope, intercept = best
    coef = slope * edges
    coef[:, 0] += intercept
    return coef, 1.0 if slope > 0 else -1.0
