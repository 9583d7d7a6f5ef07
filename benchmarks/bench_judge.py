"""The indices and the verdict of the steady-state frame alone, on real 640x480 frames.

Per frame, the pipeline (t = 1 cm, up to 5 planes, indices on the 2,000-point sample; bench_frame.py's settings) runs
once; then ``validity_indices`` and ``judge`` are called again on the arguments it gave them, and their CPU medians
are printed (process_time: other work on the machine slows it less than the wall clock), with their sum.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_judge.py [PCD ...] [--repeat 25]
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
from plane_validation.core.blas import limit_blas_threads  # noqa: E402
from plane_validation.core.kernels import warm  # noqa: E402
from plane_validation.formats.files import load_cloud  # noqa: E402

MEASURED = ('validity_indices', 'judge')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('clouds', nargs='*', default=[str(p) for p in sorted(DATA.glob('*.pcd'))])
    parser.add_argument('--repeat', type=int, default=25)
    args = parser.parse_args()
    limit_blas_threads()
    warm()
    calls, originals = {}, {name: getattr(pipeline, name) for name in MEASURED}
    for name, func in originals.items():
        setattr(pipeline, name, _recorded(func, calls, name))
    print('| frame | validity_indices, CPU (ms) | judge (ms) | both (ms) |')
    print('|---|--:|--:|--:|')
    for path in args.clouds:
        points, shape = load_cloud(path)
        if shape != (480, 640):
            continue
        pipeline.FramePipeline(pipeline.PipelineConfig(**SETTINGS)).process_cloud(cloud_message(points, *shape))
        medians = []
        for name in MEASURED:
            func, (call_args, kwargs) = originals[name], calls[name]
            func(*call_args, **kwargs)  # a warm-up
            took = []
            for _ in range(args.repeat):
                start = time.process_time()
                func(*call_args, **kwargs)
                took.append(1e3 * (time.process_time() - start))
            medians.append(statistics.median(took))
        print(f'| {Path(path).stem} | {medians[0]:.1f} | {medians[1]:.1f} | {sum(medians):.1f} |', flush=True)


def _recorded(func, calls: dict, name: str):
    """``func``, keeping the arguments of its last call in ``calls[name]``."""
    def recorded(*args, **kwargs):
        calls[name] = (args, kwargs)
        return func(*args, **kwargs)
    return recorded


if __name__ == '__main__':
    main()
