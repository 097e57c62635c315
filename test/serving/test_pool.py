"""SolverPool (crane_planner.serving.pool): lends each instance to one caller, grows lazily, never blocks long."""
import threading
import time

import pytest

from crane_planner.planning.plan import PlanError
from crane_planner.serving.pool import SolverPool


class Counter:
    def __init__(self):
        self.made = 0

    def __call__(self):
        self.made += 1
        return object()


def wait_for(predicate, timeout=5.0):
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline
        time.sleep(0.005)


def test_a_spare_is_made_in_the_background_when_the_last_idle_one_is_lent():
    create = Counter()
    pool = SolverPool(create, size=3, grace=0.0)
    with pool.lend(0.1) as a:  # the first: built in the request
        assert create.made == 1
    with pool.lend(0.1) as again:  # the idle one again; a spare is made meanwhile
        assert again is a
        wait_for(lambda: create.made == 2)
        with pool.lend(0.1) as b:  # beside it: the spare, no build in this request
            assert b is not a  # the spare
            wait_for(lambda: create.made == 3)  # and the next spare, up to the size
            with pool.lend(0.1) as c:
                assert len({id(a), id(b), id(c)}) == 3  # never one instance to two callers
                with pytest.raises(PlanError):
                    with pool.lend(0.05):
                        pass
    assert create.made == 3 and pool.instances == 3


def test_the_most_recently_returned_instance_is_lent_first():
    pool = SolverPool(Counter(), size=2, grace=0.0)
    with pool.lend(0.1) as a, pool.lend(0.1):
        pass  # the second one is returned before a
    with pool.lend(0.1) as first:
        assert first is a  # its warm start is the freshest


def test_a_full_pool_is_waited_for_then_refused_naming_the_size_parameter():
    pool = SolverPool(Counter(), size=1, name='rvf')
    with pool.lend(0.1):
        with pytest.raises(PlanError, match='all 1 rvf solvers stayed busy for 0.05 s; raise solver_pool_size'):
            with pool.lend(0.05):
                pass
        # another caller waiting is served as soon as the instance comes back
        got = []
        waiter = threading.Thread(target=lambda: got.append(pool.lend(5.0).__enter__()))
        waiter.start()
    waiter.join(5.0)
    assert got and pool.instances == 1


def test_growing_the_pool_frees_a_waiting_caller_and_shrinking_drops_returned_instances():
    create = Counter()
    pool = SolverPool(create, size=1, grace=0.0)
    lent = pool.lend(0.1)
    lent.__enter__()
    got = []
    waiter = threading.Thread(target=lambda: got.append(pool.lend(5.0).__enter__()))
    waiter.start()
    pool.size = 2
    waiter.join(5.0)
    assert got and create.made == 2
    pool.size = 1
    lent.__exit__(None, None, None)  # more instances than the size: dropped
    assert pool.instances == 1


def test_a_failed_creation_frees_its_place():
    calls = []

    def create():
        calls.append(1)
        if len(calls) == 1:
            raise RuntimeError('build failed')
        return object()

    pool = SolverPool(create, size=1)
    with pytest.raises(RuntimeError):
        with pool.lend(0.1):
            pass
    with pool.lend(0.1) as solver:
        assert solver is not None
    assert pool.instances == 1


def test_an_instance_coming_back_within_the_grace_is_lent_instead_of_a_new_one():
    create = Counter()
    pool = SolverPool(create, size=4, grace=5.0)
    lent = pool.lend(0.1)
    first = lent.__enter__()
    threading.Timer(0.05, lent.__exit__, (None, None, None)).start()  # a short solve ends
    with pool.lend(0.1) as solver:
        assert solver is first
    # with no grace, a second instance is made at once
    eager = SolverPool(Counter(), size=4, grace=0.0)
    with eager.lend(0.1) as a, eager.lend(0.1) as b:
        assert a is not b


@pytest.mark.parametrize('size', [0, -1, 1.5])
def test_size_must_be_a_positive_integer(size):
    with pytest.raises(ValueError, match='pool size'):
        SolverPool(Counter(), size)


class Closable:
    def __init__(self):
        self.closed = False

    def close(self):
        self.closed = True


def test_fill_makes_every_instance_up_front_and_replaces_one_that_closes():
    made = []

    def create():
        made.append(Closable())
        return made[-1]

    pool = SolverPool(create, size=3, grace=0.0)
    assert pool.fill(ready_within=5.0)
    wait_for(lambda: len(pool._idle) == 3)
    solver = pool.take(0.1)
    solver.closed = True  # e.g. a worker process that died
    pool.give_back(solver)
    wait_for(lambda: len(made) == 4 and len(pool._idle) == 3)
    assert solver not in pool._idle and pool.instances == 3


