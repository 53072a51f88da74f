"""Every robot of config/robots/ on every surface a user sees it on (a new robot file gets this
test): ``scripts/launch.sh --robot NAME --live PORT --record DIR`` as a user runs it, for a few
seconds of sim time (ideal profile: the fastest).

- The live view (a Foxglove WebSocket client) serves the robot's URDF as /robot_description,
  a /tf holding every link of that URDF plus odom -> base_link, and every mesh the URDF names
  (``package://``) through the asset fetch, byte for byte.
- The bag holds /robot_description and /tf alike (read with rosbags): an ANYmal C run once
  recorded neither, and passed.
- ``scripts/rerun.sh BAG`` makes the run again, bit for bit.
"""

from __future__ import annotations

import json
import re
import subprocess
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from harness import CONFIG_DIR, REPO_ROOT, graph_env
from test_launch import LaunchProcess
from test_live_view import Viewer

from replan_core.robot.robot_file import example_robot_data_dir, load_robot_file, robot_names
from replan_ros.view.live_client import free_port

DURATION = 3.0          # sim s: the live view's checks and the bag's /tf need no more
WAIT = 90.0             # wall s for what the live view serves


def urdf_tree(text: str) -> tuple[set[str], set[tuple[str, str]]]:
    """The links of a URDF and the (parent, child) link pair of each of its joints."""
    root = ET.fromstring(text)
    links = {link.get('name') for link in root.findall('link')}
    pairs = {(j.find('parent').get('link'), j.find('child').get('link'))
             for j in root.findall('joint')}
    return links, pairs


def expected_tf(text: str, root_link: str) -> set[tuple[str, str]]:
    """(parent, child) of every transform a viewer needs: each URDF joint's, odom ->
    base_link, and base_link -> the model's root where the root has another name."""
    _, pairs = urdf_tree(text)
    extra = {('odom', 'base_link')}
    if root_link != 'base_link':
        extra.add(('base_link', root_link))
    return pairs | extra


def mesh_file(uri: str) -> Path:
    """The file a ``package://`` name means, as ROS_PACKAGE_PATH would find it in
    example-robot-data's share tree (independently of the live view's own resolution)."""
    package, _, path = uri.removeprefix('package://').partition('/')
    robots = example_robot_data_dir()
    return robots.parent / path if package == 'example-robot-data' else robots / package / path


def check_tf(pairs: set[tuple[str, str]], text: str, expected: set[tuple[str, str]]) -> None:
    links, _ = urdf_tree(text)
    assert pairs == expected, (sorted(expected - pairs), sorted(pairs - expected))
    assert {child for _, child in pairs} == links | {'base_link'}     # every link, once placed


@pytest.mark.parametrize('robot', robot_names(CONFIG_DIR))
def test_live_view_bag_and_rerun_show_the_robot(robot, ros_domain, tmp_path):
    spec = load_robot_file(CONFIG_DIR / 'robots' / f'{robot}.yaml', REPO_ROOT)
    urdf = spec.urdf.read_text()
    expected = expected_tf(urdf, spec.root_link)
    meshes = sorted(set(re.findall(r'filename="(package://[^"]+)"', urdf)))
    port = free_port()
    launch = LaunchProcess(['--robot', robot, '--profile', 'ideal', '--live', str(port),
                            '--record', str(tmp_path / 'bag'), '--run-dir', str(tmp_path / 'run'),
                            '--duration', str(DURATION), '--quiet'], ros_domain)
    try:
        assert launch.wait_for('started live_view', 60), launch.output
        viewer = Viewer(port)
        try:
            assert 'assets' in viewer.info['capabilities']
            viewer.subscribe(['/robot_description', '/tf'], timeout=60)
            description, tf = None, None
            end = time.monotonic() + WAIT
            while description is None and time.monotonic() < end:
                for topic, _stamp, payload in viewer.poll(0.2):
                    if topic == '/robot_description':
                        description = viewer.decode(topic, payload).data
            assert description == urdf
            # Every mesh at once, while the graph starts: answers come in with the /tf frames.
            requests = {}
            for k, uri in enumerate(meshes, start=1):
                viewer.ws.send(json.dumps({'op': 'fetchAsset', 'uri': uri, 'requestId': k}))
                requests[k] = uri
            while (tf is None or not requests.keys() <= viewer.assets.keys()) \
                    and time.monotonic() < end:
                for topic, _stamp, payload in viewer.poll(0.2):
                    if topic == '/tf' and tf is None:
                        tf = viewer.decode(topic, payload)
            assert tf is not None, launch.output
            check_tf({(t.header.frame_id, t.child_frame_id) for t in tf.transforms}, urdf,
                     expected)
            for k, uri in requests.items():
                status, error, data = viewer.assets.get(k, (None, 'no answer', b''))
                assert (status, error) == (0, ''), uri
                assert data == mesh_file(uri).read_bytes(), uri
        finally:
            viewer.close()
        assert launch.process.wait(120) == 0, launch.output
    finally:
        launch.stop()

    from rosbags.highlevel import AnyReader

    bags = sorted((tmp_path / 'bag').glob('*.mcap'))
    assert len(bags) == 1, launch.output
    with AnyReader(bags) as reader:
        by_topic = {c.topic: c for c in reader.connections}
        assert {'/robot_description', '/tf'} <= by_topic.keys(), sorted(by_topic)
        descriptions = [reader.deserialize(raw, c.msgtype).data for c, _t, raw in
                        reader.messages(connections=[by_topic['/robot_description']])]
        assert descriptions == [urdf]
        count = 0
        for connection, _t, raw in reader.messages(connections=[by_topic['/tf']]):
            msg = reader.deserialize(raw, connection.msgtype)
            check_tf({(t.header.frame_id, t.child_frame_id) for t in msg.transforms}, urdf,
                     expected)
            count += 1
        assert count >= 25 * DURATION * 0.9        # 25 Hz of sim time (StateView's period)

    rerun = subprocess.run(
        [str(REPO_ROOT / 'scripts' / 'rerun.sh'), str(bags[0]), '--out', str(tmp_path / 'rerun'),
         '--quiet'], env=graph_env(ros_domain), capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stdout + rerun.stderr
    assert '-> MATCH' in rerun.stdout and '[rerun] messages: bit-identical' in rerun.stdout, \
        rerun.stdout
    assert f'both end at t = {DURATION:.3f} s' in rerun.stdout, rerun.stdout
