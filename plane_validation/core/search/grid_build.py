"""How the grid neighbours of an image are built (:class:`.neighbours_grid.GridNeighbours`): depth-jump cuts, the
normals' reach, and on a lidar's image the bridges over missing returns and the wrap of a full turn.

Neighbours on the image grid are 4-connected, except across a depth jump: a gap between two pixels ``JUMP`` times
the gaps beside it on the same image line (and larger than ``JUMP`` typical pixel spacings at that range) separates
surfaces, and the far pixel of such a jump joins no region (its full-resolution neighbours are labelled afterwards
from the regions around them).
"""
from __future__ import annotations

import numpy as np

from .. import kernels
from .neighbours_grid import GridNeighbours

__all__ = ['grid_neighbours', 'grid_neighbours_numpy', 'median', 'JUMP', 'NORMAL_REACH', 'HOLE_BRIDGE',
           'BRIDGE_SLACK', 'LIDAR_BEND']

#: A gap between grid neighbours this many times the gaps next to it along the image line (and
#: this many typical pixel spacings at its range) is a depth jump.
JUMP = 4.0
#: Grid normals from neighbours this many pixels away (smoother than adjacent pixels).
NORMAL_REACH = 3
#: The image's pitch along each axis (see _reach) is measured on every this many-th line.
REACH_SAMPLE = 4
#: A lidar image's normal (its pixels coarser across the rings than along them) is unknown where its pixel lies
#: off the middle of its neighbours by more than this share of their distance: 3 cm range noise near walls
#: swamps a normal over one ring, and such normals cut walls apart (synthetic VLP-16 scans at 3 cm noise: office
#: F1 0.69 and corridor 0.43 without this test, 0.96 and 0.93 with it). A depth camera's normals stay exact: the
#: coherence test needs them at stair nosings (with this test its stairs fell from 12/12 to 9/12).
LIDAR_BEND = 0.05
#: On a lidar's image (pixels coarser across the rings), a run of up to this many pixels without a point
#: (no return) along a row or column does not cut a region whose pixels lie on both sides of it: a lidar misses
#: single returns (a 16-ring scan with one return in ten missing fell apart into pieces below min_inliers: no
#: plane), and a floor seen by one ring is one pixel high. Not on a depth camera's image, whose holes are
#: patches at grazing angles and behind edges: there it changed which t quality.py's depth room was tuned to
#: (8/9 planes correct, F1 0.978, became 6/9, 0.964), and its sub-grid already steps over scattered holes.
HOLE_BRIDGE = 3
#: ... unless the two pixels are farther apart than this many times the run's pixel steps times the gaps
#: beside it (a box front 8 cm before a wall, seen across one missing pixel, stays apart).
BRIDGE_SLACK = 1.5


def _gaps(image_points: np.ndarray, valid: np.ndarray, ranges: np.ndarray, axis: int
          ) -> tuple[np.ndarray, np.ndarray]:
    """3-D distance between pixel neighbours along ``axis`` (NaN where either is invalid) and the
    range of the nearer of the two."""
    a = image_points[:, :-1] if axis == 1 else image_points[:-1]
    b = image_points[:, 1:] if axis == 1 else image_points[1:]
    va = valid[:, :-1] if axis == 1 else valid[:-1]
    vb = valid[:, 1:] if axis == 1 else valid[1:]
    ra = ranges[:, :-1] if axis == 1 else ranges[:-1]
    rb = ranges[:, 1:] if axis == 1 else ranges[1:]
    d = a - b
    with np.errstate(invalid='ignore'):
        gap = np.where(va & vb, np.sqrt(np.einsum('...i,...i->...', d, d)), np.nan)
    return gap, np.minimum(ra, rb)



def _jumps(gap: np.ndarray, reach: np.ndarray, axis: int, typical: float) -> np.ndarray:
    """Edges whose gap is JUMP times the larger of the gaps just before and after them along the
    same image line (a surface seen at a grazing angle has large but steady gaps; a depth jump is
    a lone large one), and more than JUMP typical pixel spacings at their range."""
    pad = np.full((gap.shape[0], 1) if axis == 1 else (1, gap.shape[1]), np.nan)
    before = np.concatenate([pad, gap], axis=axis)[:, :-1] if axis == 1 else np.concatenate([pad, gap])[:-1]
    after = np.concatenate([gap, pad], axis=axis)[:, 1:] if axis == 1 else np.concatenate([gap, pad])[1:]
    local = np.fmax(before, after)
    local = np.where(np.isnan(local), gap, local)
    with np.errstate(invalid='ignore'):
        return (gap > JUMP * np.maximum(local, typical * reach)) & np.isfinite(gap)



