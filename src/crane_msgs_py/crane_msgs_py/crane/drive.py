"""The states of an axis's drive as it reports them (``crane_interfaces/AxisStatus``'s ``state``).

A drive fed cyclic setpoints that stops getting them runs its fault
reaction (it brakes to rest, then holds); whoever drives or watches the axes
(the simulator's axis controller, the planner following a goal, the
streamer) reads the same states, so they are named here once. Which changes
between them are legal is the controller's own rule
(``crane_sim.axis_controller.TRANSITIONS``). Pure Python, no ROS import.
"""
from __future__ import annotations

import enum


class AxisState(enum.Enum):
    """A drive's state; the values are ``crane_interfaces/AxisStatus``'s ``state`` strings."""

    IDLE = 'idle'
    TRACKING = 'tracking'
    FAULT_STOPPING = 'fault_stopping'
    FAULT_HOLD = 'fault_hold'


#: The states of a fault reaction.
FAULT_STATES = frozenset({AxisState.FAULT_STOPPING, AxisState.FAULT_HOLD})
#: The same as ``AxisStatus.state`` strings, as they arrive in a message.
FAULT_STATE_VALUES = frozenset(state.value for state in FAULT_STATES)
