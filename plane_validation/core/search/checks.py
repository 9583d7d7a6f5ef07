"""Checks at the edge of the search: arguments and points are validated here, with clear errors, before any
search step or compiled kernel sees them."""
from __future__ import annotations

import decimal
import numbers

import numpy as np

from .. import kernels
from .types import Viewpoint

__all__ = ['generator', 'check_integer', 'check_number', 'check_flag', 'as_points', 'finite_rows', 'finite_extent',
           'no_returns_as_nan', 'no_returns_note', 'check_magnitude', 'min_inliers_number', 'resolve_min_inliers',
           'check_shape', 'check_viewpoint', 'check_search_size', 'gathered_rows', 'AT_VIEWPOINT', 'MAX_COORDINATE',
           'MAX_SPREAD']


def generator(seed: int | np.random.Generator | None) -> np.random.Generator:
    """A numpy Generator from ``seed``: an integer >= 0, a Generator (used as is), None (fresh entropy), or what
    else ``np.random.default_rng`` takes (a SeedSequence, a BitGenerator, integers); ValueError otherwise (the
    command line's and the node's seed -1 is None here)."""
    if isinstance(seed, np.random.Generator):
        return seed
    why = f'seed must be an integer >= 0, a numpy Generator or None (fresh entropy), got {seed!r}'
    if isinstance(seed, (bool, np.bool_, float, np.floating, str)) or \
            (isinstance(seed, (int, np.integer)) and seed < 0):
        raise ValueError(why)
    try:
        return np.random.default_rng(seed)
    except (TypeError, ValueError):
        raise ValueError(why) from None


def check_integer(name: str, value, low: int | None) -> int:
    """``value`` as an int, or ValueError unless it is a whole number (not a bool), >= ``low`` unless that is None."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer, float, np.floating)) \
            or (isinstance(value, (float, np.floating)) and not np.isfinite(value)) or int(value) != value \
            or (low is not None and value < low):
        raise ValueError(f'{name} must be an integer{"" if low is None else f" >= {low}"}, got {value!r}')
    return int(value)


def check_number(name: str, value, what: str = 'a number') -> float:
    """``value`` as a float, or ValueError unless it is a real number (a numpy scalar or 0-d array too; not a bool,
    a string or None) that is finite; ``what`` says what was expected."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Real, decimal.Decimal)):
        raise ValueError(f'{name} must be {what}, got {value!r}')
    try:  # a Python int may be beyond float's range (np.isfinite cannot take it either)
        number = float(value)
    except OverflowError:
        number = np.inf
    if not np.isfinite(number):
        raise ValueError(f'{name} must be {what}, got {value!r}')
    return number


def check_flag(name: str, value) -> bool:
    """``value`` as a bool, or ValueError unless it is one (a string such as 'no' would count as true)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f'{name} must be True or False, got {value!r}')
    return bool(value)


def as_points(points: np.ndarray) -> np.ndarray:
    """Validate an (N, 3) real array and return it as float64 (no copy when already float64); a masked array's
    masked coordinates become NaN (their rows are no points, as NaN rows)."""
    arr = np.asarray(points)  # (a masked array's data, mask dropped)
    if arr.dtype.kind not in 'fiu':
        raise ValueError(f'points must be a real numeric array, got dtype {arr.dtype}')
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f'points must have shape (N, 3), got {arr.shape}')
    if isinstance(points, np.ma.MaskedArray) and np.ma.is_masked(points):
        return np.where(np.ma.getmaskarray(points), np.nan, arr.astype(np.float64))
    return arr.astype(np.float64, copy=False)


#: rows_less subtracts nothing from the rows gathered.
_ORIGIN = np.zeros(3)


def gathered_rows(values: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``values[rows]`` ((n, 3), ``rows`` (m,)) in one compiled pass (:func:`.kernels.rows_less`; numpy's gather of
    3-wide rows is several times slower)."""
    return kernels.rows_less(kernels.c_array(values, np.float64), kernels.c_array(rows, np.int64), _ORIGIN)


