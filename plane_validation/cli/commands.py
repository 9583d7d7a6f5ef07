"""Command line: ``plane-validation <command>`` (also ``python -m plane_validation.cli``).

    plane-validation demo                      # the main job: a bundled bag through the node over DDS
    plane-validation replay BAG [--live] ...   # replay a bag offline (default) or live
    plane-validation batch SOURCE... --out DIR # replay many bags: per-bag reports and an index
    plane-validation detect CLOUD [--tolerance T | --auto] [--json] [--out LABELED.ply]
    plane-validation sweep CLOUD [--tolerances A:B:N] [--plot PNG] [--csv CSV] [--json]   # alias: tune
    plane-validation planes CLOUD [--tolerance T] [--max-planes K] [--plot PNG] [--json]
    plane-validation scene NAME [--noise E] [--out FILE]
    plane-validation paper [--out DIR]         # the paper's synthetic experiments: PNGs + summary.md

CLOUD is a .pcd, .ply, .npy, .xyz/.txt/.csv file or ``BAG[:TOPIC[:INDEX]]``. Exit status: 0 on
success, 2 for bad usage or input (one line on stderr), 130 when interrupted (Ctrl-C), 143 on
SIGTERM, 129 on SIGHUP and 141, quietly, when stdout closes early (piped into ``head``); an output
is complete or absent either way. ``batch`` exits with 1 when a bag failed.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

import numpy as np

from ..app.config import min_inliers_value
from ..app.report import format_planes
from ..formats.files import atomic_outputs, check_output, check_writable, load_scan

__all__ = ['main', 'build_parser', 'format_planes', 'parse_tolerances']

#: The bag the demo replays and where its outputs go (relative to the repository / current directory); an
#: installed package has the bag in its share folder (setup.py), which the demo uses from anywhere else.
DEMO_BAG = 'bags/room'
DEMO_OUT = 'out/demo'
#: In a demo's --out folder: the names of the outputs demos wrote there, which the next one may replace.
DEMO_MARK = '.plane-validation-demo'
#: Where ``paper`` writes by default (docs/paper.md's figures are made with ``--out docs/paper``).
PAPER_OUT = 'out/paper'
#: Exit status for bad usage or input (argparse uses it too).
EXIT_USAGE = 2
#: Exit status when stdout closes early (128 + SIGPIPE, as a tool the signal ends).
EXIT_BROKEN_PIPE = 141

CLOUD_HELP = ('point cloud: .pcd (ascii/binary/binary_compressed), .ply, .npy, .xyz/.txt/.csv, or a bag as '
              'BAG[:TOPIC[:INDEX]] (rosbag2 directory, .mcap, .db3 or ROS 1 .bag; INDEX counts from 0, '
              'negative from the end)')


def parse_tolerances(text: str) -> np.ndarray:
    """``A:B:N`` -> N tolerances evenly spaced from A to B (meters), 0 < A < B, N >= 2."""
    parts = text.split(':')
    try:
        if len(parts) != 3:
            raise ValueError
        lo, hi, count = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected A:B:N (e.g. 0.005:0.05:10), got {text!r}') from None
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi and count >= 2):
        raise argparse.ArgumentTypeError(f'need 0 < A < B and N >= 2, got {text!r}')
    from ..app.config import PARAMETERS
    for name, value in (('tolerance', lo), ('tolerance', hi), ('tune_count', count)):  # the node's limits
        why = PARAMETERS[name].problem(value)
        if why is not None:
            raise argparse.ArgumentTypeError(f'{text!r}: {why}')
    return np.linspace(lo, hi, count)


@contextmanager
def progress_bar(description: str, *, quiet: bool) -> Iterator[Callable[[int, int], None] | None]:
    """A tqdm bar on stderr driven by ``callback(done, total)``; None when quiet or not on a terminal."""
    if quiet or not sys.stderr.isatty():
        yield None
        return
    from tqdm import tqdm
    bar = tqdm(desc=description, file=sys.stderr, leave=False, unit='step')

    def update(done: int, total: int, *_) -> None:
        bar.total = total
        bar.n = done
        bar.refresh()

    try:
        yield update
    finally:
        bar.close()


def _emit_json(document: dict) -> None:
    from ..app.report import dumps
    print(dumps(document))


# -- commands ------------------------------------------------------------------------------------


def _cloud_path(cloud: str) -> Path:
    """The file or bag a CLOUD argument reads (``BAG[:TOPIC[:INDEX]]`` names its bag)."""
    from ..formats.bags import parse_bag_source
    bag = parse_bag_source(cloud)
    return Path(cloud) if bag is None else bag.path


#: Output options that write a figure, in the format of the file's extension (app.plot.figure_format).
FIGURE_OPTIONS = ('png', 'plot')
#: Their help: what the formats are.
FIGURE_HELP = 'the format follows the extension: .png (also without one), .pdf, .svg, .jpg, ...'


def _check_outputs(args: argparse.Namespace, *names: str) -> None:
    """Before the work, not after: the output options ``names`` that were given name a writable
    place, neither the input cloud nor each other (``--out`` also a point-file type, a figure option
    a figure format)."""
    given = [(name, getattr(args, name)) for name in names if getattr(args, name, None) is not None]
    for i, (name, path) in enumerate(given):
        if not str(path).strip():
            raise ValueError(f'--{name} needs a file name, got an empty one')
        (check_output if name == 'out' else check_writable)(path, inputs=(_cloud_path(args.cloud),))
        if name in FIGURE_OPTIONS:
            from ..app.plot import figure_format
            figure_format(path)
        for other, other_path in given[:i]:
            if Path(path).resolve() == Path(other_path).resolve():
                raise ValueError(f'{path}: given to both --{other} and --{name}; choose two names')


def _load(args: argparse.Namespace) -> tuple[np.ndarray, tuple[int, int] | None, np.ndarray | None, np.ndarray]:
    """load_scan of ``args.cloud`` (rows at (0, 0, 0), or at the viewpoint, as NaN with
    ``args.zero_is_no_return``), refusing a cloud with fewer than 3 valid points: no plane can be found in it;
    then the points as read (what an output file repeats)."""
    from ..core.ransac import finite_rows, no_returns_as_nan, no_returns_note
    from ..formats.files import pcd_viewpoint
    points, shape, ring = load_scan(args.cloud)
    # the sensor origin: each coordinate as given, else a PCD's VIEWPOINT (pcl and pcl_ros write where the
    # sensor was), else 0
    given = [getattr(args, f'viewpoint_{axis}') for axis in 'xyz']
    try:
        args.file_viewpoint = pcd_viewpoint(_cloud_path(args.cloud))
    except ValueError:
        if None in given:
            raise
        args.file_viewpoint = None  # all three given: the file's (malformed) VIEWPOINT is not needed
    origin = args.file_viewpoint[:3] if args.file_viewpoint is not None else [0.0] * 3
    args.viewpoint_from_file = [v is None and o != 0 for v, o in zip(given, origin)]
    for axis, value, default in zip('xyz', given, origin):
        setattr(args, f'viewpoint_{axis}', float(default if value is None else value))
    read, no_returns = points, 0
    if args.zero_is_no_return:
        points, no_returns = no_returns_as_nan(points, _viewpoint(args))
    valid = int(np.count_nonzero(finite_rows(points)))
    if valid < 3:
        raise ValueError(f'{valid} valid point(s) of {len(points)}: a plane needs at least 3'
                         + no_returns_note(no_returns))
    return points, shape, ring, read


@contextmanager
def _about(cloud: str) -> Iterator[None]:
    """A ValueError raised inside names the cloud it is about (when it does not name its file already)."""
    try:
        yield
    except ValueError as exc:
        if _cloud_path(cloud).name in str(exc):
            raise
        raise ValueError(f'{cloud}: {exc}') from exc


#: Said when the tuned t is the largest candidate.
LARGEST_CANDIDATE = ('(t is the largest candidate: a wider range might choose a larger one; '
                     '`sweep CLOUD --tolerances LO:HI:N` tries one, the node\'s tune_max sets it)')


def cmd_detect(args: argparse.Namespace) -> int:
    from ..app.detection import detect
    from ..app.report import detection_document, format_indices, noise_line

    _check_outputs(args, 'out', 'png')
    tolerance = None if args.auto else args.tolerance
    with _about(args.cloud), progress_bar('tuning t', quiet=args.json) as progress:
        points, shape, ring, read = _load(args)
        det = detect(points, tolerance, search=_config(args).search, seed=args.seed, progress=progress,
                     shape=shape, jobs=args.tune_jobs, ring=ring, organize_rings=args.organize_rings)
    from ..formats.files import is_bag_output
    bag = args.out is not None and is_bag_output(args.out)
    files = [path for path in (None if bag else args.out, args.png) if path]
    with atomic_outputs(*files) as staged:  # an interrupted run writes none of them (a bag: it, last, or nothing)
        at = dict(zip(files, staged))
        if args.png:
            from ..app.plot import plot_planes
            valid = np.isfinite(points).all(axis=1)
            plot_planes(points[valid], det.segmentation.labels[valid], at[args.png], title=str(args.cloud))
        if args.out:
            from ..formats.files import save_points
            pose = (*_viewpoint(args), *(args.file_viewpoint[3:] if args.file_viewpoint is not None else (1, 0, 0, 0)))
            save_points(at.get(args.out, args.out), read, det.segmentation.labels, shape=shape, viewpoint=pose)
    written = [Path(path) for path in (args.out, args.png) if path]
    if args.json:
        _emit_json(detection_document(args.cloud, det, max_planes=args.max_planes,
                                      min_inliers=min_inliers_value(args.min_inliers),
                                      output=str(args.out) if args.out else None))
        return 0
    seg = det.segmentation
    print(f'{args.cloud}: {len(points)} points, {seg.n_valid} valid')
    if det.ring_image is not None:
        print(f'ring image: {det.ring_image}')
    if any(_viewpoint(args)):
        print('viewpoint ' + ' '.join(f'{v:g}' for v in _viewpoint(args)) + ' m'
              + (' (the file\'s VIEWPOINT where no option gave it)' if any(args.viewpoint_from_file) else ''))
    if det.tuning is not None:
        print(f'tuned tolerance {det.tolerance:.4g} m ({det.tuning.criterion} over {len(det.tuning.rows)} '
              f'candidates, {det.tuning.rows[0].tolerance:.3g}-{det.tuning.rows[-1].tolerance:.3g} m)')
        if det.tuning.at_largest:
            print(LARGEST_CANDIDATE)
    else:
        print(f'fixed tolerance {det.tolerance:.4g} m')
    print(format_planes(seg))
    print('indices:')
    print(format_indices(det.indices))
    if seg.noise_model != 'constant':
        print(noise_line(seg, points))
    print(f'noise estimate e = {det.noise_estimate:.3g} m; {"reliable" if det.reliable else "NOT reliable"}: '
          f'{det.verdict}')
    print(f'took {1000 * det.seconds:.0f} ms')
    for path in written:
        print(f'wrote {path}')
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    from ..app.detection import tune_scan
    from ..app.report import noise_line, sweep_document, write_sweep_csv

    _check_outputs(args, 'plot', 'csv')
    with _about(args.cloud), progress_bar('sweeping t', quiet=args.json) as progress:
        points, shape, ring, _ = _load(args)
        result, ring_note = tune_scan(points, search=_config(args).search, ring=ring,
                                      organize_rings=args.organize_rings, shape=shape, seed=args.seed,
                                      tolerances=args.tolerances, criterion=args.criterion, progress=progress,
                                      jobs=args.tune_jobs)
    written = [Path(path) for path in (args.csv, args.plot) if path]
    with atomic_outputs(*written) as staged:  # an interrupted run writes neither
        at = dict(zip(written, staged))
        if args.csv:
            write_sweep_csv(at[Path(args.csv)], result)
        if args.plot:
            from ..app.plot import plot_sweep
            plot_sweep(result, at[Path(args.plot)], title=Path(str(args.cloud)).name)
    if args.json:
        _emit_json(sweep_document(args.cloud, points, result, seed=args.seed, ring_image=ring_note))
        return 0
    if ring_note is not None:
        print(f'ring image: {ring_note}' + ('' if ring_note.startswith('not used') else
                                            ' (the candidates below were searched on it)'))
    print(result.table())
    if result.sweep_points < result.segmentation.n_valid:
        print(f'(candidates scored on a {result.sweep_points}-point subsample; the chosen t is then applied to all '
              f'{result.segmentation.n_valid} valid points)')
    if result.noise_model != 'constant':
        print(noise_line(result.segmentation, points))
    if result.at_largest:
        print(LARGEST_CANDIDATE)
    print(f'chosen t = {result.tolerance:.4g} m by {result.criterion}; {result.segmentation.n_planes} planes; '
          f'noise estimate {result.noise_estimate:.3g} m; {"reliable" if result.reliable else "NOT reliable"}: '
          f'{result.verdict}; {result.seconds:.1f} s')
    for path in written:
        print(f'wrote {path}')
    return 0


def cmd_planes(args: argparse.Namespace) -> int:
    from ..app.detection import tune_scan
    from ..app.report import plane_count_document, plane_count_table
    from ..core.tuning import DEFAULT_CRITERION, MIN_PLANE_SILHOUETTE, select_plane_count

    _check_outputs(args, 'plot')
    tolerance, source, chosen = args.tolerance, 'fixed', None
    with _about(args.cloud):
        points, shape, ring, _ = _load(args)
        search = _config(args).search
        if tolerance is None:  # as detect tunes it (a lidar scan on its ring image)
            with progress_bar('tuning t', quiet=args.json) as progress:
                tuned = tune_scan(points, search=search, ring=ring, organize_rings=args.organize_rings,
                                  shape=shape, seed=args.seed, progress=progress, jobs=args.tune_jobs)[0]
            tolerance, source, chosen = tuned.tolerance, 'auto', tuned.noise_model
        result = select_plane_count(points, tolerance, seed=args.seed, shape=shape, **search.at_tolerance(chosen))
    written = []
    if args.plot:
        from ..app.plot import plot_plane_count
        written.append(plot_plane_count(result, args.plot, title=Path(str(args.cloud)).name))
    if args.json:
        _emit_json(plane_count_document(args.cloud, points, result, tolerance=tolerance, tolerance_source=source,
                                        seed=args.seed, max_planes=args.max_planes))
        return 0
    kind = 'tuned' if source == 'auto' else 'fixed'
    print(f'{args.cloud}: {len(points)} points; {kind} tolerance {tolerance:.4g} m; up to {args.max_planes} planes, '
          'first k scored for each k')
    print(plane_count_table(result))
    if result.counts:
        others = ', '.join(f'{name} {result.best_by(name)}' for name in
                           (DEFAULT_CRITERION, 'gs', 'davies_bouldin', 'dunn', 'gs_planes'))
        rule = f'largest k whose planes all have S_j >= {MIN_PLANE_SILHOUETTE}'
        if result.n_planes == 1:  # one plane has no silhouette: 1 is what is left when no k >= 2 qualifies
            rule = f'no k >= 2 has all its planes at S_j >= {MIN_PLANE_SILHOUETTE}'
        print(f'selected k = {result.n_planes} ({rule}); each index\'s own optimum: {others}')
    else:
        print('no planes found')
    for path in written:
        print(f'wrote {path}')
    return 0


def cmd_scene(args: argparse.Namespace) -> int:
    from ..core import scenes
    from ..formats.files import save_points

    kwargs = {name: getattr(args, name) for name in ('noise', 'n_points', 'outlier_fraction', 'scale')
              if getattr(args, name) is not None}
    try:
        scene = scenes.SCENES[args.name](**kwargs, seed=args.seed)
    except TypeError as exc:  # an option the generator does not take (e.g. outliers for the sphere)
        raise ValueError(f'scene {args.name}: {exc}') from exc
    out = args.out or f'{args.name}.ply'
    save_points(out, scene.points, scene.labels)
    print(f'wrote {out}: {scene.name}, {len(scene.points)} points, noise e = {scene.noise:g}, '
          f'{scene.n_planes} planes (a x + b y + c z + d = 0):')
    for k, (a, b, c, d) in enumerate(scene.planes):
        print(f'  plane {k}: {a:+.4f} {b:+.4f} {c:+.4f} {d:+.4f}')
    return 0


def cmd_paper(args: argparse.Namespace) -> int:
    from ..app.paper import CASES, linear_grid, run_paper

    start = time.perf_counter()
    print(f'Running {len(CASES)} experiments into {args.out} ...', flush=True)
    with progress_bar('experiments', quiet=False) as progress:
        results = run_paper(args.out, seed=args.seed, points=args.points, grid=linear_grid(steps=args.steps),
                            progress=progress)
    for r in results:
        stable = f'{r.stable[0]:.3g}-{r.stable[1]:.3g}' if r.stable else '-'
        print(f'{r.case.name:14s} t {r.sweep.tolerance:6.3g} (auto {r.auto.tolerance:6.3g})  planes '
              f'{r.sweep.segmentation.n_planes}  stable t {stable:>11s}  k {r.counts.n_planes}  '
              f'{r.seconds:5.1f} s')
    print(f'wrote {len(results) * 2} figures and {Path(args.out) / "summary.md"} in '
          f'{time.perf_counter() - start:.1f} s')
    return 0


def cmd_warmup(args: argparse.Namespace) -> int:
    import os

    from ..core.kernels import warm
    ready = warm(jobs=args.jobs or os.cpu_count() or 1)
    how = 'compiled and cached' if ready.compiled else 'loaded from the cache'
    print(f'kernels ready in {ready.seconds:.2f} s: {how}')
    return 0


def _config(args: argparse.Namespace):
    """PipelineConfig from the pipeline options (only those given override the table's defaults)."""
    from ..app.config import PARAMETERS, PipelineConfig
    changes = {name: getattr(args, name) for name in PARAMETERS if getattr(args, name, None) is not None}
    if getattr(args, 'fixed', False) or ('tolerance' in changes and 'auto_tune' not in changes):
        changes['auto_tune'] = False  # a tolerance given on its own is the t to use, as in detect
    return dataclasses.replace(PipelineConfig(), **changes).validate()


def _ros_replay(module: str = 'replay'):
    """The ROS layer's replay module (or ``module``); ValueError (a one-line error) when the ROS 2 packages are
    not installed."""
    import importlib
    try:
        replay = importlib.import_module(f'..ros.{module}', __package__)
    except ImportError as exc:  # ModuleNotFoundError in a core-only install
        raise ValueError(f'this command needs the ROS 2 Python packages ({exc.name or exc} is missing): install it '
                         "with its ros extra (pip install '.[ros]', as ./run does), or source a ROS 2 Jazzy "
                         'installation') from exc
    return replay


def cmd_replay(args: argparse.Namespace) -> int:
    replay = _ros_replay()
    replay_live, replay_offline = replay.replay_live, replay.replay_offline
    cfg = _config(args)
    if args.out is not None and not args.out.strip():
        raise ValueError('--out needs a folder name, got an empty one')
    if not args.live and (args.rate is not None or args.no_node):
        raise ValueError(f'{"--rate" if args.rate is not None else "--no-node"} applies to --live replay only '
                         '(offline replay processes every frame, in order, as fast as it can)')
    if args.live:
        summary = replay_live(args.bag, topic=args.topic, out=args.out, rate=args.rate or 1.0,
                              start_node=not args.no_node, config=cfg, storage=args.storage)
    else:
        summary = replay_offline(args.bag, topic=args.topic, out=args.out, config=cfg, storage=args.storage)
    print(summary.line())
    return 0


def cmd_batch(args: argparse.Namespace) -> int:
    from ..app.fleet import Status, format_table
    cfg = _config(args)
    if not args.out.strip():
        raise ValueError('--out needs a folder name, got an empty one')
    if args.ray is not None:
        from ..app.executors import import_ray
        import_ray()  # before the work: without Ray, say how to install it
    batch = _ros_replay('batch')
    start = time.perf_counter()
    rows = batch.run_batch(args.sources, args.out, config=cfg, topic=args.topic, storage=args.storage,
                           workers=args.workers, ray=args.ray, force=args.force)
    print(format_table(rows))
    failed = sum(row.status is Status.FAILED for row in rows)
    print(f'{len(rows)} bags, {failed} failed, in {time.perf_counter() - start:.1f} s; index: '
          f'{Path(args.out) / "index.md"}')
    return 1 if failed else 0


def demo_bag() -> Path:
    """DEMO_BAG: in the current directory, else beside the package in its checkout, else in the share folder of
    the prefix it is installed in (pip, colcon); the first that exists (DEMO_BAG when none does)."""
    package = Path(__file__).resolve().parents[1]
    prefix = package.parents[3] if package.parent.name in ('site-packages', 'dist-packages') else None
    places = [Path(DEMO_BAG), package.parent / DEMO_BAG]
    if prefix is not None:
        places.append(prefix / 'share' / 'plane_validation' / DEMO_BAG)
    return next((place for place in places if place.is_dir()), Path(DEMO_BAG))


def cmd_demo(args: argparse.Namespace) -> int:
    from ..app.pipeline import PipelineConfig
    from ..app.plot import plot_cloud_message
    replay_live = _ros_replay().replay_live
    if args.bag is None:
        args.bag = str(demo_bag())
    if not Path(args.bag).exists():
        raise ValueError(f'bag not found: {args.bag}' + (' (the package\'s demo bag: run from its checkout, or give '
                                                         '--bag)' if Path(args.bag) == Path(DEMO_BAG) else ''))
    out_dir = Path(args.out)
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f'--out {out_dir} is a file: give a folder')
    out_bag = out_dir / f'{Path(args.bag).name}.planes'
    png = out_dir / 'last_frame.png'
    mark = out_dir / DEMO_MARK
    ours = set(mark.read_text().splitlines()) if mark.is_file() else set()
    if out_dir.resolve() == Path(DEMO_OUT).resolve():  # what demos wrote there before the mark
        ours |= {f'{Path(DEMO_BAG).name}.planes', png.name}
    for path in (out_bag, png):
        if (path.exists() or path.is_symlink()) and path.name not in ours:
            raise ValueError(f'{path} exists and an earlier demo did not write it (a replay bag?): give another '
                             '--out, or remove it')
    if out_bag.exists() and not out_bag.is_dir():
        raise ValueError(f'{out_bag} is a file, not a bag an earlier demo wrote: remove it or give another --out')
    made = [d for d in (out_dir, *out_dir.parents) if not d.exists()]  # the folders this run creates
    out_dir.mkdir(parents=True, exist_ok=True)
    if out_bag.exists():
        import shutil
        shutil.rmtree(out_bag)
    png.unlink(missing_ok=True)  # the picture is the last run's: one that fails leaves none, not an older one
    print(f'Replaying {args.bag} live over DDS into plane_validation_node (auto-tuned tolerance, seed 0)...')
    start = time.perf_counter()
    try:
        summary = replay_live(args.bag, out=out_bag, rate=args.rate, config=PipelineConfig())
    except BaseException:
        for folder in made:  # innermost first: no folders left behind that this run made and never filled
            if any(folder.iterdir()):
                break
            folder.rmdir()
        raise
    print(summary.line())
    tuned = [f for f in summary.frames if f.tolerance_source.startswith('tuned')]
    if tuned:
        print(f'Tuned t = {tuned[-1].tolerance:.4g} m ({tuned[-1].tolerance_source}); {len(tuned)} of '
              f'{len(summary.frames)} frames answered with it (the first with the quick estimate, while it was swept)')
    else:
        print(f'No sweep succeeded: t = {summary.frames[-1].tolerance:.4g} m ({summary.frames[-1].tolerance_source})'
              if summary.frames else 'No frame was answered')
    ours |= {out_bag.name, png.name}
    mark.write_text(''.join(f'{name}\n' for name in sorted(ours)))
    if summary.last_segmented is not None:
        plot_cloud_message(summary.last_segmented, png, title=f'{Path(args.bag).name}: last frame')
    print(f'Outputs: node outputs recorded in the rosbag2 bag {out_bag} (input cloud, segmented, planes, '
          f'obstacles, plane_poses, plane_coefficients, /diagnostics); picture of the last frame: {png}. '
          f'Took {time.perf_counter() - start:.1f} s.')
    return 0


