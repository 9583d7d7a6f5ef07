"""Reading and writing bags with ``rosbags`` (no rclpy; rosbags is imported only when used).

:func:`read_clouds` yields the PointCloud2 messages of a bag (rosbag2 directories, bare .mcap or
.db3 files, compressed bags and ROS 1 .bag files); :func:`read_bag_points` and
:func:`write_bag_points` read and write one cloud for the command line (``BAG[:TOPIC[:INDEX]]``).
"""
from __future__ import annotations

import functools
import shutil
import tempfile
from collections import deque
from collections.abc import Iterator
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ['BAG_SUFFIXES', 'BagSource', 'BagError', 'POINTCLOUD2', 'STORAGES', 'parse_bag_source', 'read_clouds',
           'open_bag', 'pick_topic', 'bag_storage', 'typestore', 'read_bag_points', 'read_bag_message',
           'write_bag_points', 'TOPIC',
           'STAMP_NS']

#: File extensions read as bags (a directory is always a rosbag2 bag).
BAG_SUFFIXES = ('.mcap', '.db3', '.bag')
#: Topic and header stamp (ns) of the cloud :func:`write_bag_points` writes.
TOPIC = '/points'
STAMP_NS = 1_700_000_000 * 10**9
FRAME_ID = 'map'
POINTCLOUD2 = 'sensor_msgs/msg/PointCloud2'
#: rosbag2 storage plugins we write, by their metadata.yaml storage_identifier; data file suffixes.
STORAGES = {'mcap': '.mcap', 'sqlite3': '.db3'}


class BagError(ValueError):
    """A bag that cannot be read or written: missing, corrupt, no such topic, wrong type, bad path."""


@functools.cache
def typestore():
    """The ROS 2 Jazzy message types of rosbags."""
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def open_bag(bag: Path):
    """An opened rosbags AnyReader for ``bag``, or BagError."""
    from rosbags.highlevel import AnyReader, AnyReaderError
    if not bag.exists():
        raise BagError(f'bag not found: {bag}')
    if bag.is_file() and bag.suffix.lower() not in BAG_SUFFIXES:  # rosbags: "Unrecognized storage format '.pcd'"
        from .files import POINT_SUFFIXES
        hint = ': a point file, which detect, sweep and planes read' if bag.suffix.lower() in POINT_SUFFIXES else ''
        raise BagError(f'{bag}: not a bag (a rosbag2 directory, or a {", ".join(BAG_SUFFIXES)} file){hint}')
    if bag.is_dir() and not (bag / 'metadata.yaml').is_file():
        files = sorted(p.name for suffix in STORAGES.values() for p in bag.glob(f'*{suffix}'))
        if not files:
            raise BagError(f'{bag}: a directory but not a rosbag2 bag (no metadata.yaml, no .mcap or .db3 file)')
        raise BagError(f'{bag}: a directory without metadata.yaml, so not a rosbag2 bag; to read one storage file '
                       f'of it, name the file ({", ".join(files[:3])}{", ..." if len(files) > 3 else ""})')
    try:
        reader = AnyReader([_StoragePath(bag) if bag.is_file() else bag], default_typestore=typestore())
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError) as exc:
        hint = next((why for sign, why in DAMAGED.items() if sign in str(exc)), '')
        raise BagError(f'cannot open bag {bag}: {exc}{hint}') from exc
    return reader


class _StoragePath(type(Path())):
    """A path whose suffix reads in lower case: rosbags picks a bag file's reader by its suffix, case-sensitively
    (B.MCAP, which write_bag_points writes, was an "Unrecognized storage format '.MCAP'")."""

    @property
    def suffix(self) -> str:
        return super().suffix.lower()


#: Words of a reader's error -> what it means for a bag cut short (a recorder killed before closing it).
DAMAGED = {
    'end magic': ' (the MCAP file ends early, as when its recorder stopped without closing it: '
                 '`mcap recover` copies the messages it holds into a readable file)',
    'disk image is malformed': ' (the sqlite3 file is damaged or cut short: sqlite3\'s `.recover` may save '
                               'its messages)',
    'index looks damaged': ' (the ROS 1 bag ends early or its index is damaged: `rosbag reindex` rebuilds it)',
}


