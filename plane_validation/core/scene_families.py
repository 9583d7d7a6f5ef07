"""Randomised scene families with per-point truth, for a benchmark that cannot be overfit.

Each family is a plain function ``(seed) -> Scene``, deterministic per seed: every draw (room size,
furniture poses, sensor pose, noise levels) comes from the seed. Labels are the true plane of each
point, -1 for points on no plane (non-planar clutter, flying pixels at depth jumps, outliers, lost
returns) and for planar patches with fewer points than the family's minimum (too small to count as
a plane). Coplanar pieces of one surface (the stepped side of a stair flight) share one label;
separate surfaces in one infinite plane (two box tops at the same height) have their own.

Two disjoint seed sets split the benchmark: :data:`TUNING_SEEDS` to choose thresholds and rules on,
:data:`HELD_OUT_SEEDS` only to report; :func:`split` lists a split's (family, seed) pairs.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .scenes import Scene, _look_at, _pinhole_rays, _raycast, _Rect

__all__ = ['indoor_depth', 'lidar_scan', 'aerial_roof', 'FAMILIES', 'TUNING_SEEDS', 'HELD_OUT_SEEDS',
           'SCENES_PER_SPLIT', 'QUICK_SCENES_PER_SPLIT', 'SPLITS', 'split']

#: A Kinect-like depth camera: sigma(z) = a + b z^2 (m, z in m), a up to 1 mm, b about 1.5 mm/m^2;
#: the family draws a and b up to 3 times these.
KINECT_A, KINECT_B = 0.001, 0.0015


# -- geometry ----------------------------------------------------------------------------------

def _rot(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _place(rects: list[_Rect], yaw: float, at) -> list[_Rect]:
    """The rectangles turned by ``yaw`` (rad) about z, then moved by ``at`` (3,) m."""
    r, at = _rot(yaw), np.asarray(at, float)
    return [_Rect(tuple(r @ np.asarray(q.origin) + at), tuple(r @ np.asarray(q.u)), tuple(r @ np.asarray(q.v)),
                  q.su, q.sv) for q in rects]


def _box(size, *, bottom: bool = False) -> list[list[_Rect]]:
    """Faces of the box [0, dx] x [0, dy] x [0, dz], one surface each."""
    dx, dy, dz = size
    x, y, z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
    faces = [_Rect((0, 0, 0), z, y, dz, dy), _Rect((dx, 0, 0), y, z, dy, dz), _Rect((0, 0, 0), x, z, dx, dz),
             _Rect((0, dy, 0), z, x, dz, dx), _Rect((0, 0, dz), x, y, dx, dy)]
    if bottom:
        faces.append(_Rect((0, 0, 0), y, x, dy, dx))
    return [[f] for f in faces]


def _stair_flight(steps: int, rise: float, run: float, width: float) -> list[list[_Rect]]:
    """Treads, risers, the two stepped sides (one surface each) and the back of a free-standing flight."""
    x, y, z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
    treads = [[_Rect((k * run, 0, (k + 1) * rise), x, y, run, width)] for k in range(steps)]
    risers = [[_Rect((k * run, 0, k * rise), y, z, width, rise)] for k in range(steps)]
    left = [_Rect((k * run, 0, 0), x, z, run, (k + 1) * rise) for k in range(steps)]
    right = [_Rect((k * run, width, 0), z, x, (k + 1) * rise, run) for k in range(steps)]
    back = [_Rect((steps * run, 0, 0), y, z, width, steps * rise)]
    return treads + risers + [left, right, back]


@dataclass(frozen=True)
class _Ball:
    """Non-planar clutter: a sphere (centre (3,), radius m)."""

    centre: tuple[float, float, float]
    radius: float

    def hit(self, eye: np.ndarray, rays: np.ndarray) -> np.ndarray:
        oc = eye - np.asarray(self.centre)
        b = rays @ oc
        disc = b * b - (oc @ oc - self.radius ** 2)
        with np.errstate(invalid='ignore'):
            t = -b - np.sqrt(disc)
        return np.where((disc >= 0) & (t > 1e-6), t, np.inf)


@dataclass(frozen=True)
class _Post:
    """Non-planar clutter: a vertical cylinder (axis at x, y; radius; from z0 to z1, m), no caps."""

    x: float
    y: float
    radius: float
    z0: float
    z1: float

    def hit(self, eye: np.ndarray, rays: np.ndarray) -> np.ndarray:
        o = eye[:2] - (self.x, self.y)
        d = rays[:, :2]
        a = np.einsum('ij,ij->i', d, d)
        b = d @ o
        disc = b * b - a * (o @ o - self.radius ** 2)
        with np.errstate(invalid='ignore', divide='ignore'):
            t = (-b - np.sqrt(disc)) / a
        z = eye[2] + t * rays[:, 2]
        return np.where((disc >= 0) & (t > 1e-6) & (z >= self.z0) & (z <= self.z1), t, np.inf)


def _cast(surfaces: list[list[_Rect]], clutter: list, eye: np.ndarray,
          rays: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest hit of each unit ray: (range (n,), surface index (n,), -1 for clutter or none,
    |cos| (n,) between ray and surface normal, 1 for clutter)."""
    rects = [r for s in surfaces for r in s]
    owner = np.array([i for i, s in enumerate(surfaces) for _ in s] + [-1], dtype=np.int32)
    dist, which = _raycast(rects, eye, rays)
    surface = owner[which]  # which == -1 picks the trailing -1
    normals = np.array([r.normal for r in rects] + [(0.0, 0.0, 1.0)])
    cos = np.abs(np.einsum('ij,ij->i', rays, normals[which]))
    for c in clutter:
        t = c.hit(eye, rays)
        closer = t < dist
        dist[closer], surface[closer], cos[closer] = t[closer], -1, 1.0
    return dist, surface, cos


