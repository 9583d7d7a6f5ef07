"""How a search and a tolerance sweep run, as frozen values: every setting of :func:`.ransac.detect_planes`
(:class:`SearchParams`) and of :func:`.tuning.tune_tolerance`'s sweep (:class:`TuneParams`) but the cloud's own.

Built once from the parameter table (``PipelineConfig.search``, ``PipelineConfig.tune``) and passed on as keywords
(``detect_planes(points, t, seed=..., shape=..., **search.at_tolerance())``; ``tune_tolerance(points, seed=...,
**search.kwargs(), **tune.kwargs())``; :func:`.plane_count.select_plane_count` takes the search's keywords), so that the
node, replay and every command search and tune alike. The public functions keep their keyword arguments and
defaults for API users.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from .noise import searched_model
from .orientation import Orientation

__all__ = ['SearchParams', 'TuneParams', 'MAX_PLANES', 'MIN_INLIERS', 'PROBABILITY', 'MAX_ITERATIONS', 'RANSAC_POINTS',
           'GRID_POINTS']

#: Defaults of :func:`.ransac.detect_planes` and of the parameter table (``PipelineConfig``): planes searched for at
#: most; the smallest plane, a share of the valid points; RANSAC's success probability and hypotheses per plane.
MAX_PLANES = 10
MIN_INLIERS = 0.02
PROBABILITY = 0.99
MAX_ITERATIONS = 1000
#: Default for ``detect_planes(ransac_points=...)``: larger clouds are searched on a random
#: sample of this many points; every point is then labelled against the planes found.
RANSAC_POINTS = 32768
#: Default for ``detect_planes(grid_points=...)``: an image (``shape``) with more valid pixels is searched on a
#: regular sub-grid of about this many (a step of 3 pixels on a 640x480 Kinect frame). Fewer is faster but
#: loses small faces: at 20,000 (a step of 4) the Kinect frame's search is a third faster, but milk_cartoon's
#: auto-tuned planes go from 4 to 2 (the objects' fronts are lost; benchmarks/README.md).
GRID_POINTS = RANSAC_POINTS


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
        """The fields as keyword arguments of :func:`.tuning.tune_tolerance` (``noise_model`` may be ``auto``)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def at_tolerance(self, chosen: str | None = None) -> dict[str, object]:
        """The fields as keyword arguments of :func:`.ransac.detect_planes` and :func:`.plane_count.select_plane_count`
        at a t: ``auto`` becomes the noise model the sweep behind that t ``chosen`` (``constant`` for a t given)."""
        return dict(self.kwargs(), noise_model=searched_model(self.noise_model, chosen))


@dataclass(frozen=True)
class TuneParams:
    """criterion: the index that picks t; sample_size: the index sample (points; None: all); tune_points: the
    sweep's subsample (points; None: all); t_min, t_max: the candidates' range (meters; None: derived from the
    cloud); count: candidates; sampled_separation: Dunn and Davies-Bouldin on the index sample (None: exact up to
    criteria.EXACT_SEPARATION_POINTS); jobs: processes the candidates run in."""

    criterion: str
    sample_size: int | None
    tune_points: int | None
    t_min: float | None
    t_max: float | None
    count: int
    sampled_separation: bool | None
    jobs: int

    def kwargs(self) -> dict[str, object]:
        """The fields as keyword arguments of :func:`.tuning.tune_tolerance`."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