def bag_storage(bag: str | Path) -> str | None:
    """'mcap' or 'sqlite3' for a rosbag2 bag (directory or bare storage file), None otherwise."""
    bag = Path(bag)
    if bag.is_dir():
        meta = bag / 'metadata.yaml'
        text = meta.read_text(errors='replace') if meta.is_file() else ''
        for name, suffix in STORAGES.items():
            if f'storage_identifier: {name}' in text or any(bag.glob(f'*{suffix}')):
                return name
        return None
    return next((name for name, suffix in STORAGES.items() if bag.suffix.lower() == suffix), None)


def pick_topic(reader, bag: Path, topic: str | None) -> list:
    """The connections of ``topic``, or of the bag's only PointCloud2 topic when None."""
    clouds = sorted({c.topic for c in reader.connections if c.msgtype == POINTCLOUD2})
    if topic is None:
        if not clouds:
            others = ', '.join(f'{t} ({m})' for t, m in sorted({(c.topic, c.msgtype) for c in reader.connections}))
            raise BagError(f'{bag}: no {POINTCLOUD2} topic in the bag (its topics: {others or "none"})')
        if len(clouds) != 1:
            raise BagError(f'{bag}: cannot pick the cloud topic automatically '
                           f'(PointCloud2 topics: {", ".join(clouds)}); '
                           'name one (replay --topic TOPIC, or BAG:TOPIC for a cloud file argument)')
        topic = clouds[0]
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns:
        raise BagError(f'{bag}: no topic {topic!r}; PointCloud2 topics: {", ".join(clouds) or "none"}')
    types = sorted({c.msgtype for c in conns})
    if types != [POINTCLOUD2]:
        carries = ' and '.join(types)
        if POINTCLOUD2 in types:
            raise BagError(f'{bag}: topic {topic!r} carries {carries}; only {POINTCLOUD2} can be read')
        raise BagError(f'{bag}: topic {topic!r} carries {carries}, not {POINTCLOUD2}')
    return conns


def read_clouds(bag: str | Path, topic: str | None = None) -> Iterator[tuple[str, int, object]]:
    """Yield (topic, bag timestamp ns, rosbags PointCloud2) for every cloud on ``topic``
    (auto-detected when the bag has exactly one PointCloud2 topic). Raises BagError."""
    bag = Path(bag)
    reader = open_bag(bag)
    try:
        conns = pick_topic(reader, bag, topic)
        try:
            for conn, timestamp, raw in reader.messages(connections=conns):
                yield conn.topic, timestamp, reader.deserialize(raw, conn.msgtype)
        except BagError:
            raise
        except Exception as exc:  # rosbags raises many types on damaged data
            raise BagError(f'{bag}: cannot read message: {type(exc).__name__}: {exc}') from exc
    finally:
        reader.close()


@dataclass(frozen=True)
class BagSource:
    """Cloud number ``index`` (negative: from the end) on ``topic`` (None: the only cloud topic)."""

    path: Path
    topic: str | None = None
    index: int = 0

    def __str__(self) -> str:
        return f'{self.path}:{self.topic or ""}:{self.index}'


def _is_bag(path: Path) -> bool:
    return path.is_dir() or (path.is_file() and path.suffix.lower() in BAG_SUFFIXES)


