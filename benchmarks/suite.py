"""The benchmark suite of plane_validation: speed, memory and quality, side by side with Open3D.

    .venv/bin/pip install -r benchmarks/requirements.txt     # Open3D (optional; needs libusb-1.0-0)
    .venv/bin/python benchmarks/suite.py [--quick] [--skip-node] [FILE ...]

FILE: extra frames (.pcd, .ply, .npy, text, or a bag's first cloud), e.g. the Kinect frames in
../shared/data. Synthetic 640 x 480 depth-camera frames with ground truth are always included
(benchmarks/pvbench/frames.py). Prints one table per figure and the targets with PASS/FAIL.
Every time is a median over repeated runs in this one process, with min and max.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
# Before rclpy starts (the node processes inherit it): full-resolution clouds need the large
# shared-memory segment over Fast DDS (see the README's node section).
os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(ROOT / 'config' / 'fastdds_large_clouds.xml'))
os.environ.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 50))
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

import numpy as np  # noqa: E402
import scipy  # noqa: E402

from plane_validation.cloud import create_cloud, xyz_array  # noqa: E402
from plane_validation.indices import validity_indices  # noqa: E402
from plane_validation.pipeline import FramePipeline, PipelineConfig, limit_blas_threads  # noqa: E402
from plane_validation.ransac import as_points, detect_planes, finite_rows  # noqa: E402
from plane_validation.tuning import judge  # noqa: E402
from pvbench import open3d_ref, quality  # noqa: E402
from pvbench.frames import Frame, load_frames, resampled, synthetic_frames  # noqa: E402
from pvbench.stats import Summary, loglog_exponent  # noqa: E402

TOLERANCE = 0.01       # m, as in the Open3D measurement
PLANES = 5
SAMPLE = 2000          # index sample
SIZES = (10_000, 30_000, 100_000, 300_000, 1_000_000)


def ms(summary: Summary) -> str:
    return f'{summary.median:.1f} ({summary.low:.1f}–{summary.high:.1f})'


def cloud_message(frame: Frame):
    import sensor_msgs.msg
    from std_msgs.msg import Header
    pts = frame.points.astype(np.float32)
    msg = create_cloud(Header(frame_id='camera'), {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2]},
                       types=sensor_msgs.msg)
    msg.height, msg.width, msg.row_step = frame.height, frame.width, frame.width * msg.point_step
    return msg


def steady_state(frame: Frame, repeats: int) -> dict:
    """Figure (1): the node's per-frame work at a fixed tolerance, whole and by stage."""
    from plane_validation.messages import frame_messages
    msg = cloud_message(frame)
    pipe = FramePipeline(PipelineConfig(auto_tune=False, tolerance=TOLERANCE, max_planes=PLANES,
                                        index_sample_size=SAMPLE))
    totals, convert, ransac, indices, publish = [], [], [], [], []
    result = None
    for i in range(repeats + 1):  # the first run warms up caches and imports
        msg.header.stamp.sec = 1000 + i
        t0 = time.perf_counter()
        result = pipe.process_cloud(msg)
        t1 = time.perf_counter()
        frame_messages(msg.header, result, 'bench')
        t2 = time.perf_counter()
        # the same stages once more, one at a time (same input and seed: the same work)
        seed = 1000 + i
        c0 = time.perf_counter()
        pts = as_points(xyz_array(msg))
        valid = np.compress(finite_rows(pts), pts, axis=0)
        c1 = time.perf_counter()
        seg = detect_planes(valid, TOLERANCE, max_planes=PLANES, seed=seed)
        c2 = time.perf_counter()
        scores = validity_indices(valid, seg.labels, sample_size=SAMPLE, seed=seed, sampled_separation=True)
        judge(valid, seg, scores)
        c3 = time.perf_counter()
        if i:
            totals.append(t2 - t0)
            publish.append(t2 - t1)
            convert.append(c1 - c0)
            ransac.append(c2 - c1)
            indices.append(c3 - c2)
    return {'total': Summary.of(totals).scaled(1e3), 'convert': Summary.of(convert).scaled(1e3),
            'ransac': Summary.of(ransac).scaled(1e3), 'indices': Summary.of(indices).scaled(1e3),
            'publish': Summary.of(publish).scaled(1e3), 'result': result}


