"""Why a true plane was not matched (core/scoring.py's miss_cause) on small hand-made labelings."""
import numpy as np
import pytest

from plane_validation.core.scoring import MissCause, miss_cause


def _labels(*runs: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """(truth, detected) (N,) from runs of (true label, detected label, count)."""
    truth = np.concatenate([np.full(n, t) for t, _, n in runs])
    detected = np.concatenate([np.full(n, d) for _, d, n in runs])
    return truth.astype(np.int64), detected.astype(np.int64)


@pytest.mark.parametrize('runs, plane, cause', [
    # fewer points than min_inliers (10): no t finds it
    ([(0, 0, 100), (1, -1, 5)], 1, 'small'),
    # all of it in a plane that holds another true plane as large
    ([(0, 0, 50), (1, 0, 50)], 1, 'merged'),
    # two planes, each mostly its own
    ([(0, 0, 50), (0, 1, 50)], 0, 'split'),
    # most of it in no plane
    ([(0, 0, 30), (0, -1, 70)], 0, 'unassigned'),
    # most of it taken by the plane of a larger surface, the rest in no plane
    ([(0, 0, 100), (1, 0, 14), (1, -1, 6)], 1, 'absorbed'),
    # its own plane holds 70 % of it, the rest in no plane
    ([(0, 0, 70), (0, -1, 30)], 0, 'partial'),
])
def test_miss_cause(runs, plane, cause):
    truth, detected = _labels(*runs)
    assert miss_cause(truth, detected, plane, 10) is MissCause(cause)


def test_miss_cause_needs_a_label_per_point():
    truth, detected = _labels((0, 0, 20))
    with pytest.raises(ValueError, match='19 detected labels for 20 true labels'):
        miss_cause(truth, detected[:-1], 0, 10)
