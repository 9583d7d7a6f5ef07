"""Benchmark inputs: synthetic 640 x 480 depth-camera frames with per-pixel truth, and real files.

A synthetic frame is a project scene (:mod:`plane_validation.scenes`) seen by a Kinect-like depth
camera. Unlike ``scripts/make_bags.py``, which z-buffers sampled points, each pixel's ray is cast
against the scene's planar faces (convex polygons: the 2-D hull of each face's sample points), so
every pixel that sees a face gets a point; non-planar clutter (table legs) is z-buffered from its
sample points. Then, per pixel (all in the camera optical frame, meters):

* depth noise along the ray, Gaussian with sigma(z) = 1.2 mm + 1.9 mm * (z - 0.4 m)^2 / m^2
  (Kinect v1 axial noise, Nguyen, Izadi and Lovell 2012): 1.9 mm at 1 m, 6.1 mm at 2 m;
* NaN holes: no surface within 0.5 - 4.5 m, grazing incidence (|cos| < 0.1), 1 % random pixel
  dropout and a few rectangular dropout patches.

Ground truth per pixel: the index of the scene plane it sees, -1 clutter, -2 hole.
"""
from __future__ import annotations

import importlib.util
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

from plane_validation import scenes
from plane_validation.core.geometry import plane_basis

ROOT = Path(__file__).resolve().parents[2]

WIDTH, HEIGHT = 640, 480
HFOV_DEG = 57.0          # Kinect v1 horizontal field of view
MIN_RANGE, MAX_RANGE = 0.5, 4.5   # m, depth along the optical axis
MIN_COS = 0.1            # grazing incidence below this |cos| gives no return
DROPOUT = 0.01           # share of isolated lost pixels
PATCHES = 6              # rectangular dropout patches per frame
SCENE_POINTS = 1_500_000  # samples that outline each face (hull) and the clutter


def _make_bags():
    """scripts/make_bags.py as a module (for its Camera and look_at)."""
    name = 'pv_make_bags'
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / 'scripts' / 'make_bags.py')
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


@dataclass(frozen=True, eq=False)
class Frame:
    """One benchmark input. points: (height*width, 3) float64 meters, NaN rows for holes.
    truth: (height*width,) int32 true plane per point, -1 clutter, -2 hole; None for real data."""

    name: str
    points: np.ndarray
    height: int
    width: int
    source: str
    truth: np.ndarray | None = None
    finite: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, 'finite', np.isfinite(self.points).all(axis=1))

    @property
    def n_valid(self) -> int:
        return int(self.finite.sum())

    @property
    def synthetic(self) -> bool:
        return self.truth is not None


@dataclass(frozen=True)
class View:
    """A scene (generator name and keyword arguments) and the camera pose looking at it."""

    scene: str
    kwargs: dict
    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    seed: int


#: The synthetic frames, in table order.
VIEWS: dict[str, View] = {
    'room': View('room', {}, eye=(1.8, 1.0, 1.2), target=(5.0, 3.0, 1.5), seed=1),
    'table': View('table', {}, eye=(0.55, -0.6, 1.7), target=(0.6, 0.4, 0.8), seed=2),
    'boxes': View('boxes', {'outlier_fraction': 0.0}, eye=(3.0, 0.0, 1.5), target=(1.2, 2.2, 0.5), seed=3),
    'stairs': View('stairs', {}, eye=(-0.8, 0.5, 1.3), target=(0.6, 0.5, 0.4), seed=4),
}


def pixel_rays(width: int = WIDTH, height: int = HEIGHT, hfov_deg: float = HFOV_DEG) -> np.ndarray:
    """(height*width, 3) optical-frame rays through the pixel centres, scaled to z = 1."""
    camera = _make_bags().Camera(width=width, height=height, hfov_deg=hfov_deg, max_range=MAX_RANGE)
    u, v = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    return np.column_stack([((u - camera.cx) / camera.fx).ravel(), ((v - camera.cy) / camera.fx).ravel(),
                            np.ones(width * height)])


def cast_face(eye: np.ndarray, rays: np.ndarray, plane: np.ndarray, face_points: np.ndarray) -> np.ndarray:
    """Ray parameter (= optical depth, m) where each scene-frame ray hits the convex face, inf if not.

    plane: (4,) a, b, c, d with unit normal; face_points: (m, 3) samples of the face (its outline).
    """
    normal, offset = plane[:3], plane[3]
    basis = plane_basis(normal)[:, :2]  # (3, 2) orthonormal in-plane axes
    anchor = face_points.mean(axis=0)
    hull = ConvexHull((face_points - anchor) @ basis)
    corners = hull.points[hull.vertices]            # counter-clockwise
    with np.errstate(divide='ignore', invalid='ignore'):
        depth = -(normal @ eye + offset) / (rays @ normal)
    depth[~np.isfinite(depth) | (depth <= 0)] = np.inf
    hit = np.flatnonzero(np.isfinite(depth))
    local = (eye - anchor + depth[hit, None] * rays[hit]) @ basis
    inside = np.ones(len(hit), bool)
    for a, b in zip(corners, np.roll(corners, -1, axis=0)):
        edge = b - a
        inside &= edge[0] * (local[:, 1] - a[1]) - edge[1] * (local[:, 0] - a[0]) >= 0
    depth[hit[~inside]] = np.inf
    return depth


