"""What the planner knows of the crane: the streamer's newest ``stream_state``, the newest ``joint_states``
and the motion it last sent, as records.

``stream_state`` (50 Hz) says where the streamer holds each joint, whether
it streams or is in operator mode, and the current motion's start and
origin; ``joint_states`` (50 Hz) give the swing a handover is predicted
from. The view tells whether the streamer was heard recently, where it
holds the axes, and whether a motion is in progress (``in_motion``), whose
origin a motion sent as soon as possible learns from ``stream_state``
(``origin``). Pure Python, no ROS import: the node hands in the messages'
values.
"""
from __future__ import annotations

import dataclasses
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Callable

from crane_msgs_py.crane.axes import AXES, CART

from ..planning.signals import Swing
from .goals import Goals
from .timeline import Timeline
from .transitions import JointReading, Measurement, Running

#: How fresh (s) the last ``stream_state`` must be for the streamer to count as heard.
STREAM_FRESH = 1.0
#: How long (s) a goal waits for a streamer not heard: one just (re)started is matched by discovery within a
#: participant announcement period of Fast DDS (3 s) if its first announcements were missed.
DISCOVERY_WAIT = 3.5
#: ``StreamState.state`` values (``crane_msgs_py.messages.conversions``): streaming a motion, following cmd_vel,
#: at rest.
STREAMING, OPERATOR, HOLDING = 'streaming', 'operator', 'holding'
#: A motion the streamer says it does not stream this long (ns) after its origin was refused.
REFUSED_AFTER_NS = 100_000_000


@dataclass(frozen=True)
class StreamSample:
    """One ``stream_state`` (the fields ``conversions.read_stream_state`` reads, in its order)."""

    stamp_ns: int
    state: str  # streaming, holding or operator
    hold: dict  # joint -> position (m)
    motion_start_ns: int  # the current (or last) motion's first tick
    motion_duration: float
    motion_origin_ns: int  # when its first knot is streamed
    correction: dict = field(default_factory=dict)  # joint -> the sway feedback's correction (m), not in hold
    reason: str = ''  # why the streamer itself stopped or refused the newest motion (its runway guard)

    @property
    def operator(self) -> bool:
        return self.state == OPERATOR


def joint_sample(stamp_ns: int, position, velocity, names=(), joint_positions=(), joint_velocities=()) \
        -> Measurement:
    """A ``joint_states`` message as a ``Measurement``: the sim's joints' ``position`` and ``velocity`` (cart,
    theta1, theta2; a NaN velocity as 0), and each other axis among ``names`` (its ``sim_joint``) from
    ``joint_positions`` and ``joint_velocities`` (the hoist's: its rope length and rate); with ``phi1`` and
    ``phi2`` among them (a crane with a bridge), the spatial ``Swing`` (phi too). ValueError if a position it
    takes is not finite: a message that measures nothing (a camera that has lost the load sends NaN angles)."""
    def finite(value, name: str) -> float:
        value = float(value)
        if not math.isfinite(value):
            raise ValueError(f'joint_states: {name} is {value}, not a measurement')
        return value

    velocity = [0.0 if math.isnan(v) else float(v) for v in velocity]
    joints = {CART.name: JointReading(finite(position[0], CART.name), velocity[0])}
    names = list(names)

    def reading(k: int) -> tuple[float, float]:
        rate = float(joint_velocities[k]) if len(joint_velocities) > k else 0.0
        return finite(joint_positions[k], names[k]), 0.0 if math.isnan(rate) else rate

    for other in AXES[1:]:
        if other.sim_joint in names:
            joints[other.name] = JointReading(*reading(names.index(other.sim_joint)))
    swing = Swing(finite(position[1], 'theta1'), finite(position[2], 'theta2'), velocity[1], velocity[2])
    if 'phi1' in names and 'phi2' in names:
        (phi1, dphi1), (phi2, dphi2) = (reading(names.index(n)) for n in ('phi1', 'phi2'))
        swing = dataclasses.replace(swing, phi1=phi1, phi2=phi2, dphi1=dphi1, dphi2=dphi2)
    return Measurement(stamp_ns, joints, swing)


