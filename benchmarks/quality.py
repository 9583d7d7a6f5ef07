"""Segmentation quality against per-point ground truth, ours (regions on and off) and Open3D.

Clouds: every labelled cloud in ../shared/data/gt (skipped with a message when the folder is
absent), the ICL-NUIM frame with depth-camera noise added, and the synthetic sensor scenes of
plane_validation.core.scenes (depth camera: room, table, stairs; spinning lidar). Each method runs
over a grid of tolerances; a row gives each method at its best t (most Hoover-correct regions,
then F1) and, for ours, the auto-tuned result (tune_tolerance with the library defaults).
--criteria instead auto-tunes with each criterion of plane_validation.core.criteria.CRITERIA and
gives each one's F1 as a fraction of the best regions result over the grid (the oracle).

--split tuning|held-out|both runs the randomised scene families of plane_validation.core.scene_families
on a split's seeds instead (:func:`evaluate`): per scene, per family and per split the Hoover counts and
F1 of each method at its best t, ours auto-tuned, and the verdict's confusion table (``reliable`` against
"good": auto-tuned Hoover-correct on >= 80 % of the true planes and F1 >= 0.97 x the best fixed t's).
Choose thresholds and rules on the tuning split; only report the held-out split. The labelled clouds of
../shared/data/gt belong to the tuning split: they were looked at while tuning the library, so they
cannot be held out honestly.

Run: .venv/bin/python benchmarks/quality.py [--criteria] [--quick] [--write-readme] [--only NAME ...]
     .venv/bin/python benchmarks/quality.py --split both [--quick] [--families NAME ...] [--json PATH]
         [--no-baselines] [--gt DIR] [--noise-bound K]
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pvbench import open3d_ref  # noqa: E402

import plane_validation as pv  # noqa: E402
from plane_validation.core import scene_families, scenes  # noqa: E402
from plane_validation.core.criteria import CRITERIA, DEFAULT_CRITERION  # noqa: E402
from plane_validation.core.scoring import Quality, segmentation_quality  # noqa: E402

GT = Path(__file__).resolve().parents[2] / 'shared' / 'data' / 'gt'
README = Path(__file__).resolve().parent / 'README.md'
MARK = '<!-- quality table -->'
CRITERIA_MARK = '<!-- criteria table -->'
GOOD_RATIO = 0.97


@dataclass(frozen=True, eq=False)
class Cloud:
    """points (N, 3) m with NaN rows; labels (N,) true plane or -1; shape (H, W) or None; min_plane_points: the
    fewest points its generator labels a plane with (None: not known)."""

    name: str
    points: np.ndarray
    labels: np.ndarray
    shape: tuple[int, int] | None
    min_plane_points: int | None = None

    @classmethod
    def of_scene(cls, s: scenes.Scene) -> Cloud:
        return cls(s.name, s.points, s.labels.astype(np.int64), s.shape, s.min_plane_points)

    @property
    def true_planes(self) -> int:
        return len(np.unique(self.labels[self.labels >= 0]))


def _depth_noise(points: np.ndarray, seed: int = 0, sigma_1m: float = 0.0015, quantum_1m: float = 0.002) -> np.ndarray:
    """Depth-camera noise along each ray from the origin: sigma(z) = sigma_1m z^2, quantised depth."""
    rng = np.random.default_rng(seed)
    z = points[:, 2]
    noisy = z + rng.normal(0.0, 1.0, len(z)) * sigma_1m * z ** 2
    step = quantum_1m * noisy ** 2
    with np.errstate(invalid='ignore', divide='ignore'):
        noisy = np.round(noisy / step) * step
        return points * (noisy / z)[:, None]


def labelled_clouds(gt: Path = GT) -> list[Cloud]:
    """Every labelled cloud in ``gt`` (each ICL-NUIM frame also with depth-camera noise added);
    empty, with a message, when the folder is absent."""
    clouds = []
    if not gt.is_dir():
        print(f'{gt} not found: labelled clouds skipped, synthetic scenes only', flush=True)
        return clouds
    for path in sorted(gt.glob('*.npz')):
        d = np.load(path)
        shape = tuple(int(v) for v in d['shape'])
        clouds.append(Cloud(path.stem, d['points'].astype(np.float64), d['labels'].astype(np.int64),
                            shape if shape != (0, 0) else None))
        if path.stem.startswith('icl_'):
            c = clouds[-1]
            clouds.append(Cloud(c.name + '_noisy', _depth_noise(c.points), c.labels, c.shape))
    return clouds


def load_clouds(only: list[str] | None = None, gt: Path = GT) -> list[Cloud]:
    """The benchmark's clouds (the labelled folder's when present, then the synthetic ones)."""
    clouds = labelled_clouds(gt)
    for view in scenes.SENSOR_VIEWS:
        s = scenes.depth_camera(view, seed=1)
        clouds.append(Cloud.of_scene(s))
    for s in (scenes.lidar(seed=1), scenes.lidar(**scenes.VLP16_ROOM, seed=1)):
        clouds.append(Cloud(s.name, s.points, s.labels.astype(np.int64), None))
    for s in (scenes.lidar(seed=1, organized=True), scenes.lidar(**scenes.VLP16_ROOM, seed=1, organized=True)):
        # as a driver publishes it organized, or organize_rings lays it out: the same image
        clouds.append(Cloud(s.name + '_organized', s.points, s.labels.astype(np.int64), s.shape))
    return [c for c in clouds if not only or c.name in only]


def _grid(cloud: Cloud, count: int) -> np.ndarray:
    lo, hi = (0.0005, 0.15) if cloud.shape is not None else (0.002, 0.15)
    return np.geomspace(lo, hi, count)


def _params(cloud: Cloud) -> dict:
    n = int(np.isfinite(cloud.points).all(axis=1).sum())
    least = max(5, int((0.0008 if n > 20000 else 0.01) * n))
    if cloud.min_plane_points is not None:  # a surface labelled as a true plane must be one the search may return
        least = min(least, cloud.min_plane_points)
    return dict(max_planes=cloud.true_planes + 8, min_inliers=least)


def _best(results: list[tuple[float, Quality, float]]) -> tuple[float, Quality, float]:
    return max(results, key=lambda r: (r[1].correct, r[1].f1))


def ours(cloud: Cloud, t: float, connectivity: bool, seed: int = 0) -> tuple[Quality, float]:
    start = time.perf_counter()
    seg = pv.detect_planes(cloud.points, t, seed=seed, shape=cloud.shape, connectivity=connectivity,
                           **_params(cloud))
    seconds = time.perf_counter() - start
    return segmentation_quality(seg.labels, cloud.labels, points=cloud.points, pred_planes=seg.coefficients), seconds


def open3d(cloud: Cloud, t: float, seed: int = 0) -> tuple[Quality, float]:
    valid = np.flatnonzero(np.isfinite(cloud.points).all(axis=1))
    pcd = open3d_ref.to_cloud(cloud.points[valid])
    start = time.perf_counter()
    coeffs, labels = open3d_ref.sequential_planes(pcd, len(valid), t, planes=_params(cloud)['max_planes'], seed=seed)
    seconds = time.perf_counter() - start
    min_count = _params(cloud)['min_inliers']
    counts = np.bincount(labels[labels >= 0], minlength=len(coeffs))
    labels = np.where((labels >= 0) & (counts[np.maximum(labels, 0)] >= min_count), labels, -1)
    full = np.full(len(cloud.points), -1, dtype=np.int64)
    full[valid] = labels
    return segmentation_quality(full, cloud.labels, points=cloud.points, pred_planes=np.asarray(coeffs)), seconds


def auto(cloud: Cloud, seed: int = 0, **kwargs) -> tuple[float, Quality, float, bool, float]:
    """Library defaults but max_planes, min_inliers: (t, quality, seconds, reliable, PS)."""
    start = time.perf_counter()
    result = pv.tune_tolerance(cloud.points, seed=seed, shape=cloud.shape, **_params(cloud), **kwargs)
    seconds = time.perf_counter() - start
    seg = result.segmentation
    return (result.tolerance, segmentation_quality(seg.labels, cloud.labels, points=cloud.points,
                                                   pred_planes=seg.coefficients), seconds, result.reliable,
            result.indices.plane_silhouette)


def _cell(t: float, q: Quality) -> str:
    return f'{q.correct}/{q.true_planes} ({q.over}/{q.under}/{q.missed}/{q.noise}) F1 {q.f1:.3f} @ {1000 * t:.3g} mm'


def run(clouds: list[Cloud], count: int, with_auto: bool) -> list[str]:
    rows = ['| cloud | points | planes | ours, regions | ours, infinite planes (paper) | Open3D | ours auto-tuned | '
            'F1 auto / best | verdict (PS) |',
            '|---|--:|--:|---|---|---|---|--:|---|']
    for cloud in clouds:
        grid = _grid(cloud, count)
        region = _best([(t, *ours(cloud, t, True)) for t in grid])
        infinite = _best([(t, *ours(cloud, t, False)) for t in grid])
        o3d = _best([(t, *open3d(cloud, t)) for t in grid]) if open3d_ref.available() else None
        tuned = auto(cloud) if with_auto else None
        n_valid = int(np.isfinite(cloud.points).all(axis=1).sum())
        o3d_cell = _cell(o3d[0], o3d[1]) if o3d else 'not installed'
        auto_cell = f'{_cell(tuned[0], tuned[1])}, {tuned[2]:.2f} s' if tuned else '—'
        ratio = f'{tuned[1].f1 / region[1].f1:.3f}' if tuned and region[1].f1 else '—'
        verdict = f'{"reliable" if tuned[3] else "not reliable"} ({tuned[4]:.2f})' if tuned else '—'
        row = (f'| {cloud.name} | {n_valid} | {cloud.true_planes} | {_cell(region[0], region[1])} | '
               f'{_cell(infinite[0], infinite[1])} | {o3d_cell} | {auto_cell} | {ratio} | {verdict} |')
        rows.append(row)
        print(row, flush=True)
    return rows


def run_criteria(clouds: list[Cloud], count: int) -> list[str]:
    """Per cloud: the oracle (best regions result over the grid), then auto-tuning by each criterion."""
    names = list(CRITERIA)
    ratios: dict[str, list[float]] = {c: [] for c in names}
    seconds: dict[str, list[float]] = {c: [] for c in names}
    rows = ['| cloud | oracle F1 | ' + ' | '.join(f'{c} (default)' if c == DEFAULT_CRITERION else c
                                                for c in names) + ' |',
            '|---|--:|' + '---|' * len(names)]
    print(*rows, sep='\n', flush=True)
    for cloud in clouds:
        oracle = _best([(t, *ours(cloud, t, True)) for t in _grid(cloud, count)])[1]
        cells = []
        for c in names:
            t, q, s, _, _ = auto(cloud, criterion=c)
            ratio = q.f1 / oracle.f1 if oracle.f1 else float('nan')
            ratios[c].append(ratio)
            seconds[c].append(s)
            cell = f'{ratio:.3f}, {q.correct}/{q.true_planes}, {1000 * t:.3g} mm'
            cells.append(f'**{cell}**' if ratio >= GOOD_RATIO else cell)
        rows.append(f'| {cloud.name} | {oracle.f1:.3f} | ' + ' | '.join(cells) + ' |')
        print(rows[-1], flush=True)
    rows += [f'| ratio: median / min, clouds ≥ {GOOD_RATIO} | | ' + ' | '.join(
                 f'{np.nanmedian(ratios[c]):.3f} / {np.nanmin(ratios[c]):.3f}, '
                 f'{sum(r >= GOOD_RATIO for r in ratios[c])}/{len(clouds)}' for c in names) + ' |',
             '| median tuning s | | ' + ' | '.join(f'{np.median(seconds[c]):.2f}' for c in names) + ' |']
    print(*rows[-2:], sep='\n', flush=True)
    return rows


def _write_block(mark: str, heading: str, block: str) -> None:
    """Replace the text between the mark pair in the README, or append it under heading."""
    text = README.read_text()
    block = f'{mark}\n{block}\n{mark}'
    if mark in text:
        text = re.sub(re.escape(mark) + '.*?' + re.escape(mark), lambda _: block, text, flags=re.S)
    else:
        text += f'\n## {heading}\n\n{block}\n'
    README.write_text(text)


def write_readme(rows: list[str], command: str) -> None:
    _write_block(MARK, 'Segmentation quality against ground truth (benchmarks/quality.py)',
                 f'Command: `{command}`. Each cell: correct/true planes (over/under/missed/noise, Hoover '
                 'at overlap 0.8), point F1 after one-to-one matching, and the tolerance; the best over the grid '
                 'for each method, the auto-tuned t for the last columns.\n\n' + '\n'.join(rows))


def write_criteria_readme(rows: list[str], command: str) -> None:
    _write_block(CRITERIA_MARK, 'Auto-tuning by each criterion (benchmarks/quality.py --criteria)',
                 f'Command: `{command}`. Oracle: the point F1 of the best regions result over the tolerance grid '
                 '(most Hoover-correct regions, then F1). Each cell: auto-tuned F1 / oracle F1, correct/true '
                 f'planes, the tuned t; bold when the ratio is ≥ {GOOD_RATIO}.\n\n' + '\n'.join(rows))


# -- the tuning and held-out splits ------------------------------------------------------------

#: "good": auto-tuned Hoover-correct on at least this share of the true planes, and F1 at least
#: GOOD_RATIO x the F1 of the best fixed t.
GOOD_CORRECT = 0.8
#: A verdict must say "not reliable" below these: correct share, auto / best F1.
BAD_CORRECT, BAD_RATIO = 0.5, 0.9
SPLIT_NAMES = ('tuning', 'held-out')
#: More arguments of the splits' tune_tolerance calls (--noise-bound: to compare a rule on and off).
TUNE_OPTIONS: dict = {}
LABELLED = 'labelled'


@dataclass(frozen=True)
class Result:
    """One method on one cloud: tolerance t (m) and its quality; seconds of the call."""

    t: float
    quality: Quality
    seconds: float


@dataclass(frozen=True)
class Row:
    """One cloud of a split: the best fixed t of each method over the grid (most Hoover-correct, then F1;
    None when not run: Open3D not installed, or no baselines), the auto-tuned result and its verdict;
    ratio = auto F1 / regions' best F1; good: GOOD_CORRECT and GOOD_RATIO met; bad: below BAD_CORRECT
    or BAD_RATIO (must not be reliable)."""

    split: str
    family: str
    name: str
    points: int
    true_planes: int
    regions: Result
    infinite: Result | None
    open3d: Result | None
    auto: Result
    reliable: bool
    verdict: str
    ratio: float
    good: bool
    bad: bool
    failures: tuple[str, ...] = ()  # the verdict's failure kinds (core/failures.py)


def split_clouds(split: str, quick: bool = False, gt: Path = GT) -> list[tuple[str, Cloud]]:
    """(family, cloud) of a split: the scene families' seeds of it; the tuning split also holds the
    labelled clouds of ``gt`` (family LABELLED)."""
    if split not in SPLIT_NAMES:
        raise ValueError(f'unknown split {split!r}; choose one of {", ".join(SPLIT_NAMES)}')
    out = [(LABELLED, c) for c in labelled_clouds(gt)] if split == 'tuning' else []
    for family, seed in scene_families.split(split, quick=quick):
        out.append((family, Cloud.of_scene(scene_families.FAMILIES[family](seed))))
    return out


def _split_grid(cloud: Cloud, count: int) -> np.ndarray:
    """Tolerances (m) for the best fixed t: wide enough for 5 cm roof noise and far depth pixels."""
    return np.geomspace(0.0005 if cloud.shape is not None else 0.002, 0.3, count)


#: Open3D's tolerances in the splits (m): fewer than ours, as each of its plane calls costs about 1 s
#: on a 640 x 480 frame (1,000 iterations over all remaining points).
OPEN3D_GRID, OPEN3D_QUICK_GRID = np.geomspace(0.002, 0.3, 6), np.geomspace(0.002, 0.3, 4)


def evaluate_cloud(split: str, family: str, cloud: Cloud, count: int, open3d_grid: np.ndarray = OPEN3D_GRID,
                   baselines: bool = True) -> Row:
    """Every method on one cloud (ours over ``count`` tolerances, Open3D over ``open3d_grid``) and the
    auto-tuned result; without ``baselines`` only ours with regions (infinite planes and Open3D None)."""
    grid = _split_grid(cloud, count)
    best = {}
    for key, fn, ts in (('regions', lambda t: ours(cloud, t, True), grid),
                        ('infinite', lambda t: ours(cloud, t, False), grid),
                        ('open3d', lambda t: open3d(cloud, t), open3d_grid)):
        if key != 'regions' and not baselines or key == 'open3d' and not open3d_ref.available():
            best[key] = None
            continue
        t, q, sec = _best([(t, *fn(t)) for t in ts])
        best[key] = Result(float(t), q, sec)
    start = time.perf_counter()
    tuned = pv.tune_tolerance(cloud.points, seed=0, shape=cloud.shape, **_params(cloud), **TUNE_OPTIONS)
    seconds = time.perf_counter() - start
    seg = tuned.segmentation
    q = segmentation_quality(seg.labels, cloud.labels, points=cloud.points, pred_planes=seg.coefficients)
    ref = best['regions'].quality.f1
    ratio = q.f1 / ref if ref > 0 else float('nan')
    share = q.correct / q.true_planes if q.true_planes else 1.0
    return Row(split, family, cloud.name, int(np.isfinite(cloud.points).all(axis=1).sum()), cloud.true_planes,
               best['regions'], best['infinite'], best['open3d'], Result(float(tuned.tolerance), q, seconds),
               bool(tuned.reliable), str(tuned.verdict), float(ratio),
               bool(share >= GOOD_CORRECT and ratio >= GOOD_RATIO), bool(share < BAD_CORRECT or not ratio >= BAD_RATIO),
               tuple(f.kind.value for f in tuned.verdict.failures))


def evaluate(split: str, quick: bool = False, gt: Path = GT, families: list[str] | None = None,
             on_row: Callable[[Row], None] | None = None, baselines: bool = True) -> list[Row]:
    """Rows of one split ('tuning' or 'held-out'): 12 tolerances for ours, 6 for Open3D (6 and 4 with
    ``quick``, which also takes fewer seeds per family); families: only these (LABELLED for the labelled
    clouds); ``baselines``: also infinite planes and Open3D (else None, faster)."""
    rows = []
    for family, cloud in split_clouds(split, quick, gt):
        if families and family not in families:
            continue
        open3d_grid = OPEN3D_QUICK_GRID if quick else OPEN3D_GRID
        rows.append(evaluate_cloud(split, family, cloud, 6 if quick else 12, open3d_grid, baselines))
        if on_row:
            on_row(rows[-1])
    return rows


def _short(r: Result | None) -> str:
    if r is None:
        return '—'
    return f'{r.quality.correct}/{r.quality.true_planes} F1 {r.quality.f1:.3f} @ {1000 * r.t:.3g} mm'


SCENE_HEADER = ('| split | family | scene | points | planes | regions best | infinite best | Open3D best | auto-tuned '
                '| auto / best F1 | reliable | good |\n|---|---|---|--:|--:|---|---|---|---|--:|---|---|')


def scene_line(r: Row) -> str:
    return (f'| {r.split} | {r.family} | {r.name} | {r.points} | {r.true_planes} | {_short(r.regions)} | '
            f'{_short(r.infinite)} | {_short(r.open3d)} | {_short(r.auto)}, {r.auto.seconds:.2f} s | {r.ratio:.3f} | '
            f'{"yes" if r.reliable else "no"} | {"yes" if r.good else "no"} |')


def _sum_correct(rows: list[Row], key: str) -> str:
    results = [getattr(r, key) for r in rows]
    if any(x is None for x in results):
        return '—'
    correct, true = sum(x.quality.correct for x in results), sum(x.quality.true_planes for x in results)
    return f'{correct}/{true} ({100 * correct / max(true, 1):.0f} %), F1 {np.mean([x.quality.f1 for x in results]):.3f}'


def summary_lines(rows: list[Row]) -> list[str]:
    """Per split and family, then per split: Hoover counts and mean F1 of each method, auto / best F1."""
    lines = ['| split | family | scenes | regions best | infinite best | Open3D best | auto-tuned | auto / best F1 '
             'median (min) | good | reliable |', '|---|---|--:|---|---|---|---|---|--:|--:|']
    groups: dict[tuple[str, str], list[Row]] = {}
    for r in rows:
        groups.setdefault((r.split, r.family), []).append(r)
    for split in dict.fromkeys(r.split for r in rows):
        groups[split, 'all'] = [r for r in rows if r.split == split]
    for (split, family), g in sorted(groups.items(), key=lambda kv: (SPLIT_NAMES.index(kv[0][0]), kv[0][1] == 'all')):
        ratios = [r.ratio for r in g]
        lines.append(f'| {split} | {"**all**" if family == "all" else family} | {len(g)} | '
                     + ' | '.join(_sum_correct(g, k) for k in ('regions', 'infinite', 'open3d', 'auto'))
                     + f' | {np.nanmedian(ratios):.3f} ({np.nanmin(ratios):.3f}) | {sum(r.good for r in g)} | '
                     f'{sum(r.reliable for r in g)} |')
    return lines


def confusion_lines(rows: list[Row]) -> list[str]:
    """The verdict (reliable) against good, per split: TP/FP/FN/TN, precision of "reliable", agreement,
    and how many bad results (BAD_CORRECT, BAD_RATIO) were called reliable."""
    lines = ['| split | scenes | TP | FP | FN | TN | precision of reliable | agreement | bad called reliable |',
             '|---|--:|--:|--:|--:|--:|--:|--:|--:|']
    for split in dict.fromkeys(r.split for r in rows):
        g = [r for r in rows if r.split == split]
        tp = sum(r.reliable and r.good for r in g)
        fp = sum(r.reliable and not r.good for r in g)
        fn = sum(not r.reliable and r.good for r in g)
        tn = sum(not r.reliable and not r.good for r in g)
        precision = f'{tp / (tp + fp):.2f}' if tp + fp else '—'
        bad = [r for r in g if r.bad]
        lines.append(f'| {split} | {len(g)} | {tp} | {fp} | {fn} | {tn} | {precision} | {(tp + tn) / len(g):.2f} | '
                     f'{sum(r.reliable for r in bad)}/{len(bad)} |')
    return lines


def write_json(path: Path, rows: list[Row], command: str) -> None:
    """The rows as JSON, written whole or not at all (a temporary file renamed into place)."""
    path = Path(path)
    tmp = path.with_name(path.name + '.tmp')
    tmp.write_text(json.dumps({'command': command, 'open3d': open3d_ref.version(),
                               'good': {'correct_share': GOOD_CORRECT, 'f1_ratio': GOOD_RATIO},
                               'rows': [asdict(r) for r in rows]}, indent=1, default=float))
    os.replace(tmp, path)


def read_json(path: Path) -> list[Row]:
    """The rows :func:`write_json` wrote (to summarise again without rerunning)."""
    def result(d: dict | None) -> Result | None:
        return None if d is None else Result(d['t'], Quality(**d['quality']), d['seconds'])
    return [Row(**{**r, **{k: result(r[k]) for k in ('regions', 'infinite', 'open3d', 'auto')},
                   'failures': tuple(r.get('failures', ()))})
            for r in json.loads(Path(path).read_text())['rows']]


def run_splits(splits: list[str], quick: bool, gt: Path, families: list[str] | None,
               baselines: bool = True) -> list[Row]:
    """Print the per-scene table as it goes, then the summary and the verdict's confusion table."""
    print(SCENE_HEADER, flush=True)
    rows = []
    for split in splits:
        rows += evaluate(split, quick, gt, families, on_row=lambda r: print(scene_line(r), flush=True),
                         baselines=baselines)
    print('', *summary_lines(rows), '', *confusion_lines(rows), sep='\n', flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true',
                        help='6 tolerances instead of 14 (12 with --split), no auto-tuning (except with --criteria '
                             'or --split, which also takes fewer seeds per family)')
    parser.add_argument('--criteria', action='store_true', help='auto-tuning by each criterion against the oracle')
    parser.add_argument('--split', choices=[*SPLIT_NAMES, 'both'],
                        help='the randomised scene families of a split (the labelled clouds in tuning)')
    parser.add_argument('--families', nargs='*', help=f'with --split: only these families ({LABELLED}, '
                        + ', '.join(scene_families.FAMILIES) + ')')
    parser.add_argument('--json', type=Path, help='with --split: write the rows to this file')
    parser.add_argument('--no-baselines', action='store_true',
                        help='with --split: ours only (no infinite planes, no Open3D), for trying rules fast')
    parser.add_argument('--gt', type=Path, default=GT, help=f'the labelled clouds (default {GT})')
    parser.add_argument('--noise-bound', type=float,
                        help='with --split: tune_tolerance\'s noise_bound (0: none; default the library\'s)')
    parser.add_argument('--write-readme', action='store_true', help='put the table into benchmarks/README.md')
    parser.add_argument('--only', nargs='*', help='cloud names')
    args = parser.parse_args()
    from plane_validation.core.blas import limit_blas_threads
    limit_blas_threads()
    command = shlex.join(['python', 'benchmarks/quality.py', *sys.argv[1:]])
    if args.split:
        if args.noise_bound is not None:
            TUNE_OPTIONS['noise_bound'] = args.noise_bound
        known = {LABELLED, *scene_families.FAMILIES}
        if args.families and not set(args.families) <= known:
            parser.error(f'unknown families {sorted(set(args.families) - known)}; choose from {sorted(known)}')
        print(f'Open3D: {open3d_ref.version()}', flush=True)
        start = time.perf_counter()
        splits = list(SPLIT_NAMES) if args.split == 'both' else [args.split]
        rows = run_splits(splits, args.quick, args.gt, args.families, baselines=not args.no_baselines)
        print(f'\n{len(rows)} scenes in {time.perf_counter() - start:.0f} s: `{command}`', flush=True)
        if args.json:
            write_json(args.json, rows, command)
        return
    count = 6 if args.quick else 14
    if args.criteria:
        rows = run_criteria(load_clouds(args.only, args.gt), count)
        if args.write_readme:
            write_criteria_readme(rows, command)
        return
    print(f'Open3D: {open3d_ref.version()}', flush=True)
    rows = run(load_clouds(args.only, args.gt), count, with_auto=not args.quick)
    if args.write_readme:
        write_readme(rows, command)

if __name__ == '__main__':
    main()