def grid_neighbours(image_points: np.ndarray, valid: np.ndarray) -> GridNeighbours:
    """Neighbours of the valid pixels of an (h, w, 3) image of points (meters; the sensor at the
    origin). Points are numbered in row-major order of the valid pixels ``valid`` (h, w). The passes over the
    image are compiled (:func:`.kernels.grid_edges`, :func:`.kernels.grid_usable`, :func:`.kernels.grid_chords`,
    :func:`.kernels.grid_normals`); :func:`grid_neighbours_numpy` is their reference."""
    points = kernels.c_array(image_points, np.float64)
    flags = kernels.c_array(valid, bool)
    ranges, right, right_reach, down, down_reach, angular = kernels.grid_edges(points, flags)
    typical = median(angular) if len(angular) else 0.0  # pixel spacing per meter of range
    usable = kernels.grid_usable(flags, ranges, right, right_reach, down, down_reach, typical, JUMP)
    pitch = [kernels.grid_chords(points, flags, ranges, axis == 1, REACH_SAMPLE) for axis in (1, 0)]
    reach = _reach_of([median(chord) if len(chord) else np.nan for chord in pitch])
    lidar = reach != (NORMAL_REACH, NORMAL_REACH)  # pixels coarser one way: a lidar's rings
    normals = kernels.grid_normals(points, flags, reach[0], reach[1], LIDAR_BEND if lidar else 0.0)
    return _assembled(image_points, valid, ranges, typical, usable, lidar, normals)


