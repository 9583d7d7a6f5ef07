"""Sensor noise models: how the inlier tolerance grows with range, and the noise a segmentation shows.

* ``constant``: one tolerance ``t`` everywhere (the paper).
* ``depth_quadratic``: a depth camera's noise grows as the square of the range, so a point at range
  r (meters, from the sensor: the origin of the cloud's frame, or the ``viewpoint`` given) is an inlier within
  t(r) = t0 * max(1, (r / reference)^2). The tolerance ``t`` that :func:`~.ransac.detect_planes`
  and the tuner take is then t0, the tolerance up to ``reference`` meters.
* ``auto`` (the tuner's, :func:`~.tuning.tune_tolerance`): one of the two, chosen from the noise the cloud shows
  (:meth:`.noise_estimate.NoiseEstimate.model`). A search at a given t takes it as ``constant``: that t is then the
  tolerance everywhere, as given (:func:`searched_model`).

Pure numpy, no ROS import.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ['NOISE_MODELS', 'AUTO', 'TUNED_NOISE_MODELS', 'NOISE_REFERENCE', 'MAX_SCALE', 'check_noise_model',
           'searched_model', 'tolerance_scale', 'ray_band', 'ray_share', 'RAY_FLOOR',
           'noise_coefficient']

NOISE_MODELS = ('constant', 'depth_quadratic')
#: The tuner's choice between them, and every model a tuner (and the parameter table) takes.
AUTO = 'auto'
TUNED_NOISE_MODELS = (AUTO, *NOISE_MODELS)
#: Range (meters) up to which depth_quadratic keeps t0; beyond it the tolerance grows as range^2.
NOISE_REFERENCE = 1.0
#: ... up to this factor (10 reference ranges): a depth camera sees no farther, and a far-out row (a
#: driver's FLT_MAX) must not become an inlier of every plane.
MAX_SCALE = 100.0
#: With depth_quadratic the noise runs along each viewing ray u, so the connected-regions search takes a point within
#: t * max(|n . u|, RAY_FLOOR) of a plane of normal n: a plane the ray grazes (a table top seen past its edge face, a
#: slab through a far wall) gets a narrow band, one facing the sensor the whole band. The floor keeps a band where
#: the ray is nearly parallel to the plane (a grazing floor's far points). Indoor tuning seeds 0-23, auto-tuned: 140
#: -> 149 of 196 planes correct at 0.2, 146 at 0.35 (140 at 0.35 without border settling and merges).
RAY_FLOOR = 0.2


def check_noise_model(noise_model: str, reference: float, models: tuple[str, ...] = NOISE_MODELS) -> float:
    """The reference range as a float (meters); ValueError on a model not in ``models`` or a reference range that is
    not a distance > 0."""
    from .ransac import check_number  # ransac imports this module
    if noise_model not in models:
        why = '; auto is chosen by tune_tolerance: a search at a given t takes constant or depth_quadratic' \
            if noise_model == AUTO else ''
        raise ValueError(f'unknown noise_model {noise_model!r}; choose one of {", ".join(models)}{why}')
    number = check_number('noise_reference', reference, 'a finite range > 0 m')
    if number <= 0:
        raise ValueError(f'noise_reference must be a finite range > 0 m, got {reference!r}')
    return number


def searched_model(noise_model: str, chosen: str | None = None) -> str:
    """The model a search at a given t runs with: ``noise_model`` itself, or for ``auto`` the model a sweep
    ``chosen`` (None: no sweep chose the t, which is then ``constant``)."""
    return (chosen or NOISE_MODELS[0]) if noise_model == AUTO else noise_model


def tolerance_scale(points: np.ndarray, noise_model: str = 'constant',
                    reference: float = NOISE_REFERENCE, viewpoint: Sequence[float] | np.ndarray | None = None
                    ) -> np.ndarray | None:
    """(N,) factor the tolerance is multiplied by at each point of ``points`` (N, 3) meters, or None
    for ``constant`` (a factor of 1 everywhere): max(1, (r / reference)^2), at most MAX_SCALE, r the
    range from ``viewpoint`` (3,) (default the origin). NaN rows give NaN."""
    reference = check_noise_model(noise_model, reference)
    if noise_model == 'constant':
        return None
    if viewpoint is not None and np.any(viewpoint):
        points = points - viewpoint
    with np.errstate(over='ignore'):
        squared = np.einsum('ij,ij->i', points, points) / reference ** 2
    return np.clip(squared, 1.0, MAX_SCALE, where=~np.isnan(squared), out=squared)


def ray_band(viewpoint: np.ndarray, noise_model: str) -> np.ndarray:
    """(4,) the ``viewpoint`` (3,) meters and RAY_FLOOR: how the search kernels measure a tolerance along the rays
    (:func:`.kernels._facing`) with depth_quadratic; (0,) (a tolerance across the plane) with any other model."""
    if noise_model != 'depth_quadratic':
        return np.empty(0)
    return np.append(np.asarray(viewpoint, dtype=np.float64), RAY_FLOOR)


def ray_share(points: np.ndarray, normals: np.ndarray, ray: np.ndarray) -> np.ndarray:
    """(k, N) the share of a tolerance along the rays that lies across each plane of unit ``normals`` (k, 3) at each
    of ``points`` (N, 3) meters: max(|n . u|, floor) for ``ray`` (4,) of :func:`ray_band`, 1 for an empty ``ray``
    (the reference of :func:`.kernels._facing`)."""
    if len(ray) == 0:
        return np.ones((len(normals), len(points)))
    rays = points - ray[:3]
    with np.errstate(invalid='ignore', divide='ignore'):
        along = np.abs(normals @ rays.T) / np.linalg.norm(rays, axis=1)
    return np.where(along > ray[3], along, ray[3])  # NaN (a point at the viewpoint): the floor


def noise_coefficient(points: np.ndarray, labels: np.ndarray, coefficients: np.ndarray,
                      viewpoint: Sequence[float] | np.ndarray | None = None) -> float:
    """c (1/m) of depth noise sigma(r) = c * r^2 along each viewing ray, fitted to the planes' residuals.

    points (N, 3) meters; labels (N,) plane index or -1; coefficients (k, 4) planes (a, b, c, d) with
    unit normals; viewpoint (3,): the sensor in these coordinates (default the origin). Range noise dr
    moves a point along its ray u by dr, i.e. by dr (n . u) from its plane, so each residual is
    c r^2 (n . u) times unit noise; c is the least-squares fit of that over every plane point
    (grazing points, n . u ~ 0, weigh little).
    NaN without plane points.
    """
    own = (labels >= 0) & (labels < len(coefficients)) & np.isfinite(points).all(axis=1)
    if not own.any():
        return float('nan')
    pts = points[own]
    plane = np.asarray(coefficients, float)[labels[own]]
    residual = np.einsum('ij,ij->i', pts, plane[:, :3]) + plane[:, 3]
    if viewpoint is not None and np.any(viewpoint):
        pts = pts - viewpoint
    projection = np.einsum('ij,ij->i', pts, plane[:, :3])
    ranges = np.sqrt(np.einsum('ij,ij->i', pts, pts))
    along = np.abs(projection) / np.maximum(ranges, 1e-12)  # |n . u|
    model = ranges ** 2 * along
    with np.errstate(over='ignore', invalid='ignore'):
        denominator = float(np.sum(model ** 2))
        value = float(np.sqrt(np.sum(residual ** 2) / denominator)) if denominator > 0 else float('nan')
    return value if np.isfinite(value) else float('nan')