def finite_rows(points: np.ndarray) -> np.ndarray:
    """(N,) bool: rows of the (N, 3) array whose three coordinates are finite (one compiled pass over a
    C-ordered float64 array; otherwise column by column: numpy's reduction along a length-3 axis is several
    times slower)."""
    if points.dtype == np.float64 and points.flags.c_contiguous and points.flags.writeable:
        return kernels.finite_mask(points)[0]
    ok = np.isfinite(points[:, 0])
    ok &= np.isfinite(points[:, 1])
    ok &= np.isfinite(points[:, 2])
    return ok


#: A row this close to a viewpoint other than the origin (meters, in each coordinate) is the driver's
#: (0, 0, 0) "no return" mark moved with the cloud (float32 rounding of the transform); no sensor
#: reports a point this close to itself.
AT_VIEWPOINT = 1e-6


def no_returns_as_nan(points: np.ndarray, viewpoint: Viewpoint = None) -> tuple[np.ndarray, int]:
    """``points`` (N, 3) with rows at exactly (0, 0, 0) set to NaN (a copy, only when there are any),
    and how many there were: the "no return" mark of sensor drivers that do not use NaN (a lidar
    or depth camera reports no point at its own origin). With a ``viewpoint`` (3,) other than the
    origin (a cloud moved to another frame), rows within AT_VIEWPOINT of it instead."""
    view = check_viewpoint(viewpoint)

    def at_mark(axis: int) -> np.ndarray:
        column = points[:, axis]
        return np.abs(column - view[axis]) <= AT_VIEWPOINT if view.any() else column == 0

    zero = at_mark(0)
    if not zero.any():  # the usual frame: one comparison
        return points, 0
    zero &= at_mark(1) & at_mark(2)
    count = int(np.count_nonzero(zero))
    if count == 0:
        return points, 0
    out = np.array(points, dtype=np.result_type(points.dtype, np.float32))
    out[zero] = np.nan
    return out, count


def no_returns_note(count: int) -> str:
    """What a message about too few points adds when ``count`` rows were left out as "no return" marks."""
    return f'; {count} were left out as a driver\'s "no return" mark (at (0, 0, 0), or at the viewpoint; ' \
        'zero_is_no_return)' if count else ''


#: Largest coordinate magnitude accepted, meters: squared distances of larger ones overflow float64 (a
#: single far row below it, such as a driver's FLT_MAX, is a point far from every plane).
MAX_COORDINATE = 1e150


#: Largest spread of a cloud's points around their middle, meters (the SPREAD_PERCENTILE of their largest
#: coordinate offset from the median, on about SPREAD_ROWS of them): the hypotheses are scored in float32,
#: whose range (3.4e38) such offsets and their planes' offsets would leave; no sensor sees this far.
MAX_SPREAD = 1e30


SPREAD_PERCENTILE = 90


SPREAD_ROWS = 1024


def _largest_magnitude(flat: np.ndarray) -> float:
    """The largest |coordinate| of ``flat`` (n,) that is not NaN (inf counts), NaN when none: one compiled pass over
    float64 (:func:`.kernels.largest_magnitude`), numpy's fmax and fmin otherwise (and as the reference)."""
    if flat.dtype == np.float64:
        return float(kernels.largest_magnitude(flat))
    return largest_magnitude_numpy(flat)


def largest_magnitude_numpy(flat: np.ndarray) -> float:
    """:func:`_largest_magnitude` by numpy."""
    return max(np.fmax.reduce(flat), -np.fmin.reduce(flat))


def finite_extent(points: np.ndarray) -> tuple[np.ndarray, float]:
    """:func:`finite_rows` of ``points`` (N, 3) and the largest |coordinate| that is not NaN (inf counts; NaN when
    none), what :func:`check_magnitude` tests: one compiled pass over a C-ordered float64 array
    (:func:`.kernels.finite_extent`), two otherwise."""
    if points.dtype == np.float64 and points.flags.c_contiguous and points.flags.writeable:
        finite, _, largest = kernels.finite_extent(points)
        return finite, float(largest)
    return finite_rows(points), (_largest_magnitude(points.reshape(-1)) if points.size else np.nan)