def _plane(rect: _Rect, rot: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """(4,) plane a, b, c, d of a world rectangle in the sensor frame (x_world = rot @ x + eye)."""
    n = rect.normal
    return np.append(rot.T @ n, n @ (eye - np.asarray(rect.origin)))


def _drop_small(labels: np.ndarray, planes: np.ndarray, min_points: int) -> tuple[np.ndarray, np.ndarray]:
    """Planes with fewer than ``min_points`` points become -1; the rest renumbered 0.. in order."""
    counts = np.bincount(labels[labels >= 0], minlength=len(planes))
    keep = counts >= min_points
    new = np.full(len(planes) + 1, -1, dtype=np.int32)
    new[:-1][keep] = np.arange(keep.sum())
    return new[labels].astype(np.int32), planes[keep].reshape(-1, 4)


def _check_seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f'seed must be an integer >= 0, got {seed!r}')
    return int(seed)


def _free_spot(rng: np.random.Generator, lo, hi, radius: float, taken: list) -> tuple[float, float] | None:
    """A point in [lo, hi] (2,) at least ``radius`` from the discs in ``taken`` (x, y, r), or None."""
    for _ in range(40):
        p = rng.uniform(lo, hi)
        if all(np.hypot(p[0] - x, p[1] - y) >= radius + r for x, y, r in taken):
            taken.append((p[0], p[1], radius))
            return float(p[0]), float(p[1])
    return None


# -- indoor depth frames -----------------------------------------------------------------------

def _table(rng: np.random.Generator, size, height: float, yaw: float, at, surfaces: list, clutter: list) -> None:
    """A table top slab (its top, underside and edges) on four round legs."""
    (lx, ly), thick = size, rng.uniform(0.025, 0.05)
    z0 = height - thick
    faces = _box((lx, ly, thick), bottom=True)
    surfaces += [_place(f, yaw, (at[0], at[1], z0)) for f in faces]
    r, leg = _rot(yaw), rng.uniform(0.015, 0.035)
    for cx, cy in ((0.06, 0.06), (lx - 0.06, 0.06), (0.06, ly - 0.06), (lx - 0.06, ly - 0.06)):
        p = r @ (cx, cy, 0.0)
        clutter.append(_Post(at[0] + p[0], at[1] + p[1], leg, 0.0, z0))


