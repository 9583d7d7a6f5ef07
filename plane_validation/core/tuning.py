"""Tolerance auto-tuning by cluster validity indices (paper section 4).

``tune_tolerance`` sweeps the RANSAC tolerance ``t`` (meters), scores every segmentation with all
indices and picks ``t`` by one of them (:mod:`.criteria`) among candidates :mod:`.tolerance_grid` derives;
:mod:`.plane_count` chooses the number of planes (the paper's Fig. 2). Pure numpy, no ROS import.
"""
from __future__ import annotations

import contextlib
import contextvars
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .blas import single_blas_thread
from .criteria import (
    CRITERIA,
    DEFAULT_CRITERION,
    SEPARATION_CRITERIA,
    check_criterion,
    resolved_sampled_separation,
)
from .indices import validity_indices
from .interrupts import keeps_interrupts
from .noise import AUTO, NOISE_REFERENCE, TUNED_NOISE_MODELS, check_noise_model, noise_coefficient, tolerance_scale
from .noise_estimate import estimate_noise
from .orientation import Orientation
from .params import GRID_POINTS, MAX_ITERATIONS, MAX_PLANES, MIN_INLIERS, PROBABILITY, RANSAC_POINTS
from .ransac import (
    Segmentation,
    Viewpoint,
    as_points,
    check_flag,
    check_integer,
    check_magnitude,
    check_number,
    check_shape,
    check_viewpoint,
    detect_planes,
    finite_rows,
    generator,
    grid_image,
    grid_step,
    min_inliers_number,
    search_graph,
)
from .search.checks import gathered_rows
from .tolerance_grid import (
    TOP_DIAGONAL_SHARE,
    TUNE_CANDIDATES,
    box_diagonal,
    default_tolerances,
    finite_points,
)
from .tuning_result import TuningResult, TuningRow
from .verdict import (
    RELIABLE_GS_PLANES,
    SINGLE_PLANE_THICKNESS,
    STABILITY_RESEEDS,
    judge,
    seed_agreement,
    surface_failures,
)
from .workers import in_order, parallel_calls

__all__ = ['TUNE_POINTS', 'tune_tolerance', 'noise_from_segmentation']

#: The subsample a sweep runs on (points).
TUNE_POINTS = 20000
#: Default of tune_tolerance's ``extend``: a sweep with a derived top whose choice is its largest candidate
#: goes on, one candidate at a time in the same geometric step, while the choice stays the largest one, for
#: at most this many candidates and up to TOP_DIAGONAL_SHARE of the diagonal. The derived top (10 local
#: noise thicknesses) falls short where a neighbourhood lies on one depth step of a quantized sensor: the 5
#: Kinect frames of benchmarks/README.md chose their top, 4 with PS still rising (office1.pcd, walls at
#: 4-5 m: 46 mm, the back wall in pieces). A plateau stops it: the tie rule (SILHOUETTE_TIE) keeps the
#: smaller t unless a larger one scores clearly better. The separation criteria have no such rule, and Dunn and
#: Davies-Bouldin improve with t past every plane (with the extension: Dunn's depth_stairs 9/12 -> 2/12 correct,
#: Davies-Bouldin's depth_room t 123 -> 613 mm): their sweeps keep the derived range.
TUNE_EXTEND = 6
#: The sweep looks for at least this many planes whatever max_planes is (the final detection keeps to
#: max_planes; tune_tolerance's sweep_planes): a cap below the scene's planes would reward a t at which
#: the planes found take in strips of the others (a 6-wall room with max_planes 2-4: t = 0.10-0.15 m
#: against 5 mm noise). Not more: a candidate below the noise finds up to that many slivers (with
#: quality.py's min_inliers of 0.08 %, 30 made its sweeps 30-50 % slower; 20 costs 0-10 %).
SWEEP_MAX_PLANES = 20
#: A tuning candidate is eligible when its planes cover at least this share of the best coverage.
MIN_RELATIVE_COVERAGE = 0.5
#: Silhouette-type scores closer than this to the best count as ties (the smallest t wins).
SILHOUETTE_TIE = 0.01
#: With connected regions, the candidates of a derived range above this many times the sensor's noise are not swept,
#: nor is the range extended beyond it (the noise: sigma from core/noise_estimate.py at the NOISE_LEVEL_QUANTILE of
#: the cloud's ranges; with ``depth_quadratic``, at the reference range): a larger t takes in strips of other surfaces
#: and merges shallow ridges. On the benchmark's tuning split (benchmarks/README.md) the best fixed t of the scenes
#: auto-tuning gets right is 1.4-4.6 sigma (one roof 6.7, where its tuned 4.4 is as good), and 5 did better there
#: than 3.5 and 7; the paper's useful t is 1-2 noise half-widths (1.7-3.5 sigma for uniform noise).
NOISE_BOUND = 5.0
NOISE_LEVEL_QUANTILE = 0.9


