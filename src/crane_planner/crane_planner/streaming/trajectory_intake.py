"""Whether the streamer takes a trajectory at all, before its motion rules (``reference_stream``) look at it.

Pure Python, no ROS import.
"""
from __future__ import annotations


def trajectory_refusal(published_ns: int, created_ns: int, operator: bool, stopping: bool) -> str | None:
    """Why a trajectory published at ``published_ns`` (ROS time) is refused by a streamer created at
    ``created_ns`` in its present mode, or None: a latched plan from before the streamer started is never
    replayed (it would move the crane on its own), operator mode follows ``cmd_vel`` only, and a ``~/stop``
    under way takes nothing new."""
    if published_ns < created_ns:
        return 'published before this streamer started (a latched old plan is not replayed)'
    if operator:
        return 'the streamer is in operator mode (it follows cmd_vel); set mode to trajectory at rest to stream ' \
               'trajectories'
    if stopping:
        return 'the streamer is stopping (~/stop)'
    return None
