"""The result of a tolerance sweep (:func:`.tuning.tune_tolerance`): one row per candidate t and the choice."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .failures import Verdict
from .indices import ValidityIndices
from .noise_estimate import NoiseEstimate
from .ransac import Segmentation

__all__ = ['TuningRow', 'TuningResult', 'UNSOUND_SHARE', 'MISFIT_SHARE']

#: A candidate whose planes fail the verdict's surface tests (core/verdict.py: cut out of a volume, two surfaces
#: found as one) on this share of their points or more is unsound. With connected regions, a sweep whose choice is
#: unsound chooses again among the sound candidates below (see tuning._sound_choice): PS rewards clutter cut into slabs
#: and parallel surfaces merged (they cover more points, clear of the other planes), so a sweep otherwise runs on to
#: them (benchmarks/README.md: a floor under a bush chooses 141 mm, F1 0.90, without this and 17 mm, F1 1.00, with it;
#: two sheets 5 cm apart are one plane without it, two with it). The choices on the benchmark's labelled clouds are
#: sound. A sound choice above a merge is kept: the layering test also fires on a quantized camera's depth steps, and
#: cutting there splits a wall into its two depth layers.
UNSOUND_SHARE = 0.02
#: A candidate whose planes that fit their points worse than their patches do (verdict.MAX_LACK_OF_FIT: two sides of a
#: shallow ridge, a table top with the floor beside it) hold this share of the planes' points or more is unsound too: as
#: for the verdict (MINOR_SHARE). Smaller merges, such as a box's top with strips of its sides, come back at every t
#: and would push the choice down to a t too small for the large planes.
MISFIT_SHARE = 0.1


@dataclass(frozen=True, eq=False)
class TuningRow:
    """One candidate tolerance of a sweep: ``tolerance`` in meters, ``seconds`` of RANSAC + indices."""

    tolerance: float
    n_planes: int
    inlier_counts: tuple[int, ...]
    indices: ValidityIndices
    seconds: float
    max_thickness: float = 0.0   # largest plane_thickness among the planes (0 without planes)
    volume_share: float = 0.0    # share of the planes' points on planes cut out of a volume (verdict.surface_failures)
    merged_share: float = 0.0    # ... on planes holding several surfaces as one (two layers, a slab across steps)
    misfit_share: float = 0.0    # ... on planes that fit their points worse than their patches do (a shallow ridge)

    @property
    def unsound(self) -> bool:
        """Whether the planes fail the verdict's surface tests on UNSOUND_SHARE of their points or more, or its
        lack-of-fit test on MISFIT_SHARE or more."""
        return self.volume_share + self.merged_share >= UNSOUND_SHARE or self.misfit_share >= MISFIT_SHARE

    def score(self, criterion: str) -> float:
        return float(getattr(self.indices, criterion))


@dataclass(frozen=True, eq=False)
class TuningResult:
    """Result of :func:`tune_tolerance`.

    rows: every candidate, ascending tolerance (with any added above a derived range: ``extend``).
    tolerance: the chosen ``t`` (meters).
    segmentation: the chosen ``t`` applied to the full-resolution cloud; indices: its indices.
    sensor_noise, noise_level, noise_ratio: the sensor's noise before any segmentation (:mod:`.noise_estimate`), the
    sigma (m) the sweep is bounded by (NOISE_BOUND) and the chosen t over it.
    noise_estimate: half-width ``e`` of the sensor noise (meters), estimated from the residuals of
    the chosen planes (for uniform noise on [-e, e] the residual RMS is e / sqrt(3)); with the
    ``depth_quadratic`` model, of the residuals scaled to the reference range.
    noise_model: the segmentation's (:mod:`.noise`); noise_coefficient: with ``depth_quadratic``, c
    (1/m) of the depth noise sigma(r) = c r^2 fitted to the residuals (NaN with ``constant``).
    verdict: whether the planes are trustworthy, and every test they fail (core/failures.py); reliable: its answer.
    seed_agreement: mean point F1 between the sweep's planes at the chosen t and those of
    STABILITY_RESEEDS other RANSAC seeds on the same points (core/verdict.py, a condition of reliable).
    """

    rows: tuple[TuningRow, ...]
    criterion: str
    best: int
    tolerance: float
    segmentation: Segmentation
    indices: ValidityIndices
    noise_estimate: float
    verdict: Verdict
    seconds: float
    noise_model: str = 'constant'
    noise_coefficient: float = float('nan')
    sweep_points: int = 0  # valid points the candidates were scored on (the subsample)
    seed_agreement: float = float('nan')
    sensor_noise: NoiseEstimate | None = None  # from local plane residuals, before any segmentation
    noise_level: float = float('nan')  # sigma (m) the sweep's bound is a multiple of (tune_tolerance's noise_bound)
    bounded: bool = False  # the next candidate above the last one swept would be above the noise bound

    @property
    def noise_ratio(self) -> float:
        """The chosen t over ``noise_level``: how many sigmas of the sensor's noise the tolerance is (NaN when the
        noise is unknown or nil)."""
        return self.tolerance / self.noise_level if self.noise_level > 0 else float('nan')

    @property
    def reliable(self) -> bool:
        return self.verdict.reliable

    @property
    def tolerances(self) -> np.ndarray:
        return np.array([r.tolerance for r in self.rows])

    @property
    def at_largest(self) -> bool:
        """Whether the chosen t is the largest candidate, after any extension of the sweep, and not at the noise
        bound (a wider range might choose a larger one)."""
        return self.best == len(self.rows) - 1 and len(self.rows) > 1 and not self.bounded

    def scores(self, criterion: str | None = None) -> np.ndarray:
        return np.array([r.score(criterion or self.criterion) for r in self.rows])

    def table(self) -> str:
        """A plain-text table of the sweep, one row per tolerance."""
        head = f'{"t":>10} {"planes":>6} {"dunn":>8} {"DB":>8} {"GS":>7} {"GSpl":>7} {"PS":>7} {"sil":>7} {"ms":>7}'
        lines = [head]
        for i, r in enumerate(self.rows):
            x = r.indices
            mark = ' <' if i == self.best else ''
            lines.append(f'{r.tolerance:10.4g} {r.n_planes:6d} {x.dunn:8.4f} {x.davies_bouldin:8.3g} {x.gs:7.3f} '
                         f'{x.gs_planes:7.3f} {x.plane_silhouette:7.3f} {x.silhouette:7.3f} '
                         f'{1000 * r.seconds:7.1f}{mark}')
        return '\n'.join(lines)
