"""Packaging: colcon builds the ament_python package the way a robot would, and what it installs is
what ``ros2 run`` / ``ros2 launch`` need; package.xml declares every dependency the code imports.

The colcon part needs ``colcon-core colcon-ros colcon-python-setup-py ros-jazzy-ament-package``
(requirements-test.txt); it is skipped, with the reason, only when colcon is not installed.
"""
from __future__ import annotations

import ast
import os
import re
import secrets
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros  # rclpy and the ROS message packages (and DDS for node tests)

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = 'plane_validation'
#: what a colcon workspace needs of the repository (not .venv, benchmarks/, test/, the other bags, ...)
SOURCES = ['package.xml', 'setup.py', 'setup.cfg', 'resource', PACKAGE, 'config', 'launch', 'bags/room']
EXECUTABLES = ['plane_validation_node', 'plane-validation']
SHARE_FILES = ['package.xml', 'config/params.yaml', 'config/fastdds_large_clouds.xml',
               'launch/plane_validation.launch.py', 'bags/room/metadata.yaml', 'bags/room/room.mcap']
BUILD_TIMEOUT = 300.0

EXEC_DEPENDS = ['rclpy', 'sensor_msgs', 'std_msgs', 'geometry_msgs', 'visualization_msgs',
                'diagnostic_msgs', 'python3-numpy', 'python3-scipy']
TEST_DEPENDS = ['python3-pytest']

#: python import name -> rosdep key, for the imports that are not ROS package names
ROSDEP_KEYS = {
    'numpy': 'python3-numpy',
    'numba': 'python3-numba',
    'scipy': 'python3-scipy',
    'rosbags': 'python3-rosbags',
    'matplotlib': 'python3-matplotlib',
    'tqdm': 'python3-tqdm',
    'PIL': 'python3-pil',
    'plyfile': 'python3-plyfile',
    'threadpoolctl': 'python3-threadpoolctl',
    'joblib': 'python3-joblib',
    'psutil': 'python3-psutil',
    'yaml': 'python3-yaml',
    'sklearn': 'python3-sklearn',
    'hypothesis': 'python3-hypothesis',
    'pytest': 'python3-pytest',
}
#: pip-only optional imports, made inside functions with a clear error when missing (no rosdep key)
OPTIONAL_PIP = {'pypcd4', 'lzf', 'mcap', 'mcap_ros2',  # lzf: pypcd4's; mcap*: test-only, skipped when missing
                'ray'}  # batch --ray: the fleet extra
#: ROS packages whose python module has the package's name
ROS_PACKAGES = {'rclpy', 'launch', 'launch_ros', 'ament_index_python', 'rosidl_runtime_py',
                'message_filters', 'tf2_ros', 'tf2_py', 'rosbag2_py'}
ROS_SUFFIXES = ('_msgs', '_srvs', '_interfaces')


# -- package.xml and imports (no colcon needed) ---------------------------------------------------
def _package_xml() -> ET.Element:
    return ET.parse(ROOT / 'package.xml').getroot()


def _depends(root: ET.Element, *kinds: str) -> set[str]:
    """Dependencies of the given kinds; ``depend`` counts as build, exec and test dependency."""
    return {(e.text or '').strip() for kind in (*kinds, 'depend') for e in root.findall(kind)}


def _rosdep_key(module: str) -> str | None:
    if module in ROSDEP_KEYS:
        return ROSDEP_KEYS[module]
    if module in ROS_PACKAGES or module.endswith(ROS_SUFFIXES):
        return module
    return None


