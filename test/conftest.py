"""Shared fixtures."""
import os

import pytest


@pytest.fixture(scope='session')
def ros_domain():
    """A private ROS graph for the session: random ROS_DOMAIN_ID, localhost-only discovery.

    Set in this process's environment before rclpy.init, and inherited by the
    node subprocesses, so parallel sessions and other projects never meet.
    Yields the environment.
    """
    from crane_planner.tools.processes import isolated_ros_env
    saved = dict(os.environ)
    env = isolated_ros_env()
    os.environ.clear()
    os.environ.update(env)
    try:
        yield env
    finally:
        os.environ.clear()
        os.environ.update(saved)
