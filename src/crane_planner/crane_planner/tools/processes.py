"""Start the crane nodes as real subprocesses, watch them, and always stop them.

Used by ``crane-demo``, the harness, the benchmarks and the integration tests (there is no ``ros2
launch`` on a PyPI-only install). Pure Python: no ROS import.
"""
from __future__ import annotations

import os
import random
import shutil
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from crane_msgs_py.runtime.dds import use_loopback_udp
from crane_msgs_py.runtime.realtime import DIE_WITH_PARENT

#: Fast DDS maps domain ids 0..232 to UDP ports; 0 is everyone's default, so avoid it.
DOMAIN_ID_RANGE = (1, 232)

#: The executables of this workspace: (package, executable).
PLANNER = ('crane_planner', 'planner')
STREAMER = ('crane_planner', 'streamer')
SIM = ('crane_sim', 'sim')


class NodeDied(RuntimeError):
    """A node process exited while it was needed; the message says which and how."""


def isolated_ros_env(domain_id: int | None = None) -> dict:
    """This process's environment for a private ROS graph: a random domain id, Fast DDS on 127.0.0.1 UDP only.

    Other projects share these machines; a random ``ROS_DOMAIN_ID`` and sockets bound to loopback
    (``crane_msgs_py.runtime.dds.use_loopback_udp``) keep our traffic to ourselves.
    """
    env = dict(os.environ)
    env['ROS_DOMAIN_ID'] = str(random.randint(*DOMAIN_ID_RANGE) if domain_id is None else int(domain_id))
    use_loopback_udp(env)  # 127.0.0.1 UDP only: Fast DDS's shared memory stalls joins and hangs on stale ports
    env.setdefault('PYTHONUNBUFFERED', '1')
    env.setdefault('RCUTILS_COLORIZED_OUTPUT', '0')
    return env


@contextmanager
def isolated_graph(domain_id: int | None = None):
    """For the block, this process joins a private ROS graph (``isolated_ros_env``); yields the environment.

    Set before ``rclpy.init`` and passed to the node subprocesses, so this
    process and its nodes meet each other and nobody else. The previous
    environment is restored on exit.
    """
    saved = dict(os.environ)
    env = isolated_ros_env(domain_id)
    os.environ.clear()
    os.environ.update(env)
    try:
        yield env
    finally:
        os.environ.clear()
        os.environ.update(saved)


def find_executable(package: str, name: str) -> str:
    """Path of a node executable: the venv's console script, else ``lib/<package>/<name>`` of a ROS install."""
    here = Path(sys.executable).parent / name
    if here.exists():
        return str(here)
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        candidate = Path(prefix) / 'lib' / package / name
        if prefix and candidate.exists():
            return str(candidate)
    found = shutil.which(name)
    if found:
        return found
    raise FileNotFoundError(f'executable {name!r} of package {package!r} not found (run `make install`?)')


def ros_args(namespace: str | None = None, params: dict | None = None, params_file=None) -> list[str]:
    """``--ros-args`` for a namespace, a parameters file and parameter overrides (which win over the file)."""
    args = ['--ros-args']
    if namespace:
        args += ['-r', f'__ns:={namespace}']
    if params_file:
        args += ['--params-file', str(params_file)]
    for key, value in (params or {}).items():
        args += ['-p', f'{key}:={_param_text(value)}']
    return args


def _param_text(value) -> str:
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (list, tuple)):
        return '[' + ','.join(_param_text(v) for v in value) + ']'
    if isinstance(value, str):
        return value
    return repr(value)


@dataclass
class NodeProcess:
    name: str
    popen: subprocess.Popen
    log_path: Path

    def tail(self, lines: int = 5) -> str:
        try:
            text = self.log_path.read_text(errors='replace').strip().splitlines()
        except OSError:
            return ''
        return ' | '.join(text[-lines:])


@dataclass
class NodeGroup:
    """Node subprocesses sharing one environment, logging to ``log_dir``; a context manager.

    ``stop()`` (also on exit of the ``with`` block) sends SIGINT, waits, then
    kills whatever is left, so no node outlives its group.
    """

    env: dict
    log_dir: Path
    processes: list = field(default_factory=list)

    def run_tool(self, executable: str, *args: str) -> subprocess.Popen:
        """Start one of crane_planner's command-line tools (``crane-teleop``, say) on this graph; the
        caller waits for or kills it (it also dies with this process)."""
        return subprocess.Popen([find_executable('crane_planner', executable), *args],
                                env={**self.env, DIE_WITH_PARENT: '1'}, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True)

    def start(self, package: str, executable: str, *, name: str | None = None, namespace: str | None = None,
              params: dict | None = None, params_file=None) -> NodeProcess:
        self.log_dir.mkdir(parents=True, exist_ok=True)
        name = name or executable
        log_path = self.log_dir / f'{name}.log'
        cmd = [find_executable(package, executable), *ros_args(namespace, params, params_file)]
        with open(log_path, 'w') as log:
            popen = subprocess.Popen(cmd, env={**self.env, DIE_WITH_PARENT: '1'}, stdout=log,
                                     stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True)
        proc = NodeProcess(name, popen, log_path)
        self.processes.append(proc)
        return proc

    def check_alive(self):
        """Raise NodeDied naming the first node that has exited, with the end of its log."""
        for proc in self.processes:
            code = proc.popen.poll()
            if code is not None:
                raise NodeDied(f'node {proc.name} exited with status {code}: {proc.tail() or "no output"}')

    def stop(self, timeout: float = 5.0):
        for proc in self.processes:
            if proc.popen.poll() is None:
                _signal_group(proc.popen, signal.SIGINT)
        deadline = time.monotonic() + timeout
        for proc in self.processes:
            try:
                proc.popen.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                _signal_group(proc.popen, signal.SIGKILL)
                proc.popen.wait()
        self.processes.clear()

    def __enter__(self) -> 'NodeGroup':
        return self

    def __exit__(self, *exc):
        self.stop()


def _signal_group(popen: subprocess.Popen, sig):
    # Each node runs in its own session, so its whole process group gets the signal.
    try:
        os.killpg(popen.pid, sig)
    except ProcessLookupError:
        pass


# -- other processes, read from /proc (Linux): the fault tests and benchmarks find and watch solver processes

def process_children() -> dict:
    """Every process's children (ppid -> [pid]), from /proc."""
    tree: dict = {}
    for entry in filter(str.isdigit, os.listdir('/proc')):
        try:
            with open(f'/proc/{entry}/stat') as f:
                ppid = int(f.read().rsplit(')', 1)[1].split()[1])
        except (OSError, ValueError, IndexError):  # (it ended meanwhile)
            continue
        tree.setdefault(ppid, []).append(int(entry))
    return tree


def cmdline(pid: int) -> str:
    """The process's command line ('' once it is gone)."""
    try:
        with open(f'/proc/{pid}/cmdline', 'rb') as f:
            return f.read().replace(b'\0', b' ').decode(errors='replace')
    except OSError:
        return ''


def fork_servers(pid: int) -> list[int]:
    """The process's multiprocessing fork servers (its children running ``multiprocessing.forkserver``; the
    solver and stop worker processes are their children)."""
    return [p for p in process_children().get(pid, []) if 'multiprocessing.forkserver' in cmdline(p)]


def cpu_ticks(pid: int) -> int:
    """The process's user + system CPU time in clock ticks (0 once it is gone): whether it works, without
    timing it."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            fields = f.read().rsplit(')', 1)[1].split()
    except OSError:
        return 0
    return int(fields[11]) + int(fields[12])
