"""Deaths (serving.worker_events): the deaths of worker processes kept until replaced, each told once."""
from crane_planner.serving.worker_events import OK, REPLACED, WARN, Deaths
from crane_planner.serving.workers import Death


class _Worker:
    def __init__(self, pid):
        self.pid = pid


def test_a_death_is_told_when_found_and_its_replacement_when_ready_oldest_first():
    events = []
    deaths = Deaths(events.append)
    first, second = Death(101, -9), Death(102, None)
    deaths.replaced(first, f'{first} while idle')
    deaths.add(second)  # found under a request: its request tells of it
    assert list(deaths) == [first, second] and len(deaths) == 2
    assert [(e.level, e.action, e.death) for e in events] == [(WARN, 'replaced', first)]
    assert events[0].message == f'the solver process 101 died (signal 9) while idle; {REPLACED}'
    deaths.started(_Worker(201))
    assert events[-1].level == OK and events[-1].action == 'started' and events[-1].new_pid == 201
    assert events[-1].values() == {'pid': 101, 'signal': 9, 'exit': 'signal 9', 'action': 'started', 'new_pid': 201}
    assert list(deaths) == [second]


def test_a_first_worker_is_no_replacement_and_a_failing_listener_never_reaches_the_caller():
    events = []
    deaths = Deaths(events.append)
    deaths.started(_Worker(1))
    assert events == []

    def broken(event):
        raise RuntimeError('listener')
    Deaths(broken).replaced(Death(5, 1), 'gone')  # no exception
    Deaths().replaced(Death(6, 1), 'gone')  # no listener
