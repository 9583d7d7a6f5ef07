"""Replay of the bundled bags (rosbags, offline and live over DDS) and bad bags."""
from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from plane_validation import scenes
from plane_validation.app.pipeline import PipelineConfig
from plane_validation.cli import main as cli_main
from plane_validation.formats.pointcloud2 import create_cloud, rosbags_types, structured_array
from plane_validation.ros.replay import ReplayError, output_topics, replay_live, replay_offline

pytestmark = pytest.mark.ros  # rclpy and the ROS message packages (and DDS for node tests)

ROOT = Path(__file__).resolve().parents[1]
BAGS = ROOT / 'bags'
TRUTH = json.loads((BAGS / 'truth.json').read_text())['bags']
TS2 = get_typestore(Stores.ROS2_JAZZY)
TS1 = get_typestore(Stores.ROS1_NOETIC)


def _read_output(path: Path) -> dict[str, list]:
    """topic -> list of (timestamp, message) of an output bag, re-opened with rosbags."""
    out: dict[str, list] = {}
    with AnyReader([path], default_typestore=TS2) as reader:
        for conn, ts, raw in reader.messages():
            out.setdefault(conn.topic, []).append((ts, reader.deserialize(raw, conn.msgtype)))
    return out


@pytest.mark.parametrize('name', sorted(TRUTH))
def test_every_bundled_bag_replays_offline_as_documented(name, tmp_path):
    truth = TRUTH[name]
    out = tmp_path / 'out'
    summary = replay_offline(BAGS / name, out=out, echo=None)
    assert len(summary.frames) == truth['frames']
    counts = [f.n_planes for f in summary.frames]
    e = truth['noise']
    tolerance = summary.frames[-1].tolerance
    if truth['n_planes'] == 0:
        assert all(f.level == 1 for f in summary.frames), [f.message for f in summary.frames]
        assert all('no reliable planes' in f.message for f in summary.frames)
    else:
        assert set(counts) == {truth['n_planes']}, counts
        if e > 0:
            assert e <= tolerance <= 3 * e, tolerance
        else:
            assert tolerance < 0.005
        if truth['scene'] in ('corner', 'cube', 'room', 'table'):
            assert all(f.level == 0 for f in summary.frames), [f.message for f in summary.frames]

    recorded = _read_output(out)
    expected_topics = {truth['topic'], *output_topics().values()}
    assert set(recorded) == expected_topics
    in_stamps = [ts for ts, _ in recorded[truth['topic']]]
    assert in_stamps == [f['timestamp_ns'] for f in truth['per_frame']]
    for topic in expected_topics:
        assert [ts for ts, _ in recorded[topic]] == in_stamps, topic  # one per frame, at the input's time
    last = recorded[output_topics()['segmented']][-1][1]
    assert last.header.frame_id == truth['frame_id']
    labels = structured_array(last)['plane_id']
    assert len(set(labels.tolist()) - {-1}) == counts[-1]  # track ids: not 0..k-1 once surfaces come and go
    diag = recorded['/diagnostics'][-1][1].status[0]
    assert {kv.key for kv in diag.values} >= {'gs_planes', 'dunn', 'davies_bouldin', 'tolerance', 'planes'}


