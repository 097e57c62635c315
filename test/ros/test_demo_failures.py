"""crane-demo fails loudly: nodes that do not come up, or a node that dies mid-run, end it with exit status 1
and one message naming the cause, never a traceback, and no node is left running.

Nothing here is timed (the waits are hang guards, long enough for a start-up at niceness 10 beside a CPU-bound
process): ``make test`` runs this module beside the real-time ROS tests (``test/conftest.py``,
``UNTIMED_ROS_MODULES``).
"""
import os
import signal
import subprocess
import sys
import threading
import uuid
from pathlib import Path

BIN = Path(sys.executable).parent


def _demo(tmp_path, *args):
    return subprocess.Popen([str(BIN / 'crane-demo'), '--out', str(tmp_path), '--no-figures', *args],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)


def test_demo_exits_nonzero_when_nodes_do_not_come_up(tmp_path):
    proc = _demo(tmp_path, '--methods', 'zv', '--cases', 'nominal', '--startup-timeout', '0.01')
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 1, err  # (a crash: the faulthandler's stacks are in err)
    assert 'not up within' in err
    assert 'Traceback' not in err


def test_demo_exits_nonzero_naming_a_node_that_dies(tmp_path):
    namespace = f'/demo_{uuid.uuid4().hex[:8]}'
    proc = _demo(tmp_path, '--methods', 'zv,nvf,rvf', '--cases', 'nominal', '--namespace', namespace, '--no-record',
                 '--startup-timeout', '300')
    lines, up = [], threading.Event()

    def read_stderr():  # the demo's progress: the sim is killed once it says its nodes are up
        for line in proc.stderr:
            lines.append(line)
            if 'nodes up' in line:
                up.set()
    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    try:
        assert up.wait(300.0), 'the demo never said its nodes were up: ' + ''.join(lines)
        found = subprocess.run(['pgrep', '-f', f'bin/sim --ros-args -r __ns:={namespace}'],
                               capture_output=True, text=True).stdout.split()
        assert found, 'the demo\'s sim is not running'
        os.kill(int(found[0]), signal.SIGKILL)  # as the demo sets its cases up (parameters, reset, the first plan)
        proc.wait(timeout=300)
        reader.join(timeout=10)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    err = ''.join(lines)
    assert proc.returncode == 1, err
    assert 'node sim exited' in err
    assert 'Traceback' not in err
    # Every other node was stopped with it.
    left = subprocess.run(['pgrep', '-f', f'__ns:={namespace}'], capture_output=True, text=True).stdout.split()
    assert left == []
