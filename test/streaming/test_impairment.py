"""Network impairment model (crane_planner.streaming.impairment) under a virtual clock."""
import math

import numpy as np
import pytest

from crane_msgs_py.crane.params import ParameterError
from crane_planner.streaming.impairment import DelayLine, Impairment, Link

N = 20000
PERIOD = 1e-3


def run(imp, n=N):
    """Send n messages every 1 ms; return (send index, send time, delivery time) of delivered ones."""
    line = DelayLine(imp)
    sent = {}
    delivered = []
    for k in range(n):
        now = k * PERIOD
        delivered += [(i, now) for i in line.deliver(now)]
        if line.send(now, k) is not None:
            sent[k] = now
    delivered += [(i, math.inf) for i in line.deliver(math.inf)]
    return line, sent, delivered


def delays(imp, n=N):
    line = DelayLine(imp)
    d = [line.send(k * PERIOD, k) for k in range(n)]
    return np.array([x - k * PERIOD for k, x in enumerate(d) if x is not None]), line


@pytest.mark.parametrize('distribution, mean_extra', [('normal', 0.0), ('uniform', 0.0), ('exponential', 1.0)])
def test_mean_delay_and_jitter_std(distribution, mean_extra):
    delay, jitter = 5e-3, 1e-3  # 5 sigma from zero: truncation at 0 is negligible
    d, _ = delays(Impairment(delay=delay, jitter=jitter, distribution=distribution, reorder=True, seed=7))
    se = jitter / math.sqrt(d.size)
    assert abs(d.mean() - (delay + mean_extra * jitter)) < 5 * se
    # std of the sample std ~ sigma sqrt((kurtosis - 1) / 4N); kurtosis <= 9 (exponential)
    assert abs(d.std() - jitter) < 5 * jitter * math.sqrt(8 / (4 * d.size))
    if distribution == 'uniform':
        assert d.min() >= delay - math.sqrt(3) * jitter and d.max() <= delay + math.sqrt(3) * jitter
    if distribution == 'exponential':
        assert d.min() >= delay


def test_normal_delay_is_truncated_at_zero():
    d, _ = delays(Impairment(delay=0.0, jitter=1e-3, seed=1, reorder=True))
    assert d.min() == 0.0
    # E[max(0, X)] for X ~ N(0, s^2) is s / sqrt(2 pi)
    assert abs(d.mean() - 1e-3 / math.sqrt(2 * math.pi)) < 5e-3 / math.sqrt(d.size)


def test_loss_rate_and_counters():
    p = 0.05
    line, sent, delivered = run(Impairment(delay=2e-3, jitter=1e-3, loss=p, seed=3))
    rate = line.lost / N
    assert abs(rate - p) < 4 * math.sqrt(p * (1 - p) / N)
    assert line.sent == N and line.delivered == len(delivered) == N - line.lost == len(sent)
    assert len(line) == 0


def test_fifo_when_reorder_is_off_even_with_large_jitter():
    imp = Impairment(delay=2e-3, jitter=3e-3, seed=5)  # jitter >> spacing: reordering would be common
    line, _, delivered = run(imp)
    order = [i for i, _ in delivered]
    assert order == sorted(order) and line.reordered == 0
    # same draws without the FIFO rule give each message's own time; FIFO is their running max
    fifo_line, own_line = DelayLine(imp), DelayLine(Impairment(delay=2e-3, jitter=3e-3, seed=5, reorder=True))
    fifo = np.array([fifo_line.send(k * PERIOD, k) for k in range(N)])
    own = np.array([own_line.send(k * PERIOD, k) for k in range(N)])
    assert np.array_equal(fifo, np.maximum.accumulate(own))
    assert np.any(fifo > own)


def test_reordering_happens_and_is_counted_when_allowed():
    line, _, delivered = run(Impairment(delay=2e-3, jitter=3e-3, reorder=True, seed=5))
    newest, late = -1, 0
    for i, _ in delivered:
        if i < newest:
            late += 1
        newest = max(newest, i)
    assert late > 0.05 * N and line.reordered == late


def test_messages_are_not_delivered_before_they_are_due():
    line = DelayLine(Impairment(delay=2e-3))
    line.send(0.0, 'a')
    line.send(1e-3, 'b')
    assert line.next_due() == pytest.approx(2e-3)
    assert line.deliver(1.999e-3) == []
    assert line.deliver(2e-3) == ['a']
    assert line.deliver(3e-3) == ['b'] and line.next_due() is None


def test_same_seed_same_run_other_seed_other_run():
    imp = Impairment(delay=1e-3, jitter=1e-3, loss=0.1, distribution='exponential', seed=11)
    a, b = run(imp, 2000), run(imp, 2000)
    c = run(Impairment(delay=1e-3, jitter=1e-3, loss=0.1, distribution='exponential', seed=12), 2000)
    assert a[2] == b[2] and a[1] == b[1]
    assert a[1] != c[1]


def test_off_by_default_delivers_at_once_in_order():
    imp = Impairment()
    assert not imp.active
    line = DelayLine(imp)
    for k in range(5):
        assert line.send(k * PERIOD, k) == k * PERIOD
        assert line.deliver(k * PERIOD) == [k]


@pytest.mark.parametrize('kwargs, word', [({'delay': -1e-3}, 'delay'), ({'jitter': math.nan}, 'jitter'),
                                          ({'loss': 1.5}, 'loss'), ({'distribution': 'pareto'}, 'distribution')])
def test_bad_parameters_are_named(kwargs, word):
    with pytest.raises(ParameterError, match=word):
        Impairment(**kwargs)


def test_a_link_takes_a_new_impairment_at_once_flushing_the_old_and_counts_over_every_link():
    link = Link()
    lossy = Impairment(delay=0.01, loss=0.5, seed=3)
    assert link.use(lossy) == [] and link.line is not None
    for k in range(100):
        link.line.send(k * 1e-3, k)
    in_flight, lost = len(link.line), link.lost
    assert 0 < lost < 100 and link.use(lossy) == ()  # the same impairment: nothing changes
    flushed = link.use(Impairment())  # inactive: straight on, what was in flight delivered now
    assert len(flushed) == in_flight and link.line is None and link.lost == lost
    assert link.use(None) == [] and link.use(lossy) == [] and link.lost == lost  # a fresh line, its count on top
    link.line.send(0.0, 'x')
    assert link.lost in (lost, lost + 1)