def _third_party_imports(files: list[Path], local: set[str]) -> dict[str, set[str]]:
    """Top-level module name -> files importing it (absolute imports only, stdlib and `local` left out)."""
    found: dict[str, set[str]] = {}
    for path in files:
        tree = ast.parse(path.read_text(encoding='utf-8'), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.partition('.')[0]
                if top in sys.stdlib_module_names or top == '__future__' or top in local:
                    continue
                found.setdefault(top, set()).add(path.relative_to(ROOT).as_posix())
    return found


def _uncovered(imports: dict[str, set[str]], declared: set[str]) -> list[str]:
    problems = []
    for module, files in sorted(imports.items()):
        if module in OPTIONAL_PIP:
            continue
        key = _rosdep_key(module)
        if key is None:
            problems.append(f'{module} (imported by {sorted(files)}): no rosdep key known; '
                            'add it to ROSDEP_KEYS in test_packaging.py and to package.xml')
        elif key not in declared:
            problems.append(f'{module} (imported by {sorted(files)}): package.xml lacks {key!r}')
    return problems


def test_package_xml_format_3_and_declared_dependencies():
    root = _package_xml()
    assert root.tag == 'package' and root.get('format') == '3'
    assert root.findtext('name') == PACKAGE
    assert root.findtext('export/build_type') == 'ament_python'
    assert 'ament_python' in _depends(root, 'buildtool_depend')
    exec_deps = _depends(root, 'exec_depend')
    assert [d for d in EXEC_DEPENDS if d not in exec_deps] == []
    test_deps = _depends(root, 'test_depend')
    assert [d for d in TEST_DEPENDS if d not in test_deps] == []


def test_every_runtime_import_is_a_package_xml_dependency():
    files = sorted((ROOT / PACKAGE).rglob('*.py')) + sorted((ROOT / 'launch').glob('*.py'))
    imports = _third_party_imports(files, local={PACKAGE})
    assert {'numpy', 'scipy', 'rclpy'} <= set(imports)  # the scan does see the imports
    assert _uncovered(imports, _depends(_package_xml(), 'exec_depend')) == []


def test_every_test_import_is_a_package_xml_dependency():
    files = sorted((ROOT / 'test').glob('*.py'))
    local = {PACKAGE} | {p.stem for p in files}
    imports = _third_party_imports(files, local)
    root = _package_xml()
    declared = _depends(root, 'exec_depend', 'test_depend', 'build_depend')
    assert _uncovered(imports, declared) == []


# -- colcon build ---------------------------------------------------------------------------------
def _colcon() -> str:
    candidate = Path(sys.executable).parent / 'colcon'  # the venv's colcon, next to its python
    if candidate.is_file() and os.access(candidate, os.X_OK):
        return str(candidate)
    found = shutil.which('colcon')
    if found is None:
        pytest.skip('colcon is not installed: `pip install -r requirements-test.txt` '
                    '(colcon-core colcon-ros colcon-python-setup-py ros-jazzy-ament-package)')
    return found


def _colcon_env(ws: Path) -> dict[str, str]:
    env = os.environ.copy()
    env['PATH'] = os.pathsep.join([str(Path(sys.executable).parent), env.get('PATH', '')])
    env['COLCON_HOME'] = str(ws / '.colcon_home')  # no user defaults.yaml (e.g. symlink-install)
    env.pop('COLCON_DEFAULTS_FILE', None)
    return env


def _run(cmd: list[str], ws: Path, timeout: float) -> subprocess.CompletedProcess:
    proc = subprocess.run(cmd, cwd=ws, env=_colcon_env(ws), capture_output=True, text=True,
                          timeout=timeout)
    assert proc.returncode == 0, (f'{" ".join(cmd)} exited with {proc.returncode}\n'
                                  f'--- stdout ---\n{proc.stdout[-4000:]}\n--- stderr ---\n{proc.stderr[-4000:]}')
    return proc


@pytest.fixture(scope='module')
def workspace(tmp_path_factory) -> Path:
    colcon = _colcon()
    ws = tmp_path_factory.mktemp('colcon_ws')
    src = ws / 'src' / PACKAGE
    src.mkdir(parents=True)
    ignore = shutil.ignore_patterns('__pycache__', '*.pyc', '*.egg-info')
    for name in SOURCES:
        path = ROOT / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=ignore)
        else:
            shutil.copy2(path, src / name)
    _run([colcon, '--log-base', str(ws / 'log'), 'build', '--base-paths', str(ws / 'src'),
          '--build-base', str(ws / 'build'), '--install-base', str(ws / 'install'),
          '--event-handlers', 'console_direct-'], ws, BUILD_TIMEOUT)
    log = (ws / 'log' / 'latest_build' / 'logger_all.log').read_text(encoding='utf-8', errors='replace')
    assert f"with type 'ros.ament_python' and name '{PACKAGE}'" in log, (
        'colcon did not build the package as ament_python (is colcon-ros installed?)')
    return ws


@pytest.fixture(scope='module')
def prefix(workspace) -> Path:
    """install/plane_validation (isolated install layout)."""
    return workspace / 'install' / PACKAGE


def _site_packages(prefix: Path) -> Path:
    found = sorted(prefix.glob('lib/python3*/site-packages'))
    assert len(found) == 1, f'expected one site-packages under {prefix}/lib, found {found}'
    return found[0]


