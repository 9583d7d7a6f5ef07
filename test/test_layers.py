"""The package's layers and its single sources of facts: the core, formats and application layers
load without ROS or rosbags; params.yaml, the README and the CLI agree with the parameter table."""
from __future__ import annotations

import pkgutil
import subprocess
import sys
import textwrap
from pathlib import Path

import yaml

import plane_validation
from plane_validation.app.config import PARAMETERS, PipelineConfig, parameters_markdown
from plane_validation.core.verdict import RELIABLE_PS

ROOT = Path(__file__).resolve().parents[1]
ROS_FREE_LAYERS = ('core', 'formats', 'app')

#: Run in a fresh interpreter: block ROS and rosbags, import every module of the given layers.
BLOCKED_IMPORT = textwrap.dedent('''
    import importlib, pkgutil, sys
    import no_ros
    no_ros.install()
    import plane_validation
    loaded = []
    for layer in sys.argv[1:]:
        package = importlib.import_module(f'plane_validation.{layer}')
        for info in pkgutil.iter_modules(package.__path__):
            importlib.import_module(f'plane_validation.{layer}.{info.name}')
            loaded.append(f'{layer}.{info.name}')
    assert not no_ros.leaked(), no_ros.leaked()
    print(' '.join(loaded))
''')


def _run_without_ros(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-c', BLOCKED_IMPORT, *args], capture_output=True, text=True,
                          timeout=120, cwd=Path(__file__).parent)


def test_core_formats_and_app_import_without_ros_or_rosbags():
    proc = _run_without_ros(*ROS_FREE_LAYERS)
    assert proc.returncode == 0, proc.stderr
    loaded = set(proc.stdout.split())
    expected = {f'{layer}.{info.name}' for layer in ROS_FREE_LAYERS
                for info in pkgutil.iter_modules([str(Path(plane_validation.__file__).parent / layer)])}
    assert loaded == expected and {'core.ransac', 'formats.bags', 'app.pipeline', 'app.plot'} <= loaded


def test_replay_and_demo_without_ros_say_so_in_one_line():
    script = textwrap.dedent('''
        import sys
        import no_ros
        no_ros.install()
        from plane_validation.cli.run import main
        sys.exit(main(sys.argv[1:]))
    ''')
    for argv in (['replay', str(ROOT / 'bags' / 'cube')], ['demo', '--out', 'unused'],
                 ['batch', str(ROOT / 'bags' / 'cube'), '--out', 'unused']):
        proc = subprocess.run([sys.executable, '-c', script, *argv], capture_output=True, text=True, timeout=120,
                              cwd=Path(__file__).parent)
        assert proc.returncode == 2 and 'Traceback' not in proc.stderr, proc.stderr
        assert 'needs the ROS 2 Python packages' in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_the_blocker_does_block_ros():
    proc = _run_without_ros('ros')
    assert proc.returncode != 0 and 'blocked: ' in proc.stderr


def test_layers_import_only_earlier_layers():
    order = ['core', 'formats', 'app', 'ros', 'cli']
    package = Path(plane_validation.__file__).parent
    for rank, layer in enumerate(order):
        for path in (package / layer).glob('*.py'):
            imports = [line.strip() for line in path.read_text().splitlines()
                       if line.strip().startswith(('from ', 'import '))]
            for later in order[rank + 1:]:
                bad = [line for line in imports if f'..{later}' in line or f'plane_validation.{later}' in line]
                assert not bad, (path, bad)


def test_public_api_is_kept():
    import plane_validation.scenes as scenes_alias
    from plane_validation import scenes
    assert scenes is scenes_alias is plane_validation.core.scenes
    for name in ('detect_planes', 'validity_indices', 'tune_tolerance', 'select_plane_count'):
        assert callable(getattr(plane_validation, name))


def test_params_yaml_lists_exactly_the_node_parameters_with_the_table_defaults():
    from plane_validation.ros.node import NODE_PARAMETERS
    params = yaml.safe_load((ROOT / 'config' / 'params.yaml').read_text())['/**']['ros__parameters']
    table = {**PARAMETERS, **NODE_PARAMETERS}
    assert list(params) == list(table)
    for name, spec in table.items():
        assert params[name] == spec.default and type(params[name]) is spec.type, name


def test_readme_parameter_table_is_the_generated_one():
    assert parameters_markdown() in (ROOT / 'README.md').read_text()


def test_readme_quotes_the_verdict_threshold():
    text = (ROOT / 'README.md').read_text()
    assert f'PS ≥ {RELIABLE_PS}' in text
    assert 'GSplanes 0.1 ' not in text and 'GSplanes < 0.1.' not in text


def test_every_parameter_default_is_valid_and_each_range_is_enforced():
    PipelineConfig().validate()
    for name, spec in PARAMETERS.items():
        if spec.low is None:
            continue
        bad = spec.high * 2 if spec.high > 0 else spec.high + 1
        try:
            PipelineConfig(**{name: spec.type(bad)}).validate()
        except ValueError as exc:
            assert name in str(exc)
        else:
            raise AssertionError(f'{name}={bad} accepted')
    assert PARAMETERS['ransac_points'].problem(0) is None and PARAMETERS['ransac_points'].problem(999)


def test_params_yaml_is_the_generated_file():
    from plane_validation.ros.node import params_yaml
    assert (ROOT / 'config' / 'params.yaml').read_text() == params_yaml()


def test_the_search_functions_default_to_the_parameter_table_s_search():
    """detect_planes, search_graph, tune_tolerance and select_plane_count take the parameter table's search settings
    by default (core/params.py defines the RANSAC defaults once; the viewpoint's default is None, the origin)."""
    import inspect

    from plane_validation.core.plane_count import select_plane_count
    from plane_validation.core.ransac import detect_planes, search_graph
    from plane_validation.core.tuning import tune_tolerance
    search = PipelineConfig().search
    tuned, at_t = search.kwargs(), search.at_tolerance()  # a search at a given t runs auto's noise model as constant
    del tuned['viewpoint'], at_t['viewpoint']
    for function, table, least in ((detect_planes, at_t, set(at_t)),
                                   (search_graph, at_t, {'ransac_points', 'grid_points'}),
                                   (tune_tolerance, tuned, set(tuned)),
                                   (select_plane_count, at_t, {'max_planes', 'min_inliers', 'noise_model'})):
        defaults = {name: p.default for name, p in inspect.signature(function).parameters.items() if name in table}
        assert least <= set(defaults), (function.__name__, least - set(defaults))
        differ = {name: (value, table[name]) for name, value in defaults.items() if value != table[name]}
        assert not differ, (function.__name__, differ)
