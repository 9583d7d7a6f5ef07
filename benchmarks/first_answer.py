"""How soon the node answers with auto-tuning on: a real node process fed 640x480 frames over DDS.

Prints, per run, the latency of the first frame (publish -> its /diagnostics), the frame whose
answer first carries a tuned tolerance, and the median latency of the frames in between.

Run: .venv/bin/python benchmarks/first_answer.py [PCD ...] [--runs 3] [--rate 10] [--tune-jobs 1 0]
"""
from __future__ import annotations

import argparse
import itertools
import os
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pvbench.node_e2e import NodeBench, cloud_message, domain_environment  # noqa: E402

PROFILE = Path(__file__).resolve().parents[1] / 'config' / 'fastdds_large_clouds.xml'
DEFAULT = Path(__file__).resolve().parents[2] / 'shared' / 'data' / 'kinect_frame_142255.pcd'


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('clouds', nargs='*', default=[str(DEFAULT)])
    parser.add_argument('--runs', type=int, default=3)
    parser.add_argument('--rate', type=float, default=10.0)
    parser.add_argument('--frames', type=int, default=30)
    parser.add_argument('--tune-jobs', type=int, nargs='+', default=[1],
                        help='the node\'s tune_jobs; several values alternate run by run')
    args = parser.parse_args()
    domain_environment()
    os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(PROFILE))  # 640x480 clouds need it
    from plane_validation.formats.files import load_points
    for path in args.clouds:
        points = load_points(path)
        msg = cloud_message(points, 480, 640) if len(points) == 480 * 640 else cloud_message(points, 1, len(points))
        bench = NodeBench([msg], tolerance=0.02, planes=10, log_dir=Path(tempfile.mkdtemp()))
        try:
            for run_index, jobs in itertools.product(range(args.runs), args.tune_jobs):
                run = bench.run(args.rate, args.frames, params={'auto_tune': 'true', 'tune_jobs': str(jobs)},
                                name=f'first{run_index}_{jobs}')
                tuned = next((i for i, s in enumerate(run.tolerance_sources) if s.startswith('tuned')), None)
                between = run.latencies_ms[1:tuned] if tuned else []
                print(f'{Path(path).name}, tune_jobs {jobs}: first answer {run.latencies_ms[0]:.0f} ms '
                      f'(processing {run.processing_ms[0]:.0f} ms) '
                      f'({run.tolerance_sources[0]}); tuned from answer {tuned} of {run.answered} '
                      f'({run.dropped} dropped); median latency before that '
                      f'{statistics.median(between) if between else float("nan"):.0f} ms', flush=True)
        finally:
            bench.close()


if __name__ == '__main__':
    main()