def noise_from_segmentation(seg: Segmentation, points: np.ndarray | None = None) -> float:
    """Half-width e (meters) of uniform noise matching the pooled residual RMS of the planes; with a
    range-dependent noise model (``points`` (N, 3) then needed), of the residuals divided by the
    model's tolerance factor, i.e. e at the reference range."""
    counts = np.array([len(p.inliers) for p in seg.planes])
    if counts.sum() == 0:
        return float('nan')
    if seg.noise_model == 'constant' or points is None:
        rms = np.array([p.rms for p in seg.planes])
        return float(np.sqrt(3 * np.sum(counts * rms ** 2) / counts.sum()))
    pts = as_points(points)
    own = seg.labels >= 0
    plane = seg.coefficients[seg.labels[own]]
    residual = np.einsum('ij,ij->i', pts[own], plane[:, :3]) + plane[:, 3]
    residual /= tolerance_scale(pts[own], seg.noise_model, seg.noise_reference, seg.viewpoint)
    return float(np.sqrt(3 * np.mean(residual ** 2)))


@keeps_interrupts
@single_blas_thread
def tune_tolerance(points: np.ndarray, tolerances=None, criterion: str = DEFAULT_CRITERION, *,
                   max_planes: int = MAX_PLANES, min_inliers: int | float = MIN_INLIERS,
                   probability: float = PROBABILITY, max_iterations: int = MAX_ITERATIONS,
                   sample_size: int | None = 2000, tune_points: int | None = TUNE_POINTS,
                   t_min: float | None = None, t_max: float | None = None, count: int = TUNE_CANDIDATES,
                   seed: int | None = None, progress: Callable[[int, int], None] | None = None,
                   ransac_points: int | None = RANSAC_POINTS, sampled_separation: bool | None = None,
                   shape: tuple[int, int] | None = None, connectivity: bool = True,
                   noise_model: str = AUTO, noise_reference: float = NOISE_REFERENCE,
                   viewpoint: Viewpoint = None, jobs: int = 1, sweep_planes: int = SWEEP_MAX_PLANES,
                   extend: int = TUNE_EXTEND, grid_points: int | None = GRID_POINTS,
                   orientation: Orientation | None = None, noise_bound: float = NOISE_BOUND) -> TuningResult:
    """Sweep the RANSAC tolerance and pick the best by ``criterion``.

    points: (N, 3) meters. tolerances: candidate ``t`` values in meters, or None for ``count``
    candidates from ``t_min`` to ``t_max``, each derived from the cloud when None
    (:func:`default_tolerances`). criterion: one of :data:`CRITERIA`.
    extend: when the top of the range was derived (no ``tolerances``, no ``t_max``) and the choice is the
    largest candidate, up to this many more candidates are swept above it, one at a time in the same
    geometric step, while the choice stays the largest and up to TOP_DIAGONAL_SHARE of the bounding-box
    diagonal (see TUNE_EXTEND); 0 keeps the derived range (the paper's sweep). Not with Dunn or Davies-Bouldin:
    they grow (fall) with t without a plateau, and have no tie rule to stop at one.
    tune_points: the sweep runs on a random subsample of this many points (None = all); the
    chosen ``t`` is then applied to the full cloud. sample_size: silhouette sample per score.
    Candidates whose planes cover less than half the best coverage of the sweep are not eligible
    (GSplanes ignores unassigned points); among the eligible ones whose score is within
    max(3 SE, 0.01) of the best (indistinguishable given the silhouette sampling), the smallest
    ``t`` wins; see :func:`_choose` for the single-plane case. With ``connectivity``, a choice whose planes fail
    the verdict's surface tests (clutter cut into slabs, several surfaces as one) is made again among the smaller
    candidates that pass them and cover half the sweep's best coverage, if any (UNSOUND_SHARE, :func:`_sound_choice`).
    progress: called as ``progress(done, total)`` after each candidate (e.g. to drive a progress bar).
    ransac_points, grid_points, sampled_separation: passed to :func:`detect_planes` and :func:`validity_indices`;
    sampled_separation None (the default) means exact up to EXACT_SEPARATION_POINTS valid points and
    on the index sample beyond (exact minimum distances between large planes far apart cost seconds).
    The candidates' Dunn and Davies-Bouldin are computed on the index sample unless one of them is
    the criterion (they cannot change the choice);
    shape, connectivity: to :func:`detect_planes` (an organized cloud is swept on a regular
    sub-grid of about ``tune_points`` pixels, which keeps it organized).
    orientation: to :func:`detect_planes` (the sweep's planes satisfy it too).
    noise_model, noise_reference, viewpoint: to :func:`detect_planes`; ``auto`` (the default) is ``depth_quadratic``
    where the sensor's noise grows with range, else ``constant`` (:meth:`.noise_estimate.NoiseEstimate.model`; the
    result's ``noise_model`` says which). With ``depth_quadratic`` the candidates are t0, the tolerance up to the
    reference range; derived bounds (with ``connectivity`` and a noise estimate) run from one sigma of the noise at
    the reference range to ``noise_bound`` sigmas, else from the derived tolerances divided by the median tolerance
    factor of the cloud.
    jobs: processes the candidates (and the reseeded reruns, beside the final detection) run in,
    this one and ``jobs`` - 1 worker processes that stay WORKER_IDLE_S for the next sweep; 1 = this
    process only, 0 = one per CPU core, and never more than the cores. The result is the same for
    any value.
    sweep_planes: the candidates look for up to max(max_planes, sweep_planes) planes, and only the
    final detection keeps to ``max_planes`` (t is the sensor's, whatever number of planes is wanted);
    0 = ``max_planes`` (the paper's experiments).
    noise_bound: with ``connectivity`` and a derived top (no ``tolerances``, no ``t_max``), candidates above this many
    sigmas of the sensor's noise (NOISE_BOUND; :func:`.noise_estimate.estimate_noise`) are not swept and the range is
    not extended beyond it, unless that leaves fewer than two candidates (a noise-free cloud); 0 = no bound.
    """
    check_criterion(criterion)
    if isinstance(jobs, bool) or not isinstance(jobs, (int, np.integer)) or jobs < 0:
        raise ValueError(f'jobs must be an integer >= 0 (0 = one per CPU core), got {jobs!r}')
    if isinstance(sweep_planes, bool) or not isinstance(sweep_planes, (int, np.integer)) or sweep_planes < 0:
        raise ValueError(f'sweep_planes must be an integer >= 0 (0 = max_planes), got {sweep_planes!r}')
    extend = check_integer('extend', extend, 0)
    max_planes = check_integer('max_planes', max_planes, 0)
    t_min, t_max, tune_points = _check_range(t_min, t_max, tune_points)
    if tolerances is not None:
        tolerances = _check_tolerances(tolerances)
    count = check_integer('count', count, 2)
    check_flag('connectivity', connectivity)
    noise_bound = check_number('noise_bound', noise_bound, 'a number >= 0 (0: no bound)')
    if noise_bound < 0:
        raise ValueError(f'noise_bound must be a number >= 0 (0: no bound), got {noise_bound!r}')
    start = time.perf_counter()
    pts = as_points(points)
    finite = finite_points(pts)
    if len(finite) < 3:
        raise ValueError(f'need at least 3 finite points to tune, got {len(finite)}')
    check_magnitude(finite)
    rng = generator(seed)
    view = check_viewpoint(viewpoint)
    check_noise_model(noise_model, noise_reference, TUNED_NOISE_MODELS)
    shape = None if shape is None else check_shape(shape, len(pts))
    # a fixed seed: the estimate is the cloud's, and the sweep's random stream stays as it was without it
    sensor = estimate_noise(pts, shape, viewpoint=view, reference=noise_reference, seed=0)
    if noise_model == AUTO:
        noise_model = sensor.model(finite, view)
    scale = tolerance_scale(finite, noise_model, noise_reference, view)
    factor = 1.0 if scale is None else float(np.median(scale))
    # with a noise model a given t_min is a t0: checked against the derived top once that is one too
    given_lo = t_min if scale is None or t_max is not None else None
    cand = default_tolerances(finite, count, lo=given_lo, hi=t_max, seed=rng) if tolerances is None else tolerances
    if scale is not None and tolerances is None:
        # t0 from one sigma of the noise at the reference range to the bound's sigmas (the cloud's extent says little
        # of a depth camera's noise, which grows 10-fold over its range); without an estimate, the derived bounds
        # are tolerances at typical range
        anchored = connectivity and noise_bound > 0 and sensor.sigma_reference > 0
        lo = (sensor.sigma_reference if anchored else cand[0] / factor) if t_min is None else float(t_min)
        hi = (noise_bound * sensor.sigma_reference if anchored else cand[-1] / factor) if t_max is None else cand[-1]
        if hi <= lo:
            raise ValueError(f'the smallest candidate {lo:g} m (t_min, the node\'s tune_min) is not below the '
                             f'largest t0 derived from this cloud, {hi:.3g} m: lower it or give t_max too')
        cand = np.geomspace(lo, hi, len(cand))
    noise_level = sensor.sigma_reference if scale is not None else \
        sensor.level(finite, view, NOISE_LEVEL_QUANTILE)
    bound = noise_bound * noise_level if connectivity and noise_bound and tolerances is None and t_max is None \
        and len(cand) > 2 and cand[1] <= noise_bound * noise_level else np.inf
    cand = cand[cand <= bound]  # the same candidates below it: a choice changes only where the bound binds
    cand = np.unique(cand)
    if cand.size == 0:
        raise ValueError('tolerances is empty: give at least one candidate (or None to derive them)')
    if not np.all(np.isfinite(cand)) or cand[0] <= 0:
        raise ValueError('tolerances must be finite and > 0')
    # a derived top may be extended up to TOP_DIAGONAL_SHARE of the diagonal (``extend``); a given range is kept
    top = TOP_DIAGONAL_SHARE * box_diagonal(finite) / factor \
        if extend and tolerances is None and t_max is None and len(cand) > 1 and criterion not in SEPARATION_CRITERIA \
        else 0.0
    top = min(top, bound)  # the extension keeps to the bound too
    sweep_shape = None
    step = 0 if shape is None else grid_step(shape, len(finite), tune_points)
    if step:
        grid, _ = grid_image(pts, finite_rows(pts), shape, step)
        sweep_pts, sweep_shape = grid.reshape(-1, 3), grid.shape[:2]
    else:  # unorganized, or an image too thin for a 2-D grid
        sweep_pts = finite if tune_points is None or len(finite) <= tune_points else \
            gathered_rows(finite, rng.choice(len(finite), tune_points, replace=False))
    n_sweep = int(np.count_nonzero(finite_rows(sweep_pts)))
    ransac_seed, index_seed = rng.integers(0, 2**63, size=2)
    opts = dict(max_planes=max_planes, min_inliers=min_inliers, probability=probability,
                max_iterations=max_iterations, ransac_points=ransac_points, grid_points=grid_points,
                connectivity=connectivity, noise_model=noise_model, noise_reference=noise_reference, viewpoint=view,
                orientation=orientation)
    # a count means the same share of the cloud on the subsample (as ransac_points scales it)
    # t is a property of the sensor, not of how many planes the caller wants: the sweep looks for at least
    # sweep_planes (a cap that stops it early makes the planes take in strips of the surfaces left out)
    sweep_opts = dict(opts, min_inliers=_scaled_min_inliers(min_inliers, n_sweep, len(finite)), shape=sweep_shape,
                      max_planes=max(max_planes, sweep_planes))
    sampled_separation = resolved_sampled_separation(sampled_separation, len(finite))
    sweep_sampled = sampled_separation or criterion not in SEPARATION_CRITERIA
    score = dict(sample_size=sample_size, seed=int(index_seed), sampled_separation=sweep_sampled)
    # The final detection's graph does not depend on t: built in a thread beside the sweep (its kd-tree
    # and numpy work release the GIL), from the generator that detect_planes(seed=ransac_seed) would
    # build it from (the same planes).
    final_rng = np.random.default_rng(int(ransac_seed))
    pool = ThreadPoolExecutor(1)
    with contextlib.ExitStack() as stack:
        # a sweep that fails or is abandoned does not wait for the graph (the thread ends on its own)
        stack.callback(pool.shutdown, wait=False, cancel_futures=True)
        final_graph = pool.submit(contextvars.copy_context().run, search_graph, pts, shape, ransac_points,
                                  final_rng, view, grid_points) if connectivity else None
        if connectivity:  # the same neighbourhood graph for every candidate (None when it would be sampled)
            sweep_opts['graph'] = search_graph(sweep_pts, sweep_shape, ransac_points, viewpoint=view,
                                               grid_points=grid_points)
        run = stack.enter_context(parallel_calls(jobs, (sweep_pts, sweep_opts)))
        rows: list[TuningRow] = [None] * len(cand)
        sweep_labels: list[np.ndarray] = [None] * len(cand)
        candidates = run(_candidate, [(t, int(ransac_seed), score) for t in cand])
        for done, (i, (row, labels)) in enumerate(candidates, start=1):
            rows[i], sweep_labels[i] = row, labels
            if progress is not None:
                progress(done, len(cand))
        best = _sound_choice(rows, criterion, n_sweep) if connectivity else _choose(rows, criterion, n_sweep)
        ratio = cand[-1] / cand[-2] if top else 1.0
        while best == len(rows) - 1 and len(rows) < len(cand) + extend and rows[-1].tolerance * ratio <= top:
            for _, (row, labels) in run(_candidate, [(rows[-1].tolerance * ratio, int(ransac_seed), score)]):
                rows.append(row)
                sweep_labels.append(labels)
            if progress is not None:
                progress(len(rows), len(rows))
            best = _sound_choice(rows, criterion, n_sweep) if connectivity else _choose(rows, criterion, n_sweep)
        t_best = rows[best].tolerance
        bounded = bool(len(cand) > 1 and rows[-1].tolerance * cand[-1] / cand[-2] > bound)
        # stability under reseeding, on the sweep's points and graph (a fraction of the full cloud's cost);
        # only when there are planes to find again. With workers they run beside the final detection.
        reseeds = rng.integers(0, 2**63, size=STABILITY_RESEEDS)
        reruns = in_order(run(_labels, [(t_best, int(s)) for s in reseeds])) \
            if rows[best].n_planes else iter(())
        final = detect_planes(pts, t_best, seed=final_rng, shape=shape,
                              graph=None if final_graph is None else final_graph.result(), **opts)
        if sweep_pts is finite and len(finite) == len(pts) and shape is None and sweep_sampled == sampled_separation \
                and sweep_opts['max_planes'] == max_planes:
            final_scores = rows[best].indices  # the sweep already scored this very segmentation
        else:
            final_scores = validity_indices(pts, final.labels, sample_size=sample_size, seed=int(index_seed),
                                            sampled_separation=sampled_separation)
        agreement = seed_agreement(sweep_labels[best], reruns)
    return TuningResult(rows=tuple(rows), criterion=criterion, best=best, tolerance=t_best, segmentation=final,
                        indices=final_scores, noise_estimate=noise_from_segmentation(final, pts),
                        verdict=judge(pts, final, final_scores, agreement), seconds=time.perf_counter() - start,
                        noise_model=noise_model,
                        noise_coefficient=noise_coefficient(pts, final.labels, final.coefficients, view)
                        if noise_model == 'depth_quadratic' else float('nan'), sweep_points=n_sweep,
                        seed_agreement=agreement, sensor_noise=sensor, noise_level=noise_level, bounded=bounded)


