"""CasADi functions compiled to machine code with the host's C compiler, in the background, cached on disk.

CasADi evaluates a symbolic function in its virtual machine, one instruction at a time; the same function
generated as C and compiled runs several times faster (the spatial crane's per-point Hessian: 29 ms over
96 points in the virtual machine, 3.6 ms compiled). Compiling takes seconds to tens of seconds, so it
never holds a caller: ``in_background`` returns at once, compiles in a thread (the compiler is a niced
subprocess, off the interpreter lock), and hands the compiled functions to a callback, which swaps
them in. Until then, or if no compiler is found or compiling fails, the caller keeps the functions it
has: only slower.

The shared libraries are kept in a cache directory, named by a hash of their C source, the compiler's
flags and CasADi's version, so each is compiled once per machine: ``CRANE_PLANNER_CACHE`` (default
``$XDG_CACHE_HOME/crane_planner``, else ``~/.cache/crane_planner``); ``off`` turns compiling off.
Processes that need the same library at once (a planner's solver processes) compile it once: a lock
file per library. Pure Python, no ROS import.
"""
from __future__ import annotations

import fcntl
import hashlib
import logging
import os
import shutil
import subprocess
import tempfile
import threading
from pathlib import Path
from typing import Callable

import casadi as ca

#: The C compiler's optimization: -O1 runs within a few per cent of -O2 on these straight-line functions
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
    """The C compiler (``CC``, else cc or gcc on the PATH), or None."""
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


def compile_function(fn: ca.Function) -> ca.Function | None:
    """``fn`` compiled (from the cache if it is there), or None when compiling is off or fails. Blocks while
    it compiles: call it from a background thread (``in_background``)."""
    where, cc = cache_dir(), compiler()
    if where is None:
        return None
    if cc is None:
        _warn_once('no C compiler (cc, gcc or $CC) found: NVF/RVF derivatives stay interpreted (slower solves)')
        return None
    code = source(fn)
    key = hashlib.sha256('\n'.join([code, *FLAGS, ca.__version__]).encode()).hexdigest()[:20]
    library = where / f'{fn.name()}-{key}.so'
    try:
        where.mkdir(parents=True, exist_ok=True)
        with open(where / f'{library.name}.lock', 'w') as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # another process compiling it: wait for its library
            if not library.exists():
                _compile(cc, code, library)
        return ca.external(fn.name(), str(library))
    except (OSError, RuntimeError, subprocess.SubprocessError) as exc:
        _warn_once(f'compiling {fn.name()} failed ({type(exc).__name__}: {str(exc).strip()[:200]}): it stays '
                   'interpreted (slower solves)')
        return None


def _compile(cc: str, code: str, library: Path) -> None:
    """Compile ``code`` into ``library``, which appears whole or not at all."""
    with tempfile.TemporaryDirectory(dir=library.parent) as tmp:
        c_file, built = Path(tmp) / 'f.c', Path(tmp) / library.name
        c_file.write_text(code)
        nice = shutil.which('nice')
        command = ([nice, '-n', str(COMPILER_NICE)] if nice else []) + [cc, *FLAGS, str(c_file), '-o', str(built),
                                                                        '-lm']
        done = subprocess.run(command, capture_output=True, text=True, timeout=COMPILE_TIMEOUT)
        if done.returncode != 0:
            raise RuntimeError(done.stderr or f'{cc} exited with {done.returncode}')
        os.replace(built, library)


def in_background(functions: dict[str, ca.Function], ready: Callable[[dict[str, ca.Function]], None]) -> None:
    """Compile every one of ``functions`` in a daemon thread, then call ``ready`` with them compiled (by the
    same keys), if every one compiled; returns at once. Nothing is called when compiling is off or fails."""
    if cache_dir() is None:
        return

    def run():
        done = {}
        for name, fn in functions.items():
            done[name] = compile_function(fn)
            if done[name] is None:
                return
        ready(done)

    threading.Thread(target=run, name='compile-derivatives', daemon=True).start()
