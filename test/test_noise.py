"""The depth_quadratic noise model: per-point tolerance, tuning of t0 and the fitted sigma(r) = c r^2."""
import numpy as np
import pytest

import plane_validation as pv
from plane_validation import scenes
from plane_validation.app.pipeline import FramePipeline, PipelineConfig
from plane_validation.core.noise import noise_coefficient, tolerance_scale
from plane_validation.core.scoring import segmentation_quality


def _near_and_far_walls(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Two parallel walls facing the sensor, 1 m and 3 m away, with depth noise sigma = 0.002 r^2
    along each ray (2 mm near, 18 mm far): (points (N, 3), true wall per point)."""
    rng = np.random.default_rng(seed)
    parts, truth = [], []
    for k, (z, x0) in enumerate(((1.0, -0.6), (3.0, 0.1))):
        p = np.column_stack([rng.uniform(x0, x0 + 0.5, 4000) * z, rng.uniform(-0.3, 0.3, 4000) * z,
                             np.full(4000, z)])
        r = np.linalg.norm(p, axis=1)
        parts.append(p * (1 + rng.normal(0, 0.002, len(p)) * r)[:, None])  # dr = 0.002 r^2 N(0, 1)
        truth.append(np.full(4000, k))
    return np.vstack(parts), np.concatenate(truth)


def test_tolerance_grows_as_range_squared_beyond_the_reference():
    pts = np.array([[0, 0, 0.5], [0, 0, 1.0], [0, 3.0, 4.0], [np.nan, 0, 0]])
    assert tolerance_scale(pts) is None  # constant
    scale = tolerance_scale(pts, 'depth_quadratic')
    assert np.allclose(scale[:3], [1.0, 1.0, 25.0]) and np.isnan(scale[3])
    assert np.allclose(tolerance_scale(pts[:3], 'depth_quadratic', 2.5), [1.0, 1.0, 4.0])
    with pytest.raises(ValueError, match='unknown noise_model'):
        pv.detect_planes(pts, 0.01, noise_model='quadratic')
    with pytest.raises(ValueError, match='noise_reference'):
        pv.detect_planes(pts, 0.01, noise_model='depth_quadratic', noise_reference=0.0)


def test_a_reference_range_may_be_any_real_number_and_a_huge_one_is_a_clear_error():
    from decimal import Decimal
    from fractions import Fraction
    pts = np.array([[0, 0, 0.5], [0, 0, 1.0], [0, 3.0, 4.0]])
    for reference in (Fraction(5, 2), Decimal('2.5'), np.float32(2.5), 5 // 2 + 0.5):
        assert np.allclose(tolerance_scale(pts, 'depth_quadratic', reference), [1.0, 1.0, 4.0])
    assert np.allclose(tolerance_scale(pts, 'depth_quadratic', 2**70), 1.0)
    for reference in (10**400, '2.5', True, -1, float('inf')):
        with pytest.raises(ValueError, match='noise_reference must be a finite range > 0 m'):
            tolerance_scale(pts, 'depth_quadratic', reference)


@pytest.mark.parametrize('connectivity', [True, False])
def test_one_t0_fits_a_near_and_a_far_wall_where_one_t_cannot(connectivity):
    pts, truth = _near_and_far_walls()
    # 5 mm: about 2.5 sigma at 1 m but only 0.3 sigma at 3 m
    constant = pv.detect_planes(pts, 0.005, seed=0, min_inliers=1000, connectivity=connectivity)
    model = pv.detect_planes(pts, 0.005, seed=0, min_inliers=1000, connectivity=connectivity,
                             noise_model='depth_quadratic')
    q_constant, q_model = segmentation_quality(constant.labels, truth), segmentation_quality(model.labels, truth)
    assert q_model.correct == 2 and q_model.f1 > 0.95, q_model
    assert q_constant.correct < 2 and q_constant.f1 < q_model.f1 - 0.1, q_constant
    assert model.tolerance == 0.005 and model.noise_model == 'depth_quadratic'
    far = model.planes[int(np.argmax([abs(p.offset) for p in model.planes]))]
    assert abs(abs(far.offset) - 3.0) < 0.01


def test_noise_coefficient_is_fitted_from_plane_residuals():
    pts, truth = _near_and_far_walls(seed=1)
    coefficients = np.array([[0, 0, 1, -1.0], [0, 0, 1, -3.0]])
    assert noise_coefficient(pts, truth, coefficients) == pytest.approx(0.002, rel=0.05)
    assert np.isnan(noise_coefficient(pts, np.full(len(pts), -1), coefficients))


def test_tuning_with_the_depth_model_recovers_the_camera_noise():
    scene = scenes.depth_camera('room', width=320, height=240, seed=3)  # sigma(z) = 0.0015 z^2
    result = pv.tune_tolerance(scene.points, seed=0, shape=scene.shape, max_planes=12, min_inliers=0.005,
                               noise_model='depth_quadratic')
    assert result.noise_model == 'depth_quadratic' and result.segmentation.noise_model == 'depth_quadratic'
    assert result.noise_coefficient == pytest.approx(scene.noise, rel=0.3)
    assert segmentation_quality(result.segmentation.labels, scene.labels).correct >= 6
    constant = pv.tune_tolerance(scene.points, seed=0, shape=scene.shape, max_planes=12, min_inliers=0.005,
                                 noise_model='constant')
    assert np.isnan(constant.noise_coefficient)
    assert result.tolerance < constant.tolerance  # t0 holds up to 1 m; the room is 2-6 m away


def test_the_pipeline_reports_the_model_and_its_coefficient():
    scene = scenes.depth_camera('table', width=160, height=120, seed=2)
    cfg = PipelineConfig(auto_tune=False, tolerance=0.003, noise_model='depth_quadratic', max_planes=8,
                         min_inliers=0.01)
    result = FramePipeline(cfg).process(scene.points, shape=scene.shape)
    values = dict(result.values)
    assert values['noise_model'] == 'depth_quadratic'
    assert float(values['noise_coefficient']) == pytest.approx(scene.noise, rel=0.3)
    assert 'noise_coefficient' not in dict(FramePipeline(PipelineConfig(auto_tune=False)).process(scene.points).values)
    with pytest.raises(ValueError, match='noise_model must be one of'):
        PipelineConfig(noise_model='linear').validate()


@pytest.mark.filterwarnings('error::RuntimeWarning')  # a driver's FLT_MAX row is input, not a numpy accident
def test_a_far_out_row_is_no_inlier_and_the_frame_still_works():
    rng = np.random.default_rng(0)
    plane = np.column_stack([rng.uniform(-1, 1, 3000), rng.uniform(-1, 1, 3000), 2 + rng.normal(0, 0.002, 3000)])
    with_sentinel = np.vstack([plane, [[3.4e38] * 3]])  # a driver's FLT_MAX row
    with np.errstate(over='ignore'):
        seg = pv.detect_planes(with_sentinel, 0.01, seed=0, connectivity=False, noise_model='depth_quadratic')
    assert seg.n_planes == 1 and seg.labels[-1] == -1 and np.count_nonzero(seg.labels == 0) > 2900
    for auto in (False, True):
        cfg = PipelineConfig(noise_model='depth_quadratic', auto_tune=auto, connectivity=False, tolerance=0.01)
        result = FramePipeline(cfg).process(with_sentinel, 1)
        assert result.n_planes == 1, result.message
        assert float(dict(result.values)['noise_coefficient']) == pytest.approx(0.0005, rel=0.5)
    far = np.vstack([plane[:2000], [[60.0, 80.0, 40.0]]])  # 38 m off the plane, 108 m away
    assert pv.detect_planes(far, 0.01, seed=0, noise_model='depth_quadratic', ransac_points=500).labels[-1] == -1
    assert tolerance_scale(far[-1:], 'depth_quadratic')[0] == 100.0  # capped


def test_a_tuning_range_the_model_cannot_honour_is_an_error():
    rng = np.random.default_rng(0)
    wall = np.column_stack([rng.uniform(-2, 2, 3000), rng.uniform(-1, 1, 3000), 6 + rng.normal(0, 0.01, 3000)])
    with pytest.raises(ValueError, match='t_min'):  # 50 cm at 1 m: above the sweep's top, 5 sigmas of 1 cm noise
        pv.tune_tolerance(wall, count=6, noise_model='depth_quadratic', t_min=0.5, seed=0)


def test_depth_quadratic_ranges_are_measured_from_the_viewpoint():
    scene = scenes.depth_camera('table', width=80, height=60, seed=0)
    pts = scene.points[np.isfinite(scene.points).all(axis=1)]
    v = np.array([0.3, -0.2, 1.0])
    np.testing.assert_allclose(tolerance_scale(pts + v, 'depth_quadratic', viewpoint=v),
                               tolerance_scale(pts, 'depth_quadratic'))
    own = pv.detect_planes(pts, 0.005, seed=0, noise_model='depth_quadratic')
    moved = pv.detect_planes(pts + v, 0.005, seed=0, noise_model='depth_quadratic', viewpoint=v)
    assert np.array_equal(own.labels, moved.labels)
    assert noise_coefficient(pts + v, moved.labels, moved.coefficients, v) == pytest.approx(
        noise_coefficient(pts, own.labels, own.coefficients), rel=1e-6)


def test_auto_is_the_tuner_s_and_a_given_t_searches_constant():
    from plane_validation import detect_planes
    from plane_validation.app.config import PipelineConfig
    from plane_validation.core.noise import searched_model
    pts = np.random.default_rng(0).uniform(0, 1, (200, 3))
    with pytest.raises(ValueError, match='auto is chosen by tune_tolerance'):
        detect_planes(pts, 0.01, noise_model='auto')
    assert searched_model('auto') == 'constant' and searched_model('auto', 'depth_quadratic') == 'depth_quadratic'
    assert searched_model('depth_quadratic') == 'depth_quadratic' == searched_model('depth_quadratic', 'constant')
    search = PipelineConfig().search
    assert search.noise_model == 'auto' and search.kwargs()['noise_model'] == 'auto'
    assert search.at_tolerance()['noise_model'] == 'constant'
    assert search.at_tolerance('depth_quadratic')['noise_model'] == 'depth_quadratic'


def test_the_node_searches_frames_with_the_model_its_sweep_chose():
    scene = scenes.depth_camera('room', width=320, height=240, seed=3)  # sigma(z) = 0.0015 z^2
    pipeline = FramePipeline(PipelineConfig(max_planes=12, min_inliers=0.005))  # noise_model auto
    first = dict(pipeline.process(scene.points, 1, shape=scene.shape).values)
    assert pipeline.last_tuning.noise_model == pipeline.last_model == 'depth_quadratic'
    later = dict(pipeline.process(scene.points, 2, shape=scene.shape).values)
    assert first['noise_model'] == later['noise_model'] == 'depth_quadratic'
    assert later['tolerance_source'].startswith('tuned') and 'noise_coefficient' in later
    fixed = FramePipeline(PipelineConfig(auto_tune=False, tolerance=0.02, max_planes=12, min_inliers=0.005))
    assert dict(fixed.process(scene.points, 1, shape=scene.shape).values)['noise_model'] == 'constant'
