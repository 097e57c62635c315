"""A goal whose reference the streamer's sway feedback corrected (serving.execution, serving.following): the
settle window starts once the corrected reference has settled at the goal, the residual is measured over it, and
the result says how far the correction moved the axes. On the fake crane (``fake_crane``)."""
import math

import pytest

from crane_planner.planning.signals import Swing
from crane_planner.serving.execution import AT_GOAL, STILL
from crane_planner.serving.transitions import JointReading, Measurement
from serving.fake_crane import MS, T0, Crane, move

END = T0 + 2_000 * MS  # the motion's end (a 2 s move sent at once starts within a tick of T0)


def correction(now: int) -> float:
    """3 mm at the end of the motion, decaying with a 0.3 s time constant after it (as the feedback's return)."""
    return 0.0 if now < END - 500 * MS else 0.003 * math.exp(-max(0, now - END) * 1e-9 / 0.3)


def swinging(crane, stop_ns: int):
    """joint_states every 20 ms: the load 5 mm aside until ``stop_ns``, then quiet."""
    due = [crane.clock()]

    def measure(now):
        if now >= due[0]:
            due[0] = now + 20 * MS
            theta = math.asin(0.005 / 0.861) if now < stop_ns else 0.0
            crane.service.on_joint_state(Measurement(now, {'cart': JointReading(crane.hold)}, Swing(theta1=theta)))
    crane.clock.hooks.append(measure)


def test_the_window_starts_once_the_corrected_reference_is_back_at_the_goal_and_the_result_names_the_correction():
    crane = Crane(correction=correction)
    swinging(crane, END + 600 * MS)  # the swing damped 0.6 s after the end: before the reference settled
    goal = crane.goal('a', move(0.3, 2.0))
    outcome, _ = crane.execute(goal, move(0.3, 2.0), settle=0.5)
    execution = goal.execution
    # the reference within AT_GOAL of the goal and slower than STILL from 0.3 ln(3 mm / the nearer) s after the end
    settled = END + round(0.3 * math.log(0.003 / min(AT_GOAL, 0.3 * STILL)) * 1e9)
    assert settled <= execution.window_start_ns <= settled + 120 * MS  # (stream_state every 20-50 ms here)
    assert outcome.success and outcome.residual_swing == 0.0
    assert outcome.correction == pytest.approx(0.003, rel=0.05)
    assert 'the sway feedback having moved the axes up to 3.0' in outcome.message


def test_without_a_correction_the_window_starts_at_the_end_and_the_swing_there_counts():
    crane = Crane()
    swinging(crane, END + 600 * MS)
    goal = crane.goal('a', move(0.3, 2.0))
    outcome, _ = crane.execute(goal, move(0.3, 2.0), settle=0.5)
    assert goal.execution.window_start_ns == goal.execution.end_ns
    assert outcome.how == 'abort' and outcome.residual_swing == pytest.approx(0.005, rel=1e-3)
    assert outcome.correction < 1e-6 and 'sway feedback' not in outcome.message
