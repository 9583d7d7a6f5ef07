"""The command line layer: ``plane-validation`` (see :mod:`.commands`), loaded on first use."""
import importlib

__all__ = ['main', 'build_parser', 'parse_tolerances', 'progress_bar']


def main(argv: list[str] | None = None) -> int:
    """``plane-validation``: :func:`.commands.main`; Ctrl-C while numpy and scipy load (the first
    second) also exits quietly with 130."""
    try:
        run = importlib.import_module('.commands', __name__).main
    except KeyboardInterrupt:
        return 130
    return run(argv)


def __getattr__(name: str):
    if name in __all__:
        return getattr(importlib.import_module('.commands', __name__), name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
