"""ROS 2 node: PointCloud2 in, segmented planes and validity diagnostics out.

    ros2 run plane_validation plane_validation_node --ros-args --params-file config/params.yaml \
        -r cloud:=/camera/depth/points

Data flow (:class:`~plane_validation.ros.worker.FrameWorker`, shared with the managed node in
:mod:`.lifecycle_node`): the subscription hands each cloud to the worker's one-slot mailbox; its
thread runs the shared pipeline and publishes /diagnostics and each output that has a subscriber; tolerance
sweeps run in the background.
"""
from __future__ import annotations

import gc
import os
import signal
import sys

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.signals import uninstall_signal_handlers

from ..app.config import PARAMETERS
from ..app.pipeline import FramePipeline, limit_blas_threads, reuse_freed_memory
from ..core.interrupts import stop_at_signals, unignored
from ..core.kernels import Warmup, warm_probe
from ..core.workers import stop_workers
from .messages import OUTPUTS, status_name
from .parameters import NODE_PARAMETERS, apply_parameters, declare, descriptor, params_yaml, set_requests_whole
from .worker import LOG_THROTTLE_S, SWEEP_STOP_S, FrameWorker, output_publishers, subscribe, warm_kernels

__all__ = ['PlaneValidationNode', 'NODE_PARAMETERS', 'descriptor', 'params_yaml', 'spin', 'main',
           'LOG_THROTTLE_S', 'SWEEP_STOP_S', 'SPIN_CHECK_S']

#: Seconds between two looks at whether the node's context has shut down (spin).
SPIN_CHECK_S = 0.5


class PlaneValidationNode(Node):
    """Subscribes ``cloud``; publishes ``~/segmented``, ``~/planes``, ``~/plane_poses``,
    ``~/plane_coefficients`` and ``/diagnostics``."""

    def __init__(self, name: str = 'plane_validation', *, warmup: Warmup | None = None, **kwargs) -> None:
        """warmup: what main() did to the compiled kernels before the node existed: None (nothing), the probe of a warm
        cache (the other kernels load here), or the compile of a cold one (all done)."""
        super().__init__(name, **kwargs)
        config, self.options = declare(self)
        self.pipeline = FramePipeline(config)
        self.worker = None
        self.add_on_set_parameters_callback(lambda params: apply_parameters(self, params))
        set_requests_whole(self)
        pubs = output_publishers(self.create_publisher)
        self.worker = FrameWorker(self, self.pipeline, lambda key, msg: pubs[key].publish(msg),
                                  status_name(self.get_name()), min_output_rate_hz=self.options.min_output_rate_hz,
                                  listened=lambda key: pubs[key].get_subscription_count() > 0)
        subscribe(self, self.worker, self.options.reliability)
        # the kernels load once the subscription exists, while DDS discovers it (in its own threads) and the first
        # cloud travels: no frame is answered before the node spins
        self.warmup = warmup if warmup is not None and warmup.compiled else warm_kernels(self.get_logger(), warmup)

    def wait_for_sweep(self, timeout: float | None = None) -> bool:
        """Wait until no tolerance sweep is running (True) or ``timeout`` seconds pass (False)."""
        return self.worker.wait_for_sweep(timeout)

    def destroy_node(self) -> None:
        self.worker.stop()
        super().destroy_node()


def spin(node: Node, executor: SingleThreadedExecutor | None = None) -> None:
    """Serve ``node`` until its context shuts down, looking at the context every SPIN_CHECK_S: a SIGTERM's
    shutdown can fail to wake an executor that waits without a timeout (about 1 in 6 SIGTERMs during a
    parallel sweep left the node waiting forever with its context gone)."""
    executor = executor or SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        while node.context.ok():
            executor.spin_once(timeout_sec=SPIN_CHECK_S)
    finally:
        executor.remove_node(node)


def usage(prog: str = 'plane_validation_node', about: str = '') -> str:
    """The --help of the node started as ``prog``: how to start it, ``about`` it (a line or none), its topics and its
    parameters (from the parameter tables)."""
    lines = [f'usage: {prog} [--ros-args [-p NAME:=VALUE ...] [--params-file FILE] '
             '[-r cloud:=TOPIC]]', '', *([about] if about else []),
             'Subscribes to sensor_msgs/PointCloud2 on "cloud"; publishes '
             + ', '.join(f'~/{key}' for key in list(OUTPUTS)[:-1]) + ' and /diagnostics.',
             'config/params.yaml (installed in share/plane_validation/config) lists every parameter with its '
             'default. Parameters:']
    for spec in (*PARAMETERS.values(), *NODE_PARAMETERS.values()):
        allowed = f'; {spec.allowed}' if spec.allowed else ''
        lines.append(f'  {spec.name} (default {spec.default}{allowed}): {spec.description}')
    return '\n'.join(lines)


def _warm_first() -> tuple[bool, Warmup]:
    """Before rclpy starts, tell whether the kernel cache is cold (:func:`~..core.kernels.warm_probe`) and if so
    compile every kernel: the node appears on the graph ready to answer. SIGINT, SIGTERM and SIGHUP are held while
    the probe runs (numba's compiler swallows the KeyboardInterrupt a Ctrl-C raises inside it), and end the process
    at once, status 0, during a cold compile (:func:`~..core.interrupts.stop_at_signals`). A warm cache's other
    kernels load in the node (its subscription is being discovered meanwhile). Returns whether such a signal came
    (the node then does not start), and what was done."""
    caught: list[int] = []
    held = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    previous = {sig: signal.signal(sig, lambda signum, _frame: caught.append(signum)) for sig in held}
    try:
        done = warm_probe()
        if done.compiled:  # minutes of compiling before the node exists: a signal ends it at once, quietly
            # not one the node was started ignoring (nohup); at once for one held while the first kernels compiled
            stop_at_signals(lambda _signum: 0, 'plane_validation_node: stopped while compiling the kernels',
                            unignored(previous), caught)
            gc.enable()  # compiling makes garbage cycles (numba's IR): collected as usual
            done = warm_kernels(rclpy.logging.get_logger('plane_validation'), done)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return bool(caught), done


