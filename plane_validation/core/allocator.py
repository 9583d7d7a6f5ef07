"""A frame's large arrays from memory the process already holds, not from fresh pages (glibc's malloc).

glibc serves an allocation above its mmap threshold (128 KiB at first; it rises, up to 32 MiB, only as such blocks
are freed) with a new mapping, unmapped again when freed, and hands the free top of its heap back to the kernel
beyond its trim threshold. A 640 x 480 frame's arrays (a few MB each: rows, labels, masks, the output buffers) then
come as new pages every frame, each faulted in and zeroed by the kernel: 4,000-4,900 minor page faults (16-19 MB)
a Kinect frame, a quarter of its CPU time or more. With both thresholds set, freed blocks up to MMAP_THRESHOLD
stay in the heap for the next frame's arrays (benchmarks/README.md, issue 37). Process-wide, like the BLAS limit:
the node, the command line, the batch workers and the parallel sweeps' worker processes set it at start.
"""
from __future__ import annotations

import ctypes
import functools

__all__ = ['MMAP_THRESHOLD', 'TRIM_THRESHOLD', 'reuse_freed_memory']

#: Blocks up to this size come from the heap (bytes): glibc's own upper bound for its moving threshold; only arrays
#: larger than a million-point cloud's float64 rows (24 MB) are mapped apart.
MMAP_THRESHOLD = 32 << 20
#: The heap keeps up to this much free memory at its top (bytes) instead of returning it to the kernel: a frame's
#: arrays freed at its end are there for the next frame. The node's peak memory measured the same
#: (benchmarks/README.md).
TRIM_THRESHOLD = 64 << 20

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # mallopt's parameter numbers (glibc's malloc.h)


@functools.cache
def reuse_freed_memory() -> bool:
    """Set glibc's mmap and trim thresholds (MMAP_THRESHOLD, TRIM_THRESHOLD) for the rest of the process, once.
    True when set; False where the C library has no ``mallopt`` (musl, macOS, Windows): nothing changes there."""
    try:
        mallopt = ctypes.CDLL(None).mallopt  # the C library the interpreter runs on
    except (OSError, AttributeError, TypeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))
