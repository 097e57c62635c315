"""rclpy's ``ActionClient``, with each request registered before its response can be handled.

rclpy 7.1's ``send_goal_async`` (and its cancel and result requests) sends the
request, then registers its sequence number. An executor thread handling the
response in between finds no request of that number, logs "Ignoring unexpected
goal response. There may be more than one action server ..." and drops it: the
future never completes (ros2/rclpy#1123; fixed upstream by ros2/rclpy#1308 and
its backports, after the 7.1.6 we pin). A caller sending from its own thread
while an executor spins the client's node meets it when the server answers
before the sender's bookkeeping is done, which a fast server on the same host
does. Here a request
is sent and registered under one lock, which the handling of responses waits for.
"""
from __future__ import annotations

import threading

from rclpy import action


class ActionClient(action.ActionClient):
    """``rclpy.action.ActionClient`` whose requests are registered before their responses are handled."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._sending = threading.Lock()

    def send_goal_async(self, *args, **kwargs):
        with self._sending:
            return super().send_goal_async(*args, **kwargs)

    def _cancel_goal_async(self, goal_handle):
        with self._sending:
            return super()._cancel_goal_async(goal_handle)

    def _get_result_async(self, goal_handle):
        with self._sending:
            return super()._get_result_async(goal_handle)

    async def execute(self, taken_data):
        with self._sending:  # a request being sent now is registered before its response is looked up
            pass
        return await super().execute(taken_data)
