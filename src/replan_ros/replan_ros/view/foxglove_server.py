"""A Foxglove WebSocket server (protocol v1), on ``websockets``, in its own thread.

Speaks the published protocol (github.com/foxglove/ws-protocol, docs/spec.md) under both
subprotocol names that viewers offer: ``foxglove.websocket.v1`` (Lichtblick, older Foxglove)
and ``foxglove.sdk.v1`` (the current Foxglove app, foxglove_bridge 3.x; same messages).
``foxglove-sdk`` 0.30.3's server refuses clients that offer only the first (HTTP 400), hence
this small server. Implemented: serverInfo, advertise, subscribe/unsubscribe, binary message
data (0x01) and time (0x02), status, client publishing (``clientPublish``: client
advertise/unadvertise and client message data, encodings ``cdr`` and ``json``) and, given a
``fetch_asset`` function, the ``assets`` capability (``fetchAsset`` answered by a binary Fetch
Asset Response, 0x04: viewers fetch the meshes a URDF names, ``package://...``).

Never blocks the caller: ``add_channel``, ``send`` and ``send_time`` hand their work to the
server's event loop and return; each client has a bounded queue whose oldest frames are
dropped when the client reads too slowly. ``on_first_subscriber(channel_id)`` tells the owner
when a channel is first wanted, so that it reads only what viewers look at. ``fetch_asset(uri)``
runs in a worker thread (a mesh may be tens of MB) and returns the bytes or raises; its
exception's text is the error the client gets.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import struct
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from websockets.asyncio.server import ServerConnection, serve
from websockets.exceptions import ConnectionClosed

SUBPROTOCOLS = ('foxglove.websocket.v1', 'foxglove.sdk.v1')   # preferred first
OP_MESSAGE_DATA = 0x01          # server -> client: u32 subscription id, u64 time ns, payload
OP_TIME = 0x02                  # server -> client: u64 time ns
OP_FETCH_ASSET_RESPONSE = 0x04  # server -> client: u32 request id, u8 status, u32 error
                                #   length, error (UTF-8), data (spec: "Fetch Asset Response")
ASSET_OK, ASSET_ERROR = 0, 1
OP_CLIENT_MESSAGE_DATA = 0x01   # client -> server: u32 client channel id, payload
CLIENT_ENCODINGS = ('cdr', 'json')
STATUS_INFO, STATUS_WARNING, STATUS_ERROR = 0, 1, 2

# (topic, encoding, schema name, payload) -> None if accepted, else why not.
ClientMessageHandler = Callable[[str, str, str, bytes], str | None]
# uri -> the asset's bytes; raises (any exception) if it is not served, its text the reason.
AssetFetcher = Callable[[str], bytes]


@dataclass
class Channel:
    """A server channel; ``latched`` ones keep their last message for new subscribers."""

    id: int
    topic: str
    schema_name: str
    schema: str
    encoding: str = 'cdr'
    schema_encoding: str = 'ros2msg'
    latched: bool = False
    last: tuple[int, bytes] | None = None

    def advertisement(self) -> dict:
        return {'id': self.id, 'topic': self.topic, 'encoding': self.encoding,
                'schemaName': self.schema_name, 'schema': self.schema,
                'schemaEncoding': self.schema_encoding}


class _Client:
    def __init__(self, connection: ServerConnection, queue_size: int) -> None:
        self.connection = connection
        self.subscriptions: dict[int, int] = {}        # channel id -> subscription id
        self.advertised: dict[int, dict] = {}          # client channel id -> its advertisement
        self.queue: deque[bytes | str] = deque(maxlen=queue_size)
        self.wake = asyncio.Event()
        self.dropped = 0
        self.fetches: set[asyncio.Task] = set()        # asset reads under way (kept alive)

    def push(self, frame: bytes | str) -> None:
        if len(self.queue) == self.queue.maxlen:
            self.dropped += 1
        self.queue.append(frame)
        self.wake.set()


def message_frame(subscription_id: int, stamp_ns: int, payload: bytes) -> bytes:
    """Binary message data frame (opcode 0x01)."""
    return struct.pack('<BIQ', OP_MESSAGE_DATA, subscription_id, max(int(stamp_ns), 0)) + payload


def fetch_asset_frame(request_id: int, data: bytes = b'', error: str = '') -> bytes:
    """Binary Fetch Asset Response (opcode 0x04): status 0 and the data, or, with an
    ``error``, status 1, the error text and no data."""
    text = error.encode()
    return (struct.pack('<BIBI', OP_FETCH_ASSET_RESPONSE, request_id,
                        ASSET_ERROR if error else ASSET_OK, len(text))
            + text + (b'' if error else bytes(data)))


def status(level: int, message: str) -> str:
    return json.dumps({'op': 'status', 'level': level, 'message': message})


class FoxgloveServer:
    """The server; ``start`` binds and serves from a daemon thread, ``stop`` ends it."""

    def __init__(self, host: str = '127.0.0.1', port: int = 8765, *, name: str = 'replan',
                 client_topics: tuple[str, ...] = (),
                 on_client_message: ClientMessageHandler | None = None,
                 on_first_subscriber: Callable[[int], None] | None = None,
                 fetch_asset: AssetFetcher | None = None,
                 queue_size: int = 500, log: Callable[[str], None] = print) -> None:
        self.host, self.requested_port, self.name = host, int(port), name
        self.client_topics = tuple(_absolute(t) for t in client_topics)
        self.on_client_message = on_client_message
        self.on_first_subscriber = on_first_subscriber
        self.fetch_asset = fetch_asset
        self.capabilities = ['clientPublish', 'time'] + (['assets'] if fetch_asset else [])
        self.wanted: set[int] = set()            # channels that have had a subscriber
        self.queue_size = max(int(queue_size), 1)
        self.log = log
        self.port: int | None = None
        self.channels: dict[int, Channel] = {}
        self._clients: set[_Client] = set()
        self._next_id = 1
        self._lock = threading.Lock()          # channel ids, from any thread
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._stop: asyncio.Event | None = None
        self._session = str(time.time_ns())

    # ------------------------------------------------------------------ life cycle

    def start(self, timeout: float = 10.0) -> int:
        """Bind and serve; returns the port. OSError if the port cannot be bound."""
        self._thread = threading.Thread(target=self._run, name='foxglove_server', daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise OSError(f'server on {self.host}:{self.requested_port} did not start')
        if self._error is not None:
            raise OSError(f'cannot serve on {self.host}:{self.requested_port}: {self._error}')
        return self.port

    def _run(self) -> None:
        self._loop = asyncio.new_event_loop()
        try:
            self._loop.run_until_complete(self._serve())
        except BaseException as err:  # reported to start() through _error
            self._error = err
            self._ready.set()
        finally:
            self._loop.close()

    async def _serve(self) -> None:
        self._stop = asyncio.Event()
        async with serve(self._handle, self.host, self.requested_port,
                         subprotocols=list(SUBPROTOCOLS), max_size=1 << 20,
                         compression=None) as server:
            self.port = next(iter(server.sockets)).getsockname()[1]
            self._ready.set()
            await self._stop.wait()

    def stop(self) -> None:
        if self._loop is not None and self._stop is not None and self._loop.is_running():
            with contextlib.suppress(RuntimeError):
                self._loop.call_soon_threadsafe(self._stop.set)
        if self._thread is not None:
            self._thread.join(timeout=5.0)

    @property
    def client_count(self) -> int:
        return len(self._clients)

    # ------------------------------------------------------------------ from any thread

    def add_channel(self, topic: str, schema_name: str, schema: str, *, encoding: str = 'cdr',
                    schema_encoding: str = 'ros2msg', latched: bool = False) -> int:
        """Advertise a channel to every client (now and later); returns its id."""
        with self._lock:
            channel = Channel(self._next_id, topic, schema_name, schema, encoding,
                              schema_encoding, latched)
            self._next_id += 1
        self._call(self._advertise, channel)
        return channel.id

    def send(self, channel_id: int, stamp_ns: int, payload: bytes) -> None:
        """Message data for the subscribers of a channel (dropped if none)."""
        self._call(self._send, channel_id, int(stamp_ns), bytes(payload))

    def send_time(self, stamp_ns: int) -> None:
        """The server time (sim time) for the ``time`` capability."""
        self._call(self._broadcast, struct.pack('<BQ', OP_TIME, max(int(stamp_ns), 0)))

    def _call(self, function, *args) -> None:
        if self._loop is not None and not self._loop.is_closed():
            with contextlib.suppress(RuntimeError):      # the loop is closing
                self._loop.call_soon_threadsafe(function, *args)

    # ------------------------------------------------------------------ in the loop

    def _advertise(self, channel: Channel) -> None:
        self.channels[channel.id] = channel
        text = json.dumps({'op': 'advertise', 'channels': [channel.advertisement()]})
        for client in self._clients:
            client.push(text)

    def _send(self, channel_id: int, stamp_ns: int, payload: bytes) -> None:
        channel = self.channels.get(channel_id)
        if channel is None:
            return
        if channel.latched:
            channel.last = (stamp_ns, payload)
        for client in self._clients:
            subscription = client.subscriptions.get(channel_id)
            if subscription is not None:
                client.push(message_frame(subscription, stamp_ns, payload))

    def _broadcast(self, frame: bytes | str) -> None:
        for client in self._clients:
            client.push(frame)

    async def _handle(self, connection: ServerConnection) -> None:
        client = _Client(connection, self.queue_size)
        self._clients.add(client)
        peer = connection.remote_address
        self.log(f'client {peer} connected ({connection.subprotocol})')
        client.push(json.dumps({
            'op': 'serverInfo', 'name': self.name,
            'capabilities': self.capabilities,
            'supportedEncodings': list(CLIENT_ENCODINGS),
            'metadata': {'client_topics': ','.join(self.client_topics)},
            'sessionId': self._session}))
        client.push(json.dumps({'op': 'advertise', 'channels': [
            c.advertisement() for c in self.channels.values()]}))
        writer = asyncio.create_task(self._write(client))
        try:
            async for frame in connection:
                if isinstance(frame, str):
                    self._on_text(client, frame)
                else:
                    self._on_binary(client, frame)
        except ConnectionClosed:
            pass
        finally:
            self._clients.discard(client)
            writer.cancel()
            for fetch in list(client.fetches):
                fetch.cancel()
            self.log(f'client {peer} disconnected'
                     + (f' ({client.dropped} frames dropped: slow reader)' if client.dropped
                        else ''))

    async def _write(self, client: _Client) -> None:
        with contextlib.suppress(ConnectionClosed):
            while True:
                await client.wake.wait()
                client.wake.clear()
                while client.queue:
                    await client.connection.send(client.queue.popleft())

    def _on_text(self, client: _Client, text: str) -> None:
        try:
            message = json.loads(text)
            op = message['op']
        except (ValueError, KeyError, TypeError):
            client.push(status(STATUS_ERROR, 'not a JSON object with an "op"'))
            return
        try:
            if op == 'subscribe':
                for entry in message['subscriptions']:
                    self._subscribe(client, int(entry['id']), int(entry['channelId']))
            elif op == 'unsubscribe':
                ids = {int(i) for i in message['subscriptionIds']}
                client.subscriptions = {c: s for c, s in client.subscriptions.items()
                                        if s not in ids}
            elif op == 'advertise':
                for entry in message['channels']:
                    self._client_advertise(client, entry)
            elif op == 'unadvertise':
                for channel_id in message['channelIds']:
                    client.advertised.pop(int(channel_id), None)
            elif op == 'fetchAsset' and self.fetch_asset is not None:
                self._start_fetch(client, message['requestId'], message['uri'])
            else:
                client.push(status(STATUS_WARNING, f'unsupported op {op!r}'))
        except (KeyError, TypeError, ValueError) as err:
            client.push(status(STATUS_ERROR, f'malformed {op!r}: {err!r}'))

    def _subscribe(self, client: _Client, subscription_id: int, channel_id: int) -> None:
        channel = self.channels.get(channel_id)
        if channel is None:
            client.push(status(STATUS_WARNING, f'no channel {channel_id}'))
            return
        client.subscriptions[channel_id] = subscription_id
        if channel_id not in self.wanted:
            self.wanted.add(channel_id)
            if self.on_first_subscriber is not None:
                self.on_first_subscriber(channel_id)
        if channel.last is not None:
            client.push(message_frame(subscription_id, *channel.last))

    def _start_fetch(self, client: _Client, request_id, uri) -> None:
        if isinstance(request_id, bool) or not isinstance(request_id, int) or not (
                0 <= request_id < 1 << 32) or not isinstance(uri, str):
            raise ValueError('expected "requestId": a uint32 and "uri": a string')
        fetch = asyncio.get_running_loop().create_task(self._fetch(client, request_id, uri))
        client.fetches.add(fetch)
        fetch.add_done_callback(client.fetches.discard)

    async def _fetch(self, client: _Client, request_id: int, uri: str) -> None:
        try:
            # Off the loop: reading a large mesh must not hold up the message frames.
            data = await asyncio.to_thread(self.fetch_asset, uri)
            frame = fetch_asset_frame(request_id, data=data)
        except Exception as err:  # a refused or failed fetch is the client's answer only
            frame = fetch_asset_frame(request_id, error=str(err) or type(err).__name__)
        client.push(frame)

    def _client_advertise(self, client: _Client, entry: dict) -> None:
        topic = _absolute(str(entry['topic']))
        encoding = str(entry['encoding'])
        if topic not in self.client_topics:
            client.push(status(STATUS_ERROR, f'publishing on {topic} is not allowed (allowed: '
                                             f'{", ".join(self.client_topics) or "none"})'))
            return
        if encoding not in CLIENT_ENCODINGS:
            client.push(status(STATUS_ERROR, f'encoding {encoding!r} is not supported '
                                             f'({", ".join(CLIENT_ENCODINGS)})'))
            return
        client.advertised[int(entry['id'])] = {
            'topic': topic, 'encoding': encoding, 'schemaName': str(entry.get('schemaName', ''))}

    def _on_binary(self, client: _Client, frame: bytes) -> None:
        if len(frame) < 5 or frame[0] != OP_CLIENT_MESSAGE_DATA:
            client.push(status(STATUS_ERROR, 'unsupported binary message'))
            return
        channel_id = struct.unpack_from('<I', frame, 1)[0]
        advertised = client.advertised.get(channel_id)
        if advertised is None:
            client.push(status(STATUS_ERROR, f'client channel {channel_id} not advertised'))
            return
        if self.on_client_message is None:
            return
        try:
            error = self.on_client_message(advertised['topic'], advertised['encoding'],
                                           advertised['schemaName'], bytes(frame[5:]))
        except Exception as err:  # a bad client message must not end the server
            error = f'{type(err).__name__}: {err}'
        if error:
            client.push(status(STATUS_ERROR, f'{advertised["topic"]}: {error}'))


def _absolute(topic: str) -> str:
    return topic if topic.startswith('/') else '/' + topic
