"""bag_io: schema text, QoS metadata, writing, reading with an independent decoder, recovery."""

import os

import pytest
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import Transform, Twist
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap_ros2._dynamic import generate_dynamic
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState, PointCloud2, PointField
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint

from replan_ros.recording import bag_io
from replan_ros.recording.bag_io import SEPARATOR, iter_decoded, message_definition
from replan_ros.recording.bag_writer import BagWriter, recover
from replan_ros.transport.stamped_buffer import cdr_header_stamp_ns


def _msg_file(package, name):
    return (bag_io.interface_share_dir(package) / 'msg' / f'{name}.msg').read_text()


def test_schema_text_is_the_rosbag2_concatenation_of_installed_definitions():
    text = message_definition('nav_msgs/msg/Odometry')
    parts = text.split(f'\n{SEPARATOR}\n')
    assert parts[0] == _msg_file('nav_msgs', 'Odometry')
    headers = [p.split('\n', 1)[0] for p in parts[1:]]
    # Depth first, dependencies of each type in sorted order, every type once.
    assert headers == [
        'MSG: geometry_msgs/PoseWithCovariance', 'MSG: geometry_msgs/Pose',
        'MSG: geometry_msgs/Point', 'MSG: geometry_msgs/Quaternion',
        'MSG: geometry_msgs/TwistWithCovariance', 'MSG: geometry_msgs/Twist',
        'MSG: geometry_msgs/Vector3', 'MSG: std_msgs/Header', 'MSG: builtin_interfaces/Time']
    for part in parts[1:]:
        header, body = part.split('\n', 1)
        package, name = header[len('MSG: '):].split('/')
        assert body == _msg_file(package, name)


@pytest.mark.parametrize('type_name', [
    'sensor_msgs/msg/JointState', 'nav_msgs/msg/Odometry', 'sensor_msgs/msg/PointCloud2',
    'trajectory_msgs/msg/MultiDOFJointTrajectory', 'geometry_msgs/msg/WrenchStamped',
    'geometry_msgs/msg/TwistStamped', 'nav_msgs/msg/Path', 'rosgraph_msgs/msg/Clock',
    'visualization_msgs/msg/MarkerArray', 'diagnostic_msgs/msg/DiagnosticArray'])
def test_schema_text_parses_with_mcap_ros2(type_name):
    decoders = generate_dynamic(type_name, message_definition(type_name))
    assert type_name in decoders


def test_unknown_type_is_rejected():
    with pytest.raises(ValueError):
        message_definition('not a type')
    with pytest.raises((LookupError, FileNotFoundError)):
        message_definition('sensor_msgs/msg/NoSuchType')


def test_header_detection_and_stamp_extraction():
    assert bag_io.has_header('sensor_msgs/msg/JointState')
    assert bag_io.has_header('std_msgs/msg/Header') is False
    assert not bag_io.has_header('rosgraph_msgs/msg/Clock')
    assert not bag_io.has_header('geometry_msgs/msg/Twist')
    msg = JointState()
    msg.header.stamp = Time(sec=12, nanosec=345)
    assert cdr_header_stamp_ns(serialize_message(msg)) == 12_000_000_345


def test_qos_metadata_round_trip():
    offered = [QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL)]
    text = bag_io.qos_profiles_yaml(offered)
    assert 'reliability: reliable' in text and 'durability: transient_local' in text
    qos = bag_io.qos_from_yaml(text)
    assert qos.reliability == ReliabilityPolicy.RELIABLE
    assert qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
    # The metadata version 8 spelling (integers) is read too.
    old = bag_io.qos_from_yaml('- history: 3\n  depth: 0\n  reliability: 2\n  durability: 2\n'
                               '  deadline: {sec: 0, nsec: 0}\n  lifespan: {sec: 0, nsec: 0}\n'
                               '  liveliness: 1\n  liveliness_lease_duration: {sec: 0, nsec: 0}\n'
                               '  avoid_ros_namespace_conventions: false\n')
    assert old.reliability == ReliabilityPolicy.BEST_EFFORT
    assert bag_io.qos_from_yaml('') is None


def _sample_messages():
    js = JointState(name=['lf_haa_joint', 'rf_haa_joint'], position=[0.1, -0.2],
                    velocity=[1.0, 2.0], effort=[3.5, -4.5])
    js.header.stamp = Time(sec=1, nanosec=4_000_000)
    odom = Odometry(child_frame_id='base_link')
    odom.header.frame_id = 'odom'
    odom.pose.pose.position.x = 0.25
    odom.pose.covariance[7] = 0.5
    odom.twist.twist.angular.z = -0.75
    cloud = PointCloud2(height=1, width=2, point_step=8, row_step=16, is_dense=True,
                        fields=[PointField(name='x', offset=0, datatype=PointField.FLOAT64,
                                           count=1)],
                        data=bytes(range(16)))
    traj = MultiDOFJointTrajectory(joint_names=['com'], points=[
        MultiDOFJointTrajectoryPoint(transforms=[Transform()], velocities=[Twist()],
                                     accelerations=[Twist()],
                                     time_from_start=Duration(sec=0, nanosec=20_000_000))])
    traj.points[0].transforms[0].translation.z = 0.6
    return {'/joint_states': js, '/odom': odom, '/contacts': cloud, '/com_plan': traj}


