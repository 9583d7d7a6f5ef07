"""Every logging call site of the node, driven through each of its severities with real rclpy.

rclpy ties a call site to one severity: a site that logs INFO once and WARN later raises 'Logger severity
cannot be changed between calls' (the second line is lost, and the exception lands wherever the caller
catches it). The call sites are found in the source, so one added without a case here fails the test."""
from __future__ import annotations

import ast
import time
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')
from rclpy.parameter import Parameter  # noqa: E402
from ros_harness import Harness, xyz_cloud  # noqa: E402

from plane_validation import scenes  # noqa: E402
from plane_validation.ros.node import PlaneValidationNode  # noqa: E402

pytestmark = pytest.mark.ros

ROS = Path(__file__).resolve().parents[1] / 'plane_validation' / 'ros'
LEVELS = {'debug': 'DEBUG', 'info': 'INFO', 'warning': 'WARN', 'warn': 'WARN', 'error': 'ERROR', 'fatal': 'FATAL'}
#: (module, function, severity) of each call site -> what its line says. The lifecycle node's sites are
#: driven by test_lifecycle_node.py; they are listed there.
EXPECTED = {
    ('worker.py', '_work', 'ERROR'): 'frame failed unexpectedly: RuntimeError(',
    ('worker.py', 'process', 'ERROR'): 'ERROR: malformed PointCloud2',
    ('worker.py', 'process', 'WARN'): 'WARN: no reliable planes',  # the first WARN frame (throttled after)
    ('worker.py', 'run', 'INFO'): 'retuned: t = ',
    ('worker.py', 'run', 'WARN'): ('retuned: t = ', 'retune failed, keeping t: '),
    ('worker.py', 'subscribe', 'INFO'): 'listening for PointCloud2 on /cloud (best_effort); publishing ~/segmented',
}


def call_sites(path: Path) -> list[tuple[str, str, str, int]]:
    """(module, enclosing function, severity, line) of every logger call in ``path``."""
    sites = []

    def visit(node: ast.AST, function: str) -> None:
        for child in ast.iter_child_nodes(node):
            name = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else function
            if isinstance(child, ast.Call) and isinstance(child.func, ast.Attribute) and child.func.attr in LEVELS:
                target = child.func.value
                if (isinstance(target, ast.Attribute) and target.attr == 'logger') or (
                        isinstance(target, ast.Call) and isinstance(target.func, ast.Attribute)
                        and target.func.attr == 'get_logger'):
                    sites.append((path.name, function, LEVELS[child.func.attr], child.lineno))
            visit(child, name)
    visit(ast.parse(path.read_text()), '<module>')
    return sites


def test_every_call_site_of_the_shared_wiring_is_known():
    found = {site[:3] for site in call_sites(ROS / 'worker.py') + call_sites(ROS / 'node.py')}
    assert found == set(EXPECTED), found ^ set(EXPECTED)
    # the two retune sites with WARN are two lines (one per message), not one line with two severities
    lines = {}
    for module in ('worker.py', 'node.py', 'lifecycle_node.py'):
        if (ROS / module).exists():
            for mod, _, level, line in call_sites(ROS / module):
                lines.setdefault((mod, line), set()).add(level)
    assert all(len(levels) == 1 for levels in lines.values())


@pytest.fixture(scope='module')
def ros():
    rclpy.init()
    yield
    rclpy.try_shutdown()


