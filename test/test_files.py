"""Point files for the command line: PCD, PLY, .npy, text and bags, read and written; the detect command."""
import re
from pathlib import Path

import numpy as np
import pytest

from plane_validation import scenes
from plane_validation.cli import main as cli_main
from plane_validation.formats.files import load_points, load_scan, save_points

POINTS = scenes.corner(600, 1.0, scale=0.01, seed=2).points


def _pcd_header(data: str, n: int, *, version: str = '0.7') -> bytes:
    return (f'# .PCD v{version} - written by the test\nVERSION {version}\nFIELDS x y z rgb\nSIZE 4 4 4 4\n'
            f'TYPE F F F U\nCOUNT 1 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\n'
            f'DATA {data}\n').encode()


@pytest.mark.parametrize('version', ['0.7', '.5'])
def test_pcd_ascii_and_binary(tmp_path, version):
    ascii_path = tmp_path / 'a.pcd'
    rows = '\n'.join(f'{x:.7g} {y:.7g} {z:.7g} 4278190080' for x, y, z in POINTS)
    ascii_path.write_bytes(_pcd_header('ascii', len(POINTS), version=version) + rows.encode() + b'\n')
    np.testing.assert_allclose(load_points(ascii_path), POINTS, atol=1e-6)

    binary_path = tmp_path / 'b.pcd'
    records = np.zeros(len(POINTS), dtype=[('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('rgb', '<u4')])
    records['x'], records['y'], records['z'] = POINTS.T
    binary_path.write_bytes(_pcd_header('binary', len(POINTS), version=version) + records.tobytes())
    np.testing.assert_array_equal(load_points(binary_path), POINTS.astype(np.float32).astype(np.float64))


def test_text_and_npy(tmp_path):
    np.save(tmp_path / 'p.npy', POINTS)
    np.savetxt(tmp_path / 'p.xyz', POINTS)
    np.savetxt(tmp_path / 'p.csv', np.column_stack([POINTS, np.ones(len(POINTS))]), delimiter=',')
    for name in ('p.npy', 'p.xyz', 'p.csv'):
        np.testing.assert_allclose(load_points(tmp_path / name), POINTS)


@pytest.mark.parametrize('content, words', [
    (b'VERSION 0.7\nFIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\n'
     b'DATA ascii\n1 2 3\n', 'no x, y, z'),
    (b'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n', 'no DATA'),
    (b'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 10\nHEIGHT 1\nPOINTS 10\nDATA binary\n'
     + bytes(20), 'need'),
    (b'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n'
     + bytes(36), r'more than its 2 points need \(24\): POINTS too small'),  # was read silently as 2 points
    (b'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\nPOINTS 3\nDATA ascii\n'
     b'1 2 3\n4 5 6\n', 'has 2 rows, the header declares 3'),  # cut short
    (b'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n'
     b'1 2 3\n4 5 6\n', 'has 2 rows, the header declares 1'),
    (b'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 2\nPOINTS 3\nDATA ascii\n'
     b'1 2 3\n4 5 6\n7 8 9\n', 'WIDTH x HEIGHT = 4 but POINTS 3'),
    (b'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 0\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n'
     + bytes(24), 'COUNT must be at least 1'),  # was an IndexError
    (b'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 2 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n'
     b'1 2 3 4\n', '1 for x, y and z'),
    (b'VERSION 0.7\nFIELDS x y z f\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1000000000000\nWIDTH 1\nHEIGHT 1\n'
     b'POINTS 1\nDATA binary\n' + bytes(12), 'bad.pcd: a PCD point of more than 2 GiB'),  # was numpy's "C int" error
])
def test_malformed_pcd_is_a_clear_error(tmp_path, content, words):
    path = tmp_path / 'bad.pcd'
    path.write_bytes(content)
    with pytest.raises(ValueError, match=words):
        load_points(path)


def test_an_empty_file_name_is_refused():
    with pytest.raises(ValueError, match='the file name is empty'):  # an outside probe: it read '.' as a bag
        load_points('')


def test_detect_command(tmp_path, capsys):
    np.save(tmp_path / 'corner.npy', POINTS)
    assert cli_main(['detect', str(tmp_path / 'corner.npy'), '--png', str(tmp_path / 'c.png')]) == 0
    out = capsys.readouterr().out
    assert '3 plane(s)' in out and 'tuned tolerance' in out and 'reliable' in out
    assert (tmp_path / 'c.png').stat().st_size > 10_000
    assert cli_main(['detect', str(tmp_path / 'corner.npy'), '--tolerance', '0.02']) == 0
    assert '3 plane(s), tolerance 0.02 m' in capsys.readouterr().out
    assert cli_main(['detect', str(tmp_path / 'missing.pcd')]) == 2
    assert 'no such file' in capsys.readouterr().err
    assert cli_main(['tune', str(tmp_path / 'corner.npy')]) == 0
    assert 'chosen t =' in capsys.readouterr().out


# -- every input format, written by third-party writers where there is one ---------------------------

def test_pcd_binary_compressed_and_ascii_written_by_pypcd4(tmp_path):
    from pypcd4 import Encoding, PointCloud
    # pypcd4 falls back to plain binary when LZF cannot shrink the data: use a compressible cloud
    grid = np.round(scenes.corner(600, 0.0, seed=2).points / 5) * 5
    cloud = PointCloud.from_xyz_points(grid.astype(np.float32))
    for encoding in (Encoding.BINARY_COMPRESSED, Encoding.ASCII, Encoding.BINARY):
        path = tmp_path / f'{encoding.value}.pcd'
        cloud.save(path, encoding=encoding)
        assert f'DATA {encoding.value}\n'.encode() in path.read_bytes()[:400]
        np.testing.assert_array_equal(load_points(path), grid)



@pytest.mark.parametrize('declared', [300, 1200])
def test_a_binary_compressed_pcd_whose_points_do_not_match_its_data_is_an_error(tmp_path, declared):
    # with fewer points declared pypcd4 read the first fields' bytes as all the columns (y from the x of
    # later points): a wrong cloud without an error
    from pypcd4 import Encoding, PointCloud
    grid = np.round(scenes.corner(600, 0.0, seed=2).points / 5) * 5
    path = tmp_path / 'c.pcd'
    PointCloud.from_xyz_points(grid.astype(np.float32)).save(path, encoding=Encoding.BINARY_COMPRESSED)
    raw = path.read_bytes()
    assert b'DATA binary_compressed' in raw and b'POINTS 600\n' in raw
    path.write_bytes(raw.replace(b'POINTS 600\n', f'POINTS {declared}\n'.encode())
                     .replace(b'WIDTH 600\n', f'WIDTH {declared}\n'.encode()))
    with pytest.raises(ValueError, match=f'unpacks to 7200 bytes, but its {declared} points of 12 bytes'):
        load_points(path)



def test_a_binary_compressed_pcd_whose_data_does_not_decompress_to_its_fields_is_an_error(tmp_path):
    """An outside probe: a header with 3 float fields over a compressed block of 4 gave pypcd4's "object of type
    'NoneType' has no len()"."""
    import struct

    import lzf
    n = len(POINTS)
    header = (f'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\nPOINTS {n}\n'
              'DATA binary_compressed\n').encode()
    for columns, why in ((np.column_stack([POINTS, POINTS[:, :1]]), f'decompresses to more than the {12 * n} bytes '
                          "the header's fields need: corrupt, or FIELDS/SIZE/COUNT leave a field out"),
                         (POINTS[:, :2], f"decompresses to {8 * n} bytes, the header's fields need {12 * n}: cut short "
                          'or corrupt')):
        raw = np.ascontiguousarray(columns.T, dtype='<f4').tobytes()
        block = lzf.compress(raw, 2 * len(raw))
        path = tmp_path / 'bad.pcd'
        path.write_bytes(header + struct.pack('<II', len(block), 12 * n) + block)
        with pytest.raises(ValueError, match=f'^{path}: cannot read binary_compressed PCD: the compressed data {why}$'):
            load_points(path)
    path.write_bytes(header + struct.pack('<II', 8, 12 * n) + b'\xff' * 8)
    with pytest.raises(ValueError, match='the compressed data is corrupt'):
        load_points(path)


def test_an_empty_binary_compressed_pcd_is_an_empty_cloud(tmp_path):
    from pypcd4 import Encoding, PointCloud
    path = tmp_path / 'empty.pcd'
    PointCloud.from_xyz_points(np.empty((0, 3), np.float32)).save(path, encoding=Encoding.BINARY_COMPRESSED)
    assert load_points(path).shape == (0, 3)
    path.write_bytes(path.read_bytes().replace(b'POINTS 0\n', b'POINTS 1\n').replace(b'WIDTH 0\n', b'WIDTH 1\n'))
    with pytest.raises(ValueError, match='cut short'):
        load_points(path)


def _lidar_pcd(path: Path, points: np.ndarray, ring: np.ndarray, data: str = 'binary', ring_type: str = 'U') -> Path:
    """A spinning lidar's PCD as velodyne_pointcloud's writers lay it out: x y z intensity ring."""
    n = len(points)
    path.write_bytes(f'VERSION 0.7\nFIELDS x y z intensity ring\nSIZE 4 4 4 4 {2 if ring_type == "U" else 4}\n'
                     f'TYPE F F F F {ring_type}\nCOUNT 1 1 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n'
                     f'POINTS {n}\nDATA {data}\n'.encode())
    if data == 'ascii':
        with open(path, 'a') as f:
            f.writelines(f'{x:.9g} {y:.9g} {z:.9g} 7 {r}\n' for (x, y, z), r in zip(points, ring))
        return path
    records = np.zeros(n, dtype=[('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('intensity', '<f4'),
                                 ('ring', '<u2' if ring_type == 'U' else '<f4')])
    records['x'], records['y'], records['z'] = points.T
    records['ring'] = ring
    with open(path, 'ab') as f:
        f.write(records.tobytes())
    return path


def test_a_lidar_scan_keeps_its_ring_field(tmp_path):
    from pypcd4 import Encoding, PointCloud
    scan = scenes.lidar(rings=16, azimuths=900, seed=1)
    points, ring = scan.points.astype(np.float32), scan.rings.astype(np.uint16)
    compressed = tmp_path / 'c.pcd'
    PointCloud.from_xyzir_points(np.column_stack([points, np.full(len(points), 7.0), ring])).save(
        compressed, encoding=Encoding.BINARY_COMPRESSED)
    for path in (_lidar_pcd(tmp_path / 'b.pcd', points, ring), _lidar_pcd(tmp_path / 'a.pcd', points, ring, 'ascii'),
                 compressed):
        xyz, shape, rings = load_scan(path)
        np.testing.assert_allclose(xyz, points, rtol=1e-7)  # ascii: the decimal digits, not the float32
        assert shape is None and rings.dtype == np.int64
        np.testing.assert_array_equal(rings, ring)
    # a float ring field of whole numbers numbers the beams as well; of other values it is kept for ring_image to
    # refuse (and the report to say why); a cloud without one has none
    floated = load_scan(_lidar_pcd(tmp_path / 'f.pcd', points, ring, ring_type='F'))[2]
    assert floated.dtype == np.int64 and np.array_equal(floated, ring)
    halves = load_scan(_lidar_pcd(tmp_path / 'h.pcd', points, ring + 0.5, ring_type='F'))[2]
    assert halves.dtype == np.float32 and np.array_equal(halves, ring + np.float32(0.5))
    assert load_scan(tmp_path / 'b.pcd')[2] is not None and load_scan(str(BAGS / 'room'))[2] is None


def test_detect_searches_a_lidar_pcd_on_its_ring_image_as_the_node_does(tmp_path, capsys):
    import json

    from plane_validation.app.pipeline import FramePipeline, PipelineConfig
    from plane_validation.core.scoring import segmentation_quality
    scan = scenes.lidar(rings=16, seed=1)
    order = np.random.default_rng(0).permutation(len(scan.points))  # as a driver may order it
    points, ring, truth = scan.points[order].astype(np.float32), scan.rings[order], scan.labels[order]
    path = _lidar_pcd(tmp_path / 'scan.pcd', points, ring)
    docs = {}
    for name, option in (('laid', '--organize-rings'), ('graph', '--no-organize-rings')):
        assert cli_main(['detect', str(path), '--tolerance', '0.05', '--json', '--out', str(tmp_path / f'{name}.npy'),
                         option]) == 0
        docs[name] = json.loads(capsys.readouterr().out)
    assert docs['laid']['ring_image'] == '16x1800' and docs['graph']['ring_image'] is None
    labels = {name: np.load(tmp_path / f'{name}.npy')[:, 3].astype(np.int64) for name in docs}
    assert [p['inliers'] for p in docs['laid']['planes']] == \
        [int(np.count_nonzero(labels['laid'] == k)) for k in range(len(docs['laid']['planes']))]
    # the node's per-frame pipeline on the same scan (its seed comes from the stamp: other draws, the same method)
    node = FramePipeline(PipelineConfig(auto_tune=False, tolerance=0.05, seed=0)).process(
        load_points(path), 0, ring=ring)
    assert dict(node.values)['ring_image'] == '16x1800'
    for name, got in (('laid', labels['laid']), ('graph', labels['graph']), ('node', node.labels)):
        q = segmentation_quality(got, truth)
        assert q.correct >= 5 and q.f1 > 0.97, (name, q)
    assert segmentation_quality(labels['laid'], node.labels).f1 > 0.97
    # sweep and detect --auto tune the scan alike, on its ring image
    assert cli_main(['detect', str(path), '--json']) == 0
    tuned = json.loads(capsys.readouterr().out)
    assert cli_main(['sweep', str(path), '--json']) == 0
    swept = json.loads(capsys.readouterr().out)
    assert swept['ring_image'] == tuned['ring_image'] == '16x1800'
    assert swept['tolerance'] == tuned['tolerance'] and swept['n_points'] == len(points)
    assert [p['inliers'] for p in swept['planes']] == [p['inliers'] for p in tuned['planes']]
    # a field that numbers no beams: the graph, and the text says why without claiming the image
    odd = _lidar_pcd(tmp_path / 'odd.pcd', points, ring % 2)
    assert cli_main(['sweep', str(odd), '--tolerances', '0.03:0.06:2']) == 0
    out = capsys.readouterr().out
    assert 'ring image: not used: 2 rings' in out and 'searched on it' not in out


def test_organized_pcd_keeps_nan_rows_in_place(tmp_path):
    width, height = 30, 20
    grid = np.full((width * height, 3), np.nan)
    holes = np.random.default_rng(0).random(width * height) < 0.2
    grid[~holes] = POINTS[:(~holes).sum()]
    records = grid.astype('<f4')
    header = (f'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {width}\nHEIGHT {height}\n'
              f'VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {width * height}\nDATA binary\n').encode()
    path = tmp_path / 'organized.pcd'
    path.write_bytes(header + records.tobytes())
    loaded = load_points(path)
    assert loaded.shape == (width * height, 3)
    np.testing.assert_array_equal(np.isnan(loaded).any(axis=1), holes)
    from plane_validation.formats.files import load_cloud
    points, shape = load_cloud(path)
    assert shape == (height, width) and np.array_equal(points, loaded, equal_nan=True)
    assert load_cloud(tmp_path / 'organized.pcd')[1] == (height, width)
    assert cli_main(['detect', str(path), '--tolerance', '0.02']) == 0


def test_a_ply_whose_x_is_a_list_property_is_a_one_line_error(tmp_path):
    path = tmp_path / 'lists.ply'
    path.write_text('ply\nformat ascii 1.0\nelement vertex 2\nproperty list uchar float x\nproperty float y\n'
                    'property float z\nend_header\n2 0 1 0 0\n1 5 0 0\n')
    with pytest.raises(ValueError, match=r'lists\.ply: field x does not hold one number per point'):
        load_points(path)


def test_ply_ascii_by_plyfile_and_binary_by_us(tmp_path):
    from plyfile import PlyData, PlyElement
    vertex = np.zeros(len(POINTS), [('x', 'f8'), ('y', 'f8'), ('z', 'f8'), ('red', 'u1')])
    vertex['x'], vertex['y'], vertex['z'] = POINTS.T
    ascii_path = tmp_path / 'ascii.ply'
    PlyData([PlyElement.describe(vertex, 'vertex')], text=True).write(str(ascii_path))
    assert ascii_path.read_bytes().startswith(b'ply\nformat ascii')
    np.testing.assert_allclose(load_points(ascii_path), POINTS, atol=1e-9)

    labels = np.arange(len(POINTS)) % 4 - 1
    binary_path = save_points(tmp_path / 'binary.ply', POINTS, labels)
    assert binary_path.read_bytes().startswith(b'ply\nformat binary_little_endian')
    ply = PlyData.read(str(binary_path))
    np.testing.assert_array_equal(ply['vertex']['plane_id'], labels)
    assert ply['vertex'].data.dtype['plane_id'] == np.dtype('<i4')
    np.testing.assert_allclose(load_points(binary_path), POINTS, atol=1e-6)


@pytest.mark.parametrize('text', [True, False])
def test_a_ply_with_records_beyond_its_declared_count_is_refused(tmp_path, text):
    from plyfile import PlyData, PlyElement
    vertex = np.zeros(3, [('x', 'f4'), ('y', 'f4'), ('z', 'f4')])
    vertex['x'] = [0, 1, 2]
    faces = np.array([([0, 1, 2],)], dtype=[('vertex_indices', 'i4', (3,))])
    path = tmp_path / 'p.ply'
    PlyData([PlyElement.describe(vertex, 'vertex'), PlyElement.describe(faces, 'face')], text=text).write(str(path))
    whole = path.read_bytes()
    path.write_bytes(whole + b'\n')  # a line end after the data: fine
    assert load_points(path).shape == (3, 3)
    path.write_bytes(whole + (b'5 5 5\n' if text else vertex[:1].tobytes()))
    with pytest.raises(ValueError, match=r'p\.ply: PLY holds .* after its .*: an element count too small'):
        load_points(path)
    if not text:  # NUL padding shorter than a record (a review): fine; a record of zeros is not padding
        PlyData([PlyElement.describe(vertex, 'vertex')], text=False).write(str(path))
        whole = path.read_bytes()
        path.write_bytes(whole + bytes(4))
        assert load_points(path).shape == (3, 3)
        path.write_bytes(whole + bytes(12))
        with pytest.raises(ValueError, match='an element count too small'):
            load_points(path)


def test_saved_labels_in_every_point_format(tmp_path):
    from pypcd4 import PointCloud
    labels = np.where(np.arange(len(POINTS)) % 5 == 0, -1, np.arange(len(POINTS)) % 3)
    pcd = save_points(tmp_path / 'l.pcd', POINTS, labels)
    assert PointCloud.from_path(pcd).fields == ('x', 'y', 'z', 'label')
    np.testing.assert_array_equal(PointCloud.from_path(pcd).numpy(('label',))[:, 0], labels)
    np.testing.assert_array_equal(np.load(save_points(tmp_path / 'l.npy', POINTS, labels))[:, 3], labels)
    for name in ('l.xyz', 'l.csv', 'l.txt'):
        path = save_points(tmp_path / name, POINTS, labels)
        table = np.loadtxt(path, delimiter=',' if name.endswith('.csv') else None)
        np.testing.assert_array_equal(table[:, 3], labels)
        np.testing.assert_allclose(load_points(path), POINTS, atol=1e-8)


def test_an_npy_of_coordinates_in_rows_is_refused_not_read_as_three_points(tmp_path):
    path = tmp_path / 'cols.npy'
    np.save(path, POINTS.T)  # (3, N): what a column-major habit writes
    with pytest.raises(ValueError, match=r'shape \(3, \d+\) looks like the coordinates in rows'):
        load_points(path)
    np.save(path, POINTS[:3])  # three points of x y z: a (3, 3) table is read as points
    np.testing.assert_array_equal(load_points(path), POINTS[:3])


def test_structured_npy_with_xyz_fields(tmp_path):
    table = np.zeros(len(POINTS), [('intensity', 'f4'), ('x', 'f8'), ('y', 'f8'), ('z', 'f8')])
    table['x'], table['y'], table['z'] = POINTS.T
    np.save(tmp_path / 's.npy', table)
    np.testing.assert_array_equal(load_points(tmp_path / 's.npy'), POINTS)


BAGS = Path(__file__).resolve().parents[1] / 'bags'


def test_bag_sources_pick_topic_and_message(tmp_path):
    from plane_validation.formats.bags import read_clouds
    from plane_validation.formats.pointcloud2 import xyz_array
    frames = [xyz_array(msg) for _, _, msg in read_clouds(BAGS / 'corner_e025')]
    assert len(frames) == 5
    bag = str(BAGS / 'corner_e025')
    np.testing.assert_array_equal(load_points(bag), frames[0])
    np.testing.assert_array_equal(load_points(f'{bag}:/points'), frames[0])
    np.testing.assert_array_equal(load_points(f'{bag}:2'), frames[2])
    np.testing.assert_array_equal(load_points(f'{bag}:/points:3'), frames[3])
    np.testing.assert_array_equal(load_points(f'{bag}::-1'), frames[4])
    np.testing.assert_array_equal(load_points(f'{bag}:/points:-5'), frames[0])
    db3 = next((BAGS / 'corner_e025').glob('*.db3'))
    np.testing.assert_array_equal(load_points(f'{db3}:1'), frames[1])
    mcap = next((BAGS / 'room').glob('*.mcap'))
    room = load_points(f'{mcap}:-1')
    assert room.shape == (10800, 3) and np.isnan(room).any()  # organized depth image with holes
    for source, words in [(f'{bag}:5', r'no cloud number 5 on its cloud topic \(only 5 clouds\)'),
                          (f'{bag}:-6', 'no cloud number -6'),
                          (f'{bag}:/other', "no topic '/other'"),
                          (f'{bag}:/points:x', 'not an integer'),
                          (str(tmp_path / 'nope.mcap:/points'), 'bag not found')]:
        with pytest.raises(ValueError, match=words):
            load_points(source)


def test_ros1_bag_source(tmp_path):
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.typesys import Stores, get_typestore

    from plane_validation.formats.pointcloud2 import create_cloud, rosbags_types
    ts = get_typestore(Stores.ROS1_NOETIC)
    types = rosbags_types(ts)
    path = tmp_path / 'old.bag'
    with Writer1(path) as writer:
        conn = writer.add_connection('/cloud', 'sensor_msgs/msg/PointCloud2', typestore=ts)
        for k in range(2):
            header = types.Header(seq=k, stamp=types.Time(sec=k, nanosec=0), frame_id='s')
            pts = (POINTS + k).astype(np.float32)
            msg = create_cloud(header, {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2]}, types=types)
            writer.write(conn, 10**9 * (k + 1), ts.serialize_ros1(msg, 'sensor_msgs/msg/PointCloud2'))
    np.testing.assert_allclose(load_points(f'{path}:/cloud:1'), POINTS + 1, atol=1e-5)


@pytest.mark.parametrize('name', ['one.mcap', 'one.db3', 'one_dir'])
def test_written_bag_reads_back_and_is_not_overwritten(tmp_path, name):
    path = save_points(tmp_path / name, POINTS)
    assert path.is_dir() == (name == 'one_dir')
    np.testing.assert_allclose(load_points(f'{path}:/points:0'), POINTS, atol=1e-6)
    assert [p.name for p in tmp_path.iterdir()] == [name]  # no temporary leftovers
    with pytest.raises(ValueError, match='already exists'):
        save_points(path, POINTS)


@pytest.mark.parametrize('name, content, words', [
    ('garbage.pcd', bytes(range(256)) * 8, 'PCD header has no DATA line'),
    ('garbage.ply', bytes(range(256)) * 8, 'not a readable PLY file'),
    ('garbage.npy', bytes(range(256)) * 8, 'not a .npy file'),
    ('empty.npy', b'', 'not a .npy file'),
    ('garbage.xyz', bytes(range(256)) * 8, 'not a text file'),
    ('two.csv', b'1,2\n3,4\n', 'at least x y z'),
    ('columns.csv', b'0,1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16\n' * 3, 'a point per column'),  # coordinates in rows
    ('cloud.las', b'LASF', "unsupported file type '.las'"),
    ('noxyz.ply', b'ply\nformat ascii 1.0\nelement vertex 1\nproperty float a\nend_header\n1\n', 'no x, y, z'),
    ('faces.ply', b'ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n',
     'no vertex element'),
])
def test_bad_point_files_are_one_line_errors(tmp_path, name, content, words):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(ValueError, match=words) as info:
        load_points(path)
    assert str(path) in str(info.value)


def test_labels_written_to_a_bag_are_kept(tmp_path):
    """--out NAME without an extension writes a rosbag2 bag: the labels go into an int32 field
    'label' instead of being dropped."""
    from plane_validation.formats.bags import read_clouds
    from plane_validation.formats.pointcloud2 import structured_array
    labels = np.arange(len(POINTS)) % 3 - 1
    path = save_points(tmp_path / 'labelled', POINTS, labels)
    ((_, _, msg),) = list(read_clouds(path))
    cloud = structured_array(msg)
    np.testing.assert_array_equal(cloud['label'], labels)
    np.testing.assert_allclose(np.column_stack([cloud['x'], cloud['y'], cloud['z']]), POINTS, atol=1e-6)


def test_point_file_outputs_are_complete_or_absent(tmp_path):
    with pytest.raises(ValueError):
        save_points(tmp_path / 'bad.ply', POINTS, np.zeros(3))  # wrong label count: nothing written
    save_points(tmp_path / 'ok.pcd', POINTS, np.zeros(len(POINTS)))
    assert [p.name for p in tmp_path.iterdir()] == ['ok.pcd']  # no temporary leftovers


def test_points_and_labels_that_are_not_one_row_and_one_label_per_point_are_refused(tmp_path):
    """An outside probe: an (N, 4) x y z intensity array whose size divides by 3 was written as other points,
    and labels beyond an int32 or with fractions were cast silently."""
    xyzi = np.array([[1, 2, 3, 100], [4, 5, 6, 200], [7, 8, 9, 300.0]])
    for bad, why in [(xyzi, r'\(N, 3\) array'), (POINTS.T, 'transpose'), (POINTS.astype(str), 'real')]:
        with pytest.raises(ValueError, match=why):
            save_points(tmp_path / 'bad.ply', bad)
    n = len(POINTS)
    for labels, why in [(np.full(n, 2**31), 'fit an int32'), (np.full(n, 1.7), 'whole numbers'),
                        (np.zeros((n, 1)), 'one per point')]:
        with pytest.raises(ValueError, match=why):
            save_points(tmp_path / 'bad.ply', POINTS, labels)
    assert not any(tmp_path.iterdir())
    path = save_points(tmp_path / 'ok.npy', POINTS, np.arange(n, dtype=float) - 1)  # whole floats are labels
    np.testing.assert_array_equal(np.load(path)[:, 3], np.arange(n) - 1)


def test_an_organized_cloud_is_written_and_read_back_organized(tmp_path):
    from plane_validation.formats.files import load_cloud
    scene = scenes.depth_camera('table', width=80, height=60, seed=1)  # NaN holes included
    path = save_points(tmp_path / 'organized.pcd', scene.points, scene.labels, shape=scene.shape)
    points, shape = load_cloud(path)
    assert shape == (60, 80)
    np.testing.assert_array_equal(np.isnan(points), np.isnan(scene.points))
    np.testing.assert_allclose(points, scene.points.astype(np.float32), equal_nan=True)
    assert load_cloud(save_points(tmp_path / 'flat.pcd', scene.points))[1] is None
    with pytest.raises(ValueError, match='does not match'):
        save_points(tmp_path / 'bad.pcd', scene.points, shape=(10, 10))


@pytest.mark.parametrize('name', ['big.pcd', 'big.ply', 'big.mcap'])
def test_coordinates_beyond_float32_are_written_as_float64_not_inf(tmp_path, name):
    big = POINTS * 1e38  # up to about 1e38 m * 0.5: float32 ends at 3.4e38
    big[0] = (5e38, -7e38, 1.0)
    path = save_points(tmp_path / name, big, np.zeros(len(big), int))
    np.testing.assert_allclose(load_points(path if path.suffix != '.mcap' else f'{path}:/points:0'), big, rtol=1e-12)
    small = save_points(tmp_path / ('small' + Path(name).suffix), POINTS)  # meters stay float32
    np.testing.assert_array_equal(load_points(small if small.suffix != '.mcap' else f'{small}:/points:0'),
                                  POINTS.astype(np.float32).astype(np.float64))


@pytest.mark.parametrize('name', ['utm.pcd', 'utm.ply', 'utm.mcap', 'utm.xyz', 'utm.csv'])
def test_georeferenced_coordinates_keep_their_millimetres(tmp_path, name):
    utm = POINTS + (512_345.6789, 4_012_345.6789, 101.2345)  # float32 would round them to 0.25 m
    path = save_points(tmp_path / name, utm)
    back = load_points(path if path.suffix != '.mcap' else f'{path}:/points:0')
    np.testing.assert_allclose(back, utm, rtol=0, atol=1e-9)
    near = POINTS * 800  # within 838 m: float32 rounds by at most 0.06 mm
    path = save_points(tmp_path / ('near' + Path(name).suffix), near)
    back = load_points(path if path.suffix != '.mcap' else f'{path}:/points:0')
    assert np.abs(back - near).max() <= 1e-4
    if path.suffix not in ('.xyz', '.csv'):  # binary: float32
        np.testing.assert_array_equal(back, near.astype(np.float32).astype(np.float64))
    came_as_float32 = utm.astype(np.float32).astype(np.float64)  # float32 can write them without loss
    path = save_points(tmp_path / ('f32' + Path(name).suffix), came_as_float32)
    np.testing.assert_array_equal(load_points(path if path.suffix != '.mcap' else f'{path}:/points:0'), came_as_float32)
    if path.suffix == '.ply':
        assert b'property float x' in path.read_bytes()[:300]
    if path.suffix == '.pcd':
        assert b'SIZE 4 4 4' in path.read_bytes()[:300]


def test_an_organized_cloud_written_to_a_bag_reads_back_organized(tmp_path):
    from plane_validation.formats.files import load_cloud
    scene = scenes.depth_camera('table', width=80, height=60, seed=1)
    path = save_points(tmp_path / 'organized.mcap', scene.points, scene.labels, shape=scene.shape)
    points, shape = load_cloud(f'{path}:/points:0')
    assert shape == (60, 80)
    np.testing.assert_array_equal(np.isnan(points), np.isnan(scene.points))
    assert load_cloud(f'{save_points(tmp_path / "flat.mcap", scene.points)}:/points:0')[1] is None


def test_an_empty_text_file_is_an_empty_cloud_without_warnings(tmp_path):
    import warnings
    (tmp_path / 'empty.xyz').write_text('')
    (tmp_path / 'empty.pcd').write_bytes(b'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n'
                                         b'WIDTH 0\nHEIGHT 1\nPOINTS 0\nDATA ascii\n')
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        assert load_points(tmp_path / 'empty.xyz').shape == (0, 3)
        assert load_points(tmp_path / 'empty.pcd').shape == (0, 3)


def test_an_output_that_cannot_be_made_is_named_without_its_temporary_file(tmp_path):
    from plane_validation.formats.outputs import atomic_output
    target = tmp_path / 'gone' / 'x.ply'  # its folder vanished after the checks
    with pytest.raises(OSError, match=r'^cannot write .*/gone/x\.ply: No such file or directory$'):
        with atomic_output(target):
            pass
    folder = tmp_path / 'taken'
    folder.mkdir()
    (folder / 'x.ply').mkdir()  # a folder where the file goes: the final rename fails
    (folder / 'x.ply' / 'f').write_text('')
    with pytest.raises(OSError, match=r'^cannot write .*/taken/x\.ply: '):
        with atomic_output(folder / 'x.ply') as tmp:
            tmp.write_text('data')
    assert sorted(p.name for p in folder.iterdir()) == ['x.ply']  # no temporary file left


def test_a_text_table_may_start_with_a_row_of_column_names(tmp_path):
    rows = '0,0,0\n1,0,0\n0,1,0\n'
    cases = (('named.csv', 'x,y,z\n' + rows), ('plain.csv', rows), ('named.xyz', 'x y z\n' + rows.replace(',', ' ')),
             ('digits.csv', 'x,y,z,intensity_8bit\n' + rows.replace('\n', ',7\n')),
             ('quoted.csv', '"x","y","z"\n' + rows), ('bom.csv', '\ufeff' + rows),
             ('bom_named.csv', '\ufeffx,y,z\n' + rows), ('cloudcompare.csv', '//X,Y,Z\n' + rows))
    for name, text in cases:
        (tmp_path / name).write_text(text, encoding='utf-8')
        np.testing.assert_array_equal(load_points(tmp_path / name), [[0, 0, 0], [1, 0, 0], [0, 1, 0]], err_msg=name)
    (tmp_path / 'mixed.csv').write_text('x,1,2\n' + rows)  # a number among names: not a header
    (tmp_path / 'commas.xyz').write_text(rows)  # numbers with the wrong separator: not names either
    for name in ('mixed.csv', 'commas.xyz'):
        with pytest.raises(ValueError, match=r"not a table of numbers .*'(x|0,0,0)'.* at row 0"):
            load_points(tmp_path / name)


def test_a_header_row_says_which_columns_are_x_y_z(tmp_path):
    """An outside probe: the header was skipped but the first three columns read as x, y, z, so
    ``intensity,x,y,z`` gave (intensity, x, y) and ``z,y,x`` swapped x and z, silently."""
    xyz = np.array([[1.0, 2, 3], [4, 5, 6], [7, 8, 9]])
    cases = (('ixyz.csv', 'intensity,x,y,z', [3, 0, 1, 2]), ('zyx.csv', 'z,y,x', [2, 1, 0]),
             ('quoted.csv', '"Y","X","Z"', [1, 0, 2]), ('cloudcompare.txt', '//Z Y X R', [2, 1, 0, 3]),
             ('units.csv', 'i,z [m],y [m],x (m)', [3, 2, 1, 0]), ('units.xyz', 'y [m] x [m] z [m] i', [1, 0, 2, 3]),
             ('utm.csv', 'i,Northing,Easting,Height', [3, 1, 0, 2]), ('commas.txt', 'x,y,z,i', [0, 1, 2, 3]),
             ('comment.txt', '# i x y z', [3, 0, 1, 2]),  # names in a comment (the table reader skips it)
             ('remark.txt', '# exported by a scanner', [0, 1, 2, 3]))  # a comment of other words: no header
    for name, header, order in cases:
        table = np.column_stack([xyz, np.full(3, 7.0)])[:, order]
        sep = ',' if name.endswith('.csv') else ' '
        (tmp_path / name).write_text(header + '\n' + '\n'.join(sep.join(f'{v:g}' for v in row) for row in table))
        np.testing.assert_array_equal(load_points(tmp_path / name), xyz, err_msg=name)
    for name, text, why in (('noz.csv', 'intensity,x,y\n1,2,3\n', 'name each of x, y and z once .*, got the '
                                                                     'columns intensity, x, y'),
                            ('twice.csv', 'x,y,z,x\n1,2,3,4\n', 'name each of x, y and z once'),
                            ('none.csv', 'intensity,x_m,y_m,z_m\n1,2,3,4\n', 'name each of x, y and z once'),
                            ('wide.csv', 'intensity,x,y,z\n1,2,3\n', 'header row names 4 columns, the rows have 3')):
        (tmp_path / name).write_text(text)
        with pytest.raises(ValueError, match=why) as info:
            load_points(tmp_path / name)
        assert str(tmp_path / name) in str(info.value)


def test_rows_ending_in_a_comma_have_no_empty_last_column(tmp_path):
    """Some exporters end every CSV row with the delimiter ('1,2,3,'): the empty field after it was read as a
    fourth column and the file refused ("could not convert string ''"), with or without a header row."""
    xyz = [[1.0, 2, 3], [4, 5, 6], [7, 8, 9]]
    rows = '1,2,3,\n4,5,6,\n7,8,9,\n'
    for name, text in (('plain.csv', rows), ('named.csv', 'x,y,z,\n' + rows),
                       ('zyx.csv', 'z,y,x,\n3,2,1,\n6,5,4,\n9,8,7,\n'), ('remark.csv', '# exported\n' + rows),
                       ('header_only.csv', 'x,y,z,\n1,2,3\n4,5,6\n7,8,9\n')):
        (tmp_path / name).write_text(text)
        np.testing.assert_array_equal(load_points(tmp_path / name), xyz, err_msg=name)
    (tmp_path / 'ragged.csv').write_text('1,2,3\n4,5,6,\n')  # rows of other widths: said without numpy's advice
    with pytest.raises(ValueError, match=r'number of columns changed from 3 to 4 at row 2\)$'):
        load_points(tmp_path / 'ragged.csv')
    (tmp_path / 'gap.csv').write_text('1,,3\n4,5,6\n')  # an empty field inside a row is still no number
    with pytest.raises(ValueError, match="not a table of numbers"):
        load_points(tmp_path / 'gap.csv')


def test_a_folder_of_storage_files_without_metadata_names_them(tmp_path):
    bag = save_points(tmp_path / 'one.mcap', POINTS)
    folder = tmp_path / 'folder'
    folder.mkdir()
    bag.rename(folder / 'one.mcap')
    with pytest.raises(ValueError, match=r'folder: a directory without metadata\.yaml.*name the file \(one\.mcap\)'):
        load_points(folder)
    assert load_points(folder / 'one.mcap').shape == POINTS.shape


def test_a_pcds_viewpoint_is_the_sensor_origin_unless_given_and_is_written_back(tmp_path, capsys):
    """pcl writes where the sensor was (VIEWPOINT tx ty tz qw qx qy qz): detect takes it as the viewpoint,
    as --viewpoint-x/y/z would give it, and writes it into its labelled PCD."""
    import json

    from plane_validation.formats.files import pcd_viewpoint
    scene = scenes.depth_camera('room', seed=1)
    shift = np.array([0.3, -0.2, 1.5])
    moved = scene.points + shift
    plain = tmp_path / 'plain.pcd'
    save_points(plain, moved, shape=scene.shape)
    assert pcd_viewpoint(plain).tolist() == [0, 0, 0, 1, 0, 0, 0]
    located = tmp_path / 'located.pcd'
    save_points(located, moved, shape=scene.shape, viewpoint=shift)
    assert pcd_viewpoint(located).tolist() == [0.3, -0.2, 1.5, 1, 0, 0, 0]
    assert pcd_viewpoint(tmp_path / 'other.ply') is None

    def detect(path, *options):
        out = tmp_path / f'out{len(options)}{path.stem}.pcd'
        assert cli_main(['detect', str(path), '--tolerance', '0.005', '--noise-model', 'depth_quadratic',
                         '--json', '--out', str(out), *options]) == 0
        return json.loads(capsys.readouterr().out), out
    from_file, out = detect(located)
    by_hand, _ = detect(plain, '--viewpoint-x', '0.3', '--viewpoint-y', '-0.2', '--viewpoint-z', '1.5')
    at_origin, _ = detect(plain)
    assert from_file['viewpoint'] == by_hand['viewpoint'] == [0.3, -0.2, 1.5] and at_origin['viewpoint'] == [0, 0, 0]
    assert from_file['planes'] == by_hand['planes'] != at_origin['planes']
    assert pcd_viewpoint(out).tolist() == [0.3, -0.2, 1.5, 1, 0, 0, 0]
    overridden, out = detect(located, '--viewpoint-z', '0')  # one coordinate given: the others the file's
    assert overridden['viewpoint'] == [0.3, -0.2, 0.0]
    assert pcd_viewpoint(out).tolist() == [0.3, -0.2, 0.0, 1, 0, 0, 0]
    turned = tmp_path / 'turned.pcd'
    save_points(turned, moved, shape=scene.shape, viewpoint=[*shift, 0, 1, 0, 0])
    _, out = detect(turned)
    assert pcd_viewpoint(out).tolist() == [0.3, -0.2, 1.5, 0, 1, 0, 0]  # the orientation kept
    bad = tmp_path / 'bad.pcd'
    bad.write_bytes(plain.read_bytes().replace(b'VIEWPOINT 0.0 0.0 0.0 1.0 0.0 0.0 0.0', b'VIEWPOINT 0 0 x'))
    assert cli_main(['detect', str(bad), '--tolerance', '0.005']) == 2
    assert 'VIEWPOINT must be 7 numbers' in capsys.readouterr().err
    options = ['--viewpoint-x', '0', '--viewpoint-y', '0', '--viewpoint-z', '0']  # all given: the file's not needed
    assert cli_main(['detect', str(bad), '--tolerance', '0.005', *options]) == 0


def test_a_binary_pcd_with_less_than_a_point_of_padding_is_read():
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'padded.pcd'
        path.write_bytes(b'VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n'
                         b'POINTS 2\nDATA binary\n' + np.arange(6, dtype='<f4').tobytes() + b'\n')
        np.testing.assert_array_equal(load_points(path), np.arange(6.0).reshape(2, 3))


def test_a_set_of_outputs_refuses_one_file_twice_and_a_directory(tmp_path):
    from plane_validation.formats.outputs import atomic_outputs
    with pytest.raises(ValueError, match='the same file is given twice'):
        with atomic_outputs(tmp_path / 'a.csv', tmp_path / '.' / 'a.csv'):
            pass
    with pytest.raises(ValueError, match='is a directory'):
        with atomic_outputs(tmp_path / 'a.csv', tmp_path):
            pass
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize('suffix', ['.NPY', '.Npy', '.PLY', '.PCD', '.XYZ', '.TXT', '.CSV'])
def test_an_upper_case_suffix_writes_a_complete_file(tmp_path, suffix):
    """An outside probe: OUT.NPY was left empty and the data went to a hidden '.OUT.xxxx.NPY.npy' (np.save adds
    '.npy' to a name not ending in it)."""
    labels = np.arange(len(POINTS)) % 3 - 1
    path = save_points(tmp_path / f'out{suffix}', POINTS, labels)
    np.testing.assert_allclose(load_points(path), POINTS, atol=1e-6)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # nothing beside it
    if suffix.lower() == '.npy':
        np.testing.assert_array_equal(np.load(path)[:, 3], labels)


def test_detect_writes_an_upper_case_npy(tmp_path):
    np.save(tmp_path / 'corner.npy', POINTS)
    out = tmp_path / 'DET.NPY'
    assert cli_main(['detect', str(tmp_path / 'corner.npy'), '--tolerance', '0.02', '--out', str(out)]) == 0
    assert np.load(out).shape == (len(POINTS), 4)
    assert sorted(p.name for p in tmp_path.iterdir()) == ['DET.NPY', 'corner.npy']


@pytest.mark.parametrize('suffix', ['.MCAP', '.DB3', '.Mcap'])
def test_a_bag_written_with_an_upper_case_suffix_is_read_back(tmp_path, suffix):
    """rosbags picks a storage by its suffix, case-sensitively: B.MCAP was written but not read ("Unrecognized
    storage format '.MCAP'")."""
    path = save_points(tmp_path / f'b{suffix}', POINTS)
    np.testing.assert_allclose(load_points(path), POINTS, atol=1e-6)
    np.testing.assert_allclose(load_points(f'{path}:/points:0'), POINTS, atol=1e-6)


@pytest.mark.parametrize('data, body', [('ascii', b'1 2 3 4\n'), ('binary', np.arange(4, dtype='<f4').tobytes()),
                                        ('binary_compressed', bytes(24))])
def test_a_pcd_field_named_twice_is_refused(tmp_path, data, body):
    """An outside probe: an ascii PCD with two x fields was read with the first, while binary ones were refused
    (with numpy's words, not naming the file)."""
    path = tmp_path / 'twice.pcd'
    path.write_bytes(b'VERSION 0.7\nFIELDS x y z x\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 1\nHEIGHT 1\n'
                     b'POINTS 1\nDATA ' + data.encode() + b'\n' + body)
    with pytest.raises(ValueError, match=r"twice\.pcd: PCD field 'x' appears more than once \(FIELDS x y z x\)"):
        load_points(path)


def test_a_pcd_field_other_than_x_y_z_named_twice_is_read(tmp_path):
    """A review: 'FIELDS x y z intensity intensity' was read before the refusal of repeated fields; only x, y and z
    must be named once."""
    header = (b'VERSION 0.7\nFIELDS x y z intensity intensity\nSIZE 4 4 4 4 4\nTYPE F F F F F\nCOUNT 1 1 1 1 1\n'
              b'WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ')
    values = np.array([[1, 2, 3, 4, 5], [6, 7, 8, 9, 10]], '<f4')
    for data, body in (('ascii', b'1 2 3 4 5\n6 7 8 9 10\n'), ('binary', values.tobytes())):
        path = tmp_path / f'{data}.pcd'
        path.write_bytes(header + data.encode() + b'\n' + body)
        np.testing.assert_array_equal(load_points(path), [[1, 2, 3], [6, 7, 8]], err_msg=data)


def test_ply_and_npy_fields_are_matched_as_a_text_header_is(tmp_path):
    """An outside probe: a PLY with vertex properties X Y Z was refused, while a text header X Y Z is read."""
    def ply(name, names, row):
        properties = ''.join(f'property float {n}\n' for n in names)
        (tmp_path / name).write_text(f'ply\nformat ascii 1.0\nelement vertex 1\n{properties}end_header\n{row}\n')
        return tmp_path / name
    np.testing.assert_array_equal(load_points(ply('upper.ply', 'XYZ', '1 2 3')), [[1, 2, 3]])
    np.testing.assert_array_equal(load_points(ply('zyx.ply', 'ZYX', '3 2 1')), [[1, 2, 3]])
    np.testing.assert_array_equal(load_points(ply('height.ply', ['x', 'y', 'z', 'height'], '1 2 3 9')), [[1, 2, 3]])
    # x and X (a review: read with x before, refused for a while): the lower-case one
    np.testing.assert_array_equal(load_points(ply('both.ply', 'xXyz', '1 2 3 4')), [[1, 3, 4]])
    # a unit in the fields' names is converted, as in a header (a review: they were read as meters)
    np.testing.assert_allclose(load_points(ply('mm.ply', ['x(mm)', 'y(mm)', 'z(mm)'], '1000 2000 3000')), [[1, 2, 3]])
    records = np.zeros(2, [('X', 'f4'), ('Y', 'f4'), ('Z', 'f4')])
    records['X'], records['Y'], records['Z'] = 1, 2, 3
    np.save(tmp_path / 'upper.npy', records)
    np.testing.assert_array_equal(load_points(tmp_path / 'upper.npy'), [[1, 2, 3], [1, 2, 3]])


def test_cloudcompares_header_over_rows_split_by_commas(tmp_path):
    """An outside probe: '//X,Y,Z' was understood in a .txt, but then its rows '1,2,3' were no table of numbers."""
    for name, text in (('cc.txt', '//X,Y,Z\n1,2,3\n4,5,6\n'), ('cc.xyz', '//X,Y,Z,R,G,B\n1,2,3,0,0,0\n4,5,6,0,0,0\n'),
                       ('spaced.txt', 'x, y, z\n1, 2, 3\n4, 5, 6\n'), ('comment.txt', '# z,y,x\n3,2,1\n6,5,4\n')):
        (tmp_path / name).write_text(text)
        np.testing.assert_array_equal(load_points(tmp_path / name), [[1, 2, 3], [4, 5, 6]], err_msg=name)


def test_a_header_unit_is_converted_to_meters_and_a_unit_on_some_columns_is_refused(tmp_path):
    """An outside probe: 'x (mm)' was read as meters; points are in meters in ROS. A review: 'x y z (mm)' scaled z
    alone, and words in brackets that are no unit ('x (east)', 'x(1)') were refused."""
    for name, text in (('mm.txt', 'x (mm) y (mm) z (mm)\n1000 2000 3000\n'),
                       ('mixed.csv', 'i,z [m],y [cm],x [mm]\n7,3,200,1000\n'),
                       ('commas.xyz', '"X (MM)","Y (mm)","Z (mm)"\n1000,2000,3000\n'),
                       ('feet.csv', 'x (ft),y (ft),z (ft)\n3.2808398950131235,6.561679790026247,9.842519685039370\n'),
                       ('words.txt', 'x (east) y (north) z (up)\n1 2 3\n'), ('index.txt', 'x(1) y(1) z(1)\n1 2 3\n')):
        (tmp_path / name).write_text(text)
        np.testing.assert_allclose(load_points(tmp_path / name), [[1, 2, 3]], err_msg=name)
    for name, text in (('z.txt', 'x y z (mm)\n1 2 3\n'), ('x.csv', 'x [mm],y,z\n1,2,3\n')):
        (tmp_path / name).write_text(text)
        with pytest.raises(ValueError, match=re.escape(name) + r': only some of x, y and z give a unit'):
            load_points(tmp_path / name)


def test_a_comma_in_another_columns_name_does_not_split_a_header_on_commas(tmp_path):
    """A review: 'X Y Z R,G,B' over rows split by spaces was refused once commas split every header."""
    for name, text in (('rgb.txt', 'X Y Z R,G,B\n1 2 3 7\n'), ('tab.xyz', 'x\ty\tz\trgb(r,g,b)\n1\t2\t3\t7\n'),
                       ('plain.txt', 'x,y,z\n1 2 3\n')):
        (tmp_path / name).write_text(text)
        np.testing.assert_array_equal(load_points(tmp_path / name), [[1, 2, 3]], err_msg=name)




def test_staged_files_clear_the_stages_of_killed_runs_only(tmp_path, capfd):
    import os
    import subprocess
    import sys

    from plane_validation.formats.outputs import staged_files
    ended = subprocess.run([sys.executable, '-c', 'import os; print(os.getpid())'], capture_output=True, text=True)
    dead = int(ended.stdout)  # a process that has ended (and been reaped): its stage is stale
    out = tmp_path / 'out'
    out.mkdir()
    stale = out / f'.stage.{dead}.k1ll3d00.partial'
    held = out / f'.stage.{os.getpid()}.l1v3ab00.partial'
    for stage in (stale, held):
        stage.mkdir()
        (stage / 'figure.png').write_bytes(b'half')
    with staged_files(out) as stage:
        (stage / 'summary.md').write_text('done\n')
    assert sorted(p.name for p in out.iterdir()) == sorted([held.name, 'summary.md'])
    err = capfd.readouterr().err.splitlines()
    assert len(err) == 1 and str(stale) in err[0] and f'process {dead}' in err[0], err


def test_a_binary_pcd_with_bytes_after_its_points_is_refused_as_a_ply_is(tmp_path):
    path = tmp_path / 'p.pcd'
    save_points(path, scenes.corner(30, 0.0, seed=1).points)
    whole = path.read_bytes()
    for padding in (b'\n', b'\x00' * 5):  # a line end, NULs shorter than a point: padding, read as before
        path.write_bytes(whole + padding)
        assert load_points(path).shape == (30, 3)
    for junk in (b'JUNK', b'\x07\xff\x00'):  # shorter than a point, and not padding
        path.write_bytes(whole + junk)
        with pytest.raises(ValueError, match=r'p\.pcd: PCD data holds .* more than its 30 points need .*other data '
                                             r'appended'):
            load_points(path)


def test_detect_on_a_binary_file_named_as_text_shows_its_bytes_escaped(tmp_path, capsys):
    path = tmp_path / 'g.xyz'
    garbage = bytes(np.random.default_rng(0).integers(0, 128, 300, dtype=np.uint8))  # valid UTF-8, not text
    path.write_bytes(garbage)
    assert cli_main(['detect', str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.isprintable() and 'not a text file' in err and len(err) < 300, err
    path.write_bytes(b'\xa9\xb4' + garbage)  # not UTF-8 at all
    assert cli_main(['detect', str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.isprintable() and 'not a text file' in err and '\\xa9\\xb4' in err, err
