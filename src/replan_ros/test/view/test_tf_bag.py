"""state_view + bag_io: /tf (tf2_msgs, no Python class) and /robot_description written into an
mcap bag decode with an independent reader (rosbags), and the derived markers and figures
say what they should. No DDS."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import Point, Vector3Stamped
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.highlevel import AnyReader
from std_msgs.msg import ColorRGBA, Float64
from visualization_msgs.msg import Marker, MarkerArray

from replan_core.common.types import STANDING_POSE, BaseState, ContactState, JointState
from replan_core.robot.frames import LinkFrames, base_transform
from replan_ros.messages.contacts import contacts_to_msg
from replan_ros.messages.joint_state import joint_state_to_msg
from replan_ros.messages.odom import encode_odom, odom_fields_from_cdr, odom_from_base_state
from replan_ros.recording.bag_io import qos_profiles_yaml
from replan_ros.recording.bag_writer import BagWriter
from replan_ros.transport.qos import LATCHED
from replan_ros.view.state_view import (
    COP_MARGIN_TOPIC,
    DERIVED_TOPICS,
    FORCES_TOPIC,
    TF_TOPIC,
    TF_TYPE,
    VELOCITY_ERROR_TOPIC,
    MarkerSpec,
    StateView,
    default_urdf_path,
    definition,
    encode_float64,
    encode_markers,
    encode_tf,
    encode_vector3_stamped,
)

DT = 0.004


@pytest.fixture(scope='module')
def view():
    return StateView(period=0.02)


def state(t: float, x: float = 0.1) -> tuple[bytes, bytes]:
    joints = JointState(t, STANDING_POSE + 0.01 * t, np.zeros(12), np.zeros(12))
    base = BaseState(t, np.array([x + 0.1 * t, -0.05, 0.6]),
                     np.array([0.0, 0.0, np.sin(0.1), np.cos(0.1)]), np.zeros(3), np.zeros(3))
    return (bytes(serialize_message(joint_state_to_msg(joints))),
            bytes(serialize_message(odom_from_base_state(base))))


def test_tf_pairs_odom_and_joints_by_stamp_in_any_order_once_per_period():
    view = StateView(period=0.02)
    out = []
    for k in range(50):                         # 0.2 s of ticks
        joints, odom = state(k * DT)
        first, second = (('/odom', odom), ('/joint_states', joints)) if k % 2 else (
            ('/joint_states', joints), ('/odom', odom))
        out += view.feed(*first) + view.feed(*second)
    tf = [d for d in out if d.topic == TF_TOPIC]
    assert [d.stamp_ns for d in tf] == [round(k * DT * 1e9) for k in range(0, 50, 5)]
    assert len([d for d in out if d.topic == VELOCITY_ERROR_TOPIC]) == len(tf)
    # Only one of the two: nothing to pair.
    lonely = StateView(period=0.02)
    assert lonely.feed('/odom', state(0.0)[1]) == []


def test_tf_pairs_a_topic_that_arrives_a_retransmission_late():
    """A reliable reader that lost a sample gets that writer's later samples only after the
    resend, a heartbeat (100 ms, 25 ticks) later, in a burst: every /tf due still comes."""
    view = StateView(period=0.04)
    states = [state(k * DT) for k in range(100)]
    late = 40                                   # ticks /odom arrives behind /joint_states
    out = []
    for k in range(100 + late):
        if k < 100:
            out += view.feed('/joint_states', states[k][0])
        if k >= late:
            out += view.feed('/odom', states[k - late][1])
    tf = [d.stamp_ns for d in out if d.topic == TF_TOPIC]
    assert tf == [round(k * DT * 1e9) for k in range(0, 100, 10)]


def test_bag_tf_and_description_decode_with_rosbags(tmp_path, view):
    path = tmp_path / 'view.mcap'
    writer = BagWriter(path)
    items = [view.description()]
    for k in range(25):
        joints, odom = state(1.0 + k * DT)
        items += view.feed('/joint_states', joints) + view.feed('/odom', odom)
    channels = {}
    for item in items:
        if item.topic not in channels:
            channels[item.topic] = writer.add_channel(
                item.topic, item.type_name, qos_profiles_yaml([LATCHED]),
                definition=definition(item.type_name))
        writer.write(channels[item.topic], item.data, item.stamp_ns, item.stamp_ns)
    writer.close()

    with AnyReader([Path(path)]) as reader:
        by_topic = {c.topic: c for c in reader.connections}
        assert by_topic['/tf'].msgtype == 'tf2_msgs/msg/TFMessage'
        (description,) = [reader.deserialize(raw, c.msgtype) for c, _t, raw in
                          reader.messages(connections=[by_topic['/robot_description']])]
        assert description.data == Path(default_urdf_path()).read_text()
        messages = [reader.deserialize(raw, c.msgtype) for c, _t, raw in
                    reader.messages(connections=[by_topic['/tf']])]
    assert len(messages) == 5
    msg = messages[-1]
    base = msg.transforms[0]
    assert (base.header.frame_id, base.child_frame_id) == ('odom', 'base_link')
    t = 1.0 + 20 * DT
    assert base.header.stamp.sec == 1 and abs(base.header.stamp.nanosec - 80_000_000) < 2
    np.testing.assert_allclose([base.transform.translation.x, base.transform.rotation.z],
                               [0.1 + 0.1 * t, np.sin(0.1)], atol=1e-12)
    expected = LinkFrames(default_urdf_path()).link_transforms(STANDING_POSE + 0.01 * t)
    assert [(m.header.frame_id, m.child_frame_id) for m in msg.transforms[1:]] == [
        (e.parent, e.child) for e in expected]
    for got, want in zip(msg.transforms[1:], expected, strict=True):
        np.testing.assert_allclose([got.transform.translation.x, got.transform.translation.y,
                                    got.transform.translation.z], want.translation, atol=1e-12)


def test_force_markers_cop_and_polygon(view):
    feet = np.array([[0.4, 0.3, 0.0], [0.4, -0.3, 0.0], [-0.4, 0.3, 0.0], [-0.4, -0.3, 0.0]])
    forces = np.array([[0.0, 0.0, 300.0], [0.0, 0.0, 300.0], [0.0, 0.0, 300.0],
                       [0.0, 0.0, 0.0]])                     # rh in swing
    contacts = ContactState(3.0, feet, forces, np.array([1, 1, 1, 0], bool),
                            np.zeros(4, bool), np.zeros(4, bool))
    out = {d.topic: d for d in view.feed('/ground_truth/contacts',
                                         bytes(serialize_message(contacts_to_msg(contacts))))}
    markers = deserialize_message(out[FORCES_TOPIC].data, MarkerArray).markers
    assert markers[0].action == Marker.DELETEALL
    arrows = [m for m in markers if m.type == Marker.ARROW and m.action == Marker.ADD]
    assert sorted(m.id for m in arrows) == [0, 1, 2]
    assert arrows[0].points[1].z == pytest.approx(300.0 * view.force_scale)
    (polygon,) = [m for m in markers if m.type == Marker.LINE_STRIP]
    assert len(polygon.points) == 4 and polygon.points[0] == polygon.points[-1]   # closed
    (cop,) = [m for m in markers if m.type == Marker.SPHERE]
    assert (cop.pose.position.x, cop.pose.position.y) == pytest.approx((0.4 / 3, 0.1))
    margin = deserialize_message(out[COP_MARGIN_TOPIC].data, Float64).data
    # The nearest edge of the triangle lf, rf, lh is rf-lh (0.6 x + 0.8 y = 0): 0.16 m.
    assert margin == pytest.approx(0.6 * 0.4 / 3 + 0.8 * 0.1)
    assert cop.color.g > cop.color.r                       # inside: green


def test_malformed_input_is_skipped(view):
    assert view.feed('/ground_truth/contacts', b'\x00\x01\x00\x00garbage') == []
    assert view.feed('/diagnostics', b'') == []


def test_shipped_layout_names_only_topics_that_exist():
    layout = json.loads((Path(__file__).resolve().parents[4] / 'config' / 'foxglove'
                         / 'replan.json').read_text())
    graph = {'/odom', '/velocity_setpoint', '/gait_markers', '/com_path', '/zmp_plan',
             '/contacts', '/footholds', '/diagnostics', '/cmd_vel'}
    known = graph | set(DERIVED_TOPICS)
    panels = layout['configById']
    used = set(panels['3D!robot']['topics'])
    for name, config in panels.items():
        if name.startswith('Plot!'):
            used |= {re.match(r'(/[\w/]+)\.', p['value']).group(1) for p in config['paths']}
    used |= {panels['Teleop!teleop']['topic'], panels['DiagnosticSummary!diag']['topicToRender']}
    assert used <= known, used - known
    assert {'/robot_description', '/view/contact_forces', '/view/cop_margin',
            '/view/mpc_solve_time_ms'} <= used


def test_tf_encoder_writes_the_bytes_of_the_generic_encoder(view):
    from mcap_ros2._dynamic import serialize_dynamic

    generic = serialize_dynamic(TF_TYPE, definition(TF_TYPE))[TF_TYPE]
    transforms = [base_transform((1.0, -2.0, 0.5), (0.0, 0.0, 0.6, 0.8), 'odom', 'base_link'),
                  *view.frames.link_transforms(STANDING_POSE)]
    stamp = 12_345_678_901
    expected = generic({'transforms': [{
        'header': {'stamp': {'sec': 12, 'nanosec': 345_678_901}, 'frame_id': t.parent},
        'child_frame_id': t.child,
        'transform': {'translation': dict(zip('xyz', t.translation, strict=True)),
                      'rotation': dict(zip('xyzw', t.rotation, strict=True))}}
        for t in transforms]})
    assert encode_tf(stamp, transforms) == bytes(expected)
    assert encode_tf(0, []) == bytes(generic({'transforms': []}))


def same_as_rclpy(data: bytes, msg) -> None:
    """``data`` is rclpy's bytes of ``msg`` but for the padding (rclpy does not zero it; ours
    is zero), and rclpy decodes both alike (float32 colours rounded in both)."""
    theirs = bytes(serialize_message(msg))
    assert len(data) == len(theirs)
    assert all(ours in (their, 0) for ours, their in zip(data, theirs, strict=True))
    assert deserialize_message(data, type(msg)) == deserialize_message(theirs, type(msg))


def marker_array_msg(specs: list[MarkerSpec]) -> MarkerArray:
    """The same markers built from rclpy's classes: the reference for ``encode_markers``."""
    out = []
    for spec in specs:
        m = Marker()
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(spec.stamp_ns, 1_000_000_000)
        m.header.frame_id = spec.frame_id
        m.ns, m.id, m.type, m.action = spec.ns, spec.marker_id, spec.kind, spec.action
        m.pose.position = Point(x=spec.position[0], y=spec.position[1], z=spec.position[2])
        m.scale.x, m.scale.y, m.scale.z = spec.scale
        m.color = ColorRGBA(r=spec.color[0], g=spec.color[1], b=spec.color[2], a=spec.color[3])
        m.points = [Point(x=x, y=y, z=z) for x, y, z in spec.points]
        out.append(m)
    return MarkerArray(markers=out)


