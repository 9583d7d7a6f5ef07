"""The node's ROS parameters: descriptors from the parameter tables, declaration with validation,
changes at run time, and config/params.yaml. Shared by the plain and the managed node."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterNotDeclaredException,
)
from rclpy.parameter import Parameter as RosParameter

from ..app.config import PARAMETERS, Parameter, PipelineConfig

__all__ = ['NODE_PARAMETERS', 'NodeOptions', 'descriptor', 'declare', 'declare_each', 'unknown_overrides',
           'unused_tolerance', 'checked_changes', 'each_checked', 'apply_parameters', 'params_yaml', 'not_declared',
           'set_requests_whole']

#: Node-only parameters (the pipeline's are in app/config.py's table).
NODE_PARAMETERS = {
    'reliability': Parameter('reliability', 'best_effort', 'subscription reliability: best_effort (sensor data) or '
                             'reliable', choices=('best_effort', 'reliable'), read_only=True),
    'min_output_rate_hz': Parameter('min_output_rate_hz', 0.0, 'a frame is WARN when the node answers fewer frames '
                                    'per second than this (over the last 5 s); 0 = off', low=0.0, high=10_000.0,
                                    unit='Hz'),
}


@dataclass(frozen=True)
class NodeOptions:
    """The node-only parameters' values."""

    reliability: str = NODE_PARAMETERS['reliability'].default
    min_output_rate_hz: float = NODE_PARAMETERS['min_output_rate_hz'].default

    def validate(self) -> NodeOptions:
        for spec in NODE_PARAMETERS.values():
            why = spec.problem(getattr(self, spec.name))
            if why is not None:
                raise ValueError(why)
        return self


def descriptor(spec: Parameter) -> ParameterDescriptor:
    """The ROS parameter descriptor of one table entry (its range includes the special value)."""
    desc = ParameterDescriptor(description=spec.description + (f' [{spec.unit}]' if spec.unit else ''),
                               read_only=spec.read_only,
                               # a whole number for a float (`tolerance: 1`, `-p min_inliers:=500`) is fine
                               # (Parameter.converted); the table's check refuses every other type instead
                               dynamic_typing=spec.type is float)
    if spec.low is not None:
        lo, hi = spec.low, spec.high
        if spec.special is not None:
            lo, hi = min(lo, spec.special), max(hi, spec.special)
        if spec.type is float:
            desc.floating_point_range = [FloatingPointRange(from_value=float(lo), to_value=float(hi))]
        elif spec.type is int:
            desc.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=1)]
    return desc


def declare_each(node) -> dict[str, str]:
    """Declare every parameter not yet declared on ``node`` with its descriptor, overrides from the command line or
    a params file applied, and return why rclpy refused an override (out of range, wrong type), by name: such a
    parameter is declared at its default, so that it can be set right (undeclared, it could not, and every
    configure failed on the override again)."""
    refused = {}
    for name, spec in {**PARAMETERS, **NODE_PARAMETERS}.items():
        if not node.has_parameter(name):
            try:
                node.declare_parameter(name, spec.default, descriptor(spec))
            except (InvalidParameterTypeException, InvalidParameterValueException) as exc:
                refused[name] = str(exc)
                node.declare_parameter(name, spec.default, descriptor(spec), ignore_override=True)
    return refused


def declare(node) -> tuple[PipelineConfig, NodeOptions]:
    """Declare every parameter not yet declared on ``node`` (overrides from the command line or a
    params file apply) and return the validated values; log a warning naming any override that is no parameter
    (:func:`unknown_overrides`). Raises ValueError naming the first invalid one (rclpy raises its own for a value
    outside a descriptor's range)."""
    values = {}
    for name, spec in {**PARAMETERS, **NODE_PARAMETERS}.items():
        param = node.get_parameter(name) if node.has_parameter(name) else \
            node.declare_parameter(name, spec.default, descriptor(spec))
        values[name] = spec.converted(param.value)
    config = PipelineConfig(**{k: v for k, v in values.items() if k in PARAMETERS}).validate()
    options = NodeOptions(**{k: v for k, v in values.items() if k in NODE_PARAMETERS}).validate()
    unknown = unknown_overrides(node)
    if unknown:
        node.get_logger().warning(f'ignoring {_not_parameters(unknown)}')
    unused = unused_tolerance(node, config)
    if unused:
        node.get_logger().warning(unused)
    return config, options


def unused_tolerance(node, config: PipelineConfig) -> str | None:
    """Why a ``tolerance`` given on the command line or in a params file will not be the t of the frames, or None:
    with auto_tune on (the default) the sweep chooses t, so ``-p tolerance:=0.01`` alone changed nothing, where
    ``replay --tolerance 0.01`` fixes t. A value equal to the default (the shipped params.yaml) is no request."""
    given = (getattr(node, '_parameter_overrides', None) or {}).get('tolerance')
    if given is None or not config.auto_tune or config.tolerance == PARAMETERS['tolerance'].default:
        return None
    return _tolerance_unused(config.tolerance)


def _tolerance_unused(tolerance: float) -> str:
    return (f'tolerance {tolerance:g} is not used while auto_tune is true (the sweep chooses t): '
            'set auto_tune:=false for a fixed t')


