"""A frame's diagnostics as typed values: a :class:`Level` and a small :class:`Diagnostic`.

The ROS layer turns a Diagnostic into a ``diagnostic_msgs/DiagnosticStatus`` and back
(:mod:`plane_validation.ros.messages`); nothing else formats or parses them. No ROS import.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass

__all__ = ['Level', 'Diagnostic', 'fmt']


class Level(enum.IntEnum):
    """Severity; the values are ``diagnostic_msgs/DiagnosticStatus`` levels."""

    OK = 0
    WARN = 1
    ERROR = 2


@dataclass(frozen=True)
class Diagnostic:
    """level, a one-line message, and key-values (strings, as on /diagnostics) in a fixed order."""

    level: Level
    message: str
    values: tuple[tuple[str, str], ...] = ()

    def get(self, key: str, default: str | None = None) -> str | None:
        return dict(self.values).get(key, default)

    def number(self, key: str) -> float:
        """A numeric value, NaN when absent or not a number."""
        try:
            return float(self.get(key, 'nan'))
        except ValueError:
            return math.nan

    def with_values(self, *pairs: tuple[str, str]) -> Diagnostic:
        """This diagnostic with ``pairs`` added (an existing key is replaced in place)."""
        new = dict(pairs)
        kept = tuple((k, new.pop(k) if k in new else v) for k, v in self.values)
        return Diagnostic(self.level, self.message, kept + tuple(new.items()))

    def escalated(self, level: Level, note: str) -> Diagnostic:
        """At least ``level``, with ``note`` appended to the message."""
        return Diagnostic(max(self.level, level), f'{self.message}; {note}', self.values)


def fmt(x: float | None) -> str:
    """A diagnostic number: 6 significant digits, 'nan' for None/NaN/inf."""
    return 'nan' if x is None or not math.isfinite(x) else f'{x:.6g}'