def indoor_depth(seed: int, *, width: int = 640, height: int = 480, hfov_deg: float = 58.0,
                 noise: tuple[float, float] | None = None, quantum: float | None = None) -> Scene:
    """An organized depth frame (camera frame, meters, NaN rows for lost pixels; shape (height, width))
    of a random furnished room.

    The room is 3.5-8 x 3-6 x 2.4-3.2 m with a 1.6 x 1.0 m table, a smaller table, 1-4 boxes at random
    yaw (one maybe on the large table), a stair flight half the time, and balls, a plant and table legs
    as non-planar clutter (-1). The camera stands 1.2-3.2 m from the large table, 0.5-1.8 m high, looking
    at a random point near it (pitch from the geometry, yaw jitter +-20 deg). Depth noise
    sigma(z) = a + b z^2 with a in [0, 3 mm] and b in [0.5, 4.5] mm/m^2 (up to 3 x a Kinect's), depth
    quantised in steps q z^2 (q 1-3 mm/m^2); lost: 0-5 % random dropouts, grazing rays
    (|cos| < 0.1-0.3), beyond 3.5-6 m (a Kinect's working range); at depth jumps (> 4 % between
    neighbours) a pixel is lost or takes a depth between both sides (a flying pixel, -1). Planes with
    fewer than 0.1 % of the pixels are -1. ``noise`` is sigma at 1 m (a + b).
    noise (a m, b 1/m), quantum (q 1/m, 0: none): these instead of the drawn ones (the rest of the scene as drawn).
    """
    seed = _check_seed(seed)
    if width < 8 or height < 8 or not 20 <= hfov_deg <= 120:
        raise ValueError(f'need width, height >= 8 and 20 <= hfov_deg <= 120, got {width}, {height}, {hfov_deg}')
    rng = np.random.default_rng((seed, 1))
    room = rng.uniform((3.5, 3.0, 2.4), (8.0, 6.0, 3.2))
    surfaces = _box(room, bottom=True)
    clutter: list = []
    taken: list = []
    lo, hi = np.array([0.9, 0.9]), room[:2] - 0.9
    centre = _free_spot(rng, lo, hi, 1.0, taken) or tuple((lo + hi) / 2)
    yaw = rng.uniform(0, np.pi)
    corner = np.array(centre) - _rot(yaw)[:2, :2] @ (0.8, 0.5)
    _table(rng, (1.6, 1.0), rng.uniform(0.7, 0.78), yaw, corner, surfaces, clutter)
    big_top = surfaces[-2][0]  # the slab's top face
    if rng.random() < 0.5:  # a box on the large table
        size = rng.uniform((0.2, 0.2, 0.1), (0.5, 0.4, 0.35))
        at = np.asarray(big_top.origin) + rng.uniform(0.05, 0.9) * np.asarray(big_top.u) * (1.6 - size[0]) \
            + rng.uniform(0.05, 0.9) * np.asarray(big_top.v) * (1.0 - size[1])
        surfaces += [_place(f, yaw, at) for f in _box(size)]
    spot = _free_spot(rng, lo - 0.4, hi + 0.4, 0.6, taken)
    if spot:
        size = rng.uniform((0.6, 0.5), (1.2, 0.8))
        _table(rng, size, rng.uniform(0.45, 0.8), rng.uniform(0, np.pi), spot, surfaces, clutter)
    for _ in range(rng.integers(1, 5)):
        size = rng.uniform((0.25, 0.25, 0.2), (0.9, 0.7, 0.9))
        spot = _free_spot(rng, lo - 0.5, hi + 0.5, float(np.hypot(*size[:2]) / 2), taken)
        if spot:
            surfaces += [_place(f, rng.uniform(0, np.pi), (*spot, 0.0)) for f in _box(size)]
    if rng.random() < 0.5:
        steps, run, w = int(rng.integers(3, 7)), rng.uniform(0.24, 0.32), rng.uniform(0.8, 1.4)
        spot = _free_spot(rng, lo, hi, 0.5 * float(np.hypot(steps * run, w)), taken)
        if spot:
            surfaces += [_place(f, rng.uniform(0, 2 * np.pi), (*spot, 0.0))
                         for f in _stair_flight(steps, rng.uniform(0.15, 0.2), run, w)]
    for _ in range(rng.integers(0, 3)):
        r = rng.uniform(0.1, 0.35)
        spot = _free_spot(rng, lo - 0.5, hi + 0.5, r, taken)
        if spot:
            clutter.append(_Ball((*spot, r), r))
    if rng.random() < 0.5:  # a plant: a cluster of leaves-sized balls on a stem
        spot = _free_spot(rng, lo - 0.5, hi + 0.5, 0.35, taken)
        if spot:
            top = rng.uniform(0.6, 1.4)
            clutter.append(_Post(*spot, 0.02, 0.0, top))
            for _ in range(rng.integers(4, 9)):
                clutter.append(_Ball(tuple(np.array((*spot, top)) + rng.normal(0, 0.15, 3)), rng.uniform(0.06, 0.15)))

    # camera: 1.2-3.2 m from the large table, inside the room, looking near it
    for _ in range(60):
        heading, dist = rng.uniform(0, 2 * np.pi), rng.uniform(1.2, 3.2)
        eye_xy = np.array(centre) + dist * np.array([np.cos(heading), np.sin(heading)])
        if np.all(eye_xy > 0.3) and np.all(eye_xy < room[:2] - 0.3):
            break
    else:
        eye_xy = np.clip(eye_xy, 0.3, room[:2] - 0.3)
    eye = np.array([*eye_xy, rng.uniform(0.5, 1.8)])
    target = np.array([*centre, rng.uniform(0.0, 1.0)])
    target[:2] += _rot(rng.uniform(-0.35, 0.35))[:2, :2] @ (target[:2] - eye[:2]) - (target[:2] - eye[:2])
    rot = _look_at(eye, target)

    rays_cam, rays = _pinhole_rays(width, height, hfov_deg, rot)
    dist, surface, cos = _cast(surfaces, clutter, eye, rays)
    z = dist * (rays @ rot[:, 2])  # optical depth
    a, b = rng.uniform(0.0, 3 * KINECT_A), rng.uniform(0.0005, 3 * KINECT_B)
    q, min_cos, max_range = rng.uniform(0.001, 0.003), rng.uniform(0.1, 0.3), rng.uniform(3.5, 6.0)
    a, b = (a, b) if noise is None else (float(noise[0]), float(noise[1]))
    q = q if quantum is None else float(quantum)
    lost = ~np.isfinite(z) | (cos < min_cos) | (z > max_range) | (rng.random(len(z)) < rng.uniform(0, 0.05))
    labels = np.where(lost, -1, surface)

    # depth jumps: a pixel whose 4-neighbour is more than 4 % nearer or farther is lost or flies
    pad = np.pad(np.where(np.isfinite(z), z, np.nan).reshape(height, width), 1, constant_values=np.nan)
    img = pad[1:-1, 1:-1]
    other = np.full_like(img, np.nan)
    for nb in (pad[:-2, 1:-1], pad[2:, 1:-1], pad[1:-1, :-2], pad[1:-1, 2:]):
        with np.errstate(invalid='ignore'):
            jump = np.abs(nb - img) > 0.04 * img
        other = np.where(jump & np.isnan(other), nb, other)
    other = other.ravel()
    jumpy = np.isfinite(other) & ~lost & (rng.random(len(z)) < 0.7)
    flying = jumpy & (rng.random(len(z)) < 0.5)
    lost |= jumpy & ~flying
    w = rng.uniform(0.2, 0.8, len(z))
    z = np.where(flying, w * z + (1 - w) * np.where(np.isfinite(other), other, 0.0), z)
    labels = np.where(lost | flying, -1, labels)

    z = np.where(lost, 1.0, z)
    z = z + rng.normal(0.0, 1.0, len(z)) * (a + b * z ** 2)
    if q > 0:
        step = q * z ** 2
        z = np.round(z / step) * step
    points = rays_cam * np.where(lost, np.nan, z)[:, None]
    planes = np.array([_plane(s[0], rot, eye) for s in surfaces])
    floor = max(20, int(0.001 * width * height))
    labels, planes = _drop_small(labels.astype(np.int32), planes, floor)
    return Scene(name=f'indoor_depth_{seed}', points=points, labels=labels, planes=planes, noise=a + b,
                 shape=(height, width), min_plane_points=floor)


