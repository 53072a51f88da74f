"""scripts/launch.sh --live --record as a user runs it: a client speaking the Foxglove WebSocket
protocol (websockets, both subprotocols) receives the URDF, the transforms, odom and
joint_states and the force markers, and turns the robot through cmd_vel; the bag's /tf and
/robot_description decode with an independent reader (rosbags). The live view of Go1 alone
serves the meshes its /robot_description names (fetchAsset).

One graph for the module (ideal profile: the fastest): the tests run in file order and the last
one stops it to read the bag.
"""

from __future__ import annotations

import itertools
import json
import math
import re
import socket
import struct
import sys
import time
from pathlib import Path

import pytest
from geometry_msgs.msg import Twist
from harness import CONFIG_DIR, REPO_ROOT, NodeProcess, graph_env
from mcap_ros2._dynamic import generate_dynamic
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from test_launch import LaunchProcess
from visualization_msgs.msg import Marker, MarkerArray

from replan_core.common.types import JOINT_NAMES
from replan_core.robot.robot_file import example_robot_data_dir
from replan_ros.view.live_client import LiveClient, free_port

URDF = (REPO_ROOT / 'urdf' / 'hyq.urdf').read_text()
WANTED = ('/robot_description', '/tf', '/odom', '/joint_states', '/view/contact_forces')
CLASSES = {'/robot_description': String, '/odom': Odometry, '/joint_states': JointState,
           '/view/contact_forces': MarkerArray}


class Viewer(LiveClient):
    """The live client (replan_ros.view.live_client), decoding what it receives."""

    def decode(self, topic: str, payload: bytes):
        if topic in CLASSES:
            return deserialize_message(payload, CLASSES[topic])
        channel = self.channels[topic]   # /tf: no Python class; decoded from the schema sent
        return generate_dynamic(channel['schemaName'], channel['schema'])[
            channel['schemaName']](payload)


def yaw(msg: Odometry) -> float:
    q = msg.pose.pose.orientation
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def test_a_taken_port_stops_the_start_before_anything_runs(ros_domain, tmp_path):
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        launch = LaunchProcess(['--live', str(port), '--run-dir', str(tmp_path / 'run')],
                               ros_domain)
        assert launch.process.wait(60) == 2, launch.output
    assert launch.wait_for(f'--live {port}: port not free', 5), launch.output
    assert not (tmp_path / 'run').exists()


def test_the_go1_live_view_serves_the_meshes_of_its_robot_description(ros_domain, tmp_path):
    """The live view as `--robot go1` starts it (its robot_file), alone: no graph needed to
    draw the model."""
    port = free_port()
    node = NodeProcess('live_view', [
        sys.executable, '-m', 'replan_ros.view.live_view', '--ros-args', '-r',
        '__node:=live_view', '--params-file', str(CONFIG_DIR / 'live_view.yaml'),
        '-p', 'robot_file:=go1', '-p', f'port:={port}'], graph_env(ros_domain),
        tmp_path / 'live_view.log')
    viewer = None
    try:
        viewer = Viewer(port)
        assert 'assets' in viewer.info['capabilities']
        viewer.subscribe(['/robot_description'], timeout=30)
        urdf = ''
        end = time.monotonic() + 30
        while not urdf and time.monotonic() < end:
            urdf = next((viewer.decode(t, p).data for t, _s, p in viewer.poll(0.5)), '')
        meshes = sorted(set(re.findall(r'filename="(package://[^"]+)"', urdf)))
        assert len(meshes) >= 5, urdf[:300]
        uri = next(m for m in meshes if m.endswith('/calf.dae'))
        expected = (example_robot_data_dir() / uri.split('/robots/', 1)[1]).read_bytes()
        assert viewer.fetch_asset(uri) == (0, '', expected)
        status, error, _data = viewer.fetch_asset('package://go1_description/../../x')
        assert status == 1 and 'inside its package' in error
    finally:
        if viewer is not None:
            viewer.close()
        node.stop()
    assert 'Traceback' not in node.log(), node.log()


@pytest.fixture(scope='module')
def live_run(ros_domain, tmp_path_factory):
    folder = tmp_path_factory.mktemp('live')
    port = free_port()
    launch = LaunchProcess(['--profile', 'ideal', '--live', str(port), '--record',
                            str(folder / 'bag'), '--run-dir', str(folder / 'run'), '--quiet',
                            '--duration', '120'], ros_domain)
    launch.port, launch.folder = port, folder
    yield launch
    launch.stop()


