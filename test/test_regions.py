"""Planes as connected regions (detect_planes(connectivity=True), the default)."""
import hashlib
import re

import numpy as np
import pytest

import plane_validation as pv
from plane_validation import scenes
from plane_validation.core.scoring import segmentation_quality


def _wall_with_box(holes: float = 0.1, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """An organized 120 x 160 depth image: a wall 2 m away and, in the middle, the front of a box
    8 cm in front of it (a depth jump); ``holes`` of the pixels are NaN. Returns points, truth."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:120, 0:160]
    x, y = (u - 80) / 150.0, (v - 60) / 150.0
    box = (np.abs(u - 80) < 30) & (np.abs(v - 60) < 25)
    depth = np.where(box, 1.92, 2.0) + rng.normal(0, 0.002, box.shape)
    pts = np.stack([x * depth, y * depth, depth], -1).reshape(-1, 3)
    pts[rng.random(len(pts)) < holes] = np.nan
    return pts, box.reshape(-1).astype(np.int32)


def test_organized_depth_jump_separates_a_box_front_from_the_wall_behind():
    pts, truth = _wall_with_box()
    regions = pv.detect_planes(pts, 0.1, seed=1, shape=(120, 160), min_inliers=200)
    infinite = pv.detect_planes(pts, 0.1, seed=1, connectivity=False, min_inliers=200)
    q = segmentation_quality(regions.labels, truth)
    assert regions.n_planes == 2 and q.correct == 2 and q.f1 > 0.93, q
    # t = 10 cm: the infinite plane of the wall also takes the box front 8 cm before it
    assert infinite.n_planes == 1 and segmentation_quality(infinite.labels, truth).correct < 2
    assert np.all(regions.labels[np.isnan(pts[:, 0])] == -1)  # holes stay unassigned


def test_an_image_with_points_at_the_sensor_gives_no_numpy_warning():
    """An outside probe: a pixel at (0, 0, 0) (range 0) leaked 'invalid value encountered in divide'."""
    import warnings
    scene = scenes.depth_camera('room', width=80, height=60, seed=0)
    points = scene.points.copy()
    points[[0, 79]] = 0.0  # both ends of the first row: the seam test divides by their range
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        seg = pv.detect_planes(points, 0.03, seed=0, shape=(60, 80))
    assert seg.n_planes >= 4


def test_coplanar_separate_objects_are_separate_planes_in_an_unorganized_cloud():
    rng = np.random.default_rng(2)
    tops = [np.column_stack([rng.uniform(x0, x0 + 0.4, 3000), rng.uniform(0, 0.4, 3000), rng.normal(0, 0.002, 3000)])
            for x0 in (0.0, 1.0)]  # two box tops at the same height, 0.6 m apart
    pts = np.vstack(tops)
    regions = pv.detect_planes(pts, 0.01, seed=0, min_inliers=500)
    infinite = pv.detect_planes(pts, 0.01, seed=0, min_inliers=500, connectivity=False)
    assert infinite.n_planes == 1 and regions.n_planes == 2
    q = segmentation_quality(regions.labels, np.repeat([0, 1], 3000))
    assert q.correct == 2
    a, b = regions.planes
    assert abs(abs(a.normal @ b.normal) - 1) < 1e-4 and abs(abs(a.offset) - abs(b.offset)) < 0.002  # coplanar


def test_every_tread_and_riser_at_a_tolerance_of_three_tenths_of_the_rise():
    scene = scenes.stairs(16000, 0.003, steps=4, rise=0.17, seed=3)
    seg = pv.detect_planes(scene.points, 0.3 * 0.17, seed=0, max_planes=12, min_inliers=0.02)
    q = segmentation_quality(seg.labels, scene.labels)
    assert q.correct == scene.n_planes == 8, q
    infinite = pv.detect_planes(scene.points, 0.3 * 0.17, seed=0, max_planes=12, min_inliers=0.02,
                                connectivity=False)
    assert segmentation_quality(infinite.labels, scene.labels).correct < 8  # the slanted plane wins there


def test_depth_camera_frame_with_holes_and_grazing_losses():
    scene = scenes.depth_camera('table', width=160, height=120, seed=0)
    assert scene.shape == (120, 160) and np.isnan(scene.points[:, 0]).any()
    seg = pv.detect_planes(scene.points, 0.01, seed=0, shape=scene.shape, max_planes=10, min_inliers=50)
    q = segmentation_quality(seg.labels, scene.labels)
    assert q.correct >= 4 and q.f1 > 0.9, q


def test_lidar_scene_is_unorganized_and_its_planes_are_found():
    scene = scenes.lidar(rings=32, azimuths=900, seed=0)
    assert scene.shape is None
    seg = pv.detect_planes(scene.points, 0.05, seed=0, max_planes=10, min_inliers=100)
    q = segmentation_quality(seg.labels, scene.labels)
    assert q.correct >= 4 and q.f1 > 0.9, q


def test_without_connectivity_the_result_is_the_paper_method_of_before():
    """Digests of (labels, coefficients) made by the implementation before connected regions
    existed (commit 0289458), for the same scenes, tolerances and seeds."""
    cases = [(scenes.corner(3000, 2.5, seed=1).points, 3.0, '3bdba61ccefb1772'),
             (scenes.boxes(60000, seed=2).points, 0.02, '8796fb7f58b7e617'),
             (scenes.stairs(8000, 0.004, seed=3).points, 0.03, '390857867ff10b2b')]
    for points, t, digest in cases:
        seg = pv.detect_planes(points, t, seed=5, ransac_points=20000, connectivity=False)
        got = hashlib.sha256(seg.labels.tobytes() + seg.coefficients.round(9).tobytes()).hexdigest()[:16]
        assert got == digest


def test_regions_are_seeded_and_shape_is_checked():
    pts, _ = _wall_with_box()
    a = pv.detect_planes(pts, 0.01, seed=4, shape=(120, 160))
    b = pv.detect_planes(pts, 0.01, seed=4, shape=(120, 160))
    assert np.array_equal(a.labels, b.labels)
    with pytest.raises(ValueError, match='does not match'):
        pv.detect_planes(pts, 0.01, shape=(100, 100))
    with pytest.raises(ValueError, match='shape must be'):
        pv.detect_planes(pts, 0.01, shape='120x160')


def test_large_organized_frame_is_searched_on_a_sub_grid_and_fully_labelled():
    scene = scenes.depth_camera('room', seed=2)  # 640 x 480
    seg = pv.detect_planes(scene.points, 0.06, seed=0, shape=scene.shape, max_planes=12, min_inliers=0.005)
    assert 'in a sample of' in seg.reason or seg.n_planes == 12
    q = segmentation_quality(seg.labels, scene.labels)
    assert q.correct >= 5 and q.f1 > 0.9, q


def test_grid_points_sets_the_sub_grid_of_an_image_and_ransac_points_does_not():
    from plane_validation.core.ransac import search_graph
    scene = scenes.depth_camera('table', seed=1)  # 640 x 480, ~190,000 valid pixels
    valid = int(np.isfinite(scene.points).all(axis=1).sum())
    steps = {g: search_graph(scene.points, scene.shape, grid_points=g).step for g in (None, 60000, 20000, 5000)}
    assert steps == {None: 1, 60000: 2, 20000: 4, 5000: 7}, steps
    assert all(steps[g] == np.ceil(np.sqrt(valid / g)) for g in (60000, 20000, 5000))
    assert search_graph(scene.points, scene.shape, ransac_points=1000).step == 3  # the default grid_points
    graph = search_graph(scene.points, scene.shape, grid_points=20000)
    assert graph.grid_points == 20000 and graph.neighbours.shape == (120, 160)  # every 4th row and column
    coarse = pv.detect_planes(scene.points, 0.03, seed=0, shape=scene.shape, grid_points=20000)
    assert np.array_equal(coarse.labels, pv.detect_planes(scene.points, 0.03, seed=0, shape=scene.shape,
                                                          grid_points=20000, graph=graph).labels)
    q = segmentation_quality(coarse.labels, scene.labels)
    assert q.correct >= 5 and q.f1 > 0.95, q  # every pixel labelled from the coarser search
    with pytest.raises(ValueError, match='grid_points'):
        pv.detect_planes(scene.points, 0.03, shape=scene.shape, grid_points=2.5)
    with pytest.raises(ValueError, match='grid_points'):
        search_graph(scene.points, scene.shape, grid_points=0)


def test_a_prebuilt_search_graph_gives_the_same_planes_as_building_it_per_call():
    from plane_validation.core.ransac import search_graph
    pts, _ = _wall_with_box()
    unorganized = np.vstack([pts[np.isfinite(pts).all(axis=1)], pts[:5] + 10])  # NaN rows and far points too
    for cloud, shape in ((pts, (120, 160)), (unorganized, None)):
        graph = search_graph(cloud, shape)
        for t in (0.004, 0.02, 0.1):
            own = pv.detect_planes(cloud, t, seed=3, shape=shape, min_inliers=200)
            shared = pv.detect_planes(cloud, t, seed=3, shape=shape, min_inliers=200, graph=graph)
            assert np.array_equal(own.labels, shared.labels) and own.n_planes == shared.n_planes >= 1
    assert search_graph(unorganized, ransac_points=1000) is None  # it would be a random sample: not fixed
    # a sampled graph drawn from the generator detect_planes would draw it from (tune_tolerance builds
    # the final detection's graph that way while its sweep runs)
    rng = np.random.default_rng(3)
    sampled = search_graph(unorganized, ransac_points=1000, rng=rng)
    shared = pv.detect_planes(unorganized, 0.02, seed=rng, min_inliers=20, ransac_points=1000, graph=sampled)
    own = pv.detect_planes(unorganized, 0.02, seed=3, min_inliers=20, ransac_points=1000)
    assert np.array_equal(own.labels, shared.labels) and own.n_planes >= 1
    with pytest.raises(ValueError, match='built for'):
        pv.detect_planes(pts[:-1], 0.01, graph=search_graph(pts, (120, 160)))


def test_a_search_graph_of_another_layout_is_refused():
    from plane_validation.core.ransac import search_graph
    pts, _ = _wall_with_box()
    graph = search_graph(pts, (120, 160))
    for kwargs in (dict(), dict(shape=(160, 120)), dict(shape=(120, 160), ransac_points=1000),
                   dict(shape=(120, 160), grid_points=5000)):
        with pytest.raises(ValueError, match='built for'):
            pv.detect_planes(pts, 0.01, graph=graph, **kwargs)
    other = pts.copy()
    other[:50] = np.nan  # same size, other holes
    with pytest.raises(ValueError, match='other valid'):
        pv.detect_planes(other, 0.01, shape=(120, 160), graph=graph)


def test_nearby_points_lie_in_the_window_or_at_the_end_of_a_short_walk():
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import shortest_path

    from plane_validation.core.regions import graph_neighbours
    from plane_validation.core.search.grid_build import grid_neighbours
    from plane_validation.core.search.neighbours import NEARBY_SCALES
    rng = np.random.default_rng(0)
    pts, _ = _wall_with_box()
    image, valid = pts.reshape(120, 160, 3), np.isfinite(pts).all(axis=1).reshape(120, 160)
    grid = grid_neighbours(image, valid)
    nodes = rng.integers(0, grid.n, 5000)
    near = grid.nearby(nodes, rng)
    assert (near >= -1).all() and (near >= 0).mean() > 0.8  # -1: the window fell on a hole or outside
    r0, c0 = np.divmod(grid.pixel[nodes], 160)
    r1, c1 = np.divmod(grid.pixel[near[near >= 0]], 160)
    assert np.maximum(np.abs(r1 - r0[near >= 0]), np.abs(c1 - c0[near >= 0])).max() == max(NEARBY_SCALES)
    cloud = pts[np.isfinite(pts).all(axis=1)][:3000]
    graph = graph_neighbours(cloud)
    indptr, indices = graph.adjacency
    hops = shortest_path(csr_matrix((np.ones(len(indices)), indices, indptr), shape=(graph.n, graph.n)),
                         unweighted=True, indices=np.arange(50))
    for start in range(50):
        ends = graph.nearby(np.full(200, start), rng)
        assert hops[start, ends].max() <= max(NEARBY_SCALES) and (ends != start).any()
    from plane_validation.core.regions import _neighbours
    lone = _neighbours(5, np.array([[0, 1], [1, 2]]), None)  # points 3 and 4 have no neighbour
    ends = lone.nearby(np.array([3, 4, 0, 3] * 50), rng)
    assert (ends.reshape(50, 4)[:, [0, 1, 3]] == [3, 4, 3]).all() and set(ends[2::4]) <= {0, 1, 2}


def test_sampling_nearby_points_finds_small_planes_that_global_triples_miss(monkeypatch):
    """60 tiles of 100 points, 20 x 20 cm, randomly turned, in as many uniform clutter points: a
    budget of 200 hypotheses per plane finds every tile only with local triples (LOCAL_SHARE)."""
    from plane_validation.core.search import hypotheses
    rng = np.random.default_rng(0)
    pts, truth = [], []
    for j in range(60):
        normal = rng.normal(size=3)
        basis = np.linalg.svd((normal / np.linalg.norm(normal))[None])[2][1:]
        pts.append(rng.uniform(0, 3, 3) + rng.uniform(-0.1, 0.1, (100, 2)) @ basis)
        truth.append(np.full(100, j))
    pts, truth = np.vstack(pts + [rng.uniform(0, 3, (6000, 3))]), np.concatenate(truth + [np.full(6000, -1)])
    found, local = {}, hypotheses.LOCAL_SHARE
    for share in (local, 0.0):
        monkeypatch.setattr(hypotheses, 'LOCAL_SHARE', share)
        seg = pv.detect_planes(pts, 0.004, max_planes=70, min_inliers=50, max_iterations=200, seed=0)
        found[share] = segmentation_quality(seg.labels, truth).correct
    assert local > 0 and found[local] >= 58 and found[0.0] < found[local], found


def test_a_graph_pickles_without_its_caches():
    """A parallel sweep pickles the search graph for its workers while this process, searching too, fills in the
    graph's cached properties; pickling the live __dict__ failed ("dictionary changed size during iteration")."""
    import pickle

    from plane_validation.core.ransac import search_graph
    graph = search_graph(scenes.cube(3000, 1.0, seed=1).points, None, None)
    warm = graph.neighbours
    expected = warm.components(np.arange(warm.n) % 10 == 0)  # a small mask: fills edge_rows
    assert 'edge_rows' in warm.__dict__
    copy = pickle.loads(pickle.dumps(graph)).neighbours
    assert 'edge_rows' not in copy.__dict__
    got = copy.components(np.arange(copy.n) % 10 == 0)
    np.testing.assert_array_equal(got[0], expected[0])
    assert got[1] == expected[1]


def test_touching_regions_of_one_surface_are_merged_and_others_are_not():
    from plane_validation.core.regions import graph_neighbours
    from plane_validation.core.search.connected import _merge_coplanar
    from plane_validation.core.search.fit import fit_columns
    rng = np.random.default_rng(1)
    floor = np.column_stack([rng.uniform(0, 2, 4000), rng.uniform(0, 1, 4000), rng.normal(0, 0.002, 4000)])
    wall = np.column_stack([rng.uniform(0, 2, 2000), np.full(2000, 1.0) + rng.normal(0, 0.002, 2000),
                            rng.uniform(0, 1, 2000)])
    apart = floor[:1000] + [3.0, 0, 0]  # coplanar with the floor, 1 m away
    pts = np.vstack([floor, wall, apart])
    region = np.concatenate([np.where(floor[:, 0] < 1, 0, 2), np.full(2000, 1), np.full(1000, 3)])
    search = np.ascontiguousarray(pts.T)
    found = [fit_columns(np.compress(region == j, search, axis=1)) for j in range(4)]
    merged, planes = _merge_coplanar(search, region.copy(), found, 0.01, graph_neighbours(pts))
    assert len(planes) == 3  # the two floor halves are one region; the wall and the far patch stay apart
    assert np.array_equal(merged, np.concatenate([np.zeros(4000), np.ones(2000), np.full(1000, 2)]))
    assert abs(abs(planes[0][0][2]) - 1) < 1e-3


def _chain(n: int):
    """The graph of n points joined one after another (0-1, 1-2, ...)."""
    from plane_validation.core.regions import _neighbours
    return _neighbours(n, np.column_stack([np.arange(n - 1), np.arange(1, n)]), None)


def test_border_settling_breaks_exact_ties_towards_the_smaller_index_neighbour():
    # a point between two regions whose planes are exactly as far: the graph neighbour with the
    # smaller index wins (as before border settling looked only at changed points)
    from plane_validation.core.search.connected import _compete
    nb = _chain(3)
    search = np.array([[-1.0, 0.0, 1.0], [0.0, 0.5, 1.0], [0.0, 0.0, 0.0]])  # y = 0, 0.5, 1
    planes = [(np.array([0.0, 1.0, 0.0]), 0.0), (np.array([0.0, 1.0, 0.0]), -1.0)]  # y = 0 and y = 1
    origin = np.zeros(3)
    assert _compete(search, np.array([0, -1, 1]), planes, 0.6, nb, origin).tolist() == [0, 0, 1]
    assert _compete(search, np.array([1, -1, 0]), planes[::-1], 0.6, nb, origin).tolist() == [1, 1, 0]


def test_border_settling_compares_planes_along_the_viewing_ray():
    # a wall 2 m ahead of the sensor (y = 2) and a side face (x = 0.3) the rays graze: a wall point 2 cm
    # off the wall near the corner is 1 cm from the side face in meters, but its ray meets the wall first
    from plane_validation.core.search.connected import _compete
    nb = _chain(3)
    search = np.array([[0.3, 1.5, 0.0], [0.31, 2.02, 0.0], [0.8, 2.0, 0.0]]).T  # side, the wall point, wall
    planes = [(np.array([1.0, 0.0, 0.0]), -0.3), (np.array([0.0, 1.0, 0.0]), -2.0)]  # side, wall
    assert _compete(search, np.array([0, 0, 1]), planes, 0.05, nb, np.zeros(3)).tolist() == [0, 1, 1]
    # seen from straight above the corner, both faces are grazed alike: the nearer in meters, the side face
    assert _compete(search, np.array([0, 1, 1]), planes, 0.05, nb, np.array([0.3, 2.0, 5.0])).tolist() == [0, 0, 1]


@pytest.mark.parametrize('organized', [True, False])
def test_skipping_hypotheses_by_their_coherent_inliers_keeps_the_same_planes(monkeypatch, organized):
    """best_region labels a hypothesis only when its inliers with agreeing normals could beat the
    region found so far: the same planes as labelling every hypothesis."""
    from plane_validation.core.search import hypotheses, neighbours_graph, neighbours_grid
    from plane_validation.core.search.neighbours import Remaining
    if organized:
        scene = scenes.depth_camera('table', width=160, height=120, seed=3)
        points, shape, t = scene.points, (120, 160), 0.02
    else:
        scene = scenes.room(6000, 0.01, seed=3)
        points, shape, t = scene.points, None, 0.03
    calls = []
    module, name = (neighbours_grid, 'grid_region') if organized else (neighbours_graph, 'graph_region')
    compiled = getattr(module, name)  # each region comes from one compiled call
    monkeypatch.setattr(module, name, lambda *args: calls.append(1) or compiled(*args))
    # the generic loop, labelling through the call counted (the kernels that run it are tested alike)
    if organized:
        monkeypatch.setattr(neighbours_grid._GridRemaining, 'best', Remaining.best)
        monkeypatch.setattr(neighbours_grid._GridRemaining, 'refitted', Remaining.refitted)
    else:
        monkeypatch.setattr(neighbours_graph._GraphRemaining, 'refitted', Remaining.refitted)
    fast = pv.detect_planes(points, t, seed=5, shape=shape, max_planes=8)
    n_fast, calls[:] = len(calls), []
    best_region = hypotheses.best_region
    # no point normals
    monkeypatch.setattr(hypotheses, 'best_region', lambda *args, **kw: best_region(*args[:5], **kw))
    full = pv.detect_planes(points, t, seed=5, shape=shape, max_planes=8)
    assert fast.n_planes >= 3 and np.array_equal(fast.labels, full.labels)
    coefficients = [np.array([p.coefficients for p in seg.planes]) for seg in (fast, full)]
    assert np.array_equal(*coefficients)
    assert n_fast < len(calls)  # and fewer labellings


def test_integer_points_have_a_graph():
    from plane_validation.core.regions import graph_neighbours
    pts = np.random.default_rng(0).integers(0, 100, size=(500, 3))
    assert np.array_equal(graph_neighbours(pts).edges, graph_neighbours(pts.astype(float)).edges)


def test_exact_copies_of_points_do_not_split_a_plane():
    from plane_validation.core.regions import graph_neighbours
    rng = np.random.default_rng(1)
    floor = np.column_stack([rng.uniform(-1, 1, (200, 2)), np.zeros(200)])
    stacked = np.repeat(floor, 12, axis=0)  # twelve scans of a static scene, stacked
    seg = pv.detect_planes(stacked, 0.01, seed=0)
    assert seg.n_planes == 1 and np.all(seg.labels == 0)
    graph = graph_neighbours(stacked)
    assert np.array_equal(graph.normals, np.repeat(graph_neighbours(floor).normals, 12, axis=0))
    # every copy is joined to the first point at its place, and the distinct points as without copies
    first = np.arange(0, len(stacked), 12)
    edges = {tuple(e) for e in graph.edges.tolist()}
    assert all((f, f + c) in edges for f in first for c in range(1, 12))
    assert {(a // 12, b // 12) for a, b in edges if a % 12 == 0 and b % 12 == 0} == \
        {tuple(e) for e in graph_neighbours(floor).edges.tolist()}
    # half the points copies of one: still one plane
    spot = np.vstack([floor[:50], np.repeat(floor[:1], 50, axis=0)])
    assert pv.detect_planes(spot, 0.01, seed=0, min_inliers=10).n_planes == 1


@pytest.mark.parametrize('shape', [(3000, 1), (1, 3000), (2, 1500)])
def test_an_image_too_thin_for_a_grid_is_searched_as_an_unorganized_cloud(shape):
    rng = np.random.default_rng(0)
    floor = np.column_stack([rng.uniform(0, 4, (3000, 2)), rng.normal(0, 0.002, 3000)])
    thin = pv.detect_planes(floor, 0.01, seed=0, shape=shape, ransac_points=500)
    assert thin.n_planes == 1 and np.count_nonzero(thin.labels == 0) > 2900
    assert np.array_equal(thin.labels, pv.detect_planes(floor, 0.01, seed=0, ransac_points=500).labels)
    tuned = pv.tune_tolerance(floor, seed=0, count=3, shape=shape, tune_points=1000)
    plain = pv.tune_tolerance(floor, seed=0, count=3, tune_points=1000)
    assert tuned.tolerance == plain.tolerance and tuned.segmentation.n_planes == 1
    assert np.array_equal(tuned.segmentation.labels, plain.segmentation.labels)


def test_the_reason_says_when_regions_were_merged():
    pts, sh = scenes.depth_camera('table', width=160, height=120, seed=1).points, (120, 160)
    seg = pv.detect_planes(pts, 0.02, seed=0, shape=sh, min_inliers=1, max_planes=10)
    merged = re.search(r'merged (\d+) region', seg.reason)
    assert merged and seg.n_planes + int(merged[1]) <= 10, seg.reason


def test_each_sub_grid_block_is_stood_for_by_its_centre_or_its_valid_pixel_nearest_to_it():
    from plane_validation.core.ransac import grid_pixels
    valid = np.zeros((7, 7), bool)  # step 3: blocks of rows/columns 0-2 and 3-5 (row and column 6 in none)
    valid[1, 1] = valid[0, 0] = True  # block (0, 0): its centre (1, 1)
    valid[0, 3] = valid[2, 4] = True  # block (0, 1): centre (1, 4) lost; (2, 4) is next to it, (0, 3) a corner
    valid[6, 6] = True  # in no block: block (1, 1) stays empty
    pixels = grid_pixels(valid.reshape(-1), (7, 7), 3)
    assert pixels.tolist() == [[1 * 7 + 1, 2 * 7 + 4], [-1, -1]]


def test_scattered_lost_pixels_do_not_cut_an_organized_frame_into_pieces():
    # half the pixels lost at random (a stereo camera on a textureless wall): the 4-connected sub-grid
    # of centre pixels alone falls apart below ~59 % valid pixels; a block's other pixels stand in
    scene = scenes.depth_camera('room', seed=2)
    pts = scene.points.copy()
    lost = np.random.default_rng(0).random(len(pts)) < 0.5
    pts[lost] = np.nan
    truth = np.where(lost, -1, scene.labels)
    seg = pv.detect_planes(pts, 0.06, seed=0, shape=scene.shape, max_planes=12, min_inliers=0.005)
    q = segmentation_quality(seg.labels, truth)
    assert q.correct >= 5 and q.f1 > 0.9, q


def test_a_360_degree_lidar_image_is_joined_across_its_seam():
    # the wall at x = 12 m faces azimuth 0, where an organized scan's first and last columns meet
    scene = scenes.lidar(organized=True, rings=16, seed=1)
    assert scene.shape == (16, 1800)
    seg = pv.detect_planes(scene.points, 0.06, seed=0, shape=scene.shape, max_planes=12, min_inliers=0.005)
    q = segmentation_quality(seg.labels, scene.labels)
    assert seg.n_planes == q.correct == q.true_planes == 6, q
    wall = seg.labels[scene.labels == 3]
    assert np.bincount(wall[wall >= 0]).max() > 0.85 * len(wall)



@pytest.mark.parametrize('missing', ['every tenth', 'random tenth', 'random third'])
def test_a_16_ring_scan_with_missing_returns_keeps_its_planes(missing):
    # a 16-ring scan's image is searched at full resolution: every missing return cut its ring there, and
    # with one return in ten missing (the same azimuth on every ring) no region reached min_inliers (0 planes)
    from plane_validation.app.detection import detect
    scene = scenes.lidar(seed=1, **scenes.VLP16_ROOM)
    index = np.arange(len(scene.points))
    rng = np.random.default_rng(7)
    drop = {'every tenth': index % 10 == 0, 'random tenth': rng.random(len(index)) < 0.1,
            'random third': rng.random(len(index)) < 0.33}[missing]
    keep = ~drop
    result = detect(scene.points[keep], 0.05, ring=scene.rings[keep], seed=0)
    assert result.ring_image == '16x1800'
    q = segmentation_quality(result.segmentation.labels, scene.labels[keep])
    assert result.segmentation.n_planes == q.correct == 5 and q.f1 > 0.97, q


def test_a_seam_behind_missing_returns_still_wraps():
    scene = scenes.lidar(organized=True, rings=16, seed=1)
    points = scene.points.copy()
    points.reshape(16, 1800, 3)[:, [0, 1, -1]] = np.nan  # the columns at the seam: no return
    seg = pv.detect_planes(points, 0.06, seed=0, shape=scene.shape, max_planes=12, min_inliers=0.005)
    wall = seg.labels[(scene.labels == 3) & np.isfinite(points[:, 0])]
    assert np.bincount(wall[wall >= 0]).max() > 0.85 * len(wall)


def test_lidar_regions_span_short_runs_of_holes_but_not_a_depth_jump_behind_one():
    from plane_validation.core.search.grid_build import HOLE_BRIDGE, grid_neighbours
    # a lidar's image: its rows (rings) 10 times farther apart in angle than its columns
    v, u = np.mgrid[0:20, 0:40]
    depth = np.where(u < 20, 2.0, 1.0)  # the right half 1 m nearer: a depth jump at column 20
    image = np.stack([(u - 20) / 150 * depth, (v - 10) / 15 * depth, depth], -1).astype(float)
    image[:, 8:8 + HOLE_BRIDGE] = np.nan  # a run of holes within the far half
    image[:, 30:31 + HOLE_BRIDGE] = np.nan  # one too long, within the near half
    image[:, 19] = np.nan  # a hole just before the jump
    valid = np.isfinite(image).all(axis=2)
    neighbours = grid_neighbours(image, valid)
    assert neighbours.bridges is not None and len(neighbours.bridges)
    labels, count = neighbours.components(np.ones(neighbours.n, bool))
    at = np.full(valid.shape, -1)
    at[valid] = labels
    assert count == 3  # columns 0-18 (across the short run), 20-29, 31+HOLE_BRIDGE-39
    assert len(np.unique(at[:, :19][valid[:, :19]])) == 1 and len(np.unique(at[:, 20:30])) == 1
    assert len({at[0, 0], at[0, 20], at[0, 39]}) == 3


def test_only_a_scan_whose_last_column_is_next_to_its_first_wraps_around():
    from plane_validation.core.search.grid_build import grid_neighbours
    for scene, wraps in ((scenes.lidar(organized=True, rings=16, seed=1), True),
                         (scenes.depth_camera('room', width=160, height=120, seed=0), False)):
        image = scene.points.reshape(*scene.shape, 3)
        assert grid_neighbours(image, np.isfinite(image).all(axis=2)).wraps is wraps


def _room_scan() -> scenes.Scene:
    """A 16-beam lidar in the middle of a furnished room: walls 1.5-3 m away, where the 1800 returns
    of a ring lie 5-10 mm apart, closer than the 2 cm range noise."""
    return scenes.lidar(**scenes.VLP16_ROOM, seed=0)


def test_an_unorganized_lidar_scan_of_near_walls_keeps_its_walls():
    # one ring's noisy returns on a wall are a strip along the beam's cone: its normal was taken for the
    # wall's, 90 degrees off, and the normal-coherence test cut every wall into pieces (0 of 6 correct)
    scene = _room_scan()
    seg = pv.detect_planes(scene.points, 0.05, seed=0, max_planes=20, min_inliers=50)
    q = segmentation_quality(seg.labels, scene.labels)
    assert q.correct >= 5 and q.f1 > 0.95, q


def test_local_normals_of_lidar_rings_come_from_two_rings():
    from plane_validation.core.regions import NORMAL_MIN_COS, graph_neighbours
    scene = _room_scan()
    normals = graph_neighbours(scene.points).normals
    cos = np.abs(np.einsum('ij,ij->i', normals, scene.planes[scene.labels, :3]))
    assert np.mean(cos < NORMAL_MIN_COS) < 0.05  # was 95 %; NaN (unknown) is not wrong


def test_a_plane_through_the_origin_is_not_taken_for_a_lidar_ring():
    from plane_validation.core.regions import graph_neighbours
    corner = scenes.corner(3000, 0.2, seed=0).points  # three faces meeting at the origin, each seen edge-on
    moved = graph_neighbours(corner + 500.0).normals
    assert np.isfinite(moved).all(axis=1).mean() > 0.9
    np.testing.assert_allclose(graph_neighbours(corner).normals, moved, rtol=0, atol=1e-9)


def test_far_lidar_rings_on_the_ground_are_joined_to_each_other():
    # two rings 2 m apart with returns 3.5 cm apart along each: the next ring lies beyond the
    # ACROSS_CANDIDATES nearest points, so only the far search (every ACROSS_FAR_STRIDE-th point) finds it
    from plane_validation.core.regions import ACROSS_CANDIDATES, graph_neighbours
    azimuth = np.linspace(0, 2 * np.pi, 3600, endpoint=False)
    rings = [np.column_stack([r * np.cos(azimuth), r * np.sin(azimuth), np.full(3600, -1.8)]) for r in (20.0, 22.0)]
    points = np.concatenate(rings)
    assert 2.0 / (2 * np.pi * 20.0 / 3600) > ACROSS_CANDIDATES
    graph = graph_neighbours(points)
    labels, count = graph.components(np.ones(len(points), bool))
    assert count == 1
    across = np.count_nonzero((graph.edges[:, 0] < 3600) != (graph.edges[:, 1] < 3600))
    assert across > 1000  # nearly every point of the inner ring is joined to the outer one, or by a neighbour


def test_the_strip_test_looks_from_the_sensor_also_when_the_scan_is_cropped():
    # detect_planes centres a cloud on its median; a 90-degree slice of a scan has its median far
    # from the sensor, which stays at the cloud's origin
    scene = _room_scan()
    front = scene.points[:, 0] > np.abs(scene.points[:, 1])
    seg = pv.detect_planes(scene.points[front], 0.05, seed=0, max_planes=20, min_inliers=50)
    q = segmentation_quality(seg.labels, scene.labels[front])
    assert q.correct == q.true_planes and q.f1 > 0.95, q


def test_a_corridor_floor_under_a_16_beam_lidar_is_one_region_on_each_side_of_the_sensor():
    # the rings cross the 2.4 m wide floor 0.5-6 m apart; the nearest points off a ring's line were the
    # same ring climbing the walls, so each ring on the floor was a region of its own (8 of them, and
    # 33-73 % of the floor in a plane); now a ring looks for the next ring in the direction of the scan
    from plane_validation.core.regions import graph_neighbours
    scene = scenes.lidar(**scenes.VLP16_CORRIDOR, seed=2)
    floor = int(np.flatnonzero((scene.planes[:, 2] < -0.9) & np.isclose(scene.planes[:, 3], -0.8))[0])
    on_floor = scene.labels == floor
    _, count = graph_neighbours(scene.points).components(on_floor)
    assert count == 2  # in front of and behind the sensor's blind circle (3 m across at 0.8 m height)
    seg = pv.detect_planes(scene.points, 0.05, seed=0)
    horizontal = [k for k, plane in enumerate(seg.planes) if abs(plane.normal[2]) > 0.9]
    assert np.isin(seg.labels[on_floor], horizontal).mean() > 0.95


def test_a_cabinet_side_seen_at_a_grazing_angle_keeps_to_itself():
    # the side face (144 returns) took 41 points of the wall behind and of the front at its corners,
    # nearer its plane in meters: overlap 0.78 < 0.8, so 5 of 6 correct; along the rays 6 of 6
    scene = scenes.lidar(**scenes.VLP16_ROOM, seed=1)
    seg = pv.detect_planes(scene.points, 0.055, seed=0, max_planes=14, min_inliers=23)
    q = segmentation_quality(seg.labels, scene.labels)
    assert q.correct == 6 and q.f1 > 0.99, q


def test_a_lidar_scan_far_from_its_frames_origin_is_not_taken_for_rings():
    # seen from 100 m away, every neighbourhood shares one elevation; it spans far less than the
    # angle between rings, so it is no ring (it was: partners had to be 0.1 degrees away, 17 cm there,
    # and the room fell apart, 0/6 correct, F1 0.15; 5/6, F1 0.90 as before the ring test)
    scene = _room_scan()
    seg = pv.detect_planes(scene.points + [80.0, 60.0, 0.0], 0.05, seed=0, max_planes=20, min_inliers=50)
    q = segmentation_quality(seg.labels, scene.labels)
    assert q.correct >= 5 and q.f1 > 0.85, q


def test_a_lidar_scan_in_another_frame_is_seen_from_its_viewpoint():
    # base_link: the sensor 1.8 m above the frame's origin. From the origin the strip and ring tests
    # do not apply (0/6 correct, F1 0.16); given the viewpoint, the planes are those of the sensor
    # frame, their offsets moved with the frame
    scene = scenes.lidar(**scenes.VLP16_ROOM, seed=1)
    up = np.array([0.0, 0.0, 1.8])
    own = pv.detect_planes(scene.points, 0.05, seed=0, max_planes=14, min_inliers=23)
    moved = pv.detect_planes(scene.points + up, 0.05, seed=0, max_planes=14, min_inliers=23, viewpoint=up)
    assert np.array_equal(own.labels, moved.labels)
    np.testing.assert_allclose(moved.coefficients[:, 3], own.coefficients[:, 3] - own.coefficients[:, :3] @ up,
                               atol=1e-9)
    assert moved.viewpoint == (0.0, 0.0, 1.8)
    blind = pv.detect_planes(scene.points + up, 0.05, seed=0, max_planes=14, min_inliers=23)
    assert segmentation_quality(blind.labels, scene.labels).correct < segmentation_quality(
        moved.labels, scene.labels).correct


def test_a_viewpoint_must_be_three_finite_coordinates_and_match_a_prebuilt_graph():
    from plane_validation.core.ransac import search_graph
    pts = scenes.room(600, 0.005, seed=0).points
    for bad in ((0.0, 1.0), (0.0, np.nan, 1.0), 'sensor'):
        with pytest.raises(ValueError, match='viewpoint'):
            pv.detect_planes(pts, 0.02, viewpoint=bad)
    graph = search_graph(pts, viewpoint=(0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match='viewpoint'):
        pv.detect_planes(pts, 0.02, graph=graph)
    assert pv.detect_planes(pts, 0.02, graph=graph, viewpoint=(0, 0, 1)).n_planes > 0


def test_grid_normals_of_a_lidar_image_look_one_ring_away():
    # a lidar's rings lie 13 times farther apart than its returns along a ring: normals from 3 rings away
    # reached past a wall that 5 rings cross, and the wall fell apart (no region of it above 341 points)
    from plane_validation.core.search.grid_build import _reach
    scan = scenes.lidar(rings=16, seed=1, organized=True)
    image = scan.points.reshape(*scan.shape, 3)
    valid = np.isfinite(image).all(axis=2)
    assert _reach(image, valid, np.linalg.norm(image, axis=2)) == (1, 14)  # the same angle both ways
    depth = scenes.depth_camera('room', width=160, height=120, seed=0)
    image = depth.points.reshape(*depth.shape, 3)
    assert _reach(image, np.isfinite(image).all(axis=2), np.linalg.norm(image, axis=2)) == (3, 3)
    seg = pv.detect_planes(scan.points, 0.05, seed=0, shape=scan.shape)
    wall = scan.labels == 3  # x = 12 m, 3 m high: 5 rings
    assert max(np.count_nonzero(seg.labels[wall] == j) for j in range(seg.n_planes)) > 0.6 * np.count_nonzero(wall)


def test_noisy_normals_of_a_lidar_image_are_unknown_not_wrong(monkeypatch):
    # 3 cm range noise in a 2.4 m corridor: a normal over one ring is noise, and such normals cut the floor
    # and walls apart (0/8 correct, F1 0.41, where only the inliers connect a region, and the pieces are not
    # joined again); unknown, they let any plane keep the point
    from plane_validation.core.search import connected, grid_build, hypotheses, sequential
    scan = scenes.lidar(**{**scenes.VLP16_CORRIDOR, 'sigma': 0.03}, seed=1, organized=True)
    seg = pv.detect_planes(scan.points, 0.05, seed=0, shape=scan.shape)
    assert segmentation_quality(seg.labels, scan.labels).f1 > 0.9
    monkeypatch.setattr(grid_build, 'LIDAR_BEND', np.inf)  # no normal unknown for noise
    monkeypatch.setattr(hypotheses, 'SUPPORT', 1.0)
    monkeypatch.setattr(connected, 'merge_occluded', lambda search, region, found, *args: (region, found))
    monkeypatch.setattr(sequential, 'SET_ASIDE', 0)  # nor a scattered surface joined whatever its normals
    seg = pv.detect_planes(scan.points, 0.05, seed=0, shape=scan.shape)
    assert segmentation_quality(seg.labels, scan.labels).f1 < 0.6


@pytest.mark.parametrize('n', [1, 40, 300, 70_000])
def test_components_of_joined_pairs_equal_scipys_connected_components(n):
    """joined_components calls the kernel behind csgraph.connected_components directly: the same
    count and labels (numbered by first point) on random graphs, small and beyond 16-bit indices."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    from plane_validation.core.search.neighbours import joined_components
    rng = np.random.default_rng(n)
    for _ in range(20 if n < 1000 else 2):
        a, b = rng.integers(0, n, (2, int(rng.integers(0, 2 * n + 1))))
        src, dst = np.minimum(a, b), np.maximum(a, b)
        order = np.lexsort((dst, src))
        count, labels = joined_components(n, src[order], dst[order])
        expected = connected_components(csr_matrix((np.ones(len(a)), (src, dst)), shape=(n, n)),
                                        directed=True, connection='weak')
        assert count == expected[0] and np.array_equal(labels, expected[1])


def test_a_bridge_within_a_wrapping_row_is_found_once_and_not_taken_for_the_seam():
    # the row's end pixels were scanned twice (the row extended past its end for the seam): a bridge from
    # column 0 to 2 came out a second time flagged as crossing the seam, and its steps beside it differed
    from plane_validation.core.search.grid_build import _bridges
    x = np.array([0.0, np.nan, 0.05, 0.06, 0.07, 0.08, 0.09, 0.10, 0.11, -0.04])
    image = np.stack([x, np.zeros(10), np.full(10, 5.0)], -1)[None]
    valid = np.isfinite(image).all(-1)
    bridges = _bridges(image, valid, np.linalg.norm(np.nan_to_num(image), axis=-1), 1e-4, True)
    assert bridges.tolist() == [[0, 2, 0]]
    x = np.array([np.nan, 0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.08, -0.01])  # a hole at the seam
    image = np.stack([x, np.zeros(10), np.full(10, 5.0)], -1)[None]
    valid = np.isfinite(image).all(-1)
    assert _bridges(image, valid, np.linalg.norm(np.nan_to_num(image), axis=-1), 1e-4, True).tolist() == [[9, 1, 1]]



def _noisy_wall(sigma: float, seed: int = 0) -> np.ndarray:
    """An organized 120 x 160 depth image of a wall 2 m away with depth noise ``sigma`` (m)."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:120, 0:160]
    depth = 2.0 + rng.normal(0, sigma, u.shape)
    return np.stack([(u - 80) / 150.0 * depth, (v - 60) / 150.0 * depth, depth], -1).reshape(-1, 3)


def test_a_wall_noisier_than_t_stays_one_region_on_the_image(monkeypatch):
    # t = 0.6 sigma: 45 % of the wall lies within t, too few to hold together as 4-connected pixels;
    # the points within SUPPORT tolerances connect them
    from plane_validation.core.search import hypotheses
    pts = _noisy_wall(0.01)
    within = np.abs(pts[:, 2] - 2.0) <= 0.006  # about the points within t of the true wall
    seg = pv.detect_planes(pts, 0.006, seed=0, shape=(120, 160), max_planes=3, min_inliers=0.05)
    assert seg.n_planes >= 1
    kept = np.count_nonzero(seg.labels == 0)
    assert kept >= 0.8 * within.sum() and abs(seg.planes[0].normal[2]) > 0.99, (kept, within.sum())
    monkeypatch.setattr(hypotheses, 'SUPPORT', 1.0)  # connected through the inliers alone: pieces
    pieces = pv.detect_planes(pts, 0.006, seed=0, shape=(120, 160), max_planes=3, min_inliers=0.05)
    assert np.count_nonzero(pieces.labels == 0) < 0.5 * within.sum()


def test_a_region_is_joined_through_its_support_only_when_its_inliers_fall_apart():
    from plane_validation.core.search.neighbours import fragmented
    from plane_validation.core.search.neighbours_graph import GraphNeighbours
    from plane_validation.core.search.neighbours_grid import GridNeighbours
    assert not fragmented(np.array([60, 30]))  # the larger piece holds >= FRAGMENTED (half)
    assert not fragmented(np.array([34, 33, 33]))  # three drawer fronts: large pieces, kept apart
    assert fragmented(np.array([5] + [1] * 95)) and not fragmented(np.zeros(0, np.int64))
    h, w = 10, 20
    grid = GridNeighbours(n=h * w, shape=(h, w), pixel=np.arange(h * w), node=np.arange(h * w),
                      usable=np.ones(h * w, bool))
    support = np.ones((h, w), bool)
    above = (np.arange(h)[:, None] < h // 2).repeat(w, axis=1).ravel()  # the support beyond t on both sides
    two = np.zeros((h, w), bool)
    two[:, :12], two[:, 14:] = True, True  # 60 % and 30 % of the pixels, joined by the support between them
    kept, taken = grid.region(two.ravel(), support.ravel(), above)
    assert np.array_equal(kept.reshape(h, w), two & (np.arange(w) < 12)) and np.array_equal(kept, taken)
    dots = np.zeros((h, w), bool)
    dots[::2, ::2] = True  # single pixels, none 4-connected to another
    assert grid.largest(dots.ravel()).sum() == 1
    kept, taken = grid.region(dots.ravel(), support.ravel(), above)  # joined through the support, which it takes
    assert np.array_equal(kept, dots.ravel()) and taken.all()
    # the support beyond t all on one side of the plane (a recess, a backing): not joined
    assert grid.largest(dots.ravel(), support.ravel(), np.ones(h * w, bool)).sum() == 1
    assert grid.largest(dots.ravel(), support.ravel(), np.zeros(h * w, bool)).sum() == 1
    assert grid.largest(dots.ravel(), support.ravel()).sum() == 1  # sides unknown: not joined
    gap = support.copy()
    gap[:, 9] = False  # the support cut in two: the side with more of the dots
    joined = grid.largest(dots.ravel(), gap.ravel(), above).reshape(h, w)
    assert joined.sum() == 25 and not joined[:, 10:].any()
    # the same on a graph: a chain of 200 points, every other one in the mask, the support cut after 120
    chain = GraphNeighbours(n=200, edges=np.column_stack([np.arange(199), np.arange(1, 200)]))
    every_other, support = np.arange(200) % 2 == 0, np.arange(200) != 121
    kept, taken = chain.region(every_other, support, np.arange(200) % 4 == 1)
    assert np.array_equal(kept, every_other & (np.arange(200) <= 120)) and np.array_equal(taken, np.arange(200) <= 120)
    kept, taken = chain.region(every_other)
    assert kept.sum() == 1 and np.array_equal(kept, taken)


def test_many_separate_coplanar_fronts_keep_the_panel_behind_them():
    """25 drawer fronts 1.8 cm before their cabinet's panel, noise 2 mm, t = 1 cm: the fronts are 25 small
    pieces, which looked like a surface fallen apart, and were joined through the recesses (within 2 t) into one
    plane that took the panel out of the search (an outside review: no panel point labelled, F1 0.03). The
    support beyond t lies all behind the fronts, on one side: not noise, not joined."""
    rng = np.random.default_rng(0)
    v, u = np.mgrid[0:120, 0:160]
    cu, cv = u // 32, v // 24
    front = (u % 32 >= 3) & (u % 32 < 29) & (v % 24 >= 3) & (v % 24 < 21)
    truth = np.where(front, cv * 5 + cu, 25).reshape(-1)  # 25: the panel
    depth = np.where(front, 1.982, 2.0) + rng.normal(0, 0.002, u.shape)
    pts = np.stack([(u - 80) / 150 * depth, (v - 60) / 150 * depth, depth], -1).reshape(-1, 3)
    for shape in ((120, 160), None):
        seg = pv.detect_planes(pts, 0.01, seed=0, shape=shape, max_planes=30)
        counts = np.array([np.bincount(truth[p.inliers], minlength=26) for p in seg.planes])
        sizes = np.bincount(truth, minlength=26)
        assert (counts[:, :25] >= 0.5 * sizes[:25]).sum(axis=1).max() < 12, (shape, counts)  # no plane of many fronts
        assert np.mean(seg.labels[truth == 25] >= 0) > 0.8  # the panel is found


def test_separate_coplanar_fronts_are_not_joined_through_a_recess_within_two_tolerances():
    # three drawer fronts 1.8 cm before the recesses between them, noise 2 mm, t = 1 cm: the recesses lie
    # within 2 t and face the same way, but the fronts are three large pieces, not a surface fallen apart
    rng = np.random.default_rng(0)
    v, u = np.mgrid[0:120, 0:160]
    part = np.select([u < 45, (u >= 55) & (u < 105), u >= 115], [0, 1, 2], 3)
    depth = np.where(part == 3, 2.003, 1.985) + rng.normal(0, 0.002, u.shape)
    pts = np.stack([(u - 80) / 150 * depth, (v - 60) / 150 * depth, depth], -1).reshape(-1, 3)
    seg = pv.detect_planes(pts, 0.01, seed=0, shape=(120, 160), max_planes=6, min_inliers=0.02)
    part = part.reshape(-1)
    left = [np.bincount(part[p.inliers], minlength=4) for p in seg.planes]
    assert any(c[0] >= 0.95 * np.sum(part == 0) and c[1] + c[2] == 0 for c in left), left  # the left front alone


def test_the_two_neighbourhood_forms_answer_alike_on_one_topology():
    """The valid pixels of an image as GridNeighbours and as GraphNeighbours joined by the grid's touching pairs
    (4-connected): the same components, in the same order, and the same regions kept and taken, by the grid's
    numpy rule and the graph's compiled one (with and without joining through the support)."""
    from plane_validation.core.regions import _neighbours
    from plane_validation.core.search.neighbours_grid import GridNeighbours
    rng = np.random.default_rng(3)
    h, w = 12, 17
    valid = rng.random(h * w) < 0.85
    pixel = np.flatnonzero(valid)
    node = np.full(h * w, -1)
    node[pixel] = np.arange(len(pixel))
    grid = GridNeighbours(n=len(pixel), shape=(h, w), pixel=pixel, node=node, usable=valid)
    graph = _neighbours(grid.n, np.column_stack(grid.touching()), None)
    assert np.array_equal(grid.searchable(), graph.searchable())
    rules = [form.remaining(form.searchable()) for form in (grid, graph)]
    normal = np.array([0.0, 0.0, 1.0])
    joined = 0
    for _ in range(40):
        mask = rng.random(grid.n) < rng.uniform(0.05, 0.8)
        support = mask | (rng.random(grid.n) < rng.uniform(0.0, 0.9))
        above = rng.random(grid.n) < 0.5
        (labels, count), (graph_labels, graph_count) = grid.components(mask), graph.components(mask)
        assert count == graph_count and np.array_equal(labels, graph_labels)
        (kept, taken), (graph_kept, graph_taken) = (rule.keep(mask, normal, support, above) for rule in rules)
        assert np.array_equal(kept, graph_kept) and np.array_equal(taken, graph_taken)
        joined += int(not np.array_equal(kept, taken))
    assert joined > 0  # some masks fell apart and were joined through their support


def test_a_far_wall_of_a_lidar_scan_is_one_piece_of_the_graph():
    """A corridor's end wall 8.7 m from a 32-ring lidar: its rings lie farther apart than the cloud's typical
    spacing, and its points are joined across them by their own neighbourhood's spacing (with the cloud's alone it
    fell apart into one piece per few rings, and no plane was found on it)."""
    from plane_validation.core import regions, scene_families
    from plane_validation.core.search.neighbours import joined_components
    scene = scene_families.lidar_scan(0)
    wall = np.flatnonzero(scene.labels == 0)
    assert 'corridor' in scene.name and abs(np.median(scene.points[wall, 0]) + 8.7) < 0.2
    edges = regions.graph_neighbours(scene.points).edges
    keep = np.isin(edges[:, 0], wall) & np.isin(edges[:, 1], wall)
    within = np.searchsorted(wall, edges[keep])
    count, _ = joined_components(len(wall), within[:, 0], within[:, 1])
    assert count == 1
    seg = pv.detect_planes(scene.points, 0.08, seed=0, max_planes=60, min_inliers=0.002)
    taken = np.bincount(seg.labels[wall][seg.labels[wall] >= 0], minlength=seg.n_planes)
    assert taken.max() >= 0.9 * len(wall)  # one plane holds the wall
