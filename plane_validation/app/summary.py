"""One line per replayed frame and one for the whole replay (no ROS import)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .diagnostics import Diagnostic, Level

__all__ = ['FrameSummary', 'ReplaySummary']


@dataclass(frozen=True)
class FrameSummary:
    """One replayed frame: bag timestamp (ns), planes, tolerance (m), GSplanes, level, ms."""

    index: int
    timestamp: int
    n_planes: int
    tolerance: float
    gs_planes: float
    level: Level
    message: str
    ms: float
    searched: bool = True  # False: rejected before the search (malformed, too few valid points)
    plane_ids: tuple[int, ...] = ()  # the planes' track ids (stable from frame to frame), ascending
    tolerance_source: str = ''  # where the tolerance came from (the diagnostics' tolerance_source)

    @classmethod
    def from_diagnostic(cls, index: int, timestamp: int, diag: Diagnostic) -> FrameSummary:
        return cls(index=index, timestamp=timestamp, n_planes=int(diag.number('planes')),
                   tolerance=diag.number('tolerance'), gs_planes=diag.number('gs_planes'), level=diag.level,
                   message=diag.message, ms=diag.number('processing_ms'), searched=diag.get('stop_reason') is not None,
                   plane_ids=tuple(int(i) for i in (diag.get('plane_ids') or '').split()),
                   tolerance_source=diag.get('tolerance_source') or '')

    def line(self) -> str:
        return (f'frame {self.index:4d}  t={self.timestamp / 1e9:.3f}s  planes {self.n_planes:2d}  '
                f'tolerance {self.tolerance:.4g} m  GSplanes {self.gs_planes:6.3f}  {self.ms:7.1f} ms  '
                f'{Level(self.level).name}: {self.message}')


@dataclass
class ReplaySummary:
    bag: Path
    topic: str
    output: Path | None
    frames: list[FrameSummary] = field(default_factory=list)
    dropped: int = 0  # clouds the node dropped (a newer one replaced them while it was busy)
    last_segmented: object | None = None  # the last frame's segmented PointCloud2 (rclpy)
    sent: int = 0  # clouds published to a live node (0: offline, every cloud processed)

    def line(self) -> str:
        if not self.frames:
            return f'{self.bag}: no frames replayed'
        ms = np.array([f.ms for f in self.frames if f.searched])
        rejected = len(self.frames) - len(ms)
        counts = np.bincount([f.n_planes for f in self.frames])
        planes = ', '.join(f'{k} planes x{c}' for k, c in enumerate(counts) if c)
        out = f'; output bag {self.output}' if self.output else ''
        dropped = f', {self.dropped} dropped' if self.dropped else ''
        if self.sent > len(self.frames):  # live: say where the unanswered ones went
            lost = max(self.sent - len(self.frames) - self.dropped, 0)
            dropped = (f' ({self.sent} sent: {self.dropped} dropped by the busy node, {lost} lost before it, '
                       'e.g. in the depth-1 sensor-data queue)')
        return (f'{len(self.frames)} frames from {self.bag} [{self.topic}]{dropped}: {planes}'
                + (f'; {rejected} rejected before the search' if rejected else '')
                + (f'; median {np.median(ms):.1f} ms per searched frame' if len(ms) else '')
                + f'; last tolerance {self.frames[-1].tolerance:.4g} m{out}')
