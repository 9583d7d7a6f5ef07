"""Results as JSON documents, CSV rows and text tables for the command line (schema in docs/cli.md).

JSON documents hold plain numbers only: numpy scalars become Python numbers and every NaN or
infinity becomes ``null`` (e.g. Davies-Bouldin is inf with fewer than two clusters), so that
``json.dumps(..., allow_nan=False)`` succeeds and any JSON parser reads them.
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..core.criteria import CRITERIA
from ..core.indices import ValidityIndices
from ..core.noise import noise_coefficient
from ..core.plane_count import PlaneCountResult
from ..core.ransac import Segmentation, as_points
from ..core.tuning_result import TuningResult
from .detection import Detection

__all__ = ['jsonable', 'dumps', 'planes_json', 'indices_json', 'detection_document', 'sweep_document',
           'plane_count_document', 'SWEEP_COLUMNS', 'write_sweep_csv', 'format_planes', 'format_indices',
           'plane_count_table']

#: Index fields reported per sweep row / plane count (the ValidityIndices scalars).
INDEX_FIELDS = ('dunn', 'davies_bouldin', 'davies_bouldin_classic', 'silhouette', 'gs', 'gs_planes',
                'plane_silhouette', 'silhouette_se', 'gs_se', 'gs_planes_se')
#: Columns of the sweep CSV, one row per candidate tolerance.
SWEEP_COLUMNS = ('tolerance', 'n_planes', 'assigned_points') + INDEX_FIELDS + \
    ('max_thickness', 'volume_share', 'merged_share', 'misfit_share', 'seconds', 'chosen')


def jsonable(value: Any) -> Any:
    """``value`` with numpy types turned into Python ones and non-finite floats into None."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [jsonable(v) for v in (value.tolist() if isinstance(value, np.ndarray) else value)]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, Path):
        return str(value)
    return value


def dumps(document: dict) -> str:
    """One JSON document (indented); raises if a NaN or infinity slipped through."""
    return json.dumps(jsonable(document), indent=2, allow_nan=False)


def planes_json(seg: Segmentation) -> list[dict]:
    """Per plane: id, coefficients [a, b, c, d] (a x + b y + c z + d = 0, unit normal), inliers, rms (m)."""
    return [{'id': k, 'coefficients': plane.coefficients, 'inliers': len(plane.inliers), 'rms': plane.rms}
            for k, plane in enumerate(seg.planes)]


def indices_json(scores: ValidityIndices) -> dict:
    """Every index with its standard error, the counts, and each plane's mean silhouette S_j."""
    out = scores.as_dict()
    out['sampled'] = bool(out['sampled'])
    out['plane_silhouettes'] = list(scores.plane_silhouettes)
    return out


def _counts(points: np.ndarray, seg: Segmentation) -> dict:
    valid = int(np.isfinite(points).all(axis=1).sum())
    assigned = int((seg.labels >= 0).sum())
    return {'n_points': len(points), 'n_valid': valid, 'unassigned': valid - assigned}


def detection_document(source: str, det: Detection, *, max_planes: int, min_inliers: int | float,
                       output: str | None = None) -> dict:
    """The ``detect --json`` document."""
    seg = det.segmentation
    tuning = None
    if det.tuning is not None:
        tuning = {'criterion': det.tuning.criterion, 'candidates': len(det.tuning.rows),
                  't_min': det.tuning.rows[0].tolerance, 't_max': det.tuning.rows[-1].tolerance,
                  'seed_agreement': det.tuning.seed_agreement}
    return jsonable({
        'file': source, **_counts(det.points, seg),
        'tolerance': det.tolerance, 'tolerance_source': det.tolerance_source, 'seed': det.seed,
        'max_planes': max_planes, 'min_inliers': min_inliers,
        'planes': planes_json(seg), 'stop_reason': seg.reason,
        'indices': indices_json(det.indices),
        **det.verdict.as_dict(), 'noise_estimate': det.noise_estimate,
        **_noise_model(seg, det.points), 'viewpoint': seg.viewpoint, 'tuning': tuning, 'ring_image': det.ring_image,
        'output': output,
        'seconds': det.seconds,
    })


def noise_line(seg: Segmentation, points: np.ndarray) -> str:
    """The noise model in words: 'constant' or 'depth_quadratic (t is t0 up to 1 m; sigma(r) = 0.0015 r^2)'."""
    if seg.noise_model == 'constant':
        return 'noise model constant'
    c = noise_coefficient(as_points(points), seg.labels, seg.coefficients, seg.viewpoint)
    return (f'noise model {seg.noise_model} (t is t0 up to {seg.noise_reference:g} m, growing as range^2 beyond; '
            f'fitted sigma(r) = {c:.3g} r^2)')


def _noise_model(seg: Segmentation, points: np.ndarray) -> dict:
    """noise_model, and with depth_quadratic its reference range and fitted sigma(r) = c r^2 coefficient c."""
    if seg.noise_model == 'constant':
        return {'noise_model': seg.noise_model}
    return {'noise_model': seg.noise_model, 'noise_reference': seg.noise_reference,
            'noise_coefficient': noise_coefficient(points, seg.labels, seg.coefficients, seg.viewpoint)}


