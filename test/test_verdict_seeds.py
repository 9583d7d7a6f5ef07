"""benchmarks/verdict_seeds.py's causes of a missed true plane (miss_cause) on small hand-made labelings."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'benchmarks'))
import quality  # noqa: E402
import verdict_seeds  # noqa: E402


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
    assert verdict_seeds.miss_cause(truth, detected, plane, 10) == cause


def test_missed_planes_lists_only_the_planes_not_matched():
    truth, detected = _labels((0, 0, 100), (1, 1, 40), (1, 2, 40))  # plane 0 found, plane 1 split in two
    cloud = quality.Cloud('t', np.ones((len(truth), 3)), truth, None)
    missed = verdict_seeds.missed_planes(cloud, detected, 10)
    assert [cause for cause, _ in missed] == ['split']
    assert missed[0][1].startswith('true 1 (split): 80 pts')
