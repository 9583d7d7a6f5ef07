"""The benchmark suite of plane_validation: speed, memory and quality, side by side with Open3D.

    .venv/bin/pip install -r benchmarks/requirements.txt     # Open3D and pyinstrument (optional)
    .venv/bin/python benchmarks/suite.py [--quick] [--skip-node] [--skip-quality] [--skip-tuning] [FILE ...]

FILE: extra frames (.pcd, .ply, .npy, text, or a bag's first cloud), e.g. the Kinect frames in
../shared/data. Synthetic 640 x 480 depth-camera frames with ground truth are always included
(benchmarks/pvbench/frames.py). Prints the figures as markdown tables and the targets with
PASS/FAIL. Every figure is a median over repeated runs in this one process, with min and max.
See benchmarks/README.md for what each figure means.
"""
from __future__ import annotations

import argparse
import inspect
import os
import platform
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from pvbench.node_e2e import domain_environment  # noqa: E402

# Before rclpy starts (the node processes inherit it): an isolated DDS domain, and the Fast DDS
# profile full-resolution clouds need (README, "Large clouds over Fast DDS").
domain_environment()
os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(ROOT / 'config' / 'fastdds_large_clouds.xml'))

import bench_autotune  # noqa: E402
import bench_lidar  # noqa: E402
import bench_many_planes  # noqa: E402
import numpy as np  # noqa: E402
import quality as gt_quality  # noqa: E402  (benchmarks/quality.py, not pvbench.quality)
import scipy  # noqa: E402
import verdict  # noqa: E402
from pvbench import open3d_ref, quality  # noqa: E402
from pvbench.frames import Frame, load_frames, resampled, synthetic_frames  # noqa: E402
from pvbench.node_e2e import NodeBench, NodeRun, cloud_message  # noqa: E402
from pvbench.stats import Summary, loglog_exponent  # noqa: E402

from plane_validation.app import pipeline as pv_pipeline  # noqa: E402
from plane_validation.app.pipeline import (  # noqa: E402
    FramePipeline,
    FrameResult,
    PipelineConfig,
    frame_seed,
)
from plane_validation.core import ransac as pv_ransac  # noqa: E402
from plane_validation.core.indices import validity_indices  # noqa: E402
from plane_validation.core.ransac import as_points, detect_planes  # noqa: E402
from plane_validation.core.verdict import judge  # noqa: E402
from plane_validation.formats.pointcloud2 import xyz_array  # noqa: E402

TOLERANCE = 0.01       # m, as in the Open3D measurement
PLANES = 5
SAMPLE = 2000          # points for the sampled indices
MIN_INLIERS = 0.005    # fraction of the valid points: small enough that 5 planes are found
SIZES = (10_000, 30_000, 100_000, 300_000, 1_000_000)
RATES = (2, 5, 10, 15, 20, 30)
F1_SLACK = 0.01        # F1 differences below this count as equal (run-to-run spread)
RSS_GROWTH_MB = 10.0   # "no growth": the fitted RSS trend from frame 100 to the end stays below this
RSS_EVERY = 50         # frames between RSS samples of figure (5)
STEADY = PipelineConfig(auto_tune=False, tolerance=TOLERANCE, max_planes=PLANES, index_sample_size=SAMPLE,
                        min_inliers=MIN_INLIERS)


def fmt(s: Summary, digits: int = 1) -> str:
    """'median (min–max)'."""
    return f'{s.median:.{digits}f} ({s.low:.{digits}f}–{s.high:.{digits}f})' if s.count else '—'


def _supported(fn, **kwargs) -> dict:
    """The keyword arguments ``fn`` accepts (the suite runs against a core that is still changing)."""
    names = inspect.signature(fn).parameters
    return {k: v for k, v in kwargs.items() if k in names}


def _finite(pts: np.ndarray) -> np.ndarray:
    return np.compress(pv_ransac.finite_rows(pts), pts, axis=0)


