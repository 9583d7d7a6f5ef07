"""Outputs that are complete or absent whatever ends the run: a file written beside its path and moved in at the
end (:func:`atomic_output`, :func:`atomic_outputs`), a folder's set of files staged inside it (:func:`staged_files`),
and the checks made before any work (:func:`check_writable`)."""
from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager, suppress
from pathlib import Path

from .partials import clear_stale_partials, make_partial

__all__ = ['atomic_output', 'atomic_outputs', 'staged_files', 'check_writable']


def check_writable(path: str | Path, *, inputs: tuple[str | Path, ...] = ()) -> None:
    """ValueError unless ``path`` (any file type) is none of the ``inputs`` and its directory exists."""
    path = Path(path)
    _not_an_input(path, inputs)
    _in_a_directory(path)


def _not_an_input(path: Path, inputs: tuple[str | Path, ...]) -> None:
    for source in inputs:
        if path.resolve() == Path(str(source)).resolve():
            raise ValueError(f'{path}: the output would overwrite the input; choose another name')


def _in_a_directory(path: Path) -> None:
    if not path.parent.is_dir():
        raise ValueError(f'{path}: directory {path.parent} does not exist')


@contextmanager
def atomic_output(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix) that replaces ``path`` when the block ends
    normally and is deleted otherwise, so an output file is complete or absent. A symbolic link's target is
    replaced (not the link); an existing device or pipe (``/dev/stdout``) is written in place."""
    path = Path(path)
    if path.exists() and not path.is_file() and not path.is_dir():  # a device or a pipe: no file to stage
        yield path
        return
    path = path.resolve() if path.is_symlink() else path
    try:
        fd, name = tempfile.mkstemp(dir=path.parent, prefix=f'.{path.stem}.', suffix=path.suffix)
    except OSError as exc:  # named by the output, not by the temporary file
        raise OSError(f'cannot write {path}: {exc.strerror or exc}') from exc
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        umask = os.umask(0)
        os.umask(umask)
        tmp.chmod(0o666 & ~umask)  # as a plain open() would have made it (mkstemp makes 0600)
        try:
            os.replace(tmp, path)
        except OSError as exc:
            raise OSError(f'cannot write {path}: {exc.strerror or exc}') from exc
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def atomic_outputs(*paths: str | Path) -> Iterator[list[Path]]:
    """:func:`atomic_output` for files a command writes together: a temporary path for each of ``paths``; once the
    block ends normally they replace their paths (one after the other, after all are written), otherwise all are
    deleted: an interrupted run leaves none of its files, not some beside an earlier run's others."""
    targets = [Path(path) for path in paths]
    for path in targets:  # refused before anything is written: a late failure would leave the others replaced
        if path.is_dir():
            raise ValueError(f'{path} is a directory: give a file name')
    if len({path.resolve() for path in targets}) < len(targets):
        raise ValueError(f'the same file is given twice: {", ".join(map(str, targets))}')
    with ExitStack() as stack:
        yield [stack.enter_context(atomic_output(path)) for path in targets]


@contextmanager
def staged_files(folder: str | Path) -> Iterator[Path]:
    """A hidden temporary folder in ``folder`` (created) for a set of output files: when the block ends normally
    they replace their namesakes in ``folder``, one by one (each atomically); otherwise they are deleted, and an
    interrupted run leaves the folder's earlier set as it was, not a mix of two runs. Inside the folder, not
    beside it: on the same file system also when ``folder`` is a mount point or a link to another one."""
    import shutil
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise ValueError(f'{folder}: exists and is not a directory (the output folder)')
    made = [] if folder.exists() else [parent for parent in (folder, *folder.parents) if not parent.exists()]
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f'{folder}: cannot create the output folder ({exc.strerror or exc})') from exc
    clear_stale_partials(folder, 'stage')
    stage = make_partial(folder, 'stage')
    done = False
    try:
        yield stage
        for path in sorted(stage.iterdir()):
            os.replace(path, folder / path.name)
        done = True
    finally:
        shutil.rmtree(stage, ignore_errors=True)
        if not done:  # a failed run leaves no folder it made (when still empty)
            for parent in made:
                with suppress(OSError):
                    parent.rmdir()
