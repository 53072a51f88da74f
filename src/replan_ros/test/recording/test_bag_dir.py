"""bag_dir: the bag directory's metadata.yaml, read by rosbags as rosbag2 would read it."""

from pathlib import Path

import yaml
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability, QosReliability
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from std_msgs.msg import String

from replan_ros.recording import bag_io
from replan_ros.recording.bag_dir import METADATA_FILE, main, write_directory_metadata
from replan_ros.recording.bag_io import summarize
from replan_ros.recording.bag_writer import BagWriter, recover

STRING = 'std_msgs/msg/String'
ODOM = 'nav_msgs/msg/Odometry'
# The real hash: AnyReader checks it against the message definition in the bag.
ODOM_HASH = get_typestore(Stores.ROS2_JAZZY).hash_rihs01(ODOM)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _odom(k: int) -> Odometry:
    msg = Odometry(child_frame_id='base_link')
    msg.header.frame_id = 'odom'
    msg.header.stamp.sec = k
    msg.pose.pose.position.x = 0.01 * k
    msg.twist.twist.angular.z = -0.5 * k
    return msg


def _write(path: Path, start_ns: int, n: int, tag: str = '') -> list[tuple[str, int, bytes]]:
    """A bag of ``n`` /odom and ``n // 2`` /chatter messages from ``start_ns`` (10 ms apart);
    returns (topic, log time, CDR) of every message written."""
    writer = BagWriter(path, chunk_size=2048)
    odom = writer.add_channel('/odom', ODOM, bag_io.qos_profiles_yaml([QoSProfile(depth=10)]),
                              ODOM_HASH)
    chatter = writer.add_channel('/chatter', STRING, bag_io.qos_profiles_yaml([LATCHED]))
    written = []
    for k in range(n):
        t = start_ns + k * 10_000_000
        data = serialize_message(_odom(k))
        writer.write(odom, data, log_time=t, publish_time=t)
        written.append(('/odom', t, data))
        if k % 2 == 0:
            data = serialize_message(String(data=f'{tag}hello {k}'))
            writer.write(chatter, data, log_time=t + 1, publish_time=t + 1)
            written.append(('/chatter', t + 1, data))
    writer.close()
    return written


def test_closed_bag_directory_opens_with_the_rosbag2_reader(tmp_path):
    bag = tmp_path / 'bag'
    bag.mkdir()
    start = 5_000_000_000
    written = _write(bag / 'run.mcap', start, 40)
    assert (bag / METADATA_FILE).is_file()

    with Reader(bag) as reader:
        topics = {c.topic: c for c in reader.connections}
        assert {t: c.msgtype for t, c in topics.items()} == {'/odom': ODOM, '/chatter': STRING}
        assert topics['/odom'].msgcount == 40 and topics['/chatter'].msgcount == 20
        assert topics['/odom'].digest == ODOM_HASH
        qos = topics['/chatter'].ext.offered_qos_profiles[0]
        assert qos.reliability == QosReliability.RELIABLE
        assert qos.durability == QosDurability.TRANSIENT_LOCAL
        assert reader.message_count == 60
        assert reader.start_time == start
        last = written[-1][1]
        # rosbags reports end = start + duration + 1 (its end is exclusive).
        assert reader.duration == last - start + 1
        assert reader.ros_distro == 'jazzy'
        read = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
    assert read == sorted(written, key=lambda m: m[1])

    with AnyReader([bag]) as reader:
        decoded = [(c.topic, reader.deserialize(d, c.msgtype))
                   for c, _, d in reader.messages()]
    odoms = [m for t, m in decoded if t == '/odom']
    assert [m.pose.pose.position.x for m in odoms] == [0.01 * k for k in range(40)]
    assert [m.header.stamp.sec for m in odoms] == list(range(40))
    assert [m.data for t, m in decoded if t == '/chatter'] == [
        f'hello {k}' for k in range(0, 40, 2)]


def test_metadata_counts_equal_the_mcap_summary(tmp_path):
    _write(tmp_path / 'run.mcap', 1_000, 25)
    info = yaml.safe_load((tmp_path / METADATA_FILE).read_text())['rosbag2_bagfile_information']
    summary = summarize(tmp_path / 'run.mcap')
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    assert info['message_count'] == summary.message_count == 38
    assert {t['topic_metadata']['name']: t['message_count']
            for t in info['topics_with_message_count']} == {
        t.topic: t.message_count for t in summary.topics.values()}
    assert info['starting_time']['nanoseconds_since_epoch'] == summary.start_ns
    assert info['duration']['nanoseconds'] == summary.end_ns - summary.start_ns
    assert info['relative_file_paths'] == ['run.mcap']
    assert info['files'] == [{
        'path': 'run.mcap', 'starting_time': {'nanoseconds_since_epoch': summary.start_ns},
        'duration': {'nanoseconds': summary.end_ns - summary.start_ns},
        'message_count': summary.message_count}]
    topic = info['topics_with_message_count'][0]['topic_metadata']
    assert topic['serialization_format'] == 'cdr'
    assert topic['offered_qos_profiles'][0]['history'] == 'keep_last'
    assert info['compression_format'] == '' and info['compression_mode'] == ''
    assert info['custom_data'] == {} and info['ros_distro'] == 'jazzy'


def test_two_files_in_a_directory_read_as_one_bag(tmp_path):
    first = _write(tmp_path / 'run_0.mcap', 1_000_000_000, 30, tag='a ')
    second = _write(tmp_path / 'run_1.mcap', 2_000_000_000, 10, tag='b ')
    info = yaml.safe_load((tmp_path / METADATA_FILE).read_text())['rosbag2_bagfile_information']
    assert info['relative_file_paths'] == ['run_0.mcap', 'run_1.mcap']
    assert [f['message_count'] for f in info['files']] == [45, 15]
    assert info['message_count'] == 60
    assert info['starting_time']['nanoseconds_since_epoch'] == 1_000_000_000
    assert info['duration']['nanoseconds'] == second[-1][1] - 1_000_000_000
    with AnyReader([tmp_path]) as reader:
        assert reader.message_count == 60
        counts = {c.topic: c.msgcount for c in reader.connections}
        read = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
    assert counts == {'/odom': 40, '/chatter': 20}
    assert read == sorted(first + second, key=lambda m: m[1])


def test_rewrite_after_recovery_lists_the_recovered_copy(tmp_path, capsys):
    src = tmp_path / 'killed.mcap'
    writer = BagWriter(src, chunk_size=1024)
    cid = writer.add_channel('/chatter', STRING)
    for k in range(200):
        writer.write(cid, serialize_message(String(data=str(k))), log_time=k, publish_time=k)
    writer.flush()
    kept = writer.message_count
    # As a SIGKILL leaves it: no summary, no metadata.yaml.
    assert not (tmp_path / METADATA_FILE).exists()
    report = write_directory_metadata(tmp_path)
    assert report.path is None and report.skipped[0][0] == 'killed.mcap'

    recover(src, tmp_path / 'killed.recovered.mcap')
    assert main([str(tmp_path)]) == 0
    assert 'killed.mcap: left out' in capsys.readouterr().out
    info = yaml.safe_load((tmp_path / METADATA_FILE).read_text())['rosbag2_bagfile_information']
    assert [f['path'] for f in info['files']] == ['killed.recovered.mcap']
    with Reader(tmp_path) as reader:
        assert reader.message_count == kept
    writer.close()   # the source completed later: still replaced by its recovered copy
    info = yaml.safe_load((tmp_path / METADATA_FILE).read_text())['rosbag2_bagfile_information']
    assert info['relative_file_paths'] == ['killed.recovered.mcap']
