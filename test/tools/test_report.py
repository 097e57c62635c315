"""crane-plan report: where a recorded motion starts (its settle window counts from there)."""
import numpy as np
import pytest

from crane_planner.tools.report import streamed_starts

TICK = 1e-3


def reference(moving_from: float, moving_until: float, end: float = 6.0) -> np.ndarray:
    """A 1 kHz reference at rest, moving (a velocity not 0) over [moving_from, moving_until]."""
    t = np.arange(0.0, end, TICK)
    moving = ((t > moving_from + TICK / 2) & (t < moving_until)).astype(float)
    return np.column_stack([t, np.zeros_like(t), moving])


def test_a_motion_streamed_late_starts_where_the_reference_leaves_rest():
    """Stamped 1.0 s, it reached the streamer late and was streamed whole from 1.25 s: its first sample (at
    rest, its first knot) is there."""
    [(start, duration, goal)] = streamed_starts(reference(1.25, 4.25), [(1.0, 3.0, 0.3)])
    assert start == pytest.approx(1.25, abs=1e-9) and (duration, goal) == (3.0, 0.3)


def test_a_motion_on_time_starts_at_its_stamp():
    [(start, _, _)] = streamed_starts(reference(1.0, 4.0), [(1.0, 3.0, 0.3)])
    assert start == pytest.approx(1.0, abs=1e-9)


def test_a_handover_moving_at_its_stamp_and_a_recording_without_references_keep_the_stamp():
    ref = reference(1.0, 5.0)
    starts = streamed_starts(ref, [(1.0, 3.0, 0.3), (2.2, 2.8, 0.5)])
    assert starts[1][0] == 2.2
    assert streamed_starts(np.empty((0, 3)), [(1.0, 3.0, 0.3)]) == [(1.0, 3.0, 0.3)]
