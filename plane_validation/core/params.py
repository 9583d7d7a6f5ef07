"""How a search runs, as one frozen value: every setting of :func:`.ransac.detect_planes` but the cloud's own.

Built once from the parameter table (``PipelineConfig.search``) and passed on as keywords
(``detect_planes(points, t, seed=..., shape=..., **search.kwargs())``; :func:`.tuning.tune_tolerance` and
:func:`.tuning.select_plane_count` take the same keywords), so that the node, replay and every command search
alike. The public functions keep their keyword arguments and defaults for API users.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from .orientation import Orientation

__all__ = ['SearchParams']


@dataclass(frozen=True)
class SearchParams:
    """max_planes; min_inliers: a count, or a share of the valid points when < 1; probability, max_iterations:
    RANSAC's; ransac_points, grid_points: the search sample's sizes (None: every point); connectivity: regions
    (False: the paper's infinite planes); noise_model, noise_reference (meters); viewpoint: (x, y, z) meters;
    orientation: the constraint on the normals (None: any)."""

    max_planes: int
    min_inliers: int | float
    probability: float
    max_iterations: int
    ransac_points: int | None
    grid_points: int | None
    connectivity: bool
    noise_model: str
    noise_reference: float
    viewpoint: tuple[float, float, float]
    orientation: Orientation | None

    def kwargs(self) -> dict[str, object]:
        """The fields as keyword arguments of :func:`.ransac.detect_planes`."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
