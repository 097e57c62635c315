"""runway.schedule over random pairs of occupancies (hypothesis): the delay it gives keeps the minimum distance
between the true paths checked every millisecond (not only at the samples it looked at), and it is the least:
one DELAY_STEP less comes within the distance the samples must keep (every shorter delay too), or it is 0.

Each occupancy is sampled every 20 ms, as a plan's is, from a known path: a crane's girder along a quintic
S-curve of y, its hook and load swinging about it along both axes (a window of the motion times a sine), held
before and after, the load a bit ahead of the hook. The dense check evaluates those paths themselves."""
import math
from dataclasses import dataclass

import numpy as np
from hypothesis import event, given, settings
from hypothesis import strategies as st

from crane_planner.runway.occupancy import OCCUPANCY_STEP, Footprint, Occupancy, Shape, separation
from crane_planner.runway.schedule import DELAY_STEP, Conflict, conflicts, required, schedule

SHAPE = Shape(0.05, 0.05)
SETTLE = 1.0
MS = 1_000_000


@dataclass(frozen=True)
class Path:
    """A crane's footprint as functions of time: the girder from ``y0`` by ``dy`` in ``T`` s from ``start``
    (s), the trolley at ``x``; the load swinging ``amplitude`` (m) at ``omega`` (rad/s) along ``direction``."""

    crane: str
    start: float
    y0: float
    dy: float
    T: float
    x: float
    amplitude: float
    omega: float
    direction: float

    def at(self, t: np.ndarray) -> Footprint:
        tau = np.clip((t - self.start) / self.T, 0.0, 1.0)
        girder = self.y0 + self.dy * tau ** 3 * (10 - 15 * tau + 6 * tau ** 2)
        swing = self.amplitude * np.sin(math.pi * tau) ** 2 * np.sin(self.omega * (t - self.start))
        ux, uy = math.cos(self.direction), math.sin(self.direction)
        hook = np.stack([self.x + 0.5 * swing * ux, girder + 0.5 * swing * uy], axis=-1)
        load = np.stack([self.x + swing * ux, girder + swing * uy], axis=-1)
        return Footprint(girder, np.stack([hook, load], axis=1))

    def occupancy(self, published_ns: int = 0) -> Occupancy:
        end = self.T + SETTLE
        t = np.linspace(0.0, end, math.ceil(end / OCCUPANCY_STEP - 1e-9) + 1)
        start_ns = round(self.start * 1e9)
        return Occupancy(self.crane, published_ns, start_ns, t, self.at(self.start + t), SHAPE)

    def delayed(self, delay: float) -> 'Path':
        return Path(self.crane, self.start + delay, self.y0, self.dy, self.T, self.x, self.amplitude, self.omega,
                    self.direction)


def dense_min(mine: Path, other: Path, until: float) -> float:
    """The least distance between the two paths every millisecond from ``mine``'s start to ``until`` (s)."""
    t = np.arange(round(mine.start * 1e3), round(until * 1e3) + 1) * 1e-3
    return float(separation(mine.at(t), SHAPE, other.at(t), SHAPE).min())


def paths(name: str):
    """A path whose start and duration fall on whole milliseconds (the dense grid then holds every sample)."""
    return st.builds(Path, st.just(name), st.integers(0, 3000).map(lambda k: k * 1e-3), st.floats(-3.0, 3.0),
                     st.floats(-3.0, 3.0), st.integers(1500, 5000).map(lambda k: k * 1e-3), st.floats(0.0, 2.0),
                     st.floats(0.0, 0.25), st.floats(2.0, 9.0), st.floats(0.0, 2 * math.pi))


@st.composite
def following(draw):
    """(mine, other): ``mine`` behind ``other`` along its motion, as fast or faster, ending behind it: it may
    catch it up on the way (a wait), or not."""
    other = draw(paths('other'))
    ahead = math.copysign(1.0, other.dy) if other.dy else 1.0
    gap0, gap1 = draw(st.floats(0.4, 2.0)), draw(st.floats(0.4, 1.0))
    y0 = other.y0 - ahead * gap0
    start = max(0.0, other.start + draw(st.integers(-500, 1000)) * 1e-3)
    mine = Path('mine', round(start, 3), y0, other.y0 + other.dy - ahead * gap1 - y0,
                draw(st.integers(1000, round(other.T * 1e3))) * 1e-3, draw(st.floats(0.0, 2.0)),
                draw(st.floats(0.0, 0.25)), draw(st.floats(2.0, 9.0)), draw(st.floats(0.0, 2 * math.pi)))
    return mine, other


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.tuples(paths('mine'), paths('other')), following()), st.sampled_from([0.1, 0.2, 0.3]))
def test_the_delay_keeps_the_minimum_distance_between_the_true_paths_and_is_the_least(pair, min_distance):
    mine, other = pair
    a, b = mine.occupancy(1), other.occupancy(0)
    until = max(mine.start + mine.T, other.start + other.T) + SETTLE
    try:
        s = schedule(a, [b], min_distance)
    except Conflict as refused:
        event('refused')
        assert refused.crane == 'other'
        # no delay up to when the other stands still and a step more keeps the samples clear
        horizon = max(0.0, other.start + other.T + SETTLE - mine.start) + DELAY_STEP
        steps = math.ceil(horizon / DELAY_STEP - 1e-9)
        assert all(conflicts(a.delayed(k * DELAY_STEP), [b], min_distance) for k in range(steps + 1))
        return
    k = round(s.delay / DELAY_STEP)
    event('waits' if k else 'clear at once')
    assert s.delay == k * DELAY_STEP or math.isclose(s.delay, k * DELAY_STEP)
    moved = mine.delayed(s.delay)
    assert dense_min(moved, other, until + s.delay) >= min_distance - 1e-12  # (to the float: at rest exactly it)
    assert (s.waited_for == 'other') == (k > 0)
    if k > 0:
        # one step less comes within the distance the samples must keep, on the true paths too ...
        sooner = mine.delayed((k - 1) * DELAY_STEP)
        assert dense_min(sooner, other, until + s.delay) < required(a, b, min_distance)
        # ... and so does every shorter delay, as the schedule sees them
        assert all(conflicts(a.delayed(j * DELAY_STEP), [b], min_distance) for j in range(k))
