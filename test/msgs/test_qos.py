"""crane_msgs_py.runtime.qos: a recording reader's queue is deeper, every other policy the publisher's."""
from crane_msgs_py.runtime.qos import JOINT_STATES_QOS, MARKERS_QOS, REFERENCE_EVERY_SAMPLE_QOS, recording


def test_a_recording_profile_holds_the_seconds_asked_and_matches_the_publisher_otherwise():
    for profile, rate in ((JOINT_STATES_QOS, 50.0), (MARKERS_QOS, 50.0), (REFERENCE_EVERY_SAMPLE_QOS, 1000.0)):
        deep = recording(profile, 10.0, rate)
        assert deep.depth == round(10.0 * rate)
        assert (deep.history, deep.reliability, deep.durability) == (profile.history, profile.reliability,
                                                                     profile.durability)
    assert JOINT_STATES_QOS.depth == 25 and MARKERS_QOS.depth == 5  # the originals are untouched
    assert recording(REFERENCE_EVERY_SAMPLE_QOS, 0.1, 1000.0).depth == 1000  # never shallower
