"""The middleware settings the crane nodes bring with them.

A service server answers a request only once it has matched the client's
response reader, and discovery matches the two sides one after the other: a
client that has just found the service (``wait_for_service`` true) can send
its request before the server has found the client's reader. rmw_fastrtps
then waits ``max_blocking_time`` of the service's response writer (100 ms by
default) and drops the answer ("failed to send response (timeout): client
will not receive response"); the client waits for ever. On a busy machine
discovery takes longer than that. The nodes' profile gives their service
answers far longer than discovery takes (``fastdds_profiles.xml``: the profile
rmw_fastrtps reads for service response writers only; no topic is affected).

For a graph confined to one host (the tests, ``crane-demo``, a bench crane),
``use_loopback_udp`` runs Fast DDS over loopback UDP only. Its shared-memory
transport, which rmw_fastrtps adds itself under
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` whatever ``FASTDDS_BUILTIN_TRANSPORTS``
says, stalls a sender for hundreds of 1 kHz ticks whenever a participant joins
(eProsima/Fast-DDS#6535), and a participant killed while it opens a port leaves
a segment that makes the next one to open it spin for ever in
``SharedMemGlobal::open_port_internal``.
"""
from __future__ import annotations

import os
from pathlib import Path

#: The Fast DDS XML profiles the nodes load when the user names none.
FASTDDS_PROFILES = Path(__file__).with_name('fastdds_profiles.xml')

#: Fast DDS profiles for a graph on this host over loopback UDP only (``use_loopback_udp``), with the nodes'
#: ``service`` profile.
LOOPBACK_PROFILES = Path(__file__).with_name('fastdds_loopback.xml')

#: The environment variables by which a user gives Fast DDS profiles of their own (Fast DDS 2 and 3).
PROFILE_VARIABLES = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')


def use_node_profiles(environ=os.environ) -> bool:
    """Before ``rclpy.init``: point Fast DDS at ``FASTDDS_PROFILES`` unless the user's environment already
    names a profiles file (then theirs is used, unchanged). Whether the nodes' profile is used."""
    if any(environ.get(name) for name in PROFILE_VARIABLES):
        return False
    environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(FASTDDS_PROFILES)
    return True


def use_loopback_udp(environ=os.environ) -> None:
    """Before ``rclpy.init``, and for the node processes started with ``environ``: discovery and data over
    127.0.0.1 UDP only, no shared memory (``LOOPBACK_PROFILES``), overriding any profiles file named.

    The discovery range must be ``SYSTEM_DEFAULT``: for ``LOCALHOST`` rmw_fastrtps sets the transports
    itself, shared memory first; for ``SYSTEM_DEFAULT`` it leaves them to the profile. The middleware is
    set to rmw_fastrtps (another one would read ``SYSTEM_DEFAULT`` as its own default, the whole subnet).
    Static peers, a discovery server and builtin-transport choices are removed, as they would widen or
    override the profile.
    """
    environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SYSTEM_DEFAULT'
    environ['RMW_IMPLEMENTATION'] = 'rmw_fastrtps_cpp'
    for name in ('ROS_LOCALHOST_ONLY', 'ROS_STATIC_PEERS', 'ROS_DISCOVERY_SERVER', 'ROS_SUPER_CLIENT',
                 'FASTDDS_BUILTIN_TRANSPORTS', *PROFILE_VARIABLES):
        environ.pop(name, None)
    environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(LOOPBACK_PROFILES)
