"""The commands of ``plane-validation <command>`` (also ``python -m plane_validation.cli``); their options are
in :mod:`.parser`, the process around them (exit status, signals) in :mod:`.run`.

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
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..app.config import min_inliers_value
from ..app.report import format_planes
from ..formats.files import check_output, load_scan
from ..formats.outputs import atomic_outputs, check_writable

__all__ = ['format_planes', 'parse_tolerances', 'progress_bar']

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

#: detect's options that choose how its sweep picks t: not with --tolerance.
SWEEP_OPTIONS = ('criterion', 'tune_min', 'tune_max', 'tune_count')


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


def _viewpoint(args: argparse.Namespace) -> tuple[float, float, float]:
    return args.viewpoint_x, args.viewpoint_y, args.viewpoint_z


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
    sweep = ['--' + name.replace('_', '-') for name in SWEEP_OPTIONS if getattr(args, name) is not None]
    if args.tolerance is not None and sweep:
        raise ValueError(f'{", ".join(sweep)}: how the sweep chooses t, not with --tolerance (a fixed t)')
    tolerance = None if args.auto else args.tolerance
    with _about(args.cloud), progress_bar('tuning t', quiet=args.json) as progress:
        points, shape, ring, read = _load(args)
        cfg = _config(args)
        # the sweep as tune_tolerance sweeps by default (Dunn and Davies-Bouldin exact on small clouds), in the range
        # and by the criterion given
        tune = dataclasses.replace(cfg.tune, sampled_separation=None)
        det = detect(points, tolerance, search=cfg.search, seed=args.seed, progress=progress, shape=shape,
                     ring=ring, organize_rings=args.organize_rings, tune=tune)
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
    found = 'planes' if result.sweep_points >= result.segmentation.n_valid else 'planes on all the points'
    print(f'chosen t = {result.tolerance:.4g} m by {result.criterion}; {result.segmentation.n_planes} {found}; '
          f'noise estimate {result.noise_estimate:.3g} m; {"reliable" if result.reliable else "NOT reliable"}: '
          f'{result.verdict}; {result.seconds:.1f} s')
    for path in written:
        print(f'wrote {path}')
    return 0


def cmd_planes(args: argparse.Namespace) -> int:
    from ..app.detection import tune_scan
    from ..app.report import plane_count_document, plane_count_table
    from ..core.criteria import DEFAULT_CRITERION
    from ..core.plane_count import MIN_PLANE_SILHOUETTE, select_plane_count

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

