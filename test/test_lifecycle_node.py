"""The managed node over real DDS, driven through lifecycle_msgs' ChangeState and GetState services."""
from __future__ import annotations

import threading
import time

import pytest

rclpy = pytest.importorskip('rclpy')
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from lifecycle_msgs.msg import State, Transition  # noqa: E402
from lifecycle_msgs.srv import ChangeState, GetState  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from ros_harness import diag_values, stamp_key, xyz_cloud  # noqa: E402
from sensor_msgs.msg import PointCloud2  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402
from test_node_logging import ROS, call_sites  # noqa: E402

from plane_validation import scenes  # noqa: E402
from plane_validation.ros.lifecycle_node import PlaneValidationLifecycleNode  # noqa: E402

pytestmark = pytest.mark.ros


@pytest.fixture(scope='module')
def ros():
    rclpy.init()
    yield
    rclpy.try_shutdown()


class Manager:
    """A lifecycle manager and a probe in one: calls the node's lifecycle services, sends clouds and
    records /diagnostics, all over DDS."""

    def __init__(self, node) -> None:
        self.node = node
        self.probe = rclpy.create_node('lifecycle_probe')
        name = node.get_fully_qualified_name()
        self.change = self.probe.create_client(ChangeState, f'{name}/change_state')
        self.get = self.probe.create_client(GetState, f'{name}/get_state')
        self.pub = self.probe.create_publisher(PointCloud2, '/cloud',
                                               QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        self.diagnostics: dict[int, DiagnosticArray] = {}
        self.probe.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag,
                                       QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE))
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(node)
        self.executor.add_node(self.probe)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()
        assert self.change.wait_for_service(timeout_sec=10) and self.get.wait_for_service(timeout_sec=10)

    def _on_diag(self, msg) -> None:
        self.diagnostics[stamp_key(msg.header)] = msg

    def _call(self, client, request):
        future = client.call_async(request)
        end = time.monotonic() + 30
        while not future.done() and time.monotonic() < end:
            time.sleep(0.01)
        assert future.done(), 'no answer from the lifecycle service'
        return future.result()

    def state(self) -> str:
        return self._call(self.get, GetState.Request()).current_state.label

    def transition(self, transition_id: int) -> bool:
        return self._call(self.change, ChangeState.Request(transition=Transition(id=transition_id))).success

    def send(self, msg, timeout: float = 30.0):
        key = stamp_key(msg.header)
        self.pub.publish(msg)
        end = time.monotonic() + timeout
        while key not in self.diagnostics and time.monotonic() < end:
            time.sleep(0.02)
        return self.diagnostics.get(key)

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=5)
        self.thread.join(timeout=5)
        self.node.destroy_node()
        self.probe.destroy_node()