def test_close_closes_idle_instances_now_and_lent_ones_when_they_come_back():
    pool = SolverPool(Closable, size=2, grace=0.0)
    pool.fill(ready_within=5.0)
    wait_for(lambda: len(pool._idle) == 2)
    lent = pool.take(0.1)
    idle = list(pool._idle)
    pool.close()
    assert all(s.closed for s in idle) and not lent.closed
    pool.give_back(lent)
    assert lent.closed and pool.instances == 0


def test_the_refusal_names_the_hint_given():
    pool = SolverPool(Counter(), size=1, grace=0.0, hint='raise solver_processes')
    with pool.lend(0.1), pytest.raises(PlanError, match='raise solver_processes'):
        pool.take(0.01)


class Tagged:
    """Instances with a tag, to tell which one a preference picked."""

    def __init__(self, tags):
        self.tags = list(tags)

    def __call__(self):
        return type('Instance', (), {'tag': self.tags.pop(0)})()


def filled(tags):
    pool = SolverPool(Tagged(tags), size=len(tags), grace=0.0)
    assert pool.fill(5.0, count=len(tags))
    return pool


def test_a_preferred_idle_instance_is_lent_before_the_most_recently_returned_one():
    pool = filled(['a', 'b', 'c'])
    preferred = pool.take(0.1, prefer=lambda i: i.tag == 'b')
    assert preferred.tag == 'b'
    other = pool.take(0.1, prefer=lambda i: i.tag == 'b')  # none preferred is idle: any
    assert other.tag != 'b'


def test_upkeep_never_takes_the_last_idle_instance_nor_one_a_request_waits_for():
    pool = filled(['a', 'b'])
    upkept = pool.take_idle(lambda i: True, keep=1)
    assert upkept is not None
    assert pool.take_idle(lambda i: True, keep=1) is None  # the last idle one stays for requests
    assert pool.take_idle(lambda i: i.tag == upkept.tag, keep=0) is None  # none idle that it wants
    lent = pool.take(0.1)
    got = []
    waiting = threading.Thread(target=lambda: got.append(pool.take(5.0)))
    waiting.start()
    wait_for(lambda: pool._waiting == 1)
    pool.give_back(upkept)  # back from upkeep: the waiting request gets it, upkeep does not
    waiting.join()
    assert got == [upkept] and pool.take_idle(lambda i: True, keep=0) is None
    pool.give_back(lent)
    assert pool.take_idle(lambda i: True, keep=0) is lent


def test_fill_counts_an_instance_in_upkeep_as_ready():
    pool = filled(['a', 'b'])
    upkept = pool.take_idle(lambda i: True, keep=0)
    assert pool.fill(0.0, count=2)  # ready, only not idle
    lent = pool.take(0.1)
    assert not pool.fill(0.0, count=2)  # one serving a request is not
    pool.give_back(lent)
    pool.give_back(upkept)


def test_upkeep_takes_the_idle_instance_ranked_highest():
    pool = filled(['a', 'b', 'c'])
    ranks = {'a': 1, 'b': 3, 'c': 2}
    assert pool.take_idle(lambda i: True, keep=0, rank=lambda i: ranks[i.tag]).tag == 'b'
    assert pool.take_idle(lambda i: i.tag != 'c', keep=0, rank=lambda i: ranks[i.tag]).tag == 'a'


def test_fill_replaces_the_idle_instances_found_broken_and_returns_them():
    made = []

    def create():
        made.append(Closable())
        return made[-1]

    pool = SolverPool(create, size=3, grace=0.0)
    assert pool.fill(ready_within=5.0, count=3)
    broken = made[:2]  # e.g. worker processes that died while idle
    assert pool.discard_idle(lambda s: s in broken) == broken
    assert pool.discard_idle(lambda s: s in broken) == []  # out of the pool: found once
    wait_for(lambda: len(made) == 5 and len(pool._idle) == 3)
    assert not set(map(id, broken)) & set(map(id, pool._idle)) and pool.instances == 3


def test_a_kept_full_pool_tries_a_failed_replacement_again():
    attempts = []

    def create():  # fails once after the first instance, as a worker's start beside a dying fork server
        attempts.append(len(attempts))
        if len(attempts) == 2:
            raise OSError('no fork server')
        return Closable()

    pool = SolverPool(create, size=1, grace=0.0)
    pool.retry_delays = (0.01,)
    assert pool.fill(ready_within=5.0)
    lent = pool.take(0.1)
    lent.closed = True
    pool.give_back(lent)
    wait_for(lambda: len(pool._idle) == 1)
    assert len(attempts) == 3 and pool.instances == 1