def _check_range(t_min, t_max, tune_points) -> tuple[float | None, float | None, int | None]:
    """tune_tolerance's ``t_min`` and ``t_max`` as floats > 0 (or None) and ``tune_points`` as an int >= 3 (None or
    inf: None); ValueError naming the value as given otherwise."""
    bounds = [None if t is None else check_number(name, t, 'None or a distance > 0 (m)')
              for name, t in (('t_min', t_min), ('t_max', t_max))]
    for name, t in zip(('t_min', 't_max'), bounds):
        if t is not None and t <= 0:
            raise ValueError(f'{name} must be None or a distance > 0 (m), got {t!r}')
    if isinstance(tune_points, np.ndarray) and tune_points.ndim == 0:
        tune_points = tune_points[()]  # a 0-d array means its number
    if tune_points is None or (isinstance(tune_points, (float, np.floating)) and tune_points == np.inf):
        return bounds[0], bounds[1], None
    try:
        return bounds[0], bounds[1], check_integer('tune_points', tune_points, 3)
    except ValueError:
        raise ValueError(f'tune_points must be None or an integer >= 3, got {tune_points!r}') from None


def _check_tolerances(tolerances) -> np.ndarray:
    """``tolerances`` (a number, or a sequence (list, tuple, range, array.array, ...) or 1-D array of numbers) as a
    float array; ValueError otherwise (a string, a set, a generator, bools)."""
    if isinstance(tolerances, np.ndarray) and tolerances.ndim > 1:
        raise ValueError(f'tolerances must be a list of distances, got an array of shape {tolerances.shape}')
    items = tolerances.ravel() if isinstance(tolerances, np.ndarray) else \
        tolerances if isinstance(tolerances, Sequence) and not isinstance(tolerances, (str, bytes)) else [tolerances]
    return np.array([check_number('tolerances', t, 'a list of distances > 0 (m)') for t in items], dtype=float)