# -- parser --------------------------------------------------------------------------------------


def _at_least(low: int) -> Callable[[str], int]:
    """An argparse type: an integer >= ``low``."""
    def integer(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'expected an integer, got {text!r}') from None
        if value < low:
            raise argparse.ArgumentTypeError(f'must be >= {low}, got {value}')
        return value
    return integer


def _number(text: str, *, allow_zero: bool) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a number, got {text!r}') from None
    if not (np.isfinite(value) and (value > 0 or (allow_zero and value == 0))):
        raise argparse.ArgumentTypeError(f'must be a finite number {">=" if allow_zero else ">"} 0, got {text!r}')
    return value


def _positive_float(text: str) -> float:
    return _number(text, allow_zero=False)


def _non_negative_float(text: str) -> float:
    return _number(text, allow_zero=True)


def _fraction(text: str) -> float:
    value = _number(text, allow_zero=True)
    if value >= 1:
        raise argparse.ArgumentTypeError(f'must be in [0, 1), got {text!r}')
    return value


def _table_type(name: str) -> Callable[[str], object]:
    """An argparse type for the table's parameter ``name``: its type, range and choices."""
    from ..app.config import PARAMETERS
    spec = PARAMETERS[name]

    def parse(text: str):
        try:
            value = spec.type(text)
        except ValueError:
            kind = {int: 'an integer', float: 'a number', bool: 'true or false'}.get(spec.type, spec.type.__name__)
            raise argparse.ArgumentTypeError(f'expected {kind}, got {text!r}') from None
        why = spec.problem(value)
        if why is not None:
            raise argparse.ArgumentTypeError(why)
        return value
    parse.__name__ = name  # argparse names the type in its messages
    return parse


