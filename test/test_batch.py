"""``plane-validation batch``: many bags on the local process pool and on a real local Ray cluster."""
from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import psutil
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from plane_validation.app.config import PipelineConfig
from plane_validation.app.executors import LOCAL_ATTEMPTS, RAY_RETRIES, Lost, run_local, run_ray
from plane_validation.app.fleet import (
    FLEET_PNG,
    INDEX_CSV,
    INDEX_MD,
    REPORT,
    STAGING,
    SUMMARY,
    comparable,
    find_bags,
    plan_jobs,
)
from plane_validation.cli import main as cli_main
from plane_validation.ros.batch import _row, process_bag
from plane_validation.ros.replay import replay_offline

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[1]
BAGS = ROOT / 'bags'
# the bundled bags, not a bags/<bag>.planes that `plane-validation replay bags/cube` (the README's example) leaves
# there, which batch leaves out too
NAMES = sorted(p.name for p in BAGS.iterdir() if (p / 'metadata.yaml').is_file() and not p.name.endswith('.planes'))
#: Fewer tuning candidates than the default: the batch, not the sweep, is under test (a third faster).
FAST = ['--tune-count', '6']
FAST_CONFIG = PipelineConfig(tune_count=6)
PNG = b'\x89PNG\r\n\x1a\n'
TS2 = get_typestore(Stores.ROS2_JAZZY)