@pytest.mark.parametrize('loaded_legs', [(0, 1, 2, 3), (0, 3), (2,), ()])
def test_marker_encoder_writes_rclpys_bytes(view, loaded_legs):
    rng = np.random.default_rng(7)
    feet = rng.uniform(-0.5, 0.5, (4, 3))
    forces = np.zeros((4, 3))
    forces[list(loaded_legs)] = rng.uniform(5.0, 400.0, (len(loaded_legs), 3))
    for cop, margin in (((0.1, -0.05), 0.02), ((0.3, 0.4), -0.1), ((np.nan, np.nan), np.nan)):
        specs = view.force_markers(3_000_000_123, feet, forces, np.array(cop), margin)
        assert specs[0].action == Marker.DELETEALL
        same_as_rclpy(encode_markers(specs), marker_array_msg(specs))
    same_as_rclpy(encode_markers([]), MarkerArray())


def test_float64_and_vector3_stamped_encoders_write_rclpys_bytes():
    for value in (0.0, -1.25e-3, 1e300, np.inf):
        assert encode_float64(value) == bytes(serialize_message(Float64(data=value)))
    for frame in ('odom', '', 'a_longer_frame'):
        msg = Vector3Stamped()
        msg.header.stamp.sec, msg.header.stamp.nanosec = 7, 5
        msg.header.frame_id = frame
        msg.vector.x, msg.vector.y, msg.vector.z = 0.1, -0.2, 0.3
        same_as_rclpy(encode_vector3_stamped(7_000_000_005, frame, 0.1, -0.2, 0.3), msg)


