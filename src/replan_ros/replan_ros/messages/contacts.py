"""contacts and contact_events: the feet (position, force, contact and its edges) as a PointCloud2
table, as an rclpy message and as the lock-step's hand-written CDR.

Each message family has one module holding its rclpy conversion and, where the graph needs speed,
its hand-written CDR codec beside it (docs/ARCHITECTURE.md, "Packages: the map").
"""

from __future__ import annotations

import struct

import numpy as np
from sensor_msgs.msg import PointCloud2

from replan_core.common.types import WORLD_FRAME, ContactState
from replan_ros.messages.cdr import (
    ENCAPSULATION,
    NS,
    CdrStrings,
    CdrWriter,
    all_finite,
    deserialize_or_raise,
    pad_to,
    stamp_pair,
)
from replan_ros.messages.clouds import cloud_to_table, point_fields, require_finite, table_to_cloud
from replan_ros.messages.stamps import header, stamp_to_sec

CONTACT_DTYPE = np.dtype([('x', '<f8'), ('y', '<f8'), ('z', '<f8'), ('leg', 'u1'),
                          ('fx', '<f8'), ('fy', '<f8'), ('fz', '<f8'), ('contact', 'u1'),
                          ('touchdown', 'u1'), ('liftoff', 'u1')])


def contact_rows(cs: ContactState, rows: np.ndarray) -> np.ndarray:
    """The contact table's rows ``rows`` (legs) of ``cs``; shared with the hand-written codec."""
    table = np.zeros(len(rows), dtype=CONTACT_DTYPE)
    position, force = np.asarray(cs.foot_position)[rows], np.asarray(cs.force)[rows]
    table['x'], table['y'], table['z'] = position[:, 0], position[:, 1], position[:, 2]
    table['leg'] = rows
    table['fx'], table['fy'], table['fz'] = force[:, 0], force[:, 1], force[:, 2]
    table['contact'] = np.asarray(cs.contact)[rows]
    table['touchdown'] = np.asarray(cs.touchdown)[rows]
    table['liftoff'] = np.asarray(cs.liftoff)[rows]
    return table


def contacts_to_msg(cs: ContactState) -> PointCloud2:
    return table_to_cloud(header(cs.stamp), contact_rows(cs, np.arange(4)))


def contact_events_to_msg(cs: ContactState) -> PointCloud2 | None:
    """Rows of the feet whose contact flag changed at this tick; None if none did."""
    rows = np.flatnonzero(np.asarray(cs.touchdown) | np.asarray(cs.liftoff))
    if len(rows) == 0:
        return None
    return table_to_cloud(header(cs.stamp), contact_rows(cs, rows))


def contacts_from_msg(msg: PointCloud2) -> ContactState:
    return contacts_from_table(stamp_to_sec(msg.header.stamp),
                               cloud_to_table(msg, CONTACT_DTYPE.names))


def contacts_from_table(stamp: float, table: np.ndarray) -> ContactState:
    """``contacts_from_msg`` of an unpacked table; shared with the hand-written codec."""
    if len(table) != 4 or sorted(table['leg']) != [0, 1, 2, 3]:
        raise ValueError(f'contacts table must have one row per leg, got legs {list(table["leg"])}')
    require_finite(table, ('x', 'y', 'z', 'fx', 'fy', 'fz'), 'contacts')
    table = table[np.argsort(table['leg'])]
    return ContactState(
        stamp=stamp,
        foot_position=np.stack([table['x'], table['y'], table['z']], axis=1).astype(float),
        force=np.stack([table['fx'], table['fy'], table['fz']], axis=1).astype(float),
        contact=table['contact'].astype(bool), touchdown=table['touchdown'].astype(bool),
        liftoff=table['liftoff'].astype(bool))


def contact_events_from_msg(msg: PointCloud2) -> list[tuple[int, str, np.ndarray, np.ndarray]]:
    """Events as (leg, 'touchdown' | 'liftoff', position (3,), force (3,))."""
    table = cloud_to_table(msg, CONTACT_DTYPE.names)
    if np.any(table['leg'] > 3):
        raise ValueError('contact_events table names a leg outside 0..3')
    events = []
    for row in table:
        kind = 'touchdown' if row['touchdown'] else 'liftoff'
        events.append((int(row['leg']), kind, np.array([row['x'], row['y'], row['z']]),
                       np.array([row['fx'], row['fy'], row['fz']])))
    return events


def _fields_bytes(dtype: np.dtype) -> bytes:
    """The ``fields`` sequence of a table from a 4-aligned offset (it ends 4-aligned)."""
    w = CdrWriter()
    fields = point_fields(dtype)
    w.u32(len(fields))
    for field in fields:
        w.string(field.name)
        w.u32(field.offset)
        w.buf.append(field.datatype)
        w.u32(field.count)
    return bytes(w.buf[4:])


