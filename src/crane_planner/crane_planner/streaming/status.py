"""The streamer's status on ``/diagnostics``: its state, level and message from what the node knows.

Pure Python, no ROS import: the levels are ``diagnostic_msgs/DiagnosticStatus``'s numbers
(``crane_msgs_py.runtime.diagnostics`` has them from the message, and a test checks they agree).
"""
from __future__ import annotations

from dataclasses import dataclass

from .start_position import Phase, StartPosition

#: ``diagnostic_msgs/DiagnosticStatus`` levels.
OK, WARN, ERROR = 0, 1, 2


@dataclass(frozen=True)
class StreamStatus:
    """What the streamer reports once a second: ``state`` (streaming, holding, operator ..., stopped, waiting
    ...), the level and the message."""

    state: str
    level: int
    message: str


def stream_status(running: bool, moving: bool, operator: bool, start: StartPosition, loop_error: str | None,
                  stop_planner: str, skipped: int, rate_hz: float) -> StreamStatus:
    """The status: the loop's error first; a start waiting for the axes' position (nothing is streamed
    meanwhile) and a stop planner that is not ready (a ~/stop during a motion would fall back to the axes'
    braking ramp, which swings) are warnings, as are skipped ticks."""
    if running:
        state = ('operator, ' if operator else '') + ('streaming' if moving else 'holding')
    elif start.phase is Phase.WAITING:
        state = f'waiting for {start.waiting_for}: nothing is streamed before the hold position is known'
    else:
        state = 'stopped'
    unstoppable = stop_planner not in ('ready', 'starting')
    if loop_error:
        return StreamStatus(state, ERROR, f'the loop stopped: {loop_error}')
    message = f'{state} at {rate_hz:.1f} Hz' if running else state
    if unstoppable:
        message += f'; no stop without swing: the stop planner process is not ready ({stop_planner})'
    warn = skipped or unstoppable or start.phase is Phase.WAITING
    return StreamStatus(state, WARN if warn else OK, message)
