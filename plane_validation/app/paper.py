"""The paper's synthetic experiments end to end (Lipnickas et al. 2014, section 4): PNGs and a table.

For every case (the corner at e = 0, 2.5, 7.5 as in Fig. 1-4; a cube, the paper's Fig. 5-6,
at e = 0, 1, 2.5, 7.5; a plane-free sphere standing in for the Stanford bunny of Fig. 7-8), in
the paper's units (faces of 100 units):

1. sweep t linearly over the grid (like the paper's axes) with :func:`tune_tolerance`; the
   chosen t is the one GSplanes picks on that grid -> ``<case>_sweep.png`` (indices and number of
   planes vs t);
2. tune t with the default candidates too (what ``detect`` does on its own);
3. score the first k planes at the chosen t with :func:`select_plane_count`
   -> ``<case>_planes.png`` (indices vs k, Fig. 2);
4. one row of ``summary.md`` per case.
"""
from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core import scenes
from ..core.plane_count import PlaneCountResult, select_plane_count
from ..core.tuning import tune_tolerance
from ..core.tuning_result import TuningResult
from ..formats.outputs import staged_files
from .plot import plot_plane_count, plot_sweep

__all__ = ['Case', 'CASES', 'CaseResult', 'run_paper', 'summary_markdown', 'linear_grid']

#: Unit of the synthetic scenes' coordinates (the paper's "measuring units").
UNIT = 'units'


@dataclass(frozen=True)
class Case:
    """One experiment: scene name, noise half-width e (units), points, max planes for Fig. 2, truth."""

    scene: str
    noise: float
    points: int
    max_planes: int
    true_planes: int

    @property
    def name(self) -> str:
        return f'{self.scene}_e{self.noise:g}'

    def make(self, seed: int, points: int | None = None) -> scenes.Scene:
        n = self.points if points is None else points * self.points // 3000
        if self.scene == 'sphere':
            return scenes.sphere(n, self.noise, radius=50.0, seed=seed)
        return scenes.SCENES[self.scene](n, self.noise, seed=seed)


#: The experiments, in the paper's order. Corner and sphere 3000 points, cube 6000.
CASES: tuple[Case, ...] = (
    Case('corner', 0.0, 3000, 5, 3), Case('corner', 2.5, 3000, 5, 3), Case('corner', 7.5, 3000, 5, 3),
    Case('cube', 0.0, 6000, 8, 6), Case('cube', 1.0, 6000, 8, 6), Case('cube', 2.5, 6000, 8, 6),
    Case('cube', 7.5, 6000, 8, 6), Case('sphere', 0.5, 3000, 5, 0),
)


def linear_grid(start: float = 0.5, stop: float = 30.0, steps: int = 60) -> np.ndarray:
    """``steps`` tolerances from ``start`` to ``stop`` (units), evenly spaced like the paper's t axes."""
    return np.linspace(start, stop, steps)


@dataclass(frozen=True, eq=False)
class CaseResult:
    """Everything one case produced; ``stable``: (t_lo, t_hi) of the run of grid t around the chosen
    one that finds the true number of planes (None when none does)."""

    case: Case
    n_points: int
    sweep: TuningResult
    auto: TuningResult
    counts: PlaneCountResult
    stable: tuple[float, float] | None
    figures: tuple[Path, Path]
    seconds: float


def _stable_range(sweep: TuningResult, true_planes: int) -> tuple[float, float] | None:
    """Contiguous grid t range with the true plane count, around the chosen t (else the longest run)."""
    right = np.array([r.n_planes == true_planes for r in sweep.rows])
    if true_planes == 0 or not right.any():
        return None
    runs, start = [], None
    for i, ok in enumerate(np.append(right, False)):
        if ok and start is None:
            start = i
        elif not ok and start is not None:
            runs.append((start, i - 1))
            start = None
    around = [r for r in runs if r[0] <= sweep.best <= r[1]]
    lo, hi = around[0] if around else max(runs, key=lambda r: r[1] - r[0])
    return sweep.rows[lo].tolerance, sweep.rows[hi].tolerance


