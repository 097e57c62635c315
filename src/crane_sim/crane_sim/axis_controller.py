"""The sim's axis controller: every actuated axis follows the reference stream, and brakes when it is lost.

A drive fed cyclic setpoints (EtherCAT, PROFINET) that stops getting them
runs its fault reaction: a quick stop along a deceleration ramp, then it
holds and reports the fault; it does not jump to whatever setpoint comes
next. The sim's axes do the same. The controller owns each axis's
*reference* (position, velocity, acceleration); the plant's servo (Eq. 6)
follows the reference accelerations it returns, as always. Its states
(``AxisState``, the strings of crane_interfaces/AxisStatus):

- ``IDLE``: no reference yet (start-up, ``~/reset``): the axes rest where the
  plant stands; the first sample is taken wherever it starts.
- ``TRACKING``: the reference is the playout's (``playout.ReferencePlayout``),
  integrated here step by step into the reference's velocity and position.
- ``FAULT_STOPPING``: the stream was lost (the playout had no fresh sample for
  its timeout, or samples went missing mid-motion, ``played``): each axis brakes its reference from its velocity and
  acceleration then to rest along ``crane_msgs_py.crane.braking.Braking`` at
  ``FaultConfig.deceleration`` and ``jerk``. Samples are refused meanwhile.
- ``FAULT_HOLD``: braked to rest, holding. A sample whose position is within
  ``resume_tolerance`` of every axis's held position, at rest (within
  ``STILL`` of the sample offered before it, as a streamer's hold is),
  resumes tracking: a stream that starts where the axes stand. Any other is
  refused and counted; a stream in motion that passes where the axes hold
  too, since taking it would step the reference's velocity.

``TRANSITIONS`` lists the legal changes; any other raises
``IllegalTransition``. Every change is kept in ``changes`` (the node reports
them). Within a step the plant takes a reference acceleration ramping
linearly from ``r0`` to ``r1``; a braking's ramps are chosen so that its
velocity and position at every step's end are the closed form's, so the
plant comes to rest exactly where the reference holds. Positions are in the
plant's frame (where the axes stand), times in seconds of plant time.
Pure Python, no ROS import.
"""
from __future__ import annotations

import enum
import math
from collections import deque
from dataclasses import dataclass
from typing import Callable, Sequence

from crane_msgs_py.crane.braking import Braking
from crane_msgs_py.crane.drive import FAULT_STATES, AxisState
from crane_msgs_py.crane.params import ParameterError, check_positive

from .playout import moved_across_gap

S = AxisState
#: state -> the states it may change to. A reset goes to IDLE from every state; a stream lost always goes
#: through FAULT_STOPPING (of no length if the reference was at rest), so the fault is reported in order.
TRANSITIONS = {
    S.IDLE: frozenset({S.IDLE, S.TRACKING}),
    S.TRACKING: frozenset({S.IDLE, S.FAULT_STOPPING}),
    S.FAULT_STOPPING: frozenset({S.IDLE, S.FAULT_HOLD}),
    S.FAULT_HOLD: frozenset({S.IDLE, S.TRACKING}),
}


class IllegalTransition(RuntimeError):
    """The controller was asked to change to a state its state does not lead to."""


def check_transition(old: AxisState, new: AxisState) -> None:
    """IllegalTransition unless ``TRANSITIONS`` lets ``old`` change to ``new``."""
    if new not in TRANSITIONS[old]:
        raise IllegalTransition(f'the axis controller cannot go from {old.value} to {new.value}')


class Offer(enum.Enum):
    """What to do with a received sample (``AxisController.offer``)."""

    ACCEPT = 'accept'  # tracking: give it to the playouts
    START = 'start'    # a stream starts (first one, or the resume after a fault): reset the playouts, then give it
    REFUSE = 'refuse'  # a fault reaction is on and it is not a stream at rest where the axes stand: drop it