def _collect_from_now() -> None:
    """Turn the garbage collector back on where the ``plane_validation_node`` entry point (``ros.main``) turned it
    off for the start, with every object so far frozen (``gc.freeze``): the modules, kernels and node live as long as
    the process, and a full collection through them took 0.05-0.3 s of the start each time (three before the first
    answer) and would stall a frame later. They make almost no garbage cycles (about a thousand objects)."""
    if not gc.isenabled():
        gc.freeze()
        gc.enable()


def _end_signal_handling() -> None:
    """End rclpy's signal thread (joined) and ignore SIGINT, SIGTERM and SIGHUP from now on. That thread triggers
    every executor's signal guard condition without a lock: an executor freed on its way out of spin while a signal
    was still being handled had its guard condition triggered after the free, a segfault at shutdown (seen about once
    in 40 Ctrl-Cs during a parallel sweep on a loaded machine). Ending already, a late signal must not cut the
    clean-up short."""
    uninstall_signal_handlers()
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_IGN)


def _shutdown() -> None:
    """``rclpy.try_shutdown()``, quiet when a signal's shutdown wins the race: rclpy shuts its contexts down from
    its own signal thread, which can come between try_shutdown's look at the context and its shutdown (RCLError
    "rcl_shutdown already called")."""
    try:
        rclpy.try_shutdown()
    except RuntimeError:
        if rclpy.ok():
            raise


def _start_problem(exc: Exception) -> str:
    """What rclpy.init's failure says to the user. Its UnknownROSArgsError says only the arguments it did not take
    ("['tolerance:=0.01']", for a -p left out), not that they are no ROS arguments nor what those look like."""
    if isinstance(exc, _rclpy.UnknownROSArgsError):
        return (f'not ROS arguments after --ros-args: {exc} (a parameter is -p NAME:=VALUE, a remapping '
                '-r FROM:=TO, a parameters file --params-file FILE; --help lists the parameters)')
    return str(exc)


def main(args: list[str] | None = None, node_class: type | None = None, prog: str = 'plane_validation_node') -> int:
    """Start ``node_class`` (default :class:`PlaneValidationNode`) and serve it until a signal or shutdown."""
    node_class = node_class or PlaneValidationNode
    own = list(sys.argv[1:] if args is None else args)
    if '--ros-args' in own:  # the node's own arguments: those before it and after a '--' that ends the ROS ones
        ros = own[own.index('--ros-args') + 1:]
        own = own[:own.index('--ros-args')] + (ros[ros.index('--') + 1:] if '--' in ros else [])
    if '-h' in own or '--help' in own:  # rclpy would ignore them and start the node
        print(usage(prog, getattr(node_class, 'ABOUT', '')))
        return 0
    stopped, warmup = _warm_first()
    if stopped:
        return 0
    try:
        limit_blas_threads()
        reuse_freed_memory()  # a frame's arrays from the heap, not fresh pages (core/allocator.py)
        rclpy.init(args=args)
        # rclpy shuts down on SIGINT and SIGTERM; SIGHUP (a closed terminal or session) would end the process
        # on the spot, leaving the sweep's worker processes behind: it becomes a SIGTERM. Not try_shutdown() here:
        # this handler runs in the main thread between two bytecodes, maybe inside Context.ok(), whose lock
        # try_shutdown() takes too: the node would wait for itself. Not under nohup: a SIGHUP it was started
        # ignoring stays ignored
        if signal.SIGHUP in unignored():
            signal.signal(signal.SIGHUP, lambda signum, frame: os.kill(os.getpid(), signal.SIGTERM))
    except KeyboardInterrupt:  # Ctrl-C while starting: as quiet as while spinning
        _shutdown()
        return 0
    except Exception as exc:  # malformed --ros-args, a params file that is missing or not YAML
        print(f'{prog}: cannot start: {_start_problem(exc)}', file=sys.stderr)
        return 2
    try:
        node = node_class(warmup=warmup)
        _collect_from_now()
    except KeyboardInterrupt:  # Ctrl-C while starting: as quiet as while spinning
        _shutdown()
        return 0
    except Exception as exc:  # invalid parameters (range, type, consistency): say which and exit
        if not rclpy.ok():  # a signal shut rclpy down while kernels missing from the cache compiled (numba's compiler
            return 0        # turns the KeyboardInterrupt into another error): as quiet as Ctrl-C
        print(f'{prog}: cannot start: {exc}', file=sys.stderr)
        _shutdown()
        return 2
    executor = None  # held until rclpy's signal thread has ended (_end_signal_handling)
    try:
        if node.context.ok():  # else a SIGTERM came while the kernels loaded (an executor on it would not start)
            executor = SingleThreadedExecutor(context=node.context)
            spin(node, executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:  # rclpy's RCLError "context is not valid": a signal shut it down as spin began
        if rclpy.ok():
            raise
    finally:
        _end_signal_handling()
        node.destroy_node()
        _shutdown()
        stop_workers()  # whichever signal ended the node: its sweep's worker processes end with it
        if executor is not None:
            executor.shutdown(timeout_sec=0)
    return 0


if __name__ == '__main__':
    sys.exit(main())
