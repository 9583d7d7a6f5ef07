"""The managed (lifecycle) variant of the node, for stacks that bring perception up through
lifecycle transitions (Navigation 2's lifecycle manager, launch_ros' LifecycleNode):

    ros2 run plane_validation plane_validation_lifecycle_node --ros-args -r cloud:=/camera/depth/points
    ros2 lifecycle set /plane_validation configure   # then activate

The parameters are declared when the node is made, so that they can be set while it is unconfigured (as
Navigation 2's nodes allow); configure validates them (an invalid set is refused; the node stays unconfigured) and
creates the publishers; activate subscribes to ``cloud`` and publishes;
deactivate unsubscribes and stops publishing, keeping the tuned tolerance and the plane tracks;
cleanup releases them all. Topics and parameters are the plain node's (:mod:`.node`), and so is the
data flow (:class:`~.worker.FrameWorker`).
"""
from __future__ import annotations

import sys

from rcl_interfaces.msg import SetParametersResult
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn

from ..app.pipeline import FramePipeline
from ..core.kernels import Warmup
from .messages import status_name
from .node import main as run_node
from .parameters import apply_parameters, declare, declare_each, set_requests_whole
from .worker import FrameWorker, output_publishers, subscribe, warm_kernels

__all__ = ['PlaneValidationLifecycleNode', 'main']

SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE


class PlaneValidationLifecycleNode(LifecycleNode):
    """The node's topics and parameters, brought up by lifecycle transitions."""

    #: What its --help says of it.
    ABOUT = ('A managed (lifecycle) node: it starts unconfigured, its parameters settable; configure validates '
             'them, activate subscribes and publishes (ros2 lifecycle set NODE configure, then activate; or its '
             '~/change_state service).')

    def __init__(self, name: str = 'plane_validation', *, warmup: Warmup | None = None, **kwargs) -> None:
        """warmup: what main() did to the compiled kernels before the node existed (as the plain node's)."""
        super().__init__(name, **kwargs)
        self._warmup = warmup
        self.pipeline: FramePipeline | None = None
        self.worker: FrameWorker | None = None
        self.options = None
        self._pubs: dict[str, object] = {}
        self._subscription = None
        # settable before configure; an override rclpy refuses fails configure until the parameter is set
        self._refused = declare_each(self)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        set_requests_whole(self)
        # a transition that does not start from the current state makes rclpy's ChangeState callback raise,
        # which ends the executor's spin: it is refused instead (success false) and the node serves on
        change_state = self._service_change_state.callback

        def refuse_out_of_order(request, response):
            try:
                return change_state(request, response)
            except _rclpy.RCLError as exc:
                state = self._state_machine.current_state[1]
                self.get_logger().warning(f'transition {request.transition.id} {request.transition.label!r} '
                                          f'refused in state {state}: {exc}')
                response.success = False
                return response
        self._service_change_state.callback = refuse_out_of_order

    def _on_set_parameters(self, params) -> SetParametersResult:
        result = apply_parameters(self, params)
        if result.successful:  # an override refused at start is replaced
            for param in params:
                self._refused.pop(param.name, None)
        return result

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        try:
            if self._refused:
                name, why = next(iter(self._refused.items()))
                raise ValueError(f'{why} (given at start; set {name} to replace it)')
            config, options = declare(self)
        except Exception as exc:  # out of range, wrong type, inconsistent: refused, stays unconfigured
            self.get_logger().error(f'configure refused: {exc}')
            return FAILURE
        self.options = options
        if self._warmup is None or not self._warmup.compiled:  # a cold cache: main() compiled them all
            warm_kernels(self.get_logger(), self._warmup)
        self._warmup = None  # a later configure finds them loaded
        self.pipeline = FramePipeline(config)
        self._pubs = output_publishers(self.create_lifecycle_publisher)
        self.worker = FrameWorker(self, self.pipeline, self._publish, status_name(self.get_name()),
                                  min_output_rate_hz=options.min_output_rate_hz, listened=self._listened)
        return super().on_configure(state)

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        result = super().on_activate(state)  # enables the publishers before the first cloud can come
        self._subscription = subscribe(self, self.worker, self.options.reliability)
        return result

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._unsubscribe()
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._release()
        return super().on_cleanup(state)

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._release()
        return super().on_shutdown(state)

    def _publish(self, key: str, msg) -> None:
        publisher = self._pubs.get(key)
        if publisher is not None and publisher.is_activated:  # a frame in flight while deactivating is not sent
            publisher.publish(msg)

    def _listened(self, key: str) -> bool:
        publisher = self._pubs.get(key)
        return publisher is not None and publisher.get_subscription_count() > 0

    def _unsubscribe(self) -> None:
        if self._subscription is not None:
            self.destroy_subscription(self._subscription)
            self._subscription = None

    def _release(self) -> None:
        self._unsubscribe()
        if self.worker is not None:
            self.worker.stop()
        for publisher in self._pubs.values():
            self.destroy_lifecycle_publisher(publisher)
        self._pubs, self.worker, self.pipeline = {}, None, None

    def wait_for_sweep(self, timeout: float | None = None) -> bool:
        """Wait until no tolerance sweep is running (True) or ``timeout`` seconds pass (False)."""
        return True if self.worker is None else self.worker.wait_for_sweep(timeout)

    def destroy_node(self) -> None:
        self._release()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    return run_node(args, PlaneValidationLifecycleNode, 'plane_validation_lifecycle_node')


if __name__ == '__main__':
    sys.exit(main())
