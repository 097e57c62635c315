"""Names of the crane trajectory server's nodes, topics, services and joints (contract).

Topics are relative so that a whole setup runs in one namespace
(``--ros-args -r __ns:=/crane``); services are private to their node
(``~/...``) and reached from another node of the same namespace as
``<node name>/<service>`` (see ``service_of``). Pure Python, no ROS import.
"""
from __future__ import annotations

#: Default node names.
PLANNER_NODE = 'crane_planner'
STREAMER_NODE = 'crane_streamer'
SIM_NODE = 'crane_sim'

#: Topics (relative).
TRAJECTORY_TOPIC = 'trajectory'
REFERENCE_TOPIC = 'reference'
JOINT_STATES_TOPIC = 'joint_states'
MARKERS_TOPIC = 'crane_markers'
#: Absolute, as diagnostic_aggregator and rqt_robot_monitor expect.
DIAGNOSTICS_TOPIC = '/diagnostics'

#: Private services, as the node creating them names them.
PLAN_SERVICE = '~/plan'
EXECUTE_SERVICE = '~/execute'
FASTEST_SERVICE = '~/fastest'
EXECUTE_FASTEST_SERVICE = '~/execute_fastest'
#: The planner's service kinds: preview, execute, and both for the shortest duration within the limits.
PLANNER_SERVICES = {'plan': PLAN_SERVICE, 'execute': EXECUTE_SERVICE, 'fastest': FASTEST_SERVICE,
                    'execute_fastest': EXECUTE_FASTEST_SERVICE}
START_SERVICE = '~/start'
STOP_SERVICE = '~/stop'
RESET_SERVICE = '~/reset'

#: The cart's joint in trajectories and joint states; the swing angles follow it.
CART_JOINT = 'cart'
SIM_JOINTS = (CART_JOINT, 'theta1', 'theta2')

#: Frame of returned paths.
DEFAULT_FRAME_ID = 'crane_base'

#: ``output`` values of the streamer: a one-point JointTrajectory or a Float64MultiArray [position].
OUTPUT_JOINT_TRAJECTORY = 'joint_trajectory'
OUTPUT_FLOAT64_ARRAY = 'float64_array'
OUTPUTS = (OUTPUT_JOINT_TRAJECTORY, OUTPUT_FLOAT64_ARRAY)


def plan_service(method: str | None = None) -> str:
    """``~/plan`` (the node's default method) or ``~/plan/<method>``: a preview, moves nothing."""
    return PLAN_SERVICE if method is None else f'{PLAN_SERVICE}/{method}'


def execute_service(method: str | None = None) -> str:
    """``~/execute`` (the node's default method) or ``~/execute/<method>``."""
    return EXECUTE_SERVICE if method is None else f'{EXECUTE_SERVICE}/{method}'


def planner_service(kind: str, method: str | None = None) -> str:
    """``~/<kind>`` or ``~/<kind>/<method>`` for a kind of ``PLANNER_SERVICES``."""
    base = PLANNER_SERVICES[kind]
    return base if method is None else f'{base}/{method}'


def service_of(node_name: str, private_name: str) -> str:
    """The name another node uses for ``node_name``'s private service ``~/x``.

    Relative, so it resolves in the caller's namespace: ``service_of('crane_planner',
    plan_service('rvf'))`` is ``crane_planner/plan/rvf``.
    """
    if not private_name.startswith('~/'):
        raise ValueError(f'not a private name: {private_name!r}')
    return f'{node_name}/{private_name[2:]}'
