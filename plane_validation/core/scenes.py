"""Synthetic point clouds with known planes, for tests, the demo and benchmarks.

Every generator returns a :class:`Scene`. Noise ``noise`` is uniform in [-noise, +noise] along
each surface normal (the paper's ``e``), in the scene's own units before ``scale`` is applied;
``scale`` multiplies all coordinates (and so the noise), e.g. ``scale=0.01`` turns the paper's
100-unit corner into a 1 m corner. Outliers are uniform in the bounding box and labelled -1.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ['Scene', 'corner', 'cube', 'room', 'stairs', 'table', 'sphere', 'boxes', 'SCENES', 'clutter', 'CLUTTER',
           'depth_camera', 'lidar', 'SENSOR_VIEWS', 'LIDAR_VIEWS', 'VLP16_ROOM', 'VLP16_CORRIDOR']


@dataclass(frozen=True, eq=False)
class Scene:
    """points: (N, 3) float64; labels: (N,) int32 true plane index or -1; planes: (k, 4) a, b, c, d;
    shape: (H, W) when the rows are an image (a depth camera's organized cloud, NaN rows for holes);
    rings: (N,) each point's beam, for a lidar scan (as a driver's ``ring`` field); min_plane_points: the fewest
    points a labelled plane holds (a generator labels smaller surfaces -1; None: every surface is labelled)."""

    name: str
    points: np.ndarray
    labels: np.ndarray
    planes: np.ndarray
    noise: float
    shape: tuple[int, int] | None = None
    rings: np.ndarray | None = None
    min_plane_points: int | None = None

    @property
    def n_planes(self) -> int:
        return len(self.planes)


@dataclass(frozen=True)
class _Rect:
    """A planar rectangle: origin + s*u + r*v for s in [0, su], r in [0, sv]; u, v orthonormal."""

    origin: tuple[float, float, float]
    u: tuple[float, float, float]
    v: tuple[float, float, float]
    su: float
    sv: float

    @property
    def area(self) -> float:
        return self.su * self.sv

    @property
    def normal(self) -> np.ndarray:
        n = np.cross(self.u, self.v)
        return n / np.linalg.norm(n)

    def sample(self, n: int, noise: float, rng: np.random.Generator) -> np.ndarray:
        s = rng.uniform(0, self.su, n)[:, None]
        r = rng.uniform(0, self.sv, n)[:, None]
        pts = np.asarray(self.origin) + s * np.asarray(self.u) + r * np.asarray(self.v)
        if noise > 0:
            pts += rng.uniform(-noise, noise, n)[:, None] * self.normal
        return pts


X, Y, Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)


def _split(n: int, weights: np.ndarray) -> np.ndarray:
    """Split n points over parts proportionally to weights (largest remainders)."""
    raw = n * weights / weights.sum()
    counts = np.floor(raw).astype(int)
    counts[np.argsort(counts - raw)[: n - counts.sum()]] += 1
    return counts


def _compose(name: str, rects: list[_Rect], n_points: int, noise: float, outlier_fraction: float,
             scale: float, seed, clutter=None) -> Scene:
    """Sample the rectangles by area, add clutter (label -1) and outliers, apply scale."""
    if not 0 <= outlier_fraction < 1:
        raise ValueError(f'outlier_fraction must be in [0, 1), got {outlier_fraction}')
    if noise < 0 or scale <= 0 or n_points < 0:
        raise ValueError('noise must be >= 0, scale > 0 and n_points >= 0')
    rng = np.random.default_rng(seed)
    n_out = int(round(n_points * outlier_fraction))
    n_clutter = 0 if clutter is None else int(round((n_points - n_out) * clutter[1]))
    counts = _split(n_points - n_out - n_clutter, np.array([r.area for r in rects]))
    parts = [r.sample(c, noise, rng) for r, c in zip(rects, counts)]
    labels = [np.full(c, i, dtype=np.int32) for i, c in enumerate(counts)]
    if n_clutter:
        parts.append(clutter[0](n_clutter, rng))
        labels.append(np.full(n_clutter, -1, dtype=np.int32))
    body = np.concatenate(parts) if parts else np.empty((0, 3))
    if n_out:  # in the box of the sampled points (of the rectangles' corners when none were sampled)
        box = body if len(body) else np.array([np.asarray(r.origin) + a * r.su * np.asarray(r.u) + b * r.sv *
                                               np.asarray(r.v) for r in rects for a in (0, 1) for b in (0, 1)])
        lo, hi = box.min(axis=0), box.max(axis=0)
        parts.append(rng.uniform(lo, hi, size=(n_out, 3)))
        labels.append(np.full(n_out, -1, dtype=np.int32))
    points = np.concatenate(parts) if parts else np.empty((0, 3))
    planes = np.array([np.append(r.normal, -r.normal @ np.asarray(r.origin)) for r in rects]).reshape(-1, 4)
    planes[:, 3] *= scale
    return Scene(name=name, points=points * scale, labels=np.concatenate(labels) if labels else
                 np.empty(0, np.int32), planes=planes, noise=noise * scale)


def corner(n_points: int = 3000, noise: float = 0.0, *, side: float = 100.0, outlier_fraction: float = 0.0,
           scale: float = 1.0, seed=None) -> Scene:
    """The paper's synthetic data: three mutually perpendicular faces of a cube of ``side`` units
    meeting at the origin (planes x=0, y=0, z=0)."""
    rects = [_Rect((0, 0, 0), Y, Z, side, side), _Rect((0, 0, 0), Z, X, side, side),
             _Rect((0, 0, 0), X, Y, side, side)]
    return _compose('corner', rects, n_points, noise, outlier_fraction, scale, seed)


def _box_faces(lo, hi, *, bottom: bool = True) -> list[_Rect]:
    """Faces of the axis-aligned box [lo, hi], normals pointing outwards."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
    faces = [
        _Rect((x0, y0, z0), Z, Y, dz, dy),  # x = x0, normal -x
        _Rect((x1, y0, z0), Y, Z, dy, dz),  # x = x1, normal +x
        _Rect((x0, y0, z0), X, Z, dx, dz),  # y = y0, normal -y
        _Rect((x0, y1, z0), Z, X, dz, dx),  # y = y1, normal +y
        _Rect((x0, y0, z1), X, Y, dx, dy),  # z = z1, normal +z
    ]
    if bottom:
        faces.append(_Rect((x0, y0, z0), Y, X, dy, dx))  # z = z0, normal -z
    return faces


