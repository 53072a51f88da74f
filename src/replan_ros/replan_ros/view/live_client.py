"""A headless viewer of the live view: a Foxglove WebSocket client (``websockets``).

It speaks what Foxglove and Lichtblick speak to ``replan_ros.view.live_view``: reads the server
info and the advertised channels, subscribes, receives message frames and fetches assets (the
meshes a URDF names). The node-graph
test of the live view and ``scripts/bench_speed.sh`` (the graph's speed with a viewer
watching) use it.
"""

from __future__ import annotations

import json
import socket
import struct
import threading
import time

from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

MESSAGE_DATA = 0x01          # binary opcode of a message frame: subscription id, stamp, payload
FETCH_ASSET_RESPONSE = 0x04  # binary opcode of an asset: request id, status, error, data


def parse_fetch_asset_response(frame: bytes) -> tuple[int, int, str, bytes]:
    """(request id, status, error text, data) of a Fetch Asset Response frame (uint32 request
    id, uint8 status 0 ok / 1 error, uint32 error length, the error, then the data)."""
    request_id, status, length = struct.unpack_from('<IBI', frame, 1)
    error_end = 10 + length
    return request_id, status, frame[10:error_end].decode(), bytes(frame[error_end:])


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on now."""
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


class LiveClient:
    """One WebSocket connection to the live view: serverInfo, advertise, subscribe, publish."""

    def __init__(self, port: int, subprotocol: str = 'foxglove.websocket.v1',
                 timeout: float = 60.0) -> None:
        """Connect to 127.0.0.1:``port``, retrying for ``timeout`` s while the server starts."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                self.ws = connect(f'ws://127.0.0.1:{port}', subprotocols=[subprotocol],
                                  open_timeout=5, max_size=None, legacy=True)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.5)
        self.channels: dict[str, dict] = {}
        self.by_subscription: dict[int, str] = {}
        self.statuses: list[dict] = []
        self.assets: dict[int, tuple[int, str, bytes]] = {}   # request id -> status, error, data
        self._next_request = 1
        self.info = json.loads(self.ws.recv(timeout=10))

    def poll(self, seconds: float) -> list[tuple[str, int, bytes]]:
        """Handle what arrives for ``seconds``; returns the (topic, stamp ns, payload) data."""
        out = []
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            try:
                frame = self.ws.recv(timeout=left)
            except TimeoutError:
                break
            if isinstance(frame, str):
                message = json.loads(frame)
                if message['op'] == 'advertise':
                    self.channels.update({c['topic']: c for c in message['channels']})
                elif message['op'] == 'status':
                    self.statuses.append(message)
            elif frame[0] == MESSAGE_DATA:
                subscription, stamp = struct.unpack_from('<IQ', frame, 1)
                out.append((self.by_subscription[subscription], stamp, frame[13:]))
            elif frame[0] == FETCH_ASSET_RESPONSE:
                request_id, *answer = parse_fetch_asset_response(frame)
                self.assets[request_id] = tuple(answer)
        return out

    def fetch_asset(self, uri: str, timeout: float = 30.0) -> tuple[int, str, bytes]:
        """(status, error, data) of a ``fetchAsset`` of ``uri`` (TimeoutError after
        ``timeout`` s); message frames that arrive meanwhile are dropped."""
        request_id, self._next_request = self._next_request, self._next_request + 1
        self.ws.send(json.dumps({'op': 'fetchAsset', 'uri': uri, 'requestId': request_id}))
        end = time.monotonic() + timeout
        while request_id not in self.assets:
            if time.monotonic() > end:
                raise TimeoutError(f'no answer to fetchAsset {uri} in {timeout} s')
            self.poll(0.2)
        return self.assets.pop(request_id)

    def subscribe(self, topics, timeout: float = 30.0) -> None:
        """Subscribe to ``topics`` once all are advertised (ValueError after ``timeout`` s)."""
        end = time.monotonic() + timeout
        while not all(t in self.channels for t in topics) and time.monotonic() < end:
            self.poll(0.2)
        missing = [t for t in topics if t not in self.channels]
        if missing:
            raise ValueError(f'not advertised: {missing} (have {sorted(self.channels)})')
        subscriptions = []
        for topic in topics:
            sid = len(self.by_subscription) + 1
            self.by_subscription[sid] = topic
            subscriptions.append({'id': sid, 'channelId': self.channels[topic]['id']})
        self.ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subscriptions}))

    def close(self) -> None:
        self.ws.close()


class WatchEverything(threading.Thread):
    """A viewer in a thread that subscribes to every channel the live view advertises, as
    soon as it is advertised, and counts what it receives until ``stop()``."""

    def __init__(self, port: int, timeout: float = 60.0) -> None:
        super().__init__(daemon=True, name='live-client')
        self.port, self.timeout = port, timeout
        self.frames = 0
        self.bytes = 0
        self.error: str | None = None
        self._stopping = threading.Event()

    def run(self) -> None:
        try:
            client = LiveClient(self.port, timeout=self.timeout)
        except OSError as err:
            self.error = f'no live view on port {self.port}: {err}'
            return
        try:
            while not self._stopping.is_set():
                for _topic, _stamp, payload in client.poll(0.2):
                    self.frames += 1
                    self.bytes += len(payload)
                new = [t for t in client.channels if t not in client.by_subscription.values()]
                if new:
                    client.subscribe(new)
        except ConnectionClosed:
            pass                      # the live view stopped with the graph
        finally:
            client.close()

    def stop(self) -> None:
        self._stopping.set()
        self.join(timeout=10.0)