@pytest.mark.parametrize('subprotocol', ['foxglove.websocket.v1', 'foxglove.sdk.v1'])
def test_viewer_gets_urdf_transforms_odom_joint_states_and_forces(live_run, subprotocol):
    assert live_run.wait_for(r'started live_view', 60), live_run.output
    viewer = Viewer(live_run.port, subprotocol)
    try:
        assert viewer.ws.subprotocol == subprotocol
        assert viewer.info['op'] == 'serverInfo'
        assert 'clientPublish' in viewer.info['capabilities']
        viewer.subscribe(WANTED, timeout=60)
        got: dict[str, list] = {t: [] for t in WANTED}

        def drawn() -> set:
            return {m.type for array in got['/view/contact_forces'] for m in array.markers
                    if m.action == Marker.ADD}

        # The first frames may be of the tick before the first command (no force yet): wait
        # for forces to draw as well.
        end = time.monotonic() + 90
        while not (all(got.values()) and drawn()) and time.monotonic() < end:
            for topic, _stamp, payload in viewer.poll(0.5):
                got[topic].append(viewer.decode(topic, payload))
        assert all(got.values()), {t: len(v) for t, v in got.items()}
        assert got['/robot_description'][0].data == URDF
        tf = got['/tf'][-1]
        pairs = {(t.header.frame_id, t.child_frame_id) for t in tf.transforms}
        assert ('odom', 'base_link') in pairs and ('lf_lowerleg', 'lf_foot') in pairs
        assert len(tf.transforms) == 17
        base = next(t for t in tf.transforms if t.child_frame_id == 'base_link')
        assert 0.4 < base.transform.translation.z < 0.8          # standing, estimate in odom
        assert got['/odom'][-1].child_frame_id == 'base_link'
        assert list(got['/joint_states'][-1].name) == list(JOINT_NAMES)
        assert {Marker.ARROW, Marker.LINE_STRIP, Marker.SPHERE} <= drawn()
    finally:
        viewer.close()


def test_viewer_publishes_cmd_vel_that_turns_the_robot(live_run):
    viewer = Viewer(live_run.port, 'foxglove.websocket.v1')
    try:
        viewer.subscribe(['/odom'])
        viewer.ws.send(json.dumps({'op': 'advertise', 'channels': [
            {'id': 7, 'topic': '/not_allowed', 'encoding': 'cdr',
             'schemaName': 'geometry_msgs/msg/Twist'},
            {'id': 8, 'topic': '/cmd_vel', 'encoding': 'cdr',
             'schemaName': 'geometry_msgs/msg/Twist'}]}))
        turn = Twist()
        turn.angular.z = 0.3
        frame = struct.pack('<BI', 0x01, 8) + bytes(serialize_message(turn))
        start = None
        turned = 0.0
        end = time.monotonic() + 90
        # As a Teleop panel does: the set-point again and again (the gait node's 0.5 s timeout).
        while time.monotonic() < end and turned < 0.15:
            viewer.ws.send(frame)
            for _topic, _stamp, payload in viewer.poll(0.1):
                heading = yaw(deserialize_message(payload, Odometry))
                start = heading if start is None else start
                turned = heading - start
        assert any('/not_allowed' in s['message'] for s in viewer.statuses), viewer.statuses
        assert turned >= 0.15, f'turned {turned:.3f} rad\n{live_run.output}'
    finally:
        viewer.close()


def test_only_watched_topics_are_read_over_dds(live_run, probe):
    """Every reader costs its publisher a send per sample: the live view reads the topics
    viewers subscribed to (and the derived topics' inputs), not /imu nor the torques."""
    def readers(topic):
        return {i.node_name for i in probe.node.get_subscriptions_info_by_topic(topic)}

    assert probe.spin_until(lambda: 'live_view_on_demand' in readers('/odom'), 30)
    for topic in ('/joint_states', '/ground_truth/contacts'):
        assert 'live_view_on_demand' in readers(topic), topic
    for topic in ('/imu', '/joint_torque_cmd'):
        assert 'live_view_on_demand' not in readers(topic), topic


def test_bag_tf_and_robot_description_decode_with_rosbags(live_run):
    from rosbags.highlevel import AnyReader

    live_run.stop()
    bags = sorted((live_run.folder / 'bag').glob('*.mcap'))
    assert bags, live_run.output
    with AnyReader([Path(b) for b in bags]) as reader:
        by_topic = {c.topic: c for c in reader.connections}
        assert by_topic['/tf'].msgtype == 'tf2_msgs/msg/TFMessage'
        assert by_topic['/robot_description'].msgtype == 'std_msgs/msg/String'
        descriptions = [reader.deserialize(raw, c.msgtype).data for c, _t, raw in
                        reader.messages(connections=[by_topic['/robot_description']])]
        assert descriptions == [URDF]
        stamps = []
        for connection, _t, raw in reader.messages(connections=[by_topic['/tf']]):
            msg = reader.deserialize(raw, connection.msgtype)
            assert len(msg.transforms) == 17
            stamp = msg.transforms[0].header.stamp
            stamps.append(stamp.sec + stamp.nanosec * 1e-9)
        assert len(stamps) > 25 and stamps == sorted(stamps)
        # At most one per 0.04 s of sim time (StateView's period: 25 Hz).
        assert min(b - a for a, b in itertools.pairwise(stamps)) >= 0.04 - 1e-6