def test_live_replay_matches_offline_for_the_same_seed(tmp_path):
    bag = BAGS / 'corner_e025'
    offline = replay_offline(bag, out=tmp_path / 'offline', echo=None)
    start = time.monotonic()
    live = replay_live(bag, out=tmp_path / 'live', rate=1.0, echo=None)
    # the wait for the first sweep ends with the sweep (about 2 s here), not at its 60 s time-out
    assert time.monotonic() - start < 40
    assert live.frames, 'the node answered no frame'
    by_stamp = {f.timestamp: f for f in offline.frames}
    # live replay waits for the first frame's sweep (as offline replay runs it before the second frame):
    # every frame answered is answered as offline answers it, all but the first with the tuned t
    matched = set()
    for frame in live.frames:  # frames the node dropped under load have no answer
        ref = by_stamp[frame.timestamp]
        assert (frame.n_planes, frame.plane_ids, frame.tolerance_source) == (
            ref.n_planes, ref.plane_ids, ref.tolerance_source), frame.line()
        assert frame.tolerance == pytest.approx(ref.tolerance, rel=1e-5)
        assert frame.gs_planes == pytest.approx(ref.gs_planes, rel=1e-5)
        assert frame.tolerance_source.startswith('tuned') == (frame.index > 0), frame.tolerance_source
        matched.add(frame.timestamp)
    assert len(matched) >= len(offline.frames) - 1
    off_seg = {ts: structured_array(m)['plane_id'] for ts, m in _read_output(tmp_path / 'offline')[
        output_topics()['segmented']]}
    live_seg = _read_output(tmp_path / 'live')[output_topics()['segmented']]
    assert live_seg
    for ts, msg in live_seg:
        if ts in matched:
            np.testing.assert_array_equal(structured_array(msg)['plane_id'], off_seg[ts])
    # coefficients carry no header: they must still be recorded at their own frame's time
    topic = output_topics()['plane_coefficients']
    off_coeffs = dict(_read_output(tmp_path / 'offline')[topic])
    live_coeffs = _read_output(tmp_path / 'live')[topic]
    assert [ts for ts, _ in live_coeffs] == [ts for ts, _ in live_seg]
    for ts, msg in live_coeffs:
        if ts in matched:
            np.testing.assert_allclose(msg.data, off_coeffs[ts].data)


def _cloud_msg(ts, points, stamp_ns, family_types):
    header_cls, time_cls = ts.types['std_msgs/msg/Header'], ts.types['builtin_interfaces/msg/Time']
    stamp = time_cls(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    fields = {name: f.default for name, f in header_cls.__dataclass_fields__.items()
              if name not in ('stamp', 'frame_id') and not name.startswith('__')}
    header = header_cls(stamp=stamp, frame_id='sensor', **{k: 0 for k in fields})
    pts = points.astype(np.float32)
    return create_cloud(header, {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2]}, types=family_types)


def test_compressed_and_ros1_bags_replay(tmp_path):
    points = scenes.corner(1500, 1.0, scale=0.01, seed=3).points
    # rosbag2 with per-file zstd compression
    comp = tmp_path / 'compressed'
    writer = Writer(comp, version=9, storage_plugin=StoragePlugin.SQLITE3)
    writer.set_compression(CompressionMode.FILE, CompressionFormat.ZSTD)
    with writer:
        conn = writer.add_connection('/cam/points', 'sensor_msgs/msg/PointCloud2', typestore=TS2)
        for k in range(2):
            msg = _cloud_msg(TS2, points, 10**18 + k * 10**8, rosbags_types(TS2))
            writer.write(conn, 10**18 + k * 10**8, TS2.serialize_cdr(msg, 'sensor_msgs/msg/PointCloud2'))
    summary = replay_offline(comp, out=tmp_path / 'comp_out', echo=None)
    assert [f.n_planes for f in summary.frames] == [3, 3]
    # ROS 1 bag
    bag1 = tmp_path / 'old.bag'
    with Writer1(bag1) as writer:
        conn = writer.add_connection('/points', 'sensor_msgs/msg/PointCloud2', typestore=TS1)
        for k in range(2):
            msg = _cloud_msg(TS1, points, 10**18 + k * 10**8, rosbags_types(TS1))
            writer.write(conn, 10**18 + k * 10**8, TS1.serialize_ros1(msg, 'sensor_msgs/msg/PointCloud2'))
    summary = replay_offline(bag1, out=tmp_path / 'ros1_out', echo=None)
    assert [f.n_planes for f in summary.frames] == [3, 3]
    assert set(_read_output(tmp_path / 'ros1_out')) >= {'/points', '/diagnostics'}



