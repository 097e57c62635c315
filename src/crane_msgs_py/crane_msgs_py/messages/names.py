"""Names of the crane trajectory server's nodes, topics, services and joints (contract).

Topics are relative so that a whole setup runs in one namespace
(``--ros-args -r __ns:=/crane``); services are private to their node
(``~/...``) and reached from another node of the same namespace as
``<node name>/<service>`` (see ``service_of``). Pure Python, no ROS import.
"""
from __future__ import annotations

from crane_msgs_py.crane.axes import AXIS_NAMES, BRIDGE, CART, HOIST, check_axes

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
#: The sim's axis controller: tracking, or its fault reaction to a lost reference stream (crane_interfaces/AxisStatus).
AXIS_STATUS_TOPIC = 'axis_status'
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
#: How an ExecuteMove result that ended aborted only because the load swings over residual_tolerance says so
#: (its residual_swing has the figure): what a client that measures residuals takes as a result, not a refusal.
STILL_SWINGING = 'the load still swings'

#: The actuated joints, named by their axes (``axes.AXES``, the one registry): the cart's, the swing angles
#: the sim publishes after it, the hoist's (its position is the upper cable's length L1; larger = load lower).
CART_JOINT = CART.name
SIM_JOINTS = (CART.sim_joint, 'theta1', 'theta2')
HOIST_JOINT = HOIST.name
BRIDGE_JOINT = BRIDGE.name
#: The actuated joints a setup may have, in their order in every array (contract "Joints and hoisting").
ACTUATED_JOINTS = AXIS_NAMES


def check_joints(joints, name: str = 'joints') -> tuple:
    """``joints`` as a tuple if they are the cart and any of the other axes in ``ACTUATED_JOINTS`` order;
    else ParameterError naming ``name``."""
    return check_axes(joints, name)

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
