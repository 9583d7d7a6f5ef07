"""depth_quadratic's tolerance along the viewing rays (core/noise.py ray_band, RAY_FLOOR): a point within
t * max(|n . u|, floor) of a plane; the compiled kernels against plain numpy, and the constant model untouched."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from plane_validation.core import kernels
from plane_validation.core.noise import RAY_FLOOR, ray_band, ray_share

SETTINGS = settings(max_examples=60, deadline=None)


def test_ray_band_only_for_depth_quadratic():
    """constant keeps the tolerance across the plane (no ray, the paper's figures unchanged)."""
    assert ray_band(np.zeros(3), 'constant').shape == (0,)
    np.testing.assert_array_equal(ray_band(np.array([1.0, 2.0, 3.0]), 'depth_quadratic'), [1.0, 2.0, 3.0, RAY_FLOOR])


def test_ray_share_is_the_cosine_above_the_floor():
    """A plane facing the sensor keeps the whole band, one the ray grazes keeps the floor; no ray: 1."""
    points = np.array([[0.0, 0.0, 2.0], [0.0, 0.1, 2.0], [0.0, 0.0, 0.0]])
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    share = ray_share(points, normals, np.array([0.0, 0.0, 0.0, 0.2]))
    np.testing.assert_allclose(share[0, :2], [1.0, 2.0 / np.hypot(0.1, 2.0)])
    np.testing.assert_allclose(share[1, :2], [0.2, 0.2])  # |n . u| = 0 and 0.05: the floor
    assert share[0, 2] == 0.2 and share[1, 2] == 0.2  # a point at the viewpoint: the floor
    np.testing.assert_array_equal(ray_share(points, normals, kernels.NO_RAY), np.ones((2, 3)))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans(), st.booleans())
def test_inliers_on_along_rays_matches_numpy(seed, per_point, with_normals):
    """kernels._inliers_on (hypothesis scoring) and kernels._ranked (confirming) count the points within
    t * ray_share of a plane (with agreeing normals when known)."""
    rng = np.random.default_rng(seed)
    s = int(rng.integers(1, 200))
    subset = rng.normal(size=(3, s))
    tolerance = rng.uniform(0.05, 1.0, s) if per_point else np.array([rng.uniform(0.05, 1.0)])
    point_normals = rng.normal(size=(3, s)) if with_normals else np.empty((3, 0))
    if with_normals:
        point_normals /= np.linalg.norm(point_normals, axis=0)
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    d = float(rng.normal())
    ray = np.append(rng.normal(size=3), rng.uniform(0.05, 0.9))
    lo = int(rng.integers(0, s))
    hi = int(rng.integers(lo, s + 1))
    band = np.broadcast_to(tolerance, (s,)) * ray_share(subset.T, normal[None, :], ray)[0]
    near = np.abs(normal @ subset + d) <= band
    if with_normals:
        near &= ~(np.abs(normal @ point_normals) < 0.5)
    got = kernels._inliers_on(subset, tolerance, point_normals, *normal, d, lo, hi, 0.5, ray)
    assert got == np.count_nonzero(near[lo:hi])
    counts = kernels._ranked(subset, tolerance, normal[None, :], np.array([d]), ray)[0]
    assert counts[0] == np.count_nonzero(np.abs(normal @ subset + d) <= band)


def _correct(seg, labels: np.ndarray) -> set:
    """The true planes of ``labels`` (N,) some plane of ``seg`` matches at Hoover overlap 0.8."""
    out = set()
    for k in np.unique(labels[labels >= 0]):
        true = labels == k
        for j in range(len(seg.planes)):
            mine = seg.labels == j
            both = np.count_nonzero(mine & true)
            if both >= 0.8 * np.count_nonzero(true) and both >= 0.8 * np.count_nonzero(mine):
                out.add(int(k))
    return out


def test_depth_frame_planes_found_along_rays(monkeypatch):
    """A generated depth frame (indoor_depth, a tuning seed) at t0 = 9 mm with depth_quadratic: the tolerance along
    the rays finds every plane the tolerance across the plane finds (the search without a ray), and more."""
    from plane_validation.core import scene_families
    from plane_validation.core.ransac import detect_planes
    from plane_validation.core.search import detect
    scene = scene_families.indoor_depth(7)
    n = int(np.isfinite(scene.points).all(axis=1).sum())
    kwargs = dict(shape=scene.shape, noise_model='depth_quadratic', seed=0, max_planes=len(scene.planes) + 8,
                  min_inliers=min(int(0.0008 * n), scene.min_plane_points))
    along = _correct(detect_planes(scene.points, 0.009, **kwargs), scene.labels)
    monkeypatch.setattr(detect, 'ray_band', lambda viewpoint, noise_model: kernels.NO_RAY)
    across = _correct(detect_planes(scene.points, 0.009, **kwargs), scene.labels)
    assert across < along, (across, along)