def test_live_replay_puts_the_answers_to_frames_with_one_stamp_at_their_own_frames(tmp_path):
    """Five clouds with header stamp 0 (a driver that leaves it unset) at bag times 1-5 s: live, each
    answer and its outputs are recorded at its own frame's time, as offline."""
    bag = tmp_path / 'frozen'
    with Writer(bag, version=9) as writer:
        conn = writer.add_connection('/points', 'sensor_msgs/msg/PointCloud2', typestore=TS2)
        for k in range(5):
            points = scenes.corner(1500, 1.0, scale=0.01, seed=k).points
            msg = _cloud_msg(TS2, points, 0, rosbags_types(TS2))
            writer.write(conn, (k + 1) * 10**9, TS2.serialize_cdr(msg, 'sensor_msgs/msg/PointCloud2'))
    config = PipelineConfig(auto_tune=False, tolerance=0.03)
    offline = replay_offline(bag, out=tmp_path / 'offline', config=config, echo=None)
    live = replay_live(bag, out=tmp_path / 'live', rate=2.0, config=config, echo=None)
    times = [(k + 1) * 10**9 for k in range(5)]
    assert [f.timestamp for f in offline.frames] == times
    assert [f.timestamp for f in live.frames] == times and [f.index for f in live.frames] == list(range(5))
    outputs = _read_output(tmp_path / 'live')
    for topic in (output_topics()['segmented'], output_topics()['plane_coefficients'], '/diagnostics'):
        assert [ts for ts, _ in outputs[topic]] == times, topic
    off_seg = [structured_array(m)['plane_id'] for _, m in _read_output(tmp_path / 'offline')[
        output_topics()['segmented']]]
    for (_, msg), ref in zip(outputs[output_topics()['segmented']], off_seg):
        np.testing.assert_array_equal(structured_array(msg)['plane_id'], ref)


def _copy(name: str, tmp_path: Path) -> Path:
    dst = tmp_path / name
    shutil.copytree(BAGS / name, dst)
    return dst


