"""The per-frame pipeline shared by the ROS node and bag replay (no ROS import).

``FramePipeline.process(points, stamp)`` takes one cloud, (re)tunes the tolerance when due,
detects planes, scores them and returns a :class:`FrameResult` that says what to publish,
including its :class:`~.diagnostics.Diagnostic`. The only state is the current tolerance and
when it was tuned; everything else comes from :class:`~.config.PipelineConfig`.
"""
from __future__ import annotations

import importlib
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from ..core import kernels
from ..core.allocator import reuse_freed_memory
from ..core.blas import limit_blas_threads
from ..core.geometry import plane_rows, voxel_downsample
from ..core.indices import validity_indices
from ..core.ransac import (
    as_points,
    check_integer,
    check_shape,
    detect_planes,
    finite_rows,
    no_returns_note,
    within_planes,
)
from ..core.tolerance_grid import quick_tolerance
from ..core.tuning import noise_from_segmentation, tune_tolerance
from ..core.tuning_result import TuningResult
from ..core.verdict import judge
from ..core.workers import TuningWorkerError
from ..formats.pointcloud2 import ring_array, trailing_bytes, xyz_array, xyz_words
from .config import PipelineConfig
from .detection import ring_layout
from .diagnostics import Diagnostic, Level, fmt
from .frame_result import FrameResult, by_track_id, failed_result, frame_values
from .frame_rows import frame_rows, on_rows
from .obstacles import ground_plane, obstacle_mask
from .tracking import PlaneTracker

__all__ = ['PipelineConfig', 'FrameResult', 'FramePipeline', 'header_stamp_ns', 'frame_seed', 'Level',
           'limit_blas_threads', 'reuse_freed_memory', 'FIRST_USE_MODULES', 'import_first_use_modules',
           'OK', 'WARN', 'ERROR']

OK, WARN, ERROR = Level.OK, Level.WARN, Level.ERROR

#: A sweep that raises one of these failed (the frame goes on with the last good t and says why).
TUNE_FAILURES = (ValueError, np.linalg.LinAlgError, TuningWorkerError)

#: With retune_period 0, a failed sweep is tried again after this much header time (s), doubled
#: after each further failure up to RETRY_MAX_S: a sensor's first frames may hold no plane (all
#: points identical, a line), and a stream without planes should not keep a core sweeping.
RETRY_AFTER_S = 1.0
RETRY_MAX_S = 60.0
#: Retunes are timed in header time (live and offline replay then sweep the same frames). A frame whose
#: stamp equals the previous frame's (a driver or simulator that leaves it unset or constant) counts as
#: this much header time instead, as from a 10 Hz sensor: a failed sweep is retried and retune_period
#: fires on such a stream too.
FROZEN_FRAME_S = 0.1

#: Modules the per-frame step imports where it first needs them (0.1-0.2 s each; a command on one file may never):
#: the tracker's matching from the second frame on, the noise estimate's fits, the search's dilations.
FIRST_USE_MODULES = ('scipy.optimize', 'scipy.ndimage')


def import_first_use_modules() -> None:
    """Import FIRST_USE_MODULES: a node does so as it starts, so that no frame after its first pays for them (the
    second Kinect frame took 144 ms against 44-49 ms, its tracker importing scipy.optimize)."""
    for name in FIRST_USE_MODULES:
        importlib.import_module(name)


#: Configuration fields whose change voids the tuned tolerance (and a sweep in progress).
TUNING_FIELDS = ('auto_tune', 'tune_min', 'tune_max', 'tune_count', 'tune_points', 'criterion', 'max_planes',
                 'min_inliers', 'voxel_size', 'probability', 'max_iterations', 'index_sample_size',
                 'exact_indices', 'ransac_points', 'grid_points', 'connectivity', 'noise_model', 'noise_reference',
                 'viewpoint_x', 'viewpoint_y', 'viewpoint_z', 'zero_is_no_return')


#: Header times (s) come from nanosecond stamps through float64, whose rounding (2.4e-7 s at the epoch's 1.7e9 s)
#: must not hold a period back by a frame: 123 s and 183 s came out 59.999999999999986 s apart.
CLOCK_SLACK_S = 1e-6


