"""IPOPT instances of a ``collocation.Transcription``: the per-iteration callback and the warm start kept.

IPOPT calls an ``IterationCallback`` after each iteration: it stops a solve
past its deadline; a server that runs solves side by side may give a
subclass that also paces them (``crane_planner.serving.yielding``).
"""
from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass

import casadi as ca

from .collocation import Transcription


class IterationCallback(ca.Callback):
    """IPOPT's per-iteration callback: stops a solve past its ``deadline``.

    Past a ``deadline`` it stops IPOPT at its next iteration (status
    ``User_Requested_Stop``): a request made of several solves (``fastest``)
    ends within its budget. ``between_iterations`` is the hook a subclass
    uses to act after each iteration (e.g. pace solves sharing a process:
    ``crane_planner.serving.yielding``).
    """

    def __init__(self, nx: int, ng: int, np_: int):
        ca.Callback.__init__(self)
        self._sizes = {'x': nx, 'lam_x': nx, 'g': ng, 'lam_g': ng, 'f': 1, 'lam_p': np_}
        self.start = self._last = 0.0
        self.deadline = math.inf
        self.construct('iteration', {})

    @contextlib.contextmanager
    def solving(self, deadline: float | None = None):
        """Around one IPOPT call: marks its start and stops it past ``deadline``
        (``time.perf_counter`` s), if given."""
        self.start = self._last = time.perf_counter()
        self.deadline = math.inf if deadline is None else deadline
        yield

    def between_iterations(self, now: float) -> None:
        """Called after each iteration within the deadline, ``now`` its end (``time.perf_counter`` s)."""

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return 'ret'

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self._sizes[ca.nlpsol_out(i)])

    def eval(self, arg):
        now = time.perf_counter()
        if now > self.deadline:
            return [1]
        self.between_iterations(now)
        self._last = time.perf_counter()
        return [0]


@dataclass
class Instance:
    """One IPOPT instance of a transcription, its iteration callback and the warm start it keeps."""

    transcription: Transcription
    solver: ca.Function
    callback: IterationCallback
    warm: tuple | None = None  # (sign of D, x0 / lam_x0 / lam_g0 of the solution)
    warm_state: tuple | None = None  # the same of the last plan from a state (``continuation``)
    T0: float | None = None  # free-time instances: the duration T = sigma T0 is scaled by
    options: dict | None = None  # what ``solver`` was made with (``refresh``)
    generation: int = 0  # the transcription's derivatives ``solver`` was made with

    @classmethod
    def new(cls, transcription: Transcription, options: dict, callback: IterationCallback,
            warm: tuple | None = None) -> 'Instance':
        """An IPOPT instance of ``transcription`` with ``options`` (their iteration callback ``callback``)."""
        generation = transcription.generation
        return cls(transcription, transcription.nlpsol(options), callback, warm, options=options,
                   generation=generation)

    def refresh(self) -> 'Instance':
        """Itself, its IPOPT instance made again if the transcription's derivatives were replaced since (by
        their compiled form: ``collocation.Transcription``); the warm starts are kept. Before a solve."""
        if self.generation != self.transcription.generation and self.options is not None:
            self.generation = self.transcription.generation
            self.solver = self.transcription.nlpsol(self.options)
        return self
