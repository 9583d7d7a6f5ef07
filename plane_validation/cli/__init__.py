"""The command line layer: ``plane-validation`` (the commands in :mod:`.commands`, their options in :mod:`.parser`,
the process in :mod:`.run`), loaded on first use."""
import importlib

from .. import _entry_point

__all__ = ['main', 'build_parser', 'parse_tolerances', 'progress_bar']

#: Where each of __all__'s names but main lives.
_HOMES = {'build_parser': '.parser', 'parse_tolerances': '.commands', 'progress_bar': '.commands'}


def main(argv: list[str] | None = None) -> int:
    """``plane-validation``: :func:`.run.main`; Ctrl-C while numpy and scipy load (the first
    second) also exits quietly with 130."""
    run = _entry_point('.run', __name__)
    return 130 if run is None else run(argv)


def __getattr__(name: str):
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name], __name__), name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
