"""Serving plans: solver pools, worker processes and the pacing of solves that share a process.

``Planner`` is the facade that the CLI and the planner node use. This package
may import ``crane_planner.planning``, never the other way round; no ROS import.
"""


def __getattr__(name: str):
    # the planner (and CasADi with it) loads on first use: the streamer imports serving.stops and must not
    if name == 'Planner':
        from .planner import Planner
        return Planner
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


__all__ = ['Planner']
