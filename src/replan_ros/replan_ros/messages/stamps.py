"""Time in messages: stamps and durations to and from seconds and nanoseconds, headers.

Each message family has one module holding its rclpy conversion and, where the graph needs speed,
its hand-written CDR codec beside it (docs/ARCHITECTURE.md, "Packages: the map").
"""

from __future__ import annotations

from builtin_interfaces.msg import Duration, Time
from std_msgs.msg import Header

from replan_core.common.types import WORLD_FRAME


def stamp_to_sec(stamp: Time) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def stamp_to_ns(stamp: Time) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def sec_to_ns(t: float) -> int:
    return round(t * 1e9)


def ns_to_sec(ns: int) -> float:
    """The float seconds of a stamp of ``ns`` ns, as every decoder gives the core (the same
    float as ``stamp_to_sec(ns_to_stamp(ns))``), without building a message."""
    sec, nanosec = divmod(ns, 1_000_000_000)
    return sec + nanosec * 1e-9


def ns_to_stamp(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def sec_to_stamp(t: float) -> Time:
    return ns_to_stamp(sec_to_ns(t))


def sec_to_duration(t: float) -> Duration:
    ns = sec_to_ns(t)
    return Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def duration_to_sec(d: Duration) -> float:
    return d.sec + d.nanosec * 1e-9


def header(t: float, frame_id: str = WORLD_FRAME) -> Header:
    return Header(stamp=sec_to_stamp(t), frame_id=frame_id)
