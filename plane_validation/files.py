"""Point files for the command line: PCD (ascii, binary; binary_compressed via pypcd4), .npy, text."""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ['load_points']

#: PCD TYPE letter and SIZE -> numpy dtype character.
_PCD_TYPES = {('F', 4): 'f4', ('F', 8): 'f8', ('I', 1): 'i1', ('I', 2): 'i2', ('I', 4): 'i4', ('I', 8): 'i8',
              ('U', 1): 'u1', ('U', 2): 'u2', ('U', 4): 'u4', ('U', 8): 'u8'}


def load_points(path: str | Path) -> np.ndarray:
    """(N, 3) x, y, z from a .pcd, .npy, or whitespace/comma separated text file (.xyz .txt .csv).

    Organized PCD files keep their NaN rows. Raises ValueError naming the problem.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f'no such file: {path}')
    suffix = path.suffix.lower()
    if suffix == '.pcd':
        return _read_pcd(path)
    if suffix == '.npy':
        pts = np.load(path)
    elif suffix in ('.xyz', '.txt', '.csv'):
        pts = np.loadtxt(path, delimiter=',' if suffix == '.csv' else None, ndmin=2)
    else:
        raise ValueError(f'{path}: unsupported file type {suffix!r} (use .pcd, .npy, .xyz, .txt or .csv)')
    if pts.ndim != 2 or pts.shape[1] < 3:
        raise ValueError(f'{path}: expected rows of at least x y z, got shape {pts.shape}')
    return pts[:, :3]


def _read_pcd(path: Path) -> np.ndarray:
    raw = path.read_bytes()
    header: dict[str, list[str]] = {}
    offset = 0
    while True:
        end = raw.find(b'\n', offset)
        if end < 0:
            raise ValueError(f'{path}: PCD header has no DATA line')
        line = raw[offset:end].decode('ascii', errors='replace').strip()
        offset = end + 1
        if not line or line.startswith('#'):
            continue
        key, *values = line.split()
        header[key.upper()] = values
        if key.upper() == 'DATA':
            break
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
    if not len(fields) == len(sizes) == len(types) == len(counts):
        raise ValueError(f'{path}: PCD FIELDS, SIZE, TYPE and COUNT disagree in length')
    if data == 'ascii':
        table = np.loadtxt(raw[offset:].decode('ascii', errors='replace').splitlines(), ndmin=2)
        columns = np.cumsum([0] + counts)
        return np.column_stack([table[:, columns[fields.index(a)]] for a in 'xyz']).astype(np.float64)
    if data == 'binary':
        try:
            dtype = np.dtype([(f if f != '_' else f'_pad{i}', '<' + _PCD_TYPES[(t.upper(), s)], (c,))
                              for i, (f, s, t, c) in enumerate(zip(fields, sizes, types, counts))])
        except KeyError as exc:
            raise ValueError(f'{path}: unsupported PCD TYPE/SIZE {exc}') from exc
        if len(raw) - offset < n * dtype.itemsize:
            raise ValueError(f'{path}: PCD data holds {len(raw) - offset} bytes, {n} points need '
                             f'{n * dtype.itemsize}')
        records = np.frombuffer(raw, dtype=dtype, count=n, offset=offset)
        return np.column_stack([records[a][:, 0] for a in 'xyz']).astype(np.float64)
    if data == 'binary_compressed':
        try:
            from pypcd4 import PointCloud  # LZF-compressed PCD
        except ImportError as exc:
            raise ValueError(f'{path}: binary_compressed PCD needs pypcd4 (pip install pypcd4)') from exc
        try:
            return PointCloud.from_path(path).numpy(('x', 'y', 'z')).astype(np.float64)
        except Exception as exc:  # pypcd4 reports problems with many exception types
            first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise ValueError(f'{path}: cannot read binary_compressed PCD: {first}') from exc
    raise ValueError(f'{path}: unknown PCD DATA type {data!r}')
