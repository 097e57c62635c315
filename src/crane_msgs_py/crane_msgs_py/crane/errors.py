"""Errors shared by the planner and its clients (pure Python, no ROS import)."""
from __future__ import annotations


class PlanError(ValueError):
    """A plan cannot be made; the message says why (bad request, solver status, limit).

    Raised alike by the planner in-process (``crane_planner.planning.Planner``) and by
    ``crane_msgs_py.client.PlannerClient`` with the planner node's reason, so a
    caller catches one exception either way.
    """
