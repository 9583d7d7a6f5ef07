"""A depth image's normals are unknown where its noise alone tilts them (neighbours_grid.noisy_normals_unknown): a far
noisy wall stays one plane, and near or noise-free surfaces keep their normals."""
from __future__ import annotations

import numpy as np

import plane_validation as pv
from plane_validation.core import scenes
from plane_validation.core.search import neighbours_grid
from plane_validation.core.search.graph import search_graph


def _floor_and_wall(b: float, seed: int = 0, wall: float = 5.0, height: float = 1.0
                    ) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """A 320 x 240 depth frame (camera ``height`` m above a floor, a wall ``wall`` m ahead), depth noise b * z^2:
    (points (N, 3) m, labels (N,) 0 floor 1 wall, shape)."""
    h, w = 240, 320
    f = w / (2 * np.tan(np.radians(29)))
    v, u = np.mgrid[0:h, 0:w]
    rays = np.stack([(u - w / 2) / f, (v - h / 2) / f, np.ones((h, w))], -1)
    with np.errstate(divide='ignore'):
        z_floor = np.where(rays[..., 1] > 0, height / rays[..., 1], np.inf)
    z = np.minimum(wall, z_floor)
    labels = (z_floor >= wall).astype(np.int64)
    z = z + np.random.default_rng(seed).normal(size=z.shape) * b * z * z
    return (rays * z[..., None]).reshape(-1, 3), labels.reshape(-1), (h, w)


def _share_in_one_plane(seg, members: np.ndarray) -> float:
    return max((np.count_nonzero(seg.labels[members] == j) for j in range(seg.n_planes)), default=0) / members.sum()


def test_a_far_noisy_wall_is_one_plane_not_pieces(monkeypatch):
    # 3 mm/m^2 depth noise (twice a Kinect's): 7.5 cm on the wall 5 m away, whose normals over a chord of about 10 cm
    # are noise; the coherence test cut it into pieces (30 % in the largest plane at t = 0.2 m)
    points, labels, shape = _floor_and_wall(0.003)
    wall = labels == 1
    seg = pv.detect_planes(points, 0.2, seed=0, shape=shape, max_planes=5)
    assert _share_in_one_plane(seg, wall) > 0.9
    assert _share_in_one_plane(seg, ~wall) > 0.95
    monkeypatch.setattr(neighbours_grid, 'NOISY_TILT', np.inf)
    assert _share_in_one_plane(pv.detect_planes(points, 0.2, seed=0, shape=shape, max_planes=5), wall) < 0.5


def _unknown(points: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Which rows of ``points`` have an unknown (NaN) grid normal in the search's graph (its sub-grid, as
    detect_planes searches the image); rows not searched: False."""
    graph = search_graph(points, shape=shape)
    out = np.zeros(len(points), bool)
    out[graph.search_idx] = np.isnan(graph.neighbours.normals).any(axis=1)
    return out


def test_the_noise_decides_by_range_not_by_surface(monkeypatch):
    # the camera 0.5 m above the floor: up to 4 m the noise (0.4-5 cm) tilts the floor's normals by less than 14
    # degrees over their chords, on the wall 5 m away by about 40
    points, labels, shape = _floor_and_wall(0.003, height=0.5)
    with_rule = _unknown(points, shape)
    monkeypatch.setattr(neighbours_grid, 'NOISY_TILT', np.inf)
    made_unknown = with_rule & ~_unknown(points, shape)
    searched = np.zeros(len(points), bool)
    searched[search_graph(points, shape=shape).search_idx] = True
    assert made_unknown[(labels == 1) & searched].mean() > 0.85
    near = (labels == 0) & (np.linalg.norm(points, axis=1) < 4.0) & searched
    assert near.sum() > 5000 and not made_unknown[near].any()


def test_a_kinect_like_camera_keeps_its_normals(monkeypatch):
    # a Kinect's noise (1.5 mm/m^2): the stairs' nosings need their normals (the coherence test keeps treads and
    # risers apart) and keep them all; the room loses only a few beyond 4.5 m, where the noise is 3-5 cm
    stairs, room = scenes.depth_camera('stairs', seed=0), scenes.depth_camera('room', seed=0)
    with_rule = [_unknown(c.points, c.shape) for c in (stairs, room)]
    monkeypatch.setattr(neighbours_grid, 'NOISY_TILT', np.inf)
    made_unknown = [w & ~_unknown(c.points, c.shape) for w, c in zip(with_rule, (stairs, room))]
    assert not made_unknown[0].any()
    assert 0 < made_unknown[1].sum() < 0.01 * len(search_graph(room.points, shape=room.shape).search_idx)
    assert np.linalg.norm(room.points[made_unknown[1]], axis=1).min() > 4.5


def test_a_noise_free_image_keeps_its_normals(monkeypatch):
    points, _, shape = _floor_and_wall(0.0)
    with_rule = _unknown(points, shape)
    monkeypatch.setattr(neighbours_grid, 'NOISY_TILT', np.inf)
    np.testing.assert_array_equal(with_rule, _unknown(points, shape))
