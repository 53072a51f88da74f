"""CDR (XCDR1, little endian) written and read by hand, byte for byte what rclpy's serializer
writes: the pieces each message family's fast codec is built from (unit tests compare with
rclpy's serializer and decoder).

Why by hand. Every tick the sim publishes ``imu``, ``joint_states`` (and, to a reader, the
truth), the controller decodes them, publishes ``joint_torque_cmd`` and its estimate (``odom``,
``contacts``), and the sim decodes the command: all on the lock-step chain or beside it. Each
message through rclpy's Python classes costs a Python object per field both ways: 12-27 us
per message to build and serialize or to decode, against 1-7 us by hand, on an idle core
(``python -m replan_experiments.benchmarks.bench_msgs``); in the running graph the difference
was worth about a fifth of the real-time factor (docs/ARCHITECTURE.md, "Per-tick budget"). A
re-plan's ``com_plan`` (201 points over 8 s) is about 1800 Python message objects: building and
serializing it took the mpc node 4.6 ms and deserializing it took the controller 4.4 ms,
against a 2 ms solve (docs/ARCHITECTURE.md, "Re-plan path").

The layouts are fixed (our joint names in ``JOINT_NAMES`` order, our frames), so each message is
one ``struct`` pack or unpack. A decoder returns ``None`` for any other layout (another joint
order, a frame it does not know, another byte order, a truncated payload); the ``*_from_cdr``
functions then use rclpy's generic decoder (``deserialize_or_raise``), so a message from another
tool is still read, with the same checks and error messages as its rclpy conversion.
"""

from __future__ import annotations

import math
import struct

import numpy as np
from rclpy.serialization import deserialize_message

NS = 1_000_000_000


STAMP = struct.Struct('<iI')


def pad_to(pos: int, n: int) -> int:
    return -pos % n


class CdrStrings:
    """Constant strings and string sequences (a str, or a tuple of str) from body offset
    ``pos``: their struct format, with ``x`` for CDR's padding (zero when written, skipped
    when read: rclpy does not zero it), the values it packs, and the offset after them."""

    def __init__(self, pos: int, *parts) -> None:
        fmt, values = [], []

        def align4() -> None:
            nonlocal pos
            if pad_to(pos, 4):
                fmt.append(f'{pad_to(pos, 4)}x')
                pos += pad_to(pos, 4)

        for part in parts:
            texts = (part,) if isinstance(part, str) else part
            if not isinstance(part, str):
                align4()
                fmt.append('I')
                values.append(len(texts))
                pos += 4
            for text in texts:
                data = text.encode() + b'\x00'
                align4()
                fmt.append(f'I{len(data)}s')
                values += [len(data), data]
                pos += 4 + len(data)
        self.fmt = ''.join(fmt)
        self.values = tuple(values)
        self.end = pos


def double_sequences(pos: int, counts: tuple[int, ...]) -> tuple[str, int]:
    """The struct format of sequences of ``counts`` doubles from body offset ``pos``."""
    fmt = ''
    for count in counts:
        if pad_to(pos, 4):
            fmt += f'{pad_to(pos, 4)}x'
            pos += pad_to(pos, 4)
        fmt += 'I'
        pos += 4
        if count:
            if pad_to(pos, 8):
                fmt += f'{pad_to(pos, 8)}x'
                pos += pad_to(pos, 8)
            fmt += f'{count}d'
            pos += 8 * count
    return fmt, pos


def stamp_pair(ns: int) -> tuple[int, int]:
    sec, nanosec = divmod(int(ns), NS)
    return sec, nanosec


def all_finite(values: tuple[float, ...]) -> bool:
    # A sum is finite when every term is, short of an overflow (then numpy decides): one
    # call instead of numpy's per-array overhead, several us per tick.
    return math.isfinite(sum(values)) or bool(np.all(np.isfinite(values)))


def deserialize_or_raise(data: bytes, msg_type: type):
    try:
        return deserialize_message(data, msg_type)
    except Exception as err:       # rclpy raises its own error types on bad CDR
        raise ValueError(f'cannot deserialize {msg_type.__name__}: {err}') from err


ENCAPSULATION = b'\x00\x01\x00\x00'        # CDR, little endian, no options


_U32 = struct.Struct('<I')


_TIME = struct.Struct('<iI')                 # builtin_interfaces Time / Duration: sec, nanosec


class CdrWriter:
    """Appends CDR fields; alignment is relative to the end of the encapsulation header."""

    def __init__(self) -> None:
        self.buf = bytearray(ENCAPSULATION)

    def align(self, n: int) -> None:
        self.buf.extend(b'\x00' * (-(len(self.buf) - 4) % n))

    def u32(self, value: int) -> None:
        self.align(4)
        self.buf.extend(_U32.pack(value))

    def time(self, ns: int) -> None:
        """A builtin_interfaces Time or Duration of ``ns`` nanoseconds."""
        self.align(4)
        self.buf.extend(_TIME.pack(*divmod(int(ns), NS)))

    def string(self, text: str) -> None:
        data = text.encode() + b'\x00'
        self.u32(len(data))
        self.buf.extend(data)

    def header(self, stamp_ns: int, frame_id: str) -> None:
        self.time(stamp_ns)
        self.string(frame_id)

    def packed(self, fmt: struct.Struct, alignment: int, *values) -> None:
        self.align(alignment)
        self.buf.extend(fmt.pack(*values))

    def bytes(self) -> bytes:
        return bytes(self.buf)


class CdrReader:
    """Reads what ``CdrWriter`` writes; raises ``ValueError`` past the end."""

    def __init__(self, data: bytes) -> None:
        if bytes(data[:2]) != ENCAPSULATION[:2]:
            raise ValueError('not little-endian CDR')
        self.data = memoryview(data)
        self.pos = 4

    def align(self, n: int) -> None:
        self.pos += -(self.pos - 4) % n

    def unpack(self, fmt: struct.Struct, alignment: int = 4) -> tuple:
        self.align(alignment)
        if self.pos + fmt.size > len(self.data):
            raise ValueError('truncated CDR')
        values = fmt.unpack_from(self.data, self.pos)
        self.pos += fmt.size
        return values

    def u32(self) -> int:
        return self.unpack(_U32)[0]

    def time(self) -> tuple[int, int]:
        """(sec, nanosec) of a builtin_interfaces Time or Duration."""
        return self.unpack(_TIME)

    def string(self) -> str:
        size = self.u32()
        if size < 1 or self.pos + size > len(self.data):
            raise ValueError('bad CDR string')
        text = bytes(self.data[self.pos:self.pos + size - 1]).decode()
        self.pos += size
        return text
