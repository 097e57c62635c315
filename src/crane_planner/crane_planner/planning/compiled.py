"""CasADi functions compiled to machine code with the host's C compiler, in the background, cached on disk.

CasADi evaluates a symbolic function in its virtual machine, one instruction at a time; the same function
generated as C and compiled runs several times faster (the spatial crane's per-point Hessian most).
Compiling takes seconds to tens of seconds, so it never holds a caller: ``in_background`` returns at
once, compiles in a thread (the compiler is a niced subprocess; generating its C source holds the
interpreter lock, for a fraction of a second), and hands the compiled
functions to a callback, which swaps them in. Until then, or if no compiler is found or compiling
fails, the caller keeps the functions it has: only slower.

The shared libraries are kept in a cache directory, named by a hash of their C source, the flags and
the versions of CasADi and of the compiler, so each is compiled once per machine:
``CRANE_PLANNER_CACHE`` (default ``$XDG_CACHE_HOME/crane_planner``, else ``~/.cache/crane_planner``);
``off`` turns compiling off. Processes that need the same library at once (a planner's solver
processes) compile it once: a lock file per library. Pure Python, no ROS import.
"""
from __future__ import annotations

import atexit
import fcntl
import functools
import hashlib
import logging
import os
import platform
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from pathlib import Path
from typing import Callable

import casadi as ca

#: The C compiler's optimization: -O1 runs nearly as fast as -O2 on these straight-line functions
#: and compiles in a fraction of its time.
FLAGS = ('-O1', '-fPIC', '-shared')
#: Niceness of the compiler: it yields the cores to solves and to the real-time nodes.
COMPILER_NICE = 10
#: Longest compile (s) before it is given up (the functions stay interpreted).
COMPILE_TIMEOUT = 600.0

log = logging.getLogger(__name__)
_warned = set()


def cache_dir() -> Path | None:
    """Where compiled functions are kept (``CRANE_PLANNER_CACHE``), or None when compiling is off."""
    setting = os.environ.get('CRANE_PLANNER_CACHE', '')
    if setting.lower() == 'off':
        return None
    if setting:
        return Path(setting)
    base = os.environ.get('XDG_CACHE_HOME') or Path.home() / '.cache'
    return Path(base) / 'crane_planner'


def compiler() -> str | None:
    """The C compiler (``$CC`` if it names one program on the PATH, else cc or gcc there), or None."""
    for name in (os.environ.get('CC'), 'cc', 'gcc'):
        if name and shutil.which(name):
            return shutil.which(name)
    return None


def _warn_once(message: str) -> None:
    if message not in _warned:
        _warned.add(message)
        log.warning(message)


def source(fn: ca.Function) -> str:
    """The C source of ``fn`` alone (its entry point named as ``fn``)."""
    gen = ca.CodeGenerator(fn.name(), {'with_header': False})
    gen.add(fn)
    return gen.dump()


