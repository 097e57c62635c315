"""Write each package's config/<node>.yaml from the nodes' declared parameters.

``src/crane_planner/config/planner.yaml``, ``.../streamer.yaml`` and
``src/crane_sim/config/sim.yaml``: every parameter at its default, its
description as a comment, in the ROS 2 parameters-file layout
(``--ros-args --params-file``); the packages install them into
``share/<package>/config``. The node key is ``/**/<node name>``, so a file
applies in any namespace. Run after changing a node's parameters;
test/ros/test_params_files.py checks the files match.

    .venv/bin/python devtools/make_params_files.py          # write them
    .venv/bin/python devtools/make_params_files.py --check  # only compare
"""
import json
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def nodes():
    from crane_msgs_py.messages.names import PLANNER_NODE, SIM_NODE, STREAMER_NODE
    from crane_planner.serving.config import PARAMETERS
    from crane_planner.streaming import config as streamer
    from crane_sim.nodes import sim_node
    return [('planner', PLANNER_NODE, 'crane_planner planner', PARAMETERS),
            ('streamer', STREAMER_NODE, 'crane_planner streamer', streamer.PARAMETERS),
            ('sim', SIM_NODE, 'crane_sim sim', sim_node.PARAMETERS)]


def value_text(value) -> str:
    """A YAML scalar or flow sequence (JSON is valid YAML for these).

    A float always gets a decimal point: YAML 1.1 parsers (PyYAML, and rcl's
    parameter files) read ``1e-06`` as a string, ``1.0e-06`` as a number.
    """
    if isinstance(value, float):
        mantissa, e, exponent = repr(value).partition('e')
        return (mantissa if '.' in mantissa else mantissa + '.0') + e + exponent
    if isinstance(value, list):
        return '[' + ', '.join(value_text(v) for v in value) + ']'
    return json.dumps(value)


def render(node: str, executable: str, table: dict) -> str:
    lines = [f'# {node}: every parameter at its default, with its description.',
             f'#   ros2 run {executable} --ros-args --params-file '
             f'$(ros2 pkg prefix {executable.split()[0]})/share/{executable.split()[0]}/config/{node_file(node)}.yaml',
             '# (outside a ROS install: .venv/bin/<executable> --ros-args --params-file src/<package>/config/...)',
             f'/**/{node}:', '  ros__parameters:']
    tree: dict = {}  # a dotted name's parts nested, in the order the table first names each
    for name, (default, description, _) in table.items():
        *heads, tail = name.split('.')
        level = tree
        for head in heads:
            level = level.setdefault(head, {})
        level[tail] = (default, description)
    lines += _render_level(tree, '    ')
    return '\n'.join(lines) + '\n'


def _render_level(level: dict, indent: str) -> list:
    """One level's parameters, then its groups (each a key with its level below)."""
    lines = []
    for name, entry in level.items():
        if isinstance(entry, dict):
            continue
        default, description = entry
        for line in textwrap.wrap(description, 96 - len(indent)):
            lines.append(f'{indent}# {line}')
        if isinstance(default, list) and not default:
            # an empty list has no element type for the parameters file: left at the node's default
            lines.append(f'{indent}# {name}: []   (empty: the default; give values to set it)')
        else:
            lines.append(f'{indent}{name}: {value_text(default)}')
    for name, entry in level.items():
        if isinstance(entry, dict):
            lines += [f'{indent}{name}:', *_render_level(entry, indent + '  ')]
    return lines


def node_file(node: str) -> str:
    return {'crane_planner': 'planner', 'crane_streamer': 'streamer', 'crane_sim': 'sim'}[node]


def config_path(stem: str, executable: str) -> Path:
    """Where the file of the node ``stem`` lives: its package's config folder."""
    return ROOT / 'src' / executable.split()[0] / 'config' / f'{stem}.yaml'


def main(argv=None) -> int:
    import argparse
    parser = argparse.ArgumentParser(description='Write each node\'s config/<node>.yaml (planner, streamer, sim) '
                                                 'from its declared parameters: defaults and descriptions.')
    parser.add_argument('--check', action='store_true',
                        help='write nothing; exit 1 naming each file that differs from what would be written')
    args = parser.parse_args(argv)
    stale = []
    for stem, node, executable, table in nodes():
        path = config_path(stem, executable)
        text = render(node, executable, table)
        if args.check:
            if not path.exists() or path.read_text() != text:
                stale.append(path)
                print(f'{path} differs from the declared parameters: run devtools/make_params_files.py',
                      file=sys.stderr)
            continue
        path.write_text(text)
        print(f'wrote {path}')
    return 1 if stale else 0


if __name__ == '__main__':
    sys.exit(main())