def test_odom_fields_read_any_frames_and_fall_back_to_rclpy():
    base = BaseState(2.5, np.array([1.0, -2.0, 0.6]),
                     np.array([0.0, 0.0, np.sin(0.2), np.cos(0.2)]), np.array([0.3, 0.1, 0.0]),
                     np.array([0.0, 0.0, 0.4]))
    ours = encode_odom(base)
    msg = odom_from_base_state(base)
    assert odom_fields_from_cdr(ours) == odom_fields_from_cdr(bytes(serialize_message(msg)))
    stamp, frame, child, pose, twist = odom_fields_from_cdr(ours)
    assert (stamp, frame, child) == (2_500_000_000, 'odom', 'base_link')
    np.testing.assert_allclose(pose, [1.0, -2.0, 0.6, 0.0, 0.0, np.sin(0.2), np.cos(0.2)])
    other = Odometry()
    other.header.frame_id, other.child_frame_id = 'map', 'robot/base'
    other.twist.twist.angular.z = -0.7
    _, frame, child, _, twist = odom_fields_from_cdr(bytes(serialize_message(other)))
    assert (frame, child, twist[5]) == ('map', 'robot/base', -0.7)
    big_endian = b'\x00\x00\x00\x00' + bytes(serialize_message(other))[4:]
    with pytest.raises(ValueError, match='cannot deserialize Odometry'):
        odom_fields_from_cdr(big_endian[:20])