def cube(n_points: int = 6000, noise: float = 0.0, *, side: float = 100.0, outlier_fraction: float = 0.0,
         scale: float = 1.0, seed=None) -> Scene:
    """Surface of the cube [0, side]^3: six faces."""
    return _compose('cube', _box_faces((0, 0, 0), (side, side, side)), n_points, noise, outlier_fraction,
                    scale, seed)


def room(n_points: int = 20000, noise: float = 0.0, *, size=(5.0, 4.0, 2.5), outlier_fraction: float = 0.0,
         scale: float = 1.0, seed=None) -> Scene:
    """Inside of a rectangular room (meters): floor, ceiling and four walls."""
    return _compose('room', _box_faces((0, 0, 0), size), n_points, noise, outlier_fraction, scale, seed)


def stairs(n_points: int = 8000, noise: float = 0.0, *, steps: int = 4, rise: float = 0.17, run: float = 0.28,
           width: float = 1.0, outlier_fraction: float = 0.0, scale: float = 1.0, seed=None) -> Scene:
    """A staircase (meters): ``steps`` treads (horizontal, ``rise`` apart) and ``steps`` risers
    (vertical, ``run`` apart); treads first, then risers."""
    treads = [_Rect((k * run, 0, (k + 1) * rise), X, Y, run, width) for k in range(steps)]
    risers = [_Rect((k * run, 0, k * rise), Y, Z, width, rise) for k in range(steps)]
    return _compose('stairs', treads + risers, n_points, noise, outlier_fraction, scale, seed)


def _legs(centres, radius: float, height: float):
    """Sampler of points on vertical cylinders (table legs): clutter without planes."""
    centres = np.asarray(centres, dtype=float)

    def sample(n: int, rng: np.random.Generator) -> np.ndarray:
        which = rng.integers(0, len(centres), n)
        angle = rng.uniform(0, 2 * np.pi, n)
        z = rng.uniform(0, height, n)
        return np.column_stack([centres[which, 0] + radius * np.cos(angle),
                                centres[which, 1] + radius * np.sin(angle), z])
    return sample