def _bad_bags(tmp_path: Path) -> list[tuple[str, Path, dict, str]]:
    corrupt = _copy('corner_e025', tmp_path / 'c')  # sqlite3
    db = next(corrupt.glob('*.db3'))
    db.write_bytes(b'this is not a sqlite database' * 100)
    truncated = _copy('corner_e0', tmp_path / 't')  # mcap
    mcap = next(truncated.glob('*.mcap'))
    mcap.write_bytes(mcap.read_bytes()[: mcap.stat().st_size // 3])
    no_meta = _copy('cube', tmp_path / 'm')
    (no_meta / 'metadata.yaml').unlink()
    empty = tmp_path / 'empty'
    with Writer(empty, version=9) as writer:
        writer.add_connection('/points', 'sensor_msgs/msg/PointCloud2', typestore=TS2)
    wrong = tmp_path / 'wrong'
    with Writer(wrong, version=9) as writer:
        conn = writer.add_connection('/chatter', 'std_msgs/msg/String', typestore=TS2)
        writer.write(conn, 1, TS2.serialize_cdr(TS2.types['std_msgs/msg/String'](data='hi'), 'std_msgs/msg/String'))
    return [('missing', tmp_path / 'nope', {}, 'not found'),
            ('corrupt', corrupt, {}, str(corrupt)),
            ('truncated', truncated, {}, f'{truncated}: File end magic is invalid. (the MCAP file ends early'),
            ('no metadata', no_meta, {}, str(no_meta)),
            ('empty', empty, {}, 'no messages'),
            ('wrong type', wrong, {'topic': '/chatter'}, 'not sensor_msgs/msg/PointCloud2'),
            ('no cloud topic', wrong, {}, 'no sensor_msgs/msg/PointCloud2 topic in the bag (its topics: /chatter'),
            ('missing topic', BAGS / 'cube', {'topic': '/other'}, "no topic '/other'")]


def test_bad_bags_fail_clearly_without_output(tmp_path):
    for what, bag, kwargs, needle in _bad_bags(tmp_path):
        out = tmp_path / f'out_{what.replace(" ", "_")}'
        with pytest.raises(ReplayError) as info:
            replay_offline(bag, out=out, echo=None, **kwargs)
        assert needle in str(info.value), (what, str(info.value))
        assert not out.exists(), what
        assert not list(tmp_path.glob(f'.{out.name}*')), what  # no unfinished bag left behind


def test_existing_output_is_not_overwritten(tmp_path):
    out = tmp_path / 'out'
    out.mkdir()
    with pytest.raises(ReplayError, match='already exists'):
        replay_offline(BAGS / 'cube', out=out, echo=None)


def test_cli_replay_prints_frames_and_summary(tmp_path, capsys):
    assert cli_main(['replay', str(BAGS / 'cube'), '--out', str(tmp_path / 'o'), '--fixed', '--tolerance', '0.03']) == 0
    text = capsys.readouterr().out
    assert text.count('frame ') >= 5
    assert 'planes  6' in text
    assert '5 frames from' in text
    assert cli_main(['replay', str(tmp_path / 'missing')]) == 2
    assert 'bag not found' in capsys.readouterr().err
    # a point file is no bag: said so, not rosbags' "Unrecognized storage format '.pcd'"
    (tmp_path / 'frame.pcd').write_text('VERSION .7\n')
    assert cli_main(['replay', str(tmp_path / 'frame.pcd')]) == 2
    err = capsys.readouterr().err
    assert 'frame.pcd: not a bag (a rosbag2 directory, or a .mcap, .db3, .bag file): a point file, which detect' in err
    assert 'Unrecognized' not in err
    # a tolerance on its own is used as is (auto-tuning off), as in detect
    assert cli_main(['replay', str(BAGS / 'cube'), '--out', str(tmp_path / 'p'), '--tolerance', '0.005']) == 0
    text = capsys.readouterr().out
    assert text.count('tolerance 0.005 m  ') == 5, text  # the 5 frames (the summary names it once more)
    with pytest.raises(SystemExit):
        cli_main(['replay', str(BAGS / 'cube'), '--rate', '-5'])
    assert 'must be a finite number > 0' in capsys.readouterr().err


def test_an_output_topic_of_the_node_cannot_be_replayed_into_it(tmp_path):
    first = tmp_path / 'first'
    replay_offline(BAGS / 'cube', out=first, echo=None, config=PipelineConfig(auto_tune=False))
    out = tmp_path / 'second'
    with pytest.raises(ReplayError, match="one of the node's output topics"):
        replay_offline(first, topic='/plane_validation/segmented', out=out, echo=None)
    assert not out.exists() and not list(tmp_path.glob('.second*'))


def _data_files(bag: Path) -> list[str]:
    return sorted(p.name for p in bag.iterdir() if p.name != 'metadata.yaml')


def test_mcap_input_gives_mcap_output_decoded_by_foxglove_readers(tmp_path):
    """room is an MCAP bag: the output is MCAP too, named as rosbag2 names it, and Foxglove's own
    reader (mcap + mcap-ros2-support, not rosbags) decodes every message."""
    make_reader = pytest.importorskip('mcap.reader').make_reader
    DecoderFactory = pytest.importorskip('mcap_ros2.decoder').DecoderFactory

    out = tmp_path / 'room_offline'
    summary = replay_offline(BAGS / 'room', out=out, echo=None)
    assert _data_files(out) == ['room_offline_0.mcap']
    assert '- room_offline_0.mcap' in (out / 'metadata.yaml').read_text()
    counts: dict[str, int] = {}
    with open(out / 'room_offline_0.mcap', 'rb') as f:
        for _, channel, _, decoded in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == '/diagnostics':
                assert decoded.status[0].name == 'plane_validation: plane detection'
            if channel.topic == '/plane_validation/plane_coefficients':
                assert len(decoded.data) % 4 == 0
    frames = len(summary.frames)
    assert frames >= 2 and counts == {topic: frames for topic in [summary.topic, *output_topics().values()]}


def test_storage_option_and_sqlite_input(tmp_path):
    out = tmp_path / 'cube_as_mcap'
    assert cli_main(['replay', str(BAGS / 'cube'), '--out', str(out), '--storage', 'mcap', '--fixed']) == 0
    assert _data_files(out) == ['cube_as_mcap_0.mcap']
    replay_offline(BAGS / 'cube', out=tmp_path / 'cube_out', echo=None)  # cube is sqlite3
    assert _data_files(tmp_path / 'cube_out') == ['cube_out_0.db3']
    with AnyReader([tmp_path / 'cube_out'], default_typestore=TS2) as reader:
        assert sum(c.msgcount for c in reader.connections if c.topic == '/diagnostics') == 5


@pytest.mark.parametrize('sig, status', [('SIGTERM', 143), ('SIGHUP', 129)])
def test_signal_during_replay_leaves_no_output(tmp_path, sig, status):
    import os
    import signal
    import subprocess
    import sys
    out = tmp_path / 'out'
    proc = subprocess.Popen([sys.executable, '-u', '-m', 'plane_validation.cli', 'replay', str(BAGS / 'room'),
                             '--out', str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ))
    try:
        first = proc.stdout.readline()  # the first frame is written: the bag is half done
        assert first.startswith('frame    0') and list(tmp_path.glob('.out.*')), first
        proc.send_signal(getattr(signal, sig))
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == status, err
    assert list(tmp_path.iterdir()) == [], 'an unfinished output was left behind'
    assert 'Traceback' not in err


def test_a_topic_with_two_message_types_names_both(tmp_path):
    bag = tmp_path / 'mixed'
    with Writer(bag, version=9) as writer:
        writer.add_connection('/points', 'sensor_msgs/msg/PointCloud2', typestore=TS2)
        writer.add_connection('/points', 'std_msgs/msg/String', typestore=TS2)
    with pytest.raises(ReplayError) as info:
        replay_offline(bag, topic='/points', out=tmp_path / 'o', echo=None)
    assert 'sensor_msgs/msg/PointCloud2 and std_msgs/msg/String' in str(info.value)


def test_a_live_summary_says_where_the_unanswered_clouds_went():
    from plane_validation.app.diagnostics import Level
    from plane_validation.app.summary import FrameSummary, ReplaySummary
    frames = [FrameSummary(i, i, 5, 0.02, 0.3, Level.OK, 'ok', 50.0) for i in (0, 4)]
    line = ReplaySummary(bag=Path('bags/room'), topic='/points', output=None, frames=frames, dropped=2, sent=5).line()
    assert '2 frames from bags/room [/points] (5 sent: 2 dropped by the busy node, 1 lost before it' in line
    offline = ReplaySummary(bag=Path('bags/room'), topic='/points', output=None, frames=frames).line()
    assert 'sent' not in offline and 'dropped' not in offline



def test_the_summary_median_counts_only_frames_that_were_searched(tmp_path):
    # three frames rejected in 0.0-0.1 ms set the median to 0.1 ms beside two searched in 55-113 ms
    from plane_validation.app.diagnostics import Diagnostic, Level
    from plane_validation.app.summary import FrameSummary, ReplaySummary
    searched = Diagnostic(Level.OK, 'ok', (('planes', '6'), ('stop_reason', 'fewer than 3 points left'),
                                           ('processing_ms', '80.0')))
    rejected = Diagnostic(Level.WARN, 'too few valid points', (('planes', '0'), ('processing_ms', '0.1')))
    frames = [FrameSummary.from_diagnostic(i, i, d) for i, d in enumerate([rejected] * 3 + [searched] * 2)]
    assert [f.searched for f in frames] == [False] * 3 + [True] * 2
    line = ReplaySummary(bag=Path('b'), topic='/points', output=None, frames=frames).line()
    assert '3 rejected before the search; median 80.0 ms per searched frame' in line
    line = ReplaySummary(bag=Path('b'), topic='/points', output=None, frames=frames[:3]).line()
    assert '3 rejected before the search; last tolerance' in line and 'median' not in line


def test_an_output_bag_made_meanwhile_by_another_run_is_kept_and_this_one_says_so(tmp_path):
    from plane_validation.formats.bags import BagError
    from plane_validation.ros.recorder import BagRecorder
    out = tmp_path / 'same.planes'
    recorder = BagRecorder(out, '/points', 'plane_validation', 'mcap')
    out.mkdir()
    (out / 'theirs').write_text('kept')  # the other run finished first
    with pytest.raises(BagError, match='appeared while this replay ran'):
        recorder.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == ['same.planes']
    assert (out / 'theirs').read_text() == 'kept'


def test_a_malformed_bag_message_is_named_with_its_index(tmp_path, capsys):
    import dataclasses
    bag = tmp_path / 'bad'
    good = _cloud_msg(TS2, scenes.corner(500, 1.0, scale=0.01, seed=3).points, 10**18, rosbags_types(TS2))
    short = dataclasses.replace(good, data=good.data[: len(good.data) // 2])  # half its bytes
    with Writer(bag, version=9) as writer:
        conn = writer.add_connection('/points', 'sensor_msgs/msg/PointCloud2', typestore=TS2)
        for k, msg in enumerate((good, short)):
            writer.write(conn, 10**18 + k, TS2.serialize_cdr(msg, 'sensor_msgs/msg/PointCloud2'))
    assert cli_main(['detect', f'{bag}:/points:1', '--tolerance', '0.02']) == 2
    assert f'{bag}:/points:1: PointCloud2.data is too short' in capsys.readouterr().err


def test_answers_to_frames_with_one_stamp_skip_the_frames_the_node_dropped():
    """Four frames stamped 0; the node answers the first, drops the second and third (saying so in its
    next diagnostics) and answers the fourth, whose cloud arrives before its diagnostics."""
    from sensor_msgs.msg import PointCloud2
    from std_msgs.msg import Header

    from plane_validation.app.diagnostics import Diagnostic, Level
    from plane_validation.ros.messages import diagnostics, status_name
    from plane_validation.ros.pairing import OutputPairing

    pairing = OutputPairing('pv', [0, 0, 0, 0, 5], [10, 20, 30, 40, 50])
    header = Header()

    def answer(dropped: int):
        values = (('planes', '1'), ('frames_dropped_since_last', str(dropped)))
        return diagnostics(header, Diagnostic(Level.OK, 'ok', values), status_name('pv'))
    cloud = PointCloud2(header=header)
    for index in range(4):
        pairing.published(index)
    pairing.receive('segmented', cloud)
    pairing.receive('diagnostics', answer(0))
    pairing.receive('segmented', cloud)  # before its diagnostics: placed once they come
    assert [ts for _, ts, _ in pairing.take()] == [10, 10]
    pairing.receive('diagnostics', answer(2))
    assert sorted((key, ts) for key, ts, _ in pairing.take()) == [('diagnostics', 40), ('segmented', 40)]
    assert [f.index for f in pairing.frames] == [0, 3] and pairing.dropped == 2 and not pairing.answered_last()


def test_a_cloud_lost_before_the_node_neither_places_answers_on_unplayed_frames_nor_hangs_the_drain():
    """Three frames stamped 0, the second lost on the way (counted nowhere): the answer to the third goes to
    the frame before it (unknowable), never past the frames played, and the drain ends once the node is quiet."""
    import time

    from std_msgs.msg import Header

    from plane_validation.app.diagnostics import Diagnostic, Level
    from plane_validation.ros.messages import diagnostics, status_name
    from plane_validation.ros.pairing import OutputPairing

    pairing = OutputPairing('pv', [0, 0, 0], [10, 20, 30])
    answer = diagnostics(Header(), Diagnostic(Level.OK, 'ok', (('planes', '1'), ('frames_dropped_since_last', '0'))),
                         status_name('pv'))
    pairing.published(0)
    pairing.receive('diagnostics', answer)
    pairing.published(1)  # lost
    assert not pairing.answered_last(quiet=0.0)
    pairing.published(2)
    assert not pairing.answered_last(quiet=0.0)  # nothing came after the last frame was played
    pairing.receive('diagnostics', answer)
    assert [f.index for f in pairing.frames] == [0, 1]
    assert not pairing.answered_last(quiet=60.0) and pairing.answered_last(quiet=0.0)
    time.sleep(0.05)
    assert pairing.answered_last(quiet=0.05)
    early = OutputPairing('pv', [0, 0, 0], [10, 20, 30])
    early.published(0)
    early.receive('diagnostics', answer)
    early.receive('diagnostics', answer)  # an answer cannot be to a frame not played yet
    assert [f.index for f in early.frames] == [0, 0]


def test_answers_that_cannot_be_to_this_bags_frames_are_ignored_and_a_slow_node_is_waited_for():
    """A node already running (--no-node) answers clouds of another publisher: an answer before any frame
    was played is not this bag's, and drops it counts beyond the frames played do not jump past the
    frames not yet answered. A node that takes 1 s a frame is waited for three times that."""
    from std_msgs.msg import Header

    from plane_validation.app.diagnostics import Diagnostic, Level
    from plane_validation.ros.messages import diagnostics, status_name
    from plane_validation.ros.pairing import OutputPairing

    def answer(dropped: int, ms: float = 50.0):
        values = (('planes', '1'), ('frames_dropped_since_last', str(dropped)), ('processing_ms', str(ms)))
        return diagnostics(Header(), Diagnostic(Level.OK, 'ok', values), status_name('pv'))
    pairing = OutputPairing('pv', [0, 0, 0], [10, 20, 30])
    pairing.receive('diagnostics', answer(0))  # before the bag was played: another publisher's cloud
    assert pairing.frames == [] and pairing.take() == []
    for index in range(3):
        pairing.published(index)
    pairing.receive('diagnostics', answer(3))  # 3 drops, some of them another publisher's clouds
    assert [f.index for f in pairing.frames] == [0] and not pairing.answered_last(quiet=0.0)
    pairing.receive('diagnostics', answer(0, ms=1000.0))
    assert [f.index for f in pairing.frames] == [0, 1]
    assert not pairing.answered_last(quiet=0.0)  # quiet for less than 3 x 1 s: the last frame may come
    pairing.receive('diagnostics', answer(0))
    assert [f.index for f in pairing.frames] == [0, 1, 2] and pairing.answered_last(quiet=60.0)


def test_an_output_bag_with_frames_without_planes_is_read_back_by_rosbags_and_rclpy_and_is_reproducible(tmp_path):
    # rclpy's CDR ended an empty float64 sequence with alignment bytes (rosbags: "CDR message size mismatch"
    # on the plane coefficients of a frame without planes) and left padding bytes uninitialized
    from rclpy.serialization import deserialize_message
    from rosbags.highlevel import AnyReader as Reader
    from std_msgs.msg import Float64MultiArray
    bag = tmp_path / 'in'
    clouds = [scenes.corner(500, 1.0, scale=0.01, seed=3).points, np.full((40, 3), np.nan),
              scenes.corner(500, 1.0, scale=0.01, seed=4).points]
    with Writer(bag, version=9) as writer:
        conn = writer.add_connection('/points', 'sensor_msgs/msg/PointCloud2', typestore=TS2)
        for k, points in enumerate(clouds):
            msg = _cloud_msg(TS2, points, 10**18 + k * 10**8, rosbags_types(TS2))
            writer.write(conn, 10**18 + k * 10**8, TS2.serialize_cdr(msg, 'sensor_msgs/msg/PointCloud2'))
    runs = []
    for run in ('a', 'b'):
        replay_offline(bag, out=tmp_path / run, echo=None, config=PipelineConfig(auto_tune=False, tolerance=0.02))
        raw = {}
        with Reader([tmp_path / run], default_typestore=TS2) as reader:
            for c, _, data in reader.messages():
                reader.deserialize(data, c.msgtype)  # every message, also the empty ones
                raw.setdefault(c.topic, []).append(bytes(data))
        runs.append(raw)
    coefficients = runs[0][output_topics()['plane_coefficients']]
    assert len(coefficients) == 3
    empty = deserialize_message(coefficients[1], Float64MultiArray)
    assert list(empty.data) == [] and len(deserialize_message(coefficients[0], Float64MultiArray).data) > 0
    for topic in runs[0]:
        if topic != '/diagnostics':  # its processing_ms differs from run to run
            assert runs[0][topic] == runs[1][topic], topic



def test_a_bag_without_a_cloud_topic_names_the_topics_it_has(tmp_path, capsys):
    bag = tmp_path / 'chatter'
    with Writer(bag, version=9) as writer:
        conn = writer.add_connection('/chatter', 'std_msgs/msg/String', typestore=TS2)
        writer.write(conn, 1, TS2.serialize_cdr(TS2.types['std_msgs/msg/String'](data='hi'), 'std_msgs/msg/String'))
    for command in ('replay', 'detect'):
        assert cli_main([command, str(bag)]) == 2
        err = capsys.readouterr().err
        assert 'no sensor_msgs/msg/PointCloud2 topic in the bag (its topics: /chatter (std_msgs/msg/String))' in err


def test_rclpy_messages_with_boolean_and_byte_sequences_convert_for_rosbags():
    from rcl_interfaces.msg import ParameterValue
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import ByteMultiArray

    from plane_validation.ros.recorder import as_rosbags
    value = ParameterValue(type=6, bool_array_value=[True, False], byte_array_value=[b'\x01', b'\x02'])
    for msg, name in ((value, 'rcl_interfaces/msg/ParameterValue'),
                      (ByteMultiArray(data=[b'\x07']), 'std_msgs/msg/ByteMultiArray')):
        raw = bytes(TS2.serialize_cdr(as_rosbags(msg, TS2), name))
        assert deserialize_message(raw, type(msg)) == msg



_SESSION_THEN_EXIT = '''
import time
from plane_validation.ros.player import LiveSession
session = LiveSession('/points', 'plane_validation', lambda key, msg: None)
end = time.monotonic() + 30
while not session.connected() and time.monotonic() < end:
    time.sleep(0.05)
connected = session.connected()
session.close()
print('connected' if connected else 'not connected', flush=True)
'''


def test_a_process_that_talked_to_a_node_in_another_process_exits_cleanly_right_after_closing():
    """A process that closed its live session and exited at once was aborted ('terminate called without an active
    exception', status 134) when it had talked to a node in another process (replay --live --no-node from a
    script): the executor's thread was still in rclpy's wait. close() now waits for it."""
    import signal
    import subprocess
    import sys
    node = subprocess.Popen([sys.executable, '-c', 'from plane_validation.ros.node import main; main()', '--ros-args',
                             '-r', 'cloud:=/points'], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        runs = [subprocess.run([sys.executable, '-c', _SESSION_THEN_EXIT], capture_output=True, text=True, timeout=60)
                for _ in range(2)]
    finally:
        node.send_signal(signal.SIGINT)
        node.wait(timeout=30)
    for run in runs:
        assert (run.returncode, run.stdout.strip()) == (0, 'connected'), run.stderr[-500:]



def _file_size_limit(limit: int):
    """A preexec_fn: files this process writes stop at ``limit`` bytes, as on a full disk (the writes fail with
    EFBIG instead of SIGXFSZ ending the process)."""
    def apply() -> None:
        import resource
        import signal
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return apply


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_replay_onto_a_full_disk_fails_in_one_line_and_leaves_no_output(tmp_path, storage):
    import os
    import subprocess
    import sys
    out = tmp_path / 'out'
    proc = subprocess.run([sys.executable, '-m', 'plane_validation.cli', 'replay', str(BAGS / 'room'), '--out',
                           str(out), '--storage', storage], capture_output=True, text=True, timeout=300,
                          env=dict(os.environ), preexec_fn=_file_size_limit(64_000))
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('plane-validation: error:') and 'Traceback' not in proc.stderr, \
        proc.stderr
    assert str(out) in lines[0], lines[0]  # the output it could not write, with the system's reason
    assert list(tmp_path.iterdir()) == [], 'an unfinished output was left behind'


def test_a_killed_replay_leaves_a_partial_that_the_next_run_removes(tmp_path):
    import os
    import signal
    import subprocess
    import sys
    out = tmp_path / 'out'
    command = [sys.executable, '-u', '-m', 'plane_validation.cli', 'replay', str(BAGS / 'room'), '--out', str(out)]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ))
    try:
        first = proc.stdout.readline()  # the first frame is written: the bag is half done
        assert first.startswith('frame    0'), first
        proc.send_signal(signal.SIGKILL)  # no handler runs: nothing cleans up
        proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    stale = list(tmp_path.glob('.out.*.partial'))
    assert len(stale) == 1 and stale[0].is_dir(), list(tmp_path.iterdir())
    held = tmp_path / f'.out.{os.getpid()}.abcdefgh.partial'  # a live process's (this one's) is left alone
    held.mkdir()
    rerun = subprocess.run(command, capture_output=True, text=True, timeout=300, env=dict(os.environ))
    assert rerun.returncode == 0, rerun.stderr
    said = [line for line in rerun.stderr.splitlines() if 'removed' in line]
    assert len(said) == 1 and str(stale[0]) in said[0] and f'process {proc.pid}' in said[0], rerun.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(['out', held.name])
