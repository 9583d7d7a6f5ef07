"""The steady-state frame's work outside the search, the indices and the verdict, on real 640x480 frames.

Per frame (PointCloud2 in -> the five output messages built, t = 1 cm, up to 5 planes, indices on the 2,000-point
sample), the CPU medians of the whole frame, of the frame without ``detect_planes`` (target <= 20 ms), and of what
is left once ``validity_indices`` and ``judge`` are taken out too (reading the message, the tracker, the one pass
over the rows, outlines and messages), with the target of that rest (<= 12 ms); and two parts of that rest: reading
the message into the frame's rows and valid points, and building the five messages (``frame_messages``). Beside it,
what the node builds when nobody subscribes to its two clouds (the planes' markers, poses, coefficients and the
diagnostics) and when only /diagnostics is listened to. CPU time (process_time): other work on the machine slows it
less than the wall clock.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_frame_io.py [PCD ...] [--repeat 15]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_frame import DATA  # noqa: E402
from pvbench.frame_calls import SETTINGS  # noqa: E402
from pvbench.node_e2e import cloud_message  # noqa: E402

from plane_validation.app import pipeline  # noqa: E402
from plane_validation.core.allocator import reuse_freed_memory  # noqa: E402
from plane_validation.core.blas import limit_blas_threads  # noqa: E402
from plane_validation.core.kernels import warm  # noqa: E402
from plane_validation.formats.files import load_cloud  # noqa: E402
from plane_validation.ros.messages import frame_messages  # noqa: E402

REST_MS = 12.0
WITHOUT_SEARCH_MS = 20.0
TAKEN_OUT = ('detect_planes', 'validity_indices', 'judge')
READING = ('xyz_words', 'xyz_array', 'frame_rows')  # the message to the frame's rows and valid points
NO_CLOUDS = ('planes', 'plane_poses', 'plane_coefficients', 'diagnostics')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('clouds', nargs='*', default=[str(p) for p in sorted(DATA.glob('*.pcd'))])
    parser.add_argument('--repeat', type=int, default=15)
    args = parser.parse_args()
    limit_blas_threads()
    reuse_freed_memory()  # as the node: a frame's arrays from the heap (core/allocator.py)
    warm()
    spent = {name: [0.0] for name in TAKEN_OUT + READING}
    for name in TAKEN_OUT + READING:  # CPU time inside each of them, per frame
        setattr(pipeline, name, _timed(getattr(pipeline, name), spent[name]))
    print('| frame | whole frame, CPU (ms) | without search (ms) | without search, indices, verdict (ms) '
          '| reading the message (ms) | frame_messages (ms) | without the clouds (ms) | diagnostics only (ms) |')
    print('|---|--:|--:|--:|--:|--:|--:|--:|')
    for path, msg, frames in organized_frames(args.clouds):
        whole, outside, rest, reading, messages, planes, diagnostics = [], [], [], [], [], [], []
        for i in range(args.repeat + 1):
            msg.header.stamp.sec = i + 1
            for cell in spent.values():
                cell[0] = 0.0
            start = time.process_time()
            result = frames.process_cloud(msg)
            built = time.process_time()
            frame_messages(msg.header, result, 'pv')
            end = time.process_time()
            frame_messages(msg.header, result, 'pv', keys=NO_CLOUDS)
            no_clouds = time.process_time()
            frame_messages(msg.header, result, 'pv', keys=('diagnostics',))
            alone = time.process_time()
            took = end - start
            if i:  # the first is a warm-up
                whole.append(1000 * took)
                outside.append(1000 * (took - spent['detect_planes'][0]))
                rest.append(1000 * (took - sum(spent[name][0] for name in TAKEN_OUT)))
                reading.append(1000 * sum(spent[name][0] for name in READING))
                messages.append(1000 * (end - built))
                planes.append(1000 * (no_clouds - end))
                diagnostics.append(1000 * (alone - no_clouds))
        print(f'| {Path(path).name} | {statistics.median(whole):.1f} | {statistics.median(outside):.1f} | '
              f'{statistics.median(rest):.1f} | {statistics.median(reading):.1f} | {statistics.median(messages):.1f} | '
              f'{statistics.median(planes):.1f} | {statistics.median(diagnostics):.2f} |',
              flush=True)
    print(f'targets: without search <= {WITHOUT_SEARCH_MS:g} ms; without search, indices and verdict <= {REST_MS:g} ms')


def organized_frames(clouds: list[str]):
    """(path, its rclpy PointCloud2, a new FramePipeline with SETTINGS) of each 640 x 480 frame of ``clouds``."""
    for path in clouds:
        points, shape = load_cloud(path)
        if shape == (480, 640):
            yield path, cloud_message(points, *shape), pipeline.FramePipeline(pipeline.PipelineConfig(**SETTINGS))


def _timed(function, spent: list[float]):
    def timed(*args, **kwargs):
        start = time.process_time()
        try:
            return function(*args, **kwargs)
        finally:
            spent[0] += time.process_time() - start
    return timed


if __name__ == '__main__':
    main()
