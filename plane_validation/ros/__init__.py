"""The ROS layer: the node (:mod:`.node`) and its managed variant (:mod:`.lifecycle_node`), their messages and
bag replay."""
from .. import _entry_point


def main(args: list[str] | None = None) -> int:
    """``plane_validation_node``: :func:`.node.main`, loaded here so that Ctrl-C while rclpy, numpy
    and scipy load stops the node as quietly as Ctrl-C while it spins (exit 0)."""
    run = _entry_point('.node', __name__)
    return 0 if run is None else run(args)


def lifecycle_main(args: list[str] | None = None) -> int:
    """``plane_validation_lifecycle_node``: :func:`.lifecycle_node.main`, loaded as :func:`main` loads the node."""
    run = _entry_point('.lifecycle_node', __name__)
    return 0 if run is None else run(args)