# -- (1) steady-state frame, (3) Open3D, quality ---------------------------------------------------

@dataclass
class Steady:
    """Figure (1) on one frame: ms summaries and the per-run results (for quality)."""

    total: Summary
    convert: Summary
    ransac: Summary
    indices: Summary
    publish: Summary
    runs: list[FrameResult] = field(default_factory=list)


def _stages(msg, cfg: PipelineConfig, stamp_ns: int) -> tuple[float, float, float]:
    """The pipeline's stages called one at a time (same input, parameters and seed as
    process_cloud): seconds of conversion, RANSAC, indices (+ verdict)."""
    t0 = time.perf_counter()
    pts = as_points(xyz_array(msg))
    finite = pv_ransac.finite_rows(pts)
    valid = np.compress(finite, pts, axis=0)
    t1 = time.perf_counter()
    seed = frame_seed(cfg.seed, stamp_ns)
    # an organized frame is searched as the pipeline searches it: with its image shape (connected regions)
    organized = msg.height > 1 and getattr(cfg, 'connectivity', False)
    seg = detect_planes(pts if organized else valid, cfg.tolerance, **_supported(
        detect_planes, max_planes=cfg.max_planes, min_inliers=cfg.min_inliers, probability=cfg.probability,
        max_iterations=cfg.max_iterations, seed=seed, ransac_points=getattr(cfg, 'ransac_points', 0) or None,
        shape=(msg.height, msg.width) if organized else None))
    labels = seg.labels[finite] if organized else seg.labels
    t2 = time.perf_counter()
    scores = validity_indices(valid, labels, **_supported(
        validity_indices, sample_size=cfg.index_sample_size, seed=seed,
        sampled_separation=not getattr(cfg, 'exact_indices', True)))
    judge(pts if organized else valid, seg, scores)
    t3 = time.perf_counter()
    return t1 - t0, t2 - t1, t3 - t2


def steady_state(frame: Frame, repeats: int) -> Steady:
    """The node's per-frame work at a fixed tolerance: process_cloud + frame_messages (total), and
    the same stages timed one at a time. A warm-up run first; stamps differ, so do the seeds."""
    from plane_validation.ros.messages import frame_messages
    msg = cloud_message(frame.points, frame.height, frame.width)
    pipe = FramePipeline(STEADY)
    times: dict[str, list[float]] = {k: [] for k in ('total', 'convert', 'ransac', 'indices', 'publish')}
    runs = []
    for i in range(repeats + 1):
        stamp_ns = (1000 + i) * 10**9
        msg.header.stamp.sec, msg.header.stamp.nanosec = 1000 + i, 0
        t0 = time.perf_counter()
        result = pipe.process_cloud(msg)
        t1 = time.perf_counter()
        frame_messages(msg.header, result, 'bench')
        t2 = time.perf_counter()
        stages = _stages(msg, STEADY, stamp_ns)
        if i:
            runs.append(result)
            for key, value in zip(times, (t2 - t0, *stages, t2 - t1)):
                times[key].append(1e3 * value)
    return Steady(*(Summary.of(v) for v in times.values()), runs=runs)


@dataclass
class Reference:
    """Figure (3) on one frame: Open3D's time (ms) and per-run (coefficients, labels)."""

    time: Summary
    runs: list[tuple[np.ndarray, np.ndarray]]


def open3d_run(frame: Frame, repeats: int) -> Reference | None:
    """Open3D's sequential segment_plane on the very points our pipeline sees (float32 from the
    message, NaN rows removed); the PointCloud conversion is not timed."""
    if not open3d_ref.available():
        return None
    valid = _finite(xyz_array(cloud_message(frame.points, frame.height, frame.width)))
    cloud = open3d_ref.to_cloud(valid)
    times, runs = [], []
    for i in range(repeats + 1):
        t0 = time.perf_counter()
        out = open3d_ref.sequential_planes(cloud, len(valid), TOLERANCE, PLANES, seed=i)
        if i:
            times.append(1e3 * (time.perf_counter() - t0))
            runs.append(out)
    return Reference(Summary.of(times), runs)