def _elapsed(stamp: float, last: float, period: float) -> bool:
    """``period`` s of header time (> 0) passed since ``last`` (up to CLOCK_SLACK_S), or the time ran backwards."""
    return period > 0 and (stamp - last >= period - CLOCK_SLACK_S or stamp < last)


class _Abandoned(Exception):
    """Raised from a sweep's progress callback to stop it (the node is shutting down)."""


def header_stamp_ns(header) -> int:
    """A std_msgs/Header stamp in nanoseconds (rclpy or rosbags message)."""
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def frame_seed(seed: int, stamp_ns: int) -> int | None:
    """Per-frame RANSAC seed from the node seed and the header stamp, so a frame gives the same
    planes live and offline whatever frames were dropped before it; None when seed < 0."""
    if seed < 0:
        return None
    return int(np.random.SeedSequence([seed, stamp_ns & (2**63 - 1)]).generate_state(1)[0])


@dataclass
class FramePipeline:
    """Holds the tolerance in use between frames. Thread-safe: a retune may run in another thread."""

    config: PipelineConfig = field(default_factory=PipelineConfig)
    tolerance: float | None = None       # tuned tolerance; None until the first tune
    tuned_at: float | None = None        # clock (s, FrameResult.clock) of the frame the tolerance was tuned on
    tuned_stamp: float | None = None     # that frame's header stamp (s), as said in tolerance_source
    last_tuning: TuningResult | None = None
    last_good: float | None = None       # the last tuned tolerance, kept across reconfiguration
    last_model: str | None = None        # the noise model the sweep behind last_good chose
    quick: float | None = None           # quick_tolerance of a frame, until a sweep succeeds
    tune_error: str | None = None        # why the last sweep failed (None after a success)
    failed_at: float | None = None       # clock (s) of the frame the last failed or unreliable sweep ran on
    failures: int = 0                    # sweeps in a row that failed or whose verdict was not reliable
    _last_stamp: int | None = field(default=None, repr=False)  # header stamp (ns) of the last frame
    _repeats: int = field(default=0, repr=False)  # frames that repeated a stamp (each credited FROZEN_FRAME_S)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    _generation: int = field(default=0, repr=False)  # bumped when the tuning set-up changes
    tracker: PlaneTracker = field(default_factory=PlaneTracker, repr=False)  # stable plane ids across frames

    def __post_init__(self) -> None:
        self.config.validate()

    def reconfigure(self, config: PipelineConfig) -> None:
        """Swap the configuration (validated first); retune when the tuning setup changed."""
        config.validate()
        with self._lock:
            if any(getattr(config, f) != getattr(self.config, f) for f in TUNING_FIELDS):
                self.tolerance, self.tuned_at, self.tuned_stamp, self.last_tuning = None, None, None, None
                self.tune_error, self.failed_at, self.failures = None, None, 0
                self._generation += 1
            self.config = config

    def current_tolerance(self, *, tuning_failed: bool = False) -> tuple[float, str]:
        """(tolerance in meters, where it came from): the fixed parameter, the tuned value, else
        the last tuned value, the quick estimate, or the parameter until a sweep succeeds."""
        return self._tolerance_and_sweep(tuning_failed)[:2]

    def _tolerance_and_sweep(self, tuning_failed: bool = False
                             ) -> tuple[float, str, TuningResult | None, str | None]:
        """current_tolerance, the sweep that chose it when it is the tuned value, and the noise model a sweep chose
        for it (None: not a tuned t); read together: a background retune may replace them at any time."""
        with self._lock:
            if not self.config.auto_tune:
                return self.config.tolerance, 'fixed', None, None
            if self.tolerance is not None and not tuning_failed:
                doubt = '' if self.last_tuning is None or self.last_tuning.reliable else \
                    ' (its sweep was not reliable: tuned again on a later frame)'
                return (self.tolerance, f'tuned at t={self.tuned_stamp:.3f}s{doubt}', self.last_tuning,
                        self.last_model)
            why = 'tuning failed' if tuning_failed else 'sweep pending'
            if self.last_good is not None:
                return self.last_good, f'last tuned ({why})', None, self.last_model
            if self.quick is not None:
                return self.quick, f'quick estimate ({why})', None, None
            return (self.config.tolerance, f'parameter ({"tuning failed" if tuning_failed else "not tuned yet"})',
                    None, None)

    def _clock(self, stamp_ns: int) -> tuple[float, bool]:
        """A frame's time for retune timing (s) from its header stamp (ns), and whether the stamp
        repeats the previous frame's (then FROZEN_FRAME_S is credited). Called once per frame, by process()."""
        repeated = self._last_stamp is not None and stamp_ns == self._last_stamp
        if repeated:
            self._repeats += 1
        elif self._last_stamp is not None and stamp_ns < self._last_stamp:
            self._repeats = 0  # the time ran backwards (a looping bag): retune_due retunes anyway
            self.tracker.reset()  # and a new pass numbers its planes afresh
        self._last_stamp = stamp_ns
        return stamp_ns * 1e-9 + self._repeats * FROZEN_FRAME_S, repeated

    def retune_due(self, stamp: float) -> bool:
        """Whether a frame stamped ``stamp`` seconds should trigger a retune."""
        with self._lock:
            cfg = self.config
            if not cfg.auto_tune:
                return False
            last = self.failed_at if self.failed_at is not None else self.tuned_at
            if last is None:
                return True
            # a failed sweep is retried like a periodic one, or after _retry_interval without one (or
            # after a parameter change); header time running backwards (a looping bag, a restarted
            # sensor) also retunes
            period = cfg.retune_period or (self._retry_interval(self.failures) if self.failed_at is not None else 0.0)
            return _elapsed(stamp, last, period)

    def due_after_failed_sweep(self, sweep_stamp: float, stamp: float) -> bool:
        """Whether a frame stamped ``stamp`` (s) is due for a retune once the sweep running on the
        frame stamped ``sweep_stamp`` ends, should that sweep fail or not be reliable (the earliest case):
        the node keeps that frame for its next sweep, so that live and offline replay sweep the same frames."""
        with self._lock:
            cfg = self.config
            period = cfg.retune_period or self._retry_interval(self.failures + 1)
            return cfg.auto_tune and _elapsed(stamp, sweep_stamp, period)

    @staticmethod
    def _retry_interval(failures: int) -> float:
        return min(RETRY_AFTER_S * 2.0 ** (failures - 1), RETRY_MAX_S)

    def retune(self, points: np.ndarray, stamp: float, stamp_ns: int | None = None, *,
               shape: tuple[int, int] | None = None, stop: Callable[[], bool] | None = None) -> TuningResult | None:
        """Run a tolerance sweep on ``points`` (meters; all rows of an organized cloud of ``shape``,
        else its valid rows) and adopt its choice, unless the tuning set-up changed while it ran.
        stamp: the frame's clock (s, FrameResult.clock); stamp_ns: its header stamp (seeds the sweep;
        None: a caller without one, seeded as 0, its stamp taken as the clock).
        Raises one of TUNE_FAILURES when no sweep is possible, or when it finds no plane in this
        frame (its t would say nothing about the next). A sweep whose verdict is not reliable (a first
        frame of clutter) is adopted, and retried like a failed one. ``stop``: asked after each
        candidate; True abandons the sweep (None is returned, nothing adopted), as does a change of the
        tuning set-up (:meth:`reconfigure`) while it runs."""
        header_s = stamp if stamp_ns is None else stamp_ns * 1e-9
        stamp_ns = stamp_ns or 0
        with self._lock:
            cfg, generation = self.config, self._generation
        if cfg.voxel_size > 0:
            points, shape = voxel_downsample(points[finite_rows(points)], cfg.voxel_size)[0], None
        try:  # a parameter change voids the sweep: it stops after its current candidate
            result = self._sweep(cfg, points, stamp_ns, shape,
                                 lambda: self._generation != generation or (stop is not None and stop()))
            if result.segmentation.n_planes == 0:
                bounds = ' and '.join(name for name in ('tune_min', 'tune_max') if getattr(cfg, name))
                raise ValueError(f'the sweep of the frame stamped {header_s:.3f} s found no plane at any t '
                                 f'from {result.rows[0].tolerance:.3g}'
                                 f' to {result.rows[-1].tolerance:.3g} m ({result.segmentation.reason})'
                                 + (f'; {bounds} set that range' if bounds else ''))
        except _Abandoned:
            return None
        except TUNE_FAILURES as exc:
            with self._lock:
                if generation == self._generation:  # a voided sweep's failure is not reported
                    self.tune_error, self.failed_at = str(exc), stamp
                    self.failures += 1
            raise
        with self._lock:
            if generation == self._generation:  # a parameter change during the sweep voids it
                self.tolerance, self.tuned_at, self.last_tuning = result.tolerance, stamp, result
                self.tuned_stamp = header_s
                self.last_good, self.last_model, self.tune_error = result.tolerance, result.noise_model, None
                self.failed_at, self.failures = (None, 0) if result.reliable else (stamp, self.failures + 1)
        return result

    @staticmethod
    def _sweep(cfg: PipelineConfig, points: np.ndarray, stamp_ns: int, shape,
               stop: Callable[[], bool] | None = None) -> TuningResult:
        def progress(*_) -> None:
            if stop is not None and stop():
                raise _Abandoned
        return tune_tolerance(points, progress=progress, seed=frame_seed(cfg.seed, stamp_ns), shape=shape,
                              **cfg.tune.kwargs(), **cfg.search.kwargs())

    def process_cloud(self, msg, *, tune_inline: bool = True) -> FrameResult:
        """One sensor_msgs/PointCloud2 (rclpy or rosbags) through :meth:`process`; a malformed
        message gives an ERROR result. This is the per-frame step the node and replay share."""
        stamp_ns = header_stamp_ns(msg.header)
        try:
            words = xyz_words(msg)  # the usual layout: read by the frame's first compiled pass
            points = xyz_array(msg) if words is None else None
            extra = trailing_bytes(msg)
        except ValueError as exc:
            return self.reject(f'malformed PointCloud2: {exc}', ERROR, n_input=int(msg.height) * int(msg.width))
        shape = (int(msg.height), int(msg.width)) if msg.height > 1 and msg.width > 0 else None  # organized: an image
        ring = None if shape or not self.config.organize_rings else ring_array(msg)  # a spinning lidar's beams
        result = self._process(points, words, stamp_ns, tune_inline, shape, ring)
        if extra:
            note = (f'PointCloud2.data has {extra} byte(s) beyond height*row_step = {msg.height}*{msg.row_step}; '
                    'they were ignored')
            result = replace(result, diagnostic=result.diagnostic.escalated(WARN, note))
        return result

    def reject(self, message: str, level: Level = ERROR, n_input: int = 0) -> FrameResult:
        """Result for a frame that could not even be read (e.g. a malformed message declaring
        ``n_input`` points)."""
        return failed_result(level, message, time.perf_counter(), self.current_tolerance(), n_input=n_input)

    def process(self, points: np.ndarray, stamp_ns: int = 0, *, tune_inline: bool = True,
                shape: tuple[int, int] | None = None, ring: np.ndarray | None = None) -> FrameResult:
        """Run one frame. points: (N, 3) meters, NaN rows allowed; stamp_ns: header stamp, a whole number of
        nanoseconds (also as a float); shape: (H, W) when the rows are an organized image (a depth camera's
        cloud; ignored unless H * W = N); ring: (N,) each point's beam when the rows are an unorganized
        spinning-lidar scan (searched on its ring image with ``organize_rings``).

        Bad input never raises: it gives an ERROR (malformed array, stamp or shape) or WARN (too few points,
        degenerate geometry) result. With ``tune_inline`` a due retune runs before detection;
        the node passes False and runs :meth:`retune` in a background thread instead. When the
        sweep fails (e.g. a tuning range the cloud cannot honour), the frame is still detected
        with the last tuned tolerance (else the quick estimate, else the ``tolerance`` parameter)
        and reported as WARN.
        """
        return self._process(points, None, stamp_ns, tune_inline, shape, ring)

    def _process(self, points: np.ndarray | None, words: tuple[np.ndarray, np.ndarray] | None, stamp_ns: int,
                 tune_inline: bool, shape: tuple[int, int] | None, ring: np.ndarray | None) -> FrameResult:
        """:meth:`process` of ``points``, or of a PointCloud2's x, y, z as :func:`.xyz_words` gives them."""
        start = time.perf_counter()
        try:
            stamp_ns = check_integer('stamp_ns', stamp_ns, None)
            if not -2**63 <= stamp_ns < 2**63:  # a header stamp (int32 s, uint32 ns) always fits
                raise ValueError(f'stamp_ns must fit in 64 bits (nanoseconds), got {stamp_ns}')
            stamp, repeated = self._clock(stamp_ns)
            given = as_points(points) if words is None else None
            shape = None if shape is None else check_shape(shape, None)
        except ValueError as exc:
            return failed_result(ERROR, f'bad input: {exc}', start, self.current_tolerance())
        cfg = self.config
        pts, no_returns, finite, valid, infinite, largest = frame_rows(given, words, cfg)
        n_input = len(pts)
        image = shape if shape is not None and shape[0] * shape[1] == n_input else None  # kept in the outputs
        if shape is not None and (cfg.voxel_size > 0 or not cfg.connectivity or shape[0] * shape[1] != n_input):
            shape = None  # only regions use the image; the voxel grid does not keep it; a wrong shape is ignored
        if len(valid) < 3:
            why = f'too few valid points: {len(valid)} of {n_input} (need 3)' + no_returns_note(no_returns) + \
                (f'; {infinite} had an infinite coordinate' if infinite else '')
            return failed_result(WARN, why, start, self.current_tolerance(), n_input=n_input, n_valid=len(valid))
        # (image, (H, W), the pixel of each valid point) of a scan laid out by its rings, and what to say of it
        searched_as_is = shape is not None or not cfg.organize_rings or not cfg.connectivity or cfg.voxel_size > 0
        laid, ring_note = ring_layout(pts, None if searched_as_is else ring, cfg.viewpoint)
        cloud, cloud_shape = (laid[0], laid[1]) if laid else (pts if shape else valid, shape)  # swept, searched
        tune_problem = None
        if tune_inline and self.retune_due(stamp):
            try:
                self.retune(cloud, stamp, stamp_ns, shape=cloud_shape)
            except TUNE_FAILURES as exc:
                tune_problem = f'cannot tune: {exc}'
        elif self.config.auto_tune and self.tolerance is None and self.last_good is None and self.quick is None:
            try:
                quick = quick_tolerance(valid, seed=frame_seed(cfg.seed, stamp_ns))  # until the sweep ends
            except ValueError as exc:
                return failed_result(ERROR, f'numerical failure (coordinates out of range?): {exc}', start,
                               self.current_tolerance(), n_input=n_input, n_valid=len(valid))
            self.quick = float(np.clip(quick, cfg.tune_min or quick, cfg.tune_max or quick))
        if tune_problem is None and self.tune_error is not None:
            tune_problem = f'cannot tune: {self.tune_error}'  # the last sweep (maybe in the background) failed
        tolerance, source, sweep, chosen = self._tolerance_and_sweep(tuning_failed=tune_problem is not None)
        search = cfg.search.at_tolerance(chosen)
        # the sweep behind a tuned t: were its planes stable under other seeds? (NaN: not measured)
        agreement = None if sweep is None or np.isnan(sweep.seed_agreement) else sweep.seed_agreement
        try:
            with np.errstate(over='ignore', invalid='ignore'):
                if laid is not None:  # the ring image, searched as an organized cloud
                    work, inverse = laid[0], laid[2]
                elif shape is not None:  # the organized rows, NaN holes and all
                    work, inverse = pts, None
                else:
                    work, inverse = (voxel_downsample(valid, cfg.voxel_size) if cfg.voxel_size > 0 else (valid, None))
                seed = frame_seed(cfg.seed, stamp_ns)
                # the organized rows' extent as reading the message found it (no second pass over them)
                extent = None if largest is None or work is not pts else (finite, largest)
                seg = detect_planes(work, tolerance, seed=seed, shape=cloud_shape, extent=extent,
                                    **search)
                if inverse is not None:  # each point its voxel's (pixel's) plane, if it lies within t of it
                    labels = within_planes(valid, seg.labels[inverse], seg)
                else:
                    labels = kernels.labels_where(kernels.c_array(seg.labels, np.int32), finite) if shape else \
                        seg.labels
                # an organized frame's indices from its valid rows: the same values, no second NaN filter
                scored = (valid, labels) if shape is not None or laid is not None else (work, seg.labels)
                scores = validity_indices(*scored, sample_size=cfg.index_sample_size, seed=seed,
                                          sampled_separation=not cfg.exact_indices, finite=scored[0] is valid)
                # the segmentation's own labels (of the rows of work) are grouped by its planes' inliers
                tracked = (work, seg.labels) if inverse is None else (valid, labels)
                found = self.tracker.update(*tracked, seg.coefficients, plane_rows(tracked[1], seg))
                verdict = judge(work, seg, scores, agreement).renumbered(found)  # planes named by their ids
                seg, labels, ids = by_track_id(seg, labels, found, finite if shape is not None else None)
        except (np.linalg.LinAlgError, ValueError, OverflowError, FloatingPointError) as exc:
            return failed_result(ERROR, f'numerical failure (coordinates out of range?): {exc}', start,
                           (tolerance, source), n_input=n_input, n_valid=len(valid))
        if seg.n_planes == 0 and sweep is None and self.last_good is None and tolerance == self.quick:
            self.quick = None  # no plane with the quick estimate (a line, one point): the next frame's instead
        level, message = (OK, str(verdict)) if verdict.reliable else (WARN, f'no reliable planes: {verdict}')
        if tune_problem:
            used = source.split(' (')[0]
            level, message = WARN, f'{tune_problem}; detected with {used} t={tolerance:.4g} m: {message}'
        counts = np.array([len(rows) for rows in plane_rows(labels if inverse is not None else seg.labels, seg)],
                          np.int64)
        obstacles = obstacle_mask(valid, labels, seg, counts, cfg.ground_margin, cfg.ground_up)
        # an organized input's outputs are laid out on its rows: its labels there too
        image_labels = None if not image else seg.labels if shape is not None else on_rows(labels, finite, -1)
        values = frame_values(cfg, tolerance, source, n_input, len(valid), (no_returns, infinite),
                         int(np.count_nonzero(labels < 0)), seg, counts, scores, noise_from_segmentation(seg, work),
                         work, ids)
        values += (('obstacle_points', str(int(np.count_nonzero(obstacles)))),
                   ('reliable', str(verdict.reliable).lower()),
                   ('verdict_failures', ' '.join(f.kind.value for f in verdict.failures) or 'none'))
        if cfg.ground_margin > 0:
            ground = ground_plane(seg, counts, cfg.ground_up)
            values += (('ground_plane', 'none' if ground is None else str(ids[ground])),)
        if agreement is not None:
            values += (('seed_agreement', fmt(agreement)),)
        if ring_note is not None:
            values += (('ring_image', ring_note),)
        if repeated and cfg.auto_tune:
            values += (('header_time', f'not advancing (the stamp repeats the last frame\'s): retunes count each '
                                       f'such frame as {FROZEN_FRAME_S:g} s'),)
        seconds = time.perf_counter() - start
        values += (('processing_ms', f'{1000 * seconds:.1f}'),)
        return FrameResult(points=valid, labels=labels, segmentation=seg, indices=scores, tolerance=tolerance,
                           tolerance_source=source, diagnostic=Diagnostic(level, message, values), seconds=seconds,
                           plane_counts=tuple(int(c) for c in counts), organized=pts if image else None, shape=shape,
                           ring_image=(laid[0], laid[1]) if laid else None, clock=stamp, plane_ids=ids,
                           obstacles=obstacles, image_shape=image, image_labels=image_labels)
