"""The committed sample bags in bags/ are what scripts/make_bags.py writes, and they decode.

The bags are regenerated into a temporary directory and both copies are opened with
``rosbags.rosbag2.Reader``. Storage files are not compared byte for byte (the MCAP header names the
rosbags version, SQLite files depend on the SQLite build); their content is: topics, types, type
hashes, QoS, message counts, timestamps, and sha256 of every message's CDR bytes and of the first
frame's decoded xyz.
"""
from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from plane_validation.formats.pointcloud2 import structured_array, xyz_array

rosbag2 = pytest.importorskip('rosbags.rosbag2')
typesys = pytest.importorskip('rosbags.typesys')

ROOT = Path(__file__).resolve().parents[1]
BAGS_DIR = ROOT / 'bags'
SCRIPT = ROOT / 'scripts' / 'make_bags.py'
MAX_TOTAL_BYTES = 5 * 1024 * 1024
TYPESTORE = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)


def _load_script():
    spec = importlib.util.spec_from_file_location('make_bags', SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault('make_bags', module)
    spec.loader.exec_module(module)
    return module


make_bags = _load_script()
NAMES = [b.name for b in make_bags.BAGS]
COMMITTED_TRUTH = json.loads((BAGS_DIR / 'truth.json').read_text('utf8'))


@pytest.fixture(scope='module')
def regenerated(tmp_path_factory):
    out = tmp_path_factory.mktemp('bags')
    truth = make_bags.make_all(out)
    return out, truth


def _read(path: Path) -> dict:
    """Everything about a bag that must be reproducible, plus the decoded messages."""
    with rosbag2.Reader(path) as reader:
        conns = [(c.topic, c.msgtype, c.digest, c.msgcount, c.ext.serialization_format,
                  tuple(c.ext.offered_qos_profiles)) for c in reader.connections]
        stamps, shas, msgs = [], [], []
        for conn, timestamp, raw in reader.messages():
            assert conn.topic == make_bags.TOPIC
            stamps.append(timestamp)
            shas.append(hashlib.sha256(bytes(raw)).hexdigest())
            msgs.append(TYPESTORE.deserialize_cdr(raw, conn.msgtype))
        info = dict(conns=conns, count=reader.message_count, start=reader.start_time,
                    end=reader.end_time, stamps=stamps, shas=shas)
    # metadata.yaml: the reader already checked it against the storage; keep the plain fields.
    text = (path / 'metadata.yaml').read_text('utf8')
    info['meta'] = {key: re.search(rf'^  {key}: (\S+)$', text, re.M).group(1)
                    for key in ('storage_identifier', 'version', 'message_count')}
    return info | {'msgs': msgs}


def _xyz_sha(msg) -> str:
    return hashlib.sha256(np.ascontiguousarray(xyz_array(msg), '<f8').tobytes()).hexdigest()


def _close(a, b, path='') -> None:
    """Recursive equality; floats to 1e-9 (truth.json values come from libm trigonometry)."""
    if isinstance(a, float) or isinstance(b, float):
        assert math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-9), f'{path}: {a} != {b}'
    elif isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), f'{path}: keys differ'
        for key in a:
            _close(a[key], b[key], f'{path}.{key}')
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), f'{path}: lengths differ'
        for i, (x, y) in enumerate(zip(a, b)):
            _close(x, y, f'{path}[{i}]')
    else:
        assert a == b, f'{path}: {a!r} != {b!r}'


def test_every_bag_is_committed():
    assert sorted(COMMITTED_TRUTH['bags']) == sorted(NAMES)
    for name in NAMES:
        assert (BAGS_DIR / name / 'metadata.yaml').is_file(), f'{name} has no metadata.yaml'
    assert (BAGS_DIR / 'README.md').is_file()


@pytest.mark.parametrize('name', NAMES)
def test_committed_bag_matches_regenerated(name, regenerated):
    out, truth = regenerated
    committed, fresh = _read(BAGS_DIR / name), _read(out / name)
    for key in ('conns', 'count', 'start', 'end', 'stamps', 'shas'):
        assert committed[key] == fresh[key], f'{name}: {key} differs; rerun scripts/make_bags.py'
    assert committed['meta'] == fresh['meta'], f'{name}: metadata.yaml differs'
    assert _xyz_sha(committed['msgs'][0]) == _xyz_sha(fresh['msgs'][0])
    entry = COMMITTED_TRUTH['bags'][name]
    assert committed['shas'][0] == entry['first_frame_cdr_sha256'] == \
        truth['bags'][name]['first_frame_cdr_sha256']
    assert _xyz_sha(committed['msgs'][0]) == entry['first_frame_xyz_sha256']


