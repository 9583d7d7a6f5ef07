"""The pipeline's parameters, defined once: :class:`PipelineConfig` and its table :data:`PARAMETERS`.

Each field carries its description, range and unit; the node's parameter descriptors and
validation, ``config/params.yaml``, the command line's pipeline options and the README's parameter
table are derived from it (and tests check the last two against it). No ROS import.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from ..core.criteria import CRITERIA, DEFAULT_CRITERION
from ..core.noise import AUTO, NOISE_REFERENCE, TUNED_NOISE_MODELS
from ..core.orientation import AXIS_MODES, Orientation, orientation
from ..core.params import (
    GRID_POINTS,
    MAX_ITERATIONS,
    MAX_PLANES,
    MIN_INLIERS,
    PROBABILITY,
    RANSAC_POINTS,
    SearchParams,
    TuneParams,
)
from ..core.tolerance_grid import TUNE_CANDIDATES
from ..core.tuning import SWEEP_MAX_PLANES, TUNE_POINTS

__all__ = ['Parameter', 'PipelineConfig', 'PARAMETERS', 'parameters_markdown', 'min_inliers_value']


@dataclass(frozen=True)
class Parameter:
    """One parameter: ``default`` also fixes the type (bool, int, float or str); values must lie in
    [low, high] or equal ``special`` (a value with its own meaning, e.g. 0 = derive), or be one
    of ``choices``. unit: 'm', 's', 'deg' or ''."""

    name: str
    default: Any
    description: str
    low: float | None = None
    high: float | None = None
    special: float | None = None
    choices: tuple[str, ...] = ()
    unit: str = ''
    read_only: bool = False

    @property
    def type(self) -> type:
        return type(self.default)

    def converted(self, value: Any) -> Any:
        """``value`` as this parameter's type where that loses nothing (a whole number for a float),
        else as it is."""
        if self.type is float and isinstance(value, int) and not isinstance(value, bool):
            return float(value)
        return value

    @property
    def allowed(self) -> str:
        """The values allowed, for a help text: 'in [low, high] unit[ or special]', 'one of ...', or ''."""
        if self.choices:
            return f'one of {", ".join(self.choices)}'
        if self.low is None:
            return ''
        unit = f' {self.unit}' if self.unit else ''
        special = f' or {_fmt(self.special)}' if self.special is not None else ''
        return f'in [{_fmt(self.low)}, {_fmt(self.high)}]{unit}{special}'

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is not allowed, or None."""
        kind = self.type
        value = self.converted(value)
        if type(value) is not kind:
            return f'{self.name} must be a {kind.__name__}, got {value!r}'
        if self.choices and value not in self.choices:
            return f'{self.name} must be one of {", ".join(self.choices)}, got {value!r}'
        if self.low is None or value == self.special:
            return None
        if not (self.low <= value <= self.high):  # also catches NaN
            return f'{self.name} must be {self.allowed}, got {value!r}'
        return None


def _p(default: Any, description: str, **spec: Any) -> Any:
    return field(default=default, metadata={'parameter': dict(description=description, **spec)})


#: Largest distance parameter (tolerances, voxel size, viewpoint): meters from a robot's sensor, but files may
#: be in millimetres or the paper's units (the ``scene`` command's cubes have 100-unit faces).
MAX_DISTANCE = 1000.0


