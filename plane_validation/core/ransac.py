"""Sequential RANSAC plane detection (Lipnickas et al. 2014, section 3): the public entry.

The search itself lives in :mod:`.search`, one module per step; this module names what callers use.
"""
from .params import GRID_POINTS, RANSAC_POINTS
from .search.carry import carried, within_planes
from .search.checks import (
    AT_VIEWPOINT,
    MAX_COORDINATE,
    MAX_SPREAD,
    as_points,
    check_flag,
    check_integer,
    check_magnitude,
    check_number,
    check_shape,
    check_viewpoint,
    finite_rows,
    generator,
    min_inliers_number,
    no_returns_as_nan,
    no_returns_note,
    resolve_min_inliers,
)
from .search.detect import detect_planes
from .search.fit import fit_plane
from .search.graph import SearchGraph, search_graph
from .search.grid import grid_image, grid_pixels, grid_step
from .search.types import Allows, Plane, Segmentation, Tolerance, Viewpoint

__all__ = ['Plane', 'Segmentation', 'SearchGraph', 'detect_planes', 'search_graph', 'fit_plane', 'as_points',
           'finite_rows', 'no_returns_as_nan', 'resolve_min_inliers', 'within_planes', 'carried', 'no_returns_note',
           'generator', 'check_integer', 'check_number', 'check_flag', 'check_magnitude', 'check_shape',
           'check_viewpoint', 'min_inliers_number', 'grid_step', 'grid_pixels', 'grid_image', 'Allows', 'Tolerance',
           'Viewpoint', 'AT_VIEWPOINT', 'MAX_COORDINATE', 'MAX_SPREAD', 'RANSAC_POINTS', 'GRID_POINTS']