def test_transitions_bring_the_node_up_and_down_and_deactivation_keeps_the_tuned_tolerance(ros, capfd):
    node = PlaneValidationLifecycleNode(parameter_overrides=[Parameter('seed', value=3),
                                                             Parameter('tune_min', value=0.5),
                                                             Parameter('tune_max', value=0.1)])
    m = Manager(node)
    cloud = scenes.corner(3000, 0.2, scale=0.01, seed=1).points
    try:
        assert m.state() == 'unconfigured'
        assert not m.transition(Transition.TRANSITION_ACTIVATE)  # out of order: refused, the node lives on
        assert m.state() == 'unconfigured'
        assert not m.transition(Transition.TRANSITION_CONFIGURE)  # tune_max below tune_min: refused
        assert m.state() == 'unconfigured'
        assert node.set_parameters([Parameter('tune_min', value=0.0), Parameter('tune_max', value=0.0)])[0].successful
        assert m.transition(Transition.TRANSITION_CONFIGURE) and m.state() == 'inactive'
        assert m.probe.count_subscribers('/cloud') == 0  # configured, not active: not listening
        assert m.probe.count_publishers('/plane_validation/segmented') == 1

        assert m.transition(Transition.TRANSITION_ACTIVATE) and m.state() == 'active'
        end = time.monotonic() + 10
        while m.pub.get_subscription_count() == 0 and time.monotonic() < end:
            time.sleep(0.02)
        first = m.send(xyz_cloud(cloud, 20_000_000_000_000))
        assert first is not None and diag_values(first)['planes'] == '3'
        assert node.wait_for_sweep(timeout=60)
        tuned = node.pipeline.tolerance
        assert tuned is not None

        assert m.transition(Transition.TRANSITION_DEACTIVATE) and m.state() == 'inactive'
        assert m.probe.count_subscribers('/cloud') == 0
        assert m.send(xyz_cloud(cloud, 20_000_000_000_001), timeout=1.0) is None  # inactive: no answer
        assert m.transition(Transition.TRANSITION_ACTIVATE) and m.state() == 'active'
        end = time.monotonic() + 10
        while m.pub.get_subscription_count() == 0 and time.monotonic() < end:
            time.sleep(0.02)
        again = m.send(xyz_cloud(cloud, 20_000_000_000_002))
        values = diag_values(again)
        assert values['tolerance_source'].startswith('tuned at') and float(values['tolerance']) == pytest.approx(
            tuned, rel=1e-5)  # kept across deactivation
        assert values['plane_ids'] == diag_values(first)['plane_ids']  # and so are the plane tracks

        assert not m.transition(Transition.TRANSITION_CLEANUP)  # only from inactive
        assert m.transition(Transition.TRANSITION_DEACTIVATE)
        assert m.transition(Transition.TRANSITION_CLEANUP) and m.state() == 'unconfigured'
        assert node.pipeline is None and node.worker is None
        end = time.monotonic() + 10
        while m.probe.count_publishers('/plane_validation/segmented') and time.monotonic() < end:
            time.sleep(0.02)
        assert m.probe.count_publishers('/plane_validation/segmented') == 0  # released
        assert m.transition(Transition.TRANSITION_CONFIGURE) and m.state() == 'inactive'  # and again
        assert m.transition(Transition.TRANSITION_INACTIVE_SHUTDOWN) and m.state() == 'finalized'
        assert m.get.service_is_ready()  # alive after all of it
    finally:
        m.close()
    # each logging call site of the managed node, at its one severity
    err = capfd.readouterr().err
    assert 'Logger severity cannot be changed' not in err
    assert any('[ERROR]' in line and 'configure refused: tune_max must be greater than tune_min' in line
               for line in err.splitlines()), err
    assert any('[WARN]' in line and 'refused in state unconfigured' in line for line in err.splitlines()), err
    sites = {site[1:3] for site in call_sites(ROS / 'lifecycle_node.py')}
    assert sites == {('on_configure', 'ERROR'), ('refuse_out_of_order', 'WARN')}, sites