@functools.lru_cache(maxsize=4)
def _compiler_identity(cc: str) -> str:
    """What the cache key needs of the compiler: its path, version and the machine it targets."""
    try:
        version = subprocess.run([cc, '-dumpfullversion', '-dumpversion'], capture_output=True, text=True,
                                 timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        version = '?'
    return f'{cc} {version} {platform.machine()}'


def compile_function(fn: ca.Function) -> ca.Function | None:
    """``fn`` compiled (from the cache if it is there), or None when compiling is off or fails. Blocks while
    it compiles: call it from a background thread (``in_background``)."""
    where, cc = cache_dir(), compiler()
    if where is None:
        return None
    if cc is None:
        _warn_once('no C compiler ($CC, cc or gcc) found: NVF/RVF derivatives stay interpreted (slower solves)')
        return None
    try:
        code = source(fn)
        key = hashlib.sha256('\n'.join([code, *FLAGS, ca.__version__, _compiler_identity(cc)]).encode())
        library = where / f'{fn.name()}-{key.hexdigest()[:20]}.so'
        where.mkdir(parents=True, exist_ok=True)
        with open(where / f'{library.name}.lock', 'w') as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # another process compiling it: wait for its library
            _remove_stale_builds(where)
            for attempt in (0, 1):
                if not library.exists():
                    _compile(cc, code, library)
                try:
                    return ca.external(fn.name(), str(library))
                except RuntimeError:  # a damaged or foreign library: compiled again, once
                    if attempt:
                        raise
                    library.unlink(missing_ok=True)
    except Exception as exc:  # (compiling is an optimization: whatever fails leaves the function interpreted)
        _warn_once(f'compiling {fn.name()} failed ({type(exc).__name__}: {str(exc).strip()[:200]}): it stays '
                   'interpreted (slower solves)')
        return None


#: Prefix of the build directories in the cache (one per compile; a process killed meanwhile leaves its own).
BUILD_PREFIX = '.build-'


def _remove_stale_builds(where: Path) -> None:
    """Remove build directories older than the longest compile (their process is gone)."""
    now = time.time()
    for build in where.glob(BUILD_PREFIX + '*'):
        try:
            if now - build.stat().st_mtime > COMPILE_TIMEOUT:
                shutil.rmtree(build, ignore_errors=True)
        except OSError:
            pass


def _compile(cc: str, code: str, library: Path) -> None:
    """Compile ``code`` into ``library``, which appears whole or not at all.

    The compiler and the final rename run in a shell of their own session: a process killed meanwhile (a
    solver process replaced, a CLI run ended) still leaves the library in the cache for the next one, and a
    compile past ``COMPILE_TIMEOUT`` is killed with everything it started."""
    with tempfile.TemporaryDirectory(dir=library.parent, prefix=BUILD_PREFIX) as tmp:
        c_file, built = Path(tmp) / 'f.c', Path(tmp) / library.name
        c_file.write_text(code)
        nice = shutil.which('nice')
        script = ('nice -n "$NICENESS" ' if nice else '') + '"$@" && mv -f -- "$BUILT" "$LIBRARY"'
        env = dict(os.environ, NICENESS=str(COMPILER_NICE), BUILT=str(built), LIBRARY=str(library))
        proc = subprocess.Popen(['sh', '-c', script, 'compile', cc, *FLAGS, str(c_file), '-o', str(built), '-lm'],
                                env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                start_new_session=True)
        try:
            _, err = proc.communicate(timeout=COMPILE_TIMEOUT)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            raise
        if proc.returncode != 0:
            raise RuntimeError(err or f'{cc} exited with {proc.returncode}')


#: One compile at a time in a process (a planner builds several NLPs at once: one compiler each would
#: crowd the cores and the memory).
_ONE_AT_A_TIME = threading.Lock()
_exiting = threading.Event()
atexit.register(_exiting.set)  # a compile thread still running stops at its next step, not inside CasADi


#: Background compiles not yet ended in this process (``in_background``), and those that ended without their
#: functions swapped in (compiling failed), under its condition.
_running = 0
_unswapped = 0
_ended = threading.Condition()


def wait_until_compiled(timeout: float) -> bool:
    """Wait until every background compile of this process has ended; whether compiling is on and every one
    ended within ``timeout`` s with its functions swapped in. For benchmarks that measure the steady state a
    planner reaches once its warm-ups' derivatives are compiled."""
    if cache_dir() is None or compiler() is None:
        return False
    with _ended:
        return _ended.wait_for(lambda: _running == 0, timeout) and _unswapped == 0


def in_background(functions: dict[str, ca.Function], ready: Callable[[dict[str, ca.Function]], None]) -> None:
    """Compile every one of ``functions`` in a daemon thread, one compile at a time in the process, then call
    ``ready`` with them compiled (by the same keys), if every one compiled; returns at once. Nothing is
    called when compiling is off or fails (said once in the log)."""
    global _running
    if cache_dir() is None:
        return

    def run():
        global _running, _unswapped
        swapped = False
        try:
            swapped = compile_and_swap()
        finally:
            with _ended:
                _running -= 1
                _unswapped += not swapped
                _ended.notify_all()

    def compile_and_swap() -> bool:
        try:
            done = {}
            for name, fn in functions.items():
                with _ONE_AT_A_TIME:
                    if _exiting.is_set():
                        return False
                    done[name] = compile_function(fn)
                if done[name] is None:
                    return False
            if not _exiting.is_set():
                ready(done)
                return True
        except Exception as exc:  # (a failure here only leaves the functions interpreted)
            _warn_once(f'using the compiled derivatives failed ({type(exc).__name__}: {exc}): they stay '
                       'interpreted')
        return False

    with _ended:
        _running += 1
    threading.Thread(target=run, name='compile-derivatives', daemon=True).start()