def run_case(case: Case, out: Path, *, grid: np.ndarray, seed: int = 0, points: int | None = None) -> CaseResult:
    """Run one case and write its two figures into ``out``."""
    start = time.perf_counter()
    scene = case.make(seed, points)
    # the paper's method: every point within t of an infinite plane (no connected regions)
    # and the paper's search: every candidate stops at max_planes, over the derived range, with one t everywhere
    sweep = tune_tolerance(scene.points, tolerances=grid, criterion='gs_planes', seed=seed, connectivity=False,
                           sweep_planes=0, noise_model='constant')
    auto = tune_tolerance(scene.points, criterion='gs_planes', seed=seed, connectivity=False, sweep_planes=0,
                          extend=0, noise_model='constant')
    counts = select_plane_count(scene.points, sweep.tolerance, max_planes=case.max_planes, seed=seed,
                                connectivity=False)
    title = f'{case.scene}, e = {case.noise:g} {UNIT}, {len(scene.points)} points'
    truth = case.true_planes if case.true_planes else None
    sweep_png = plot_sweep(sweep, out / f'{case.name}_sweep.png', title=title, unit=UNIT, true_planes=truth)
    planes_png = plot_plane_count(counts, out / f'{case.name}_planes.png', title=title, true_planes=truth)
    return CaseResult(case=case, n_points=len(scene.points), sweep=sweep, auto=auto, counts=counts,
                      stable=_stable_range(sweep, case.true_planes), figures=(sweep_png, planes_png),
                      seconds=time.perf_counter() - start)


def run_paper(out: str | Path, *, cases: tuple[Case, ...] = CASES, seed: int = 0, points: int | None = None,
              grid: np.ndarray | None = None,
              progress: Callable[[int, int, str], None] | None = None) -> list[CaseResult]:
    """Run every case into the directory ``out`` (created), write ``summary.md``, return the results.

    points: corner/sphere point count (the cube gets twice as many), None for the paper's 3000;
    grid: the t values of the sweep figures (units), default :func:`linear_grid`.
    progress: called as ``progress(done, total, case name)`` after each case.
    """
    out = Path(out)
    grid = linear_grid() if grid is None else np.asarray(grid, dtype=float)
    start = time.perf_counter()
    results = []
    with staged_files(out) as stage:  # interrupted: the folder keeps its earlier figures and summary, not a mix
        for i, case in enumerate(cases):
            results.append(run_case(case, stage, grid=grid, seed=seed, points=points))
            if progress is not None:
                progress(i + 1, len(cases), case.name)
        seconds = time.perf_counter() - start
        (stage / 'summary.md').write_text(summary_markdown(results, grid=grid, seed=seed, seconds=seconds),
                                          encoding='utf-8')
    return [dataclasses.replace(r, figures=tuple(out / p.name for p in r.figures)) for r in results]


def _t(value: float) -> str:
    """3 significant digits; round-off residue (a noise estimate of 1e-14 units) shows as 0."""
    return f'{round(value, 6):.3g}'


def summary_markdown(results: list[CaseResult], *, grid: np.ndarray, seed: int, seconds: float) -> str:
    """The summary table (one row per case) with links to the figures."""
    lines = [
        "# The paper's synthetic experiments, reproduced",
        '',
        (f'Generated by `plane-validation paper` (seed {seed}) in {seconds:.0f} s. Units are the paper\'s '
         '"measuring units" (cube faces of 100 units); e is the half-width of the uniform noise.'),
        '',
        (f'Sweep figures: t from {_t(grid[0])} to {_t(grid[-1])} in {len(grid)} even steps; "t (sweep)" is the t '
         'GSplanes chooses on that grid, "t (auto)" the one `detect` chooses with its default candidates. '
         '"stable t" is the run of grid t around the chosen one that finds the true number of planes. '
         '"k (rule)" is `select_plane_count` at t (sweep): the largest k whose planes all keep a mean '
         'silhouette S_j >= 0.05; the next four columns are each index\'s plain optimum over k.'),
        '',
        ('| case | points | true planes | t (sweep) | t (auto) | planes at t | stable t | noise estimate | '
         'k (rule) | argmax k GS | argmin k DB | argmax k Dunn | argmax k GSplanes | GSplanes at t | reliable |'),
        '| --- | ---: | ---: | ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |',
    ]
    for r in results:
        c = r.counts
        best = [str(c.best_by(name)) if c.counts else '-' for name in ('gs', 'davies_bouldin', 'dunn', 'gs_planes')]
        stable = f'{_t(r.stable[0])} – {_t(r.stable[1])}' if r.stable else '—'
        lines.append(
            f'| {r.case.scene}, e = {r.case.noise:g} | {r.n_points} | {r.case.true_planes} | {_t(r.sweep.tolerance)} | '
            f'{_t(r.auto.tolerance)} | {r.sweep.segmentation.n_planes} | {stable} | {_t(r.sweep.noise_estimate)} | '
            f'{c.n_planes} | {" | ".join(best)} | {r.sweep.indices.gs_planes:.3f} | '
            f'{"yes" if r.sweep.reliable else "no"} |')
    lines += ['', '## Figures', '']
    for r in results:
        sweep_png, planes_png = (p.name for p in r.figures)
        lines.append(f'* {r.case.scene}, e = {r.case.noise:g}: [indices and planes vs t]({sweep_png}), '
                     f'[indices vs number of planes]({planes_png})')
    return '\n'.join(lines) + '\n'
