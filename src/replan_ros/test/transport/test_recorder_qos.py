"""The recorder's subscriptions keep every sample until taken, and the writers of the per-tick
topics keep a deep history for it, without changing what any reader matches."""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

from replan_ros.transport import qos


def test_the_recorder_keeps_all_and_follows_its_publishers():
    profile, reliable, latched = qos.recorder_qos([qos.SENSOR_PUB, qos.SENSOR_PUB])
    assert profile.history == HistoryPolicy.KEEP_ALL
    assert (reliable, latched) == (True, False)
    profile, reliable, latched = qos.recorder_qos([qos.LATCHED])
    assert profile.durability == DurabilityPolicy.TRANSIENT_LOCAL and latched
    profile, reliable, _ = qos.recorder_qos([qos.SENSOR_PUB, qos.SENSOR])
    assert profile.reliability == ReliabilityPolicy.BEST_EFFORT and not reliable
    profile, _, _ = qos.recorder_qos([qos.COMMAND], depth=5)
    assert (profile.history, profile.depth) == (HistoryPolicy.KEEP_LAST, 5)


def test_recorded_writers_differ_from_their_readers_in_depth_only():
    for pub, sub in ((qos.CONTACTS_PUB, qos.CONTACTS), (qos.COMMAND_PUB, qos.COMMAND),
                     (qos.CLOCK_PUB, qos.CLOCK)):
        assert pub.depth > sub.depth
        assert (pub.history, pub.reliability, pub.durability) == \
            (sub.history, sub.reliability, sub.durability)
    # KEEP_LAST: a writer never waits for a slow or dead reader (the recorder).
    for pub in (qos.SENSOR_PUB, qos.CONTACTS_PUB, qos.COMMAND_PUB, qos.CLOCK_PUB):
        assert pub.history == HistoryPolicy.KEEP_LAST
    assert qos.SENSOR_PUB.depth == qos.RECORDED_HISTORY