def test_colcon_installs_executables_index_marker_and_share_files(prefix):
    for name in EXECUTABLES:
        exe = prefix / 'lib' / PACKAGE / name
        assert exe.is_file(), f'{exe} (what `ros2 run {PACKAGE} {name}` starts) is missing'
        assert os.access(exe, os.X_OK), f'{exe} is not executable'
        shebang = exe.read_text(encoding='utf-8').splitlines()[0]
        assert shebang.startswith('#!'), shebang
        interpreter = shebang[2:].split()
        program = interpreter[1] if Path(interpreter[0]).name == 'env' else interpreter[0]
        assert re.fullmatch(r'python[0-9.]*', Path(program).name), f'{exe}: shebang {shebang!r}'
        if Path(program).is_absolute():
            assert os.access(program, os.X_OK), f'{exe}: shebang interpreter {program} is not executable'
    marker = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / PACKAGE
    assert marker.is_file(), f'ament index marker {marker} is missing'
    for rel in SHARE_FILES:
        installed = prefix / 'share' / PACKAGE / rel
        assert installed.is_file(), f'{installed} is missing'
        assert installed.read_bytes() == (ROOT / rel).read_bytes(), f'{installed} differs from {rel}'
    site = _site_packages(prefix)
    assert (site / PACKAGE / '__init__.py').is_file()
    assert (site / PACKAGE / 'ros' / 'node.py').is_file()


def test_colcon_build_needs_no_ros_wheels(prefix):
    """ROS dependencies come from package.xml/rosdep on a robot: no hard pip requirement on ROS wheels."""
    requires = sorted(_site_packages(prefix).glob('*.egg-info/requires.txt'))
    assert len(requires) == 1
    hard = requires[0].read_text(encoding='utf-8').split('\n[', 1)[0].split()
    assert [r for r in hard if r.startswith(('ros-', 'ros_'))] == [], hard


def test_installed_package_finds_its_demo_bag_from_anywhere(prefix, tmp_path):
    # an outside probe: `plane-validation demo` found its bag only in the checkout's root
    code = 'from plane_validation.cli.commands import demo_bag; print(demo_bag())'
    env = dict(os.environ, PYTHONPATH=str(_site_packages(prefix)))
    found = subprocess.run([sys.executable, '-c', code], cwd=tmp_path, env=env, capture_output=True, text=True,
                           timeout=60)
    assert Path(found.stdout.strip()) == prefix / 'share' / PACKAGE / 'bags' / 'room', found.stderr


def test_installed_launch_file_starts_the_node_with_params_and_remapping(prefix):
    path = prefix / 'share' / PACKAGE / 'launch' / 'plane_validation.launch.py'
    tree = ast.parse(path.read_text(encoding='utf-8'))
    functions = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    assert 'generate_launch_description' in functions
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call)]

    def named(call: ast.Call) -> str:
        return getattr(call.func, 'id', getattr(call.func, 'attr', ''))

    assert [named(c) for c in calls if named(c) in ('Node', 'LifecycleNode')] == ['Node', 'LifecycleNode']
    strings = {n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)}
    executables = {s for s in strings if s.startswith(PACKAGE) and s.endswith('_node')}
    assert executables == {'plane_validation_node', 'plane_validation_lifecycle_node'}
    for executable in executables:  # both installed where ros2 launch looks
        assert (prefix / 'lib' / PACKAGE / executable).is_file(), executable
    keywords = {k.arg for n in ast.walk(tree) if isinstance(n, ast.Call) for k in n.keywords}
    assert {'package', 'parameters', 'remappings'} <= keywords
    arguments = {ast.literal_eval(c.args[0]) for c in calls if named(c) == 'DeclareLaunchArgument'}
    assert {'namespace', 'use_sim_time', 'params_file', 'cloud', 'managed', 'large_clouds'} <= arguments
    assert {'config', 'params.yaml'} <= strings  # default params file from the package's share dir


# -- the installed node starts and stops ----------------------------------------------------------
PROBE = r'''
import sys, time
import rclpy
ns, timeout = sys.argv[1], float(sys.argv[2])
rclpy.init()
node = rclpy.create_node('pv_pkgtest_probe', namespace=ns)
deadline = time.monotonic() + timeout
try:
    while time.monotonic() < deadline:
        if ('plane_validation', ns) in node.get_node_names_and_namespaces():
            print('READY', flush=True)
            sys.exit(0)
        time.sleep(0.05)
    sys.exit(1)
finally:
    node.destroy_node()
    rclpy.try_shutdown()
'''


