"""Point files for the command line: read x, y, z from PCD, PLY, .npy, text or a bag; write labelled clouds.

Readers return an (N, 3) float64 array in the file's unit (meters for real sensors; a header name
``x (mm)`` or ``x [cm]`` is converted to meters). Rows of organized clouds keep their NaN holes, so row
i of the result is point i of the file. Every problem with a file (missing, unknown extension, corrupt
bytes, no x/y/z) raises ``ValueError`` with a one-line message naming the file.

PCD: ascii and binary are read here (any VERSION; fast, no extra dependency); binary_compressed
(LZF) through ``pypcd4``. PLY: through ``plyfile`` (GPL-3.0, imported only for .ply files).
Bags (``BAG[:TOPIC[:INDEX]]``): see :mod:`plane_validation.bagcloud`.
"""
from __future__ import annotations

import os
import re
import tempfile
import warnings
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager, suppress
from pathlib import Path

import numpy as np

from ..core.geometry import beam_numbers
from .partials import clear_stale_partials, make_partial

__all__ = ['atomic_output', 'atomic_outputs', 'staged_files', 'check_output', 'check_writable', 'load_cloud',
           'load_points', 'load_scan', 'save_points', 'is_bag_output', 'POINT_SUFFIXES', 'TEXT_SUFFIXES']

#: Extensions of plain point files (bags are recognised separately).
TEXT_SUFFIXES = ('.xyz', '.txt', '.csv')
POINT_SUFFIXES = ('.pcd', '.ply', '.npy') + TEXT_SUFFIXES
#: A table of 3 or 4 rows wider than this is taken for coordinates in rows (a point per column), and refused.
WIDEST_POINT_ROW = 16

#: PCD TYPE letter and SIZE -> numpy dtype character.
_PCD_TYPES = {('F', 4): 'f4', ('F', 8): 'f8', ('I', 1): 'i1', ('I', 2): 'i2', ('I', 4): 'i4', ('I', 8): 'i8',
              ('U', 1): 'u1', ('U', 2): 'u2', ('U', 4): 'u4', ('U', 8): 'u8'}


def load_points(source: str | Path) -> np.ndarray:
    """(N, 3) float64 x, y, z of a point file or of one cloud in a bag.

    source: a .pcd, .ply, .npy or whitespace/comma separated text file (.xyz .txt .csv: the
    columns a first row of column names calls x, y, z, else the first three), or ``BAG[:TOPIC[:INDEX]]``
    with BAG a rosbag2 directory, .mcap, .db3 or ROS 1 .bag
    (see :func:`plane_validation.formats.bags.parse_bag_source`).
    Raises ValueError naming the problem.
    """
    from .bags import parse_bag_source, read_bag_points

    if not str(source).strip():
        raise ValueError('no cloud given: the file name is empty')
    bag = parse_bag_source(source)
    if bag is not None:
        return read_bag_points(bag)
    path = Path(source)
    suffix = path.suffix.lower()
    if suffix not in POINT_SUFFIXES:
        if not path.exists():
            raise ValueError(f'no such file: {path}')
        raise ValueError(f'{path}: unsupported file type {suffix or "(no extension)"!r} '
                         f'(use {", ".join(POINT_SUFFIXES)} or a bag)')
    if not path.is_file():
        raise ValueError(f'no such file: {path}' if not path.exists() else f'{path} is not a file')
    reader = {'.pcd': _read_pcd, '.ply': _read_ply, '.npy': _read_npy}.get(suffix, _read_text)
    points = reader(path)
    return np.ascontiguousarray(points, dtype=np.float64)


def load_cloud(source: str | Path) -> tuple[np.ndarray, tuple[int, int] | None]:
    """:func:`load_points` and the cloud's image shape (H, W) when it is organized (a PCD with
    HEIGHT > 1, or a bag cloud with height > 1), else None."""
    return load_scan(source)[:2]


def load_scan(source: str | Path) -> tuple[np.ndarray, tuple[int, int] | None, np.ndarray | None]:
    """:func:`load_cloud` and, for an unorganized PCD file or bag cloud with an integer ``ring`` field
    (a spinning lidar's beam of each point, as velodyne_pointcloud writes it), that field (N,) int64;
    else None."""
    from .bags import parse_bag_source, read_bag_message
    from .pointcloud2 import ring_array, xyz_array
    if not str(source).strip():
        raise ValueError('no cloud given: the file name is empty')
    bag = parse_bag_source(source)
    if bag is None:
        if Path(source).suffix.lower() != '.pcd' or not Path(source).is_file():
            points = load_points(source)
            return points, None, None
        points, ring, shape = _read_pcd_scan(Path(source))
        return np.ascontiguousarray(points, dtype=np.float64), shape, None if shape else ring
    msg = read_bag_message(bag)
    try:
        points = xyz_array(msg)
    except ValueError as exc:  # named as given (BAG:TOPIC:INDEX): which message it is
        raise ValueError(f'{source}: {exc}') from exc
    h, w = int(msg.height), int(msg.width)
    return points, (h, w) if h > 1 else None, None if h > 1 else ring_array(msg)


