"""The ``main()`` of every node, in the shape of ros2/demos ``demo_nodes_py`` (jazzy)."""

import sys

import rclpy
from rclpy.executors import ExternalShutdownException

from .params import ParameterError


def run(node_class, args=None, name=None):
    """
    Init rclpy, build ``node_class()``, spin until shut down, then clean up.

    A :class:`ParameterError` at start is logged as fatal and ends the process with exit
    code 2, so that a runner can tell a bad configuration from a crash.
    """
    rclpy.init(args=args)
    node = None
    code = 0
    try:
        node = node_class()
        rclpy.spin(node)
    except ParameterError as exc:
        rclpy.logging.get_logger(name or node_class.__name__).fatal(str(exc))
        code = 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    if code:
        sys.exit(code)
