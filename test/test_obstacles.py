"""Obstacles: the valid points on no plane, optionally without those near the ground."""
import numpy as np

from plane_validation.app.obstacles import ground_plane, obstacle_mask
from plane_validation.app.pipeline import FramePipeline, PipelineConfig
from plane_validation.core.ransac import Plane, Segmentation
from plane_validation.core.scenes import _look_at, depth_camera


def _segmentation(labels, *coefficients):
    planes = tuple(Plane(np.array(c[:3], float), float(c[3]), np.flatnonzero(labels == k), 0.0)
                   for k, c in enumerate(coefficients))
    return Segmentation(labels=labels, planes=planes, tolerance=0.01, n_valid=len(labels), reason='test')


def test_points_on_no_plane_and_without_those_near_the_largest_horizontal_plane():
    points = np.array([[0, 0, 0.0], [1, 0, 0.0], [0, 1, 0.03], [0, 0, 0.5], [2, 0, 1.0], [3, 0, 0.02]])
    labels = np.array([0, 0, -1, -1, 1, -1], np.int32)
    # plane 0: the floor z = 0; plane 1: a table top z = 1 with more points (both horizontal); a wall
    seg = _segmentation(labels, (0, 0, 1, 0), (0, 0, 1, -1))
    assert list(obstacle_mask(points, labels, seg)) == [False, False, True, True, False, True]
    assert ground_plane(seg, (5, 9)) == 1  # the largest horizontal plane: here the table top
    assert ground_plane(seg, (9, 5)) == 0
    assert list(obstacle_mask(points, labels, seg, (9, 5), ground_margin=0.05)) == [False] * 3 + [True] + [False] * 2
    wall = _segmentation(labels, (1, 0, 0, 0), (0, 1, 0, 0))
    assert ground_plane(wall, (9, 5)) is None  # no horizontal plane: nothing more is left out
    assert obstacle_mask(points, labels, wall, (9, 5), ground_margin=0.05).sum() == 3


def test_the_up_direction_may_have_any_length_but_0():
    """ground_up 1e-200 (its length underflowed to 0, and every plane passed for horizontal: the wall was taken for
    the ground) or 1000 is the same direction as 1."""
    import pytest
    labels = np.array([0, 0, 1], np.int32)
    seg = _segmentation(labels, (1, 0, 0, 0), (0, 0, 1, 0))  # a wall with more points, and the floor
    for z in (1.0, 1000.0, -1e-200, 5e-324):
        assert ground_plane(seg, (9, 5), (0.0, 0.0, z)) == 1, z
    with pytest.raises(ValueError, match='up direction'):
        ground_plane(seg, (9, 5), (0.0, 0.0, 0.0))

def test_the_pipeline_finds_the_obstacles_of_a_room_in_a_z_up_frame_and_removes_the_ground():
    eye, target = np.array([4.6, 0.4, 1.5]), np.array([1.5, 3.6, 0.7])
    scene = depth_camera('room', width=160, height=120, seed=1)
    world = scene.points @ _look_at(eye, target).T + eye  # z up: the floor is z = 0
    cfg = PipelineConfig(auto_tune=False, tolerance=0.004, noise_model='depth_quadratic', viewpoint_x=4.6,
                         viewpoint_y=0.4, viewpoint_z=1.5, seed=1)
    plain = FramePipeline(cfg).process(world, 10**9, shape=scene.shape)
    assert plain.image_shape == (120, 160)
    np.testing.assert_array_equal(plain.obstacles, plain.labels < 0)
    assert plain.diagnostic.get('obstacle_points') == str(int((plain.labels < 0).sum()))
    ground = FramePipeline(PipelineConfig(**{**cfg.__dict__, 'ground_margin': 0.1})).process(
        world, 10**9, shape=scene.shape)
    floor = ground.segmentation.planes[ground.plane_ids.index(int(ground.diagnostic.get('ground_plane')))]
    assert abs(floor.normal[2]) > 0.99 and abs(floor.offset) < 0.02  # the floor, z = 0
    assert 0 < ground.obstacles.sum() < plain.obstacles.sum()
    assert (np.abs(ground.points[ground.obstacles, 2]) > 0.09).all()


def test_in_a_cameras_optical_frame_ground_up_names_the_floor_that_z_up_would_miss():
    """The same room in the camera's own optical frame (y down, z forward, pitched 10 degrees down): with
    ground_up 0, -1, 0 the ground is the floor, as in the z-up frame; with the default z up the floor is not
    taken for it (here no plane is: none lies within 20 degrees of the camera's z)."""
    import pytest
    eye, target = np.array([4.6, 0.4, 1.5]), np.array([1.5, 3.6, 0.7])
    scene = depth_camera('room', width=160, height=120, seed=1)
    to_world = _look_at(eye, target)
    base = dict(auto_tune=False, tolerance=0.004, noise_model='depth_quadratic', seed=1, ground_margin=0.1)
    found = {}
    for up in ((0.0, 0.0, 1.0), (0.0, -1.0, 0.0)):
        cfg = PipelineConfig(**base, ground_up_x=up[0], ground_up_y=up[1], ground_up_z=up[2])
        out = FramePipeline(cfg).process(scene.points, 10**9, shape=scene.shape)
        ground = out.diagnostic.get('ground_plane')
        plane = None if ground == 'none' else out.segmentation.planes[out.plane_ids.index(int(ground))]
        found[up] = None if plane is None else abs(float((to_world @ plane.normal)[2]))
    assert found[(0.0, -1.0, 0.0)] is not None and found[(0.0, -1.0, 0.0)] > 0.99  # the floor
    assert found[(0.0, 0.0, 1.0)] is None  # no plane: none lies within 20 degrees of the camera's z
    with pytest.raises(ValueError, match='ground_up'):
        PipelineConfig(ground_margin=0.1, ground_up_z=0.0).validate()
    PipelineConfig(ground_up_z=0.0).validate()  # unused without ground_margin


def test_the_obstacle_cloud_packed_in_one_pass_matches_the_generic_writer():
    """ros/messages.obstacle_cloud writes the records in the frame pass (kernels.frame_pass); the generic writer
    (create_cloud, used for float64 coordinates) is its reference, for an organized frame (NaN off the obstacles, an
    inf row included) and for the same points unorganized."""
    import pytest
    sensor_msgs = pytest.importorskip('sensor_msgs.msg')
    import std_msgs.msg

    from plane_validation.ros import messages
    scene = depth_camera('table', width=64, height=48, seed=0)
    points = scene.points.copy()
    points[5] = np.inf
    pipeline = FramePipeline(PipelineConfig(auto_tune=False, tolerance=0.02, max_planes=4))
    for shape in (scene.shape, None):
        result = pipeline.process(points if shape else points[np.isfinite(points).all(axis=1)], shape=shape)
        assert result.obstacles is not None and 0 < result.obstacles.sum() < len(result.points)
        header = std_msgs.msg.Header(frame_id='camera')
        packed = messages.obstacle_cloud(header, result)
        mask = result.obstacles
        reference = messages._cloud(header, result, {}, {}, rows=mask) if shape is None else \
            messages._cloud(header, result, {}, {}, hide=~mask)
        assert isinstance(packed, sensor_msgs.PointCloud2)
        assert (packed.height, packed.width, packed.point_step, packed.is_dense) == \
            (reference.height, reference.width, reference.point_step, reference.is_dense)
        assert bytes(packed.data) == bytes(reference.data)
