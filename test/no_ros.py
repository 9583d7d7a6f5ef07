"""Simulate a core-only install in a subprocess: ``import no_ros; no_ros.install()`` makes rclpy,
every ``*_msgs`` package and rosbags unimportable, as when only the ``core`` extra is installed."""
import importlib.abc
import sys

BLOCKED = ('rclpy', 'rosbags', 'rcl_interfaces', 'builtin_interfaces')


def blocked(name: str) -> bool:
    top = name.split('.')[0]
    return top in BLOCKED or top.endswith('_msgs')


class _Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if blocked(name):
            raise ImportError(f'blocked: {name} (simulated core-only install)')
        return None


def install() -> None:
    sys.meta_path.insert(0, _Block())


def leaked() -> list[str]:
    return sorted(m for m in sys.modules if blocked(m))
