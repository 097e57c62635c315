"""``crane-plan`` run in the test process through ``cli.main``: what the console script runs, without
starting Python and its imports again for each call (a few seconds each on a busy 2-core machine). The
installed executable itself is run by a few tests in ``tools/test_cli.py``."""
import io
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass

from crane_planner.tools.cli import main


@dataclass
class Completed:
    """What ``subprocess.run(..., capture_output=True, text=True)`` would give."""
    returncode: int
    stdout: str
    stderr: str


def crane_plan(*args: str) -> Completed:
    """``crane-plan ARGS``: its exit status, stdout and stderr (argparse's refusals exit, as the script does)."""
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        try:
            code = main([str(a) for a in args])
        except SystemExit as exc:
            code = exc.code
    return Completed(code, out.getvalue(), err.getvalue())