def _resolve_seed(args: argparse.Namespace) -> None:
    """A seed < 0 (fresh entropy) becomes a fresh non-negative one, which the output reports: the run
    can be repeated with it."""
    if getattr(args, 'seed', None) is not None and args.seed < 0:
        import secrets
        args.seed = secrets.randbits(31)  # within the seed parameter's range
        print(f'plane-validation: seed {args.seed} (--seed {args.seed} repeats this run)', file=sys.stderr)


def _add_table_options(parser: argparse.ArgumentParser, names: tuple[tuple[str, str], ...]) -> None:
    """One option per (parameter, metavar) of the table, with its type, range and default; booleans as
    --name/--no-name."""
    from ..app.config import PARAMETERS
    for name, metavar in names:
        spec = PARAMETERS[name]
        flag = '--' + name.replace('_', '-')
        # one cloud, no stamps
        text = 'random seed; -1 = a fresh one (printed on stderr)' if name == 'seed' else spec.description
        if spec.type is bool:
            parser.add_argument(flag, dest=name, action=argparse.BooleanOptionalAction, default=spec.default,
                                help=f'{text} (default {str(spec.default).lower()})')
        elif name.startswith('viewpoint_'):  # None: from the file (_load)
            parser.add_argument(flag, dest=name, type=_table_type(name), default=None, metavar=metavar,
                                help=f'{text} (default: a PCD file\'s VIEWPOINT, else {spec.default})')
        else:
            allowed = f'; {spec.allowed}' if spec.allowed and not spec.choices else ''  # choices: argparse lists them
            parser.add_argument(flag, dest=name, type=_table_type(name), default=spec.default, metavar=metavar,
                                help=f'{text} (default {spec.default}{allowed})')


