"""The tree's rules: only the ROS adapters import ROS; the paper's mathematics imports no serving machinery;
no import circle.

A module may import rclpy, a message/service package or another ROS module
only if it is a node (``<package>/nodes/``), one of the two ROS tools (the
demo and the harness it shares with the tests) or one of ``crane_msgs_py``'s
ROS modules. Everything else (the planning and streaming cores, the
simulator, the CLI, evaluation, figures, processes) runs without ROS.
Imports are read from the source (every ``import``, also inside functions),
not by importing, so a lazy import cannot hide.
"""
import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ('crane_msgs_py', 'crane_sim', 'crane_planner')

#: Modules allowed to import ROS, besides every module under a ``nodes`` subpackage.
ROS_MODULES = {
    'crane_planner.tools.demo', 'crane_planner.tools.feedback_demo', 'crane_planner.tools.harness',
    'crane_planner.tools.record', 'crane_planner.tools.runway_demo', 'crane_planner.tools.teleop',
    'crane_msgs_py.client', 'crane_msgs_py.messages.conversions',
    'crane_msgs_py.runtime.action_client', 'crane_msgs_py.runtime.action_server', 'crane_msgs_py.runtime.diagnostics',
    'crane_msgs_py.runtime.node_parameters', 'crane_msgs_py.runtime.qos', 'crane_msgs_py.runtime.runner',
}
#: ROS distributions' Python packages that are not named *_msgs, *_srvs or *_interfaces.
ROS_PACKAGES = {'rclpy', 'rosidl_runtime_py', 'rosidl_parser', 'rpyutils', 'launch', 'launch_ros',
                'ament_index_python', 'rosbag2_py', 'message_filters', 'tf2_ros'}


def modules() -> dict[str, Path]:
    """Dotted name -> file of every module of the three packages."""
    found = {}
    for pkg in PACKAGES:
        base = ROOT / 'src' / pkg
        for path in sorted((base / pkg).rglob('*.py')):
            parts = path.relative_to(base).with_suffix('').parts
            name = '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)
            found[name] = path
    return found


def allowed_ros(module: str) -> bool:
    return module in ROS_MODULES or '.nodes.' in module


def is_ros(imported: str) -> bool:
    """Whether importing ``imported`` (dotted) brings in ROS."""
    top = imported.split('.')[0]
    if top in ROS_PACKAGES or top.endswith(('_msgs', '_srvs', '_interfaces')):
        return True
    return allowed_ros(imported) and top in PACKAGES


def imports(module: str, path: Path) -> list[tuple[int, str]]:
    """(line, dotted name) of every import in the file, relative ones resolved against ``module``."""
    is_package = path.name == '__init__.py'
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = module.split('.')
                keep = len(parts) - node.level + (1 if is_package else 0)
                base = '.'.join(parts[:keep] + ([node.module] if node.module else []))
            else:
                base = node.module
            # ``from pkg import name`` may name a submodule: check both
            found += [(node.lineno, base)] + [(node.lineno, f'{base}.{a.name}') for a in node.names]
    return found


def violations(found: dict[str, Path]) -> list[str]:
    return [f'{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}:{line}: {module} imports {name}'
            for module, path in found.items() if not allowed_ros(module)
            for line, name in imports(module, path) if is_ros(name)]


def test_only_nodes_ros_tools_and_msgs_adapters_import_ros():
    found = modules()
    assert len(found) > 40 and 'crane_planner.planning.dispatch' in found  # the walk sees the tree
    assert violations(found) == []


def test_every_allowed_ros_module_exists_and_nodes_are_in_nodes():
    found = modules()
    assert ROS_MODULES <= set(found)
    node_files = {m for m, p in found.items() if 'Node)' in p.read_text() and 'class ' in p.read_text()}
    assert node_files and all('.nodes.' in m for m in node_files), node_files


@pytest.mark.parametrize('source, module', [
    ('import rclpy\n', 'crane_planner.planning.fake'),
    ('def f():\n    from nav_msgs.srv import GetPlan\n', 'crane_planner.streaming.fake'),
    ('from crane_msgs_py.client import PlannerClient\n', 'crane_sim.fake'),
    ('from ..tools import harness\n', 'crane_planner.planning.fake'),
    ('from .harness import CraneHarness\n', 'crane_planner.tools.fake'),
])
def test_the_rule_flags_a_ros_import_in_a_core_module(tmp_path, source, module):
    path = tmp_path / 'fake.py'
    path.write_text(source)
    assert len(violations({module: path})) >= 1


def test_the_rule_lets_nodes_and_pure_imports_pass(tmp_path):
    path = tmp_path / 'fake.py'
    path.write_text('import numpy\nfrom crane_msgs_py.crane.params import CraneParams\n'
                    'from ..planning import Planner\n')
    assert violations({'crane_planner.tools.fake': path}) == []
    path.write_text('import rclpy\nfrom nav_msgs.srv import GetPlan\n')
    assert violations({'crane_planner.nodes.fake': path}) == []