# -- spinning lidar scans ----------------------------------------------------------------------

def _lidar_street(rng: np.random.Generator, surfaces: list, clutter: list) -> float:
    """Ground, facades both sides at random distances, a cross wall, parked vans, posts and trees."""
    left, right, length = rng.uniform(4, 15), rng.uniform(4, 15), rng.uniform(40, 90)
    x, y, z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
    surfaces += [[_Rect((-length / 2, -right, 0), x, y, length, left + right)],
                 [_Rect((-length / 2, left, 0), z, x, rng.uniform(6, 20), length)],
                 [_Rect((-length / 2, -right, 0), x, z, length, rng.uniform(3, 15))]]
    if rng.random() < 0.6:
        surfaces.append([_Rect((rng.uniform(10, length / 2), -right, 0), y, z, left + right, rng.uniform(1, 4))])
    for _ in range(rng.integers(1, 5)):
        size = rng.uniform((3.5, 1.6, 1.4), (6.0, 2.2, 2.6))
        offset = rng.uniform(1.5, max(2.0, min(left, right) - size[1] - 0.5))
        at = (rng.uniform(-length / 3, length / 3), offset if rng.random() < 0.5 else -offset - size[1], 0.0)
        surfaces += [_place(f, rng.normal(0, 0.1), at) for f in _box(size)]
    for _ in range(rng.integers(0, 6)):
        clutter.append(_Post(rng.uniform(-length / 3, length / 3), rng.choice([-1, 1]) * rng.uniform(2, 4),
                             rng.uniform(0.05, 0.2), 0.0, rng.uniform(2.5, 6.0)))
    for _ in range(rng.integers(0, 4)):
        clutter.append(_Ball((rng.uniform(-length / 3, length / 3), rng.uniform(-right + 1, left - 1),
                              rng.uniform(3, 5)), rng.uniform(1.0, 2.5)))
    return rng.uniform(1.5, 2.2)