@dataclass
class Quality:
    """Per frame, over the timed runs (run i of ours against run i of Open3D)."""

    planes_ours: Summary
    planes_o3d: Summary
    angle_deg: Summary
    iou: Summary
    inliers_ours: Summary
    inliers_o3d: Summary
    f1_ours: Summary
    f1_o3d: Summary


def compare(frame: Frame, ours: Steady, ref: Reference | None) -> Quality:
    """Our planes against Open3D's (dominant plane) and both against the truth (synthetic)."""
    rows: dict[str, list[float]] = {k: [] for k in Quality.__dataclass_fields__}
    truth = frame.truth[frame.finite] if frame.synthetic else None
    for i, result in enumerate(ours.runs):
        seg = result.segmentation
        rows['planes_ours'].append(result.n_planes)
        if truth is not None:
            rows['f1_ours'].append(quality.truth_f1(truth, result.labels))
        if ref is None or seg is None:
            continue
        coeffs, labels = ref.runs[i]
        rows['planes_o3d'].append(len(coeffs))
        if truth is not None:
            rows['f1_o3d'].append(quality.truth_f1(truth, labels))
        match = quality.match_dominant(result.labels, seg.coefficients[:, :3], labels, coeffs[:, :3])
        if match is not None:
            rows['angle_deg'].append(match.angle_deg)
            rows['iou'].append(match.iou)
            rows['inliers_ours'].append(match.ours_inliers)
            rows['inliers_o3d'].append(match.open3d_inliers)
    return Quality(**{k: Summary.of(v) for k, v in rows.items()})


# -- (2) sweep, (6) scaling ------------------------------------------------------------------------

def sweep(frame: Frame, repeats: int) -> tuple[Summary, float, int]:
    """A full auto-tune sweep (FramePipeline.retune, the node's default tuning parameters):
    ms summary, the chosen t (m) and its plane count, last run."""
    valid = frame.points[frame.finite]
    times, tuned = [], None
    for i in range(repeats):
        pipe = FramePipeline(PipelineConfig())
        t0 = time.perf_counter()
        tuned = pipe.retune(valid, float(i), i)
        times.append(1e3 * (time.perf_counter() - t0))
    return Summary.of(times), tuned.tolerance, tuned.segmentation.n_planes


def scaling(frame: Frame, repeats: int, sizes) -> tuple[list[tuple[int, Summary, Summary]], float, float]:
    """Steady-state FramePipeline.process and detect_planes alone vs number of points (resampled
    from ``frame``): rows (n, pipeline ms, RANSAC ms) and the fitted exponents (pipeline, RANSAC)."""
    rows = []
    for n in sizes:
        pts = resampled(frame, n)
        pipe = FramePipeline(STEADY)
        whole, search = [], []
        for i in range(repeats + 1):
            t0 = time.perf_counter()
            pipe.process(pts, (2000 + i) * 10**9)
            t1 = time.perf_counter()
            detect_planes(pts, TOLERANCE, **_supported(
                detect_planes, max_planes=PLANES, min_inliers=MIN_INLIERS, seed=i,
                ransac_points=getattr(STEADY, 'ransac_points', 0) or None))
            t2 = time.perf_counter()
            if i:
                whole.append(1e3 * (t1 - t0))
                search.append(1e3 * (t2 - t1))
        rows.append((n, Summary.of(whole), Summary.of(search)))
    ns = [r[0] for r in rows]
    return rows, loglog_exponent(ns, [r[1].median for r in rows]), loglog_exponent(ns, [r[2].median for r in rows])