def _splat(points_cam: np.ndarray, width: int, rays: np.ndarray) -> np.ndarray:
    """Per-pixel nearest optical depth of camera-frame points (z-buffer), inf where none."""
    depth = np.full(len(rays), np.inf)
    z = points_cam[:, 2]
    front = z > MIN_RANGE / 2
    fx = 1.0 / (rays[1, 0] - rays[0, 0])            # rays are 1/fx apart along a row
    cx = 0.5 - rays[0, 0] * fx
    cy = 0.5 - rays[0, 1] * fx
    u = np.floor(fx * points_cam[front, 0] / z[front] + cx).astype(np.int64)
    v = np.floor(fx * points_cam[front, 1] / z[front] + cy).astype(np.int64)
    height = len(rays) // width
    ok = (u >= 0) & (u < width) & (v >= 0) & (v < height)
    np.minimum.at(depth, v[ok] * width + u[ok], z[front][ok])
    return depth


def kinect_sigma(depth: np.ndarray) -> np.ndarray:
    """Axial depth noise of a Kinect v1 (m) at optical depth ``depth`` (m)."""
    return 0.0012 + 0.0019 * (depth - 0.4) ** 2


def render(name: str, view: View, width: int = WIDTH, height: int = HEIGHT) -> Frame:
    """The synthetic depth-camera frame of ``view`` (see the module docstring)."""
    mb = _make_bags()
    scene = scenes.SCENES[view.scene](SCENE_POINTS, 0.0, seed=view.seed, **view.kwargs)
    rot = np.array(mb.look_at(view.eye, view.target, mb.OPTICAL))   # columns: camera axes in the scene
    eye = np.asarray(view.eye, dtype=float)
    rays_cam = pixel_rays(width, height)
    rays = rays_cam @ rot.T
    depth = np.full(len(rays), np.inf)
    truth = np.full(len(rays), -2, np.int32)
    for j, plane in enumerate(scene.planes):
        face = scene.points[scene.labels == j]
        if len(face) < 3:
            continue
        hit = cast_face(eye, rays, plane, face)
        closer = hit < depth
        depth[closer], truth[closer] = hit[closer], j
    clutter = scene.points[scene.labels < 0]
    if len(clutter):
        hit = _splat((clutter - eye) @ rot, width, rays_cam)
        closer = hit < depth
        depth[closer], truth[closer] = hit[closer], -1
    return _sensor_effects(name, scene, rays, rays_cam, depth, truth, width, height, view.seed)


def _sensor_effects(name: str, scene: scenes.Scene, rays: np.ndarray, rays_cam: np.ndarray, depth: np.ndarray,
                    truth: np.ndarray, width: int, height: int, seed: int) -> Frame:
    """Range limits, grazing-angle loss, dropouts and depth noise; camera-frame points."""
    rng = np.random.default_rng(seed)
    lost = ~((depth >= MIN_RANGE) & (depth <= MAX_RANGE))
    on_plane = truth >= 0
    unit = rays[on_plane] / np.linalg.norm(rays[on_plane], axis=1, keepdims=True)
    cos = np.abs(np.einsum('ij,ij->i', unit, scene.planes[truth[on_plane], :3]))
    lost[np.flatnonzero(on_plane)[cos < MIN_COS]] = True
    lost |= rng.random(len(depth)) < DROPOUT
    grid = lost.reshape(height, width)
    for _ in range(PATCHES):
        ph, pw = rng.integers(4, 16), rng.integers(6, 24)
        r0, c0 = rng.integers(0, height - ph), rng.integers(0, width - pw)
        grid[r0:r0 + ph, c0:c0 + pw] = True
    noisy = depth + rng.normal(0.0, 1.0, len(depth)) * kinect_sigma(np.where(lost, 1.0, depth))
    points = rays_cam * np.where(lost, np.nan, noisy)[:, None]
    truth = np.where(lost, -2, truth).astype(np.int32)
    return Frame(name=name, points=points, height=height, width=width, source='synthetic', truth=truth)


def synthetic_frames(names: list[str] | None = None) -> list[Frame]:
    """Render the named views (all of :data:`VIEWS` by default)."""
    return [render(n, VIEWS[n]) for n in (names or list(VIEWS))]


def load_frames(path: str) -> list[Frame]:
    """Frames from a point file (via plane_validation.formats.files.load_points) or the first cloud of a bag.

    Raises ValueError (with the reason) when the file cannot be read.
    """
    p = Path(path)
    if p.is_dir() or p.suffix.lower() in ('.bag', '.mcap', '.db3'):
        from plane_validation.formats.pointcloud2 import xyz_array
        from plane_validation.ros.replay import read_clouds
        bag = p if p.is_dir() else p.parent
        for _, _, msg in read_clouds(bag):
            pts = xyz_array(msg)
            return [Frame(name=p.name, points=pts, height=int(msg.height), width=int(msg.width), source=str(p))]
        raise ValueError(f'{p}: bag holds no PointCloud2 message')
    from plane_validation.formats.files import load_points
    try:
        pts = np.asarray(load_points(p), dtype=np.float64)
    except ValueError:
        raise
    except Exception as exc:  # e.g. a reader that is still missing (PLY), a broken optional dependency
        raise ValueError(f'{p}: {type(exc).__name__}: {exc}') from exc
    height, width = (HEIGHT, WIDTH) if len(pts) == WIDTH * HEIGHT else (1, len(pts))
    return [Frame(name=p.stem, points=pts, height=height, width=width, source=str(p))]


def resampled(frame: Frame, n_points: int, seed: int = 0) -> np.ndarray:
    """(n_points, 3) finite points drawn from ``frame`` (with replacement beyond its size) plus
    0.5 mm jitter so that repeats are distinct points."""
    rng = np.random.default_rng(seed)
    valid = frame.points[frame.finite]
    rows = rng.choice(len(valid), n_points, replace=n_points > len(valid))
    return valid[rows] + rng.normal(0.0, 0.0005, (n_points, 3))