def open3d_run(frame: Frame, repeats: int) -> dict | None:
    """Figure (3): Open3D's 5 sequential segment_plane calls on the same finite points."""
    if not open3d_ref.available():
        return None
    valid = frame.points[frame.finite]
    cloud = open3d_ref.to_cloud(valid)
    times, out = [], None
    for i in range(repeats + 1):
        t0 = time.perf_counter()
        out = open3d_ref.sequential_planes(cloud, len(valid), TOLERANCE, PLANES, seed=i)
        if i:
            times.append(time.perf_counter() - t0)
    return {'time': Summary.of(times).scaled(1e3), 'coefficients': out[0], 'labels': out[1]}


def sweep(frame: Frame, repeats: int) -> tuple[Summary, float, int]:
    """Figure (2): a full auto-tune sweep with the node's defaults."""
    valid = frame.points[frame.finite]
    times, tuned = [], None
    for i in range(repeats):
        pipe = FramePipeline(PipelineConfig())
        t0 = time.perf_counter()
        tuned = pipe.retune(valid, 0.0, i)
        times.append(time.perf_counter() - t0)
    return Summary.of(times).scaled(1e3), tuned.tolerance, tuned.segmentation.n_planes


def scaling(frame: Frame, repeats: int, sizes=SIZES) -> tuple[list[tuple[int, Summary]], float, float]:
    """Figure (6): detection + indices vs number of points; fitted exponents (whole, RANSAC)."""
    rows, whole, search = [], [], []
    for n in sizes:
        pts = resampled(frame, n)
        t_all, t_det = [], []
        for i in range(repeats + 1):
            t0 = time.perf_counter()
            seg = detect_planes(pts, TOLERANCE, max_planes=PLANES, seed=i)
            t1 = time.perf_counter()
            scores = validity_indices(pts, seg.labels, sample_size=SAMPLE, seed=i, sampled_separation=True)
            judge(pts, seg, scores)
            t2 = time.perf_counter()
            if i:
                t_all.append(t2 - t0)
                t_det.append(t1 - t0)
        rows.append((n, Summary.of(t_all).scaled(1e3)))
        whole.append(Summary.of(t_all).median)
        search.append(Summary.of(t_det).median)
    return rows, loglog_exponent(sizes, whole), loglog_exponent(sizes, search)