def pcd_viewpoint(source: str | Path) -> np.ndarray | None:
    """The VIEWPOINT of a PCD file: (7,) tx ty tz (meters, where the sensor was in the cloud's frame)
    qw qx qy qz; None for another file or a PCD without the line. Raises ValueError when the line is not
    7 finite numbers."""
    path = Path(source)
    if path.suffix.lower() != '.pcd' or not path.is_file():
        return None
    with path.open('rb') as f:
        parsed = _pcd_header(f.read(PCD_HEADER_MAX))
    if parsed is None or 'VIEWPOINT' not in parsed[0]:
        return None
    values = parsed[0]['VIEWPOINT']
    try:
        viewpoint = np.array([float(v) for v in values])
    except ValueError:
        viewpoint = np.empty(0)
    if viewpoint.shape != (7,) or not np.isfinite(viewpoint).all():
        raise ValueError(f'{path}: VIEWPOINT must be 7 numbers (tx ty tz qw qx qy qz), got {" ".join(values)!r}')
    return viewpoint


#: A PCD header is read from at most this many bytes (its lines are short; a comment could be long).
PCD_HEADER_MAX = 1 << 16


def save_points(path: str | Path, points: np.ndarray, labels: np.ndarray | None = None, *,
                shape: tuple[int, int] | None = None, viewpoint=None) -> Path:
    """Write (N, 3) points and optional (N,) integer labels (-1 unassigned) to ``path``.

    The format follows the extension: .ply (float32 x y z, int32 vertex property ``plane_id``),
    .pcd (binary, float32 x y z, int32 field ``label``), .npy ((N, 3) or (N, 4) float64 with the
    label as 4th column), .xyz/.txt/.csv (text columns), or a bag: a path without extension
    (rosbag2 directory) or ending in .mcap/.db3 (one PointCloud2 on /points, x y z float32 and
    int32 ``label``).
    All rows are written, NaN rows included, so that row i stays point i. ``shape`` (H, W): the
    rows are an H x W image; a .pcd or a bag is then written organized (height H), the other
    formats ignore it. ``viewpoint``: a .pcd's VIEWPOINT, 3 (tx ty tz) or 7 (and qw qx qy qz) numbers
    (default 0 0 0 1 0 0 0); the other formats have no place for it.
    """
    path = Path(path)
    pts = np.asarray(points)
    if pts.dtype.kind not in 'fiu' or pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f'points must be a real (N, 3) array of x y z rows, got {pts.dtype} of shape {pts.shape}'
                         + (' (transpose a (3, N) array)' if pts.ndim == 2 and pts.shape[0] == 3 else ''))
    pts = pts.astype(np.float64, copy=False)
    lab = None if labels is None else _labels_of(labels, len(pts))
    if shape is not None and (int(shape[0]) < 1 or int(shape[1]) < 1 or int(shape[0]) * int(shape[1]) != len(pts)):
        raise ValueError(f'shape {tuple(shape)} does not match {len(pts)} points')
    check_output(path)
    suffix = path.suffix.lower()
    if is_bag_output(path):
        from .bags import write_bag_points
        return write_bag_points(path, pts, lab, shape=shape)
    writers = {'.ply': _write_ply, '.npy': _write_npy,
               '.pcd': lambda p, x, y: _write_pcd(p, x, y, shape, viewpoint)}
    with atomic_output(path) as tmp:
        writers.get(suffix, _write_text)(tmp, pts, lab)
    return path


def is_bag_output(path: str | Path) -> bool:
    """Whether :func:`save_points` writes ``path`` as a bag: no extension (a rosbag2 directory) or one of
    bags.BAG_SUFFIXES."""
    from .bags import BAG_SUFFIXES
    return Path(path).suffix.lower() in (*BAG_SUFFIXES, '')


def _labels_of(labels, n: int) -> np.ndarray:
    """(n,) int32 plane labels from ``labels``; ValueError unless they are n whole numbers that fit an int32."""
    lab = np.asarray(labels)
    if lab.ndim != 1 or len(lab) != n:
        raise ValueError(f'labels must be one per point: a ({n},) array, got shape {lab.shape}')
    if lab.dtype.kind not in 'iub' and not (lab.dtype.kind == 'f' and np.all(np.isfinite(lab)) and
                                             np.all(lab == np.round(lab))):
        raise ValueError(f'labels must be whole numbers, got {lab.dtype}')
    info = np.iinfo(np.int32)
    if len(lab) and (lab.min() < info.min or lab.max() > info.max):
        raise ValueError(f'labels must fit an int32 ({info.min}..{info.max}), got {lab.min()}..{lab.max()}')
    return lab.astype(np.int32)


