"""The streamer's ``~/stop``: a stop without swing from whatever streams, then stopped once at rest.

At rest the stream stops at once. In operator mode the command is set to
zero: braked by ruckig and shaped, the operator's stream comes to rest by
itself. During a motion a stop without swing from the motion's state is
planned (by the caller's ``take_over``: ``serving.stops`` in a worker
process) and taken over as the stream's handover while the loop streams on;
if none can be had in time, every axis's jerk-limited braking ramp
(``braking_stop``): never an abrupt hold. Either way the streamer is
``STOPPING`` until its source is at rest, and the loop stops it there
(``streamer.Streamer.tick``). Pure Python, no ROS import.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from .braking_stop import brake
from .reference_stream import position_text
from .stop_trajectory import StopTrajectory
from .streamer import Streamer
from .streamer_state import Mode, State


@dataclass(frozen=True)
class StopAnswer:
    """What a ``~/stop`` did, in words (the service's message), and a warning to log besides, if any."""

    message: str
    warning: str = ''


def request_stop(streamer: Streamer, take_over: Callable[[], StopTrajectory | None], now: Callable[[], int],
                 deceleration: float, jerk: float, cancel_start: Callable[[], None] = lambda: None) -> StopAnswer:
    """A ``~/stop`` of ``streamer`` (see the module docstring). ``take_over()`` plans a motion's stop without
    swing and has the stream accept it (None: the motion ends first; ValueError: none in time); ``now()``: ROS
    time (ns); ``deceleration`` (m/s^2) and ``jerk`` (m/s^3): the braking ramp's; ``cancel_start()``: not
    running, a start waiting for the hold position asks no more."""
    if not streamer.running.is_set():
        cancel_start()
        streamer.cancel()
        return StopAnswer('already stopped')
    if streamer.state is State.STOPPING:
        return StopAnswer('already stopping')
    source = streamer.source
    if streamer.mode is Mode.OPERATOR and not source.at_rest:
        source.stop()
        streamer.stopping()
        return StopAnswer(f'stopping: the command set to zero, braked and shaped (at rest within '
                          f'{source.delay():.3g} s of the braking), then stopped')
    if streamer.mode is Mode.TRAJECTORY and streamer.stream.streaming:
        return _stop_motion(streamer, take_over, now, deceleration, jerk)
    streamer.halt()
    return StopAnswer('stopped')


@dataclass(frozen=True)
class MotionStop:
    """A running motion's stop taken over by the stream: its trajectory (None: the motion ends first, at rest by
    itself), how it stops in words, and a warning to log when it is the braking ramp."""

    stop: StopTrajectory | None
    how: str
    warning: str = ''

    def text(self) -> str:
        if self.stop is None:
            return 'the motion ends before a stop could take over (at rest)'
        return f'{self.how} at {position_text(self.stop.end)} m in {self.stop.duration:.3g} s ({self.stop.method})'


def stop_motion(stream, take_over: Callable[[], StopTrajectory | None], now: Callable[[], int], deceleration: float,
                jerk: float) -> MotionStop:
    """The motion ``stream`` (a ``reference_stream.ReferenceStream``) streams, stopped without swing
    (``take_over``, see ``request_stop``) or, if none can be had in time, along the axes' braking ramp; the
    streamer's state is the caller's (a ``~/stop`` stops streaming after it, the runway guard holds).
    ValueError if nothing is left to brake (the motion ended meanwhile)."""
    try:
        return MotionStop(take_over(), 'without swing')
    except ValueError as exc:
        stop = brake(stream, now, deceleration, jerk)  # (ValueError: nothing to brake)
        how = f'along the axes\' braking ramp (no stop without swing in time: {exc})'
        return MotionStop(stop, how, how)


def _stop_motion(streamer: Streamer, take_over, now, deceleration: float, jerk: float) -> StopAnswer:
    try:
        stopped = stop_motion(streamer.stream, take_over, now, deceleration, jerk)
    except ValueError as again:  # (the motion ended meanwhile: nothing to brake)
        streamer.halt()
        return StopAnswer(f'stopped ({again})')
    streamer.stopping()
    warning = f'~/stop {stopped.warning}' if stopped.warning else ''
    if stopped.stop is None:
        return StopAnswer('stopping: the motion ends before a stop could take over (at rest), then stopped', warning)
    return StopAnswer(f'stopping {stopped.text()}, then stopped', warning)