class CraneView:
    """The newest ``stream_state`` and ``joint_states`` and the motion last sent (kept by ``timeline``).

    Args:
        clock: ROS time now (ns).
        goals: the book of goals (whose execution learns a motion's origin).
        timeline: the axes' timeline (the motion last sent).
        fresh: how recent (s) a ``stream_state`` must be to count as heard.
        sleep, monotonic: how ``origin`` waits.
    """

    def __init__(self, clock: Callable[[], int], goals: Goals, timeline: Timeline, fresh: float = STREAM_FRESH,
                 sleep: Callable[[float], None] = time.sleep, monotonic: Callable[[], float] = time.monotonic):
        self._clock, self._goals, self._timeline, self._fresh = clock, goals, timeline, fresh
        self._sleep, self._monotonic = sleep, monotonic
        self._lock = threading.Lock()
        self._stream: tuple[int, StreamSample] | None = None  # (received ns, sample)
        self._measured: Measurement | None = None

    # -- inputs --------------------------------------------------------------------------

    def on_stream_state(self, sample: StreamSample) -> None:
        with self._lock:
            self._stream = (self._clock(), sample)

    def on_joint_state(self, measured: Measurement) -> None:
        with self._lock:
            self._measured = measured

    # -- what it says --------------------------------------------------------------------

    @property
    def measured(self) -> Measurement | None:
        """The newest ``joint_states`` (what a handover predicts the swing from)."""
        with self._lock:
            return self._measured

    def age(self) -> float | None:
        """Seconds since the newest ``stream_state`` arrived (None: never)."""
        with self._lock:
            stream = self._stream
        return None if stream is None else (self._clock() - stream[0]) * 1e-9

    def heard(self) -> StreamSample | None:
        """The streamer's newest state, if it was heard within ``fresh`` s."""
        with self._lock:
            stream = self._stream
        if stream is None or self._clock() - stream[0] > self._fresh * 1e9:
            return None
        return stream[1]

    def wait_heard(self, timeout: float) -> StreamSample | None:
        """The streamer's newest state, waiting up to ``timeout`` s for one if none was heard within ``fresh``:
        a streamer just (re)started is found once discovery has matched it, which takes a moment."""
        deadline = self._monotonic() + timeout
        heard = self.heard()
        while heard is None and self._monotonic() < deadline:
            self._sleep(0.02)
            heard = self.heard()
        return heard

    def hold(self) -> dict | None:
        """Where the streamer holds each joint (m), if it was heard within ``fresh`` s."""
        heard = self.heard()
        return None if heard is None else heard.hold

    def origin(self, running: Running, wait: float = 0.2) -> bool:
        """Whether ``running``'s origin is known: the streamer's once stream_state tells it (a trajectory that
        reached it after its stamp starts at its next tick), until then the stamp it was sent with; one sent
        as soon as possible (no stamp) waits up to ``wait`` s for the streamer's."""
        deadline = self._monotonic() + wait
        while not running.confirmed:
            origin = self._goals.origin_of(running)
            if origin is not None:
                running.origin_ns, running.confirmed = origin, True
                break
            if running.origin_ns or self._monotonic() > deadline:
                return running.origin_ns != 0
            self._sleep(0.002)
        return True

    def foreign_motion(self) -> float | None:
        """Seconds left (> 0) of a motion the streamer streams that this planner never sent (it started during
        it, e.g. restarted mid-move), else None. The streamer has its knots, this planner does not: it cannot
        hand it over, so it lets it finish and takes the crane's state from stream_state after it."""
        heard = self.heard()
        if heard is None or heard.state != STREAMING or self._timeline.sent_any():
            return None
        left = (heard.motion_start_ns + round(heard.motion_duration * 1e9) - self._clock()) * 1e-9
        return left if left > 0.0 else None

    def in_motion(self) -> Running | None:
        """The motion the streamer is streaming (or about to), if any: the last one sent, unless it has
        ended, or the streamer says it holds though the motion should have started ``REFUSED_AFTER_NS`` ago
        (refused)."""
        running = self._timeline.running
        if running is None:
            return None
        # one sent to start as soon as possible (or late) has started once its goal's stream_state says so
        if running.origin_ns == 0 and not self.origin(running, wait=0.0) and self._goals.owner(running) is None:
            return None  # its goal ended before the streamer started it: nothing is in motion
        if running.origin_ns and self._clock() >= running.end_ns:
            return None
        heard = self.heard()
        if heard is not None and heard.state != STREAMING and running.origin_ns and \
                heard.stamp_ns > running.origin_ns + REFUSED_AFTER_NS:
            return None
        return running
