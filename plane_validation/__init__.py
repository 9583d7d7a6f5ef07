"""plane_validation: self-validating sequential RANSAC plane detection.

The core (this package's top level) is pure numpy/scipy with no ROS import::

    import plane_validation as pv
    seg = pv.detect_planes(points, tolerance=0.02, seed=0)
    scores = pv.validity_indices(points, seg.labels)
    tuned = pv.tune_tolerance(points)          # t chosen by GSplanes, plus the noise estimate
"""
from .indices import ValidityIndices, validity_indices
from .ransac import Plane, Segmentation, detect_planes, fit_plane
from .tuning import PlaneCountResult, TuningResult, select_plane_count, tune_tolerance

__all__ = ['Plane', 'Segmentation', 'detect_planes', 'fit_plane', 'ValidityIndices', 'validity_indices',
           'TuningResult', 'PlaneCountResult', 'tune_tolerance', 'select_plane_count']
__version__ = '0.1.0'