def check_magnitude(points: np.ndarray, largest: float | None = None) -> None:
    """ValueError when a finite coordinate of ``points`` (N, 3) exceeds MAX_COORDINATE in magnitude
    (NaN and inf rows are ignored: they are no points), or when the points spread over more than MAX_SPREAD.
    ``largest``: their largest |coordinate| not NaN, when already known (:func:`finite_extent`)."""
    flat = points.reshape(-1)
    if len(flat) == 0:
        return
    if largest is None:
        largest = _largest_magnitude(flat)  # NaN when every coordinate is NaN
    if largest > MAX_COORDINATE:
        big = np.abs(flat[np.abs(flat) > MAX_COORDINATE])
        worst = float(big[np.isfinite(big)].max(initial=0.0))
        if worst > MAX_COORDINATE:
            raise ValueError(f'a coordinate reaches {worst:.3g} m: beyond {MAX_COORDINATE:g} m squared distances '
                             'overflow (wrong units or a corrupt cloud?)')
    if not largest > MAX_SPREAD:  # (also NaN) no spread can exceed it
        return
    rows = points[::max(1, len(points) // SPREAD_ROWS)]
    rows = rows[finite_rows(rows)]
    if len(rows) == 0:
        return
    spread = float(np.percentile(np.abs(rows - np.median(rows, axis=0)).max(axis=1), SPREAD_PERCENTILE))
    if spread > MAX_SPREAD:
        raise ValueError(f'the points spread over {spread:.3g} m around their middle: beyond {MAX_SPREAD:g} m, which '
                         'the search cannot score (wrong units or a corrupt cloud?)')


def min_inliers_number(min_inliers) -> int | float:
    """``min_inliers`` as an int (a count) when given as an integer type, else as a float (a fraction when < 1, a
    count otherwise: a Decimal or Fraction too); ValueError unless a real number >= 0."""
    if isinstance(min_inliers, np.ndarray) and min_inliers.ndim == 0:
        min_inliers = min_inliers[()]  # a 0-d array means its number: a fraction stays a fraction
    number = check_number('min_inliers', min_inliers, 'a count >= 0 or a fraction in [0, 1)')
    if number < 0:
        raise ValueError(f'min_inliers must be a count >= 0 or a fraction in [0, 1), got {min_inliers!r}')
    return int(min_inliers) if isinstance(min_inliers, (int, np.integer)) else number


def resolve_min_inliers(min_inliers: int | float, n_valid: int) -> int:
    """An absolute count, or a fraction of ``n_valid`` when ``min_inliers`` is not of an integer type and < 1."""
    number = min_inliers_number(min_inliers)
    if isinstance(number, float) and number < 1:
        return max(3, int(np.ceil(number * n_valid)))
    return max(3, int(number))


def check_search_size(name: str, value) -> None:
    """ValueError unless ``value`` (``ransac_points`` or ``grid_points``) is None or a whole number >= 3."""
    if value is not None:
        try:
            check_integer(name, value, 3)
        except ValueError:
            raise ValueError(f'{name} must be None or an integer >= 3, got {value!r}') from None


def check_shape(shape, n: int | None) -> tuple[int, int]:
    """``shape`` as (H, W) ints with H * W == n (any n when None), or ValueError."""
    try:
        h, w = (check_integer('shape', v, 1) for v in shape)
    except (TypeError, ValueError):
        raise ValueError(f'shape must be (H, W), two integers >= 1, got {shape!r}') from None
    if n is not None and h * w != n:
        raise ValueError(f'shape {shape!r} does not match {n} points (H * W must equal the number of rows)')
    return h, w


def check_viewpoint(viewpoint: Viewpoint) -> np.ndarray:
    """``viewpoint`` (3,) meters as a float array (None: the origin); ValueError unless 3 finite numbers."""
    why = f'viewpoint must be 3 finite coordinates (x, y, z) in meters, got {viewpoint!r}'
    try:
        view = np.zeros(3) if viewpoint is None else np.asarray(viewpoint, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(why) from None
    if view.shape != (3,) or not np.isfinite(view).all():
        raise ValueError(why)
    return view
