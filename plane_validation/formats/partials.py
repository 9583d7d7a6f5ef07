"""Hidden staging directories for outputs that must be complete or absent, named after their owner's process
so that a later run can remove those a killed run (``kill -9``, a power cut) left behind.

A staging directory of output ``name`` in ``parent`` is ``parent/.<name>.<pid>.<random>.partial``.
"""
from __future__ import annotations

import os
import re
import shutil
import sys
import tempfile
from pathlib import Path

__all__ = ['make_partial', 'clear_stale_partials']


def make_partial(parent: Path, name: str) -> Path:
    """A new, empty staging directory for output ``name`` in ``parent``, owned by this process."""
    return Path(tempfile.mkdtemp(dir=parent, prefix=f'.{name}.{os.getpid()}.', suffix='.partial'))


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def clear_stale_partials(parent: Path, name: str) -> list[Path]:
    """Remove the staging directories of output ``name`` in ``parent`` whose process has ended (one line on
    stderr for each) and return them. Those of a live process (another run writing the same output, or a
    process that took a dead one's id) are left alone."""
    owned = re.compile(rf'\.{re.escape(name)}\.(\d+)\.[^.]+\.partial')
    removed = []
    try:
        entries = list(Path(parent).iterdir())
    except OSError:
        return removed
    for entry in entries:
        match = owned.fullmatch(entry.name)
        if match is None or not entry.is_dir() or entry.is_symlink() or _alive(int(match[1])):
            continue
        shutil.rmtree(entry, ignore_errors=True)
        if not entry.exists():
            removed.append(entry)
            print(f'plane-validation: removed {entry}, the unfinished output of a run that was killed '
                  f'(process {match[1]})', file=sys.stderr)
    return removed