def rss_growth(samples: list[tuple[int, float]]) -> tuple[float, int, int]:
    """(MB, first frame, last frame): a least-squares line through the RSS samples from frame 100
    on, evaluated from its first to its last frame (robust to the sawtooth of the allocator)."""
    late = [(n, mb) for n, mb in samples if n >= 100] or samples
    if len(late) < 2:
        return float('nan'), late[0][0] if late else 0, late[-1][0] if late else 0
    n, mb = np.array(late, dtype=float).T
    slope = np.polyfit(n, mb, 1)[0]
    return float(slope * (n[-1] - n[0])), int(n[0]), int(n[-1])


# -- report ----------------------------------------------------------------------------------------

def machine() -> str:
    """CPU, core count, versions, date and the code measured."""
    model = 'unknown CPU'
    try:
        model = next(line.split(':', 1)[1].strip() for line in Path('/proc/cpuinfo').read_text().splitlines()
                     if line.startswith('model name'))
    except (OSError, StopIteration):
        pass
    try:
        commit = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=ROOT, capture_output=True,
                                text=True, check=False).stdout.strip()
        dirty = subprocess.run(['git', 'status', '--porcelain', '--', 'plane_validation'], cwd=ROOT,
                               capture_output=True, text=True, check=False).stdout.split()[1::2]
    except OSError:
        commit, dirty = 'unknown', []
    code = f'commit {commit}' + (f' + uncommitted {", ".join(dirty)}' if dirty else '')
    return (f'{time.strftime("%Y-%m-%d %H:%M")}; {os.cpu_count()} cores ({model}); Python '
            f'{platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, '
            f'Open3D {open3d_ref.version()}; code: {code}; load average {os.getloadavg()[0]:.2f} at start')


def print_steady(frames: list[Frame], steady: list[Steady], refs: list[Reference | None], repeats: int) -> None:
    print(f'## (1) steady-state frame and (3) Open3D — t = {TOLERANCE} m, up to {PLANES} planes, '
          f'min_inliers {MIN_INLIERS} of the valid points, indices on a {SAMPLE}-point sample; '
          f'ms, median (min–max) of {repeats} runs after a warm-up\n')
    print('| frame | valid points | ours: total | conversion | RANSAC | indices | publishing side | '
          'Open3D 5 × segment_plane | ours / Open3D |')
    print('| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |')
    for frame, ours, ref in zip(frames, steady, refs):
        ratio = f'{ours.total.median / ref.time.median:.2f}' if ref else '—'
        print(f'| {frame.name} | {frame.n_valid} | {fmt(ours.total)} | {fmt(ours.convert)} | {fmt(ours.ransac)} | '
              f'{fmt(ours.indices)} | {fmt(ours.publish)} | {fmt(ref.time) if ref else "—"} | {ratio} |')
    print('\ntotal = process_cloud (PointCloud2 in, planes and indices out) + frame_messages (the five output '
          'messages); the stage columns are the same steps called one at a time in the same run.')


def print_quality(frames: list[Frame], qualities: list[Quality]) -> None:
    print('\n## Quality beside speed (median over the runs; dominant = Open3D\'s first plane, matched to '
          'our plane with the best inlier IoU)\n')
    print('| frame | planes ours / Open3D | dominant angle ° (max) | IoU | dominant inliers ours / Open3D | '
          'truth F1 ours | truth F1 Open3D |')
    print('| --- | ---: | ---: | ---: | ---: | ---: | ---: |')
    for frame, q in zip(frames, qualities):
        angle = f'{q.angle_deg.median:.3f} ({q.angle_deg.high:.3f})' if q.angle_deg.count else '—'
        inl = f'{q.inliers_ours.median:.0f} / {q.inliers_o3d.median:.0f}' if q.inliers_ours.count else '—'
        print(f'| {frame.name} | {q.planes_ours.median:.0f} / {q.planes_o3d.median:.0f} | {angle} | '
              f'{q.iou.median:.3f} | {inl} | {q.f1_ours.median:.3f} | {q.f1_o3d.median:.3f} |'
              .replace('nan', '—'))


