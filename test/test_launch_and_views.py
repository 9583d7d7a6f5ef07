"""The launch file's logic (launch itself is not installable from PyPI: it runs against recording
stand-ins of the few launch classes it uses) and the RViz and Foxglove views (every topic they
show is one the node publishes)."""
from __future__ import annotations

import importlib.util
import json
import runpy
import sys
import types
from pathlib import Path

import pytest
import yaml

from plane_validation.ros.recorder import output_topics

ROOT = Path(__file__).resolve().parents[1]


class Recorded:
    """Any launch class: keeps its arguments."""

    def __init__(self, *args, **kwargs) -> None:
        self.args, self.kwargs = args, kwargs


def _stand_ins(share: Path) -> dict[str, types.ModuleType]:
    names = {'launch': ['LaunchDescription'], 'launch.actions': ['DeclareLaunchArgument', 'SetEnvironmentVariable'],
             'launch.conditions': ['IfCondition', 'UnlessCondition'], 'launch.substitutions': ['LaunchConfiguration'],
             'launch_ros': [], 'launch_ros.actions': ['Node', 'LifecycleNode'],
             'launch_ros.parameter_descriptions': ['ParameterValue'], 'ament_index_python': [],
             'ament_index_python.packages': []}
    modules = {}
    for module, classes in names.items():
        mod = types.ModuleType(module)
        for cls in classes:
            setattr(mod, cls, type(cls, (Recorded,), {}))
        modules[module] = mod
    modules['ament_index_python.packages'].get_package_share_directory = lambda name: str(share / name)
    return modules


def _launch_installed() -> bool:
    spec = importlib.util.find_spec('launch')  # the checkout's launch/ folder is a namespace package, not it
    return spec is not None and spec.origin is not None


@pytest.mark.skipif(_launch_installed(), reason='launch is installed: use ros2 launch')
def test_launch_file_declares_its_arguments_and_starts_one_of_the_two_nodes_with_the_large_cloud_profile(
        monkeypatch, tmp_path):
    for name, module in _stand_ins(tmp_path).items():
        monkeypatch.setitem(sys.modules, name, module)
    description = runpy.run_path(str(ROOT / 'launch' / 'plane_validation.launch.py'))['generate_launch_description']()
    (entities,) = description.args
    kinds = [type(e).__name__ for e in entities]
    arguments = {e.args[0]: e.kwargs['default_value'] for e in entities if kinds[entities.index(e)] ==
                 'DeclareLaunchArgument'}
    config = tmp_path / 'plane_validation' / 'config'
    assert arguments == {'namespace': '', 'use_sim_time': 'false', 'params_file': str(config / 'params.yaml'),
                         'cloud': 'cloud', 'managed': 'false', 'large_clouds': 'true'}
    (env,) = [e for e in entities if type(e).__name__ == 'SetEnvironmentVariable']
    assert env.args == ('FASTRTPS_DEFAULT_PROFILES_FILE', str(config / 'fastdds_large_clouds.xml'))
    assert (ROOT / 'config' / 'fastdds_large_clouds.xml').is_file()
    assert env.kwargs['condition'].args[0].args == ('large_clouds',)
    assert kinds.index('SetEnvironmentVariable') < kinds.index('Node')  # set before the node starts
    nodes = {type(e).__name__: e for e in entities if type(e).__name__ in ('Node', 'LifecycleNode')}
    assert {k: (v.kwargs['executable'], type(v.kwargs['condition']).__name__) for k, v in nodes.items()} == {
        'Node': ('plane_validation_node', 'UnlessCondition'),
        'LifecycleNode': ('plane_validation_lifecycle_node', 'IfCondition')}
    setup = (ROOT / 'setup.py').read_text()
    for node in nodes.values():
        kw = node.kwargs
        assert f"'{kw['executable']} = " in setup  # an installed executable
        assert kw['condition'].args[0].args == ('managed',) and kw['namespace'].args == ('namespace',)
        assert kw['remappings'][0][0] == 'cloud' and kw['remappings'][0][1].args == ('cloud',)
        params_file, sim_time = kw['parameters']
        assert params_file.args == ('params_file',)
        assert sim_time['use_sim_time'].args[0].args == ('use_sim_time',)
        assert sim_time['use_sim_time'].kwargs == {'value_type': bool}


def _topics(value) -> set[str]:
    """Every string in a nested document that names a topic under /plane_validation or /diagnostics."""
    if isinstance(value, dict):
        return set().union(*(_topics(k) | _topics(v) for k, v in value.items())) if value else set()
    if isinstance(value, list):
        return set().union(*map(_topics, value)) if value else set()
    if isinstance(value, str) and value.startswith(('/plane_validation', '/diagnostics')):
        return {value.split('.')[0]}
    return set()


def test_rviz_and_foxglove_views_show_the_node_outputs():
    published = set(output_topics().values())
    rviz = _topics(yaml.safe_load((ROOT / 'config' / 'plane_validation.rviz').read_text()))
    assert rviz == published - {'/diagnostics', '/plane_validation/plane_coefficients'}  # rviz shows no diagnostics
    foxglove = _topics(json.loads((ROOT / 'config' / 'plane_validation.foxglove.json').read_text()))
    assert foxglove == published - {'/plane_validation/plane_coefficients'}
    assert "glob('config/*.rviz')" in (ROOT / 'setup.py').read_text()  # installed with the package