def check_output(path: str | Path, *, inputs: tuple[str | Path, ...] = ()) -> None:
    """ValueError unless :func:`save_points` can write ``path`` (known type, existing directory, not
    one of the ``inputs``)."""
    path = Path(path)
    _not_an_input(path, inputs)
    suffix = path.suffix.lower()
    if suffix not in ('.ply', '.pcd', '.npy', '.mcap', '.db3', '') + TEXT_SUFFIXES:
        raise ValueError(f'{path}: cannot write {suffix!r} files (use .ply, .pcd, .npy, .xyz, .txt, .csv, '
                         '.mcap, .db3 or a bag directory)')
    _in_a_directory(path)


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


# -- readers -------------------------------------------------------------------------------------


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _xyz_columns(path: Path, table: np.ndarray) -> np.ndarray:
    """First three columns of an (N, >=3) numeric table, or a clear error."""
    if table.dtype.names:
        xyz = [table.dtype.names[i] for i in _xyz_positions(path, table.dtype.names, fields=True)]
        for a in xyz:
            if table.dtype[a].kind not in 'fiu':  # a PLY list property, say
                raise ValueError(f'{path}: field {a} does not hold one number per point (dtype {table.dtype[a]})')
        scales = _unit_scales(path, xyz)
        columns = np.column_stack([table[a].reshape(-1) for a in xyz])
        return columns if (scales == 1.0).all() else columns * scales
    if table.dtype.kind not in 'fiu':
        raise ValueError(f'{path}: expected numbers, got dtype {table.dtype}')
    if table.ndim != 2 or table.shape[1] < 3:
        raise ValueError(f'{path}: expected rows of at least x y z, got shape {table.shape}')
    if table.shape[0] in (3, 4) and table.shape[1] > WIDEST_POINT_ROW:
        raise ValueError(f'{path}: shape {table.shape} looks like the coordinates in rows (x, y, z[, w]) with a '
                         f'point per column; write one point per row, (N, 3) (transpose it)')
    return table[:, :3]


def _read_npy(path: Path) -> np.ndarray:
    """(N, >=3) numeric array, or a structured array with x, y, z fields."""
    with open(path, 'rb') as head:
        if head.read(6) != b'\x93NUMPY':
            raise ValueError(f'{path}: not a .npy file (no NUMPY magic bytes)')
    try:
        table = np.load(path, allow_pickle=False)
    except Exception as exc:  # ValueError for bad magic, EOFError for empty files, ...
        raise ValueError(f'{path}: not a readable .npy array ({_first_line(exc)})') from exc
    if not isinstance(table, np.ndarray):
        raise ValueError(f'{path}: not a .npy array')
    return _xyz_columns(path, table)


def _loadtxt(source, delimiter: str | None = None, skiprows: int = 0, usecols: int | None = None) -> np.ndarray:
    """np.loadtxt as an (n, m) table (UTF-8, a byte-order mark skipped); no data is an empty table, not a warning.
    usecols: only the first this many columns (None: all)."""
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', UserWarning)  # "input contained no data"
        return np.loadtxt(source, delimiter=delimiter, ndmin=2, skiprows=skiprows, encoding='utf-8-sig',
                          usecols=None if usecols is None else range(usecols))


def _first_row(path: Path, header: bool = False) -> str:
    """The first line of a text table that is not blank or a comment, stripped ('' when there is none); after the
    first line when that is a ``header`` row."""
    with open(path, encoding='utf-8-sig', errors='replace') as f:
        for i, line in zip(range(1000), f):
            if (text := line.strip()) and not text.startswith('#') and not (header and i == 0):
                return text
    return ''


def _column_names(path: Path, delimiter: str | None) -> list[str] | None:
    """The first line's fields when it is a row of column names (``x,y,z,intensity_8bit``, CloudCompare's
    ``//X,Y,Z``: every field holds a letter and is no number), else None (``1,2,3`` in an .xyz is data)."""
    with open(path, 'rb') as f:
        first = f.readline(4096).decode('utf-8-sig', errors='replace').strip()
    comment = first.startswith('#')  # '# x y z i': names in a comment, which the table reader skips
    first = first.lstrip('#').strip()
    if delimiter is None and ',' in first and all(len(_UNIT.sub('', p.strip().strip('"\'')).split()) <= 1
                                                  for p in first.split(',')):
        delimiter = ','  # 'x,y,z', 'x (mm), y (mm), z (mm)', CloudCompare's '//X,Y,Z'; not 'X Y Z R,G,B'
    fields = [t.strip() for t in first.split(delimiter)] if first else []
    while delimiter and len(fields) > 1 and not fields[-1]:
        fields.pop()  # 'x,y,z,': a trailing delimiter ends the row, it starts no column
    if delimiter is None:  # 'x [m] y [m] z [m]': a unit split off its name is no column of its own, but its name's
        named: list[str] = []
        for t in fields:
            if named and t[:1] in '[(' and t[-1:] in '])':
                named[-1] += f' {t}'
            else:
                named.append(t)
        fields = named

    def name(text: str) -> bool:
        try:
            float(text)  # nan and inf are numbers
        except ValueError:
            return any(c.isalpha() for c in text)
        return False
    if not (fields and all(name(t) for t in fields)):
        return None
    if comment and not {_plain(n) for n in fields} & {a for names in AXIS_NAMES.values() for a in names}:
        return None  # a comment of other words ('# exported by ...'), not a row of column names
    return fields