def _lidar_room(rng: np.random.Generator, surfaces: list, clutter: list, corridor: bool) -> float:
    """A room (or a long corridor) centred on the sensor, with cabinets, boxes and a table."""
    if corridor:
        dims = np.array([rng.uniform(15, 40), rng.uniform(1.8, 3.5), rng.uniform(2.3, 3.0)])
    else:
        dims = rng.uniform((4, 3, 2.4), (12, 9, 3.5))
    origin = -dims * np.array([rng.uniform(0.3, 0.7), rng.uniform(0.35, 0.65), 0.0])
    surfaces += [_place(f, 0.0, origin) for f in _box(dims, bottom=True)]
    taken: list = [(0.0, 0.0, 0.5)]  # keep the sensor free
    lo, hi = origin[:2] + 0.4, origin[:2] + dims[:2] - 0.4
    for _ in range(rng.integers(1, 4 if corridor else 6)):
        size = rng.uniform((0.4, 0.3, 0.4), (1.6, 0.8 if corridor else 1.2, 2.0))
        spot = _free_spot(rng, lo, hi, float(np.hypot(*size[:2]) / 2), taken)
        if spot:
            yaw = 0.0 if corridor else rng.uniform(0, np.pi)
            surfaces += [_place(f, yaw, (spot[0] - size[0] / 2, spot[1] - size[1] / 2, 0.0)) for f in _box(size)]
    if not corridor and rng.random() < 0.6:
        spot = _free_spot(rng, lo, hi, 1.0, taken)
        if spot:
            _table(rng, (1.6, 1.0), rng.uniform(0.7, 0.78), rng.uniform(0, np.pi), spot, surfaces, clutter)
    return rng.uniform(0.5, 1.5)


#: Lidar layouts: (rings, elevation range in degrees).
_LIDARS = ((16, (-15.0, 15.0)), (32, (-30.0, 10.0)), (64, (-22.5, 22.5)))
LIDAR_KINDS = ('street', 'room', 'corridor')