@single_blas_thread  # also in a worker process, whose BLAS joblib would give cores / jobs threads
def _candidate(points: np.ndarray, opts: dict, t: float, seed: int, score: dict) -> tuple[TuningRow, np.ndarray]:
    """One sweep candidate: its row and labels (N,) for ``detect_planes(points, t, seed, **opts)``
    scored by ``validity_indices(points, labels, **score)``."""
    start = time.perf_counter()
    seg = detect_planes(points, t, seed=seed, **opts)
    scores = validity_indices(points, seg.labels, **score)
    sizes = np.array([len(p.inliers) for p in seg.planes], dtype=float)
    volume, merged, misfit, thickness = surface_failures(points, seg)
    total = max(sizes.sum(), 1.0)
    return TuningRow(tolerance=float(t), n_planes=seg.n_planes, inlier_counts=tuple(int(n) for n in sizes),
                     indices=scores, seconds=time.perf_counter() - start,
                     max_thickness=float(thickness.max()) if len(thickness) else 0.0,
                     volume_share=float(sizes[volume & ~merged].sum() / total),
                     merged_share=float(sizes[merged].sum() / total),
                     misfit_share=float(sizes[misfit & ~merged].sum() / total)), seg.labels


@single_blas_thread
def _labels(points: np.ndarray, opts: dict, t: float, seed: int) -> np.ndarray:
    """(N,) labels of ``detect_planes(points, t, seed=seed, **opts)``."""
    return detect_planes(points, t, seed=seed, **opts).labels


