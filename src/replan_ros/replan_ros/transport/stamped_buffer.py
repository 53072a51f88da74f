"""Serialized messages kept by header stamp and decoded only when asked for.

A node that needs the state of one tick now and then (the gait and mpc nodes at a re-plan) but
receives every tick would otherwise deserialize 250 messages a second per topic in Python;
storing the CDR bytes and parsing only the stamp (a fixed offset after the encapsulation header)
costs a fraction of that.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from typing import Generic, TypeVar

from rclpy.serialization import deserialize_message

T = TypeVar('T')


def cdr_byte_order(cdr: bytes) -> str:
    """'little' or 'big': the byte order of a serialized payload, from its encapsulation
    identifier (bytes 0-1, big endian). The identifiers of DDS-XTYPES 1.3 (CDR_BE 0, CDR_LE 1,
    PL_CDR_BE 2, PL_CDR_LE 3, CDR2_BE 6, CDR2_LE 7, D_CDR2_BE 8, D_CDR2_LE 9, PL_CDR2_BE 10,
    PL_CDR2_LE 11) come in pairs whose odd member is the little-endian one."""
    return 'little' if cdr[1] & 1 else 'big'


def cdr_header_stamp_ns(cdr: bytes) -> int | None:
    """``header.stamp`` (ns) of a CDR payload whose first field is a std_msgs/Header."""
    if len(cdr) < 12:
        return None
    order = cdr_byte_order(cdr)
    sec = int.from_bytes(cdr[4:8], order, signed=True)
    nanosec = int.from_bytes(cdr[8:12], order, signed=False)
    return sec * 1_000_000_000 + nanosec


class RawStampedBuffer(Generic[T]):
    """The last ``capacity`` serialized messages of one topic, by header stamp (ns)."""

    def __init__(self, msg_type: type, decode: Callable[[object], T], capacity: int) -> None:
        self._msg_type = msg_type
        self._decode = decode
        self._capacity = max(int(capacity), 1)
        self._raw: OrderedDict[int, bytes] = OrderedDict()

    def add(self, cdr: bytes) -> int | None:
        """Keep one serialized message; returns its stamp (None if it has no readable one)."""
        ns = cdr_header_stamp_ns(cdr)
        if ns is None:
            return None
        self._raw[ns] = cdr
        self._raw.move_to_end(ns)
        while len(self._raw) > self._capacity:
            self._raw.popitem(last=False)
        return ns

    def __contains__(self, ns: int) -> bool:
        return ns in self._raw

    def __len__(self) -> int:
        return len(self._raw)

    def stamps(self) -> list[int]:
        return list(self._raw)

    def get(self, ns: int) -> T | None:
        """The decoded message of stamp ``ns``, None if not held. A message that fails to
        decode (``decode`` raises ValueError) is dropped and the error re-raised."""
        cdr = self._raw.get(ns)
        if cdr is None:
            return None
        try:
            return self._decode(deserialize_message(cdr, self._msg_type))
        except ValueError:
            del self._raw[ns]
            raise