def lidar_scan(seed: int, *, azimuths: int = 1024, organized: bool = False) -> Scene:
    """A spinning lidar's scan (sensor frame, meters) of a random street, room or corridor.

    Street: ground, facades 4-15 m to each side, a cross wall, 1-4 vans, posts and tree crowns (-1),
    sensor 1.5-2.2 m high. Room: 4-12 x 3-9 x 2.4-3.5 m with boxes and cabinets at random yaw and a
    table with round legs; corridor: 15-40 m long, 1.8-3.5 m wide, with cabinets; sensor 0.5-1.5 m
    high. 16, 32 or 64 rings (elevations +-15, -30..10, +-22.5 deg, jittered by up to 2 deg),
    ``azimuths`` steps per turn, range noise N(0, sigma) with sigma 5-30 mm, 0-3 % dropouts, 40-100 m
    maximum range. Unorganized (the returns only), or with ``organized`` a rings x azimuths image with
    NaN rows. Planes with fewer than 0.2 % of the returns (at least 20) are -1.
    """
    seed = _check_seed(seed)
    if azimuths < 16:
        raise ValueError(f'azimuths must be >= 16, got {azimuths}')
    rng = np.random.default_rng((seed, 2))
    kind = LIDAR_KINDS[int(rng.integers(0, 3))]
    surfaces: list = []
    clutter: list = []
    height = _lidar_street(rng, surfaces, clutter) if kind == 'street' else \
        _lidar_room(rng, surfaces, clutter, corridor=kind == 'corridor')
    rings, (lo, hi) = _LIDARS[int(rng.integers(0, 3))]
    lo, hi = lo + rng.uniform(-2, 2), hi + rng.uniform(-2, 2)
    sigma, max_range = rng.uniform(0.005, 0.03), rng.uniform(40, 100)
    eye = np.array([0.0, 0.0, height])
    el = np.radians(np.linspace(lo, hi, rings))[:, None]
    az = (np.linspace(0, 2 * np.pi, azimuths, endpoint=False) + rng.uniform(0, 2 * np.pi))[None, :]
    rays = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el) * np.ones_like(az)], -1)
    rays = rays.reshape(-1, 3)
    dist, surface, cos = _cast(surfaces, clutter, eye, rays)
    hit = np.isfinite(dist) & (dist <= max_range) & (cos > 0.02) & (rng.random(len(dist)) >= rng.uniform(0, 0.03))
    r = dist[hit] + rng.normal(0.0, sigma, hit.sum())
    points = rays[hit] * r[:, None]
    labels = surface[hit]
    planes = np.array([_plane(s[0], np.eye(3), eye) for s in surfaces])
    floor = max(20, int(0.002 * hit.sum()))
    keep_labels, planes = _drop_small(labels.astype(np.int32), planes, floor)
    beam = np.repeat(np.arange(rings, dtype=np.int32), azimuths)
    if organized:
        image = np.full((len(rays), 3), np.nan)
        image[hit] = points
        full = np.full(len(rays), -1, dtype=np.int32)
        full[hit] = keep_labels
        return Scene(name=f'lidar_scan_{kind}_{seed}', points=image, labels=full, planes=planes, noise=sigma,
                     shape=(rings, azimuths), rings=beam, min_plane_points=floor)
    return Scene(name=f'lidar_scan_{kind}_{seed}', points=points, labels=keep_labels, planes=planes, noise=sigma,
                 rings=beam[hit], min_plane_points=floor)


# -- aerial roofs ------------------------------------------------------------------------------

ROOF_KINDS = ('gable', 'hip', 'shed')


