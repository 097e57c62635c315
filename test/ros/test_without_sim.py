"""The production nodes need no simulator: the planner and the streamer run where ``crane_sim`` is not installed.

A planner on a real crane is installed without the simulator. Uninstalling it from the shared venv would break
every other test, so the node processes here find, ahead of the venv, a ``crane_sim`` whose import fails as an
absent package's does; the solver processes the planner forks inherit it. The planner answers a preview of
every method family (NVF runs in a solver process) and the streamer streams its reference.
"""
import subprocess
import sys
import time

import pytest

from crane_planner.tools.processes import PLANNER, STREAMER, NodeGroup

NS = '/no_sim'
ABSENT = 'raise ModuleNotFoundError("No module named \'crane_sim\'", name="crane_sim")\n'


@pytest.fixture(scope='module')
def without_sim(ros_domain, tmp_path_factory):
    """The node environment with ``crane_sim`` unimportable."""
    shadow = tmp_path_factory.mktemp('no-crane-sim')
    (shadow / 'crane_sim').mkdir()
    (shadow / 'crane_sim' / '__init__.py').write_text(ABSENT)
    return {**ros_domain, 'PYTHONPATH': str(shadow)}


def test_the_shadow_hides_the_simulator(without_sim):
    """The check can fail: in that environment importing the simulator fails, and the planner's core imports."""
    r = subprocess.run([sys.executable, '-c', 'import crane_sim'], env=without_sim, capture_output=True, text=True)
    assert r.returncode != 0 and "No module named 'crane_sim'" in r.stderr
    r = subprocess.run([sys.executable, '-c', 'import crane_planner.serving.service, crane_planner.streaming.'
                        'reference_stream, crane_planner.nodes.planner_node, crane_planner.nodes.streamer_node'],
                       env=without_sim, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_planner_and_streamer_run_without_the_simulator(without_sim, tmp_path):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import Float64MultiArray

    from crane_msgs_py.client import PlannerClient
    from crane_msgs_py.messages.names import REFERENCE_TOPIC
    from crane_msgs_py.runtime.qos import REFERENCE_QOS
    from crane_msgs_py.runtime.runner import spinning

    with NodeGroup(without_sim, tmp_path) as nodes:
        nodes.start(*PLANNER, namespace=NS)
        nodes.start(*STREAMER, namespace=NS, params={'hold_source': 'initial_position', 'output': 'float64_array'})
        rclpy.init()
        try:
            node = rclpy.create_node('no_sim_client', namespace=NS)
            references = []
            node.create_subscription(Float64MultiArray, REFERENCE_TOPIC, lambda m: references.append(m.data[0]),
                                     REFERENCE_QOS)
            client = PlannerClient(node)
            executor = SingleThreadedExecutor()
            executor.add_node(node)
            with spinning(executor):
                assert client.wait_for_service(90.0), nodes.check_alive() or 'the planner did not come up'
                for method in ('nvf', 'zv'):
                    plan = client.plan(method, 0.0, 0.3, 3.0, timeout=90.0)
                    assert plan.info.method == method and plan.position[-1] == pytest.approx(0.3, abs=1e-9)
                deadline = time.monotonic() + 60.0
                while len(references) < 100 and time.monotonic() < deadline:
                    nodes.check_alive()
                    time.sleep(0.05)
                assert len(references) >= 100 and references[-1] == 0.0  # holding its initial position
            nodes.check_alive()
        finally:
            rclpy.try_shutdown()
