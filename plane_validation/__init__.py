"""plane_validation: self-validating sequential RANSAC plane detection.

Layers (each imports only those before it): ``core`` (numpy/scipy: RANSAC, validity indices,
tuning, the verdict, geometry, synthetic scenes), ``formats`` (PointCloud2 and point files, bags;
no rclpy), ``app`` (the per-frame pipeline, its parameters, diagnostics, reports, plots), ``ros``
(messages, the node, replay) and ``cli``. The public API is the core's::

    import plane_validation as pv
    seg = pv.detect_planes(points, tolerance=0.02, seed=0)
    scores = pv.validity_indices(points, seg.labels)
    tuned = pv.tune_tolerance(points)          # t chosen by the plane silhouette PS, plus the verdict

The names load on first use, so that the command line starts (and stops quietly on Ctrl-C) before
numpy and scipy are imported.
"""
import importlib

#: The public API: each name and the module of ``core`` that defines it.
_API = {'Plane': 'ransac', 'Segmentation': 'ransac', 'detect_planes': 'ransac', 'fit_plane': 'ransac',
        'ValidityIndices': 'indices', 'validity_indices': 'indices', 'TuningResult': 'tuning',
        'PlaneCountResult': 'tuning', 'tune_tolerance': 'tuning', 'select_plane_count': 'tuning'}

__all__ = [*_API, 'scenes']
__version__ = '0.1.0'


def __getattr__(name: str):
    if name == 'scenes':  # also `import plane_validation.scenes` (scenes.py)
        value = importlib.import_module('.core.scenes', __name__)
    elif name in _API:
        value = getattr(importlib.import_module(f'.core.{_API[name]}', __name__), name)
    else:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