#: A bracket after a header name: 'x [m]', 'x (mm)' (a unit when it names one of UNITS).
_UNIT = re.compile(r'\s*[\[(]([^\])]*)[\])]$')
#: Length units a header name or a record's field may give x, y and z in ('x (mm)'), as meters per unit: the points
#: are read in meters (ROS's unit, REP 103). Other words in brackets ('x (east)', 'x(1)') are no unit.
UNITS = {**dict.fromkeys(('m', 'meter', 'meters', 'metre', 'metres'), 1.0),
         **dict.fromkeys(('cm', 'centimeter', 'centimeters', 'centimetre', 'centimetres'), 0.01),
         **dict.fromkeys(('mm', 'millimeter', 'millimeters', 'millimetre', 'millimetres'), 0.001),
         **dict.fromkeys(('um', 'µm', 'micrometer', 'micrometers', 'micrometre', 'micrometres', 'micron'), 1e-6),
         **dict.fromkeys(('km', 'kilometer', 'kilometers', 'kilometre', 'kilometres'), 1000.0),
         **dict.fromkeys(('in', 'inch', 'inches'), 0.0254), **dict.fromkeys(('ft', 'foot', 'feet'), 0.3048),
         **dict.fromkeys(('yd', 'yard', 'yards'), 0.9144)}


def _plain(name: str, lower: bool = True) -> str:
    """A header name (in lower case) without quotes, CloudCompare's '//' and a bracket after it ('x [m]', 'x (m)')."""
    bare = _UNIT.sub('', str(name).strip('"\'').strip())
    return (bare.lower() if lower else bare).removeprefix('//').strip()


def _unit_scales(path: Path, names: list) -> np.ndarray:
    """(3,) meters per unit of the x, y and z ``names`` (a header's, or a record's fields: 'x (mm)' 0.001; no unit: 1,
    the file's unit); ValueError when some of them give a unit and others none ('x y z (mm)' would scale z alone)."""
    units = []
    for name in names:
        unit = _UNIT.search(str(name).strip('"\'').strip())
        unit = None if unit is None else unit[1].strip().lower()
        units.append(unit if unit in UNITS else None)
    if None in units and any(units):
        raise ValueError(f'{path}: only some of x, y and z give a unit ({", ".join(map(str, names))}): give one for '
                         'each, or none')
    return np.array([UNITS.get(unit, 1.0) for unit in units])


#: Header names taken for x, y and z (lower case, units and quotes removed), besides the letters themselves.
AXIS_NAMES = {'x': ('x', 'easting', 'east'), 'y': ('y', 'northing', 'north'),
              'z': ('z', 'height', 'elevation', 'altitude', 'up')}


def _xyz_positions(path: Path, names, *, fields: bool = False) -> list[int]:
    """The positions of x, y and z among ``names``, a text table's header row or (``fields``) the fields of a PLY
    vertex or .npy record (AXIS_NAMES): case-insensitive, quoted or not, the first with CloudCompare's ``//``
    prefix, a unit after the name allowed (``x [m]``, ``x (m)``), the letter before its other names (``x y z
    height``: z), the lower-case letter before the upper-case one; ValueError unless each is named once."""
    plain = [_plain(n) for n in names]
    found = []
    for axis in 'xyz':
        letter = [i for i, n in enumerate(plain) if n == axis]
        if len(letter) > 1:  # 'x' and 'X': the lower-case one
            letter = [i for i in letter if _plain(names[i], lower=False) == axis]
        found.append(letter if len(letter) == 1 else [i for i, n in enumerate(plain) if n in AXIS_NAMES[axis]])
    if all(len(f) == 1 for f in found):
        return [f[0] for f in found]
    if fields:
        why = 'no x, y, z fields' if any(not f for f in found) else 'more than one field for x, y or z'
        raise ValueError(f'{path}: {why} (fields: {" ".join(names)})')
    raise ValueError(f'{path}: the header row must name each of x, y and z once (or easting, northing, '
                     f'height), got the columns {", ".join(names)}')


#: Bytes a text table does not hold: control characters other than tab, line ends and form feed.
_NOT_TEXT = re.compile('[\x00-\x08\x0e-\x1f\x7f]')


