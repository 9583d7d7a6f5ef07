"""``plane-validation batch`` throughput: bags per minute on the local pool with 1 and 2 workers and on a Ray
cluster of this machine (2 CPUs), and Ray's cost per bag against the local pool.

The bags are the bundled ones (bags/), copied ``--copies`` times under other names. Each run replays all of
them into a fresh output folder (nothing skipped), with the default parameters. Ray's cluster is started
once, before its timed run (the use case is an existing cluster; its start-up is printed apart), and this
process is its driver. Run: .venv/bin/python benchmarks/bench_batch.py [--copies 2] [--repeat 2] [--no-ray]
(Ray from the fleet extra: pip install '.[fleet]').
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import tempfile
import time
from pathlib import Path

from plane_validation.app.fleet import Status
from plane_validation.ros.batch import run_batch

BAGS = Path(__file__).resolve().parents[1] / 'bags'


def _bags(folder: Path, copies: int) -> Path:
    names = sorted(p.name for p in BAGS.iterdir() if (p / 'metadata.yaml').is_file())
    for copy in range(copies):
        for name in names:
            shutil.copytree(BAGS / name, folder / f'{name}_{copy}')
    return folder


def _timed(source: Path, out: Path, **where) -> tuple[float, float, int]:
    """(wall seconds, median seconds inside a bag's task, bags) of one batch run."""
    start = time.perf_counter()
    rows = run_batch([source], out, progress=False, echo=None, **where)
    wall = time.perf_counter() - start
    assert all(row.status is Status.OK for row in rows), [row.status_text for row in rows if row.reason]
    return wall, statistics.median(row.seconds for row in rows), len(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--copies', type=int, default=2, help='copies of the bundled bags (8 each)')
    parser.add_argument('--repeat', type=int, default=2, help='runs of each executor; the fastest counts')
    parser.add_argument('--no-ray', action='store_true', help='the local pool only')
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix='pv_bench_batch_') as tmp:
        source = _bags(Path(tmp) / 'bags', args.copies)
        runs: dict[str, dict] = {'local, 1 worker': dict(workers=1), 'local, 2 workers': dict(workers=2)}
        if not args.no_ray:
            import ray
            start = time.perf_counter()
            ray.init(address='local', num_cpus=2, include_dashboard=False, log_to_driver=False)
            started = time.perf_counter() - start
            runs['Ray, 2 CPUs'] = dict(ray='auto')
        times: dict[str, list] = {name: [] for name in runs}
        try:
            for repeat in range(args.repeat):  # interleaved: each executor sees the same machine
                for i, (name, where) in enumerate(runs.items()):
                    times[name].append(_timed(source, Path(tmp) / f'out{repeat}_{i}', **where))
        finally:
            if not args.no_ray:
                ray.shutdown()
        results = {name: min(t) for name, t in times.items()}  # the least disturbed run
    print(f'{next(iter(results.values()))[2]} bags of 5 frames (bags/ x {args.copies}), {os.cpu_count()} CPUs, '
          f'fastest of {args.repeat} runs each, load average {os.getloadavg()[0]:.1f} at the end')
    print('| executor | wall s | bags/min | median s in a bag\'s task |')
    print('|---|---|---|---|')
    for name, (wall, inside, n) in results.items():
        print(f'| {name} | {wall:.1f} | {60 * n / wall:.1f} | {inside:.2f} |')
    if 'Ray, 2 CPUs' in results:
        (local, _, n), (remote, _, _) = results['local, 2 workers'], results['Ray, 2 CPUs']
        print(f'Ray against the local pool, both 2 at a time: {(remote - local) / n * 2:+.2f} s of a worker per bag '
              f'({(remote - local) / n:+.2f} s wall per bag); starting the Ray cluster took {started:.1f} s '
              '(not counted)')


if __name__ == '__main__':
    main()
