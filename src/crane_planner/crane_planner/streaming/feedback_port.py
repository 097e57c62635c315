"""The sway feedback as the streamer node holds it: made when first switched on, put in the streamer's chain of
corrections, fed joint_states, switched by the parameters, and reported.

The design (``sway_law.Schedule``: a law and a gain per cable length the
hoist's range allows) takes a moment, so it is made only once the feedback is
first switched on, on the executor's thread; the loop then finds it in the
streamer's ``corrections`` at its next tick. Pure Python, no ROS import.
"""
from __future__ import annotations

from crane_msgs_py.crane.axes import AXIS_NAMES
from crane_msgs_py.messages.names import HOIST_JOINT

from .config import StreamerConfig
from .streamer import Streamer
from .sway_feedback import FeedbackState, SwayFeedback


class FeedbackPort:
    """The node's sway feedback (see the module docstring).

    Args:
        streamer: whose chain of corrections it joins.
        joints: the streamed joints.
        period: the streamer's tick (s).
        noise: ``feedback_noise`` (rad).
    """

    def __init__(self, streamer: Streamer, joints, period: float, noise: float):
        self.streamer, self.joints, self.period, self.noise = streamer, tuple(joints), period, noise
        self.feedback: SwayFeedback | None = None

    def configure(self, config: StreamerConfig, log) -> None:
        """Switch it as ``config`` says (made at its first switch on); ``log(text)`` says what changed."""
        fb = self.feedback
        if fb is None and not config.feedback:
            return
        if fb is None:
            limits = {name: config.operator.limits[AXIS_NAMES.index(name)] for name in self.joints}
            lengths = config.operator.hoist_range if HOIST_JOINT in self.joints else None
            fb = SwayFeedback(self.joints, config.model, self.period, limits, config.feedback_timeout, self.noise,
                              lengths, on=False)
            self.feedback = fb
            self.streamer.corrections = (fb,)
        fb.timeout = config.feedback_timeout
        was_on = fb.state is not FeedbackState.OFF or fb.switching_on
        fb.enable(config.feedback)
        if config.feedback != was_on:
            log('sway feedback on: correcting the swing measured on joint_states' if config.feedback else
                'sway feedback off: a correction left fades to zero')

    def measure(self, stamp_ns: int, names, positions) -> None:
        """A joint_states message: its angles, if the feedback is on."""
        if self.feedback is not None and self.feedback.state is not FeedbackState.OFF:
            self.feedback.measure(stamp_ns, dict(zip(names, positions)))

    def reset(self) -> None:
        """The stream starts again from a new hold: no correction carried over."""
        if self.feedback is not None:
            self.feedback.reset()

    def corrections(self) -> tuple | None:
        """The correction in the newest setpoint, per streamed joint (m; 0 for one it does not correct); None
        before it was ever on. The loop's (what stream_state carries)."""
        if self.feedback is None:
            return None
        applied = self.feedback.correction()
        return tuple(applied.get(joint, 0.0) for joint in self.joints)

    def status(self) -> dict:
        """Its values on /diagnostics: its state, each corrected axis's correction now and its largest since the
        last report (m), and the measurements it could not use."""
        fb = self.feedback
        if fb is None:
            return {'feedback': 'off'}
        peaks = fb.take_peak()
        return {'feedback': fb.state.value,
                **{f'{joint}_correction': value for joint, value in fb.correction().items()},
                **{f'{joint}_correction_peak': value for joint, value in peaks.items()},
                'feedback_measurements_unused': fb.ignored}