def print_node(runs: list[NodeRun], retune: NodeRun | None, memory: NodeRun | None, ref: Frame) -> None:
    print(f'\n## (4) node end to end over DDS — {ref.name}, a fresh node process per rate, sensor-data QoS, '
          f'{Path(os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"]).name}\n')
    print('| input Hz | sent | answered | dropped (node count) | lost | latency ms | processing ms (node) |')
    print('| ---: | ---: | ---: | ---: | ---: | ---: | ---: |')
    for run in runs:
        print(f'| {run.rate:g} | {run.sent} | {run.answered} | {run.dropped} | {run.lost} | '
              f'{fmt(Summary.of(run.latencies_ms))} | {fmt(Summary.of(run.processing_ms))} |')
    best = max((r.rate for r in runs if r.sustained), default=0)
    print(f'\nhighest input rate with every frame answered: {best:g} Hz')
    if retune is not None:
        during = [lat for lat, busy in zip(retune.latencies_ms[1:], retune.retune_running[1:]) if busy]
        idle = [lat for lat, busy in zip(retune.latencies_ms[1:], retune.retune_running[1:]) if not busy]
        first = f'{retune.latencies_ms[0]:.0f}' if retune.latencies_ms else '—'
        print(f'\nauto_tune on, retune_period 1 s, {retune.rate:g} Hz: answered {retune.answered} of {retune.sent}, '
              f'dropped {retune.dropped}; first frame (tuned inline) {first} ms; latency while a background sweep '
              f'runs {fmt(Summary.of(during))} ms over {len(during)} frames, otherwise {fmt(Summary.of(idle))} ms')
    if memory is not None:
        print(f'\n## (5) node memory — {memory.sent} frames at {memory.rate:g} Hz, all 640 × 480 frames in turn\n')
        print(f'RSS at start {memory.startup_rss_mb:.0f} MB; RSS (MB) every {RSS_EVERY} frames: '
              + ', '.join(f'{rss:.0f}' for _, rss in memory.rss_mb))
        growth, first, last = rss_growth(memory.rss_mb)
        print(f'peak RSS (VmHWM) {memory.peak_mb:.0f} MB; growth from frame {first} to {last} (fitted line): '
              f'{growth:+.1f} MB; answered {memory.answered}, dropped {memory.dropped}, lost {memory.lost}')


# -- main ------------------------------------------------------------------------------------------

@dataclass
class Figures:
    """Everything measured, for the targets."""

    frames: list[Frame]
    steady: list[Steady]
    refs: list[Reference | None]
    qualities: list[Quality]
    ref_index: int
    sweep_ms: Summary | None = None
    exponents: tuple[float, float] | None = None
    rates: list[NodeRun] = field(default_factory=list)
    retune: NodeRun | None = None
    memory: NodeRun | None = None