def _check_text(path: Path) -> None:
    """ValueError when ``path`` does not start as UTF-8 text, with its first bytes shown escaped (not echoed raw
    into a terminal or a log)."""
    import codecs
    with open(path, 'rb') as f:
        head = f.read(4096)
    try:
        text = codecs.getincrementaldecoder('utf-8-sig')().decode(head)  # a character cut at the end is no error
    except UnicodeDecodeError:
        text = None
    if text is None or _NOT_TEXT.search(text):
        shown = repr(head[:24])[2:-1] + ('...' if len(head) > 24 else '')
        raise ValueError(f'{path}: not a text file (it starts with the bytes "{shown}"); a {path.suffix} file is '
                         'a text table of numbers')


def _read_text(path: Path) -> np.ndarray:
    """x, y, z of a text table: the columns a header row names so, else the first three."""
    _check_text(path)
    delimiter = ',' if path.suffix.lower() == '.csv' else None
    names = _column_names(path, delimiter)
    columns = None if names is None else _xyz_positions(path, names)
    scales = None if names is None else _unit_scales(path, [names[i] for i in columns])
    first = _first_row(path, header=names is not None)
    if delimiter is None and names is not None and ',' in first:  # CloudCompare's '//X,Y,Z' over rows '1,2,3'
        delimiter = ','
    used = None  # rows ending in the delimiter ('1,2,3,', as some exporters write): the empty last field is no column
    if delimiter and first.endswith(delimiter):
        used = len(first.split(delimiter)) - 1
    try:
        table = _loadtxt(path, delimiter, int(names is not None), used)
    except Exception as exc:  # ValueError on non-numbers, UnicodeDecodeError on binary bytes
        why = _first_line(exc).split('; use `usecols`')[0]  # numpy's advice is for its API, not for a file's user
        raise ValueError(f'{path}: not a table of numbers ({why})') from exc
    if table.size == 0:
        return np.empty((0, 3))
    if columns is not None:
        if table.shape[1] != len(names):
            raise ValueError(f'{path}: the header row names {len(names)} columns, the rows have {table.shape[1]}')
        table = table[:, columns] if (scales == 1.0).all() else table[:, columns] * scales
    return _xyz_columns(path, table)


def _read_ply(path: Path) -> np.ndarray:
    """Vertex x, y, z of an ascii or binary PLY file."""
    try:
        from plyfile import PlyData
    except ImportError as exc:
        raise ValueError(f'{path}: reading .ply needs plyfile (pip install plyfile)') from exc
    try:
        with path.open('rb') as stream:
            ply = PlyData.read(stream)
            end = None if ply.text else stream.tell()  # (an ascii read closes the stream)
    except Exception as exc:  # PlyParseError, and plain ValueErrors/EOFErrors on damaged bodies
        raise ValueError(f'{path}: not a readable PLY file ({_first_line(exc)})') from exc
    _check_ply_rest(path, ply, end)
    names = [e.name for e in ply.elements]
    if 'vertex' not in names:
        raise ValueError(f'{path}: PLY has no vertex element (elements: {" ".join(names) or "none"})')
    vertex = ply['vertex'].data
    return _xyz_columns(path, vertex)


def _check_ply_rest(path: Path, ply, end: int | None) -> None:
    """ValueError when a PLY file holds data beyond the elements its header declares (an element count too
    small: those records would go unread): lines after the last record (ascii), or after the byte ``end`` where the
    records end (binary) bytes other than line ends and spaces, or NUL padding as long as a record or longer."""
    declared = sum(len(element.data) for element in ply.elements)
    with path.open('rb') as stream:
        if end is None:
            for line in stream:  # line by line: a large ascii file is not held twice
                if line.strip() == b'end_header':
                    break
            records = sum(1 for line in stream if line.strip())
            if records > declared:
                raise ValueError(f'{path}: PLY holds {records} records after its header, which declares {declared}: '
                                 'an element count too small, or other data appended')
            return
        stream.seek(end)
        rest = stream.read()
    if _appended(rest, ply.elements[-1].data.dtype.itemsize if ply.elements else 1):
        raise ValueError(f'{path}: PLY holds {len(rest)} bytes after its {declared} declared records: an element '
                         'count too small, or other data appended')


def _pcd_header(raw: bytes) -> tuple[dict[str, list[str]], int] | None:
    """(KEY -> values, offset of the data) of a PCD file's bytes; None without a DATA line."""
    header: dict[str, list[str]] = {}
    offset = 0
    while True:
        end = raw.find(b'\n', offset)
        if end < 0:
            return None
        line = raw[offset:end].decode('ascii', errors='replace').strip()
        offset = end + 1
        if not line or line.startswith('#'):
            continue
        key, *values = line.split()
        header[key.upper()] = values
        if key.upper() == 'DATA':
            return header, offset


