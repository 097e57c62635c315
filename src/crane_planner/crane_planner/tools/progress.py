"""Progress of the longer commands: a bar on stderr when it is a terminal (tqdm), plain lines otherwise.

Never on stdout (which carries tables and JSON), so ``--json`` output and
pipes stay clean; a log file or CI gets one line per step instead of a bar's
carriage returns. Pure Python, no ROS import.
"""
from __future__ import annotations

import sys


class Progress:
    """``total`` steps of ``what``; ``step(note)`` after each, ``close()`` at the end (or use ``with``).

    Args:
        prog: the command's name, prefixed to plain lines.
        stream: where to write (default stderr); a terminal gets a bar.
    """

    def __init__(self, total: int, what: str, prog: str, stream=None):
        self.total, self.what, self.prog, self.done = total, what, prog, 0
        self._stream = stream or sys.stderr
        self._bar = None
        if getattr(self._stream, 'isatty', lambda: False)():
            from tqdm import tqdm
            self._bar = tqdm(total=total, desc=what, file=self._stream, leave=False, unit='step')

    def step(self, note: str = ''):
        self.done += 1
        if self._bar is not None:
            self._bar.set_postfix_str(note, refresh=False)
            self._bar.update(1)
        else:
            print(f'{self.prog}: {self.what} {self.done}/{self.total}' + (f' {note}' if note else ''),
                  file=self._stream, flush=True)

    def close(self):
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