#: Rooms of crane_planner the planning core (the paper's mathematics) must never import.
PLANNING_MUST_NOT_IMPORT = ('crane_planner.serving', 'crane_planner.nodes', 'crane_planner.tools',
                            'crane_planner.streaming')


def planning_violations(found: dict[str, Path]) -> list[str]:
    return [f'{path.name}:{line}: {module} imports {name}'
            for module, path in found.items() if module.startswith('crane_planner.planning')
            for line, name in imports(module, path)
            if name.startswith(PLANNING_MUST_NOT_IMPORT) or is_ros(name)]


def import_graph(found: dict[str, Path]) -> dict[str, set[str]]:
    """Module -> the modules of the three packages it imports (lazily too), by dotted name."""
    return {module: {name for _, name in imports(module, path) if name in found and name != module}
            for module, path in found.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every strongly connected component of more than one module (Tarjan), i.e. each import circle."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_planning_core_imports_no_serving_node_tool_or_ros_module():
    found = modules()
    assert 'crane_planner.serving.planner' in found and 'crane_planner.planning.direct' in found
    assert planning_violations(found) == []


def test_no_import_circle_anywhere():
    assert cycles(import_graph(modules())) == []


@pytest.mark.parametrize('source', ['from ..serving.pool import SolverPool\n',
                                    'def f():\n    from crane_planner.serving import Planner\n',
                                    'from ..nodes import planner_node\n'])
def test_the_planning_rule_flags_an_import_of_the_serving_machinery(tmp_path, source):
    path = tmp_path / 'fake.py'
    path.write_text(source)
    assert len(planning_violations({'crane_planner.planning.fake': path})) >= 1


def test_the_circle_check_finds_a_lazy_circle():
    assert cycles({'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}}) == [['a', 'b', 'c']]
    assert cycles({'a': {'b'}, 'b': set()}) == []


def test_the_streamer_node_loads_no_casadi():
    """The 1 kHz streamer never waits on CasADi (nor on the GIL of a CasADi build): its stops are planned in a
    worker process (serving.stops). Imported in a fresh interpreter, its module loads no CasADi."""
    pytest.importorskip('rclpy')
    code = ('import sys\nimport crane_planner.nodes.streamer_node\n'
            'print(sorted(m for m in sys.modules if m.split(".")[0] == "casadi"))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == '[]'


#: What runs on a real crane: these rooms of crane_planner never import the simulator (the offline tools may).
PRODUCTION_ROOMS = ('crane_planner.planning', 'crane_planner.serving', 'crane_planner.streaming',
                    'crane_planner.nodes')


def simulator_violations(found: dict[str, Path]) -> list[str]:
    return [f'{path.name}:{line}: {module} imports {name}'
            for module, path in found.items() if module.startswith(PRODUCTION_ROOMS)
            for line, name in imports(module, path) if name.split('.')[0] == 'crane_sim']


def test_the_production_planner_and_streamer_import_no_simulator():
    assert simulator_violations(modules()) == []


def test_the_simulator_rule_flags_a_lazy_import(tmp_path):
    path = tmp_path / 'fake.py'
    path.write_text('def f():\n    from crane_sim.spatial import SpatialPendulum\n')
    assert len(simulator_violations({'crane_planner.serving.fake': path})) >= 1
    assert simulator_violations({'crane_planner.tools.fake': path}) == []


def test_the_shared_crane_facts_are_pure():
    """What the planner and the simulator share (``crane_msgs_py.crane``) imports neither ROS nor either of them."""
    found = modules()
    shared = {m: p for m, p in found.items() if m.startswith('crane_msgs_py.crane')}
    assert {'crane_msgs_py.crane.axes', 'crane_msgs_py.crane.geometry', 'crane_msgs_py.crane.drive'} <= set(shared)
    assert [f'{m}: {name}' for m, p in shared.items() for _, name in imports(m, p)
            if is_ros(name) or name.split('.')[0] in ('crane_sim', 'crane_planner')] == []


#: The nodes only translate messages and keep time; the serving machinery is small classes, each of one job.
NODE_LINES = 300
SERVING_CLASS_LINES = 250


def test_the_nodes_stay_thin_and_the_serving_classes_small():
    found = modules()
    long_nodes = {m: n for m in ('crane_planner.nodes.planner_node', 'crane_planner.nodes.streamer_node')
                  if (n := len(found[m].read_text().splitlines())) > NODE_LINES}
    large = {f'{m}.{c.name}': c.end_lineno - c.lineno + 1 for m, p in found.items()
             if m.startswith('crane_planner.serving.')
             for c in ast.parse(p.read_text()).body if isinstance(c, ast.ClassDef)
             and c.end_lineno - c.lineno + 1 > SERVING_CLASS_LINES}
    assert long_nodes == {} and large == {}
