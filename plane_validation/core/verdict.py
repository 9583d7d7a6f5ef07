"""The reliability verdict: are the detected planes trustworthy? Its thresholds live here only.

Pure numpy (no ROS import). :func:`judge` is used by the tuner, the pipeline and the CLI.
"""
from __future__ import annotations

import numpy as np

from .indices import ValidityIndices
from .ransac import Segmentation, as_points

__all__ = ['judge', 'plane_thickness', 'RELIABLE_PS', 'RELIABLE_GS_PLANES', 'MAX_THICKNESS', 'SINGLE_PLANE_THICKNESS']

#: Below this plane silhouette (PS, core/plane_silhouette.py) the planes are not reported as
#: reliable. Calibrated on benchmarks/quality.py and the Kinect frames (benchmarks/README.md): good
#: segmentations of real and synthetic scenes score 0.73-0.97, plane-free clouds (spheres, a uniform
#: cube, the bunny) 0.45-0.71 at their tuned t.
RELIABLE_PS = 0.7

#: A multi-plane candidate whose GSplanes stays below this does not beat a lone thin plane when t
#: is chosen by a silhouette of the paper (core/tuning.py): on plane-free clouds the paper finds GS
#: and GSplanes close to 0 (ours: up to 0.10 on noisy spheres).
RELIABLE_GS_PLANES = 0.15
#: Largest RMS-thickness / in-plane-spread ratio of a plane called reliable (see plane_thickness).
MAX_THICKNESS = 0.2
#: ... unless the thicker planes hold less than this share of the planes' points (a few stray
#: points found as a small plane do not make a good segmentation unreliable).
THICK_SHARE = 0.1
#: A lone plane this thin (see plane_thickness) is a plane; a thicker one may be a slab cut
#: through stairs or a curved surface (a noisy 2 m floor with e = 1 cm is 0.01, a stair slope 0.14).
SINGLE_PLANE_THICKNESS = 0.05
#: plane_thickness looks at a fixed random subset of this many inliers of a larger plane.
THICKNESS_POINTS = 4096


def plane_thickness(points: np.ndarray, seg: Segmentation) -> np.ndarray:
    """Per plane sqrt(l0 / l1) of its inlier scatter (smallest over middle eigenvalue): RMS
    thickness over in-plane spread, 0 for a perfect plane, ~0.15 for the paper's corner at e = 7.5,
    ~0.3 for a slab cut out of a sphere."""
    out = []
    for plane in seg.planes:
        rows = plane.inliers
        if len(rows) > THICKNESS_POINTS:  # a fixed random subset: the ratio is a robust statistic
            rows = rows[np.random.default_rng(len(rows)).integers(0, len(rows), THICKNESS_POINTS)]
        inl = points[rows]
        if len(inl) < 3:
            out.append(np.inf)
            continue
        centered = inl - inl.mean(axis=0)
        ev = np.linalg.eigvalsh(centered.T @ centered)
        out.append(float(np.sqrt(max(ev[0], 0.0) / ev[1])) if ev[1] > 0 else np.inf)
    return np.array(out)


def judge(points: np.ndarray, seg: Segmentation, scores: ValidityIndices) -> tuple[bool, str]:
    """Whether the planes of ``seg`` are reliable, with a one-line reason.

    Reliable needs at least one plane, the planes flat (those with a thickness ratio above
    MAX_THICKNESS, see :func:`plane_thickness`, hold less than THICK_SHARE of their points) and a
    plane silhouette PS >= RELIABLE_PS: the points lie on their
    planes and clear of the other regions. On plane-free clouds (sphere, bunny) the "planes" are
    thick slabs or patches whose points lie near their neighbours' planes.
    """
    if seg.n_planes == 0:
        return False, f'no plane found ({seg.reason})'
    thickness = plane_thickness(as_points(points), seg)
    sizes = np.array([len(p.inliers) for p in seg.planes], dtype=float)
    thick = thickness > MAX_THICKNESS
    if sizes[thick].sum() >= THICK_SHARE * sizes.sum():
        worst = int(np.argmax(np.where(thick, sizes, -1)))
        return False, f'plane {worst} is a thick slab (thickness ratio {thickness[worst]:.2f} > {MAX_THICKNESS})'
    if scores.plane_silhouette < RELIABLE_PS:
        return False, (f'{seg.n_planes} plane(s) but PS {scores.plane_silhouette:.2f} < {RELIABLE_PS}: the points '
                       'do not sit clearly on their planes')
    return True, f'{seg.n_planes} plane(s), PS {scores.plane_silhouette:.2f}'
