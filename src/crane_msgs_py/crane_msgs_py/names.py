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
#: The streamer's reference at its state rate (crane_interfaces/StreamState).
STREAM_STATE_TOPIC = 'stream_state'
#: Absolute, as diagnostic_aggregator and rqt_robot_monitor expect.
DIAGNOSTICS_TOPIC = '/diagnostics'

#: Private services and actions, as the node creating them names them.
PLAN_MOVE_SERVICE = '~/plan_move'        # crane_interfaces/srv/PlanMove: a preview, moves nothing
EXECUTE_MOVE_ACTION = '~/execute_move'   # crane_interfaces/action/ExecuteMove: plan, stream, settle
START_SERVICE = '~/start'
STOP_SERVICE = '~/stop'
RESET_SERVICE = '~/reset'
SETTLE_SERVICE = '~/settle'  # planner: damp the swing measured now (std_srvs/Trigger)
PUSH_SERVICE = '~/push'  # sim: set the load swinging (std_srvs/Trigger), for tests and the demo
CMD_VEL_TOPIC = 'cmd_vel'  # streamer in operator mode: geometry_msgs/Twist

#: The cart's joint in trajectories and joint states; the swing angles follow it.
CART_JOINT = 'cart'
SIM_JOINTS = (CART_JOINT, 'theta1', 'theta2')
#: The hoist's joint: its position is the upper cable's length L1 (m; larger = load lower).
HOIST_JOINT = 'hoist'
#: The actuated joints a setup may have, in their order in every array (contract "Joints and hoisting").
ACTUATED_JOINTS = (CART_JOINT, HOIST_JOINT)


def check_joints(joints, name: str = 'joints') -> tuple:
    """``joints`` as a tuple if it is the cart, optionally with the hoist, in ``ACTUATED_JOINTS`` order;
    else ParameterError naming ``name``."""
    from .params import ParameterError
    joints = tuple(joints)
    if joints not in ((CART_JOINT,), ACTUATED_JOINTS):
        raise ParameterError(f'{name} must be [cart] or [cart, hoist], got {list(joints)}')
    return joints

#: Frame of returned trajectories and markers.
DEFAULT_FRAME_ID = 'crane_base'

#: ``output`` values of the streamer: a one-point JointTrajectory or a Float64MultiArray [position].
OUTPUT_JOINT_TRAJECTORY = 'joint_trajectory'
OUTPUT_FLOAT64_ARRAY = 'float64_array'
OUTPUTS = (OUTPUT_JOINT_TRAJECTORY, OUTPUT_FLOAT64_ARRAY)


def service_of(node_name: str, private_name: str) -> str:
    """The name another node uses for ``node_name``'s private service ``~/x``.

    Relative, so it resolves in the caller's namespace: ``service_of('crane_planner',
    PLAN_MOVE_SERVICE)`` is ``crane_planner/plan_move`` (actions are named the same way).
    """
    if not private_name.startswith('~/'):
        raise ValueError(f'not a private name: {private_name!r}')
    return f'{node_name}/{private_name[2:]}'
