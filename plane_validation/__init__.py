"""plane_validation: self-validating sequential RANSAC plane detection.

The core (this package's top level) is pure numpy/scipy with no ROS import::

    import plane_validation as pv
    seg = pv.detect_planes(points, tolerance=0.02, seed=0)
"""
from .ransac import Plane, Segmentation, detect_planes, fit_plane

__all__ = ['Plane', 'Segmentation', 'detect_planes', 'fit_plane']
__version__ = '0.1.0'
