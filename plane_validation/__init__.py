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
        'ValidityIndices': 'indices', 'validity_indices': 'indices', 'TuningResult': 'tuning_result',
        'PlaneCountResult': 'plane_count', 'tune_tolerance': 'tuning', 'select_plane_count': 'plane_count',
        'Verdict': 'failures', 'Failure': 'failures', 'FailureKind': 'failures'}

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


def _entry_point(module: str, package: str):
    """The ``main`` of ``module`` (relative to ``package``), or None when Ctrl-C stopped loading it:
    a KeyboardInterrupt, or the ImportError an extension module raises when one reaches its
    initialisation (scipy's, for instance)."""
    try:
        return importlib.import_module(module, package).main
    except KeyboardInterrupt:
        return None
    except ImportError as exc:
        if _interrupted(exc):
            return None
        raise


def _interrupted(exc: BaseException | None, depth: int = 8) -> bool:
    """Whether ``exc`` or an exception it was raised from (numpy re-raises its own) is a KeyboardInterrupt."""
    if exc is None or depth == 0:
        return False
    return isinstance(exc, KeyboardInterrupt) or _interrupted(exc.__cause__, depth - 1) or \
        _interrupted(exc.__context__, depth - 1)
