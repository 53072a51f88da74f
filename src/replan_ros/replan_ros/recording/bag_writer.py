"""Writing an mcap bag in the ROS 2 conventions of ``bag_io`` (``BagWriter``) and recovering
what a killed recorder left (``recover``).

Every finished chunk is written to the OS at once (no Python-side buffering), so a recorder
killed with SIGKILL leaves a file whose finished chunks ``recover()`` turns into a valid bag.
A file that cannot be written (full disk, unwritable folder) raises ``BagWriteError`` naming
the path and the cause; the writer then refuses every further write and ``close`` only closes
the file, whose finished chunks stay readable (recovered when read: ``bag_open``).
"""

from __future__ import annotations

import contextlib
import io
import os
import time
from dataclasses import dataclass
from pathlib import Path

import yaml
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Footer, Message, Metadata, Schema
from mcap.stream_reader import breakup_chunk
from mcap.writer import CompressionType, Writer

from replan_ros.recording.bag_dir import write_directory_metadata
from replan_ros.recording.bag_io import (
    MCAP_MAGIC,
    MESSAGE_ENCODING,
    PROFILE,
    SCHEMA_ENCODING,
    message_definition,
    normalize_type_name,
    rosbag2_metadata,
)

# ----------------------------------------------------------------------------- writing

class BagWriteError(Exception):
    """The bag file cannot be written: one line with the path and the cause."""

    def __init__(self, path: Path, cause: OSError) -> None:
        reason = cause.strerror or str(cause) or type(cause).__name__
        super().__init__(f'cannot write {path}: {reason}')
        self.path = path
        self.cause = cause


class _UnbufferedFile(io.RawIOBase):
    """Write-only file without a Python buffer: what the mcap writer writes reaches the OS at
    once (the writer itself keeps the open chunk in memory and writes whole records)."""

    def __init__(self, path: str | Path) -> None:
        super().__init__()
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self._pos = 0

    def writable(self) -> bool:
        return True

    def write(self, data) -> int:
        view = memoryview(data)
        while view:
            written = os.write(self._fd, view)
            view = view[written:]
            self._pos += written
        return len(data)

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        pass

    def close(self) -> None:
        if not self.closed:
            os.close(self._fd)
        super().close()


class _StreamAdapter:
    """Gives the mcap writer a plain stream object (it wraps RawIOBase in a BufferedWriter)."""

    def __init__(self, raw: _UnbufferedFile) -> None:
        self._raw = raw

    def write(self, data) -> int:
        return self._raw.write(data)

    def tell(self) -> int:
        return self._raw.tell()

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self._raw.close()


_COMPRESSION = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE, '': CompressionType.NONE}


