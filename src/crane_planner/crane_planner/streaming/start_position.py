"""Where the streamer starts holding: the axes' measured position, never a number that may be a jump.

A position-controlled axis takes the streamer's first sample as its
setpoint: a hold position that is not where the axis stands is a jump of
the difference. So at start-up and at every ``~/start`` the streamer learns
the hold from ``joint_states`` (``hold_source: joint_states``): the first
sample of every streamed joint received after the request with the axes at
rest (each |velocity| at most ``REST_SPEED``: an axis still braking, by its
drive's fault reaction say, has not yet come to where it will stand). Until
then it streams nothing. ``hold_source: initial_position`` holds the
configured positions (a bench without feedback), and with
``initial_fallback_after`` > 0 a ``joint_states`` source that has said
nothing at all for that long falls back to them, saying so.

``StartPosition`` is that rule as an explicit state machine (``Phase``, the
legal ``TRANSITIONS``); the node feeds it ``joint_states`` and the time and
starts the stream once it is ``KNOWN``. Pure Python, no ROS import.
"""
from __future__ import annotations

import enum
import math
import threading
from dataclasses import dataclass

#: ``hold_source`` values.
HOLD_SOURCES = ('joint_states', 'initial_position')
#: An axis measured moving faster than this (m/s) is not yet where it will stand.
REST_SPEED = 1e-3


class Phase(enum.Enum):
    """Whether the hold position is known."""

    IDLE = 'idle'          # nothing asked (auto_start off, no ~/start yet)
    WAITING = 'waiting'    # asked: waiting for joint_states of every joint at rest
    KNOWN = 'known'        # the hold is known (measured, or the initial positions)


TRANSITIONS = {
    Phase.IDLE: {Phase.WAITING, Phase.KNOWN},
    Phase.WAITING: {Phase.WAITING, Phase.KNOWN, Phase.IDLE},
    Phase.KNOWN: {Phase.KNOWN, Phase.WAITING, Phase.IDLE},  # every start learns the hold again
}


class IllegalPhase(RuntimeError):
    """A transition ``TRANSITIONS`` does not allow."""


@dataclass(frozen=True)
class Hold:
    """A hold position learned: per joint (m, in the streamed joints' order), where it came from
    (``joint_states`` or ``initial_position``) and why, for the log."""

    position: tuple
    source: str
    reason: str = ''


class StartPosition:
    """The streamer's hold position at a start (see the module docstring). Thread-safe.

    Args:
        joints: the streamed joints, in order.
        source: one of ``HOLD_SOURCES``.
        initial: the configured hold per joint (m), for ``initial_position`` and the fallback.
        fallback_after: with ``joint_states``, seconds of silence after which ``initial`` is held (0: never).
    """

    def __init__(self, joints, source: str, initial, fallback_after: float = 0.0):
        if source not in HOLD_SOURCES:
            raise ValueError(f'hold_source must be one of {", ".join(HOLD_SOURCES)}, got {source!r}')
        self.joints, self.source = tuple(joints), source
        self.initial = tuple(float(x) for x in initial)
        if len(self.initial) != len(self.joints):
            raise ValueError(f'{len(self.initial)} initial position(s) for {len(self.joints)} joint(s)')
        self.fallback_after = float(fallback_after)
        self._lock = threading.Lock()
        self._phase = Phase.IDLE
        self._hold: Hold | None = None
        self._asked_ns = 0
        self._moving: str = ''  # why the last joint_states did not give the hold (for the diagnostics)
        self._heard = False  # any joint_states since the request: then the fallback never applies

    @property
    def phase(self) -> Phase:
        return self._phase

    @property
    def hold(self) -> Hold | None:
        """The hold once ``KNOWN``."""
        return self._hold

    @property
    def waiting_for(self) -> str:
        """What a ``WAITING`` start waits for, in words."""
        return self._moving or f'joint_states of {", ".join(self.joints)}'

    def _to(self, phase: Phase) -> None:
        if phase not in TRANSITIONS[self._phase]:
            raise IllegalPhase(f'{self._phase.value} -> {phase.value}')
        self._phase = phase

    def request(self, now_ns: int) -> Hold | None:
        """A start (start-up or ``~/start``): the hold at once with ``initial_position``, else None and the
        next measurement at rest gives it."""
        with self._lock:
            self._hold, self._asked_ns, self._moving, self._heard = None, int(now_ns), '', False
            if self.source == 'initial_position':
                self._to(Phase.KNOWN)
                self._hold = Hold(self.initial, 'initial_position', 'hold_source is initial_position')
                return self._hold
            self._to(Phase.WAITING)
            return None

    def cancel(self) -> None:
        """A ``~/stop`` before the hold was known: nothing is asked any more."""
        with self._lock:
            if self._phase is not Phase.IDLE:
                self._to(Phase.IDLE)

    def on_joint_state(self, names, position, velocity) -> Hold | None:
        """A ``joint_states`` message: the hold, if this is the one a ``WAITING`` start waited for."""
        with self._lock:
            if self._phase is not Phase.WAITING:
                return None
            self._heard = True
            index = {name: i for i, name in enumerate(names)}
            missing = [j for j in self.joints if j not in index]
            if missing:
                self._moving = f'joint_states without {", ".join(missing)}'
                return None
            held = []
            for joint in self.joints:
                p = float(position[index[joint]])
                v = float(velocity[index[joint]]) if len(velocity) > index[joint] else 0.0
                if not (math.isfinite(p) and math.isfinite(v)):
                    self._moving = f'{joint} measured non-finite'
                    return None
                if abs(v) > REST_SPEED:
                    self._moving = f'{joint} to come to rest (measured {v:.3g} m/s)'
                    return None
                held.append(p)
            self._to(Phase.KNOWN)
            self._hold = Hold(tuple(held), 'joint_states', 'measured at rest')
            return self._hold

    def poll(self, now_ns: int) -> Hold | None:
        """The fallback: the initial positions once ``joint_states`` has been silent ``fallback_after`` s since
        the request (a feedback that is heard but moving is waited for: it is where the axes are)."""
        with self._lock:
            if (self._phase is not Phase.WAITING or self._heard or not self.fallback_after > 0.0
                    or now_ns - self._asked_ns <= self.fallback_after * 1e9):
                return None
            self._to(Phase.KNOWN)
            self._hold = Hold(self.initial, 'initial_position',
                              f'no joint_states at rest within {self.fallback_after:g} s '
                              f'(initial_fallback_after)')
            return self._hold
