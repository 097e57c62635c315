"""A fake crane for the goal service (serving.service): a fake streamer on a fake clock, the shapers planned
for real and, if given, NVF/RVF by a real planner."""
from types import SimpleNamespace

from crane_planner.planning.dispatch import plan
from crane_planner.planning.plan import PlanError
from crane_planner.serving.config import PARAMETERS, Config
from crane_planner.serving.crane_view import StreamSample
from crane_planner.serving.moves import Move
from crane_planner.serving.service import MoveService
from crane_planner.serving.transitions import Trajectory
from serving.fake_clock import FakeClock

T0 = 40_000_000_000
MS = 1_000_000


class FakePlanner:
    """The shapers as the Planner plans them; no NVF/RVF solver here."""

    def plan(self, method, displacement, duration, params=None, options=None, hoist=None):
        return plan(method, displacement, duration, params, options)

    def variational(self, request):
        raise PlanError('no NVF/RVF solver in this test')


class Log:
    def __init__(self):
        self.lines = []

    def info(self, message):
        self.lines.append(('info', message))

    def warn(self, message):
        self.lines.append(('warn', message))

    def error(self, message):
        self.lines.append(('error', message))


class Crane:
    """The service with a fake streamer: stream_state every 20 ms; a trajectory published starts at its
    stamp's tick, or at the next 1 ms tick if it has none or it has passed (streamed whole from there); one
    published during a motion is a handover (its origin its stamp) unless ``refuse`` says to refuse it; the
    correction it reports is ``correction(ns)``, what a sway feedback adds."""

    def __init__(self, refuse=0, hold=0.0, planner=None, correction=lambda now: 0.0, **parameters):
        self.clock, self.log, self.published, self.refuse = FakeClock(T0), Log(), [], refuse
        self.correction = correction  # (ns -> m) a sway feedback's correction on the reference it reports
        values = {name: default for name, (default, _, _) in PARAMETERS.items()}
        self.config = Config.from_values({**values, 'method': 'zv', **parameters})
        self.service = MoveService(planner or FakePlanner(), lambda: self.config, self.clock, self.publish, self.report,
                                   self.log, sleep=self.clock.sleep, timer=self.clock.timer)
        self.hold, self.current, self.pending, self.next_state = hold, None, None, T0
        self.clock.hooks.append(self.tick)
        self.tick(T0)

    def report(self, values, planned, t0, solved, error=''):
        pass

    def publish(self, trajectory: Trajectory):
        self.published.append((self.clock(), trajectory))
        if self.refuse:
            self.refuse -= 1
            return
        tick = (self.clock() // MS + 1) * MS
        duration = float(trajectory.samples[0].t[-1])
        handover = self.current is not None
        start = max(trajectory.stamp_ns, tick)
        origin = trajectory.stamp_ns if handover or trajectory.stamp_ns >= tick else start
        self.pending = SimpleNamespace(start=start, origin=origin, duration=duration, trajectory=trajectory)

    def tick(self, now):
        if self.pending is not None and now >= self.pending.start:
            self.current, self.pending = self.pending, None
        m = self.current
        if m is not None and now >= m.start + round(m.duration * 1e9):
            self.hold = float(m.trajectory.starts[0] + m.trajectory.samples[0].position[-1])
        if now >= self.next_state:
            self.next_state = now + 20 * MS
            streaming = m is not None and now < m.start + round(m.duration * 1e9)
            self.service.on_stream_state(StreamSample(now, 'streaming' if streaming else 'holding',
                                                      {'cart': self.hold}, m.start if m else 0,
                                                      m.duration if m else 0.0, m.origin if m else 0,
                                                      {'cart': self.correction(now)}))

    def goal(self, key, move, settle=0.2):
        goal = self.service.arrive(key, move, settle)
        self.service.goals.accept(key, f'handle {key}')
        return goal

    def execute(self, goal, move, settle=0.2, canceled=lambda: False):
        feedback = []
        outcome = self.service.execute(goal, move, settle, lambda **f: feedback.append(f), canceled)
        return outcome, feedback

    def at(self, ns, action):
        """``action()`` once the clock reaches ``ns``."""
        def hook(now):
            if now >= ns:
                self.clock.hooks.remove(hook)
                action()
        self.clock.hooks.append(hook)


def move(goal=0.3, duration=2.0, start_ns=0, method='zv'):
    return Move(method, goal=(goal,), duration=duration, start_ns=start_ns)
