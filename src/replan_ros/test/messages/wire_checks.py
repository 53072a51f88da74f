"""Checks shared by the message tests: a message through rclpy's serializer and back, and
hand-written CDR compared with rclpy's bytes."""

from __future__ import annotations

from rclpy.serialization import deserialize_message, serialize_message

# s: stamps that exercise the sec / nanosec split (zero, one tick, a run's length, a large one)
STAMPS = [0.0, 0.004, 12.348, 1234.567891234]


def through_wire(msg):
    """``msg`` serialized and deserialized by rclpy, as a subscriber receives it."""
    return deserialize_message(serialize_message(msg), type(msg))


def same_bytes_as_rclpy(data: bytes, msg, msg_type) -> None:
    """``data`` is rclpy's serialization of ``msg`` but for the padding (rclpy leaves it
    unwritten, ours is zero) and some bytes rclpy leaves after empty sequences, and rclpy
    decodes it into ``msg``."""
    theirs = bytes(serialize_message(msg))
    assert len(theirs) - 8 <= len(data) <= len(theirs)
    assert all(ours in (their, 0) for ours, their in zip(data, theirs, strict=False))
    assert deserialize_message(data, msg_type) == msg
