"""An orientation constraint on the planes a search may find, as PCL's constrained plane models have it.

``parallel``: the plane's normal within ``angle`` of the axis (horizontal planes for a vertical axis: floors,
tables); ``perpendicular``: the normal within ``angle`` of perpendicular to it (vertical planes: walls). The
search applies it to every hypothesis and every refit, so a plane it returns always satisfies it.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

__all__ = ['AxisMode', 'Orientation', 'orientation']


class AxisMode(str, enum.Enum):
    NONE = 'none'
    PARALLEL = 'parallel'
    PERPENDICULAR = 'perpendicular'


#: The choices of the axis_mode parameter, in order.
AXIS_MODES = tuple(mode.value for mode in AxisMode)


@dataclass(frozen=True)
class Orientation:
    """axis: (3,) unit vector in the cloud's frame; angle: degrees in [0, 90]; mode: parallel or perpendicular."""

    axis: tuple[float, float, float]
    angle: float
    mode: AxisMode

    def allows(self, normals: np.ndarray) -> np.ndarray:
        """(h,) bool: which unit ``normals`` (h, 3) satisfy the constraint (a normal's sign does not matter)."""
        cos = np.abs(np.asarray(normals, dtype=np.float64).reshape(-1, 3) @ np.asarray(self.axis))
        if self.mode is AxisMode.PARALLEL:
            return cos >= np.cos(np.radians(self.angle))
        return cos <= np.sin(np.radians(self.angle))

    def allows_one(self, normal: np.ndarray) -> bool:
        return bool(self.allows(normal)[0])


def orientation(axis, angle: float, mode: str | AxisMode) -> Orientation | None:
    """The constraint of ``axis`` (3 numbers, any length but 0), ``angle`` (degrees, 0 to 90) and ``mode``
    ('none', 'parallel' or 'perpendicular'); None when ``mode`` is 'none' (the axis is then not looked at).
    ValueError names the first value that is not allowed."""
    try:
        mode = AxisMode(mode)
    except ValueError:
        raise ValueError(f'axis_mode must be one of {", ".join(AXIS_MODES)}, got {mode!r}') from None
    if mode is AxisMode.NONE:
        return None
    try:
        vector = np.asarray(axis, dtype=np.float64)
        angle = float(angle)
    except (TypeError, ValueError):
        raise ValueError(f'normal_axis must be 3 numbers and axis_angle a number, got {axis!r}, {angle!r}') from None
    if vector.shape != (3,) or not np.isfinite(vector).all():
        raise ValueError(f'normal_axis must be 3 finite numbers (x, y, z), got {axis!r}')
    length = float(np.linalg.norm(vector))
    if length == 0:
        raise ValueError(f'normal_axis is (0, 0, 0), which has no direction: set it before axis_mode {mode.value}')
    if not 0 <= angle <= 90:  # also NaN
        raise ValueError(f'axis_angle must be in [0, 90] degrees, got {angle!r}')
    return Orientation(tuple(float(v) for v in vector / length), angle, mode)
