"""Shared fixtures."""
import pytest


@pytest.fixture(scope='session')
def ros_domain():
    """A private ROS graph for the session: random ROS_DOMAIN_ID, localhost-only discovery.

    Set in this process's environment before rclpy.init, and inherited by the
    node subprocesses, so parallel sessions and other projects never meet.
    Yields the environment.
    """
    from crane_planner.tools.processes import isolated_graph
    with isolated_graph() as env:
        yield env