def table(n_points: int = 20000, noise: float = 0.0, *, outlier_fraction: float = 0.0, scale: float = 1.0,
          seed=None) -> Scene:
    """A table (meters) on a floor with two boxes on it: floor, table top, and the top and four
    sides of each box (12 planes); cylindrical legs are non-planar clutter (label -1)."""
    top_z = 0.75
    rects = [_Rect((-0.4, -0.6, 0.0), X, Y, 2.0, 2.0),          # floor
             _Rect((0.0, 0.0, top_z), X, Y, 1.2, 0.8)]           # table top
    rects += _box_faces((0.10, 0.10, top_z), (0.50, 0.40, top_z + 0.25), bottom=False)
    rects += _box_faces((0.70, 0.35, top_z), (1.00, 0.65, top_z + 0.20), bottom=False)
    legs = _legs([(0.05, 0.05), (1.15, 0.05), (0.05, 0.75), (1.15, 0.75)], 0.025, top_z)
    return _compose('table', rects, n_points, noise, outlier_fraction, scale, seed, clutter=(legs, 0.03))


def boxes(n_points: int = 307200, noise: float = 0.005, *, outlier_fraction: float = 0.05, scale: float = 1.0,
          seed=None) -> Scene:
    """Benchmark scene (meters): floor, two walls and the top and front of a crate: 5 planes."""
    rects = [_Rect((0, 0, 0), X, Y, 4.0, 3.0),            # floor z = 0
             _Rect((0, 3.0, 0), Z, X, 2.5, 4.0),          # back wall y = 3
             _Rect((0, 0, 0), Y, Z, 3.0, 2.5),            # side wall x = 0
             _Rect((1.5, 1.0, 0.8), X, Y, 1.0, 0.8),      # crate top z = 0.8
             _Rect((1.5, 1.0, 0.0), Z, X, 0.8, 1.0)]      # crate front y = 1
    return _compose('boxes', rects, n_points, noise, outlier_fraction, scale, seed)