@dataclass(frozen=True)
class FaultConfig:
    """The fault reaction's parameters: ``deceleration`` (m/s^2) and ``jerk`` (m/s^3) of the braking,
    ``resume_tolerance`` (m) of a resuming stream's start, and the playout's ``timeout`` (s) that declares
    the stream lost (for the reports: the playout applies it)."""

    deceleration: float = 0.5
    jerk: float = 5.0
    resume_tolerance: float = 1e-3
    timeout: float = 0.5

    def __post_init__(self):
        for name in ('deceleration', 'jerk', 'resume_tolerance', 'timeout'):
            object.__setattr__(self, name, check_positive(name, getattr(self, name)))


@dataclass(slots=True)
class AxisReference:
    """One axis's reference now (plant frame): position (m), velocity (m/s), acceleration (m/s^2); during a
    fault reaction its ``braking`` and the position it started from (``origin``)."""

    name: str
    position: float
    velocity: float = 0.0
    acceleration: float = 0.0
    braking: Braking | None = None
    origin: float = 0.0

    @property
    def stop(self) -> float:
        """Where the reference comes to rest: the braking's end, or the position now."""
        return self.origin + self.braking.distance if self.braking is not None else self.position

    def rest(self, position: float) -> None:
        """At rest at ``position``, no braking."""
        self.position, self.velocity, self.acceleration, self.braking = float(position), 0.0, 0.0, None


@dataclass(frozen=True)
class Fault:
    """A lost stream: when it was declared lost (``lost_at``, s of plant time), each axis's braking and where
    it started (``origins``, m), and when all were at rest (``stopped_at``, None while braking)."""

    lost_at: float
    brakings: tuple[Braking, ...]
    origins: tuple[float, ...]
    stopped_at: float | None = None
    reason: str = ''  # why it counts as lost, if not the timeout

    @property
    def stops(self) -> tuple[float, ...]:
        """Where each axis comes to rest (m): the held positions."""
        return tuple(o + b.distance for o, b in zip(self.origins, self.brakings))

    @property
    def duration(self) -> float:
        """How long the slowest axis brakes (s)."""
        return max(b.duration for b in self.brakings)


@dataclass(frozen=True)
class Change:
    """A state change at ``time`` (s of plant time)."""

    time: float
    old: AxisState
    new: AxisState


@dataclass(frozen=True)
class Status:
    """What the controller reports: its ``state``, each axis's reference ``positions`` (m: where it holds in
    FAULT_HOLD, where its braking began in FAULT_STOPPING, else where it is now) and a ``message``."""

    state: AxisState
    positions: tuple[float, ...]
    message: str


#: How far (m) a sample held at may be from the one before it, per axis, for the stream to be at rest there
#: (a streamer holding sends the same position every tick; at 1 kHz this is 1 mm/s).
STILL = 1e-6


@dataclass(frozen=True)
class Refusal:
    """A sample refused at ``time`` (s of plant time) in ``state``: how far (m) each axis's position is from
    where that axis holds (or will, while stopping); ``moving``: within ``resume_tolerance`` of it, but not at
    rest there."""

    time: float
    state: AxisState
    offsets: tuple[float, ...]
    moving: bool = False