def _scaled_min_inliers(min_inliers: int | float, n_sample: int, n_valid: int) -> int | float:
    """A count ``min_inliers`` (>= 1) scaled from ``n_valid`` points to ``n_sample``; a fraction as is."""
    min_inliers = min_inliers_number(min_inliers)
    if min_inliers < 1 or n_sample >= n_valid:
        return min_inliers
    return max(3, int(np.ceil(min_inliers * n_sample / n_valid)))


def _choose(rows: list[TuningRow], criterion: str, n_points: int) -> int:
    """Index of the chosen candidate.

    Eligible are the candidates whose planes cover at least MIN_RELATIVE_COVERAGE of the best
    coverage in the sweep: GSplanes ignores unassigned points, so at t far below the noise a
    couple of far-apart slivers would otherwise score well. Among the eligible, the smallest
    tolerance whose score is within max(3 SE, SILHOUETTE_TIE) of the best one wins (the plateau
    of good tolerances is flat up to sampling noise). The silhouettes are undefined (0) for a
    single plane, so when no multi-plane candidate reaches RELIABLE_GS_PLANES and some eligible
    candidate finds exactly one thin plane (thickness ratio <= SINGLE_PLANE_THICKNESS), the cloud
    is taken as one plane: the smallest t whose plane covers 95 % of the best such coverage.
    """
    coverage = np.array([sum(r.inlier_counts) for r in rows]) / max(n_points, 1)
    eligible = coverage >= MIN_RELATIVE_COVERAGE * coverage.max()
    scores = np.array([r.score(criterion) for r in rows])
    sign = 1 if CRITERIA[criterion] else -1
    masked = np.where(eligible, sign * np.nan_to_num(scores, nan=-np.inf * sign), -np.inf)
    best = int(np.argmax(masked))
    single = eligible & np.array([r.n_planes == 1 and r.max_thickness <= SINGLE_PLANE_THICKNESS for r in rows])
    if criterion in ('gs_planes', 'gs', 'silhouette') and single.any() and scores[best] < RELIABLE_GS_PLANES:
        return int(np.flatnonzero(single & (coverage >= 0.95 * coverage[single].max()))[0])
    se_name = {'gs_planes': 'gs_planes_se', 'gs': 'gs_se', 'silhouette': 'silhouette_se'}.get(criterion)
    # The reported SE runs ~1.5x small (shared sample noise), and 0.01 of silhouette is no real difference.
    if se_name:
        margin = max(3 * getattr(rows[best].indices, se_name), SILHOUETTE_TIE)
    else:
        margin = SILHOUETTE_TIE if criterion == 'plane_silhouette' else 0.0  # PS is sampled too
    return int(np.flatnonzero(masked >= masked[best] - margin)[0])


def _sound_choice(rows: list[TuningRow], criterion: str, n_points: int) -> int:
    """Index of the chosen candidate (:func:`_choose`); when it is unsound (TuningRow.unsound), chosen again among
    the sound smaller candidates that cover MIN_RELATIVE_COVERAGE of the whole sweep's best coverage (the first
    choice when there is none)."""
    best = _choose(rows, criterion, n_points)
    if not rows[best].unsound:
        return best
    coverage = np.array([sum(r.inlier_counts) for r in rows])
    eligible = coverage >= MIN_RELATIVE_COVERAGE * coverage.max()  # of the whole sweep: not a few slivers below it
    sound = [i for i in range(best) if eligible[i] and rows[i].n_planes and not rows[i].unsound]
    return sound[_choose([rows[i] for i in sound], criterion, n_points)] if sound else best