def _read_pcd(path: Path) -> np.ndarray:
    return _read_pcd_scan(path)[0]



def _appended(rest: bytes, record: int) -> bool:
    """Whether ``rest``, the bytes after a binary file's last declared record (``record`` bytes long), is data
    (records that would go unread, or something appended) rather than padding: line ends, spaces, or NULs
    shorter than a record."""
    return bool(rest.strip()) and bool(rest.strip(b'\x00 \t\r\n') or len(rest) >= record)


def _check_binary_size(path: Path, data: memoryview, n: int, point_bytes: int) -> None:
    """A binary PCD's ``data`` must hold its ``n`` points: not fewer (cut short) and nothing but padding after
    them (POINTS too small, and points would go unread, or other data appended), as for a PLY file."""
    held = len(data)
    if held < n * point_bytes:
        raise ValueError(f'{path}: PCD data holds {held} bytes, {n} points need {n * point_bytes}')
    if _appended(bytes(data[n * point_bytes:]), point_bytes):
        raise ValueError(f'{path}: PCD data holds {held} bytes, more than its {n} points need '
                         f'({n * point_bytes}): POINTS too small, or other data appended')

def _read_pcd_scan(path: Path) -> tuple[np.ndarray, np.ndarray | None, tuple[int, int] | None]:
    """(n, 3) float64 x, y, z of a PCD file, its ``ring`` field (n,) as :func:`beam_numbers` gives it when
    it has one of count 1 (else None), and its image shape (H, W) when HEIGHT > 1 (else None)."""
    raw = path.read_bytes()
    parsed = _pcd_header(raw)
    if parsed is None:
        raise ValueError(f'{path}: PCD header has no DATA line')
    header, offset = parsed
    try:
        fields = header['FIELDS']
        sizes = [int(v) for v in header['SIZE']]
        types = header['TYPE']
        counts = [int(v) for v in header.get('COUNT', ['1'] * len(fields))]
        n = int(header['POINTS'][0]) if 'POINTS' in header else \
            int(header['WIDTH'][0]) * int(header['HEIGHT'][0])
        data = header['DATA'][0].lower()
    except (KeyError, IndexError, ValueError) as exc:
        raise ValueError(f'{path}: malformed PCD header ({exc})') from exc
    if not {'x', 'y', 'z'} <= set(fields):
        raise ValueError(f'{path}: PCD has no x, y, z fields (fields: {" ".join(fields)})')
    repeated = [a for a in 'xyz' if fields.count(a) > 1]  # which x would be meant? (other fields: the first)
    if repeated:
        raise ValueError(f'{path}: PCD field {repeated[0]!r} appears more than once (FIELDS {" ".join(fields)})')
    if not len(fields) == len(sizes) == len(types) == len(counts):
        raise ValueError(f'{path}: PCD FIELDS, SIZE, TYPE and COUNT disagree in length')
    if n < 0:
        raise ValueError(f'{path}: PCD declares {n} points')
    if any(c < 1 for c in counts) or any(counts[fields.index(a)] != 1 for a in 'xyz'):
        raise ValueError(f'{path}: PCD COUNT must be at least 1 per field and 1 for x, y and z, got '
                         f'{" ".join(map(str, counts))}')
    if sum(size * count for size, count in zip(sizes, counts)) >= 2 ** 31:  # beyond what a numpy record can hold
        raise ValueError(f'{path}: a PCD point of more than 2 GiB (SIZE x COUNT {" ".join(map(str, counts))}): '
                         'a corrupt header?')
    try:
        image = int(header['WIDTH'][0]) * int(header['HEIGHT'][0]) if 'WIDTH' in header and 'HEIGHT' in header else n
    except (IndexError, ValueError) as exc:
        raise ValueError(f'{path}: malformed PCD header ({exc})') from exc
    if image != n:
        raise ValueError(f'{path}: PCD header says WIDTH x HEIGHT = {image} but POINTS {n}')
    shape = (int(header['HEIGHT'][0]), int(header['WIDTH'][0])) if 'HEIGHT' in header and 'WIDTH' in header else None
    shape = shape if shape and shape[0] > 1 else None
    k = fields.index('ring') if 'ring' in fields else -1
    has_ring = k >= 0 and counts[k] == 1  # integer, or float holding whole numbers (beam_numbers)
    if data == 'ascii':
        try:
            table = _loadtxt(raw[offset:].decode('ascii', errors='replace').splitlines())
        except ValueError as exc:
            why = _first_line(exc).split('; use `usecols`')[0]  # numpy's advice is about its own call
            raise ValueError(f'{path}: bad ascii PCD data ({why}; a truncated file?)') from exc
        columns = np.cumsum([0] + counts)
        if table.size and table.shape[1] < columns[-1]:
            raise ValueError(f'{path}: ascii PCD rows have {table.shape[1]} values, the fields need {columns[-1]}')
        rows = len(table) if table.size else 0
        if rows != n:
            raise ValueError(f'{path}: ascii PCD data has {rows} rows, the header declares {n} points')
        if not rows:
            return np.empty((0, 3)), (np.empty(0, np.int64) if has_ring else None), shape
        xyz = np.column_stack([table[:, columns[fields.index(a)]] for a in 'xyz']).astype(np.float64)
        return xyz, beam_numbers(table[:, columns[k]]) if has_ring else None, shape
    if data == 'binary':
        try:
            dtype = np.dtype([(f if f != '_' and fields.index(f) == i else f'_{i}', '<' + _PCD_TYPES[(t.upper(), s)],
                               (c,)) for i, (f, s, t, c) in enumerate(zip(fields, sizes, types, counts))])
        except KeyError as exc:
            raise ValueError(f'{path}: unsupported PCD TYPE/SIZE {exc}') from exc
        _check_binary_size(path, memoryview(raw)[offset:], n, dtype.itemsize)
        records = np.frombuffer(raw, dtype=dtype, count=n, offset=offset)
        xyz = np.column_stack([records[a][:, 0] for a in 'xyz']).astype(np.float64)
        return xyz, beam_numbers(records['ring'][:, 0]) if has_ring else None, shape
    if data == 'binary_compressed':
        point_bytes = sum(size * count for size, count in zip(sizes, counts))
        return _read_pcd_compressed(path, raw[offset:], n, point_bytes, has_ring) + (shape,)
    raise ValueError(f'{path}: unknown PCD DATA type {data!r}')