_CONTACT_FRAME = CdrStrings(8, WORLD_FRAME)


_CONTACT_HEADER = struct.Struct(f'<iI{_CONTACT_FRAME.fmt}{pad_to(_CONTACT_FRAME.end, 4)}xII')


_CONTACT_FIELDS = _fields_bytes(CONTACT_DTYPE)


_CLOUD_STEPS = struct.Struct('<3xIII')        # (is_bigendian before), point_step, row_step,
#                                               the data's length


def _encode_table(stamp_ns: int, table: np.ndarray) -> bytes:
    data = table.tobytes()
    step = table.dtype.itemsize
    out = bytearray(ENCAPSULATION)
    out += _CONTACT_HEADER.pack(*stamp_pair(stamp_ns), *_CONTACT_FRAME.values, 1, len(table))
    out += _CONTACT_FIELDS
    out.append(0)                                   # is_bigendian
    out += _CLOUD_STEPS.pack(step, step * len(table), len(data))
    out += data
    out.append(1)                                   # is_dense
    return bytes(out)


_CONTACT_TABLE_AT = struct.calcsize(_CONTACT_HEADER.format) + len(_CONTACT_FIELDS) + 16


_CONTACT_STEPS = struct.Struct('<BxxxIII')


# The four rows of our table, legs in order: x y z leg fx fy fz contact touchdown liftoff each.
_CONTACT_ROWS = struct.Struct('<' + '3dB3d3B' * 4)


_LEGS_IN_ORDER = (0, 1, 2, 3)


def contacts_from_cdr(data: bytes) -> tuple[int, ContactState]:
    """(stamp ns, contacts) of a serialized contacts table; ``ValueError`` as
    ``contacts_from_msg`` gives it. Only our layout (frame, fields, little endian)
    is read here; any other goes to rclpy's decoder."""
    try:
        if bytes(data[:2]) != ENCAPSULATION[:2] or len(data) < 4 + _CONTACT_TABLE_AT:
            raise ValueError
        header = _CONTACT_HEADER.unpack_from(data, 4)
        start = 4 + _CONTACT_HEADER.size
        if (header[2:-2] != _CONTACT_FRAME.values or header[-2] != 1
                or bytes(data[start:start + len(_CONTACT_FIELDS)]) != _CONTACT_FIELDS):
            raise ValueError
        big, step, _, size = _CONTACT_STEPS.unpack_from(data, start + len(_CONTACT_FIELDS))
        width = header[-1]
        if big or step != CONTACT_DTYPE.itemsize or size != width * step:
            raise ValueError
        sec, nanosec = header[0], header[1]
        if width == 4:
            # The table as the sim and controller send it: plain Python, a quarter of
            # contacts_from_table's numpy time; anything else (legs out of order, a
            # non-finite value: its error message) goes there.
            values = _CONTACT_ROWS.unpack_from(data, 4 + _CONTACT_TABLE_AT)
            rows = [values[k:k + 10] for k in range(0, 40, 10)]
            if (values[3::10] == _LEGS_IN_ORDER
                    and all_finite(tuple(v for row in rows for v in (*row[:3], *row[4:7])))):
                return sec * NS + nanosec, ContactState(
                    stamp=sec + nanosec * 1e-9,
                    foot_position=np.array([row[:3] for row in rows]),
                    force=np.array([row[4:7] for row in rows]),
                    contact=np.array([row[7] for row in rows], dtype=bool),
                    touchdown=np.array([row[8] for row in rows], dtype=bool),
                    liftoff=np.array([row[9] for row in rows], dtype=bool))
        table = np.frombuffer(data, dtype=CONTACT_DTYPE, count=width,
                              offset=4 + _CONTACT_TABLE_AT)
    except (ValueError, struct.error):
        msg = deserialize_or_raise(data, PointCloud2)
        stamp = msg.header.stamp
        return stamp.sec * NS + stamp.nanosec, contacts_from_msg(msg)
    return sec * NS + nanosec, contacts_from_table(sec + nanosec * 1e-9, table)


def encode_contacts(cs: ContactState, stamp_ns: int | None = None) -> bytes:
    """``contacts_to_msg(cs)`` serialized, stamped ``stamp_ns`` if given."""
    if stamp_ns is None:
        stamp_ns = round(cs.stamp * 1e9)
    return _encode_table(stamp_ns, contact_rows(cs, np.arange(4)))


def encode_contact_events(cs: ContactState, stamp_ns: int | None = None) -> bytes | None:
    """``contact_events_to_msg(cs)`` serialized; None if no flag changed."""
    rows = np.flatnonzero(np.asarray(cs.touchdown) | np.asarray(cs.liftoff))
    if len(rows) == 0:
        return None
    if stamp_ns is None:
        stamp_ns = round(cs.stamp * 1e9)
    return _encode_table(stamp_ns, contact_rows(cs, rows))
