"""Segmentation quality against per-point ground truth, ours (regions on and off) and Open3D.

Clouds: every labelled cloud in ../shared/data/gt (skipped with a message when the folder is
absent), the ICL-NUIM frame with depth-camera noise added, and the synthetic sensor scenes of
plane_validation.core.scenes (depth camera: room, table, stairs; spinning lidar). Each method runs
over a grid of tolerances; a row gives each method at its best t (most Hoover-correct regions,
then F1) and, for ours, the auto-tuned result (tune_tolerance with the library defaults).
--criteria instead auto-tunes with each criterion of plane_validation.core.tuning.CRITERIA and
gives each one's F1 as a fraction of the best regions result over the grid (the oracle).

Run: .venv/bin/python benchmarks/quality.py [--criteria] [--quick] [--write-readme] [--only NAME ...]
"""
from __future__ import annotations

import argparse
import re
import shlex
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pvbench import open3d_ref  # noqa: E402

import plane_validation as pv  # noqa: E402
from plane_validation.core import scenes  # noqa: E402
from plane_validation.core.scoring import Quality, segmentation_quality  # noqa: E402
from plane_validation.core.tuning import CRITERIA, DEFAULT_CRITERION  # noqa: E402

GT = Path(__file__).resolve().parents[2] / 'shared' / 'data' / 'gt'
README = Path(__file__).resolve().parent / 'README.md'
MARK = '<!-- quality table -->'
CRITERIA_MARK = '<!-- criteria table -->'
GOOD_RATIO = 0.97


@dataclass(frozen=True, eq=False)
class Cloud:
    """points (N, 3) m with NaN rows; labels (N,) true plane or -1; shape (H, W) or None."""

    name: str
    points: np.ndarray
    labels: np.ndarray
    shape: tuple[int, int] | None

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


def load_clouds(only: list[str] | None = None) -> list[Cloud]:
    """The benchmark's clouds (the labelled folder's when present, then the synthetic ones)."""
    clouds = []
    if GT.is_dir():
        for path in sorted(GT.glob('*.npz')):
            d = np.load(path)
            shape = tuple(int(v) for v in d['shape'])
            clouds.append(Cloud(path.stem, d['points'].astype(np.float64), d['labels'].astype(np.int64),
                                shape if shape != (0, 0) else None))
            if path.stem.startswith('icl_'):
                c = clouds[-1]
                clouds.append(Cloud(c.name + '_noisy', _depth_noise(c.points), c.labels, c.shape))
    else:
        print(f'{GT} not found: labelled clouds skipped, synthetic scenes only', flush=True)
    for view in scenes.SENSOR_VIEWS:
        s = scenes.depth_camera(view, seed=1)
        clouds.append(Cloud(s.name, s.points, s.labels.astype(np.int64), s.shape))
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
    return dict(max_planes=cloud.true_planes + 8, min_inliers=max(5, int((0.0008 if n > 20000 else 0.01) * n)))


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true',
                        help='6 tolerances instead of 14, no auto-tuning (except with --criteria)')
    parser.add_argument('--criteria', action='store_true', help='auto-tuning by each criterion against the oracle')
    parser.add_argument('--write-readme', action='store_true', help='put the table into benchmarks/README.md')
    parser.add_argument('--only', nargs='*', help='cloud names')
    args = parser.parse_args()
    from plane_validation.core.blas import limit_blas_threads
    limit_blas_threads()
    command = shlex.join(['python', 'benchmarks/quality.py', *sys.argv[1:]])
    count = 6 if args.quick else 14
    if args.criteria:
        rows = run_criteria(load_clouds(args.only), count)
        if args.write_readme:
            write_criteria_readme(rows, command)
        return
    print(f'Open3D: {open3d_ref.version()}', flush=True)
    rows = run(load_clouds(args.only), count, with_auto=not args.quick)
    if args.write_readme:
        write_readme(rows, command)


if __name__ == '__main__':
    main()