def _read_pcd_compressed(path: Path, data: bytes, n: int, point_bytes: int, has_ring: bool
                         ) -> tuple[np.ndarray, np.ndarray | None]:
    """x, y, z (n, 3) and the ring field (or None) of a binary_compressed PCD's ``data`` (its LZF block:
    compressed size, uncompressed size (uint32 each), then the fields one after another), read by pypcd4."""
    try:
        from pypcd4 import PointCloud  # LZF-compressed PCD
    except ImportError as exc:
        raise ValueError(f'{path}: binary_compressed PCD needs pypcd4 (pip install pypcd4)') from exc
    if n * point_bytes == 0 and len(data) < 8:  # pypcd4 writes no data block for an empty cloud
        return np.empty((0, 3)), (np.empty(0, np.int64) if has_ring else None)
    if len(data) < 8:
        raise ValueError(f'{path}: binary_compressed PCD data is cut short ({len(data)} bytes)')
    unpacked = int(np.frombuffer(data, '<u4', 2)[1])
    if unpacked != n * point_bytes:
        raise ValueError(f'{path}: binary_compressed PCD data unpacks to {unpacked} bytes, but its {n} points '
                         f'of {point_bytes} bytes need {n * point_bytes}: POINTS (or WIDTH x HEIGHT) is wrong')
    try:
        cloud = PointCloud.from_path(path)
        xyz = cloud.numpy(('x', 'y', 'z')).astype(np.float64)
        return xyz, beam_numbers(cloud.numpy(('ring',))[:, 0]) if has_ring else None
    except Exception as exc:  # pypcd4 reports problems with many exception types
        why = _lzf_problem(data, unpacked) or _first_line(exc)
        raise ValueError(f'{path}: cannot read binary_compressed PCD: {why}') from exc


def _lzf_problem(data: bytes, unpacked: int) -> str | None:
    """Why the LZF block of a binary_compressed PCD's ``data`` (compressed and uncompressed size, then the block)
    does not decompress to the ``unpacked`` bytes its header needs; None when it does."""
    import lzf  # pypcd4's LZF module (python-neo-lzf): there whenever pypcd4 is

    size = int(np.frombuffer(data, '<u4', 1)[0])
    try:
        got = lzf.decompress(data[8:8 + size], unpacked)
    except ValueError as exc:  # "error in compressed data"
        return f'the compressed data is corrupt (LZF: {exc})'
    if got is None:  # more bytes than that
        return (f'the compressed data decompresses to more than the {unpacked} bytes the header\'s fields need: '
                'corrupt, or FIELDS/SIZE/COUNT leave a field out')
    if len(got) != unpacked:
        return (f'the compressed data decompresses to {len(got)} bytes, the header\'s fields need {unpacked}: '
                'cut short or corrupt')
    return None


# -- writers -------------------------------------------------------------------------------------


#: Written coordinates are float32 unless float32 would round one by more than this (meters): then
#: float64 (georeferenced clouds, UTM coordinates in the millions of meters, need it).
COORDINATE_PRECISION = 1e-4
#: The magnitude (838.9 m) up to which float32's spacing is finer than COORDINATE_PRECISION.
FLOAT32_FINE = COORDINATE_PRECISION * 2.0 ** 23


