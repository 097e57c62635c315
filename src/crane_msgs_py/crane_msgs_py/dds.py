"""The middleware settings the crane nodes bring with them.

A service server answers a request only once it has matched the client's
response reader, and discovery matches the two sides one after the other: a
client that has just found the service (``wait_for_service`` true) can send
its request before the server has found the client's reader. rmw_fastrtps
then waits ``max_blocking_time`` of the service's response writer (100 ms by
default) and drops the answer ("failed to send response (timeout): client
will not receive response"); the client waits for ever. On a busy machine
discovery takes longer than 100 ms. The nodes' profile gives their service
answers 2 s (``fastdds_profiles.xml``: the profile rmw_fastrtps reads for
service response writers only; no topic is affected).
"""
from __future__ import annotations

import os
from pathlib import Path

#: The Fast DDS XML profiles the nodes load when the user names none.
FASTDDS_PROFILES = Path(__file__).with_name('fastdds_profiles.xml')

#: The environment variables by which a user gives Fast DDS profiles of their own (Fast DDS 2 and 3).
PROFILE_VARIABLES = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')


def use_node_profiles(environ=os.environ) -> bool:
    """Before ``rclpy.init``: point Fast DDS at ``FASTDDS_PROFILES`` unless the user's environment already
    names a profiles file (then theirs is used, unchanged). Whether the nodes' profile is used."""
    if any(environ.get(name) for name in PROFILE_VARIABLES):
        return False
    environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(FASTDDS_PROFILES)
    return True
