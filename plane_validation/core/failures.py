"""The verdict's structured result: why planes are not reliable, as typed failures with their numbers.

:func:`~.verdict.judge` returns a :class:`Verdict`; its sentence (``str(verdict)``) is derived from the
failures and is for people only. Code reads ``verdict.reliable``, ``verdict.kinds`` and each
:class:`Failure`'s numbers. Pure Python, no ROS import.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, replace

__all__ = ['FailureKind', 'Failure', 'Verdict']


class FailureKind(enum.Enum):
    """Why planes are not reliable. Each failure's ``value`` and ``limit`` are, per kind:"""

    NO_PLANES = 'no_planes'                  #: no plane found; ``note`` says why the search stopped
    TOO_FEW_POINTS = 'too_few_points'        #: distinct points of the plane < limit; ``other``: its rows with copies
    CURVED_SLAB = 'curved_slab'              #: thickness ratio > limit; ``other``: share of residual variance curvature
    NO_PLANE_SHAPE = 'no_plane_shape'        #: thickness ratio >= limit (inf or NaN: its points lie on a line)
    CUT_FROM_VOLUME = 'cut_from_volume'      #: points at t..2t per point within t >= limit
    TILTED_PATCHES = 'tilted_patches'        #: share of its patches tilted off it >= limit; ``other``: by degrees
    SURFACES_MERGED = 'surfaces_merged'      #: RMS distance / patches' RMS thickness (lack of fit) >= limit
    RIDGE = 'ridge'                          #: lack of fit >= limit, which two planes meeting at a line bring
    #: down to ``other``: the two sides of a ridge or a fold as one plane
    TENT = 'tent'                            #: lack of fit >= limit, which residuals rising evenly from the edges
    #: of the plane's points bring down to ``other``: the faces of a hip roof as one plane
    TWO_LAYERS = 'two_layers'                #: share of residual variance the step between two layers >= limit;
    #: ``other``: RMS distance / t
    LEFTOVER_PLANE = 'leftover_plane'        #: share of the valid points on the largest plane among the points no
    #: plane covers >= limit; ``other``: share of the valid points in no plane
    LOW_SILHOUETTE = 'low_silhouette'        #: plane silhouette PS < limit (the larger of PS and PS with the planes
    #: clipped to their hulls, where that was measured); ``other``: share of the points in no plane when the search
    #: stopped at max_planes (else None)
    COORDINATE_STEPS = 'coordinate_steps'    #: step of the coordinates along the normal (m) > limit, t (m)
    SEEDS_DISAGREE = 'seeds_disagree'        #: agreement with other RANSAC seeds < limit


@dataclass(frozen=True)
class Failure:
    """One failed test: its ``kind``, the worst ``plane`` (index, or None for a test of all planes), the
    measured ``value`` against its ``limit`` (units per :class:`FailureKind`), a second number ``other`` (None
    when the kind has none) and, for NO_PLANES, the search's ``note``."""

    kind: FailureKind
    value: float
    limit: float
    plane: int | None = None
    other: float | None = None
    note: str = ''

    def __str__(self) -> str:
        return _SENTENCES[self.kind](self)


@dataclass(frozen=True)
class Verdict:
    """Whether planes are reliable (no failure) and every test they fail, largest concern first as judged.
    ``n_planes``: how many planes; ``plane_silhouette``: their PS (NaN when not scored)."""

    reliable: bool
    failures: tuple[Failure, ...]
    n_planes: int
    plane_silhouette: float = math.nan

    def __post_init__(self) -> None:
        if self.reliable == bool(self.failures):
            raise ValueError('a verdict is reliable exactly when no test failed')

    @property
    def kinds(self) -> frozenset[FailureKind]:
        return frozenset(f.kind for f in self.failures)

    def __str__(self) -> str:
        if self.reliable:
            return f'{self.n_planes} plane(s), PS {self.plane_silhouette:.2f}'
        if self.n_planes == 0:
            return '; '.join(str(f) for f in self.failures)
        return f'{self.n_planes} plane(s) but ' + '; '.join(str(f) for f in self.failures)

    def renumbered(self, ids) -> Verdict:
        """The same verdict with each failure's plane index k replaced by ``ids[k]`` (a tracker's plane ids)."""
        return replace(self, failures=tuple(f if f.plane is None else replace(f, plane=int(ids[f.plane]))
                                            for f in self.failures))

    def as_dict(self) -> dict:
        """reliable, the sentence, and each failure's kind name and numbers (None where a kind has no such number)."""
        return {'reliable': self.reliable, 'verdict': str(self),
                'failures': [{'kind': f.kind.value, 'plane': f.plane, 'value': f.value, 'limit': f.limit,
                              'other': f.other} for f in self.failures]}