def machine() -> str:
    model = 'unknown CPU'
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                model = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    return (f'{os.cpu_count()} cores ({model}), Python {platform.python_version()}, numpy {np.__version__}, '
            f'scipy {scipy.__version__}, Open3D {open3d_ref.version()}; {time.strftime("%Y-%m-%d")}')


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('files', nargs='*', help='extra frames: .pcd .ply .npy text or a bag')
    parser.add_argument('--quick', action='store_true', help='fewer repeats and frames (a smoke run)')
    parser.add_argument('--skip-node', action='store_true', help='skip the DDS figures (4) and (5)')
    parser.add_argument('--rss-frames', type=int, default=1000, help='frames for the memory figure (5)')
    args = parser.parse_args(argv)
    limit_blas_threads()  # as the node does at start
    repeats = 3 if args.quick else 7

    print(f'# plane_validation benchmark suite\n\n{machine()}\n')
    frames = synthetic_frames()
    for path in args.files:
        try:
            frames += load_frames(path)
        except ValueError as exc:
            print(f'skipped {path}: {exc}')
    if not open3d_ref.available():
        print('Open3D not installed: comparison skipped (pip install -r benchmarks/requirements.txt)\n')

    # (1), (3) and quality, per frame
    print(f'## (1) steady-state frame and (3) Open3D, t = {TOLERANCE} m, up to {PLANES} planes, '
          f'indices on a {SAMPLE}-point sample; ms, median (min–max) of {repeats}\n')
    print('| frame | valid points | ours: total | conversion | RANSAC | indices | publishing side | '
          'Open3D 5 × segment_plane | ours / Open3D |')
    print('| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |')
    results = []
    for frame in frames:
        ours = steady_state(frame, repeats)
        ref = open3d_run(frame, repeats)
        ratio = ours['total'].median / ref['time'].median if ref else float('nan')
        results.append((frame, ours, ref))
        print(f'| {frame.name} | {frame.n_valid} | {ms(ours["total"])} | {ms(ours["convert"])} | '
              f'{ms(ours["ransac"])} | {ms(ours["indices"])} | {ms(ours["publish"])} | '
              f'{ms(ref["time"]) if ref else "—"} | {ratio:.2f} |')

    print('\n## Quality: our planes beside Open3D\'s (and the ground truth on synthetic frames)\n')
    print('| frame | planes ours / Open3D | dominant: angle to ours (°) | its inliers Open3D / ours | '
          'F1 ours | F1 Open3D |')
    print('| --- | ---: | ---: | ---: | ---: | ---: |')
    angles, f1_pairs = [], []
    for frame, ours, ref in results:
        seg = ours['result'].segmentation
        labels = np.full(len(frame.points), -1, np.int32)
        labels[frame.finite] = ours['result'].labels
        f1_ours = quality.truth_f1(frame.truth, labels) if frame.synthetic else float('nan')
        if ref is None:
            print(f'| {frame.name} | {seg.n_planes} / — | — | — | {f1_ours:.3f} | — |')
            continue
        angle, k = quality.matched_dominant(ref['coefficients'][0], seg.coefficients)
        o3d_labels = np.full(len(frame.points), -1, np.int32)
        o3d_labels[frame.finite] = ref['labels']
        f1_ref = quality.truth_f1(frame.truth, o3d_labels) if frame.synthetic else float('nan')
        if not frame.synthetic:
            angles.append((frame.name, angle))
        else:
            f1_pairs.append((frame.name, f1_ours, f1_ref))
        print(f'| {frame.name} | {seg.n_planes} / {len(ref["coefficients"])} | {angle:.3f} | '
              f'{int((ref["labels"] == 0).sum())} / {int((seg.labels == k).sum())} | '
              f'{f1_ours:.3f} | {f1_ref:.3f} |')

    # (2) sweep, on the largest frame (a real one when given)
    big = max(frames, key=lambda f: (not f.synthetic, f.n_valid))
    sweep_ms, tuned_t, tuned_planes = sweep(big, 2 if args.quick else 3)
    print(f'\n## (2) full auto-tune sweep (node defaults) on {big.name} ({big.n_valid} points)\n')
    print(f'{ms(sweep_ms)} ms; chose t = {tuned_t:.4g} m, {tuned_planes} planes')

    # (6) scaling
    sizes = SIZES[:4] if args.quick else SIZES
    rows, exponent, exponent_ransac = scaling(big, 2 if args.quick else 3, sizes)
    print(f'\n## (6) detection + indices vs number of points (resampled from {big.name})\n')
    print('| points | ms |\n| ---: | ---: |')
    for n, summary in rows:
        print(f'| {n} | {ms(summary)} |')
    print(f'\nfitted exponent: {exponent:.2f} (RANSAC alone {exponent_ransac:.2f})')

    node_rows = []
    if not args.skip_node:
        from pvbench.node_e2e import NodeBench
        bench = NodeBench(big.points, big.height, big.width, TOLERANCE, PLANES)
        try:
            print(f'\n## (4) node end to end over DDS ({big.name}, sensor-data QoS, '
                  f'{Path(os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"]).name})\n')
            print('| input rate (Hz) | frames sent | answered | dropped (node count) | latency ms | '
                  'processing ms (node) |')
            print('| ---: | ---: | ---: | ---: | ---: | ---: |')
            frames_per_run = 50 if args.quick else 100
            max_rate = 0.0
            for rate in (5, 10, 15, 20, 25, 30):
                run = bench.run(rate, frames_per_run)
                node_rows.append(run)
                if run.answered == run.sent and run.dropped == 0:
                    max_rate = max(max_rate, rate)
                print(f'| {rate} | {run.sent} | {run.answered} | {run.dropped} | '
                      f'{ms(Summary.of(run.latencies_ms))} | {ms(Summary.of(run.processing_ms))} |')
            retune = bench.run(10, frames_per_run, params=('auto_tune:=true', 'retune_period:=1.0'))
            print(f'\nhighest rate without drops: {max_rate:g} Hz. At 10 Hz with auto-tuning and a retune every '
                  f'second (background sweeps): answered {retune.answered} of {retune.sent}, dropped '
                  f'{retune.dropped}, latency {ms(Summary.of(retune.latencies_ms[5:]))} ms after the first '
                  'five frames (the first frame is tuned inline).')
            memory_rate = 10
            mem = bench.run(memory_rate, args.rss_frames, rss_every=100)
            first, last = mem.rss_mb[0][1], mem.rss_mb[-1][1]
            print(f'\n## (5) node memory over {mem.sent} frames at {memory_rate} Hz\n')
            print('RSS (MB) every 100 frames: ' + ', '.join(f'{rss:.0f}' for _, rss in mem.rss_mb))
            print(f'peak RSS (VmHWM) {mem.peak_mb:.0f} MB; growth from frame 100 to {mem.rss_mb[-1][0]}: '
                  f'{last - first:+.1f} MB; answered {mem.answered}, dropped {mem.dropped}')
            node_rows.append(('memory', mem))
        finally:
            bench.close()

    # targets
    print('\n## Targets\n')
    kinect = [(f, o, r) for f, o, r in results if f.height * f.width == 307_200]
    checks = []
    for frame, ours, ref in kinect:
        checks.append((f'{frame.name}: steady-state ≤ 50 ms', f'{ours["total"].median:.1f} ms',
                       ours['total'].median <= 50))
        if ref:
            checks.append((f'{frame.name}: ≤ 0.5 × Open3D', f'{ours["total"].median / ref["time"].median:.2f}',
                           ours['total'].median <= 0.5 * ref['time'].median))
    checks.append((f'sweep ≤ 1 s ({big.name})', f'{sweep_ms.median:.0f} ms', sweep_ms.median <= 1000))
    checks.append(('time exponent ≤ 1.1', f'{exponent:.2f}', exponent <= 1.1))
    for name, angle in angles:
        checks.append((f'{name}: dominant plane within 1° of Open3D\'s', f'{angle:.3f}°', angle <= 1.0))
    for name, f1_ours, f1_ref in f1_pairs:
        checks.append((f'{name}: F1 ≥ Open3D\'s', f'{f1_ours:.3f} vs {f1_ref:.3f}', f1_ours >= f1_ref))
    for item in node_rows:
        if isinstance(item, tuple):
            mem = item[1]
            checks.append(('node peak RSS ≤ 400 MB', f'{mem.peak_mb:.0f} MB', mem.peak_mb <= 400))
            growth = mem.rss_mb[-1][1] - mem.rss_mb[0][1]
            checks.append(('no RSS growth over the run (≤ 10 MB)', f'{growth:+.1f} MB', growth <= 10))
        elif item.rate == 10:
            lat = Summary.of(item.latencies_ms).median
            checks.append(('10 Hz: median latency ≤ 100 ms, no drops', f'{lat:.0f} ms, {item.dropped} dropped',
                           lat <= 100 and item.dropped == 0 and item.answered == item.sent))
        elif item.rate == 30:
            lat = Summary.of(item.latencies_ms).median
            checks.append(('30 Hz: responsive, drops counted', f'{lat:.0f} ms, {item.dropped} dropped',
                           lat <= 200 and item.answered + item.dropped >= 0.9 * item.sent))
    print('| target | measured | |\n| --- | --- | --- |')
    for what, value, ok in checks:
        print(f'| {what} | {value} | {"PASS" if ok else "FAIL"} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
