"""Network impairment of a message stream: delay, jitter, loss, optional reordering.

A pure model with an explicit clock (any monotonic time in seconds), so it
runs the same under the streamer's real-time loop and under a virtual clock
in tests. Per message, in send order:

- lost with probability ``loss``;
- otherwise delayed by ``max(0, delay + X)``, X the jitter drawn from
  ``distribution`` with standard deviation ``jitter``: ``normal`` and
  ``uniform`` are zero-mean (so ``delay`` is the mean delay unless the
  truncation at 0 bites), ``exponential`` is one-sided (``delay`` is the
  minimum, the mean is ``delay + jitter``), as on a queueing link;
- with ``reorder`` false the link is FIFO like a TCP stream: a message never
  overtakes an earlier one, its delivery time is max(own, previous message's);
  with ``reorder`` true messages are delivered in order of their own delivery
  times, so a short delay can overtake a long one.

Draws come from one ``random.Random(seed)``, so a seed reproduces the same
losses and delays for the same sequence of sends. Pure Python, no ROS import.
"""
from __future__ import annotations

import heapq
import itertools
import math
import random
from dataclasses import dataclass

from crane_msgs_py.crane.params import ParameterError, check_choice, check_nonnegative

DISTRIBUTIONS = ('normal', 'uniform', 'exponential')


@dataclass(frozen=True)
class Impairment:
    """Parameters of the impairment (all off by default).

    Attributes:
        delay: fixed delay (s), >= 0.
        jitter: standard deviation of the random delay (s), >= 0.
        distribution: one of DISTRIBUTIONS.
        loss: probability that a message is lost, in [0, 1].
        reorder: let messages overtake each other (False: FIFO delivery).
        seed: seed of the random draws.
    """

    delay: float = 0.0
    jitter: float = 0.0
    distribution: str = 'normal'
    loss: float = 0.0
    reorder: bool = False
    seed: int = 0

    def __post_init__(self):
        object.__setattr__(self, 'delay', check_nonnegative('delay', self.delay))
        object.__setattr__(self, 'jitter', check_nonnegative('jitter', self.jitter))
        loss = check_nonnegative('loss', self.loss)
        if loss > 1.0:
            raise ParameterError(f'loss must be a probability in [0, 1], got {loss}')
        object.__setattr__(self, 'loss', loss)
        check_choice('distribution', self.distribution, DISTRIBUTIONS)
        if int(self.seed) != self.seed:
            raise ParameterError(f'seed must be an integer, got {self.seed!r}')

    @property
    def active(self) -> bool:
        """Whether messages can be anything but delivered at once, in order."""
        return self.delay > 0.0 or self.jitter > 0.0 or self.loss > 0.0

    def values(self) -> dict:
        """Its settings as /diagnostics values, named ``network_<setting>``."""
        return {f'network_{k}': getattr(self, k) for k in ('delay', 'jitter', 'distribution', 'loss', 'reorder')}


class DelayLine:
    """Messages in flight through an impaired link.

    ``send(now, item)`` puts an item on the link, ``deliver(now)`` returns the
    items due by ``now`` in delivery order, ``next_due()`` says when the next
    one is due. Counters: ``sent``, ``lost``, ``delivered``, ``reordered``
    (delivered after a message sent later).
    """

    def __init__(self, impairment: Impairment):
        self.impairment = impairment
        self._rng = random.Random(impairment.seed)
        self._draw = self._jitter_draw(impairment)
        self._heap: list = []  # (delivery time, send sequence, item)
        self._seq = itertools.count()
        self._last_delivery = -math.inf
        self._newest_delivered = -1
        self.sent = self.lost = self.delivered = self.reordered = 0

    def _jitter_draw(self, imp: Impairment):
        rng, s = self._rng, imp.jitter
        if s == 0.0:
            return lambda: 0.0
        if imp.distribution == 'normal':
            return lambda: rng.gauss(0.0, s)
        if imp.distribution == 'uniform':
            half = math.sqrt(3.0) * s  # U(-w, w) has standard deviation w / sqrt(3)
            return lambda: rng.uniform(-half, half)
        return lambda: rng.expovariate(1.0 / s)

    def send(self, now: float, item) -> float | None:
        """Put ``item`` on the link at ``now``; its delivery time, or None if it is lost."""
        self.sent += 1
        seq = next(self._seq)
        imp = self.impairment
        if imp.loss > 0.0 and self._rng.random() < imp.loss:
            self.lost += 1
            return None
        due = now + max(0.0, imp.delay + self._draw())
        if not imp.reorder:
            due = max(due, self._last_delivery)
        self._last_delivery = due
        heapq.heappush(self._heap, (due, seq, item))
        return due

    def next_due(self) -> float | None:
        return self._heap[0][0] if self._heap else None

    def deliver(self, now: float) -> list:
        """Items due by ``now``, earliest first (send order among equal times)."""
        out = []
        heap = self._heap
        while heap and heap[0][0] <= now:
            _, seq, item = heapq.heappop(heap)
            if seq < self._newest_delivered:
                self.reordered += 1
            else:
                self._newest_delivered = seq
            out.append(item)
        self.delivered += len(out)
        return out

    def __len__(self) -> int:
        """Messages in flight."""
        return len(self._heap)


class Link:
    """The link under the impairment of the moment (``use``): items go through a ``DelayLine`` while it is
    active, else straight on (``line`` None). A new impairment takes over at once, the items still in flight
    on the old link delivered first; ``lost`` and ``reordered`` count over every link."""

    def __init__(self):
        self.impairment: Impairment | None = None
        self.line: DelayLine | None = None
        self._counted = (0, 0)  # lost, reordered on the links before the current one

    @property
    def lost(self) -> int:
        return self._counted[0] + (self.line.lost if self.line is not None else 0)

    @property
    def reordered(self) -> int:
        return self._counted[1] + (self.line.reordered if self.line is not None else 0)

    def use(self, impairment: Impairment | None) -> list:
        """Take ``impairment`` on (None: none, and the next is a fresh line, its draws from its seed again);
        the items in flight on the old link, to deliver now."""
        if impairment is self.impairment:
            return ()  # (every tick: nothing allocated)
        flushed = self.line.deliver(math.inf) if self.line is not None else []
        self._counted = (self.lost, self.reordered)
        self.impairment = impairment
        self.line = DelayLine(impairment) if impairment is not None and impairment.active else None
        return flushed

    def wait(self, deadline_ns: int, sleep_until, deliver) -> int:
        """Sleep until ``deadline_ns`` (``sleep_until(ns)`` returns the time woken, ns), handing ``deliver`` the
        delayed items that fall due meanwhile; the time woken at the deadline (ns)."""
        line = self.line
        while line is not None and len(line):
            due = round(line.next_due() * 1e9)
            if due >= deadline_ns:
                break
            deliver(line.deliver(sleep_until(due) * 1e-9))
        return sleep_until(deadline_ns)