class BagWriter:
    """An mcap file in the ROS 2 conventions.

    Not thread safe: one thread writes. ``chunk_size`` (bytes of uncompressed records) and
    ``chunk_interval`` (s, wall clock, checked on each write and by ``poll``) bound what a
    SIGKILL can lose. On ``close`` the directory's ``metadata.yaml`` is (re)written
    (``bag_dir``) unless ``directory_metadata`` is false; a failure there leaves the bag
    intact and is kept in ``directory_metadata_error``.
    """

    def __init__(self, path: str | Path, *, chunk_size: int = 1 << 20,
                 chunk_interval: float = 1.0, compression: str = 'zstd',
                 library: str = 'replan_ros bag_io', directory_metadata: bool = True) -> None:
        if compression not in _COMPRESSION:
            raise ValueError(f'compression must be one of zstd, lz4, none: {compression!r}')
        self.path = Path(path)
        self.error: BagWriteError | None = None
        try:
            self._file = _UnbufferedFile(self.path)
        except OSError as err:
            raise BagWriteError(self.path, err) from None
        # The mcap writer closes a chunk itself only past 2x our size: we close it (flush) first.
        self._writer = Writer(_StreamAdapter(self._file), chunk_size=2 * max(chunk_size, 1024),
                              compression=_COMPRESSION[compression])
        with self._guard():
            self._writer.start(profile=PROFILE, library=library)
        self._chunk_size = max(int(chunk_size), 1024)
        self._chunk_interval = float(chunk_interval)
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self._pending_bytes = 0
        self._pending_since: float | None = None
        self.message_count = 0
        self.chunk_count = 0
        self.closed = False
        self._directory_metadata = directory_metadata
        self.directory_metadata_error = ''
        self.add_metadata('rosbag2', rosbag2_metadata(self.path.name))

    @contextlib.contextmanager
    def _guard(self):
        """Turn a failed write into ``BagWriteError``, and refuse writes after one: the
        mcap writer's state is unknown once a record went out in part."""
        if self.error is not None:
            raise self.error
        try:
            yield
        except OSError as err:
            self.error = BagWriteError(self.path, err)
            if self._file is not None and not self._file.closed:
                self._file.close()
            raise self.error from None

    @property
    def bytes_written(self) -> int:
        return self._file.tell()

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        with self._guard():
            self._writer.add_metadata(name, {str(k): str(v) for k, v in data.items()})

    def add_schema(self, type_name: str, definition: str | None = None) -> int:
        type_name = normalize_type_name(type_name)
        if type_name not in self._schemas:
            text = message_definition(type_name) if definition is None else definition
            with self._guard():
                self._schemas[type_name] = self._writer.register_schema(
                    name=type_name, encoding=SCHEMA_ENCODING, data=text.encode())
        return self._schemas[type_name]

    def add_channel(self, topic: str, type_name: str, offered_qos_profiles: str = '',
                    type_hash: str = '', definition: str | None = None) -> int:
        """Channel id of ``topic`` (created on first use)."""
        if topic in self._channels:
            return self._channels[topic]
        schema_id = self.add_schema(type_name, definition)
        metadata = {'offered_qos_profiles': offered_qos_profiles, 'topic_type_hash': type_hash}
        with self._guard():
            channel_id = self._writer.register_channel(
                topic=topic, message_encoding=MESSAGE_ENCODING, schema_id=schema_id,
                metadata=metadata)
        self._channels[topic] = channel_id
        self._sequence[channel_id] = 0
        return channel_id

    def write(self, channel_id: int, data: bytes, log_time: int, publish_time: int,
              sequence: int | None = None) -> None:
        if sequence is None:
            self._sequence[channel_id] += 1
            sequence = self._sequence[channel_id]
        with self._guard():
            self._writer.add_message(channel_id=channel_id, log_time=max(int(log_time), 0),
                                     data=data, publish_time=max(int(publish_time), 0),
                                     sequence=sequence & 0xFFFFFFFF)
        self.message_count += 1
        self._pending_bytes += len(data) + 31   # + the message record's own fields
        if self._pending_since is None:
            self._pending_since = time.monotonic()
        if self._pending_bytes >= self._chunk_size:
            self.flush()
        else:
            self.poll()

    def poll(self) -> None:
        """Close the open chunk if it is older than ``chunk_interval``."""
        if (self._pending_since is not None
                and time.monotonic() - self._pending_since >= self._chunk_interval):
            self.flush()

    def flush(self) -> None:
        """Close the open chunk and write it out."""
        if self._pending_since is None:
            return
        with self._guard():
            self._writer.flush()
        self.chunk_count += 1
        self._pending_bytes = 0
        self._pending_since = None

    def close(self) -> None:
        """Write the last chunk, the indexes and the summary; close the file."""
        if self.closed:
            return
        self.closed = True
        if self.error is not None:      # no summary on a failed file; recovery reads it
            self._file.close()
            return
        with self._guard():
            self._writer.finish()
        self._file.close()
        if self._directory_metadata:
            try:
                write_directory_metadata(self.path.parent)
            except (OSError, yaml.YAMLError) as err:  # the bag itself is complete
                self.directory_metadata_error = str(err)


