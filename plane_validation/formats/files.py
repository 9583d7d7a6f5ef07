"""Point files for the command line: read x, y, z from PCD, PLY, .npy, text or a bag; write labelled clouds.

Readers return an (N, 3) float64 array in the file's unit (meters for real sensors; a header name
``x (mm)`` or ``x [cm]`` is converted to meters). Rows of organized clouds keep their NaN holes, so row
i of the result is point i of the file. Every problem with a file (missing, unknown extension, corrupt
bytes, no x/y/z) raises ``ValueError`` with a one-line message naming the file.

The readers are in :mod:`.readers`: PCD ascii and binary read there (any VERSION; fast, no extra dependency),
binary_compressed (LZF) through ``pypcd4``; PLY through ``plyfile`` (GPL-3.0, imported only for .ply files).
Bags (``BAG[:TOPIC[:INDEX]]``): see :mod:`.bags`. Outputs are complete or absent (:mod:`.outputs`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .outputs import atomic_output, check_writable
from .readers import PCD_HEADER_MAX, pcd_header, read_npy, read_pcd, read_pcd_scan, read_ply, read_text

__all__ = ['check_output', 'load_cloud', 'load_points', 'load_scan', 'save_points', 'is_bag_output', 'pcd_viewpoint',
           'coordinate_dtype', 'POINT_SUFFIXES', 'TEXT_SUFFIXES']

#: Extensions of plain point files (bags are recognised separately).
TEXT_SUFFIXES = ('.xyz', '.txt', '.csv')
POINT_SUFFIXES = ('.pcd', '.ply', '.npy') + TEXT_SUFFIXES


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
    reader = {'.pcd': read_pcd, '.ply': read_ply, '.npy': read_npy}.get(suffix, read_text)
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
        points, ring, shape = read_pcd_scan(Path(source))
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
        parsed = pcd_header(f.read(PCD_HEADER_MAX))
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
    suffix = path.suffix.lower()
    if suffix not in ('.ply', '.pcd', '.npy', '.mcap', '.db3', '') + TEXT_SUFFIXES:
        raise ValueError(f'{path}: cannot write {suffix!r} files (use .ply, .pcd, .npy, .xyz, .txt, .csv, '
                         '.mcap, .db3 or a bag directory)')
    check_writable(path, inputs=inputs)


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
