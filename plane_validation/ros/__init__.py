"""The ROS layer: the node (:mod:`.node`), its messages and bag replay."""
import importlib


def main(args: list[str] | None = None) -> int:
    """``plane_validation_node``: :func:`.node.main`, loaded here so that Ctrl-C while rclpy, numpy
    and scipy load stops the node as quietly as Ctrl-C while it spins (exit 0)."""
    try:
        run = importlib.import_module('.node', __name__).main
    except KeyboardInterrupt:
        return 0
    return run(args)