def sphere(n_points: int = 5000, noise: float = 0.0, *, radius: float = 1.0, outlier_fraction: float = 0.0,
           scale: float = 1.0, seed=None) -> Scene:
    """Points on a sphere (meters): no planes at all. Noise is radial."""
    if not 0 <= outlier_fraction < 1:
        raise ValueError(f'outlier_fraction must be in [0, 1), got {outlier_fraction}')
    if noise < 0 or scale <= 0 or n_points < 0 or radius <= 0:
        raise ValueError('noise must be >= 0, scale and radius > 0 and n_points >= 0')
    rng = np.random.default_rng(seed)
    n_out = int(round(n_points * outlier_fraction))
    directions = rng.normal(size=(n_points - n_out, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    r = radius + (rng.uniform(-noise, noise, len(directions)) if noise > 0 else 0.0)
    pts = directions * np.asarray(r).reshape(-1, 1)
    outliers = rng.uniform(-radius, radius, size=(n_out, 3))
    return Scene(name='sphere', points=np.concatenate([pts, outliers]) * scale,
                 labels=np.full(n_points, -1, dtype=np.int32), planes=np.empty((0, 4)), noise=noise * scale)


#: The kinds of :func:`clutter`.
CLUTTER = ('bush', 'outliers', 'sheets')


def clutter(kind: str = 'bush', *, share: float = 0.5, seed=None) -> Scene:
    """Scenes that a large t cuts into false planes (meters, labels -1 for clutter):
    'bush', a 4 m floor (6,000 points, sigma 5 mm) under a 1 m cube of 1,500 random points; 'outliers', a
    2 m plane (3,000 points, sigma 5 mm) with a ``share`` of uniform outliers in a 2 m cube around it;
    'sheets', two 2 m sheets 5 cm apart (3,000 points each, sigma 3 mm)."""
    rng = np.random.default_rng(seed)
    if kind == 'bush':
        floor = np.column_stack([rng.uniform(-2, 2, (6000, 2)), rng.normal(0, 0.005, 6000)])
        points = np.vstack([floor, rng.uniform([0, 0, 0.02], [1, 1, 1], (1500, 3))]) + [0, 0, -1.5]
        labels, planes = np.repeat([0, -1], [6000, 1500]), [[0, 0, 1, 1.5]]
    elif kind == 'outliers':
        if not 0 <= share < 1:
            raise ValueError(f'share must be in [0, 1), got {share}')
        m = int(3000 * share / (1 - share))
        plane = np.column_stack([rng.uniform(-1, 1, (3000, 2)), rng.normal(0, 0.005, 3000)])
        points = np.vstack([plane, rng.uniform(-1, 1, (m, 3))]) + [3, -2, 5]
        labels, planes = np.repeat([0, -1], [3000, m]), [[0, 0, 1, -5]]
    elif kind == 'sheets':
        sheets = [np.column_stack([rng.uniform(-1, 1, (3000, 2)), z + rng.normal(0, 0.003, 3000)]) for z in (0, 0.05)]
        points, labels = np.vstack(sheets) + [0, 0, 2], np.repeat([0, 1], 3000)
        planes = [[0, 0, 1, -2], [0, 0, 1, -2.05]]
    else:
        raise ValueError(f'unknown clutter kind {kind!r}; choose one of {", ".join(CLUTTER)}')
    noise = 0.003 if kind == 'sheets' else 0.005
    return Scene(name=f'clutter_{kind}', points=points, labels=labels.astype(np.int32), planes=np.array(planes, float),
                 noise=noise)


#: Scene generators by name, for the CLI and the bag maker.
SCENES = {'corner': corner, 'cube': cube, 'room': room, 'stairs': stairs, 'table': table, 'sphere': sphere,
          'boxes': boxes}


# -- sensor models -------------------------------------------------------------------------------

def _furnished_room() -> list[_Rect]:
    """A 5 x 4 x 2.5 m room with a cabinet against the back wall and a box on the floor."""
    rects = _box_faces((0, 0, 0), (5.0, 4.0, 2.5))
    rects += _box_faces((1.0, 3.4, 0.0), (2.2, 4.0, 1.0), bottom=False)[:5]   # cabinet, front 0.6 m out
    rects += _box_faces((3.0, 1.5, 0.0), (3.6, 2.1, 0.5), bottom=False)      # a box on the floor
    return rects


def _table_scene() -> list[_Rect]:
    top_z = 0.75
    rects = [_Rect((-1.0, -1.0, 0.0), X, Y, 3.5, 3.0), _Rect((0.0, 0.0, top_z), X, Y, 1.2, 0.8)]
    rects += _box_faces((0.10, 0.10, top_z), (0.50, 0.40, top_z + 0.25), bottom=False)
    rects += _box_faces((0.70, 0.35, top_z), (1.00, 0.65, top_z + 0.20), bottom=False)
    return rects


def _stairs_scene(steps: int = 6, rise: float = 0.17, run: float = 0.28) -> list[_Rect]:
    treads = [_Rect((k * run, 0, (k + 1) * rise), X, Y, run, 1.2) for k in range(steps)]
    risers = [_Rect((k * run, 0, k * rise), Y, Z, 1.2, rise) for k in range(steps)]
    return treads + risers


def _street() -> list[_Rect]:
    """Ground, two facades, a wall and a parked box-shaped van around the origin (meters)."""
    return ([_Rect((-30, -30, 0), X, Y, 60, 60), _Rect((-30, 8, 0), Z, X, 12, 60), _Rect((-30, -8, 0), X, Z, 60, 9),
             _Rect((12, -8, 0), Y, Z, 16, 3)] + _box_faces((3, 2, 0), (8, 4, 2.2), bottom=False))


def _corridor() -> list[_Rect]:
    """A 30 m long, 2.4 m wide and high corridor with a cabinet against one wall."""
    cabinet = _box_faces((18.0, 1.8, 0.0), (19.2, 2.4, 1.2), bottom=False)
    return _box_faces((0, 0, 0), (30.0, 2.4, 2.4)) + cabinet[:3] + cabinet[4:]  # not its back, on the wall


#: Depth-camera views: rectangles, eye and target (meters, z up), and how the scene is named.
SENSOR_VIEWS = {
    'room': (_furnished_room, (4.6, 0.4, 1.5), (1.5, 3.6, 0.7)),
    'table': (_table_scene, (0.6, -1.0, 1.6), (0.6, 0.4, 0.75)),
    'stairs': (_stairs_scene, (-1.2, 0.6, 1.6), (0.8, 0.6, 0.5)),
}


#: Spinning-lidar views: rectangles and where the sensor stands (x, y; meters), as ``lidar`` names them.
LIDAR_VIEWS = {
    'street': (_street, (0.0, 0.0)),
    'room': (_furnished_room, (2.5, 2.0)),
    'corridor': (_corridor, (12.0, 1.2)),
}


#: ``lidar(**VLP16_ROOM)``: a 16-beam lidar (+-15 degrees) 1 m above the floor in the middle of the
#: furnished room, 2 cm range noise; its walls are 1.5-3 m away, where a ring's returns lie closer
#: together than their noise.
VLP16_ROOM = dict(view='room', rings=16, elevation_deg=(-15.0, 15.0), sigma=0.02, height=1.0)
#: ``lidar(**VLP16_CORRIDOR)``: the same lidar 0.8 m above the floor of the corridor; its rings cross
#: the floor 3-9 m apart, farther than the corridor is wide.
VLP16_CORRIDOR = dict(view='corridor', rings=16, elevation_deg=(-15.0, 15.0), sigma=0.02, height=0.8)


def _raycast(rects: list[_Rect], eye: np.ndarray, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hit of each ray (n, 3, unit) from ``eye``: (range (n,), rectangle index (n,), -1 none)."""
    best = np.full(len(rays), np.inf)
    which = np.full(len(rays), -1, dtype=np.int32)
    for j, r in enumerate(rects):
        n, o, u, v = r.normal, np.asarray(r.origin, float), np.asarray(r.u, float), np.asarray(r.v, float)
        with np.errstate(divide='ignore', invalid='ignore', over='ignore'):
            t = ((o - eye) @ n) / (rays @ n)
            hit = eye + t[:, None] * rays - o
            s, q = hit @ u, hit @ v
        ok = (t > 1e-6) & (s >= 0) & (s <= r.su) & (q >= 0) & (q <= r.sv) & (t < best)
        best[ok], which[ok] = t[ok], j
    return best, which


def _look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(3, 3) rotation camera -> world for an optical frame (x right, y down, z forward), z up."""
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    return np.column_stack([right, down, forward])


def _pinhole_rays(width: int, height: int, hfov_deg: float, rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each pixel's ray, rows in image order: (camera frame with z = 1 (H*W, 3), unit, world frame
    (H*W, 3)) for a camera turned by ``rot`` (:func:`_look_at`)."""
    f = width / 2 / np.tan(np.radians(hfov_deg) / 2)
    u, v = np.meshgrid(np.arange(width) + 0.5 - width / 2, np.arange(height) + 0.5 - height / 2)
    rays_cam = np.column_stack([u.ravel() / f, v.ravel() / f, np.ones(width * height)])
    rays = rays_cam @ rot.T
    return rays_cam, rays / np.linalg.norm(rays, axis=1, keepdims=True)


def depth_camera(view: str = 'room', *, width: int = 640, height: int = 480, hfov_deg: float = 58.0,
                 sigma_1m: float = 0.0015, quantum_1m: float = 0.002, min_cos: float = 0.2,
                 max_range: float = 6.0, eye=None, target=None, seed=None) -> Scene:
    """An organized depth-camera frame (camera frame, meters, NaN holes) of a :data:`SENSOR_VIEWS`
    view: depth noise sigma(z) = sigma_1m * z^2 (1.5 mm at 1 m, 6 mm at 2 m), depth quantised in
    steps of quantum_1m * z^2, no return where the ray meets the surface at a grazing angle
    (|cos| < min_cos) or beyond max_range. ``noise`` of the scene is sigma_1m. eye, target: (3,) m in the
    view's frame, where the camera stands and what it looks at (default: the view's; a moving camera)."""
    if view not in SENSOR_VIEWS:
        raise ValueError(f'view must be one of {", ".join(SENSOR_VIEWS)}, got {view!r}')
    if width < 1 or height < 1 or not 0 < hfov_deg < 180 or sigma_1m < 0 or quantum_1m <= 0 or max_range <= 0:
        raise ValueError('need width, height >= 1, 0 < hfov_deg < 180, sigma_1m >= 0, quantum_1m > 0 and '
                         'max_range > 0')
    make, view_eye, view_target = SENSOR_VIEWS[view]
    eye, target = view_eye if eye is None else eye, view_target if target is None else target
    rects = make()
    rng = np.random.default_rng(seed)
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    rot = _look_at(eye, target)
    rays_cam, rays = _pinhole_rays(width, height, hfov_deg, rot)
    rng_, which = _raycast(rects, eye, rays)
    normals = np.array([r.normal for r in rects])
    cos = np.abs(np.einsum('ij,ij->i', rays, normals[np.maximum(which, 0)]))
    z = rng_ * (rays @ rot[:, 2])  # optical depth
    lost = (which < 0) | (cos < min_cos) | ~(z <= max_range)
    z = np.where(lost, 1.0, z)
    z = z + rng.normal(0.0, 1.0, len(z)) * sigma_1m * z ** 2
    step = quantum_1m * z ** 2
    z = np.round(z / step) * step
    points = rays_cam * np.where(lost, np.nan, z)[:, None]
    labels = np.where(lost, -1, which).astype(np.int32)
    planes = np.array([np.append(rot.T @ r.normal, -r.normal @ np.asarray(r.origin) + r.normal @ eye) for r in rects])
    return Scene(name=f'depth_{view}', points=points, labels=labels, planes=planes, noise=sigma_1m,
                 shape=(height, width))


def lidar(view: str = 'street', *, rings: int = 32, azimuths: int = 1800, sigma: float = 0.015,
          height: float = 1.8, elevation_deg: tuple[float, float] = (-30.0, 10.0), max_range: float = 60.0,
          organized: bool = False, seed=None) -> Scene:
    """A spinning lidar's scan (sensor frame, meters) of a :data:`LIDAR_VIEWS` view (a street, the
    depth camera's furnished room from its middle, or a corridor), the sensor ``height`` above the ground: ``rings``
    beams between the elevations, ``azimuths`` steps per turn from azimuth 0 (+x), range noise
    N(0, sigma) along each beam. Unorganized (the returns only), or with ``organized`` a rings x
    azimuths image with NaN rows for beams without a return (as velodyne_pointcloud and ouster-ros
    publish it)."""
    if view not in LIDAR_VIEWS:
        raise ValueError(f'view must be one of {", ".join(LIDAR_VIEWS)}, got {view!r}')
    if rings < 1 or azimuths < 1 or sigma < 0 or max_range <= 0:
        raise ValueError('need rings, azimuths >= 1, sigma >= 0 and max_range > 0')
    make, (x, y) = LIDAR_VIEWS[view]
    rects = make()
    rng = np.random.default_rng(seed)
    eye = np.array([x, y, height])
    el = np.radians(np.linspace(*elevation_deg, rings))[:, None]
    az = np.linspace(0, 2 * np.pi, azimuths, endpoint=False)[None, :]
    rays = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el) * np.ones_like(az)], -1)
    rays = rays.reshape(-1, 3)
    rng_, which = _raycast(rects, eye, rays)
    hit = (which >= 0) & (rng_ <= max_range)
    r = rng_[hit] + rng.normal(0.0, sigma, hit.sum())
    points = rays[hit] * r[:, None]
    planes = np.array([np.append(rect.normal, -rect.normal @ (np.asarray(rect.origin) - eye)) for rect in rects])
    labels = which[hit].astype(np.int32)
    beam = np.repeat(np.arange(rings, dtype=np.int32), azimuths)  # ring 0 the lowest, as velodyne_pointcloud
    if organized:
        image = np.full((len(rays), 3), np.nan)
        image[hit] = points
        points, labels = image, np.where(hit, which, -1).astype(np.int32)
    return Scene(name=f'lidar_{view}', points=points, labels=labels, planes=planes, noise=sigma,
                 shape=(rings, azimuths) if organized else None, rings=beam if organized else beam[hit])