class AxisController:
    """The axes' references and their fault reaction; one thread (the sim's loop) calls it.

    Args:
        axes: the actuated axes' names, in the order of every array here.
        positions: where each axis stands (plant), at rest: the references start there, IDLE.
        config: the fault reaction's parameters; may be replaced between steps (the next fault uses it).

    Each step: ``offer`` every received sample's positions, then ``step`` (with the playouts' reference
    accelerations while ``state`` is TRACKING). Another thread may read ``state``, ``fault``, ``refused`` and
    ``last_refusal`` (each replaced whole, never edited) and ``status()`` for its reports.
    """

    def __init__(self, axes: Sequence[str], positions: Sequence[float], config: FaultConfig | None = None):
        self.axes = tuple(axes)
        self.config = config or FaultConfig()
        self.state = S.IDLE
        self.references = tuple(AxisReference(name, p) for name, p in zip(self.axes, self._check(positions)))
        self.fault: Fault | None = None
        self.refused = 0  # samples refused during fault reactions, ever
        self.last_refusal: Refusal | None = None
        self.changes: deque[Change] = deque()  # the changes the caller has not taken yet
        self._previous: tuple | None = None  # the last sample played since the state changed (``played``)
        self._gap = ''  # why the stream counts as lost at the next step, if samples went missing mid-motion
        self._offered: tuple | None = None  # the positions last offered during a fault reaction

    def _check(self, positions) -> tuple[float, ...]:
        positions = tuple(float(p) for p in positions)
        if len(positions) != len(self.axes) or not all(map(math.isfinite, positions)):
            raise ParameterError(f'need a finite position per axis ({", ".join(self.axes)}), got {positions}')
        return positions

    def _change(self, new: AxisState, t: float) -> None:
        check_transition(self.state, new)
        self.changes.append(Change(float(t), self.state, new))
        self.state = new
        self._previous, self._gap = None, ''  # a new stream's samples, or none played
        self._offered = None

    # -- what the loop calls ------------------------------------------------------------------

    def reset(self, positions: Sequence[float], t: float) -> None:
        """Back to IDLE (``~/reset``), the references at rest at ``positions`` (where the plant now rests);
        the fault, if any, is cleared."""
        positions = self._check(positions)
        self._change(S.IDLE, t)
        for ref, p in zip(self.references, positions):
            ref.rest(p)
        self.fault = None

    def offer(self, positions: Sequence[float], t: float) -> Offer:
        """What to do with a fresh sample whose positions (m, per axis) are ``positions``, received at plant
        time ``t`` (s)."""
        if self.state is S.TRACKING:
            return Offer.ACCEPT
        if self.state is S.IDLE:  # the first reference: a stream from rest, wherever it starts
            self._change(S.TRACKING, t)
            return Offer.START
        positions = tuple(float(p) for p in positions)
        before, self._offered = self._offered, positions
        offsets = tuple(p - ref.stop for p, ref in zip(positions, self.references))
        moving = False
        if self.state is S.FAULT_HOLD and all(abs(d) <= self.config.resume_tolerance for d in offsets):
            if before is not None and all(abs(p - q) <= STILL for p, q in zip(positions, before)):
                self._change(S.TRACKING, t)  # the references rest where they hold: the new stream starts there
                self.fault = None
                return Offer.START
            if before is None:  # the first sample since the braking: whether it rests there, the next tells
                return Offer.REFUSE
            moving = True
        self.refused += 1
        self.last_refusal = Refusal(float(t), self.state, offsets, moving)
        return Offer.REFUSE

    def played(self, sample: tuple, stamped: bool = True) -> None:
        """A sample the playouts took while tracking (stamp s of plant time, then position and acceleration per
        axis). Samples missing before it while the reference moved (``playout.moved_across_gap``) cannot be
        made up: the stream counts as lost at the next step.

        ``stamped``: whether its stamp is its sender's. An unstamped sample is timed by its arrival
        (``reference_intake``): a gap before it shows a delay, not a loss, and is not judged."""
        if stamped and self._previous is not None and moved_across_gap(self._previous, sample):
            gap = sample[0] - self._previous[0]  # said, so that a log tells a burst lost from a stopped stream
            self._gap = f'samples missing for {gap * 1e3:.0f} ms mid-motion'
        self._previous = sample if stamped else None

    def step(self, t0: float, t1: float, tracked: Sequence[tuple[float, float]] | None = None,
             lost: bool = False) -> list[tuple[float, float]]:
        """Each axis's reference acceleration (m/s^2) at the start and the end of the step [t0, t1] (s of
        plant time), ramping linearly in between, for the plant.

        ``tracked``: the playouts' (r0, r1) per axis, needed while TRACKING; ``lost``: the playouts declared
        the stream lost in this step (their timeout); samples ``played`` after a gap mid-motion lose it too. The
        fault reaction starts at t0 from each reference's velocity and acceleration then.
        """
        h = t1 - t0
        if self.state is S.TRACKING:
            if not (lost or self._gap):
                for ref, (r0, r1) in zip(self.references, tracked):  # the exact integral of the ramp
                    v = ref.velocity
                    ref.position += h * (v + h * (r0 / 3.0 + r1 / 6.0))
                    ref.velocity = v + h * (r0 + r1) / 2.0
                    ref.acceleration = r1
                return list(tracked)
            self._lose(t0, self._gap)
        if self.state is S.FAULT_STOPPING:
            return self._brake(t0, t1)
        return [(0.0, 0.0)] * len(self.references)  # IDLE, FAULT_HOLD: at rest

    def _lose(self, t: float, reason: str = '') -> None:
        config = self.config
        for ref in self.references:
            ref.braking = Braking(ref.velocity, ref.acceleration, config.deceleration, config.jerk)
            ref.origin = ref.position
        self.fault = Fault(float(t), tuple(ref.braking for ref in self.references),
                           tuple(ref.origin for ref in self.references), reason=reason)
        self._change(S.FAULT_STOPPING, t)

    def _brake(self, t0: float, t1: float) -> list[tuple[float, float]]:
        """The braking's step [t0, t1]: the ramp r0 -> r1 whose velocity and position increments are the
        closed form's (a linear ramp integrates to h (r0 + r1) / 2 and h^2 (r0 / 3 + r1 / 6) beyond h v0;
        solved for r0 and r1), so the plant follows the braking exactly at the steps' ends."""
        h, start = t1 - t0, self.fault.lost_at
        out = []
        for ref in self.references:
            braking = ref.braking
            p0, v0, _ = braking.state(max(0.0, t0 - start))
            p1, v1, a1 = braking.state(max(0.0, t1 - start))
            dv, dp = v1 - v0, p1 - p0 - h * v0
            r0 = 6.0 * dp / (h * h) - 2.0 * dv / h
            out.append((r0, 2.0 * dv / h - r0))
            ref.position, ref.velocity, ref.acceleration = ref.origin + p1, v1, a1
        if t1 - start >= self.fault.duration:
            for ref in self.references:
                ref.rest(ref.stop)
            self.fault = Fault(start, self.fault.brakings, self.fault.origins, float(t1), self.fault.reason)
            self._change(S.FAULT_HOLD, t1)
        return out

    # -- what the reports read ----------------------------------------------------------------

    def take_changes(self) -> list[Change]:
        """The changes since the last call, oldest first."""
        taken = []
        while self.changes:
            taken.append(self.changes.popleft())
        return taken

    def status(self, state: AxisState | None = None, clock: Callable[[float], float] = float) -> Status:
        """The status of ``state`` (default: the state now; a change's new state, say), with times in words as
        ``clock`` gives them from plant time (s)."""
        state = self.state if state is None else state
        fault, config = self.fault, self.config  # (read once: the loop may move on meanwhile)
        if state in FAULT_STATES and fault is None:  # resumed or reset since: report that
            state = self.state
        if state not in FAULT_STATES:
            message = ('idle: at rest, waiting for a first reference (taken wherever it starts)' if state is S.IDLE
                       else 'tracking the reference stream')
            return Status(state, tuple(ref.position for ref in self.references), message)
        lost = (f'reference stream lost at {clock(fault.lost_at):.3f} s '
                f'({fault.reason or f"no fresh sample for {config.timeout:g} s"})')
        if state is S.FAULT_STOPPING or fault.stopped_at is None:
            axes = ', '.join(f'{name} from {o:.6g} m at {b.v0:.4g} m/s, {b.a0:.4g} m/s^2 to stop at {s:.6g} m'
                             for name, o, b, s in zip(self.axes, fault.origins, fault.brakings, fault.stops))
            return Status(S.FAULT_STOPPING, fault.origins,
                          f'{lost}: braking at {fault.brakings[0].D:g} m/s^2, jerk {fault.brakings[0].J:g} m/s^3: '
                          f'{axes}')
        axes = ', '.join(f'{name} at {s:.6g} m' for name, s in zip(self.axes, fault.stops))
        return Status(S.FAULT_HOLD, fault.stops,
                      f'{lost}: stopped at {clock(fault.stopped_at):.3f} s, holding {axes}; resumes from a '
                      f'reference at rest within {config.resume_tolerance:g} m of there')
