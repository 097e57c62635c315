"""``crane-plan`` run in the test process through ``cli.main``: what the console script runs, without
starting Python and its imports again for each call (a few seconds each on a busy 2-core machine). The
installed executable itself is run by a few tests in ``tools/test_cli.py``.

What the executable would show is kept: its exit status; stdout as the process's file descriptor 1 gets it
(so output written there natively, by IPOPT or CasADi, is seen too: the JSON must stay clean); stderr with
the Python warnings a script prints (Python's default filters). Native writes to stderr are not taken: in a
ROS test the middleware and the harness's node log there from other threads meanwhile; nor is what the test
process's own objects write there meanwhile (rclpy says so of a future left with an exception when it is
collected): garbage is collected before and not during, and only the calling thread's writes are taken.
"""
import gc
import io
import os
import sys
import tempfile
import threading
import warnings
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass

from crane_planner.tools.cli import main


@dataclass
class Completed:
    """What ``subprocess.run(..., capture_output=True, text=True)`` would give."""
    returncode: int
    stdout: str
    stderr: str


def _show(message, category, filename, lineno, file=None, line=None):
    sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


class _ThisThread(io.TextIOBase):
    """A stderr that keeps what the thread that made it writes, and passes what other threads write on."""

    def __init__(self, others):
        self.kept, self._others, self._thread = io.StringIO(), others, threading.get_ident()

    def write(self, text):
        return (self.kept if threading.get_ident() == self._thread else self._others).write(text)

    def flush(self):
        self._others.flush()


def crane_plan(*args) -> Completed:
    """``crane-plan ARGS`` (each argument as ``str``): its exit status, stdout and stderr."""
    # the test process's garbage, whose finalizers may write to stderr, collected before the capture and not
    # during it (on this thread)
    gc.collect()
    collecting = gc.isenabled()
    gc.disable()
    try:
        return _run(args)
    finally:
        if collecting:
            gc.enable()


def _run(args) -> Completed:
    out, err = io.StringIO(), _ThisThread(sys.stderr)
    with tempfile.TemporaryFile() as native:
        sys.stdout.flush()
        saved = os.dup(1)
        os.dup2(native.fileno(), 1)
        try:
            with redirect_stdout(out), redirect_stderr(err), warnings.catch_warnings():
                warnings.resetwarnings()  # a script's defaults, not the test run's
                for category in (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning):
                    warnings.simplefilter('ignore', category)
                warnings.showwarning = _show
                try:
                    code = main([str(a) for a in args])
                except SystemExit as exc:  # --help
                    code = exc.code
        finally:
            os.dup2(saved, 1)
            os.close(saved)
        native.seek(0)
        written = native.read().decode(errors='replace')
    return Completed(code, out.getvalue() + written, err.kept.getvalue())