def _add_detection_options(parser: argparse.ArgumentParser) -> None:
    """--seed, --max-planes, --min-inliers, --noise-model, --viewpoint-x/y/z, --tune-jobs, --zero-is-no-return
    for the file commands."""
    _add_table_options(parser, (('seed', 'S'), ('max_planes', 'K'), ('min_inliers', 'M'), ('noise_model', 'MODEL'),
                                ('noise_reference', 'R'), ('viewpoint_x', 'X'), ('viewpoint_y', 'Y'),
                                ('viewpoint_z', 'Z'), ('tune_jobs', 'N'), ('zero_is_no_return', '')))


def _viewpoint(args: argparse.Namespace) -> tuple[float, float, float]:
    return args.viewpoint_x, args.viewpoint_y, args.viewpoint_z


def _add_search_options(parser: argparse.ArgumentParser) -> None:
    """--connectivity/--no-connectivity, --ransac-points, --grid-points, --organize-rings/--no-organize-rings and the
    orientation constraint (--axis-mode, --normal-axis-x/y/z, --axis-angle) for detect, sweep and planes."""
    _add_table_options(parser, (('connectivity', ''), ('ransac_points', 'N'), ('grid_points', 'N'),
                                ('organize_rings', ''), ('axis_mode', 'MODE'), ('normal_axis_x', 'X'),
                                ('normal_axis_y', 'Y'), ('normal_axis_z', 'Z'), ('axis_angle', 'DEG')))


