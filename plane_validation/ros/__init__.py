"""The ROS layer: the node (:mod:`.node`) and its managed variant (:mod:`.lifecycle_node`), their messages and
bag replay."""
import gc

from .. import _entry_point


def main(args: list[str] | None = None) -> int:
    """``plane_validation_node``: :func:`.node.main`, loaded here so that Ctrl-C while rclpy, numpy
    and scipy load stops the node as quietly as Ctrl-C while it spins (exit 0). The garbage collector is off until
    the node is built (:func:`.node.main` turns it back on): loading makes no garbage worth its full passes."""
    gc.disable()
    run = _entry_point('.node', __name__)
    return 0 if run is None else run(args)


def lifecycle_main(args: list[str] | None = None) -> int:
    """``plane_validation_lifecycle_node``: :func:`.lifecycle_node.main`, loaded as :func:`main` loads the node."""
    gc.disable()
    run = _entry_point('.lifecycle_node', __name__)
    return 0 if run is None else run(args)
