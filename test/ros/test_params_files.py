"""Each package's config/<node>.yaml: every declared parameter at its default, and each node starts from its file.

The files are written by devtools/make_params_files.py from the nodes' own
parameter tables; the first test fails when a node's parameters change and
the files are not regenerated. The nodes run as real processes and report
their values over the parameter services.
"""
import copy
import json
import sys
import time
from pathlib import Path

import pytest
import yaml
from identification.recordings import TABLE1, record, run_identify, write_csv

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / 'devtools'))
import make_params_files  # noqa: E402

#: A few values each node gets from a changed copy of its file (the rest stay at the defaults).
CHANGES = {'planner': {'L1': 0.5, 'max_solve_time': 2.0, 'method': 'zv', 'robust_parameters': ['L1', 'L2'],
                       'solver_processes': 1},
           'streamer': {'network': {'delay': 0.001, 'seed': 7}, 'start_tolerance': 2e-6},
           'sim': {'L2': 0.4, 'noise': 0.001, 'c1': 0.002}}


def flatten(tree: dict, prefix: str = '') -> dict:
    out = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            out.update(flatten(value, f'{prefix}{key}.'))
        else:
            out[f'{prefix}{key}'] = value
    return out


@pytest.mark.parametrize('stem, node, executable, table', make_params_files.nodes())
def test_the_files_hold_every_parameter_at_its_default(stem, node, executable, table):
    path = make_params_files.config_path(stem, executable)
    assert path.read_text() == make_params_files.render(node, executable, table), \
        f'{path} is stale: run .venv/bin/python devtools/make_params_files.py'
    values = flatten(yaml.safe_load(path.read_text())[f'/**/{node}']['ros__parameters'])
    for name, (default, description, _) in table.items():
        if isinstance(default, list) and not default:
            assert f'# {name.rpartition(".")[2]}: []' in path.read_text()
        else:
            assert values[name] == default, name
        assert description.split()[0] in path.read_text()


@pytest.mark.parametrize('stem, node, executable, table', make_params_files.nodes())
def test_each_node_starts_from_its_file_and_reports_the_files_values(ros_domain, tmp_path, stem, node,
                                                                     executable, table):
    import rclpy
    from rclpy.parameter_client import AsyncParameterClient

    from crane_planner.tools.processes import NodeGroup
    document = yaml.safe_load(make_params_files.config_path(stem, executable).read_text())
    params = document[f'/**/{node}']['ros__parameters']
    changed = copy.deepcopy(params)
    for key, value in CHANGES[stem].items():
        if isinstance(value, dict):
            changed[key].update(value)
        else:
            changed[key] = value
    path = tmp_path / f'{stem}.yaml'
    path.write_text(yaml.safe_dump({f'/**/{node}': {'ros__parameters': changed}}))
    expected = flatten(changed)
    package, name = executable.split()
    rclpy.init()
    probe = rclpy.create_node(f'probe_{stem}', namespace='/files')
    try:
        with NodeGroup(ros_domain, tmp_path / 'logs') as nodes:
            nodes.start(package, name, namespace='/files', params_file=path)
            client = AsyncParameterClient(probe, node)
            deadline = time.monotonic() + 180.0
            while not client.wait_for_services(0.2):
                nodes.check_alive()
                assert time.monotonic() < deadline, f'{node} parameter services never appeared'
            # a service found in the graph may not have matched its reply writer yet (a loaded host):
            # a request whose answer does not come is asked again
            while True:
                future = client.get_parameters(list(expected))
                rclpy.spin_until_future_complete(probe, future, timeout_sec=5.0)
                if future.done():
                    break
                future.cancel()
                nodes.check_alive()
                assert time.monotonic() < deadline, f'{node} never answered get_parameters'
            reported = future.result().values
    finally:
        probe.destroy_node()
        rclpy.try_shutdown()
    from rclpy.parameter import parameter_value_to_python
    for (name, value), got in zip(expected.items(), reported):
        assert parameter_value_to_python(got) == value, name


def test_the_params_file_sets_the_planner_nodes_model(ros_domain, tmp_path):
    """The planner started with identify's --params-out file (namespaced) reports the estimates as its parameters."""
    import rclpy
    from rclpy.parameter_client import AsyncParameterClient

    from crane_planner.tools.processes import PLANNER, NodeGroup
    truth = TABLE1.replace(L1=0.55, L2=0.3, tau=0.02, c1=0.003)
    write_csv(tmp_path / 'move.csv', record(truth, reference=True))
    out = run_identify('--csv', str(tmp_path / 'move.csv'), '--json', '--params-out', str(tmp_path / 'crane.yaml'))
    estimates = json.loads(out.stdout)
    rclpy.init()
    node = rclpy.create_node('params_file_check', namespace='/cell_7')
    try:
        with NodeGroup(ros_domain, tmp_path / 'logs') as nodes:
            nodes.start(*PLANNER, namespace='/cell_7', params={'solver_processes': 1},
                        params_file=tmp_path / 'crane.yaml')
            client = AsyncParameterClient(node, 'crane_planner')
            deadline = time.monotonic() + 180.0
            while not client.wait_for_services(0.2):
                nodes.check_alive()
                assert time.monotonic() < deadline, 'planner parameter services never appeared'
            future = client.get_parameters(['L1', 'L2', 'm1', 'm2', 'c1', 'c2', 'tau'])
            rclpy.spin_until_future_complete(node, future, timeout_sec=180.0)
            values = {name: v.double_value for name, v in zip(['L1', 'L2', 'm1', 'm2', 'c1', 'c2', 'tau'],
                                                               future.result().values)}
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    assert values['L1'] == estimates['L1'] and values['L2'] == estimates['L2']
    assert values['c1'] == estimates['c1'] and values['tau'] == estimates['tau']
    total = TABLE1.m1 + TABLE1.m2
    assert values['m2'] / total == pytest.approx(estimates['mass_ratio'], rel=1e-12)
    assert values['m1'] + values['m2'] == pytest.approx(total, rel=1e-12)