def _up(value: float) -> str:
    """``value`` to 2 decimals, rounded up: a value just above a limit never prints as the limit."""
    return f'{math.ceil(value * 100) / 100:.2f}'


def _down(value: float) -> str:
    """``value`` to 2 decimals, rounded down: a value just below a limit never prints as the limit."""
    return f'{math.floor(value * 100) / 100:.2f}'


def _few(f: Failure) -> str:
    distinct, rows = int(f.value), int(f.other)
    copies = f' ({rows} with copies)' if distinct < rows else ''
    return (f'plane {f.plane} rests on {distinct}{" distinct" if copies else ""} points{copies} (< {f.limit:g}): '
            'too few to tell a plane from chance')


def _round(f: Failure) -> str:
    why = f'thickness ratio {_down(f.value)} >= {f.limit:g}' if math.isfinite(f.value) else 'its points lie on a line'
    return (f'plane {f.plane} is as thick as it is wide ({why}): a pole, a cable or an edge, whose normal is not '
            'determined')


def _silhouette(f: Failure) -> str:
    capped = '' if f.other is None else (f' (the search stopped at max_planes with {f.other:.0%} of them in no '
                                             'plane, which count against PS: more planes may be there)')
    return f'PS {_down(f.value)} < {f.limit:g}: the points do not sit clearly on their planes{capped}'


_SENTENCES = {
    FailureKind.NO_PLANES: lambda f: f'no plane found ({f.note})',
    FailureKind.TOO_FEW_POINTS: _few,
    FailureKind.CURVED_SLAB: lambda f: (f'plane {f.plane} is a curved slab (thickness ratio {_up(f.value)} > '
                                        f'{f.limit:g}, {f.other:.0%} of its residual variance is curvature)'),
    FailureKind.NO_PLANE_SHAPE: _round,
    FailureKind.CUT_FROM_VOLUME: lambda f: (f'plane {f.plane} is cut out of a volume (the cloud has {_up(f.value)} '
                                            f'points at t..2t from it per point within t, >= {f.limit:g}): clutter or '
                                            'outliers, or t below the noise'),
    FailureKind.TILTED_PATCHES: lambda f: (f'plane {f.plane}\'s local surfaces are tilted from it ({f.value:.0%} of '
                                           f'its patches with a normal, >= {f.limit:.0%}, lie over {f.other:g} '
                                           'degrees off): a slab across steps or several surfaces, not one surface'),
    FailureKind.SURFACES_MERGED: lambda f: (f'plane {f.plane} fits its points {_up(f.value)} times worse than its '
                                            f'patches fit theirs (>= {f.limit:g}): several surfaces found as one, '
                                            'such as the two sides of a shallow ridge'),
    FailureKind.RIDGE: lambda f: (f'plane {f.plane}\'s residuals form a V across a line: it fits its points '
                                  f'{_up(f.value)} times worse than its patches fit theirs (>= {f.limit:g}), two '
                                  f'planes meeting at that line {_down(f.other)} times: the two sides of a ridge or a '
                                  'fold found as one plane'),
    FailureKind.TENT: lambda f: (f'plane {f.plane}\'s residuals form a tent, rising from every edge of its points: it '
                                 f'fits its points {_up(f.value)} times worse than its patches fit theirs (>= '
                                 f'{f.limit:g}), the tent {_down(f.other)} times: the faces of a hip roof found as one '
                                 'plane'),
    FailureKind.TWO_LAYERS: lambda f: (f'plane {f.plane}\'s points lie on two parallel layers near the edges of its '
                                       f'band of +-t ({f.value:.0%} of its residual variance is the step between '
                                       f'them, >= {f.limit:.0%}; RMS distance {_up(f.other)} t): two surfaces '
                                       'found as one'),
    FailureKind.LEFTOVER_PLANE: lambda f: (f'a plane of {_up(100 * f.value)}% of the points lies among the points no '
                                           f'plane covers (>= {100 * f.limit:g}%; {f.other:.0%} of the points are in '
                                           'no plane): a surface the search did not find'),
    FailureKind.LOW_SILHOUETTE: _silhouette,
    FailureKind.COORDINATE_STEPS: lambda f: (f'plane {f.plane}\'s points come in steps of {f.value:.3g} m along its '
                                             f'normal (float32 coordinates), coarser than t = {f.limit:.3g} m: the '
                                             'planes may be those steps (a larger t; far from the origin, subtract '
                                             'an offset such as a local origin before storing coordinates as '
                                             'float32)'),
    FailureKind.SEEDS_DISAGREE: lambda f: (f'other RANSAC seeds find other planes (agreement {_down(f.value)} < '
                                           f'{f.limit:g})'),
}