def test_written_bag_decodes_with_an_independent_reader(tmp_path):
    path = tmp_path / 'bag.mcap'
    samples = _sample_messages()
    writer = BagWriter(path, chunk_size=2048)
    ids = {t: writer.add_channel(t, type(m).__module__.split('.')[0] + '/msg/'
                                 + type(m).__name__)
           for t, m in samples.items()}
    writer.add_metadata('replan_run', {'git_revision': 'abc'})
    for k in range(50):
        for topic, msg in samples.items():
            writer.write(ids[topic], serialize_message(msg), log_time=k * 4_000_000,
                         publish_time=k * 4_000_000 + 1)
    writer.close()

    with open(path, 'rb') as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert reader.get_header().profile == 'ros2'
        assert summary.statistics.message_count == 200
        assert summary.statistics.chunk_count > 1
        assert all(s.encoding == 'ros2msg' for s in summary.schemas.values())
        assert all(c.message_encoding == 'cdr' for c in summary.channels.values())
        assert all('offered_qos_profiles' in c.metadata for c in summary.channels.values())
        assert {c.compression for c in summary.chunk_indexes} == {'zstd'}
        names = {m.name for m in reader.iter_metadata()}
        assert {'rosbag2', 'replan_run'} <= names

    count = 0
    for topic, log_time, publish_time, decoded in iter_decoded(path):
        count += 1
        assert publish_time == log_time + 1
        expected = samples[topic]
        if topic == '/joint_states':
            assert list(decoded.name) == expected.name
            assert list(decoded.effort) == list(expected.effort)
            assert decoded.header.stamp.nanosec == 4_000_000
        elif topic == '/odom':
            assert decoded.pose.pose.position.x == 0.25
            assert decoded.pose.covariance[7] == 0.5
            assert decoded.twist.twist.angular.z == -0.75
            assert decoded.child_frame_id == 'base_link'
        elif topic == '/contacts':
            assert bytes(decoded.data) == bytes(range(16))
            assert decoded.fields[0].name == 'x'
        else:
            assert decoded.points[0].transforms[0].translation.z == 0.6
            assert decoded.points[0].time_from_start.nanosec == 20_000_000
    assert count == 200


def _write_bag(path, n, chunk_size):
    writer = BagWriter(path, chunk_size=chunk_size)
    cid = writer.add_channel('/joint_states', 'sensor_msgs/msg/JointState')
    writer.add_metadata('replan_run', {'git_revision': 'abc'})
    for k in range(n):
        msg = JointState(position=[float(k)])
        writer.write(cid, serialize_message(msg), log_time=k, publish_time=k)
    return writer


def _last_chunk_offset(data: bytes) -> int:
    offset, last = 8, None
    while offset + 9 <= len(data):
        if data[offset] == 0x06:   # Chunk opcode
            last = offset
        offset += 9 + int.from_bytes(data[offset + 1:offset + 9], 'little')
    return last


def test_recover_keeps_every_finished_chunk_of_a_truncated_file(tmp_path):
    src = tmp_path / 'killed.mcap'
    writer = _write_bag(src, 1000, chunk_size=4096)
    writer.flush()
    finished = writer.message_count
    chunks = writer.chunk_count
    size = os.path.getsize(src)   # the file as a SIGKILL right now would leave it
    # No summary, no footer: the normal reader cannot use it.
    with open(src, 'rb') as stream, pytest.raises(McapError):
        list(make_reader(stream).iter_messages())

    out = tmp_path / 'recovered.mcap'
    report = recover(src, out)
    assert report.messages == finished and report.chunks == chunks
    positions = [d.position[0] for _, _, _, d in iter_decoded(out)]
    assert positions == [float(k) for k in range(finished)]
    names = {m.name for m in make_reader(open(out, 'rb')).iter_metadata()}  # noqa: SIM115
    assert 'replan_run' in names

    # Cut inside the last chunk: exactly the chunks before it survive.
    data = src.read_bytes()
    assert len(data) == size
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[:_last_chunk_offset(data) + 100])
    report = recover(cut, tmp_path / 'cut_recovered.mcap')
    assert report.chunks == chunks - 1
    positions = [d.position[0] for _, _, _, d in iter_decoded(tmp_path / 'cut_recovered.mcap')]
    assert positions == [float(k) for k in range(len(positions))]
    assert 0 < len(positions) < finished
    writer.close()


def test_recover_copies_a_complete_bag_whole(tmp_path):
    src = tmp_path / 'done.mcap'
    _write_bag(src, 300, chunk_size=4096).close()
    report = recover(src, tmp_path / 'copy.mcap')
    assert report.had_footer and report.messages == 300