def aerial_roof(seed: int, *, n_points: int = 2048) -> Scene:
    """``n_points`` of a roof seen from above (meters, centred on the points' mean), roof planes only.

    A gable, hip or shed roof on a 6-16 x 5-10 m footprint at a random yaw, with 0.2-0.6 m eaves
    overhang; pitch log-uniform in 2-45 deg (a third of the roofs are 2-6 deg, the shallow gables
    that a large t merges). A gable or hip roof of 20 deg or more has a shed dormer half the time
    (a 1.5-3 m wide patch at a flatter pitch rising out of one slope). Points are uniform over the
    footprint (an airborne lidar's even density), noise N(0, sigma) in z with sigma 1-5 cm, and
    0-5 % clutter (a chimney-sized blob above the roof, -1). No ground or wall points. Planes with
    fewer than 1 % of the points are -1.
    """
    seed = _check_seed(seed)
    if n_points < 100:
        raise ValueError(f'n_points must be >= 100, got {n_points}')
    rng = np.random.default_rng((seed, 3))
    kind = ROOF_KINDS[int(rng.integers(0, 3))]
    length, width = rng.uniform(6, 16), rng.uniform(5, 10)
    length, width = max(length, width), min(length, width)
    over = rng.uniform(0.2, 0.6)
    pitch = np.radians(np.exp(rng.uniform(np.log(2.0), np.log(45.0))))
    sigma = rng.uniform(0.01, 0.05)
    n_clutter = int(round(n_points * rng.uniform(0, 0.05)))
    n_roof = n_points - n_clutter
    # local frame: x along the ridge, y across, eaves at z = 0 on the wall lines +-width/2
    xy = rng.uniform((-length / 2 - over, -width / 2 - over), (length / 2 + over, width / 2 + over), (n_roof, 2))
    s = np.tan(pitch)
    if kind == 'shed':  # one slope rising towards +y; its normal leans towards -y
        faces = [((0.0, 1.0), -width / 2)]
    elif kind == 'gable':
        faces = [((0.0, 1.0), -width / 2), ((0.0, -1.0), -width / 2)]
    else:  # hip: the ends slope too, at the same pitch (a pyramid on a square footprint)
        faces = [((0.0, 1.0), -width / 2), ((0.0, -1.0), -width / 2), ((1.0, 0.0), -length / 2),
                 ((-1.0, 0.0), -length / 2)]
    # face k: z = s * (m . xy - e), m its horizontal uphill direction, e the eave line's offset
    heights = np.stack([s * (xy @ np.asarray(m) - e) for m, e in faces], axis=1)
    label = np.argmin(heights, axis=1)
    z = heights[np.arange(n_roof), label]
    coeffs = [(-s * m[0], -s * m[1], 1.0, s * e) for m, e in faces]  # z - s (m.xy - e) = 0
    if kind != 'shed' and pitch >= np.radians(20) and rng.random() < 0.5:
        dw, dd = rng.uniform(1.5, 3.0), rng.uniform(1.5, min(2.5, width / 2 - 0.3))
        x0 = rng.uniform(-length / 2 + 1.0, length / 2 - 1.0 - dw)
        dpitch = np.tan(np.radians(rng.uniform(5.0, np.degrees(pitch) - 10.0)))
        # on face 0 (rising to +y): a flatter plane that meets the main slope at the dormer's back y1
        y1 = -width / 2 + dd + 0.5
        zb = s * (y1 + width / 2)
        dz = zb + dpitch * (xy[:, 1] - y1)
        inside = (xy[:, 0] >= x0) & (xy[:, 0] <= x0 + dw) & (xy[:, 1] <= y1) & (label == 0) & (dz > z)
        z = np.where(inside, dz, z)
        label = np.where(inside, len(coeffs), label)
        coeffs.append((0.0, -dpitch, 1.0, dpitch * y1 - zb))
    z = z + rng.normal(0.0, sigma, n_roof)
    pts = np.column_stack([xy, z])
    labels = label.astype(np.int32)
    if n_clutter:
        c = pts[rng.integers(0, n_roof)] + (0.0, 0.0, rng.uniform(0.3, 1.0))
        pts = np.vstack([pts, c + rng.normal(0, rng.uniform(0.1, 0.4), (n_clutter, 3))])
        labels = np.concatenate([labels, np.full(n_clutter, -1, np.int32)])
    planes = np.array(coeffs, float)
    planes /= np.linalg.norm(planes[:, :3], axis=1, keepdims=True)
    rot = _rot(rng.uniform(0, 2 * np.pi))
    pts = pts @ rot.T
    centre = pts.mean(axis=0)
    pts -= centre
    planes = np.column_stack([planes[:, :3] @ rot.T, planes[:, 3]])
    planes[:, 3] += planes[:, :3] @ centre
    floor = max(10, int(0.01 * n_points))
    labels, planes = _drop_small(labels, planes, floor)
    return Scene(name=f'aerial_roof_{kind}_{np.degrees(pitch):.0f}deg_{seed}', points=pts, labels=labels,
                 planes=planes, noise=sigma, min_plane_points=floor)


# -- registry and splits -----------------------------------------------------------------------

#: Scene families by name: each ``(seed) -> Scene``.
FAMILIES: dict[str, Callable[[int], Scene]] = {'indoor_depth': indoor_depth, 'lidar_scan': lidar_scan,
                                                'aerial_roof': aerial_roof}
#: Seeds to choose thresholds and rules on, and seeds only to report on; disjoint.
TUNING_SEEDS: tuple[int, ...] = tuple(range(0, 100))
HELD_OUT_SEEDS: tuple[int, ...] = tuple(range(1000, 1100))
SPLITS = {'tuning': TUNING_SEEDS, 'held-out': HELD_OUT_SEEDS}
#: Scenes per family in one split (the first seeds of the split's set), full and --quick.
SCENES_PER_SPLIT = {'indoor_depth': 4, 'lidar_scan': 6, 'aerial_roof': 20}
QUICK_SCENES_PER_SPLIT = {'indoor_depth': 1, 'lidar_scan': 2, 'aerial_roof': 6}


def split(name: str, quick: bool = False) -> list[tuple[str, int]]:
    """The (family, seed) pairs of split ``name`` ('tuning' or 'held-out'), family by family."""
    if name not in SPLITS:
        raise ValueError(f'unknown split {name!r}; choose one of {", ".join(SPLITS)}')
    counts = QUICK_SCENES_PER_SPLIT if quick else SCENES_PER_SPLIT
    return [(family, seed) for family in FAMILIES for seed in SPLITS[name][:counts[family]]]
