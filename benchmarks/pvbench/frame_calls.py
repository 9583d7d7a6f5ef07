"""The steady-state frame's calls on one real frame or lidar scan, for any importable copy of the package.

``frame_calls('plane_validation', ...)`` times the working tree; ``ab_frame.py`` passes a renamed copy of
another revision, so that both run call by call in one process. The settings are benchmarks/suite.py's:
t = 1 cm, up to 5 planes, indices on 2,000 points.
"""
from __future__ import annotations

import importlib
from collections.abc import Callable

import numpy as np

SETTINGS = dict(auto_tune=False, tolerance=0.01, max_planes=5, index_sample_size=2000, min_inliers=0.01)


def frame_calls(package: str, msg, points: np.ndarray, shape: tuple[int, int]
                ) -> dict[str, Callable[[int], object]]:
    """Per name, a call of run ``i`` (its seed) on one frame, with the package ``package``:

    - organized: ``msg`` (an organized PointCloud2) to planes, indices, verdict and the five output messages;
    - plain: the valid rows of ``points`` (N x 3, meters) through ``detect_planes`` with regions;
    - infinite: the paper's infinite planes (``connectivity=False``) through the pipeline;
    - tune: the valid rows through the full ``tune_tolerance`` with its defaults (issue 37's plain tune);
    - organized_tune: the organized rows (``shape``) through it.

    The caller advances ``msg.header.stamp`` between runs (the node's frames have fresh stamps)."""
    top = importlib.import_module(package)
    pipeline = importlib.import_module(f'{package}.app.pipeline')
    frame_messages = importlib.import_module(f'{package}.ros.messages').frame_messages
    valid = points[np.isfinite(points).all(axis=1)]
    organized = pipeline.FramePipeline(pipeline.PipelineConfig(**SETTINGS))
    infinite = pipeline.FramePipeline(pipeline.PipelineConfig(**SETTINGS, connectivity=False))
    return {'organized': lambda i: frame_messages(msg.header, organized.process_cloud(msg), 'pv'),
            'plain': lambda i: top.detect_planes(valid, 0.01, max_planes=5, min_inliers=0.01, seed=i),
            'infinite': lambda i: infinite.process(points, 10**9 * (i + 1), shape=shape),
            'tune': lambda i: top.tune_tolerance(valid, seed=i),
            'organized_tune': lambda i: top.tune_tolerance(points, seed=i, shape=shape)}


def scan_calls(package: str, points: np.ndarray, rings: np.ndarray, configs: dict[str, dict]
               ) -> dict[str, Callable[[int], object]]:
    """Per name of ``configs`` (PipelineConfig arguments), a call of run ``i`` on an unorganized lidar scan ``points``
    (N x 3, meters) with its ``rings`` (N,) through the pipeline, as bench_lidar.py runs it."""
    pipeline = importlib.import_module(f'{package}.app.pipeline')
    pipes = {name: pipeline.FramePipeline(pipeline.PipelineConfig(**kw)) for name, kw in configs.items()}
    return {name: (lambda i, pipe=pipe: pipe.process(points, 10**9 * (i + 1), tune_inline=False, ring=rings))
            for name, pipe in pipes.items()}
