"""PlaneTracker: ids kept while a surface stays in view, new ids for new surfaces."""
import numpy as np
import pytest

from plane_validation.app.tracking import PlaneTracker, TrackerConfig


def patch(origin, u, v, size=(1.0, 1.0), n=400, seed=0):
    """(n, 3) points on a rectangle and its (4,) coefficients."""
    rng = np.random.default_rng(seed)
    u, v = np.asarray(u, float), np.asarray(v, float)
    pts = np.asarray(origin, float) + rng.random((n, 1)) * size[0] * u + rng.random((n, 1)) * size[1] * v
    normal = np.cross(u, v)
    normal /= np.linalg.norm(normal)
    return pts, np.append(normal, -normal @ np.asarray(origin, float))


def frame(*patches):
    points = np.vstack([p for p, _ in patches])
    labels = np.concatenate([np.full(len(p), k, np.int32) for k, (p, _) in enumerate(patches)])
    return points, labels, np.array([c for _, c in patches])


X, Y, Z = (1, 0, 0), (0, 1, 0), (0, 0, 1)


def test_a_surface_keeps_its_id_when_found_in_another_order_and_a_new_one_gets_a_new_id():
    tracker = PlaneTracker()
    floor, wall = patch((0, 0, 0), X, Y, (3, 3)), patch((0, 3, 0), X, Z, (3, 2))
    assert tracker.update(*frame(floor, wall)) == (0, 1)
    moved_floor = patch((0.05, 0, 0.02), X, Y, (3, 3), seed=1)  # the camera moved 5 cm
    table = patch((1, 1, 0.75), X, Y, (1, 0.6), seed=2)  # parallel to the floor, 0.75 m above
    assert tracker.update(*frame(wall, table, moved_floor)) == (1, 2, 0)


def test_coplanar_patches_apart_are_different_surfaces():
    tracker = PlaneTracker()
    left = patch((0, 0, 0.75), X, Y, (1, 1))
    assert tracker.update(*frame(left)) == (0,)
    right = patch((3, 0, 0.75), X, Y, (1, 1), seed=3)  # same plane, 2 m away
    assert tracker.update(*frame(right)) == (1,)


def test_an_unseen_surface_keeps_its_id_for_max_missed_frames_and_empty_frames_only_age_tracks():
    tracker = PlaneTracker(TrackerConfig(max_missed=2))
    floor, wall = patch((0, 0, 0), X, Y, (3, 3)), patch((0, 3, 0), X, Z, (3, 2))
    assert tracker.update(*frame(floor, wall)) == (0, 1)
    assert tracker.update(*frame(floor)) == (0,)
    assert tracker.update(np.empty((0, 3)), np.empty(0, np.int32), np.empty((0, 4))) == ()
    assert tracker.track_ids == (0, 1)
    assert tracker.update(*frame(wall, floor)) == (1, 0)  # back after 2 frames unseen
    tracker.update(*frame(floor))
    tracker.update(*frame(floor))
    tracker.update(*frame(floor))  # 3 frames unseen: forgotten
    assert tracker.update(*frame(wall, floor)) == (2, 0)


def test_deterministic_and_reset():
    floor, wall = patch((0, 0, 0), X, Y, (3, 3)), patch((0, 3, 0), X, Z, (3, 2))
    runs = []
    for _ in range(2):
        tracker = PlaneTracker()
        runs.append([tracker.update(*f) for f in (frame(floor, wall), frame(wall), frame(floor, wall))])
    assert runs[0] == runs[1]
    tracker.reset()
    assert tracker.update(*frame(wall)) == (0,)


def test_a_bad_configuration_is_refused():
    with pytest.raises(ValueError, match='tracker'):
        TrackerConfig(min_overlap=0)


def test_the_pipeline_keeps_ids_through_an_empty_frame_a_malformed_frame_and_a_parameter_change():
    """A camera moving past the furnished room (small frames): the planes keep their ids."""
    import dataclasses

    from plane_validation.app.pipeline import ERROR, WARN, FramePipeline, PipelineConfig
    from plane_validation.core.scenes import depth_camera

    # a t at which the search finds the room's walls in every frame: the ids are under test (with depth_quadratic's
    # band along the rays, at 4-5 mm one frame's wall came back in pieces)
    pipeline = FramePipeline(PipelineConfig(auto_tune=False, tolerance=0.006, seed=1, noise_model='depth_quadratic'))
    frames = [depth_camera('room', width=160, height=120, eye=(4.6 - 0.05 * k, 0.4, 1.5), seed=k)
              for k in range(4)]
    first = pipeline.process(frames[0].points, 10**9, shape=frames[0].shape)
    assert first.n_planes >= 4 and first.plane_ids == tuple(range(first.n_planes))
    assert first.diagnostic.get('plane_ids') == ' '.join(map(str, first.plane_ids))
    assert pipeline.process(np.full((100, 3), np.nan), 2 * 10**9).level == WARN  # nothing valid: no planes
    assert pipeline.process(np.ones((5, 2)), 3 * 10**9).level == ERROR  # malformed
    pipeline.reconfigure(dataclasses.replace(pipeline.config, tolerance=0.007))
    later = [pipeline.process(f.points, (4 + k) * 10**9, shape=f.shape) for k, f in enumerate(frames[1:])]

    def big(result):  # id of each plane holding over 10 % of the points, by its normal
        return {tuple(np.round(p.normal, 1)): i for p, i, n in zip(result.segmentation.planes, result.plane_ids,
                                                                  result.plane_counts) if n > 0.1 * len(result.points)}
    for result in later:
        assert result.plane_ids == tuple(sorted(result.plane_ids))  # the planes come in id order
        assert big(result) == big(first)


def test_samples_from_the_planes_rows_are_those_grouped_from_the_labels():
    """The pipeline hands the tracker each plane's rows (a segmentation's inliers) instead of its labels: the
    samples, and so the ids, are the same."""
    from plane_validation.app.tracking import plane_samples
    rng = np.random.default_rng(3)
    points = rng.normal(size=(3000, 3))
    labels = rng.integers(-1, 4, len(points)).astype(np.int32)
    members = [np.flatnonzero(labels == k) for k in range(4)]
    for count in (5, 256, 2000):
        grouped = plane_samples(points, labels, 4, count)
        given = plane_samples(points, None, 4, count, members)
        assert all(np.array_equal(a, b) for a, b in zip(grouped, given))
    floor, wall = patch((0, 0, 0), X, Y), patch((0, 0, 0), X, Z, seed=1)
    tracker = PlaneTracker()
    for planes, ids in (((floor, wall), (0, 1)), ((wall, floor), (1, 0))):
        pts, labs, coeffs = frame(*planes)
        assert tracker.update(pts, None, coeffs, [np.flatnonzero(labs == k) for k in range(2)]) == ids
