"""Plane outlines for the markers: hull polygons and in-plane frames."""
import numpy as np
import pytest
from scipy.spatial import ConvexHull

import plane_validation as pv
from plane_validation import scenes
from plane_validation.core.geometry import hull_polygon, plane_basis, plane_outlines


def polygon_area(xy: np.ndarray) -> float:
    x, y = xy
    return 0.5 * float(x @ np.roll(y, -1) - y @ np.roll(x, -1))


def test_small_sets_get_the_exact_hull_counter_clockwise():
    pts = np.random.default_rng(1).normal(size=(2, 500))
    hull = hull_polygon(pts)
    assert sorted(hull) == sorted(ConvexHull(pts.T).vertices)
    assert polygon_area(pts[:, hull]) > 0


def test_large_sets_get_a_hull_touching_the_extremes():
    pts = np.random.default_rng(2).random((2, 200_000))
    hull = hull_polygon(pts)
    exact = ConvexHull(pts.T)
    assert polygon_area(pts[:, hull]) >= 0.98 * exact.volume  # 2-D "volume" is the area
    for axis in range(2):
        assert pts[axis, hull].max() == pts[axis].max() and pts[axis, hull].min() == pts[axis].min()


@pytest.mark.parametrize('pts, expected', [(np.zeros((2, 0)), 0), (np.ones((2, 2)), 2),
                                           (np.vstack([np.arange(100.0), np.zeros(100)]), 2)])
def test_degenerate_sets(pts, expected):
    assert len(hull_polygon(pts)) == expected


def test_basis_is_a_rotation_with_the_normal_as_z():
    for normal in np.random.default_rng(3).normal(size=(20, 3)):
        normal /= np.linalg.norm(normal)
        rot = plane_basis(normal)
        np.testing.assert_allclose(rot.T @ rot, np.eye(3), atol=1e-12)
        assert np.linalg.det(rot) == pytest.approx(1.0)
        np.testing.assert_allclose(rot[:, 2], normal)


def test_outlines_lie_in_their_planes():
    scene = scenes.cube(6000, 0.0, seed=1)
    seg = pv.detect_planes(scene.points, 0.5, seed=0)
    outlines = plane_outlines(scene.points, seg.labels, seg)
    assert len(outlines) == seg.n_planes == 6
    for k, (plane, outline) in enumerate(zip(seg.planes, outlines)):
        np.testing.assert_allclose(outline.centroid, scene.points[seg.labels == k].mean(axis=0))
        assert np.abs(outline.corners @ plane.normal + plane.offset).max() < 1e-9
        assert outline.extent == pytest.approx(100.0, rel=0.05)  # the cube's side


def test_outlines_are_the_hull_polygon_of_the_in_plane_coordinates():
    # plane_outlines rotates only the hull's candidates of a large plane; the polygon is hull_polygon's of all
    scene = scenes.cube(30000, 0.3, seed=4)
    seg = pv.detect_planes(scene.points, 0.5, seed=0)
    for k, outline in enumerate(plane_outlines(scene.points, seg.labels, seg)):
        members = scene.points[seg.labels == k]
        axes = outline.rotation[:, :2]
        local = axes.T @ (members - outline.centroid).T
        assert local.shape[1] > 2048  # above HULL_POINTS: the candidates' path
        np.testing.assert_allclose(outline.corners, outline.centroid + (axes @ local[:, hull_polygon(local)]).T,
                                   atol=1e-9)


def test_collinear_plane_points_get_their_length_as_extent():
    # a plane z = 0 whose points lie on one line along x (a scan line), below and above HULL_POINTS
    for n in (200, 5000):
        points = np.column_stack([np.linspace(0, 2, n), np.zeros(n), np.zeros(n)])
        labels = np.zeros(n, np.int32)
        seg = pv.Segmentation(labels=labels, planes=(pv.Plane(np.array([0.0, 0, 1]), 0.0, np.arange(n), 0.0),),
                              tolerance=0.01, n_valid=n, reason='')
        outline = plane_outlines(points, labels, seg)[0]
        assert outline.extent == pytest.approx(2.0)


@pytest.mark.parametrize('make', [
    lambda: scenes.depth_camera('room', quantum_1m=0.0), lambda: scenes.depth_camera('attic'),
    lambda: scenes.depth_camera('room', width=0), lambda: scenes.lidar(sigma=-0.01),
    lambda: scenes.sphere(noise=-1.0), lambda: scenes.sphere(radius=0.0), lambda: scenes.corner(noise=-1.0)])
def test_scene_parameters_out_of_range_raise(make):
    with pytest.raises(ValueError):
        make()


