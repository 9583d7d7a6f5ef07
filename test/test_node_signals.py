"""Signals that end a node process (SIGINT, SIGTERM, SIGHUP) during a parallel sweep: the node shuts down and
ends and reaps every process it started (loky's workers and resource tracker), over real DDS."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

rclpy = pytest.importorskip('rclpy')
psutil = pytest.importorskip('psutil')
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from ros_harness import xyz_cloud  # noqa: E402
from sensor_msgs.msg import PointCloud2  # noqa: E402

from plane_validation import scenes  # noqa: E402

pytestmark = pytest.mark.ros


@pytest.fixture(scope='module')
def ros():
    rclpy.init()
    yield
    rclpy.try_shutdown()


def _alive(proc: psutil.Process) -> bool:
    try:
        return proc.is_running() and proc.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


@pytest.mark.parametrize('sig', ['SIGHUP', 'SIGTERM', 'SIGINT'])
def test_a_signal_during_a_parallel_sweep_ends_and_reaps_the_workers(ros, sig, tmp_path):
    if (os.cpu_count() or 1) < 2:
        pytest.skip('a parallel sweep needs two cores')
    # files, not pipes: a worker left behind would hold a pipe open and hang the read
    out_file, err_file = open(tmp_path / 'out', 'w'), open(tmp_path / 'err', 'w')
    proc = subprocess.Popen([sys.executable, '-m', 'plane_validation.ros.node', '--ros-args', '-p', 'tune_jobs:=2',
                             '-p', 'tune_count:=40', '-p', 'seed:=3'], stdout=out_file, stderr=err_file,
                            start_new_session=True)
    probe = rclpy.create_node('signal_sweep_probe')
    pub = probe.create_publisher(PointCloud2, 'cloud', QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
    cloud = xyz_cloud(scenes.cube(20000, 0.005, side=1.0, seed=1).points, 1_000_000_000)
    children: list[psutil.Process] = []
    roles: dict[int, str] = {}
    try:
        node = psutil.Process(proc.pid)
        deadline = time.monotonic() + 90
        while proc.poll() is None and time.monotonic() < deadline:  # until the sweep has started its workers
            pub.publish(cloud)
            time.sleep(0.5)
            children = node.children(recursive=True)
            if any('LokyProcess' in ' '.join(c.cmdline()) for c in children if _alive(c)):
                break
        assert proc.poll() is None, (tmp_path / 'err').read_text()
        time.sleep(0.5)
        children = node.children(recursive=True)
        roles = {c.pid: ' '.join(c.cmdline()) for c in children if _alive(c)}
        assert any('LokyProcess' in role for role in roles.values()), f'no sweep worker to end: {roles}'
        proc.send_signal(getattr(signal, sig))
        proc.wait(timeout=30)
        # the node ended and reaped its workers before it exited: nothing is left for PID 1, which may never reap
        workers = [(c.pid, roles.get(c.pid, '?'), c.status()) for c in children
                   if c.is_running() and 'resource_tracker' not in roles.get(c.pid, '')]
        # loky's resource trackers end once no process holds their pipe (they may wait for PID 1 to reap them)
        deadline = time.monotonic() + 10
        while any(_alive(c) for c in children) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = workers + [(c.pid, roles.get(c.pid, '?')) for c in children if _alive(c)]
    finally:
        probe.destroy_node()
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        for child in children:  # whatever the outcome, nothing of this test outlives it
            try:
                child.kill()
            except psutil.Error:
                pass
        out_file.close()
        err_file.close()
    out, err = (tmp_path / 'out').read_text(), (tmp_path / 'err').read_text()
    assert proc.returncode == 0, (proc.returncode, err)
    assert 'Traceback' not in err + out, err
    assert not left, f'processes left behind after {sig}: {left}'


def test_the_node_ends_rclpys_signal_thread_before_its_executor_and_ignores_late_signals():
    """rclpy's signal thread triggers the executors' guard conditions without a lock: main() ends it before the
    executor is freed. After that a SIGTERM or SIGINT neither shuts rclpy down nor ends the process."""
    script = '\n'.join([
        'import os, signal, time',
        'import rclpy',
        'from rclpy.executors import SingleThreadedExecutor',
        'from plane_validation.ros.node import _end_signal_handling',
        'rclpy.init()',
        'executor = SingleThreadedExecutor()',
        'tasks = len(os.listdir("/proc/self/task"))',
        '_end_signal_handling()',
        'ended = tasks - len(os.listdir("/proc/self/task"))',
        'os.kill(os.getpid(), signal.SIGTERM)',
        'os.kill(os.getpid(), signal.SIGINT)',
        'time.sleep(0.3)',
        'print(ended, rclpy.ok())',
        'executor.shutdown()',
        'rclpy.shutdown()'])
    done = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    ended, ok = done.stdout.split()
    assert int(ended) >= 1, 'rclpy\'s signal thread still runs'
    assert ok == 'True', 'a late signal shut rclpy down'
