"""The command line layer: ``plane-validation`` (see :mod:`.commands`), loaded on first use."""
import importlib

from .. import _entry_point

__all__ = ['main', 'build_parser', 'parse_tolerances', 'progress_bar']


def main(argv: list[str] | None = None) -> int:
    """``plane-validation``: :func:`.commands.main`; Ctrl-C while numpy and scipy load (the first
    second) also exits quietly with 130."""
    run = _entry_point('.commands', __name__)
    return 130 if run is None else run(argv)


def __getattr__(name: str):
    if name in __all__:
        return getattr(importlib.import_module('.commands', __name__), name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