def test_a_scene_of_outliers_only_lies_in_the_box_of_its_planes():
    scene = scenes.cube(100, outlier_fraction=0.999, seed=0)  # 100 outliers, no plane point
    assert scene.points.shape == (100, 3) and np.all(scene.labels == -1)
    assert scene.points.min() >= 0 and scene.points.max() <= 100  # the cube's 100-unit box


def test_a_lidar_scan_shuffled_is_laid_out_as_the_drivers_ring_image():
    from plane_validation.core.geometry import ring_image
    organized = scenes.lidar(**scenes.VLP16_ROOM, seed=1, organized=True)
    scan = scenes.lidar(**scenes.VLP16_ROOM, seed=1)
    order = np.random.default_rng(0).permutation(len(scan.points))
    image, shape, pixel = ring_image(scan.points[order], scan.rings[order])
    assert shape == organized.shape == (16, 1800)
    rows, cols = np.divmod(np.flatnonzero(np.isfinite(organized.points).all(axis=1)), 1800)
    expected = ((15 - rows) * 1800 + cols)[order]  # the top ring first
    np.testing.assert_array_equal(pixel, expected)
    np.testing.assert_array_equal(image[pixel], scan.points[order])
    # a 90-degree crop keeps the scan's azimuth step: the same 1800 columns, three quarters of them empty
    front = scan.points[:, 0] > np.abs(scan.points[:, 1])
    assert ring_image(scan.points[front], scan.rings[front])[1] == (16, 1800)


def test_points_that_form_no_ring_image_are_refused_with_a_reason():
    from plane_validation.core.geometry import ring_image
    scan = scenes.lidar(**scenes.VLP16_ROOM, seed=1)
    rng = np.random.default_rng(0)
    two_rings = scan.rings < 2
    kept = rng.random(len(scan.points)) < 0.3  # thinned at random (a voxel grid that keeps the ring field)
    dual = np.concatenate([np.arange(len(scan.points)), np.flatnonzero(rng.random(len(scan.points)) < 0.1)])
    cases = [
        (scan.points[two_rings], scan.rings[two_rings], '2 rings'),
        (scan.points, scan.rings[:-1], 'not one integer per point'),
        (scan.points, scan.rings + 0.5, 'not whole numbers'),
        (scan.points, scan.rings > 3, 'not numbers'),
        (scan.points, rng.integers(0, 65536, len(scan.points)), 'rings \\(need 3 to 256\\)'),  # no beam numbers
        (scan.points, rng.integers(0, 16, len(scan.points)), 'elevations overlap'),  # numbering something else
        (scan.points[kept], scan.rings[kept], 'one azimuth step'),
        (scan.points[dual] * np.where(np.arange(len(dual)) < len(scan.points), 1.0, 1.2)[:, None], scan.rings[dual],
         'share a pixel'),  # dual returns: a second, farther return along 10 % of the beams
    ]
    for points, ring, why in cases:
        with pytest.raises(ValueError, match=why):
            ring_image(points, ring)
    whole = ring_image(scan.points, scan.rings.astype(np.float32))  # as some drivers write the field
    assert all(np.array_equal(a, b) for a, b in zip(whole, ring_image(scan.points, scan.rings), strict=True))
    every_other = np.arange(len(scan.points)) % 2 == 0  # thinned evenly: an image of half the columns
    assert ring_image(scan.points[every_other], scan.rings[every_other])[1] == (16, 900)
    # beams whose origins lie 14-20 cm above the frame's (an HDL-64): seen from it, a ring's elevation varies
    # with range near the walls, yet the scan is an image (refused before, though as good as the graph)
    lifted = scan.points + np.where(scan.rings % 2 == 0, 0.20, 0.14)[:, None] * [0.0, 0.0, 1.0]
    assert ring_image(lifted, scan.rings)[1] == (16, 1800)


def test_the_cross_product_of_the_plane_basis_equals_numpys():
    from plane_validation.core.geometry import _cross
    rng = np.random.default_rng(3)
    for a, b in zip(rng.normal(size=(2000, 3)) * rng.uniform(1e-6, 1e6, (2000, 1)), rng.normal(size=(2000, 3))):
        np.testing.assert_array_equal(_cross(a, b), np.cross(a, b))
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    rotation = plane_basis(normal)
    np.testing.assert_allclose(rotation.T @ rotation, np.eye(3), atol=1e-12)
    assert np.linalg.det(rotation) > 0 and np.array_equal(rotation[:, 2], normal)


def test_the_colours_of_some_ids_are_those_of_the_whole_palette():
    from plane_validation.core.geometry import id_colors, plane_colors
    ids = np.array([7, 0, 3, 3, 1200])
    np.testing.assert_array_equal(id_colors(ids), plane_colors(1201)[ids])
    assert id_colors(np.zeros(0, np.int64)).shape == plane_colors(0).shape == (0, 3)
