"""run_node: however the spin ends, the exit code says whether it was a failure."""

from __future__ import annotations

import pytest
import rclpy
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

from awp_ros.node.lifecycle import run_node


def _wait_set(context) -> None:
    """Build a wait set on ``context`` as rclpy's executor does in ``spin_once``."""
    with context.handle:
        _rclpy.WaitSet(0, 0, 0, 0, 0, 0, context.handle)


def test_a_shutdown_while_the_executor_builds_its_wait_set_is_a_clean_exit(
        ros_env, monkeypatch):
    # The race seen once in a CI run: SIGINT's handler shuts the context down between the
    # executor's ok() check and its WaitSet(), which raises RCLError ("the given context is
    # not valid"). Here the same call, on a context really shut down.
    for key in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_DOMAIN_ID'):
        monkeypatch.setenv(key, ros_env[key])
    raised = []

    def spin(node) -> int:
        context = node.context
        rclpy.shutdown(context=context)
        try:
            _wait_set(context)
        except _rclpy.RCLError as exc:
            raised.append(exc)
            raise
        return 7

    assert run_node([], lambda: rclpy.create_node('awp_lifecycle_test'), spin) == 0
    assert raised and 'context is not valid' in str(raised[0])


def test_an_rcl_error_with_the_context_valid_is_raised(ros_env, monkeypatch):
    for key in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_DOMAIN_ID'):
        monkeypatch.setenv(key, ros_env[key])

    def spin(node) -> int:
        with node.handle:
            _rclpy.rclpy_resolve_name(node.handle, 'not a valid name!', False, False)
        return 7

    with pytest.raises(_rclpy.RCLError):
        run_node([], lambda: rclpy.create_node('awp_lifecycle_test'), spin)
    assert not rclpy.ok()        # shut down however it ended
