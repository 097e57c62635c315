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


@pytest.fixture(scope='module')
def start_crane(ros_domain, tmp_path_factory):
    """Start the planner, streamer and sim executables in a namespace of the private graph:
    ``with start_crane(namespace, **start_crane_nodes_keywords) as driver:`` a ``CraneHarness`` once every
    node is up; at the end every node is checked alive, and whatever happened all are stopped."""
    from contextlib import contextmanager

    @contextmanager
    def start(namespace: str, startup: float = 90.0, **kwargs):
        from crane_planner.tools.harness import CraneHarness, start_crane_nodes
        from crane_planner.tools.processes import NodeGroup
        nodes = NodeGroup(ros_domain, tmp_path_factory.mktemp(namespace.strip('/') + '-node-logs'))
        driver = None
        try:
            start_crane_nodes(nodes, namespace, **kwargs)
            driver = CraneHarness(namespace, nodes)
            driver.wait_until_up(startup)
            yield driver
            nodes.check_alive()  # every node survived the whole module
        finally:
            if driver is not None:
                driver.close()
            nodes.stop(timeout=10.0)

    return start


def pytest_collection_modifyitems(config, items):
    """Mark ``ros`` every test under test/ros/ and every test that needs ``ros_domain`` (directly or
    through another fixture), so ``-m "not ros"`` leaves exactly the tests that run without DDS."""
    for item in items:
        if 'ros_domain' in item.fixturenames or ROS_TESTS in Path(item.fspath).parents:
            item.add_marker(pytest.mark.ros)