def _broken(folder: Path) -> Path:
    """A copy of the room bag whose MCAP file is cut in half (a recorder killed before closing it)."""
    bag = folder / 'broken'
    shutil.copytree(BAGS / 'room', bag)
    data = (bag / 'room.mcap').read_bytes()
    (bag / 'room.mcap').write_bytes(data[:len(data) // 2])
    return bag


def _index(out: Path) -> dict[str, dict]:
    with open(out / INDEX_CSV, newline='', encoding='utf-8') as f:
        return {row['bag']: row for row in csv.DictReader(f)}


def _summary(folder: Path) -> dict:
    return json.loads((folder / SUMMARY).read_text())


def _messages(bag: Path) -> dict[str, list[bytes]]:
    """topic -> raw messages of an output bag, /diagnostics left out (it carries processing times)."""
    out: dict[str, list[bytes]] = {}
    with AnyReader([bag], default_typestore=TS2) as reader:
        for conn, _, raw in reader.messages():
            if conn.topic != '/diagnostics':
                out.setdefault(conn.topic, []).append(bytes(raw))
    return out


def _assert_complete(folder: Path) -> None:
    assert (folder / REPORT).read_bytes().startswith(PNG)
    assert (folder / f'{folder.name}.planes' / 'metadata.yaml').is_file()
    assert _summary(folder)['frame_count'] == 5


def _no_staging(out: Path) -> None:
    assert [p for p in out.rglob(f'*{STAGING}')] == []


@pytest.fixture(scope='module')
def local_batch(tmp_path_factory):
    """The bundled bags plus a broken one through the local pool (2 workers): (out, sources, exit status)."""
    base = tmp_path_factory.mktemp('local')
    sources = [str(BAGS), str(_broken(base))]
    out = base / 'out'
    status = cli_main(['batch', *sources, '--out', str(out), '--workers', '2', *FAST])
    return out, sources, status


def test_local_pool_writes_every_bags_folder_and_the_index(local_batch):
    out, _, status = local_batch
    assert status == 1  # the broken bag failed, and the exit status says so
    rows = _index(out)
    assert sorted(rows) == sorted([*NAMES, 'broken'])
    for name in NAMES:
        assert rows[name]['status'] == 'ok', rows[name]
        _assert_complete(out / name)
        summary = _summary(out / name)
        assert len(summary['frames']) == 5 and summary['bag'] == name
        assert float(rows[name]['reliable_share']) == summary['reliable_share']
    assert rows['sphere']['reliable_share'] == '0' and rows['room']['reliable_share'] == '1'  # no planes / planes
    assert len(_summary(out / 'sphere')['verdict_failures']) == 5
    md = (out / INDEX_MD).read_text()
    assert all(f'| {name} | ok |' in md for name in NAMES) and '| broken | failed: ' in md
    assert (out / FLEET_PNG).read_bytes().startswith(PNG)
    _no_staging(out)


def test_a_bag_in_a_batch_gives_what_replay_gives(local_batch, tmp_path):
    out = local_batch[0]
    alone = replay_offline(BAGS / 'cube', out=tmp_path / 'cube.planes', config=FAST_CONFIG, echo=None,
                           progress=False)
    summary = _summary(out / 'cube')
    assert [f.n_planes for f in alone.frames] == summary['planes_per_frame']
    assert [f.tolerance for f in alone.frames] == summary['tolerance_per_frame']
    assert _messages(tmp_path / 'cube.planes') == _messages(out / 'cube' / 'cube.planes')


def test_a_corrupt_bag_gets_its_row_and_reason_and_no_folder(local_batch):
    out = local_batch[0]
    row = _index(out)['broken']
    assert row['status'].startswith('failed: cannot open bag') and 'ends early' in row['status'], row
    assert row['frames'] == '0' and not (out / 'broken').exists()


def test_a_rerun_skips_the_bags_done_and_redoes_changed_or_forced_ones(local_batch, tmp_path):
    out, sources, _ = local_batch
    again = tmp_path / 'out'
    shutil.copytree(out, again)
    before = {name: (again / name / SUMMARY).stat().st_mtime_ns for name in NAMES}
    assert cli_main(['batch', *sources, '--out', str(again), '--workers', '2', *FAST]) == 1
    rows = _index(again)
    assert {name: rows[name]['status'] for name in NAMES} == {name: 'skipped: done' for name in NAMES}
    assert rows['broken']['status'].startswith('failed: ')  # tried again
    assert before == {name: (again / name / SUMMARY).stat().st_mtime_ns for name in NAMES}
    # other options: done again; --force: done again with the same results
    assert cli_main(['batch', str(BAGS / 'table'), '--out', str(again), '--tune-count', '5']) == 0
    assert _summary(again / 'table')['settings']['config']['tune_count'] == 5
    assert cli_main(['batch', str(BAGS / 'corner_e0'), '--out', str(again), '--force', *FAST]) == 0
    assert _index(again)['corner_e0']['status'] == 'ok'
    assert (again / 'corner_e0' / SUMMARY).stat().st_mtime_ns != before['corner_e0']
    assert comparable(_summary(again / 'corner_e0')) == comparable(_summary(out / 'corner_e0'))
    _assert_complete(again / 'corner_e0')
    _no_staging(again)


def test_outputs_returned_by_a_worker_that_cannot_see_the_output_folder(local_batch, tmp_path):
    (job,) = plan_jobs([BAGS / 'stairs'], tmp_path, FAST_CONFIG)
    outcome = process_bag((job, '.batch-not-here'))  # no marker: as a Ray worker on another machine
    assert outcome.files is not None and not (tmp_path / 'stairs').exists()
    assert {SUMMARY, REPORT, 'stairs.planes/metadata.yaml'} <= set(outcome.files)
    assert _row(job, outcome).status.value == 'ok'  # the driver writes them
    _assert_complete(tmp_path / 'stairs')
    assert comparable(_summary(tmp_path / 'stairs')) == comparable(_summary(local_batch[0] / 'stairs'))
    assert _messages(tmp_path / 'stairs' / 'stairs.planes') == _messages(local_batch[0] / 'stairs' / 'stairs.planes')


@pytest.mark.parametrize('sig, status', [('SIGTERM', 143), ('SIGINT', 130)])
def test_a_signal_mid_batch_keeps_the_bags_done_and_a_rerun_continues(tmp_path, sig, status):
    out = tmp_path / 'out'
    proc = subprocess.Popen([sys.executable, '-u', '-m', 'plane_validation.cli', 'batch', str(BAGS), '--out',
                             str(out), '--workers', '1', *FAST], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        first = proc.stdout.readline()  # the first bag is done
        assert first.startswith(f'{NAMES[0]}: ok'), first + proc.stderr.read()
        deadline = time.monotonic() + 30
        while not list(out.glob(f'.*{STAGING}')) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert list(out.glob(f'.*{STAGING}')), 'the second bag was not being written'
        workers = psutil.Process(proc.pid).children(recursive=True)
        assert workers
        proc.send_signal(getattr(signal, sig))
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == status, err
    assert 'Traceback' not in err
    psutil.wait_procs(workers, timeout=10)
    assert [p.pid for p in workers if p.is_running() and p.status() != psutil.STATUS_ZOMBIE] == []
    done = sorted(p.name for p in out.iterdir() if p.is_dir())
    assert done and done == NAMES[:len(done)]
    for name in done:
        _assert_complete(out / name)
    _no_staging(out)
    assert not (out / INDEX_CSV).exists()
    if sig != 'SIGTERM':
        return  # the rerun is the same after either
    nxt = NAMES[len(done)]
    assert cli_main(['batch', str(BAGS / NAMES[0]), str(BAGS / nxt), '--out', str(out), *FAST]) == 0
    rows = _index(out)
    assert rows[NAMES[0]]['status'] == 'skipped: done' and rows[nxt]['status'] == 'ok'


def test_sources_are_bags_and_folders_searched_for_them(tmp_path):
    (tmp_path / 'a').mkdir()
    shutil.copytree(BAGS / 'room', tmp_path / 'a' / 'room')
    shutil.copytree(BAGS / 'room', tmp_path / 'a' / 'room.planes')  # a replay output: not a source
    shutil.copy(BAGS / 'cube' / 'cube.db3', tmp_path / 'a' / 'cube.db3')
    shutil.copytree(BAGS / 'room', tmp_path / 'out' / 'room')  # the batch's own outputs
    bags = find_bags([tmp_path, BAGS / 'room', tmp_path / 'a' / 'room'], tmp_path / 'out')
    assert bags == [tmp_path / 'a' / 'cube.db3', tmp_path / 'a' / 'room', BAGS / 'room']
    names = [job.name for job in plan_jobs(bags, tmp_path / 'out', FAST_CONFIG)]
    assert names[0] == 'cube' and names[1].startswith('room-') and names[2].startswith('room-') and \
        names[1] != names[2]
    (tmp_path / 'notes.txt').write_text('x')
    (tmp_path / 'empty' / 'inner').mkdir(parents=True)
    for source, why in ((tmp_path / 'missing', 'source not found'), (tmp_path / 'notes.txt', 'not a bag'),
                        (tmp_path / 'empty', 'no bags in it')):
        with pytest.raises(ValueError, match=why):
            find_bags([source], tmp_path / 'elsewhere')


def test_ray_without_ray_installed_says_how_to_install_it(tmp_path):
    script = textwrap.dedent('''
        import importlib.abc, sys
        class Block(importlib.abc.MetaPathFinder):
            def find_spec(self, name, path=None, target=None):
                if name.split('.')[0] == 'ray':
                    raise ImportError('blocked: ' + name)
        sys.meta_path.insert(0, Block())
        from plane_validation.cli.run import main
        sys.exit(main(sys.argv[1:]))
    ''')
    proc = subprocess.run([sys.executable, '-c', script, 'batch', str(BAGS / 'room'), '--out', str(tmp_path / 'o'),
                           '--ray', 'auto'], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "pip install '.[fleet]'" in proc.stderr, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and not (tmp_path / 'o').exists()


def _dies_until(marker: str, deaths: int) -> int:
    """A task whose process dies (as one killed or out of memory) its first ``deaths`` runs, counted in ``marker``."""
    path = Path(marker)
    runs = len(path.read_text()) if path.exists() else 0
    path.write_text('x' * (runs + 1))
    if runs < deaths:
        os._exit(3)
    return runs + 1


def test_a_local_worker_that_dies_is_replaced_and_its_bag_run_again(tmp_path):
    tasks = [(str(tmp_path / 'once'), 1), (str(tmp_path / 'always'), 99)]
    results = dict(run_local(_star, tasks, 1))
    assert results[0] == 2  # died once, then ran in a new worker
    assert isinstance(results[1], Lost) and f'died {LOCAL_ATTEMPTS} times' in results[1].why
    assert len((tmp_path / 'always').read_text()) == LOCAL_ATTEMPTS


def _star(args):
    return _dies_until(*args)


@pytest.fixture(scope='module')
def ray_cluster():
    """A real Ray cluster of this machine (2 CPUs, on 127.0.0.1), this process connected to it: its address."""
    ray = pytest.importorskip('ray', reason="needs Ray: pip install '.[fleet]'")
    ray.init(address='local', num_cpus=2, include_dashboard=False, log_to_driver=False)  # a new one
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])  # its workers cannot import this file
    try:
        yield ray.get_runtime_context().gcs_address
    finally:
        ray.shutdown()


@pytest.mark.ray
def test_a_ray_worker_lost_mid_task_is_retried_up_to_a_limit(ray_cluster, tmp_path):
    tasks = [(str(tmp_path / 'once'), 1), (str(tmp_path / 'always'), 99)]
    results = dict(run_ray(_star, tasks))  # this process's connection
    assert results[0] == 2
    assert isinstance(results[1], Lost) and f'lost {RAY_RETRIES + 1} times' in results[1].why, results[1]
    assert len((tmp_path / 'always').read_text()) == RAY_RETRIES + 1


@pytest.mark.ray
def test_ray_cluster_gives_the_local_pools_outputs(local_batch, ray_cluster, tmp_path):
    out = tmp_path / 'out'
    _, sources, local_status = local_batch
    proc = subprocess.Popen([sys.executable, '-m', 'plane_validation.cli', 'batch', *sources, '--out', str(out),
                             '--ray', ray_cluster, *FAST], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == local_status == 1, err
    local = local_batch[0]
    ray_rows, local_rows = _index(out), _index(local)
    assert {k: v['status'] for k, v in ray_rows.items()} == {k: v['status'] for k, v in local_rows.items()}
    for name in NAMES:
        assert comparable(_summary(out / name)) == comparable(_summary(local / name)), name
        assert (out / name / REPORT).read_bytes() == (local / name / REPORT).read_bytes(), name
        assert _messages(out / name / f'{name}.planes') == _messages(local / name / f'{name}.planes'), name
    workers = {_summary(out / name)['worker'].split(':')[1] for name in NAMES}
    assert str(proc.pid) not in workers  # the bags ran in Ray's workers, not in the driver
    _no_staging(out)