def _index(text: str, source: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise ValueError(f'{source}: message index {text!r} is not an integer (BAG[:TOPIC[:INDEX]])') from None


def parse_bag_source(source: str | Path) -> BagSource | None:
    """``BAG``, ``BAG:TOPIC``, ``BAG:INDEX``, ``BAG:TOPIC:INDEX`` or ``BAG::INDEX`` -> BagSource.

    BAG is a directory or an existing .mcap/.db3/.bag file (a path that does not exist but has a
    bag extension is returned too, so that reading it reports a missing bag). None when
    ``source`` names no bag (a point file).
    """
    text = str(source)
    path = Path(text)
    if path.exists():
        return BagSource(path) if _is_bag(path) else None
    parts = text.split(':')
    for cut in (1, 2):  # BAG:X, then BAG:TOPIC:INDEX
        if len(parts) <= cut:
            break
        head = Path(':'.join(parts[:-cut]))
        if not _is_bag(head):
            continue
        if cut == 1:
            tail = parts[-1]
            is_index = tail.lstrip('-').isdigit()
            return BagSource(head, None if is_index else (tail or None), _index(tail, text) if is_index else 0)
        return BagSource(head, parts[-2] or None, _index(parts[-1], text) if parts[-1] else 0)
    if path.suffix.lower() in BAG_SUFFIXES:
        return BagSource(path)
    head = Path(parts[0])
    if len(parts) > 1 and head.suffix.lower() in BAG_SUFFIXES:
        return BagSource(head)  # a missing bag given with a topic
    return None


def read_bag_points(source: BagSource) -> np.ndarray:
    """(height*width, 3) float64 x, y, z of one PointCloud2 in a bag (NaN holes kept)."""
    from .pointcloud2 import xyz_array
    topic, msg = _message(source)
    return _xyz(source, topic, msg, xyz_array)


def read_bag_message(source: BagSource):
    """The rosbags PointCloud2 message ``source`` names."""
    return _message(source)[1]


def _message(source: BagSource) -> tuple[str, object]:
    if source.index >= 0:
        seen = 0
        with closing(read_clouds(source.path, source.topic)) as clouds:
            for topic, _, msg in clouds:
                if seen == source.index:
                    return topic, msg
                seen += 1
    else:
        last: deque = deque(maxlen=-source.index)
        with closing(read_clouds(source.path, source.topic)) as clouds:
            for item in clouds:
                last.append(item)
        seen = len(last)
        if seen == -source.index:
            topic, _, msg = last[0]
            return topic, msg
    where = f'on {source.topic}' if source.topic else 'on its cloud topic'
    raise ValueError(f'{source.path}: no cloud number {source.index} {where} '
                     f'({"only " if seen else ""}{seen} cloud{"s" if seen != 1 else ""})')


def _xyz(source: BagSource, topic: str, msg, xyz_array) -> np.ndarray:
    try:
        return xyz_array(msg)
    except ValueError as exc:
        raise ValueError(f'{source.path} [{topic}]: {exc}') from exc


def write_bag_points(path: str | Path, points: np.ndarray, labels: np.ndarray | None = None, *,
                     topic: str = TOPIC, shape: tuple[int, int] | None = None) -> Path:
    """Write (N, 3) points (meters) as one float32 x y z PointCloud2 (float64 where float32 would lose
    precision: :func:`~plane_validation.formats.files.coordinate_dtype`) into a new rosbag2 bag, with
    (N,) labels as an int32 field ``label`` when given; organized (height H) with ``shape`` (H, W).

    ``path`` without extension: a bag directory (MCAP storage); ``.mcap`` or ``.db3``: a single
    storage file (MCAP or SQLite 3), readable without metadata.yaml. Refuses to overwrite.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    from .files import coordinate_dtype
    from .pointcloud2 import create_cloud, rosbags_types

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == '.bag':
        raise ValueError(f'{path}: writing ROS 1 bags is not supported; use a directory, .mcap or .db3')
    if suffix not in ('', '.mcap', '.db3'):
        raise ValueError(f'{path}: not a bag name (use a directory, .mcap or .db3)')
    if path.exists():
        raise ValueError(f'{path} already exists; remove it or choose another name')
    if not path.parent.is_dir():
        raise ValueError(f'{path}: directory {path.parent} does not exist')
    store = typestore()
    types = rosbags_types(store)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    xyz = points.astype(coordinate_dtype(points))
    header = types.Header(stamp=types.Time(sec=STAMP_NS // 10**9, nanosec=STAMP_NS % 10**9), frame_id=FRAME_ID)
    columns = {'x': xyz[:, 0], 'y': xyz[:, 1], 'z': xyz[:, 2]}
    if labels is not None:
        columns['label'] = np.asarray(labels).astype(np.int32).reshape(-1)
    msg = create_cloud(header, columns, types=types, shape=shape)
    storage = StoragePlugin.SQLITE3 if suffix == '.db3' else StoragePlugin.MCAP
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=f'.{path.name}.') as tmp:
        bag_dir = Path(tmp) / (path.stem if suffix else path.name)
        writer = Writer(bag_dir, version=9, storage_plugin=storage)
        with writer:
            conn = writer.add_connection(topic, POINTCLOUD2, typestore=store)
            writer.write(conn, STAMP_NS, store.serialize_cdr(msg, POINTCLOUD2))
        if suffix:
            (storage_file,) = bag_dir.glob(f'*{suffix}')
            shutil.move(storage_file, path)
        else:
            shutil.move(bag_dir, path)
    return path