@dataclass(frozen=True)
class PipelineConfig:
    """Every tunable of the per-frame pipeline; the node's ROS parameters map one to one onto
    these fields. Distances in meters."""

    tolerance: float = _p(0.02, 'RANSAC inlier distance t (used when auto_tune is false)',
                          low=1e-6, high=MAX_DISTANCE, unit='m')
    auto_tune: bool = _p(True, 'choose t by sweeping candidates scored with the validity indices')
    tune_min: float = _p(0.0, 'smallest tuning candidate; 0 = derive from the cloud (nearest-neighbour spacing / 20, '
                         'or the largest candidate / 100 when that is smaller)',
                         low=1e-6, high=MAX_DISTANCE, special=0.0, unit='m')
    tune_max: float = _p(0.0, 'largest tuning candidate; 0 = derive from the cloud, and sweep on above it while '
                         'the largest candidate is chosen (up to the bounding-box diagonal / 8)', low=1e-6,
                         high=MAX_DISTANCE, special=0.0, unit='m')
    tune_count: int = _p(TUNE_CANDIDATES, 'tuning candidates, geometrically spaced from tune_min to tune_max',
                         low=2, high=100)
    tune_points: int = _p(TUNE_POINTS, 'random subsample of the cloud the tuning sweep runs on',
                          low=100, high=10_000_000)
    tune_jobs: int = _p(1, 'processes the tuning sweep runs its candidates in: this one and tune_jobs - 1 workers (the '
                        'same t and planes for any value; at most one per CPU core); 0 = one per CPU core',
                        low=1, high=1024, special=0)
    criterion: str = _p(DEFAULT_CRITERION, 'index that picks t (dunn and the gs indices are maximized, davies_bouldin '
                        'minimized)', choices=tuple(CRITERIA))
    retune_period: float = _p(0.0, 'header time between retunes; 0 = tune on the first frame only (a failed '
                              'sweep, or one whose verdict is not reliable, is retried, less often after each)',
                              low=0.0, high=1e6, unit='s')
    max_planes: int = _p(MAX_PLANES, 'stop after this many planes (a tuning sweep looks for at least '
                         f'{SWEEP_MAX_PLANES}: t is the sensor\'s, whatever number of planes is wanted)',
                         low=1, high=100)
    min_inliers: float = _p(MIN_INLIERS, 'smallest plane: a fraction of the valid points when < 1, else a count',
                            low=0.0, high=1e9)
    probability: float = _p(PROBABILITY, 'RANSAC success probability that sets the iteration count',
                            low=1e-6, high=0.999999)
    max_iterations: int = _p(MAX_ITERATIONS, 'RANSAC hypotheses per plane, at most', low=1, high=1_000_000)
    index_sample_size: int = _p(2000, 'points the validity indices are computed on per frame (stratified sample; '
                                'the silhouettes cost grows as its square)', low=10, high=20_000)
    exact_indices: bool = _p(False, 'Dunn and Davies-Bouldin on all points (exact, slow on large clouds) instead '
                             'of on the index sample')
    ransac_points: int = _p(RANSAC_POINTS, 'RANSAC searches a random sample of this many points, then labels '
                            'every point; 0 = all', low=1000, high=100_000_000, special=0)
    grid_points: int = _p(GRID_POINTS, 'an organized cloud (image) with more valid pixels is searched on a regular '
                          'sub-grid of about this many, then every pixel is labelled; 0 = every pixel',
                          low=1000, high=100_000_000, special=0)
    connectivity: bool = _p(True, 'a plane is a connected region (organized clouds: image neighbours without a depth '
                            'jump); false = every point within t of an infinite plane (the paper)')
    organize_rings: bool = _p(True, 'an unorganized scan whose PointCloud2 has a \'ring\' field (velodyne_pointcloud '
                              'and other spinning-lidar drivers) is laid out as its range image (rings x azimuth steps '
                              'about z, from the viewpoint) and searched as an organized cloud, 4-6 times faster than '
                              'the neighbourhood graph (docs/performance.md); false = the graph')
    noise_model: str = _p(AUTO, 'how t grows with range r from the sensor: constant, or depth_quadratic '
                          '(t * max(1, (r / noise_reference)^2) along the sensor\'s rays, a depth camera; t is '
                          'then the tolerance up to noise_reference), or auto: the auto-tune chooses one from the '
                          'noise it measures (depth_quadratic where it grows with range) and a fixed t is constant',
                          choices=TUNED_NOISE_MODELS)
    noise_reference: float = _p(NOISE_REFERENCE, 'range up to which depth_quadratic keeps t', low=0.01, high=100.0,
                                unit='m')
    viewpoint_x: float = _p(0.0, 'where the sensor is in the cloud\'s frame, x (0, 0, 0 = its origin, as a driver '
                            'publishes a scan; e.g. 0, 0, 1.8 for a lidar 1.8 m above base_link): the origin of '
                            'depth_quadratic\'s ranges, of the rays by which unorganized lidar rings are told and '
                            'border points settled, and what plane normals point away from',
                            low=-MAX_DISTANCE, high=MAX_DISTANCE, unit='m')
    viewpoint_y: float = _p(0.0, 'where the sensor is in the cloud\'s frame, y (see viewpoint_x)',
                            low=-MAX_DISTANCE, high=MAX_DISTANCE, unit='m')
    viewpoint_z: float = _p(0.0, 'where the sensor is in the cloud\'s frame, z (see viewpoint_x)',
                            low=-MAX_DISTANCE, high=MAX_DISTANCE, unit='m')
    axis_mode: str = _p('none', 'orientation constraint on the planes, applied inside the search: parallel = the '
                        'normal within axis_angle of normal_axis (horizontal planes for a vertical axis: floors, '
                        'tables), perpendicular = within axis_angle of perpendicular to it (vertical planes: walls); '
                        'none = any plane', choices=AXIS_MODES)
    normal_axis_x: float = _p(0.0, 'the orientation constraint\'s axis in the cloud\'s frame, x (any length but 0 '
                              'when axis_mode is set; e.g. 0, 0, 1 for z up)', low=-MAX_DISTANCE, high=MAX_DISTANCE)
    normal_axis_y: float = _p(0.0, 'the orientation constraint\'s axis, y (see normal_axis_x)',
                              low=-MAX_DISTANCE, high=MAX_DISTANCE)
    normal_axis_z: float = _p(0.0, 'the orientation constraint\'s axis, z (see normal_axis_x)',
                              low=-MAX_DISTANCE, high=MAX_DISTANCE)
    axis_angle: float = _p(10.0, 'largest angle of a plane normal from the constraint (see axis_mode)', low=0.0,
                           high=90.0, unit='deg')
    zero_is_no_return: bool = _p(True, 'a point at exactly (0, 0, 0) (at the viewpoint, when one is set) is a '
                                 'driver\'s "no return" mark (as NaN is) and is left out; false = a point like any '
                                 'other')
    voxel_size: float = _p(0.0, 'voxel grid applied before detection (each point then takes its voxel\'s plane '
                           'if within t of it); 0 = off', low=1e-6, high=MAX_DISTANCE, special=0.0, unit='m')
    ground_margin: float = _p(0.0, '~/obstacles also leaves out the points within this distance of the largest '
                              'horizontal plane (normal within 20 degrees of ground_up: the ground); 0 = off (every '
                              'valid point on no plane is an obstacle)',
                              low=1e-6, high=MAX_DISTANCE, special=0.0, unit='m')
    ground_up_x: float = _p(0.0, 'the up direction in the cloud\'s frame for ground_margin, x (any length but 0; '
                            '0, 0, 1 in base_link or odom, 0, -1, 0 in a camera\'s optical frame, whose y points '
                            'down)', low=-MAX_DISTANCE, high=MAX_DISTANCE)
    ground_up_y: float = _p(0.0, 'the up direction for ground_margin, y (see ground_up_x)',
                            low=-MAX_DISTANCE, high=MAX_DISTANCE)
    ground_up_z: float = _p(1.0, 'the up direction for ground_margin, z (see ground_up_x)',
                            low=-MAX_DISTANCE, high=MAX_DISTANCE)
    seed: int = _p(0, 'random seed; frames are seeded by (seed, header stamp); -1 = fresh entropy every frame',
                   low=-1, high=2**31 - 1)

    @property
    def viewpoint(self) -> tuple[float, float, float]:
        """(x, y, z) meters: viewpoint_x, viewpoint_y, viewpoint_z."""
        return self.viewpoint_x, self.viewpoint_y, self.viewpoint_z

    @property
    def orientation(self) -> Orientation | None:
        """The orientation constraint of axis_mode, normal_axis_x/y/z and axis_angle (None: none set); ValueError when
        axis_mode is set and the axis is (0, 0, 0)."""
        return orientation((self.normal_axis_x, self.normal_axis_y, self.normal_axis_z), self.axis_angle,
                           self.axis_mode)

    @property
    def ground_up(self) -> tuple[float, float, float]:
        """(x, y, z): ground_up_x, ground_up_y, ground_up_z, the up direction (any length) ground_margin uses."""
        return self.ground_up_x, self.ground_up_y, self.ground_up_z

    @property
    def search(self) -> SearchParams:
        """How detect_planes searches with these parameters (the keywords every caller passes)."""
        return SearchParams(max_planes=self.max_planes, min_inliers=min_inliers_value(self.min_inliers),
                            probability=self.probability, max_iterations=self.max_iterations,
                            ransac_points=self.ransac_points or None, grid_points=self.grid_points or None,
                            connectivity=self.connectivity, noise_model=self.noise_model,
                            noise_reference=self.noise_reference, viewpoint=self.viewpoint,
                            orientation=self.orientation)

    @property
    def tune(self) -> TuneParams:
        """How tune_tolerance sweeps t with these parameters (0 for tune_min, tune_max: derived from the cloud)."""
        return TuneParams(criterion=self.criterion, sample_size=self.index_sample_size, tune_points=self.tune_points,
                          t_min=self.tune_min or None, t_max=self.tune_max or None, count=self.tune_count,
                          sampled_separation=not self.exact_indices, jobs=self.tune_jobs)

    def validate(self) -> PipelineConfig:
        """Return self, or raise ValueError naming the first invalid field and why."""
        for name, spec in PARAMETERS.items():
            why = spec.problem(getattr(self, name))
            if why is not None:
                raise ValueError(why)
        if self.tune_min > 0 and self.tune_max > 0 and self.tune_max <= self.tune_min:
            raise ValueError(f'tune_max must be greater than tune_min, got tune_min={self.tune_min}, '
                             f'tune_max={self.tune_max}')
        _ = self.orientation  # a set axis_mode needs an axis
        if self.ground_margin > 0 and not any(self.ground_up):
            raise ValueError('ground_up_x, ground_up_y, ground_up_z must not all be 0 when ground_margin is set')
        return self