def median(values: np.ndarray) -> float:
    """``np.median`` of the (n,) float64 ``values``, n >= 1, the same number from one selection of the upper middle
    value (numpy selects both middle values, several times slower on the tens of thousands of a sub-grid's gaps)."""
    n = len(values)
    part = np.partition(values, n // 2)
    upper = part[n // 2]
    if np.isnan(part[n // 2:]).any():  # NaN sorts last: any NaN lies here
        return np.nan
    if n % 2:
        return float(upper)
    return float(((0.0 + part[:n // 2].max()) + upper) / 2)  # as np.mean sums the two middle values


def grid_neighbours_numpy(image_points: np.ndarray, valid: np.ndarray) -> GridNeighbours:
    """:func:`grid_neighbours` in numpy: the reference its kernels are tested against."""
    with np.errstate(invalid='ignore'):
        ranges = np.sqrt(np.einsum('...i,...i->...', image_points, image_points))  # from the sensor
    right, right_reach = _gaps(image_points, valid, ranges, 1)
    down, down_reach = _gaps(image_points, valid, ranges, 0)
    with np.errstate(invalid='ignore', divide='ignore'):
        angular = np.concatenate([(right / right_reach)[np.isfinite(right)], (down / down_reach)[np.isfinite(down)]])
    typical = float(np.median(angular)) if len(angular) else 0.0  # pixel spacing per meter of range
    jump_r = _jumps(right, right_reach, 1, typical)
    jump_d = _jumps(down, down_reach, 0, typical)
    # the far pixel of a jump joins no region: that cuts the grid there and leaves a thin object
    # in front (a shelf edge a pixel wide) whole
    dist = np.where(valid, ranges, 0.0)
    far_right = dist[:, 1:] > dist[:, :-1]  # the right pixel is the far one
    far_down = dist[1:] > dist[:-1]
    usable = valid.copy()
    usable[:, :-1] &= ~(jump_r & ~far_right)
    usable[:, 1:] &= ~(jump_r & far_right)
    usable[:-1] &= ~(jump_d & ~far_down)
    usable[1:] &= ~(jump_d & far_down)
    reach = _reach(image_points, valid, ranges)
    lidar = reach != (NORMAL_REACH, NORMAL_REACH)
    normals = _grid_normals(image_points, valid, reach, LIDAR_BEND if lidar else None)
    return _assembled(image_points, valid, ranges, typical, usable, lidar, normals)


def _assembled(image_points: np.ndarray, valid: np.ndarray, ranges: np.ndarray, typical: float, usable: np.ndarray,
               lidar: bool, normals: np.ndarray) -> GridNeighbours:
    """The :class:`GridNeighbours` of an image's valid pixels (``valid`` (h, w)) from its ``ranges`` (h, w), typical
    pixel spacing per meter, ``usable`` (h, w) pixels and grid ``normals`` (h, w, 3); ``lidar``: its pixels are
    coarser one way (bridges over missing returns)."""
    h, w = valid.shape
    pixel = np.flatnonzero(valid.reshape(-1))
    node = np.full(h * w, -1, dtype=np.int64)
    node[pixel] = np.arange(len(pixel))
    wraps = _wraps(image_points, valid, ranges, typical)
    return GridNeighbours(n=len(pixel), shape=(h, w), pixel=pixel, node=node, usable=usable.reshape(-1),
                          normals=normals.reshape(-1, 3).take(pixel, axis=0), wraps=wraps,
                          bridges=_bridges(image_points, valid, ranges, typical, wraps) if lidar else None)


def _bridges(image_points: np.ndarray, valid: np.ndarray, ranges: np.ndarray, typical: float, wraps: bool
             ) -> np.ndarray:
    """(b, 3) int64: pixels (flat) on either side of a run of up to HOLE_BRIDGE invalid pixels along a row or
    column, whose distance fits a surface going on under the run (at most BRIDGE_SLACK times the run's pixel
    steps times the larger gap next to either end, or the typical pixel spacing at their range: a depth jump
    hidden by a hole is larger), and 1 where the pair crosses the seam of an image that wraps."""
    h, w = valid.shape
    flat = np.arange(h * w).reshape(h, w)
    out = [np.empty((0, 3), np.int64)]
    for axis in (1, 0):
        pts, ok, rng, idx = ((image_points, valid, ranges, flat) if axis == 1 else
                             (image_points.transpose(1, 0, 2), valid.T, ranges.T, flat.T))
        length, start = ok.shape[1], 0
        if axis == 1 and wraps:  # the row goes on past either end: its last pixel before, its first ones after
            start = 1
            pts, ok, rng, idx = (np.concatenate([x[:, -1:], x, x[:, :HOLE_BRIDGE + 2]], axis=1)
                                 for x in (pts, ok, rng, idx))
        with np.errstate(invalid='ignore'):
            step = np.linalg.norm(pts[:, 1:] - pts[:, :-1], axis=-1)
        step[~(ok[:, 1:] & ok[:, :-1])] = np.nan
        step = np.pad(step, ((0, 0), (1, 1)), constant_values=np.nan)  # step[:, c] ends at pixel c
        cols = ok.shape[1]
        for run in range(1, HOLE_BRIDGE + 1):
            n = min(cols - run - 1, start + length) - start  # runs starting at each pixel of the row itself
            if n <= 0:
                break
            near, far_ok = ok[:, start:start + n], ok[:, start + run + 1:start + run + 1 + n]
            span = near & far_ok
            for k in range(1, run + 1):
                span &= ~ok[:, start + k:start + k + n]
            r, c = np.nonzero(span)
            if not len(r):
                continue
            c = c + start
            far = c + run + 1
            with np.errstate(invalid='ignore'):
                gap = np.linalg.norm(pts[r, c] - pts[r, far], axis=-1)
                local = np.fmax(step[r, c], step[r, far + 1])
                local = np.fmax(local, typical * np.minimum(rng[r, c], rng[r, far]))
                fits = gap <= BRIDGE_SLACK * (run + 1) * local
            out.append(np.column_stack([idx[r, c][fits], idx[r, far][fits], (far - start >= length)[fits]]))
    return np.concatenate(out).astype(np.int64)



def _wraps(image_points: np.ndarray, valid: np.ndarray, ranges: np.ndarray, typical: float) -> bool:
    """Whether the image's last column lies next to its first, as in a spinning lidar's 360-degree scan:
    their gaps, per meter of range, are typically within JUMP typical pixel spacings. A row's end pixels are
    its first and last points within HOLE_BRIDGE + 1 pixels of the ends (the gap then per pixel between them)."""
    w = image_points.shape[1]
    if w < 2 * HOLE_BRIDGE + 3 or typical <= 0:
        return False
    head, tail = valid[:, :HOLE_BRIDGE + 1], valid[:, ::-1][:, :HOLE_BRIDGE + 1]
    rows = np.flatnonzero(head.any(axis=1) & tail.any(axis=1))
    if not len(rows):
        return False
    first, last = np.argmax(head[rows], axis=1), w - 1 - np.argmax(tail[rows], axis=1)
    gap = np.linalg.norm(image_points[rows, first] - image_points[rows, last], axis=1) / (w - last + first)
    with np.errstate(divide='ignore', invalid='ignore'):  # a point at the sensor (range 0): inf, or NaN left out
        ratio = gap / np.minimum(ranges[rows, first], ranges[rows, last])
    ratio = ratio[~np.isnan(ratio)]
    return bool(len(ratio)) and bool(np.median(ratio) <= JUMP * typical)



def _reach(image_points: np.ndarray, valid: np.ndarray, ranges: np.ndarray) -> tuple[int, int]:
    """Pixels (down, across) that grid normals look: NORMAL_REACH along the finer axis of the image, as
    far in angle along the other (a lidar's rings lie 10-15 times farther apart than its returns along a
    ring: 3 rings would reach past a wall that 5 rings cross). The image's pitch along each axis is the
    median angle between neighbouring pixels' rays, whatever the surfaces."""
    pitch = []
    for axis in (1, 0):  # neighbours along every REACH_SAMPLE-th row, then down every REACH_SAMPLE-th column
        every = slice(None, None, REACH_SAMPLE)
        lines = (every, slice(None)) if axis == 1 else (slice(None), every)
        pts, ok, rng = image_points[lines], valid[lines], ranges[lines]
        with np.errstate(invalid='ignore', divide='ignore'):
            rays = pts / rng[..., None]
        a, b = (rays[:, 1:], rays[:, :-1]) if axis == 1 else (rays[1:], rays[:-1])
        both = (ok[:, 1:] & ok[:, :-1]) if axis == 1 else (ok[1:] & ok[:-1])
        chord = np.linalg.norm(a[both] - b[both], axis=-1)
        pitch.append(float(np.median(chord)) if len(chord) else np.nan)
    return _reach_of(pitch)


def _reach_of(pitch: list[float]) -> tuple[int, int]:
    """:func:`_reach` from the image's pitch (across, down): the median angle between neighbouring rays."""
    if not (np.isfinite(pitch).all() and min(pitch) > 0):
        return NORMAL_REACH, NORMAL_REACH
    angle = max(NORMAL_REACH * min(pitch), max(pitch))  # the same angle both ways, at least one coarse pixel
    return max(1, round(angle / pitch[1])), max(1, round(angle / pitch[0]))



def _grid_normals(image_points: np.ndarray, valid: np.ndarray, reach: tuple[int, int] = (NORMAL_REACH, NORMAL_REACH),
                  bend: float | None = None) -> np.ndarray:
    """(h, w, 3) unit normals from the image neighbours ``reach`` (down, across) pixels away (NaN at holes);
    with ``bend``, NaN also where the pixel lies off the middle of its two neighbours along either axis, along
    the normal, by more than ``bend`` times their distance (see LIDAR_BEND)."""
    rv, rh = reach
    pts = np.where(valid[..., None], image_points, np.nan)
    pad = np.pad(pts, ((rv, rv), (rh, rh), (0, 0)), constant_values=np.nan)
    h, w = valid.shape
    right, left = pad[rv:rv + h, 2 * rh:], pad[rv:rv + h, :w]
    down, up = pad[2 * rv:, rh:rh + w], pad[:h, rh:rh + w]
    du, dv = right - left, down - up
    n = np.cross(du, dv)
    with np.errstate(invalid='ignore', divide='ignore'):
        n /= np.sqrt(np.einsum('...i,...i->...', n, n))[..., None]
        if bend is not None:  # the surface through the pixel and its 4 neighbours is not flat along n: noise
            centre = pad[rv:rv + h, rh:rh + w]
            bend_u = np.abs(np.einsum('...i,...i->...', right + left - 2 * centre, n)) / np.linalg.norm(du, axis=-1)
            bend_v = np.abs(np.einsum('...i,...i->...', down + up - 2 * centre, n)) / np.linalg.norm(dv, axis=-1)
            n[(bend_u > bend) | (bend_v > bend)] = np.nan
    return n