def targets(fig: Figures) -> list[tuple[str, str, bool]]:
    """(target, measured, pass) rows, as issue 7 states them."""
    checks = []
    for frame, ours, ref in zip(fig.frames, fig.steady, fig.refs):
        if frame.height * frame.width != 640 * 480:
            continue
        checks.append((f'{frame.name}: steady-state frame ≤ 50 ms', f'{ours.total.median:.1f} ms',
                       ours.total.median <= 50))
        if ref:
            ratio = ours.total.median / ref.time.median
            checks.append((f'{frame.name}: ≤ 0.5 × Open3D', f'{ratio:.2f}', ratio <= 0.5))
    for frame, q in zip(fig.frames, fig.qualities):
        if not frame.synthetic and q.angle_deg.count:
            checks.append((f'{frame.name}: dominant plane within 1° of Open3D\'s', f'{q.angle_deg.median:.3f}°',
                           q.angle_deg.median <= 1.0))
        if frame.synthetic and q.f1_o3d.count:
            checks.append((f'{frame.name}: truth F1 ≥ Open3D\'s (−{F1_SLACK})',
                           f'{q.f1_ours.median:.3f} vs {q.f1_o3d.median:.3f}',
                           q.f1_ours.median >= q.f1_o3d.median - F1_SLACK))
    ref_name = fig.frames[fig.ref_index].name
    if fig.sweep_ms is not None:
        checks.append((f'full auto-tune sweep ≤ 1 s ({ref_name})', f'{fig.sweep_ms.median:.0f} ms',
                       fig.sweep_ms.median <= 1000))
    if fig.exponents is not None:
        checks.append(('time exponent ≤ 1.1 (steady-state pipeline)', f'{fig.exponents[0]:.2f}',
                       fig.exponents[0] <= 1.1))
    for run in fig.rates:
        lat = Summary.of(run.latencies_ms).median
        if run.rate == 10:
            checks.append(('node at 10 Hz: median latency ≤ 100 ms, no drops',
                           f'{lat:.0f} ms, {run.answered}/{run.sent} answered', lat <= 100 and run.sustained))
        if run.rate == 30:
            checks.append(('node at 30 Hz: responsive (median latency ≤ 100 ms), every unanswered frame counted',
                           f'{lat:.0f} ms, {run.dropped} dropped, {run.lost} lost', lat <= 100 and run.lost == 0))
    if fig.retune is not None and fig.sweep_ms is not None:
        during = [lat for lat, busy in zip(fig.retune.latencies_ms[1:], fig.retune.retune_running[1:]) if busy]
        worst = max(during, default=float('nan'))
        checks.append(('sweep never blocks the stream (frames answered during sweeps, none waited a sweep)',
                       f'{len(during)} frames, max {worst:.0f} ms',
                       bool(during) and worst < fig.sweep_ms.median))
    if fig.memory is not None and fig.memory.rss_mb:
        mem = fig.memory
        growth, first, last = rss_growth(mem.rss_mb)
        checks.append(('node peak RSS ≤ 400 MB', f'{mem.peak_mb:.0f} MB', mem.peak_mb <= 400))
        checks.append((f'no RSS growth, frame {first} → {last} (fitted, ≤ {RSS_GROWTH_MB:g} MB)',
                       f'{growth:+.1f} MB', growth <= RSS_GROWTH_MB))
    return checks


def print_summary(fig: Figures) -> None:
    """One table of the headline figures on the reference frame: median, min, max."""
    i = fig.ref_index
    frame, ours, ref = fig.frames[i], fig.steady[i], fig.refs[i]
    rows: list[tuple[str, Summary, str]] = [
        ('(1) steady-state frame, total', ours.total, 'ms'), ('(1) conversion', ours.convert, 'ms'),
        ('(1) RANSAC', ours.ransac, 'ms'), ('(1) indices', ours.indices, 'ms'),
        ('(1) publishing side (messages built)', ours.publish, 'ms')]
    if fig.sweep_ms is not None:
        rows.append(('(2) full auto-tune sweep', fig.sweep_ms, 'ms'))
    if ref is not None:
        rows.append(('(3) Open3D, 5 sequential segment_plane', ref.time, 'ms'))
        ratio = ours.total.median / ref.time.median
        rows.append(('(3) ours / Open3D (medians)', Summary(ratio, ratio, ratio, 1), ''))
    for run in fig.rates:
        if run.rate in (10, 30):
            label = f'(4) node latency at {run.rate:g} Hz ({run.answered}/{run.sent} answered, {run.dropped} dropped)'
            rows.append((label, Summary.of(run.latencies_ms), 'ms'))
    if fig.rates:
        best = float(max((r.rate for r in fig.rates if r.sustained), default=0))
        rows.append(('(4) highest input rate with no drops (of ' + ', '.join(f'{r.rate:g}' for r in fig.rates) + ')',
                     Summary(best, best, best, 1), 'Hz'))
    if fig.memory is not None and fig.memory.rss_mb:
        rss = Summary.of([mb for _, mb in fig.memory.rss_mb])
        rows.append((f'(5) node RSS over {fig.memory.sent} frames (peak VmHWM {fig.memory.peak_mb:.0f} MB)', rss, 'MB'))
        growth = rss_growth(fig.memory.rss_mb)[0]
        rows.append(('(5) RSS growth, frame 100 to the end (fitted)', Summary(growth, growth, growth, 1), 'MB'))
    if fig.exponents is not None:
        for label, b in zip(('pipeline', 'RANSAC alone'), fig.exponents):
            rows.append((f'(6) exponent b of time ∝ N^b, {label}', Summary(b, b, b, 1), ''))
    print(f'\n## Summary — reference frame {frame.name} ({frame.n_valid} valid points)\n')
    print('| figure | median | min | max | unit |\n| --- | ---: | ---: | ---: | --- |')
    for what, s, unit in rows:
        digits = 2 if unit in ('', 'Hz') else 1
        print(f'| {what} | {s.median:.{digits}f} | {s.low:.{digits}f} | {s.high:.{digits}f} | {unit} |')


