"""The plane silhouette (PS): a point-to-plane validity index."""
import numpy as np
import pytest

from plane_validation import detect_planes, scenes, validity_indices
from plane_validation.core.plane_silhouette import plane_silhouette


def test_true_planes_score_high_and_a_noise_level_tolerance_beats_slivers():
    scene = scenes.cube(6000, 1.0, scale=0.01, seed=0)  # e = 1 cm
    truth = plane_silhouette(scene.points, scene.labels, seed=0)
    slivers = detect_planes(scene.points, 0.002, seed=0, max_planes=12, min_inliers=0.01)
    right = detect_planes(scene.points, 0.02, seed=0, max_planes=12, min_inliers=0.01)
    assert truth > 0.85
    good, bad = (plane_silhouette(scene.points, seg.labels, seed=0) for seg in (right, slivers))
    assert good > bad + 0.3


def test_strips_of_a_crossing_surface_are_punished():
    """Giving a wall's points near the floor to the floor (as an infinite plane at large t does)
    lowers PS: those points lie on the wall region, b_i ~ 0."""
    scene = scenes.corner(3000, 0.0, scale=0.01, seed=1)
    labels = scene.labels.copy()
    floor = np.argmax(np.abs(scene.planes[:, 2]))  # the plane z = const
    near = (np.abs(scene.points[:, 2] - np.median(scene.points[scene.labels == floor, 2])) < 0.1)
    labels[near] = floor
    assert plane_silhouette(scene.points, labels, seed=0) < plane_silhouette(scene.points, scene.labels, seed=0) - 0.05


def test_coverage_and_edge_cases():
    scene = scenes.room(5000, 0.005, seed=2)
    full = plane_silhouette(scene.points, scene.labels, seed=0)
    half = scene.labels.copy()
    half[: len(half) // 2] = -1
    assert plane_silhouette(scene.points, half, seed=0) < full
    assert plane_silhouette(scene.points, np.full(len(scene.points), -1), seed=0) == 0.0
    pts = scene.points.copy()
    pts[:10] = np.nan
    value = plane_silhouette(pts, scene.labels, seed=3)
    assert -1 <= value <= 1 and value == plane_silhouette(pts, scene.labels, seed=3)  # seeded: deterministic
    with pytest.raises(ValueError):
        plane_silhouette(scene.points, scene.labels[:-1])
    # any integer ids: only their order matters (no table as long as the largest id)
    huge = np.where(scene.labels >= 0, scene.labels.astype(np.int64) * 2**50 + 7, -1)
    assert plane_silhouette(scene.points, huge, seed=0) == full


def test_reported_by_validity_indices():
    scene = scenes.corner(2000, 1.0, scale=0.01, seed=4)
    scores = validity_indices(scene.points, scene.labels, seed=0)
    assert scores.plane_silhouette > 0.8 and 'plane_silhouette' in scores.as_dict()


def test_without_a_sample_size_every_assigned_point_counts():
    """20,000 points in six regions of at most FRAME_POINTS each: nothing is drawn at random, so the
    value cannot depend on the seed (it did while the mean ran over a FRAME_SAMPLE subset)."""
    from plane_validation.core.plane_silhouette import FRAME_POINTS, FRAME_SAMPLE
    scene = scenes.cube(20000, 0.5, seed=4)
    assert len(scene.points) > FRAME_SAMPLE and np.bincount(scene.labels[scene.labels >= 0]).max() <= FRAME_POINTS
    values = {plane_silhouette(scene.points, scene.labels, sample_size=None, seed=s) for s in range(3)}
    assert len(values) == 1 and 0.5 < values.pop() <= 1


def test_polygon_distances_against_the_edges_sampled_densely():
    from plane_validation.core.plane_silhouette import polygon_distances
    rng = np.random.default_rng(4)
    angles = np.sort(rng.uniform(0, 2 * np.pi, 9))
    polygon = np.column_stack([np.cos(angles), 0.5 * np.sin(angles)])  # convex, counter-clockwise
    p = rng.uniform(-2, 2, (400, 2))
    ends = np.roll(polygon, -1, axis=0)
    f = np.linspace(0, 1, 2001)[:, None, None]
    boundary = (polygon + f * (ends - polygon)).reshape(-1, 2)
    nearest = np.sqrt(((p[:, None] - boundary[None]) ** 2).sum(axis=2)).min(axis=1)
    cross = [(b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0]) for a, b in zip(polygon, ends) for q in p]
    inside = (np.array(cross).reshape(len(polygon), len(p)) >= 0).all(axis=0)
    got = polygon_distances(p, polygon)
    assert inside.any() and (~inside).any()
    assert np.all(got[inside] == 0) and np.allclose(got[~inside], nearest[~inside], atol=2e-3)


def test_hull_silhouette_is_ps_with_tighter_extents():
    """The same sample as PS with a seed: never lower; about the same on rectangles (a room's walls), where hull and
    box agree; higher on a hip roof, whose triangles' boxes reach over the faces beside them."""
    from plane_validation.core.plane_silhouette import hull_silhouette
    room = scenes.room(5000, 0.005, seed=2)
    ps, hull = plane_silhouette(room.points, room.labels, seed=0), hull_silhouette(room.points, room.labels, seed=0)
    assert ps <= hull <= ps + 0.02
    rng = np.random.default_rng(1)
    x, y = rng.uniform(-6, 6, 3000), rng.uniform(-4, 4, 3000)
    rise = np.stack([4 - y, 4 + y, 6 - x, 6 + x], axis=1)
    face = np.argmin(rise, axis=1)
    roof = np.column_stack([x, y, 0.035 * rise[np.arange(3000), face] + rng.normal(0, 0.04, 3000)])  # 2 degrees
    ps, hull = plane_silhouette(roof, face, seed=0), hull_silhouette(roof, face, seed=0)
    assert hull > ps + 0.15, (ps, hull)
    assert hull_silhouette(roof, np.full(3000, -1)) == 0.0
    with pytest.raises(ValueError, match='labels for'):
        hull_silhouette(roof, face[:-1])