@pytest.mark.parametrize('name', NAMES)
def test_bag_layout_and_decoding(name):
    entry = COMMITTED_TRUTH['bags'][name]
    bag = _read(BAGS_DIR / name)
    assert [c[:2] for c in bag['conns']] == [('/points', 'sensor_msgs/msg/PointCloud2')]
    assert bag['count'] == entry['frames'] == 5
    assert bag['meta'] == {'storage_identifier': entry['storage'], 'version': '9',
                           'message_count': '5'}
    expected_stamps = [make_bags.START_NS + k * make_bags.PERIOD_NS for k in range(5)]
    assert bag['stamps'] == expected_stamps
    for k, msg in enumerate(bag['msgs']):
        frame = entry['per_frame'][k]
        assert msg.header.frame_id == 'sensor'
        assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == expected_stamps[k]
        assert [f.name for f in msg.fields] == entry['fields']
        assert (msg.height, msg.width) == (entry['height'], entry['width'])
        xyz = xyz_array(msg)
        assert xyz.shape == (entry['points_per_frame'], 3)
        finite = np.isfinite(xyz).all(axis=1)
        assert int(finite.sum()) == frame['valid_points']
        x_type = {f.name: f.datatype for f in msg.fields}['x']
        assert x_type == (8 if entry['xyz_dtype'] == 'float64' else 7)
        if entry['organized']:
            assert msg.height > 1 and msg.width > 1
            assert not msg.is_dense
            assert 0 < (~finite).sum() < 0.6 * len(xyz), 'organized frames need some NaN holes'
            assert np.isnan(xyz[~finite]).all(), 'holes are NaN in x, y and z'
            extra = [f for f in entry['fields'] if f not in ('x', 'y', 'z')]
            for field in extra:
                assert (structured_array(msg)[field][~finite].view(np.uint32) == 0).all()
        else:
            assert msg.height == 1 and msg.is_dense and finite.all()
    # Frames differ: the sensor moves and every frame is a new sample.
    assert len(set(bag['shas'])) == len(bag['shas'])


@pytest.mark.parametrize('name', NAMES)
def test_truth_planes_fit_the_points(name):
    """In every frame each true plane holds at least its labelled points within the noise."""
    entry = COMMITTED_TRUTH['bags'][name]
    bag = _read(BAGS_DIR / name)
    assert entry['n_planes'] == len(entry['true_planes'])
    tol = entry['noise'] + 1e-5  # float32 rounding of coordinates up to ~6 m
    for k, msg in enumerate(bag['msgs']):
        frame = entry['per_frame'][k]
        xyz = xyz_array(msg)
        xyz = xyz[np.isfinite(xyz).all(axis=1)]
        planes = np.array(frame['planes'], dtype=float).reshape(-1, 4)
        assert len(planes) == entry['scene_planes']
        assert np.allclose(np.linalg.norm(planes[:, :3], axis=1), 1.0)
        for i in entry['true_planes']:
            dist = np.abs(xyz @ planes[i, :3] + planes[i, 3])
            assert (dist <= tol).sum() >= frame['plane_points'][i], f'{name} frame {k} plane {i}'
            assert frame['plane_points'][i] >= make_bags.VISIBLE_FRACTION * frame['valid_points']
        if entry['scene_planes'] == 0:  # the sphere: nothing planar
            assert entry['n_planes'] == 0


def test_expected_scenes_and_noise():
    bags = COMMITTED_TRUTH['bags']
    corners = sorted(b['noise'] for b in bags.values() if b['scene'] == 'corner')
    assert corners == pytest.approx([0.0, 0.025, 0.075])
    assert {b['scene'] for b in bags.values()} >= {'corner', 'cube', 'room', 'stairs', 'table',
                                                   'sphere'}
    assert all(b['n_planes'] == 3 for b in bags.values() if b['scene'] == 'corner')
    assert bags['sphere']['n_planes'] == 0
    assert sum(b['organized'] for b in bags.values()) >= 2
    assert {b['storage'] for b in bags.values()} == {'mcap', 'sqlite3'}


def test_both_storage_plugins_on_disk():
    assert list(BAGS_DIR.glob('*/*.mcap')), 'no MCAP bag'
    assert list(BAGS_DIR.glob('*/*.db3')), 'no sqlite3 bag'


def test_truth_and_readme_match_regenerated(regenerated):
    out, truth = regenerated
    _close(COMMITTED_TRUTH, json.loads((out / 'truth.json').read_text('utf8')), 'truth')
    _close(COMMITTED_TRUTH, json.loads(json.dumps(truth)), 'truth')
    assert (BAGS_DIR / 'README.md').read_text('utf8') == (out / 'README.md').read_text('utf8')
    readme = (BAGS_DIR / 'README.md').read_text('utf8')
    for name in NAMES:
        assert f'`{name}/`' in readme


def test_bags_dir_is_small():
    # not the bags/<bag>.planes outputs `plane-validation replay bags/cube` (the README's example) writes there
    total = sum(f.stat().st_size for f in BAGS_DIR.rglob('*')
                if f.is_file() and not any(part.endswith('.planes') for part in f.relative_to(BAGS_DIR).parts))
    assert total < MAX_TOTAL_BYTES, f'bags/ holds {total / 1e6:.2f} MB'


def test_script_runs_standalone(tmp_path):
    out = tmp_path / 'out'
    proc = subprocess.run([sys.executable, str(SCRIPT), '--out', str(out)], capture_output=True,
                          text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    for name in NAMES:
        assert (out / name / 'metadata.yaml').is_file()
    # Rerunning over existing output replaces the bags instead of failing.
    again = subprocess.run([sys.executable, str(SCRIPT), '--out', str(out)], capture_output=True,
                           text=True, timeout=120, cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert sorted(json.loads((out / 'truth.json').read_text('utf8'))['bags']) == sorted(NAMES)
