"""Serving plans: solver pools, worker processes and the pacing of solves that share a process.

``Planner`` is the facade that the CLI and the planner node use. This package
may import ``crane_planner.planning``, never the other way round; no ROS import.
"""
from .planner import Planner

__all__ = ['Planner']