def _sweep_row(row, chosen: bool) -> dict:
    out = {'tolerance': row.tolerance, 'n_planes': row.n_planes, 'assigned_points': sum(row.inlier_counts)}
    out.update({name: getattr(row.indices, name) for name in INDEX_FIELDS})
    out.update(max_thickness=row.max_thickness, volume_share=row.volume_share, merged_share=row.merged_share,
               misfit_share=row.misfit_share,
               seconds=row.seconds, chosen=chosen)
    return out


def sweep_document(source: str, points: np.ndarray, result: TuningResult, *, seed: int,
                   ring_image: str | None = None) -> dict:
    """The ``sweep --json`` document: every candidate's indices and the chosen t with its planes."""
    seg = result.segmentation
    return jsonable({
        'file': source, **_counts(points, seg), 'seed': seed, 'criterion': result.criterion,
        'tolerance': result.tolerance, 'chosen': result.best,
        'sweep': [_sweep_row(r, i == result.best) for i, r in enumerate(result.rows)],
        'planes': planes_json(seg), 'indices': indices_json(result.indices),
        **result.verdict.as_dict(), 'seed_agreement': result.seed_agreement,
        'noise_estimate': result.noise_estimate, **_noise_model(seg, points), 'ring_image': ring_image,
        'seconds': result.seconds,
    })


def plane_count_document(source: str, points: np.ndarray, result: PlaneCountResult, *, tolerance: float,
                         tolerance_source: str, seed: int, max_planes: int) -> dict:
    """The ``planes --json`` document: the indices of the first k planes for every k."""
    seg = result.segmentation
    return jsonable({
        'file': source, **_counts(points, seg), 'tolerance': tolerance, 'tolerance_source': tolerance_source,
        'seed': seed, 'max_planes': max_planes, 'criterion': result.criterion,
        'selected': result.n_planes,
        'best_by': {name: result.best_by(name) for name in CRITERIA} if result.counts else {},
        'counts': [{'k': k, **indices_json(x)} for k, x in zip(result.counts, result.indices)],
        'planes': planes_json(seg), **_noise_model(seg, points),
    })


def write_sweep_csv(path: str | Path, result: TuningResult) -> Path:
    """One row per candidate tolerance with :data:`SWEEP_COLUMNS` (empty cell for NaN/inf)."""
    path = Path(path)
    with open(path, 'w', newline='', encoding='utf-8') as out:
        writer = csv.DictWriter(out, fieldnames=SWEEP_COLUMNS)
        writer.writeheader()
        for i, row in enumerate(result.rows):
            values = jsonable(_sweep_row(row, i == result.best))
            values['chosen'] = int(values['chosen'])
            writer.writerow({k: '' if v is None else v for k, v in values.items()})
    return path


def format_planes(seg: Segmentation) -> str:
    """One line per plane: id, coefficients, inliers, rms."""
    lines = [f'{seg.n_planes} plane(s), tolerance {seg.tolerance:.4g} m; stopped: {seg.reason}']
    for k, plane in enumerate(seg.planes):
        a, b, c, d = plane.coefficients
        lines.append(f'  plane {k}: {a:+.4f} x {b:+.4f} y {c:+.4f} z {d:+.4f} = 0   '
                     f'inliers {len(plane.inliers):7d}   rms {plane.rms:.4g} m')
    return '\n'.join(lines)


def format_indices(scores: ValidityIndices) -> str:
    """The indices on two lines, with standard errors where sampled."""
    def se(value: float, err: float) -> str:
        return f'{value:.4f}' + (f' ± {err:.4f}' if err > 0 else '')
    return (f'  PS {scores.plane_silhouette:.4f}   '
            f'GSplanes {se(scores.gs_planes, scores.gs_planes_se)}   GS {se(scores.gs, scores.gs_se)}   '
            f'silhouette {se(scores.silhouette, scores.silhouette_se)}\n'
            f'  Dunn {scores.dunn:.4g}   Davies-Bouldin {scores.davies_bouldin:.4g} '
            f'(classic {scores.davies_bouldin_classic:.4g})   planes {scores.n_planes}, clusters {scores.n_clusters}, '
            f'points {scores.n_points}')


def plane_count_table(result: PlaneCountResult) -> str:
    """Indices of the first k planes per row, the smallest S_j, and the k each index picks."""
    lines = [f'{"k":>3} {"inliers":>8} {"dunn":>8} {"DB":>8} {"GS":>7} {"GSpl":>7} {"PS":>7} {"sil":>7} '
             f'{"min S_j":>8}']
    for k, x in zip(result.counts, result.indices):
        inliers = len(result.segmentation.planes[k - 1].inliers)
        low = min(x.plane_silhouettes, default=float('nan'))
        mark = ' <' if k == result.n_planes else ''
        lines.append(f'{k:3d} {inliers:8d} {x.dunn:8.4f} {x.davies_bouldin:8.3g} {x.gs:7.3f} {x.gs_planes:7.3f} '
                     f'{x.plane_silhouette:7.3f} {x.silhouette:7.3f} {low:8.3f}{mark}')
    return '\n'.join(lines)