def test_each_call_site_logs_each_of_its_severities(ros, capfd):
    node = PlaneValidationNode(parameter_overrides=[Parameter('seed', value=3)])
    h = Harness(node)
    t0 = 12_000_000_000_000
    corner = scenes.corner(3000, 0.2, scale=0.01, seed=1).points
    try:
        # a first sweep on clutter is not reliable (WARN at the retune site), its retry 1.5 s later on a
        # corner is (INFO at the same function, its own line): the order that used to lose the second line
        h.send(xyz_cloud(np.random.default_rng(0).random((3000, 3)), t0))
        assert node.wait_for_sweep(timeout=60)
        h.send(xyz_cloud(corner, t0 + 1_500_000_000))
        assert node.wait_for_sweep(timeout=60)
        assert node.pipeline.last_tuning.reliable
        # a sweep that cannot run (a range the cloud cannot honour): WARN 'retune failed'
        assert node.set_parameters([Parameter('tune_min', value=5.0)])[0].successful
        h.send(xyz_cloud(corner, t0 + 2_000_000_000))
        assert node.wait_for_sweep(timeout=60)
        # the frame sites: ERROR, WARN, ERROR again (throttled per severity, never refused)
        no_z = xyz_cloud(corner, t0 + 3_000_000_000)
        no_z.fields = list(no_z.fields)[:2]
        answers = [h.send(no_z), h.send(xyz_cloud(np.array([[0, 0, 1.0], [1, 1, 1.0]]), t0 + 3_000_000_001))]
        assert [a['diagnostics'].status[0].level for a in answers] == [b'\x02', b'\x01']
        # an unexpected failure inside a frame is logged at ERROR and the node goes on
        process_cloud = node.pipeline.process_cloud

        def broken(msg, **kwargs):
            node.pipeline.process_cloud = process_cloud
            raise RuntimeError('injected')
        node.pipeline.process_cloud = broken
        h.pub.publish(xyz_cloud(corner, t0 + 4_000_000_000))
        h._wait(lambda: node.pipeline.process_cloud == process_cloud, 30, 'the injected failure')
        after = h.send(xyz_cloud(corner, t0 + 5_000_000_000))  # answered: the worker lives on
        assert after['diagnostics'].status[0].level in (b'\x00', b'\x01')
        time.sleep(0.3)
    finally:
        h.close()
    err = capfd.readouterr().err
    assert 'Logger severity cannot be changed' not in err, err
    lines = err.splitlines()
    for (module, function, level), says in EXPECTED.items():
        for text in (says,) if isinstance(says, str) else says:
            assert any(f'[{level}]' in line and text in line for line in lines), (module, function, level, text, err)
    retuned = [line for line in lines if 'retuned: t = ' in line]
    assert [('[WARN]' in line, '[INFO]' in line) for line in retuned] == [(True, False), (False, True)], retuned


def test_a_misspelt_parameter_is_named_in_a_warning_not_ignored_in_silence(ros, capfd):
    node = PlaneValidationNode(parameter_overrides=[Parameter('tolerence', value=0.037),
                                                    Parameter('max_planes', value=3)])
    try:
        assert node.pipeline.config.max_planes == 3 and node.pipeline.config.tolerance != 0.037
    finally:
        node.destroy_node()
    warned = [line for line in capfd.readouterr().err.splitlines() if '[WARN]' in line and 'ignoring' in line]
    assert len(warned) == 1 and 'tolerence' in warned[0] and 'max_planes' not in warned[0], warned


@pytest.mark.parametrize('overrides, warns', [
    ({'tolerance': 0.01}, True),                         # auto_tune on by default: t is swept, not 0.01
    ({'tolerance': 0.01, 'auto_tune': False}, False),    # a fixed t: used
    ({'tolerance': 0.02}, False),                        # the default (the shipped params.yaml): no request
    ({'max_planes': 3}, False),
])
def test_a_tolerance_given_while_auto_tune_is_on_is_named_in_a_warning(ros, capfd, overrides, warns):
    node = PlaneValidationNode(parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
    node.destroy_node()
    warned = [line for line in capfd.readouterr().err.splitlines() if '[WARN]' in line and 'auto_tune' in line]
    assert len(warned) == int(warns), warned
    if warns:
        assert 'tolerance 0.01 is not used while auto_tune is true' in warned[0] and 'auto_tune:=false' in warned[0]


@pytest.mark.parametrize('change, warns', [({'tolerance': 0.03}, True),
                                           ({'tolerance': 0.03, 'auto_tune': False}, False),
                                           ({'max_planes': 4}, False)])
def test_a_tolerance_set_while_auto_tune_is_on_is_named_in_a_warning(ros, capfd, change, warns):
    """`ros2 param set /plane_validation tolerance 0.03` is accepted and changes nothing while auto_tune is on."""
    node = PlaneValidationNode()
    try:
        capfd.readouterr()
        result = node.set_parameters_atomically([Parameter(k, value=v) for k, v in change.items()])
        assert result.successful, result.reason
    finally:
        node.destroy_node()
    warned = [line for line in capfd.readouterr().err.splitlines() if '[WARN]' in line and 'auto_tune' in line]
    assert len(warned) == int(warns), warned
    if warns:
        assert 'tolerance 0.03 is not used while auto_tune is true' in warned[0], warned


def test_the_start_names_the_topic_the_node_listens_on_and_where_it_publishes(ros, capfd):
    node = PlaneValidationNode(cli_args=['--ros-args', '-r', 'cloud:=/camera/depth/points', '-r', '__ns:=/front'])
    node.destroy_node()
    said = [line for line in capfd.readouterr().err.splitlines() if '[INFO]' in line and 'listening' in line]
    assert len(said) == 1 and 'listening for PointCloud2 on /camera/depth/points (best_effort)' in said[0], said
    assert '(~ = /front/plane_validation; each while it has a subscriber) and /diagnostics' in said[0], said
