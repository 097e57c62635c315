"""rclpy's ``ActionServer``, with each new goal's ID formatted as hex instead of by numpy.

rclpy 7.1 formats every new goal's ID (a ``unique_identifier_msgs/UUID``: a
numpy uint8 array) into two debug messages, before and after its goal
callback, whether or not debug messages are logged. numpy's array printing
is slow when the process's caches are cold (a goal every few seconds), and
that comes out of a shaper's handover budget (5 ms from the goal sent to the
reference changed). ``take_data`` (the Waitable API the executor calls) hands
the ID on as a view that formats as its 32 hex digits; its bytes, dtype and
size are the message's, so everything else (the goal handle, the response,
``bytes(goal_id.uuid)``) sees the same ID.
"""
from __future__ import annotations

import numpy as np
from rclpy import action
from unique_identifier_msgs.msg import UUID


class GoalId(np.ndarray):
    """A goal ID's 16 bytes that format (``str.format``, f-strings) as 32 hex digits."""

    def __format__(self, spec: str) -> str:
        return format(bytes(self).hex(), spec)


class ActionServer(action.ActionServer):
    """``rclpy.action.ActionServer`` whose new goals' IDs are ``GoalId`` views (cheap to format)."""

    def take_data(self):
        data = super().take_data()
        if 'goal' in data:
            request = data['goal'][1]
            # checked fields keep the array given (unchecked ones copy it into a plain ndarray)
            request.goal_id = UUID(uuid=np.asarray(request.goal_id.uuid).view(GoalId), check_fields=True)
        return data
