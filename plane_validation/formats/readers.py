"""Readers of point files: x, y, z (N, 3) float64 from .npy, text (.xyz .txt .csv), PLY and PCD files, each problem a
``ValueError`` naming the file (see :mod:`.files`, which picks the reader)."""
from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from ..core.geometry import beam_numbers

__all__ = ['read_npy', 'read_text', 'read_ply', 'read_pcd', 'read_pcd_scan', 'pcd_header', 'UNITS', 'AXIS_NAMES',
           'WIDEST_POINT_ROW', 'PCD_HEADER_MAX']


#: A table of 3 or 4 rows wider than this is taken for coordinates in rows (a point per column), and refused.
WIDEST_POINT_ROW = 16


#: PCD TYPE letter and SIZE -> numpy dtype character.
_PCD_TYPES = {('F', 4): 'f4', ('F', 8): 'f8', ('I', 1): 'i1', ('I', 2): 'i2', ('I', 4): 'i4', ('I', 8): 'i8',
              ('U', 1): 'u1', ('U', 2): 'u2', ('U', 4): 'u4', ('U', 8): 'u8'}


#: A PCD header is read from at most this many bytes (its lines are short; a comment could be long).
PCD_HEADER_MAX = 1 << 16


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


def read_npy(path: Path) -> np.ndarray:
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


def read_text(path: Path) -> np.ndarray:
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


def read_ply(path: Path) -> np.ndarray:
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


def pcd_header(raw: bytes) -> tuple[dict[str, list[str]], int] | None:
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


def read_pcd(path: Path) -> np.ndarray:
    return read_pcd_scan(path)[0]


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


def read_pcd_scan(path: Path) -> tuple[np.ndarray, np.ndarray | None, tuple[int, int] | None]:
    """(n, 3) float64 x, y, z of a PCD file, its ``ring`` field (n,) as :func:`..core.geometry.beam_numbers` gives it
    when it has one of count 1 (else None), and its image shape (H, W) when HEIGHT > 1 (else None)."""
    raw = path.read_bytes()
    parsed = pcd_header(raw)
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
