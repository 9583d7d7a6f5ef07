"""core/allocator.py: a frame's large arrays come from memory the process holds, without page faults."""
from __future__ import annotations

import platform
import resource

import numpy as np
import pytest

from plane_validation.core.allocator import MMAP_THRESHOLD, reuse_freed_memory


def _frame() -> None:
    """Arrays of a 640 x 480 frame's sizes (its rows, labels, output clouds, a mask), freed in another order than
    made."""
    rows, labels = np.ones(7_372_800, np.uint8), np.ones(2_457_600, np.uint8)
    cloud, mask = np.ones(6_144_000, np.uint8), np.ones(300_000, np.uint8)
    del rows, cloud
    obstacles = np.ones(3_686_400, np.uint8)
    assert labels.all() and mask.all() and obstacles.all()


@pytest.mark.skipif(platform.libc_ver()[0] != 'glibc', reason="glibc's mallopt thresholds")
def test_a_frames_arrays_are_allocated_again_without_page_faults():
    # without the thresholds glibc maps the larger blocks anew or trims its heap's top each frame: about 1,400
    # faults a frame here (4,900 on a Kinect frame through the pipeline)
    assert reuse_freed_memory()
    assert 7_372_800 < MMAP_THRESHOLD
    for _ in range(3):  # the heap grows to hold them once
        _frame()
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(10):
        _frame()
    assert resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before < 500


def _faults_of_frames() -> int:
    """Minor page faults of 10 frames' arrays after 3 (in the process that calls it)."""
    for _ in range(3):
        _frame()
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(10):
        _frame()
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before


@pytest.mark.skipif(platform.libc_ver()[0] != 'glibc', reason="glibc's mallopt thresholds")
def test_a_parallel_sweeps_worker_processes_reuse_freed_memory_too():
    from plane_validation.core.workers import parallel_calls, stop_workers
    try:
        with parallel_calls(2) as run:  # this process takes the first call, a worker the last
            faults = dict(run(_faults_of_frames, [(), (), (), ()]))
    finally:
        stop_workers()
    assert max(faults.values()) < 500, faults