def _stop(proc: subprocess.Popen) -> None:
    """Kill a process started in its own session, with anything it started."""
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    proc.wait(timeout=10)


def _warm_installed_kernels(site: Path) -> None:
    """Give the installed copy of the compiled kernels the repository's cache (numba takes a cache whose source has
    the same time stamp and size), as ``plane-validation warmup`` in an install step would: a cold compile takes
    25 s, and test_node tests one."""
    from plane_validation.core import kernels
    kernels.warm()
    source = Path(kernels.__file__)
    installed = site / PACKAGE / 'core' / 'kernels.py'
    if installed.read_bytes() != source.read_bytes():
        return
    stat = source.stat()
    os.utime(installed, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    (installed.parent / '__pycache__').mkdir(exist_ok=True)
    # where this process's kernels are cached: beside the source, or under NUMBA_CACHE_DIR when that is set
    for path in Path(kernels.finite_mask._cache._cache_path).glob('kernels.*.nb*'):
        shutil.copy(path, installed.parent / '__pycache__' / path.name)


def test_installed_node_starts_and_exits_cleanly_on_sigint(prefix, tmp_path):
    exe = prefix / 'lib' / PACKAGE / 'plane_validation_node'
    site = _site_packages(prefix)
    env = os.environ.copy()
    env.update(ROS_DOMAIN_ID='187', ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONUNBUFFERED='1',
               PYTHONPATH=os.pathsep.join(p for p in [str(site), env.get('PYTHONPATH', '')] if p),
               AMENT_PREFIX_PATH=os.pathsep.join(p for p in [str(prefix), env.get('AMENT_PREFIX_PATH', '')] if p))
    # NUMBA_CACHE_DIR too: the installed copy reads the cache put beside it (a cache there is keyed by source path)
    for var in ('ROS_LOCALHOST_ONLY', 'ROS_STATIC_PEERS', 'NUMBA_CACHE_DIR'):
        env.pop(var, None)
    # the installed copy of the package is the one imported, not the repository's editable install
    # (cwd outside the repository, as `ros2 run` would be)
    where = subprocess.run([sys.executable, '-c', f'import {PACKAGE}; print({PACKAGE}.__file__)'],
                           env=env, cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert Path(where.stdout.strip()).is_relative_to(site), where.stdout + where.stderr

    # a unique namespace tells this node apart from any other run on the same domain; the installed
    # params file, keyed /**, applies to the namespaced node as it is
    ns = f'/pv_pkgtest_{os.getpid()}_{secrets.token_hex(3)}'
    params = prefix / 'share' / PACKAGE / 'config' / 'params.yaml'
    assert params.read_text(encoding='utf-8').splitlines().count('/**:') == 1

    _warm_installed_kernels(site)
    log = tmp_path / 'node.log'
    with open(log, 'wb') as out:
        node = subprocess.Popen([str(exe), '--ros-args', '-r', f'__ns:={ns}', '--params-file', str(params)],
                                env=env, cwd=tmp_path, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True)
        # the installed copy compiles its kernels on a cold cache first (20-35 s): the probe waits for that
        probe = subprocess.Popen([sys.executable, '-c', PROBE, ns, '90'], env=env, cwd=tmp_path,
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                 start_new_session=True)
        try:
            deadline = time.monotonic() + 100.0
            while probe.poll() is None and node.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
            assert node.poll() is None, (f'node exited with {node.returncode} before it was discovered:\n'
                                         f'{log.read_text(errors="replace")}')
            probe_out = probe.communicate(timeout=10)[0]
            assert probe.returncode == 0 and 'READY' in probe_out, (
                f'node not discovered on the ROS graph as {ns}/plane_validation:\n{probe_out}\n'
                f'--- node output ---\n{log.read_text(errors="replace")}')
            time.sleep(0.5)  # let it settle into spin
            node.send_signal(signal.SIGINT)
            try:
                code = node.wait(timeout=10)
            except subprocess.TimeoutExpired:
                pytest.fail(f'node still running 10 s after SIGINT:\n{log.read_text(errors="replace")}')
        finally:
            _stop(probe)
            _stop(node)
    output = log.read_text(errors='replace')
    assert code == 0, f'exit code {code} after SIGINT:\n{output}'
    assert 'Traceback' not in output, output
