"""Record the input clouds and the node's outputs into a rosbag2 bag that is complete or absent.

The bag is written under a hidden temporary directory beside ``path`` and moved into place on
:meth:`BagRecorder.close`; :meth:`BagRecorder.abort` (an exception or a signal turned into one)
deletes it. Data files are named as rosbag2 names them (``<name>_0.mcap`` / ``<name>_0.db3``).

Messages are serialized by rosbags, not rclpy: rclpy's CDR leaves its padding bytes uninitialized (two runs
give different bags) and ends an empty float64 sequence with alignment bytes that rosbags rejects as a
size mismatch (a Float64MultiArray of a frame without planes); rclpy reads rosbags' CDR as well.
"""
from __future__ import annotations

import array
import shutil
import sqlite3
from pathlib import Path

import numpy as np

from ..formats.bags import POINTCLOUD2, STORAGES, BagError, typestore
from ..formats.partials import clear_stale_partials, make_partial
from .messages import OUTPUTS, msgtype

__all__ = ['BagRecorder', 'output_topics', 'as_rosbags']


def output_topics(node_name: str = 'plane_validation') -> dict[str, str]:
    """Output key -> topic name, as the node publishes them."""
    return {key: '/diagnostics' if key == 'diagnostics' else f'/{node_name}/{key}' for key in OUTPUTS}


def as_rosbags(msg, store):
    """The rosbags message (of ``store``'s types) with the fields of an rclpy message ``msg``; a rosbags
    message as it is."""
    if hasattr(msg, '__msgtype__'):
        return msg
    fields = {name: _value(getattr(msg, name), kind, store) for name, kind in msg.get_fields_and_field_types().items()}
    return store.types[msgtype(type(msg))](**fields)


def _value(value, kind: str, store):
    """An rclpy field value as rosbags holds it: messages converted, numeric arrays as numpy arrays, a
    byte (octet) as an int. ``kind``: rclpy's field type ('octet', 'sequence<double>', 'float[4]', ...)."""
    if hasattr(value, 'get_fields_and_field_types'):
        return as_rosbags(value, store)
    if isinstance(value, array.array):  # a sequence of numbers: without a copy
        return np.frombuffer(value, dtype=np.dtype(value.typecode)) if len(value) else np.array(value)
    if isinstance(value, np.ndarray):
        return value
    if isinstance(value, (bytes, bytearray)):
        return value[0] if kind == 'octet' else np.frombuffer(value, np.uint8)
    if isinstance(value, list):
        element = kind.split('<', 1)[-1].split(',')[0].rstrip('>').split('[')[0].strip()
        if element == 'boolean':
            return np.array(value, dtype=bool)
        if element == 'octet':
            return np.frombuffer(b''.join(value), np.uint8).copy()
        return [_value(v, element, store) for v in value]
    return value


class BagRecorder:
    """Writes rclpy (or rosbags) messages keyed 'input' or an output key. storage: 'mcap' or 'sqlite3'."""

    def __init__(self, path: Path, input_topic: str, node_name: str = 'plane_validation',
                 storage: str = 'mcap') -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        if storage not in STORAGES:
            raise BagError(f'unknown storage {storage!r}; choose one of {", ".join(STORAGES)}')
        if input_topic in output_topics(node_name).values():
            raise BagError(f'input topic {input_topic} is one of the node\'s output topics: its clouds and the '
                           'node\'s would share it; replay the topic the node read instead')
        if path.exists():
            raise BagError(f'output {path} already exists; remove it or pass another --out')
        if not path.parent.is_dir():
            raise BagError(f'cannot write output bag {path}: directory {path.parent} does not exist')
        self.path, self.storage = path, storage
        self._tmp = None
        try:
            clear_stale_partials(path.parent, path.name)
            self._tmp = make_partial(path.parent, path.name)
            self._bag = self._tmp / path.name
            self.writer = Writer(self._bag, version=9, storage_plugin=StoragePlugin[storage.upper()])
            self.writer.open()
            store = self._store = typestore()
            self.connections = {'input': self.writer.add_connection(input_topic, POINTCLOUD2, typestore=store)}
            for key, topic in output_topics(node_name).items():
                self.connections[key] = self.writer.add_connection(topic, msgtype(OUTPUTS[key]), typestore=store)
        except BaseException as exc:  # also a signal turned into an exception
            if self._tmp is not None:
                shutil.rmtree(self._tmp, ignore_errors=True)
            if isinstance(exc, Exception):
                raise BagError(f'cannot write output bag {path}: {exc}') from exc
            raise

    def write(self, key: str, timestamp: int, msg) -> None:
        connection = self.connections[key]
        data = self._store.serialize_cdr(as_rosbags(msg, self._store), connection.msgtype)
        try:
            self.writer.write(connection, timestamp, data)
        except (OSError, sqlite3.Error) as exc:  # a full disk: an OSError from MCAP, sqlite3's own error
            raise self._failed(exc) from exc

    def _failed(self, exc: OSError | sqlite3.Error) -> BagError:
        return BagError(f'cannot write output bag {self.path}: {getattr(exc, "strerror", None) or exc}')

    def close(self) -> Path:
        """Finish the bag and move it to ``path``."""
        try:
            try:
                self.writer.close()
            except (OSError, sqlite3.Error) as exc:
                raise self._failed(exc) from exc
            suffix = STORAGES[self.storage]
            data = self._bag / f'{self._bag.name}{suffix}'
            rosbag2_name = f'{self._bag.name}_0{suffix}'
            data.rename(self._bag / rosbag2_name)
            meta = self._bag / 'metadata.yaml'
            # the name stands in relative_file_paths and in files[].path
            meta.write_text(meta.read_text().replace(f' {data.name}\n', f' {rosbag2_name}\n'))
            try:
                self._bag.rename(self.path)
            except OSError as exc:
                raise BagError(f'cannot write output bag {self.path}: it appeared while this replay ran (another '
                               f'run writing the same --out?); nothing written ({exc.strerror or exc})') from exc
        except BaseException:
            self.abort()
            raise
        shutil.rmtree(self._tmp, ignore_errors=True)
        return self.path

    def abort(self) -> None:
        """Throw the unfinished bag away."""
        try:
            self.writer.close()
        except Exception:  # noqa: BLE001 - the bag is being thrown away anyway
            pass
        shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self) -> BagRecorder:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
