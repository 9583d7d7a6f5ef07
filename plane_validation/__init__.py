"""plane_validation: self-validating sequential RANSAC plane detection.

Layers (each imports only those before it): ``core`` (numpy/scipy: RANSAC, validity indices,
tuning, the verdict, geometry, synthetic scenes), ``formats`` (PointCloud2 and point files, bags;
no rclpy), ``app`` (the per-frame pipeline, its parameters, diagnostics, reports, plots), ``ros``
(messages, the node, replay) and ``cli``. The public API is the core's::

    import plane_validation as pv
    seg = pv.detect_planes(points, tolerance=0.02, seed=0)
    scores = pv.validity_indices(points, seg.labels)
    tuned = pv.tune_tolerance(points)          # t chosen by the plane silhouette PS, plus the verdict
"""
import sys

from .core import scenes
from .core.indices import ValidityIndices, validity_indices
from .core.ransac import Plane, Segmentation, detect_planes, fit_plane
from .core.tuning import PlaneCountResult, TuningResult, select_plane_count, tune_tolerance

sys.modules[__name__ + '.scenes'] = scenes  # `import plane_validation.scenes` keeps working

__all__ = ['Plane', 'Segmentation', 'detect_planes', 'fit_plane', 'ValidityIndices', 'validity_indices',
           'TuningResult', 'PlaneCountResult', 'tune_tolerance', 'select_plane_count', 'scenes']
__version__ = '0.1.0'