def _add_replay_options(parser: argparse.ArgumentParser) -> None:
    """What replay and batch both take: --topic, --storage and the pipeline options."""
    parser.add_argument('--topic', help='PointCloud2 topic (auto-detected when there is one)')
    parser.add_argument('--storage', choices=('mcap', 'sqlite3'),
                        help='output bag storage (default: the input bag\'s; MCAP for a ROS 1 bag)')
    _add_pipeline_options(parser)


def _add_pipeline_options(parser: argparse.ArgumentParser) -> None:
    """One option per pipeline parameter (replay), e.g. --tune-min for tune_min; unset ones keep the
    table's default. Values are checked by PipelineConfig.validate."""
    from ..app.config import PARAMETERS
    group = parser.add_argument_group('pipeline parameters (as the node\'s ROS parameters)')
    for name, spec in PARAMETERS.items():
        flag = '--' + name.replace('_', '-')
        default = str(spec.default).lower() if spec.type is bool else spec.default
        text = f'{spec.description}{f" [{spec.unit}]" if spec.unit else ""} (default {default})'
        if spec.type is bool:
            group.add_argument(flag, dest=name, action=argparse.BooleanOptionalAction, default=None, help=text)
        else:
            group.add_argument(flag, dest=name, type=_table_type(name), default=None, help=text,
                               metavar='{' + ','.join(spec.choices) + '}' if spec.choices else name.upper())
    group.add_argument('--fixed', action='store_true', help='same as --no-auto-tune: use --tolerance as is (a '
                       '--tolerance without --auto-tune is fixed too)')


