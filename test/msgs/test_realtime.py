"""crane_msgs_py.runtime.realtime.die_with_parent: a child started for a test or a demo does not outlive it."""
import os
import signal
import subprocess
import sys
import time

CHILD = ('import signal, sys, time\n'
         'from crane_msgs_py.runtime.realtime import die_with_parent\n'
         'signal.signal(signal.SIGINT, lambda *_: sys.exit(0))\n'
         'print(die_with_parent(), flush=True)\n'
         'time.sleep(30)\n')
PARENT = ('import subprocess, sys, time\n'
          f'child = subprocess.Popen([sys.executable, "-c", {CHILD!r}], env={{**__import__("os").environ, '
          '"CRANE_DIE_WITH_PARENT": sys.argv[1]}, stdout=sys.stdout)\n'
          'print(child.pid, flush=True)\n'
          'time.sleep(30)\n')


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def run_parent(flag: str):
    parent = subprocess.Popen([sys.executable, '-c', PARENT, flag], stdout=subprocess.PIPE, text=True)
    child = int(parent.stdout.readline())
    armed = parent.stdout.readline().strip()
    parent.kill()  # SIGKILL: the parent can clean up nothing
    parent.wait()
    return child, armed


def test_a_child_armed_by_the_environment_ends_when_its_parent_is_killed():
    child, armed = run_parent('1')
    assert armed == 'True'
    deadline = time.monotonic() + 5.0
    while alive(child) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not alive(child)


def test_without_the_flag_a_child_is_left_alone():
    child, armed = run_parent('')
    try:
        assert armed == 'False'
        time.sleep(0.3)
        assert alive(child)
    finally:
        os.kill(child, signal.SIGKILL)


def test_set_fifo_sets_and_clears_the_priority_of_the_calling_thread_only():
    import threading

    from crane_msgs_py.runtime.realtime import set_fifo
    seen = {}

    def thread():
        seen['refused'] = set_fifo(10)
        seen['inside'] = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
        seen['cleared'] = set_fifo(0)
        seen['after'] = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority

    before = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    worker = threading.Thread(target=thread)
    worker.start()
    worker.join()
    assert (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) == before  # this thread's untouched
    assert seen['cleared'] == '' and seen['after'] == (os.SCHED_OTHER, 0)
    if seen['refused']:  # no CAP_SYS_NICE: said, and nothing changed
        assert seen['refused'].startswith('SCHED_FIFO priority 10 refused') and seen['inside'] == (os.SCHED_OTHER, 0)
    else:
        assert seen['inside'] == (os.SCHED_FIFO, 10)


def test_set_threads_fifo_raises_the_threads_so_named_and_no_other():
    import threading

    from crane_msgs_py.runtime.realtime import set_threads_fifo
    ready, done, tids = threading.Barrier(3), threading.Event(), {}

    def thread(name):
        tid = threading.get_native_id()
        with open(f'/proc/self/task/{tid}/comm', 'w') as comm:  # (names no middleware thread here has)
            comm.write(name)
        tids[name] = tid
        ready.wait()
        done.wait(10.0)

    workers = [threading.Thread(target=thread, args=(name,)) for name in ('rt.rx.7411', 'rt.ev.0')]
    for worker in workers:
        worker.start()
    ready.wait()
    try:
        count, refused = set_threads_fifo(10, ('rt.rx.', 'rt.shm.'))
        raised = os.sched_getscheduler(tids['rt.rx.7411']), os.sched_getparam(tids['rt.rx.7411']).sched_priority
        other = os.sched_getscheduler(tids['rt.ev.0'])
        cleared = set_threads_fifo(0, ('rt.rx.',))
        after = os.sched_getscheduler(tids['rt.rx.7411'])
    finally:
        done.set()
        for worker in workers:
            worker.join()
    assert other == os.SCHED_OTHER and os.sched_getscheduler(0) == os.SCHED_OTHER  # only the ones named
    assert cleared == (1, '') and after == os.SCHED_OTHER
    if refused:  # no CAP_SYS_NICE: said, and nothing changed
        assert count == 0 and refused.startswith('SCHED_FIFO priority 10 refused') and raised[0] == os.SCHED_OTHER
    else:
        assert count == 1 and raised == (os.SCHED_FIFO, 10)
