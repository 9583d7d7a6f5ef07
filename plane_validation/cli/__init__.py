"""The command line layer: ``plane-validation`` (see :mod:`.main`)."""
from .main import build_parser, main, parse_tolerances, progress_bar

__all__ = ['main', 'build_parser', 'parse_tolerances', 'progress_bar']