def build_parser() -> argparse.ArgumentParser:
    from ..app.config import PARAMETERS
    from ..core.scenes import SCENES
    from ..core.tuning import CRITERIA, DEFAULT_CRITERION, SWEEP_MAX_PLANES, TUNE_CANDIDATES

    parser = argparse.ArgumentParser(
        prog='plane-validation', description='Self-validating plane detection: sequential RANSAC planes scored by '
        'cluster validity indices (Dunn, Davies-Bouldin, GS, GSplanes). Coordinates are taken as meters.',
        epilog='Exit status: 0 success, 1 a worker process of a parallel sweep died or a bag of a batch failed, '
        '2 bad usage or input, '
        f'130 interrupted, 143 SIGTERM, 129 SIGHUP, {EXIT_BROKEN_PIPE} stdout closed early (piped into head).')
    sub = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')

    demo = sub.add_parser('demo', help='the main job: replay a bundled bag through the node over DDS',
                          description='Replay a bundled bag live over DDS through plane_validation_node (started '
                          'in this process, auto-tuned tolerance, seed 0), print each answered frame and record '
                          'everything the node publishes into a bag, with a picture of the last frame.')
    demo.add_argument('--bag', default=None, help=f'the bag to replay (default {DEMO_BAG}, from the checkout or the '
                      'installed package; see bags/README.md)')
    demo.add_argument('--out', default=DEMO_OUT, help='directory for the output bag and PNG')
    demo.add_argument('--rate', type=_positive_float, default=0.25,
                      help='playback speed (default 0.25: slow enough that the node answers every frame)')
    demo.set_defaults(func=cmd_demo)

    replay = sub.add_parser('replay', help='replay a bag through the per-frame pipeline')
    replay.add_argument('bag', help='a rosbag2 directory, .mcap or .db3 file, or ROS 1 .bag with PointCloud2 messages')
    replay.add_argument('--out', help='output rosbag2 directory (default: <bag>.planes beside the bag)')
    replay.add_argument('--live', action='store_true', help='publish on ROS topics at the recorded timing')
    replay.add_argument('--rate', type=_positive_float, help='playback speed factor for --live (default 1)')
    replay.add_argument('--no-node', action='store_true', help='with --live: do not start the node in-process')
    _add_replay_options(replay)
    replay.set_defaults(func=cmd_replay)

    batch = sub.add_parser('batch', help='replay many bags offline: per bag an output bag, summary.json and '
                           'report.png; an index across them', description='Replay every bag the sources name '
                           'offline, as replay does, into OUT/<bag name>/ (the output bag, summary.json, report.png, '
                           'each folder complete or absent), and write OUT/index.csv, index.md and fleet.png. Bags '
                           'run in a local process pool, or with --ray on a Ray cluster. A rerun skips the bags '
                           'already done with the same options. Exit status 1 when a bag failed (its row says why).')
    batch.add_argument('sources', nargs='+', metavar='SOURCE', help='a bag (rosbag2 directory, .mcap, .db3 or ROS 1 '
                       '.bag), or a folder searched for bags')
    batch.add_argument('--out', required=True, metavar='DIR', help='output folder')
    where = batch.add_mutually_exclusive_group()
    where.add_argument('--workers', type=_at_least(1), metavar='N', help='local worker processes (default: one per '
                       'CPU core), each with one BLAS thread')
    where.add_argument('--ray', metavar='ADDRESS', help="run on an existing Ray cluster: 'auto', host:port or "
                       "ray://host:port (needs the fleet extra: pip install '.[fleet]'; docs/batch.md)")
    batch.add_argument('--force', action='store_true', help='replay the bags already done too')
    _add_replay_options(batch)
    batch.set_defaults(func=cmd_batch)

    detect = sub.add_parser('detect', help='detect planes in a cloud: planes, tolerance, every index, verdict',
                            description='Detect planes in one cloud and score them. Without --tolerance the '
                            f'tolerance is auto-tuned (a sweep chosen by {DEFAULT_CRITERION}).')
    detect.add_argument('cloud', metavar='CLOUD', help=CLOUD_HELP)
    which = detect.add_mutually_exclusive_group()
    which.add_argument('--tolerance', type=_table_type('tolerance'), metavar='T',
                       help=f'fixed RANSAC tolerance t in meters ({PARAMETERS["tolerance"].allowed})')
    which.add_argument('--auto', '--tune', dest='auto', action='store_true',
                       help=f'auto-tune t by a sweep chosen by {DEFAULT_CRITERION} (the default without --tolerance)')
    _add_detection_options(detect)
    _add_search_options(detect)
    detect.add_argument('--json', action='store_true', help='print one JSON document (schema in docs/cli.md) '
                        'and nothing else on stdout')
    detect.add_argument('--out', metavar='FILE', help='write the labelled cloud: .ply (plane_id), .pcd (label), '
                        '.npy (4th column), .xyz/.txt/.csv; -1 = unassigned')
    detect.add_argument('--png', metavar='PNG', help=f'write a 3-D picture of the planes ({FIGURE_HELP})')
    detect.set_defaults(func=cmd_detect)

    sweep = sub.add_parser('sweep', aliases=['tune'], help='the paper\'s experiment: every index and the number of '
                           'planes vs t, the chosen t', description='Sweep the RANSAC tolerance t, score every '
                           'segmentation with all indices and choose t (paper Fig. 1, 3-8). The candidates look '
                           f'for up to max(--max-planes, {SWEEP_MAX_PLANES}) planes (t is the sensor\'s, whatever '
                           'number of planes is wanted); --max-planes limits the planes at the chosen t. A lidar '
                           'scan with a ring field is swept on its ring image, as detect and the node do.')
    sweep.add_argument('cloud', metavar='CLOUD', help=CLOUD_HELP)
    sweep.add_argument('--tolerances', type=parse_tolerances, metavar='A:B:N',
                       help='N tolerances evenly spaced from A to B meters, like the paper\'s axes (default: '
                       f'{TUNE_CANDIDATES} geometric candidates derived from the cloud)')
    sweep.add_argument('--criterion', default=PARAMETERS['criterion'].default, choices=sorted(CRITERIA),
                       help=f'index that chooses t (default {PARAMETERS["criterion"].default})')
    _add_detection_options(sweep)
    _add_search_options(sweep)
    sweep.add_argument('--plot', metavar='PNG', help=f'write indices and planes vs t, chosen t marked ({FIGURE_HELP})')
    sweep.add_argument('--csv', metavar='CSV', help='write one row per t: planes and every index')
    sweep.add_argument('--json', action='store_true', help='print one JSON document and nothing else on stdout')
    sweep.set_defaults(func=cmd_sweep)

    planes = sub.add_parser('planes', help='indices vs number of planes k and the selected k (paper Fig. 2)',
                            description='Extract up to K planes at t and score the first k planes for every k. '
                            'Without --tolerance, t is tuned as detect tunes it (a lidar scan with a ring field on '
                            'its ring image); the planes are then searched on the points as given.')
    planes.add_argument('cloud', metavar='CLOUD', help=CLOUD_HELP)
    planes.add_argument('--tolerance', type=_table_type('tolerance'), metavar='T',
                        help=f'RANSAC tolerance t in meters (default: auto-tuned; {PARAMETERS["tolerance"].allowed})')
    _add_detection_options(planes)
    _add_search_options(planes)
    planes.add_argument('--plot', metavar='PNG', help=f'write indices vs k, selected k marked ({FIGURE_HELP})')
    planes.add_argument('--json', action='store_true', help='print one JSON document and nothing else on stdout')
    planes.set_defaults(func=cmd_planes)

    scene = sub.add_parser('scene', help='write a synthetic scene with known planes',
                           description='Write a synthetic scene (scenes.py) as PLY, PCD, NPY, text or a bag. '
                           'corner and cube are in the paper\'s units (faces of 100), the others in meters.')
    scene.add_argument('name', choices=sorted(SCENES))
    scene.add_argument('--noise', type=_non_negative_float, metavar='E',
                       help='uniform noise half-width e along the normals')
    scene.add_argument('--points', dest='n_points', type=_at_least(1), metavar='N', help='number of points')
    scene.add_argument('--outliers', dest='outlier_fraction', type=_fraction, metavar='F',
                       help='fraction of uniform outliers')
    scene.add_argument('--scale', type=_positive_float, metavar='S',
                       help='multiply all coordinates (0.01: paper units -> m)')
    _add_table_options(scene, (('seed', 'S'),))
    scene.add_argument('--out', metavar='FILE', help='.ply, .pcd, .npy, .xyz/.txt/.csv (with the true plane of each '
                       'point), or a bag: a new directory, .mcap or .db3 (one PointCloud2 on /points); '
                       'default NAME.ply')
    scene.set_defaults(func=cmd_scene)

    paper = sub.add_parser('paper', help='regenerate the paper\'s synthetic experiments: PNGs and summary.md',
                           description='Corner at e = 0, 2.5, 7.5, cube at e = 0, 1, 2.5, 7.5 and a plane-free '
                           'sphere: indices vs t, planes vs t, indices vs k, and a Markdown summary table.')
    paper.add_argument('--out', default=PAPER_OUT, metavar='DIR', help=f'output directory (default {PAPER_OUT})')
    _add_table_options(paper, (('seed', 'S'),))
    paper.add_argument('--points', type=_at_least(3), metavar='N', help='points per corner/sphere, twice for the cube '
                       '(default 3000, as in the paper; smaller for a quick look)')
    paper.add_argument('--steps', type=_at_least(2), default=60, metavar='N',
                       help='tolerances per sweep, 0.5 to 30 units '
                       '(default 60)')
    paper.set_defaults(func=cmd_paper)

    warmup = sub.add_parser('warmup', help='compile the numba kernels into their cache (for an install step)',
                            description='Compile (or load) every compiled kernel and keep it in numba\'s cache, so '
                            'that the first start of the node loads them instead of compiling (docs/performance.md).')
    warmup.add_argument('--jobs', type=_at_least(0), default=0, metavar='N',
                        help='processes that compile in parallel on a cold cache (default 0: one per core)')
    warmup.set_defaults(func=cmd_warmup)
    return parser