#: name -> Parameter, in declaration order.
PARAMETERS: dict[str, Parameter] = {
    f.name: Parameter(name=f.name, default=f.default, **f.metadata['parameter'])
    for f in dataclasses.fields(PipelineConfig)}


def min_inliers_value(value: float) -> int | float:
    """The min_inliers parameter (a double in ROS) as the core takes it: a fraction when < 1,
    else a count (150.0 -> 150)."""
    return value if value < 1 else int(value)


def _fmt(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e15:
        return f'{value:.1f}'
    return f'{value:g}' if isinstance(value, float) else str(value)


def parameters_markdown(parameters: dict[str, Parameter] | None = None) -> str:
    """The README's parameter table (Markdown), one row per parameter."""
    rows = ['| parameter | default | range | meaning |', '|---|---|---|---|']
    for p in (parameters or PARAMETERS).values():
        if p.choices:
            allowed = ' \\| '.join(p.choices)
        elif p.low is not None:
            allowed = f'{_fmt(p.low)} – {_fmt(p.high)}' + (f' or {_fmt(p.special)}' if p.special is not None else '')
        else:
            allowed = 'true \\| false' if p.type is bool else ''
        unit = f' {p.unit}' if p.unit and p.low is not None else ''
        note = ' (read-only)' if p.read_only else ''
        rows.append(f'| `{p.name}` | `{_fmt(p.default)}` | {allowed}{unit} | {p.description}{note} |')
    return '\n'.join(rows)
