"""PNG pictures of segmented clouds (matplotlib, headless Agg backend)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def plot_planes(points: np.ndarray, labels: np.ndarray, path: str | Path, *, title: str = '',
                max_points: int = 20000, seed: int = 0) -> Path:
    """3-D scatter of (n, 3) points coloured by plane label (grey = unassigned), saved to ``path``."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    from .messages import plane_colors

    path = Path(path)
    if len(points) > max_points:
        keep = np.random.default_rng(seed).choice(len(points), max_points, replace=False)
        points, labels = points[keep], labels[keep]
    n_planes = int(labels.max()) + 1 if len(labels) else 0
    palette = np.vstack([plane_colors(n_planes) / 255.0, [[0.6, 0.6, 0.6]]])
    colors = palette[np.where(labels >= 0, labels, n_planes)]
    fig = plt.figure(figsize=(7, 6), dpi=100)
    ax = fig.add_subplot(projection='3d')
    ax.scatter(points[:, 0], points[:, 1], points[:, 2], c=colors, s=1.5, linewidths=0)
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    ax.set_zlabel('z [m]')
    ax.set_title(f'{title}\n{n_planes} planes (grey: unassigned)')
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def plot_cloud_message(msg, path: str | Path, *, title: str = '') -> Path:
    """Plot a ``segmented`` PointCloud2 (x, y, z, plane_id) as published by the node."""
    from .cloud import structured_array, xyz_array
    return plot_planes(xyz_array(msg), np.asarray(structured_array(msg)['plane_id']), path, title=title)