def unknown_overrides(node) -> list[str]:
    """The names given to ``node`` on the command line or in a params file that are none of its parameters, once
    it has declared its own: rclpy ignores them without a word, so a misspelt ``tolerence`` would leave the
    default in place unseen."""
    given = getattr(node, '_parameter_overrides', None) or {}  # rclpy keeps them there (no public accessor)
    return sorted(name for name in given if not node.has_parameter(name))


def checked_changes(config: PipelineConfig, options: NodeOptions,
                    params) -> tuple[PipelineConfig, NodeOptions] | SetParametersResult:
    """The configuration after a SetParameters request, validated as a whole, or the refusal to send back."""
    pipeline = {p.name: PARAMETERS[p.name].converted(p.value) for p in params if p.name in PARAMETERS}
    node = {p.name: NODE_PARAMETERS[p.name].converted(p.value) for p in params if p.name in NODE_PARAMETERS}
    try:
        return dataclasses.replace(config, **pipeline).validate(), dataclasses.replace(options, **node).validate()
    except (ValueError, TypeError) as exc:
        return SetParametersResult(successful=False, reason=str(exc))


def params_yaml() -> str:
    """config/params.yaml: every node parameter at its default, with its description, for any node name."""
    lines = ['# Parameters of plane_validation_node and plane_validation_lifecycle_node (generated from',
             '# plane_validation/app/config.py and ros/parameters.py by params_yaml(); a test checks it).',
             '# Distances are in meters. Keyed /** so that it applies whatever the node is named:',
             '#   ros2 run plane_validation plane_validation_node --ros-args --params-file config/params.yaml \\',
             '#     -r cloud:=/camera/depth/points',
             '/**:', '  ros__parameters:']
    for spec in {**PARAMETERS, **NODE_PARAMETERS}.values():
        value = str(spec.default).lower() if spec.type is bool else spec.default
        lines.append(f'    # {spec.description}' + (f' [{spec.unit}]' if spec.unit else ''))
        lines.append(f'    {spec.name}: {value}')
    return '\n'.join(lines) + '\n'


def each_checked(params) -> SetParametersResult:
    """Whether each of a SetParameters request's values is allowed on its own (type, choices, range: what does not
    depend on the order parameters are set in), or the refusal naming the first that is not."""
    specs = {**PARAMETERS, **NODE_PARAMETERS}
    for param in params:
        spec = specs.get(param.name)
        why = None if spec is None else spec.problem(param.value)
        if why is not None:
            return SetParametersResult(successful=False, reason=why)
    return SetParametersResult(successful=True)


def apply_parameters(node, params):
    """The on-set-parameters callback of both nodes: validate the request as a whole against the current
    values, then hand the new configuration to the pipeline and the worker. A managed node that is not
    configured takes any value allowed on its own: configuring checks them together."""
    if node.pipeline is None:
        return each_checked(params)
    checked = checked_changes(node.pipeline.config, node.options, params)
    if isinstance(checked, SetParametersResult):
        return checked
    config, node.options = checked
    node.pipeline.reconfigure(config)
    if node.worker is not None:
        node.worker.min_output_rate_hz = node.options.min_output_rate_hz
    if config.auto_tune and any(param.name == 'tolerance' for param in params):  # accepted, and changes nothing
        node.get_logger().warning(_tolerance_unused(config.tolerance))
    return SetParametersResult(successful=True)


def not_declared(node, params) -> SetParametersResult:
    """The refusal of a request that names parameters ``node`` does not have, naming them: rclpy's own reason names
    none ('Invalid access to undeclared parameter(s): []', its list built from a generator already spent), so
    ``ros2 param set /plane_validation tolerence 0.01`` did not say which name was wrong."""
    unknown = sorted({param.name for param in params if not node.has_parameter(param.name)})
    return SetParametersResult(successful=False, reason=_not_parameters(unknown))


def _not_parameters(names: list[str]) -> str:
    return f'{", ".join(names)}: not a parameter of this node (--help lists them)'


def set_requests_whole(node) -> None:
    """Make ``node``'s plain SetParameters service apply each request as one change, all or none, as
    SetParametersAtomically does. rclpy's sets the parameters one by one, each checked against the values before
    it: tune_min above tune_max, sent together, applied tune_min and refused tune_max, a configuration nobody
    asked for (every later sweep failed), and two values valid together could be refused in one order. Both
    services name the parameters a request has that the node does not (:func:`not_declared`)."""
    def applied(params) -> SetParametersResult:
        try:
            return node.set_parameters_atomically(params)
        except ParameterNotDeclaredException:
            return not_declared(node, params)

    def whole(request, response):
        params = [RosParameter.from_parameter_msg(p) for p in request.parameters]
        response.results = [applied(params)] * len(params)  # one answer per parameter, as the service defines
        return response

    def atomically(request, response):
        response.result = applied([RosParameter.from_parameter_msg(p) for p in request.parameters])
        return response
    for service in node.services:
        if service.srv_type is SetParameters:
            service.callback = whole
        elif service.srv_type is SetParametersAtomically:
            service.callback = atomically
