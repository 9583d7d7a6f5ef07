"""The sensor noise from local plane residuals (core/noise_estimate.py) against scenes of known noise, its compiled
kernel against numpy, and the sweep's bound by it (core/tuning.py)."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plane_validation.core import kernels, scene_families
from plane_validation.core.noise_estimate import _patch_fits_numpy, estimate_noise
from plane_validation.core.tuning import NOISE_BOUND, tune_tolerance


@pytest.mark.parametrize('seed, a, b', [(0, 0.002, 0.003), (1, 0.0, 0.0015), (2, 0.003, 0.0), (3, 0.001, 0.0045)])
def test_depth_frame_noise_fits_a_and_b(seed, a, b):
    # depth noise a + b z^2 along each ray of a furnished room's 640 x 480 frame (no quantisation: the truth is a, b)
    scene = scene_families.indoor_depth(seed, noise=(a, b), quantum=0)
    est = estimate_noise(scene.points, scene.shape, seed=0)
    assert est.along_ray and est.patches > 500
    r = np.linspace(min(est.ranges), max(est.ranges), 5)
    np.testing.assert_allclose(est.sigma(r), a + b * r ** 2, rtol=0.2)
    assert est.sigma_reference == pytest.approx(est.a + est.b)


def test_constant_noise_has_no_range_term():
    # a lidar scan (unorganized: voxel neighbourhoods) with range noise sigma, the same at every range
    for seed in (1, 2, 3):
        scene = scene_families.lidar_scan(seed)
        est = estimate_noise(scene.points, seed=0)
        assert est.along_ray
        np.testing.assert_allclose(est.sigma(np.array(est.ranges)), scene.noise, rtol=0.15)


def test_corridor_walls_at_grazing_angles_give_the_range_noise():
    # most of a corridor's wall runs away from the sensor: fewer than half its neighbourhoods face it, and the
    # others' thickness is only the range noise times |cos|; those facing it still measure the range noise
    for seed in (17, 37):
        scene = scene_families.lidar_scan(seed)
        assert scene.name.startswith('lidar_scan_corridor')
        est = estimate_noise(scene.points, seed=0)
        assert est.along_ray
        assert est.a == pytest.approx(scene.noise, rel=0.15)


def test_roof_from_its_own_centre_is_perpendicular_noise():
    # a roof centred on its mean: the origin sees it edge-on, its noise is vertical, not along any ray
    for seed in (0, 2, 5, 6):
        scene = scene_families.aerial_roof(seed)
        est = estimate_noise(scene.points, seed=0)
        assert not est.along_ray and est.b == 0.0
        assert est.a == pytest.approx(scene.noise, rel=0.15)


def test_noise_free_and_degenerate_clouds():
    rng = np.random.default_rng(0)
    flat = np.column_stack([rng.uniform(-1, 1, (5000, 2)), np.full(5000, 3.0)])
    assert estimate_noise(flat, seed=0).patches == 0  # noise-free: nothing measured, not a noise of 0
    steps = flat + (0, 0, 1)
    steps[:, 2] = np.round(rng.normal(4, 0.004, 5000) / 0.01) * 0.01  # 1 cm depth steps over 4 mm noise
    assert estimate_noise(steps, seed=0).a > 0.001
    few = estimate_noise(flat[:12], seed=0)  # too few neighbourhoods: no estimate, no error
    assert few.patches == 0 and np.isnan(few.sigma_reference) and np.isnan(few.level(flat))
    assert estimate_noise(np.full((100, 3), np.nan), seed=0).patches == 0
    with pytest.raises(ValueError, match='shape'):
        estimate_noise(flat, (10, 10))
    far = np.vstack([flat, [[1e9, 1e9, 1e9]]])  # voxels fine enough for the plane cannot span it: no estimate
    assert estimate_noise(far, seed=0).patches == 0


def test_estimate_is_deterministic_per_seed():
    scene = scene_families.indoor_depth(4)
    first, again = (estimate_noise(scene.points, scene.shape, seed=3) for _ in range(2))
    assert first == again


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_patch_fits_match_numpy(seed):
    rng = np.random.default_rng(seed)
    n, m = 300, 40
    pts = rng.normal(size=(n, 3)) * rng.uniform(0.01, 1, 3) + rng.normal(0, 3, 3) + (0, 0, 4)
    sizes = rng.integers(4, 30, m)
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    # distinct points in each patch: a patch on two points repeated has no normal to compare
    members = np.concatenate([rng.choice(n, size, replace=False) for size in sizes]).astype(np.int64)
    got = kernels.patch_fits(pts, members, starts)
    ref = _patch_fits_numpy(pts, members, starts)
    for name, g, r in zip(('ray_var', 'facing', 'perp_var', 'plane_facing', 'flatness', 'breadth', 'range'), got, ref):
        both = np.isfinite(g) & np.isfinite(r)
        assert both.sum() >= 0.9 * m, name
        scale = np.nanmax(np.abs(r)) if name.endswith('var') else 1.0
        np.testing.assert_allclose(g[both], r[both], rtol=1e-6, atol=1e-9 * scale, err_msg=name)


def test_patch_fits_single_ray_is_no_fit():
    pts = np.outer(np.linspace(1, 2, 10), [0.0, 0.6, 0.8])  # every point on one ray: directions span nothing
    ray_var, facing, *_ = kernels.patch_fits(pts, np.arange(10, dtype=np.int64), np.array([0, 10], np.int64))
    assert np.isnan(ray_var[0]) and np.isnan(facing[0])


def test_sweep_is_bounded_by_the_noise():
    # a 2-degree gable under 2.7 cm noise: unbounded, the sweep chooses 5.5 sigma (both sides as one plane)
    scene = scene_families.aerial_roof(10)
    opts = dict(seed=0, max_planes=10, min_inliers=20)
    bounded = tune_tolerance(scene.points, **opts)
    free = tune_tolerance(scene.points, noise_bound=0, **opts)
    assert bounded.noise_level == pytest.approx(scene.noise, rel=0.15)
    assert bounded.tolerances.max() <= NOISE_BOUND * bounded.noise_level * (1 + 1e-9)
    assert bounded.noise_ratio <= NOISE_BOUND * (1 + 1e-9) < free.noise_ratio
    assert free.noise_level == bounded.noise_level and free.tolerances.max() > NOISE_BOUND * free.noise_level
    # the paper's method (no connected regions) keeps its derived range
    paper = tune_tolerance(scene.points, connectivity=False, extend=0, **opts)
    assert paper.tolerances.max() > NOISE_BOUND * paper.noise_level
    with pytest.raises(ValueError, match='noise_bound'):
        tune_tolerance(scene.points, noise_bound=-1, **opts)


def test_noise_free_cloud_is_not_bounded():
    # no measurable noise: a bound of 0 would leave no candidate, so the derived range stays
    rng = np.random.default_rng(1)
    a = np.column_stack([rng.uniform(0, 1, (1500, 2)), np.zeros(1500)])
    b = np.column_stack([rng.uniform(0, 1, 1500), np.zeros(1500), rng.uniform(0, 1, 1500)])
    result = tune_tolerance(np.vstack([a, b]) + (0, 0.5, 2), seed=0)
    assert np.isnan(result.noise_level) and np.isnan(result.noise_ratio)
    assert len(result.tolerances) >= 12 and result.segmentation.n_planes == 2


def test_auto_noise_model_follows_the_measured_noise():
    # noise growing with range (a depth camera) calls for depth_quadratic; the same at every range, for constant
    depth = scene_families.indoor_depth(1, noise=(0.0005, 0.003), quantum=0)
    assert estimate_noise(depth.points, depth.shape, seed=0).model(depth.points) == 'depth_quadratic'
    # within sqrt(2) reference ranges (the room is 2.4-3.6 m away) the two models differ little: constant
    near = estimate_noise(depth.points, depth.shape, seed=0, reference=3.0)
    assert near.b > 0 and near.model(depth.points) == 'constant'
    flat_noise = scene_families.indoor_depth(1, noise=(0.01, 0.0), quantum=0)
    assert estimate_noise(flat_noise.points, flat_noise.shape, seed=0).model(flat_noise.points) == 'constant'
    lidar = scene_families.lidar_scan(1)
    assert estimate_noise(lidar.points, seed=0).model(lidar.points) == 'constant'
    roof = scene_families.aerial_roof(0)  # seen edge-on: no range term at all
    assert estimate_noise(roof.points, seed=0).model(roof.points) == 'constant'
    rng = np.random.default_rng(0)
    flat = np.column_stack([rng.uniform(-1, 1, (5000, 2)), np.full(5000, 3.0)])
    assert estimate_noise(flat, seed=0).model(flat) == 'constant'  # no estimate: the paper's single t


def test_auto_sweeps_depth_quadratic_from_one_to_the_bound_s_sigmas():
    scene = scene_families.indoor_depth(2, noise=(0.0005, 0.003), quantum=0)
    opts = dict(seed=0, max_planes=12, min_inliers=200)
    auto = tune_tolerance(scene.points, shape=scene.shape, **opts)
    sigma = auto.sensor_noise.sigma_reference
    assert auto.noise_model == auto.segmentation.noise_model == 'depth_quadratic'
    assert auto.tolerances.min() == pytest.approx(sigma) and auto.tolerances.max() <= NOISE_BOUND * sigma * (1 + 1e-9)
    assert auto.tolerances.max() == pytest.approx(NOISE_BOUND * sigma)
    given = tune_tolerance(scene.points, shape=scene.shape, noise_model='depth_quadratic', **opts)
    assert given.tolerance == auto.tolerance and np.array_equal(given.segmentation.labels, auto.segmentation.labels)
    constant = tune_tolerance(scene.points, shape=scene.shape, noise_model='constant', **opts)
    assert constant.noise_model == 'constant' and constant.tolerances.min() != pytest.approx(sigma)
    with pytest.raises(ValueError, match='noise_model'):
        tune_tolerance(scene.points, shape=scene.shape, noise_model='quadratic', **opts)


def test_a_range_term_fitted_on_few_bins_chooses_no_model():
    # a corridor's neighbourhoods in two range bins, the far one on grazing walls: b from one outlier bin
    scene = scene_families.lidar_scan(22)
    est = estimate_noise(scene.points, seed=0)
    assert len(est.ranges) < 4 and est.b > 0
    assert est.model(scene.points) == 'constant'
