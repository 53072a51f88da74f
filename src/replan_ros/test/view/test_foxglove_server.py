"""foxglove_server: the Foxglove WebSocket protocol v1 under both subprotocol names, with a
plain websockets client (no ROS)."""

from __future__ import annotations

import json
import struct
import time
from pathlib import Path

import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from replan_core.robot.assets import served_model_assets
from replan_core.robot.robot_file import example_robot_data_dir, load_robot_file
from replan_ros.view.foxglove_server import FoxgloveServer


@pytest.fixture
def server():
    received = []

    def on_message(topic, encoding, schema_name, payload):
        received.append((topic, encoding, schema_name, payload))
        return 'refused' if payload == b'bad' else None

    srv = FoxgloveServer('127.0.0.1', 0, client_topics=('cmd_vel',),
                         on_client_message=on_message, log=lambda _text: None)
    srv.start()
    srv.received = received
    yield srv
    srv.stop()


def client(srv, subprotocols):
    return connect(f'ws://127.0.0.1:{srv.port}', subprotocols=subprotocols, open_timeout=5)


def recv_json(ws, op):
    while True:
        frame = ws.recv(timeout=5)
        if isinstance(frame, str) and json.loads(frame)['op'] == op:
            return json.loads(frame)


def recv_binary(ws):
    while True:
        frame = ws.recv(timeout=5)
        if isinstance(frame, bytes):
            return frame


@pytest.mark.parametrize('subprotocol', ['foxglove.websocket.v1', 'foxglove.sdk.v1'])
def test_each_subprotocol_gets_server_info_channels_and_messages(server, subprotocol):
    latched = server.add_channel('/robot_description', 'std_msgs/msg/String', 'string data',
                                 latched=True)
    server.send(latched, 0, b'urdf')
    with client(server, [subprotocol]) as ws:
        assert ws.subprotocol == subprotocol
        info = recv_json(ws, 'serverInfo')
        assert {'clientPublish', 'time'} <= set(info['capabilities'])
        assert set(info['supportedEncodings']) == {'cdr', 'json'}
        first = recv_json(ws, 'advertise')['channels']
        assert [(c['topic'], c['schemaEncoding']) for c in first] == [
            ('/robot_description', 'ros2msg')]
        odom = server.add_channel('/odom', 'nav_msgs/msg/Odometry', 'schema text')
        assert recv_json(ws, 'advertise')['channels'][0]['id'] == odom
        ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
            {'id': 3, 'channelId': latched}, {'id': 4, 'channelId': odom}]}))
        assert recv_binary(ws) == struct.pack('<BIQ', 1, 3, 0) + b'urdf'   # the latched one
        server.send(odom, 123, b'payload')
        assert recv_binary(ws) == struct.pack('<BIQ', 1, 4, 123) + b'payload'
        ws.send(json.dumps({'op': 'unsubscribe', 'subscriptionIds': [4]}))
        time.sleep(0.2)
        server.send(odom, 124, b'gone')
        server.send_time(125)
        assert recv_binary(ws) == struct.pack('<BQ', 2, 125)     # time, not the odom


def test_client_without_a_known_subprotocol_is_refused(server):
    for offered in ([], ['some.other.v1']):
        with pytest.raises(InvalidStatus) as info:
            client(server, offered)
        assert info.value.response.status_code == 400


def test_client_publishing_only_on_allowed_topics(server):
    with client(server, ['foxglove.sdk.v1']) as ws:
        recv_json(ws, 'serverInfo')
        ws.send(json.dumps({'op': 'advertise', 'channels': [
            {'id': 1, 'topic': '/cmd_vel', 'encoding': 'json', 'schemaName': 'geometry_msgs/Twist'},
            {'id': 2, 'topic': '/other', 'encoding': 'cdr', 'schemaName': 'x'},
            {'id': 3, 'topic': 'cmd_vel', 'encoding': 'protobuf', 'schemaName': 'x'}]}))
        assert '/other is not allowed' in recv_json(ws, 'status')['message']
        assert 'protobuf' in recv_json(ws, 'status')['message']
        ws.send(struct.pack('<BI', 1, 1) + b'{"linear": {"x": 0.1}}')
        ws.send(struct.pack('<BI', 1, 2) + b'x')               # not advertised (refused above)
        assert 'not advertised' in recv_json(ws, 'status')['message']
        ws.send(struct.pack('<BI', 1, 1) + b'bad')             # the handler refuses it
        assert recv_json(ws, 'status')['message'] == '/cmd_vel: refused'
        ws.send(json.dumps({'op': 'unadvertise', 'channelIds': [1]}))
        ws.send(struct.pack('<BI', 1, 1) + b'late')
        assert 'not advertised' in recv_json(ws, 'status')['message']
    assert server.received == [
        ('/cmd_vel', 'json', 'geometry_msgs/Twist', b'{"linear": {"x": 0.1}}'),
        ('/cmd_vel', 'json', 'geometry_msgs/Twist', b'bad')]


