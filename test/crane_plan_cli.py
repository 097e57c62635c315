"""``crane-plan`` run in the test process through ``cli.main``: what the console script runs, without
starting Python and its imports again for each call (a few seconds each on a busy 2-core machine). The
installed executable itself is run by a few tests in ``tools/test_cli.py``.

What the executable would show is kept: its exit status; stdout as the process's file descriptor 1 gets it
(so output written there natively, by IPOPT or CasADi, is seen too: the JSON must stay clean); stderr with
the Python warnings a script prints (Python's default filters). Native writes to stderr are not taken: in a
ROS test the middleware and the harness's node log there from other threads meanwhile.
"""
import io
import os
import sys
import tempfile
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


def crane_plan(*args) -> Completed:
    """``crane-plan ARGS`` (each argument as ``str``): its exit status, stdout and stderr."""
    out, err = io.StringIO(), io.StringIO()
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
    return Completed(code, out.getvalue() + written, err.getvalue())
