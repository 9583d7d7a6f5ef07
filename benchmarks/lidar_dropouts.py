"""Spinning-lidar scans with returns missing: planes found on the ring image against the neighbourhood graph.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/lidar_dropouts.py

The scenes' lidar (scenes.lidar: a 16-ring street, the 16-ring room of VLP16_ROOM, the 32-ring street; seed 1)
with no return missing, every tenth return missing (the same azimuth on every ring), and a tenth or a third of
them missing at random; detected as ``detect`` does with library defaults (t = 5 cm, min_inliers 2 %), with the
ring numbers (the ring image, as the node does with ``organize_rings``) and without (the graph). Prints one
row per scan and pattern: planes found, correct (Hoover, overlap 0.8) and point F1 against the scene's labels.
"""
from __future__ import annotations

import numpy as np

from plane_validation.app.detection import detect
from plane_validation.core import scenes
from plane_validation.core.blas import limit_blas_threads
from plane_validation.core.scoring import segmentation_quality

SCANS = {'16-ring street': dict(rings=16), '16-ring room': dict(**scenes.VLP16_ROOM), '32-ring street': {}}
#: pattern -> which returns of a scan of n returns (in ring-major order) go missing
PATTERNS = {'none': lambda n: np.zeros(n, bool),
            'every tenth': lambda n: np.arange(n) % 10 == 0,
            'random tenth': lambda n: np.random.default_rng(7).random(n) < 0.1,
            'random third': lambda n: np.random.default_rng(7).random(n) < 0.33}


def main() -> None:
    limit_blas_threads()
    print('| scan | returns missing | ring image | graph |\n|---|---|---|---|')
    for name, kwargs in SCANS.items():
        scan = scenes.lidar(seed=1, **kwargs)
        for pattern, missing in PATTERNS.items():
            keep = ~missing(len(scan.points))
            cells = []
            for ring in (scan.rings[keep], None):
                seg = detect(scan.points[keep], 0.05, ring=ring, seed=0).segmentation
                q = segmentation_quality(seg.labels, scan.labels[keep])
                cells.append(f'{seg.n_planes} planes, {q.correct}/{q.true_planes} correct, F1 {q.f1:.3f}')
            print(f'| {name} | {pattern} | ' + ' | '.join(cells) + ' |', flush=True)


if __name__ == '__main__':
    main()