def test_the_managed_node_builds_only_the_outputs_someone_subscribes_to(ros):
    node = PlaneValidationLifecycleNode(parameter_overrides=[Parameter('auto_tune', value=False),
                                                             Parameter('tolerance', value=0.01)])
    m = Manager(node)
    got: list = []
    m.probe.create_subscription(Float64MultiArray, '/plane_validation/plane_coefficients', got.append,
                                QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    try:
        assert m.transition(Transition.TRANSITION_CONFIGURE) and m.transition(Transition.TRANSITION_ACTIVATE)
        end = time.monotonic() + 10
        while not (m.pub.get_subscription_count() and node.worker.listened('plane_coefficients')) \
                and time.monotonic() < end:
            time.sleep(0.02)
        built: list[str] = []
        publish = node.worker.publish
        node.worker.publish = lambda key, msg: (built.append(key), publish(key, msg))
        diag = m.send(xyz_cloud(scenes.corner(3000, 0.2, scale=0.01, seed=1).points, 21_000_000_000_000))
        assert diag is not None and diag_values(diag)['planes'] == '3'
        end = time.monotonic() + 10
        while not got and time.monotonic() < end:
            time.sleep(0.02)
        assert len(got) == 1 and len(got[0].data) == 3 * 4
        assert built == ['plane_coefficients', 'diagnostics']
    finally:
        m.close()


def _set_over_dds(m: Manager, **params) -> list:
    """SetParameters on the managed node, called over DDS as ``ros2 param set`` does; its results."""
    from rcl_interfaces.srv import SetParameters
    client = m.probe.create_client(SetParameters, f'{m.node.get_fully_qualified_name()}/set_parameters')
    try:
        assert client.wait_for_service(timeout_sec=10)
        request = SetParameters.Request(parameters=[Parameter(k, value=v).to_parameter_msg()
                                                    for k, v in params.items()])
        return list(m._call(client, request).results)
    finally:
        m.probe.destroy_client(client)


def test_parameters_can_be_set_over_dds_before_configure_and_configure_uses_them(ros):
    """As with Navigation 2's managed nodes: the parameters exist while the node is unconfigured; a descriptor's
    range is enforced at once, the checks between parameters at configure."""
    m = Manager(PlaneValidationLifecycleNode())
    try:
        assert m.state() == 'unconfigured' and m.node.pipeline is None
        assert all(r.successful for r in _set_over_dds(m, tolerance=0.035, max_planes=4))
        refused = _set_over_dds(m, tolerance=-1.0)  # below the descriptor's range
        assert not refused[0].successful and m.node.get_parameter('tolerance').value == 0.035
        assert all(r.successful for r in _set_over_dds(m, tune_min=0.5, tune_max=0.1))  # checked together later
        assert not m.transition(Transition.TRANSITION_CONFIGURE) and m.state() == 'unconfigured'
        assert all(r.successful for r in _set_over_dds(m, tune_min=0.0, tune_max=0.0))
        assert m.transition(Transition.TRANSITION_CONFIGURE) and m.state() == 'inactive'
        config = m.node.pipeline.config
        assert (config.tolerance, config.max_planes, config.tune_min) == (0.035, 4, 0.0)
    finally:
        m.close()


def test_a_value_not_allowed_on_its_own_is_refused_at_once_while_unconfigured(ros):
    """A choice or a type is no check between parameters: refused when set, as on a configured node (it was taken
    and configure then failed on it), while a pair that only fails together still waits for configure."""
    m = Manager(PlaneValidationLifecycleNode())
    try:
        bogus = _set_over_dds(m, noise_model='bogus')
        assert not bogus[0].successful and 'noise_model must be one of' in bogus[0].reason
        word = _set_over_dds(m, tolerance='abc')
        assert not word[0].successful and 'tolerance must be a float' in word[0].reason
        assert m.node.get_parameter('noise_model').value == 'auto'
        assert all(r.successful for r in _set_over_dds(m, ground_margin=0.1, ground_up_z=0.0))
        assert not m.transition(Transition.TRANSITION_CONFIGURE) and m.state() == 'unconfigured'
    finally:
        m.close()


def test_an_override_refused_at_start_fails_configure_until_the_parameter_is_set(ros):
    """An override out of range (``-p tolerance:=-1.0``) refuses configure, naming it; the parameter exists at its
    default, so setting it lets configure go on (it stayed undeclared: it could not be set, and the node could not
    be configured again until it was restarted)."""
    node = PlaneValidationLifecycleNode(cli_args=['--ros-args', '-p', 'tolerance:=-1.0', '-p', 'max_planes:=4'])
    m = Manager(node)
    try:
        assert node.get_parameter('max_planes').value == 4 and node.has_parameter('tolerance')
        for _ in range(2):
            assert not m.transition(Transition.TRANSITION_CONFIGURE) and m.state() == 'unconfigured'
        assert not _set_over_dds(m, tolerance=-2.0)[0].successful
        assert not m.transition(Transition.TRANSITION_CONFIGURE)
        assert all(r.successful for r in _set_over_dds(m, tolerance=0.03))
        assert m.transition(Transition.TRANSITION_CONFIGURE) and m.state() == 'inactive'
        assert (node.pipeline.config.tolerance, node.pipeline.config.max_planes) == (0.03, 4)
    finally:
        m.close()

def test_the_lifecycle_executable_prints_its_usage():
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, '-m', 'plane_validation.ros.lifecycle_node', '--help'],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and 'min_output_rate_hz' in proc.stdout
    assert proc.stdout.startswith('usage: plane_validation_lifecycle_node ') and 'starts unconfigured' in proc.stdout
    assert State.PRIMARY_STATE_ACTIVE == 3  # lifecycle_msgs is importable from the ros extra
