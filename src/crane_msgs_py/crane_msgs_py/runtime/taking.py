"""Messages taken from a subscription by its owner's own thread, not by an executor.

A 1 kHz topic handed through an rclpy executor's callbacks costs a large part of a core in
Python; a subscription that no executor spins (its node is never added to one), created with
``raw=True``, is read by taking its queued messages' bytes in a loop. The recorder
(``crane-record``) and the simulator's stepping loop read so. No executor may spin the node:
it would take the messages first.
"""
from __future__ import annotations


def take_all(subscription) -> list[tuple[bytes, dict]]:
    """Every message queued on a raw ``subscription``, oldest first: (its serialized bytes, its message info:
    ``received_timestamp`` (ns, the middleware's system clock), ``publication_sequence_number``, ...)."""
    handle, msg_type, taken = subscription.handle, subscription.msg_type, []
    with handle:
        while (message := handle.take_message(msg_type, True)) is not None:
            taken.append(message)
    return taken
