"""What a plane search returns (:class:`Plane`, :class:`Segmentation`) and the types its steps pass around.

Coordinates are in meters; a tolerance is an absolute point-to-plane distance in the same unit.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..noise import NOISE_REFERENCE

__all__ = ['Plane', 'Segmentation', 'Allows', 'Tolerance', 'Viewpoint', 'Sampler', 'Keep']


@dataclass(frozen=True, eq=False)
class Plane:
    """One detected plane ``normal · x + offset = 0``.

    normal: (3,) unit vector; offset: meters; inliers: (m,) int64 indices into the input points;
    rms: point-to-plane RMS distance of the inliers, meters.
    """

    normal: np.ndarray
    offset: float
    inliers: np.ndarray
    rms: float

    @property
    def coefficients(self) -> np.ndarray:
        """(4,) array ``(a, b, c, d)`` with ``a x + b y + c z + d = 0``."""
        return np.append(self.normal, self.offset)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Absolute distance of each row of ``points`` (n, 3) to the plane, meters."""
        return np.abs(points @ self.normal + self.offset)


@dataclass(frozen=True, eq=False)
class Segmentation:
    """Result of :func:`detect_planes`.

    labels: (N,) int32, plane index 0..k-1 in extraction order, -1 unassigned or invalid row.
    planes: detected planes in extraction order. tolerance: meters. n_valid: finite rows.
    reason: why extraction stopped (human-readable). noise_model, noise_reference: how the
    tolerance grows with range (:mod:`.noise`; ``tolerance`` is t0, the one up to the reference range).
    viewpoint: (x, y, z) meters, where the sensor is in the cloud's frame. capped: the search stopped
    at ``max_planes`` with at least ``min_inliers`` points left, which may lie on planes it did not look
    for (or be clutter: no further search is made to tell).
    """

    labels: np.ndarray
    planes: tuple[Plane, ...]
    tolerance: float
    n_valid: int
    reason: str
    noise_model: str = 'constant'
    noise_reference: float = NOISE_REFERENCE
    viewpoint: tuple[float, float, float] = (0.0, 0.0, 0.0)
    capped: bool = False
    coefficients: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        coeffs = np.array([p.coefficients for p in self.planes]).reshape(-1, 4)
        object.__setattr__(self, 'coefficients', coeffs)

    @property
    def n_planes(self) -> int:
        return len(self.planes)


#: Draws (count, 3) column indices of triples of nearby points (rows with a -1 are dropped).
Sampler = Callable[[np.random.Generator, int], np.ndarray]


#: Maps (inlier mask (m,), plane normal (3,), support mask (m,), mask (m,) of the points on the side of the plane
#: its normal points to) to (the part of the inliers a plane keeps, the points it takes out of the search: those,
#: or with them its surface's points beyond t).
Keep = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


#: Which of the unit normals (h, 3) a plane may have ((h,) bool; an orientation constraint), or None: any.
Allows = Callable[[np.ndarray], np.ndarray] | None


#: An inlier tolerance in meters: one for every point, or (n,) one per point (a noise model).
Tolerance = float | np.ndarray


#: Where the sensor is in a cloud's frame: (x, y, z) meters, or None for the origin.
Viewpoint = Sequence[float] | np.ndarray | None
