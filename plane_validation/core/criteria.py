"""The validity indices a tolerance sweep or a plane count is chosen by, and which way each is better.

Pure numpy, no ROS import.
"""
from __future__ import annotations

import numpy as np

__all__ = ['CRITERIA', 'SEPARATION_CRITERIA', 'EXACT_SEPARATION_POINTS', 'DEFAULT_CRITERION', 'best_position',
           'check_criterion', 'resolved_sampled_separation']

#: Index name -> True when larger is better.
CRITERIA = {'gs_planes': True, 'gs': True, 'silhouette': True, 'dunn': True, 'davies_bouldin': False,
            'davies_bouldin_classic': False, 'plane_silhouette': True}
#: Criteria computed from cluster separations (exact on all points unless sampled_separation).
SEPARATION_CRITERIA = ('dunn', 'davies_bouldin', 'davies_bouldin_classic')
#: tune_tolerance computes the chosen planes' Dunn and Davies-Bouldin exactly up to this many points.
EXACT_SEPARATION_POINTS = 50_000
#: The criterion tune_tolerance uses unless told (chosen on benchmarks/quality.py; the paper's is gs_planes).
DEFAULT_CRITERION = 'plane_silhouette'


def best_position(values, criterion: str) -> int:
    """Position of the best of ``values`` (one per candidate) by ``criterion``; NaN counts as the worst."""
    values = np.asarray(values, dtype=float)
    values = np.where(np.isnan(values), -np.inf if CRITERIA[criterion] else np.inf, values)
    return int(np.argmax(values) if CRITERIA[criterion] else np.argmin(values))


def check_criterion(criterion: str) -> None:
    """ValueError unless ``criterion`` is one of CRITERIA."""
    if criterion not in CRITERIA:
        raise ValueError(f'unknown criterion {criterion!r}; choose one of {sorted(CRITERIA)}')


def resolved_sampled_separation(sampled_separation: bool | None, n_valid: int) -> bool:
    """The sampled_separation argument, None resolved: on the index sample beyond EXACT_SEPARATION_POINTS."""
    return n_valid > EXACT_SEPARATION_POINTS if sampled_separation is None else sampled_separation