class Terminated(BaseException):
    """SIGTERM or SIGHUP arrived: unwind like KeyboardInterrupt (partial outputs are removed)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _raise_terminated(signum: int, _frame) -> None:
    import signal
    for sig in (signal.SIGTERM, signal.SIGHUP):  # a second signal must not interrupt the clean-up
        signal.signal(sig, signal.SIG_IGN)
    raise Terminated(signum)


@contextmanager
def _terminate_cleanly() -> Iterator[None]:
    """SIGTERM and SIGHUP (timeout, systemd, docker stop, a closed terminal) raise Terminated in
    the main thread, so every ``with``/``finally`` cleans up as for Ctrl-C."""
    import signal
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, _raise_terminated) for sig in (signal.SIGTERM, signal.SIGHUP)}
    previous_hook = sys.unraisablehook

    def redeliver(unraisable) -> None:
        """A signal's exception raised inside a finalizer (``__del__``) is printed and dropped by Python: the
        command would go on and exit 0. The signal is raised again, to land in the main thread's code."""
        previous_hook(unraisable)
        if isinstance(unraisable.exc_value, Terminated):  # once this hook has returned (raised here, it is dropped
            # again); the handler runs in the main thread, and a timer is another thread
            signal.signal(unraisable.exc_value.signum, _raise_terminated)
            later = threading.Timer(0.01, signal.raise_signal, args=(unraisable.exc_value.signum,))
            later.daemon = True
            later.start()

    sys.unraisablehook = redeliver
    try:
        yield
    finally:
        sys.unraisablehook = previous_hook
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _load_kernels() -> None:
    """Load (or compile) the compiled kernels with SIGINT, SIGTERM and SIGHUP held, then deliver the first one
    held: an exception raised inside numba's loader or compiler is dropped, or crashes it in a callback."""
    import os
    import signal

    from ..core.kernels import warm
    caught: list[int] = []
    held = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    previous = {sig: signal.signal(sig, lambda signum, _frame: caught.append(signum)) for sig in held}
    try:
        warm(jobs=os.cpu_count() or 1)  # a cold cache compiles on every core
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    for signum in caught[:1]:
        signal.raise_signal(signum)


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
        _resolve_seed(args)
        from ..app.pipeline import limit_blas_threads, reuse_freed_memory
        from ..core.workers import TuningWorkerError, stop_workers, workers_ignore_sigint
        limit_blas_threads()  # small matrix products; spinning BLAS threads only slow a busy machine down
        reuse_freed_memory()  # a frame's arrays from the heap, not fresh pages (core/allocator.py)
    except KeyboardInterrupt:  # while they load (threadpoolctl opens the BLAS libraries)
        return 130
    try:
        with _terminate_cleanly(), workers_ignore_sigint():
            if args.func not in (cmd_scene, cmd_warmup):
                _load_kernels()
            return args.func(args)
    except KeyboardInterrupt:
        return 130
    except Terminated as exc:
        return 128 + exc.signum
    except SystemError as exc:  # a signal's exception raised while a compiled kernel ran comes wrapped in one or more
        cause = exc
        while isinstance(cause, SystemError) and cause.__cause__ is not None:
            cause = cause.__cause__
        if isinstance(cause, Terminated):
            return 128 + cause.signum
        if isinstance(cause, KeyboardInterrupt):
            return 130
        raise
    except BrokenPipeError:  # stdout closed early (piped into head): quiet, as a tool killed by SIGPIPE
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # nothing left to flush at exit
        return EXIT_BROKEN_PIPE
    except (ValueError, OSError, TuningWorkerError) as exc:
        message = ' '.join(str(exc).split()) or type(exc).__name__
        print(f'plane-validation: error: {message}', file=sys.stderr)
        return 1 if isinstance(exc, TuningWorkerError) else EXIT_USAGE
    finally:  # a parallel sweep's workers end with the command, whatever ended it; left to the interpreter's exit,
        # a signal while they started could leave it waiting for loky's threads for ever
        with suppress(KeyboardInterrupt):
            stop_workers()


if __name__ == '__main__':
    sys.exit(main())