def run_node(fig: Figures, quick: bool, rss_frames: int) -> None:
    """Figures (4) and (5): rates, a retune run and the memory run, each with a fresh node."""
    ref = fig.frames[fig.ref_index]
    clouds = [cloud_message(ref.points, ref.height, ref.width)]
    with tempfile.TemporaryDirectory(prefix='pv_bench_') as logs:
        bench = NodeBench(clouds, TOLERANCE, PLANES, Path(logs))
        try:
            frames_per_run = 30 if quick else 100
            for rate in ((5, 10, 30) if quick else RATES):
                fig.rates.append(bench.run(rate, max(frames_per_run, int(2 * rate)), name=f'{rate}hz'))
            fig.retune = bench.run(10, frames_per_run, params={'auto_tune': 'true', 'retune_period': '1.0'},
                                   name='retune')
            sustained = [r.rate for r in fig.rates if r.sustained]
            rate = min(10, max(sustained, default=min(RATES)))
            bench.clouds = [cloud_message(f.points, f.height, f.width) for f in fig.frames
                            if f.height * f.width == 640 * 480]
            fig.memory = bench.run(rate, rss_frames, rss_every=RSS_EVERY, name='memory')
        finally:
            bench.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('files', nargs='*', help='extra frames: .pcd .ply .npy text, or a bag (its first cloud)')
    parser.add_argument('--quick', action='store_true', help='fewer repeats, rates and points (a smoke run)')
    parser.add_argument('--skip-node', action='store_true', help='skip the DDS figures (4) and (5)')
    parser.add_argument('--skip-scaling', action='store_true', help='skip figure (6)')
    parser.add_argument('--skip-sweep', action='store_true', help='skip figure (2)')
    parser.add_argument('--rss-frames', type=int, default=None, help='frames of figure (5) (1000; --quick 200)')
    parser.add_argument('--skip-quality', action='store_true',
                        help='skip (7) quality against ground truth and (9) the verdict calibration')
    parser.add_argument('--skip-tuning', action='store_true', help='skip (8) auto-tuning speed against Open3D')
    parser.add_argument('--skip-lidar', action='store_true', help='skip (8b) unorganized lidar frames')
    args = parser.parse_args(argv)
    limit = getattr(pv_pipeline, 'limit_blas_threads', None)
    if limit:
        limit()  # as the node does at start
    repeats = 3 if args.quick else 7
    rss_frames = args.rss_frames or (200 if args.quick else 1000)

    print(f'# plane_validation benchmark suite\n\n{machine()}\n')
    frames = synthetic_frames()
    for path in args.files:
        try:
            frames += load_frames(path)
        except (ValueError, OSError) as exc:
            print(f'skipped {path}: {exc}')
    if open3d_ref.available():
        print(f'Open3D: {open3d_ref.params()}\n')
    else:
        print(f'Open3D {open3d_ref.version()}: comparison skipped (pip install -r benchmarks/requirements.txt; '
              'open3d needs libusb-1.0 from the system)\n')

    steady = [steady_state(f, repeats) for f in frames]
    refs = [open3d_run(f, repeats) for f in frames]
    ref_index = max(range(len(frames)), key=lambda i: (not frames[i].synthetic, frames[i].n_valid))
    fig = Figures(frames, steady, refs, [compare(f, s, r) for f, s, r in zip(frames, steady, refs)], ref_index)
    print_steady(frames, steady, refs, repeats)
    print_quality(frames, fig.qualities)
    ref = frames[ref_index]

    if not args.skip_sweep:
        fig.sweep_ms, tuned_t, tuned_planes = sweep(ref, 3)
        print(f'\n## (2) full auto-tune sweep — FramePipeline.retune with the node\'s default tuning parameters, '
              f'{ref.name} ({ref.n_valid} points); ms, median (min–max) of 3\n')
        print(f'{fmt(fig.sweep_ms)} ms; chose t = {tuned_t:.4g} m, {tuned_planes} planes')

    if not args.skip_scaling:
        sizes = SIZES[:4] if args.quick else SIZES
        rows, whole, search = scaling(ref, 1 if args.quick else 3, sizes)
        fig.exponents = (whole, search)
        print(f'\n## (6) time vs number of points — resampled from {ref.name}, steady-state settings; '
              'ms, median (min–max)\n')
        print('| points | pipeline (FramePipeline.process) | RANSAC alone (detect_planes) |\n| ---: | ---: | ---: |')
        for n, w, s in rows:
            print(f'| {n} | {fmt(w)} | {fmt(s)} |')
        print(f'\nfitted exponent b of time ∝ N^b: pipeline {whole:.2f}, RANSAC alone {search:.2f}')
        if len(rows) >= 2:
            (n0, w0, s0), (n1, w1, s1) = rows[-2:]
            print(f'between the two largest sizes ({n0} → {n1}): pipeline '
                  f'{loglog_exponent([n0, n1], [w0.median, w1.median]):.2f}, RANSAC alone '
                  f'{loglog_exponent([n0, n1], [s0.median, s1.median]):.2f}')

    if not args.skip_node:
        run_node(fig, args.quick, rss_frames)
        print_node(fig.rates, fig.retune, fig.memory, ref)

    if not args.skip_quality:
        print('\n## (7) segmentation quality against ground truth — benchmarks/quality.py\n')
        gt_quality.run(gt_quality.load_clouds(), 6 if args.quick else 14, with_auto=not args.quick)
    if not args.skip_tuning:
        print('\n## (8) auto-tuning speed — benchmarks/bench_autotune.py, bench_many_planes.py\n')
        bench_autotune.table([str(p) for p in sorted(bench_autotune.DATA.glob('*.pcd'))], 1 if args.quick else 3)
        print()
        bench_many_planes.measure(1 if args.quick else 3)
    if not args.skip_lidar:
        print('\n## (8b) unorganized lidar frames — benchmarks/bench_lidar.py\n')
        bench_lidar.table(1 if args.quick else 5)
    if not args.skip_quality and not args.quick:
        print('\n## (9) verdict calibration — benchmarks/verdict.py\n')
        verdict.table()

    print_summary(fig)
    print('\n## Targets (issue 7)\n')
    print('| target | measured | |\n| --- | --- | --- |')
    for what, value, ok in targets(fig):
        print(f'| {what} | {value} | {"PASS" if ok else "FAIL"} |')
    print(f'\nload average at the end (1 min): {os.getloadavg()[0]:.2f} — other work on the machine skews the times')
    return 0


if __name__ == '__main__':
    sys.exit(main())
