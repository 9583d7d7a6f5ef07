"""The orientation constraint (axis_mode, normal_axis_x/y/z, axis_angle): inside the search, in the API, the CLI,
the pipeline's parameters and the node's (over DDS)."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import plane_validation as pv
from plane_validation import scenes
from plane_validation.app.config import PipelineConfig
from plane_validation.core.orientation import AxisMode, orientation

UP = np.array([0.0, 0.0, 1.0])


def _angles(seg, axis) -> np.ndarray:
    """Degrees between each plane's normal and ``axis`` (sign ignored)."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.degrees(np.arccos(np.clip([abs(p.normal @ axis) for p in seg.planes], 0, 1)))


@pytest.mark.parametrize('connectivity', [True, False])
def test_parallel_keeps_horizontal_planes_and_perpendicular_vertical_ones(connectivity):
    room = scenes.room(8000, 0.005, seed=2)  # floor, ceiling and four walls, z up
    free = pv.detect_planes(room.points, 0.02, seed=1, connectivity=connectivity)
    assert free.n_planes == 6
    flat = pv.detect_planes(room.points, 0.02, seed=1, connectivity=connectivity,
                            orientation=orientation(UP, 5, 'parallel'))
    assert flat.n_planes == 2 and (_angles(flat, UP) <= 5).all()
    walls = pv.detect_planes(room.points, 0.02, seed=1, connectivity=connectivity,
                             orientation=orientation(UP, 5, 'perpendicular'))
    assert walls.n_planes == 4 and (_angles(walls, UP) >= 85).all()


def test_a_tilted_camera_frame_keeps_its_tilted_floor_and_table_within_the_angle():
    """Every plane returned, after its refits and merges, lies within the angle: also planes it cuts through
    points of other surfaces when no true surface fits (the constraint is not a filter afterwards)."""
    scene = scenes.depth_camera('table', width=160, height=120, seed=3)
    up = np.array([0.0, 0.85, 0.52])  # the floor's normal in the camera's frame
    for angle in (2.0, 10.0, 30.0):
        for mode in ('parallel', 'perpendicular'):
            seg = pv.detect_planes(scene.points, 0.02, shape=(120, 160), seed=1,
                                   orientation=orientation(up, angle, mode))
            off = _angles(seg, up) if mode == 'parallel' else 90 - _angles(seg, up)
            assert seg.n_planes >= 1 and (off <= angle + 1e-9).all(), (angle, mode, off)


def test_tuning_takes_the_constraint_too():
    room = scenes.room(8000, 0.005, seed=2)
    tuned = pv.tune_tolerance(room.points, seed=0, orientation=orientation(UP, 5, 'parallel'))
    assert tuned.segmentation.n_planes == 2 and (_angles(tuned.segmentation, UP) <= 5).all()


@pytest.mark.parametrize('axis, angle, mode, why', [
    ((0, 0, 0), 10, 'parallel', 'normal_axis is (0, 0, 0)'),
    ((0, 0, 1), 91, 'parallel', 'axis_angle must be in [0, 90]'),
    ((0, 0, 1), -1, 'perpendicular', 'axis_angle must be in [0, 90]'),
    ((0, 0, 1), float('nan'), 'parallel', 'axis_angle must be in [0, 90]'),
    ((0, np.inf, 1), 10, 'parallel', 'normal_axis must be 3 finite numbers'),
    ((0, 1), 10, 'parallel', 'normal_axis must be 3 finite numbers'),
    ((0, 0, 1), 10, 'sideways', 'axis_mode must be one of none, parallel, perpendicular'),
])
def test_bad_constraints_are_refused_with_the_reason(axis, angle, mode, why):
    with pytest.raises(ValueError, match=why.replace('(', r'\(').replace(')', r'\)').replace('[', r'\[')):
        orientation(axis, angle, mode)


def test_mode_none_is_no_constraint_whatever_the_axis_and_the_api_refuses_another_type():
    assert orientation((0, 0, 0), 10, 'none') is None
    assert orientation((0, 0, 2), 10, AxisMode.PARALLEL).axis == (0.0, 0.0, 1.0)
    with pytest.raises(ValueError, match='orientation must be an Orientation'):
        pv.detect_planes(scenes.room(500, 0.0, seed=0).points, 0.02, orientation=(0, 0, 1))


def test_pipeline_config_refuses_a_mode_without_an_axis_and_detects_with_one():
    with pytest.raises(ValueError, match='normal_axis is'):
        PipelineConfig(axis_mode='parallel').validate()
    cfg = PipelineConfig(axis_mode='parallel', normal_axis_z=1.0, axis_angle=5.0, auto_tune=False, tolerance=0.02)
    from plane_validation.app.pipeline import FramePipeline
    result = FramePipeline(cfg.validate()).process(scenes.room(8000, 0.005, seed=2).points, 10**9)
    assert result.segmentation.n_planes == 2 and (_angles(result.segmentation, UP) <= 5).all()


def test_cli_options(tmp_path):
    cloud = tmp_path / 'room.npy'
    np.save(cloud, scenes.room(8000, 0.005, seed=2).points)
    run = subprocess.run([sys.executable, '-m', 'plane_validation', 'detect', str(cloud), '--tolerance', '0.02',
                          '--axis-mode', 'perpendicular', '--normal-axis-z', '1', '--axis-angle', '5', '--json'],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    import json
    planes = json.loads(run.stdout)['planes']
    assert len(planes) == 4
    bad = subprocess.run([sys.executable, '-m', 'plane_validation', 'detect', str(cloud), '--tolerance', '0.02',
                          '--axis-mode', 'parallel'], capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and 'normal_axis is (0, 0, 0)' in bad.stderr


def test_every_command_searches_with_the_table_s_search_params(tmp_path, monkeypatch):
    """detect, sweep and planes pass the same SearchParams (PipelineConfig.search) on: an option such as
    --ransac-points reaches the search from each command (planes used to drop it)."""
    from plane_validation.cli.run import main
    from plane_validation.core import ransac
    cloud = tmp_path / 'room.npy'
    np.save(cloud, scenes.room(3000, 0.005, seed=2).points)
    seen = []
    search = ransac.detect_planes

    def spy(*args, **kwargs):
        seen.append((kwargs['ransac_points'], kwargs['orientation']))
        return search(*args, **kwargs)
    monkeypatch.setattr(ransac, 'detect_planes', spy)
    for module in ('core.tuning', 'core.plane_count', 'app.detection'):
        monkeypatch.setattr(f'plane_validation.{module}.detect_planes', spy)
    options = ['--ransac-points', '2500', '--axis-mode', 'perpendicular', '--normal-axis-z', '1', '--json']
    for command in (['detect', str(cloud), '--tolerance', '0.02'], ['sweep', str(cloud), '--tolerances', '0.01:0.02:2'],
                    ['planes', str(cloud), '--tolerance', '0.02']):
        seen.clear()
        assert main(command + options) == 0, command
        assert seen and all(points == 2500 and o is not None and o.mode is AxisMode.PERPENDICULAR
                            for points, o in seen), (command, seen)