def _float32_fine(points: np.ndarray) -> bool:
    """Whether every finite coordinate is within FLOAT32_FINE."""
    bound = FLOAT32_FINE
    if not points.size or (-bound <= np.fmin.reduce(points, axis=None) and np.fmax.reduce(points, axis=None) <= bound):
        return True  # the usual case, without copying the finite values (fmin/fmax skip NaN)
    finite = np.abs(points[np.isfinite(points)])
    return not finite.size or finite.max() <= bound


def coordinate_dtype(points: np.ndarray) -> np.dtype:
    """float32 for written coordinates, float64 when float32 would round a finite one by more than
    COORDINATE_PRECISION or write it as inf (coordinates that came as float32 stay float32)."""
    if _float32_fine(points):
        return np.dtype('<f4')
    finite = points[np.isfinite(points)]
    with np.errstate(over='ignore'):
        error = np.abs(finite.astype(np.float32).astype(np.float64) - finite).max()
    return np.dtype('<f8' if error > COORDINATE_PRECISION else '<f4')


def _write_pcd(path: Path, points: np.ndarray, labels: np.ndarray | None,
               shape: tuple[int, int] | None = None, viewpoint=None) -> None:
    """Binary PCD v0.7, float32 x y z (float64 beyond float32's range) (+ int32 label); organized
    (HEIGHT H, WIDTH W) for a ``shape``; VIEWPOINT ``viewpoint`` (see save_points)."""
    height, width = (int(shape[0]), int(shape[1])) if shape is not None else (1, len(points))
    pose = np.array([0.0, 0, 0, 1, 0, 0, 0])
    given = np.zeros(0) if viewpoint is None else np.asarray(viewpoint, dtype=np.float64).reshape(-1)
    if len(given) not in (0, 3, 7) or not np.isfinite(given).all():
        raise ValueError(f'a PCD viewpoint is 3 or 7 finite numbers, got {given.tolist()}')
    pose[:len(given)] = given
    names = ['x', 'y', 'z'] + ([] if labels is None else ['label'])
    real = coordinate_dtype(points)
    dtype = np.dtype([(name, real) for name in 'xyz'] + ([] if labels is None else [('label', '<i4')]))
    records = np.empty(len(points), dtype)
    for i, name in enumerate('xyz'):
        records[name] = points[:, i]
    if labels is not None:
        records['label'] = labels
    header = ('# .PCD v0.7 - Point Cloud Data file format (written by plane_validation)\n'
              'VERSION 0.7\n'
              f'FIELDS {" ".join(names)}\n'
              f'SIZE {" ".join("4" if n == "label" else str(real.itemsize) for n in names)}\n'
              f'TYPE {" ".join("I" if n == "label" else "F" for n in names)}\n'
              f'COUNT {" ".join("1" for _ in names)}\n'
              f'WIDTH {width}\nHEIGHT {height}\nVIEWPOINT {" ".join(repr(float(v)) for v in pose)}\n'
              f'POINTS {len(points)}\nDATA binary\n')
    path.write_bytes(header.encode('ascii') + records.tobytes())


def _write_ply(path: Path, points: np.ndarray, labels: np.ndarray | None) -> None:
    """Binary little-endian PLY: vertex float32 x y z (float64 beyond float32's range) (+ int32 plane_id)."""
    try:
        from plyfile import PlyData, PlyElement
    except ImportError as exc:
        raise ValueError(f'{path}: writing .ply needs plyfile (pip install plyfile)') from exc
    real = coordinate_dtype(points).str
    dtype = [('x', real), ('y', real), ('z', real)] + ([] if labels is None else [('plane_id', '<i4')])
    vertex = np.empty(len(points), dtype)
    for i, name in enumerate('xyz'):
        vertex[name] = points[:, i]
    if labels is not None:
        vertex['plane_id'] = labels
    element = PlyElement.describe(vertex, 'vertex')
    PlyData([element], text=False, byte_order='<',
            comments=['written by plane_validation; plane_id -1 = unassigned']).write(str(path))


def _write_npy(path: Path, points: np.ndarray, labels: np.ndarray | None) -> None:
    """(N, 3) float64, or (N, 4) with the label column. Through an open file: np.save given a name that does not
    end in '.npy' (OUT.NPY, or a temporary name) would write to that name + '.npy' instead."""
    with path.open('wb') as f:
        np.save(f, points if labels is None else np.column_stack([points, labels.astype(np.float64)]))


def _write_text(path: Path, points: np.ndarray, labels: np.ndarray | None) -> None:
    sep = ',' if path.suffix.lower() == '.csv' else ' '
    digits = '%.9g' if _float32_fine(points) else '%.17g'  # 9 significant digits keep as much as float32
    if labels is None:
        np.savetxt(path, points, fmt=digits, delimiter=sep)
    else:
        np.savetxt(path, np.column_stack([points, labels]), fmt=[digits] * 3 + ['%d'], delimiter=sep)
