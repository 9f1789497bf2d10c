"""
The rclpy session of the node's processes: ``awp_node`` and its ``~/evaluate`` worker.

:func:`run_node` selects the Fast DDS profile the input queues need
(:func:`~awp_ros.node.dds.use_deep_queues`), initialises rclpy, builds the node, spins it
and, however that ends, destroys the node and shuts rclpy down, so that each process's
``main`` states only what it builds and how it spins.
"""

from __future__ import annotations

from collections.abc import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node

from awp_ros.node.dds import use_deep_queues

__all__ = ['run_node']


def run_node(argv: list[str], build: Callable[[], Node], spin: Callable[[Node], int]) -> int:
    """
    Run one node in this process and return the exit code.

    :param argv: the command line with its ROS arguments (``rclpy.init(args=argv)``).
    :param build: returns the node (after rclpy.init).
    :param spin: spins it until shutdown; returns the exit code (0 after Ctrl-C or an
        external shutdown, including one that lands while the executor builds its wait set).
    """
    use_deep_queues()           # before the participant exists (awp_ros.node.dds)
    rclpy.init(args=argv)
    node = None
    try:
        node = build()
        return spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    except _rclpy.RCLError:
        # SIGINT/SIGTERM shut the context down while the executor was building its wait
        # set ("the given context is not valid"): a shutdown, not a failure. With the
        # context still valid the error is real.
        if not rclpy.ok():
            return 0
        raise
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
