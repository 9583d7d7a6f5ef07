"""The command line's arguments: ``build_parser()``, every command's options (from the parameter table where it
has them) and their argparse types."""
from __future__ import annotations

import argparse
from collections.abc import Callable

import numpy as np

from .commands import (
    CLOUD_HELP,
    DEMO_BAG,
    DEMO_OUT,
    EXIT_BROKEN_PIPE,
    FIGURE_HELP,
    PAPER_OUT,
    SWEEP_OPTIONS,
    cmd_batch,
    cmd_demo,
    cmd_detect,
    cmd_paper,
    cmd_planes,
    cmd_replay,
    cmd_scene,
    cmd_sweep,
    cmd_warmup,
    parse_tolerances,
)

__all__ = ['build_parser']


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
            allowed = f'; {spec.allowed}' if spec.allowed and not spec.choices else ''  # choices: the metavar
            shown = '{' + ','.join(spec.choices) + '}' if spec.choices else metavar
            parser.add_argument(flag, dest=name, type=_table_type(name), default=spec.default, metavar=shown,
                                help=f'{text} (default {spec.default}{allowed})')


def _add_detection_options(parser: argparse.ArgumentParser) -> None:
    """--seed, --max-planes, --min-inliers, --noise-model, --viewpoint-x/y/z, --tune-jobs, --zero-is-no-return
    for the file commands."""
    _add_table_options(parser, (('seed', 'S'), ('max_planes', 'K'), ('min_inliers', 'M'), ('noise_model', 'MODEL'),
                                ('noise_reference', 'R'), ('viewpoint_x', 'X'), ('viewpoint_y', 'Y'),
                                ('viewpoint_z', 'Z'), ('tune_jobs', 'N'), ('zero_is_no_return', '')))


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
    from ..core.criteria import CRITERIA, DEFAULT_CRITERION
    from ..core.scenes import SCENES
    from ..core.tolerance_grid import TUNE_CANDIDATES
    from ..core.tuning import SWEEP_MAX_PLANES

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

    replay = sub.add_parser('replay', help='replay a bag through the per-frame pipeline',
                            description='Run every cloud of a bag through the node\'s per-frame step. Offline (the '
                            'default), as fast as it can, into an output bag holding the input clouds and every '
                            'output at their timestamps; with --live, published over DDS at the recorded timing to '
                            'the node, started in this process unless --no-node. A --tolerance given without '
                            '--auto-tune is used as is (auto-tuning off).')
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
                            f'tolerance is auto-tuned (a sweep chosen by --criterion, {DEFAULT_CRITERION} by default).')
    detect.add_argument('cloud', metavar='CLOUD', help=CLOUD_HELP)
    which = detect.add_mutually_exclusive_group()
    which.add_argument('--tolerance', type=_table_type('tolerance'), metavar='T',
                       help=f'fixed RANSAC tolerance t in meters ({PARAMETERS["tolerance"].allowed})')
    which.add_argument('--auto', '--tune', dest='auto', action='store_true',
                       help='auto-tune t by a sweep chosen by --criterion (the default without --tolerance)')
    _add_detection_options(detect)
    _add_search_options(detect)
    _add_table_options(detect, (('criterion', 'NAME'), ('tune_min', 'A'), ('tune_max', 'B'), ('tune_count', 'N')))
    detect.set_defaults(**dict.fromkeys(SWEEP_OPTIONS))  # None: not given (the table's default applies)
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