def test_a_taken_port_is_an_os_error(server):
    with pytest.raises(OSError):
        FoxgloveServer('127.0.0.1', server.port, log=lambda _text: None).start()


# ---------------------------------------------------------------------- assets (fetchAsset)

ROOT = Path(__file__).resolve().parents[4]
GO1_MESH = 'package://example-robot-data/robots/go1_description/meshes/thigh.dae'


def fetch(ws, uri, request_id):
    """A fetchAsset and its answer, decoded as the spec's Fetch Asset Response says: opcode
    0x04, uint32 request id, uint8 status, uint32 error length, error, data (little-endian)."""
    ws.send(json.dumps({'op': 'fetchAsset', 'uri': uri, 'requestId': request_id}))
    frame = recv_binary(ws)
    opcode, got_id, status, length = struct.unpack_from('<BIBI', frame)
    assert (opcode, got_id) == (0x04, request_id)
    return status, frame[10:10 + length].decode(), frame[10 + length:]


@pytest.fixture
def asset_server():
    srv = FoxgloveServer('127.0.0.1', 0, fetch_asset=served_model_assets(ROOT).read,
                         log=lambda _text: None)
    srv.start()
    yield srv
    srv.stop()


def test_assets_capability_only_with_a_fetcher(server, asset_server):
    with client(server, ['foxglove.websocket.v1']) as ws:
        assert 'assets' not in recv_json(ws, 'serverInfo')['capabilities']
        ws.send(json.dumps({'op': 'fetchAsset', 'uri': GO1_MESH, 'requestId': 1}))
        assert 'unsupported op' in recv_json(ws, 'status')['message']
    with client(asset_server, ['foxglove.websocket.v1']) as ws:
        assert {'assets', 'clientPublish', 'time'} <= set(
            recv_json(ws, 'serverInfo')['capabilities'])


def test_a_go1_mesh_is_served_byte_for_byte(asset_server):
    """A mesh Go1's URDF names (its /robot_description), as Foxglove asks for it."""
    spec = load_robot_file(ROOT / 'config' / 'robots' / 'go1.yaml', ROOT)
    assert f'filename="{GO1_MESH}"' in spec.urdf.read_text()
    mesh = example_robot_data_dir() / 'go1_description' / 'meshes' / 'thigh.dae'
    with connect(f'ws://127.0.0.1:{asset_server.port}', subprotocols=['foxglove.sdk.v1'],
                 open_timeout=5, max_size=None) as ws:
        recv_json(ws, 'serverInfo')
        assert fetch(ws, GO1_MESH, 7) == (0, '', mesh.read_bytes())
        assert fetch(ws, 'package://go1_description/meshes/thigh.dae', 2**32 - 1) == (
            0, '', mesh.read_bytes())


@pytest.mark.parametrize(('uri', 'why'), [
    ('package://no_such_package/meshes/a.dae', "unknown package 'no_such_package'"),
    ('package://go1_description/../../../../../../../etc/passwd', 'stay inside its package'),
    ('package://example-robot-data/robots/go1_description/meshes/missing.dae', 'no such file'),
    ('file:///etc/passwd', 'only package:// URIs'),
    ('http://127.0.0.1/x.dae', 'only package:// URIs'),
])
def test_a_uri_not_served_is_an_error_response_and_the_server_goes_on(asset_server, uri, why):
    with client(asset_server, ['foxglove.websocket.v1']) as ws:
        recv_json(ws, 'serverInfo')
        status, error, data = fetch(ws, uri, 3)
        assert status == 1 and why in error and data == b''
        assert fetch(ws, 'package://replan_ros/urdf/hyq.urdf', 4) == (
            0, '', (ROOT / 'urdf' / 'hyq.urdf').read_bytes())


def test_a_malformed_fetch_is_a_status_and_a_failing_fetcher_an_error_response():
    def broken(_uri):
        raise RuntimeError('disk on fire')

    srv = FoxgloveServer('127.0.0.1', 0, fetch_asset=broken, log=lambda _text: None)
    srv.start()
    try:
        with client(srv, ['foxglove.websocket.v1']) as ws:
            recv_json(ws, 'serverInfo')
            for bad in ({'uri': GO1_MESH}, {'uri': GO1_MESH, 'requestId': -1},
                        {'uri': 5, 'requestId': 1}, {'uri': GO1_MESH, 'requestId': 2**32}):
                ws.send(json.dumps({'op': 'fetchAsset', **bad}))
                assert "malformed 'fetchAsset'" in recv_json(ws, 'status')['message']
            assert fetch(ws, GO1_MESH, 9) == (1, 'disk on fire', b'')
    finally:
        srv.stop()
