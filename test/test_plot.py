"""PNG figures: the segmented cloud, indices vs t (with the chosen t) and indices vs k, also degenerate."""
from __future__ import annotations

import matplotlib.image
import numpy as np

import plane_validation as pv
from plane_validation import scenes
from plane_validation.app.plot import plot_plane_count, plot_planes, plot_sweep

CORNER = scenes.corner(900, 2.5, seed=5)


def _image(path) -> np.ndarray:
    data = path.read_bytes()
    assert data.startswith(b'\x89PNG\r\n\x1a\n') and 5_000 < len(data) < 200_000
    return matplotlib.image.imread(path)


def test_sweep_and_plane_count_figures(tmp_path):
    sweep = pv.tune_tolerance(CORNER.points, tolerances=np.linspace(0.5, 20, 12), seed=0)
    image = _image(plot_sweep(sweep, tmp_path / 'sweep.png', title='corner', unit='units', true_planes=3))
    assert image.shape[:2] == (576, 800)  # 10 x 7.2 in at 80 dpi
    geometric = pv.tune_tolerance(CORNER.points, seed=0, count=6)  # log t axis
    assert _image(plot_sweep(geometric, tmp_path / 'geo.png')).shape[:2] == (576, 800)
    counts = pv.select_plane_count(CORNER.points, sweep.tolerance, max_planes=5, seed=0)
    assert counts.n_planes == 3
    assert _image(plot_plane_count(counts, tmp_path / 'k.png', true_planes=3)).shape[:2] == (352, 800)
    assert _image(plot_planes(CORNER.points, counts.segmentation.labels, tmp_path / 'cloud.png')).ndim == 3


def test_figures_without_any_plane(tmp_path):
    few = CORNER.points[:50]
    sweep = pv.tune_tolerance(few, tolerances=[1.0, 2.0, 3.0], min_inliers=10_000, seed=0)
    assert all(row.n_planes == 0 for row in sweep.rows)
    _image(plot_sweep(sweep, tmp_path / 'empty_sweep.png'))
    counts = pv.select_plane_count(few, 2.0, min_inliers=10_000, seed=0)
    assert counts.counts == ()
    _image(plot_plane_count(counts, tmp_path / 'empty_k.png'))