# ----------------------------------------------------------------------------- recovery

@dataclass
class RecoveryReport:
    messages: int = 0
    chunks: int = 0
    channels: int = 0
    metadata: int = 0
    truncated_bytes: int = 0
    had_footer: bool = False
    reason: str = ''


_RECORD_TYPES = {
    Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel, Opcode.MESSAGE: Message,
    Opcode.CHUNK: Chunk, Opcode.METADATA: Metadata, Opcode.FOOTER: Footer}


def _iter_records_tolerant(stream, report: RecoveryReport):
    """Records of a possibly truncated mcap file, stopping at the first incomplete or corrupt
    one. Chunks are yielded whole; other record kinds than those recovered are skipped."""
    if stream.read(8) != MCAP_MAGIC:
        raise McapError('not an mcap file (bad magic)')
    offset = 8
    size = os.fstat(stream.fileno()).st_size
    while True:
        head = stream.read(9)
        if len(head) < 9:
            report.reason = 'end of data' if not head else 'truncated record header'
            report.truncated_bytes = size - offset
            return
        opcode, length = head[0], int.from_bytes(head[1:], 'little')
        if length > size - offset - 9:
            report.reason = f'truncated record (opcode 0x{opcode:02x})'
            report.truncated_bytes = size - offset
            return
        body = stream.read(length)
        record_type = _RECORD_TYPES.get(opcode)
        if record_type is not None:
            data = ReadDataStream(io.BytesIO(body))
            try:
                if record_type is Message:
                    record = Message.read(data, length)
                else:
                    record = record_type.read(data)
            except Exception as err:  # a bad record ends the usable data
                report.reason = f'corrupt record (opcode 0x{opcode:02x}): {err}'
                report.truncated_bytes = size - offset
                return
            yield record
            if record_type is Footer:
                report.had_footer = True
                report.reason = 'complete file'
                return
        offset += 9 + length


def recover(src: str | Path, dst: str | Path, *, compression: str = 'zstd') -> RecoveryReport:
    """Copy every intact record of ``src`` (e.g. a recorder killed with SIGKILL) into a new,
    complete bag ``dst``: schemas, channels, metadata and the messages of all intact chunks
    (and unchunked messages), with their original times and sequence numbers."""
    report = RecoveryReport()
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    channel_map: dict[int, int] = {}
    writer = BagWriter(dst, compression=compression, library='replan_ros bag_recover',
                       chunk_interval=1e9)

    def take(record) -> None:
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            channels[record.id] = record
        elif isinstance(record, Message):
            if record.channel_id not in channel_map:
                channel = channels.get(record.channel_id)
                if channel is None:
                    return   # a message without its channel cannot be interpreted
                schema = schemas.get(channel.schema_id)
                type_name = schema.name if schema else 'unknown/msg/Unknown'
                channel_map[record.channel_id] = writer.add_channel(
                    channel.topic, type_name,
                    channel.metadata.get('offered_qos_profiles', ''),
                    channel.metadata.get('topic_type_hash', ''),
                    definition=schema.data.decode() if schema else '')
                report.channels += 1
            writer.write(channel_map[record.channel_id], record.data, record.log_time,
                         record.publish_time, sequence=record.sequence)
            report.messages += 1

    try:
        with open(src, 'rb') as stream:
            for record in _iter_records_tolerant(stream, report):
                if isinstance(record, Chunk):
                    try:
                        inner = breakup_chunk(record, validate_crc=True)
                    except Exception as err:
                        report.reason = f'corrupt chunk: {err}'
                        break
                    report.chunks += 1
                    for item in inner:
                        take(item)
                elif isinstance(record, Metadata):
                    if record.name != 'rosbag2':   # the writer adds its own
                        writer.add_metadata(record.name, dict(record.metadata))
                        report.metadata += 1
                else:
                    take(record)
    finally:
        writer.close()
    return report
