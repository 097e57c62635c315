"""Shared fixtures, and the ``ros`` marker (pytest.ini) on every test that joins a ROS graph."""
from pathlib import Path

import pytest

ROS_TESTS = Path(__file__).resolve().parent / 'ros'


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


def pytest_collection_modifyitems(config, items):
    """Mark ``ros`` every test under test/ros/ and every test that needs ``ros_domain`` (directly or
    through another fixture), so ``-m "not ros"`` leaves exactly the tests that run without DDS."""
    for item in items:
        if 'ros_domain' in item.fixturenames or ROS_TESTS in Path(item.fspath).parents:
            item.add_marker(pytest.mark.ros)
