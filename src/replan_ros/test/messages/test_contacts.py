"""contacts and contact_events tables: round trip, edges, and the hand-written CDR against
rclpy's serializer and decoder."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import PointCloud2
from wire_checks import STAMPS, same_bytes_as_rclpy, through_wire

from replan_core.common.types import ContactState
from replan_ros.messages.contacts import (
    _encode_table,
    contact_events_from_msg,
    contact_events_to_msg,
    contact_rows,
    contacts_from_cdr,
    contacts_from_msg,
    contacts_to_msg,
    encode_contact_events,
    encode_contacts,
)
from replan_ros.messages.stamps import ns_to_stamp


def _some_contacts():
    rng = np.random.default_rng(1)
    return ContactState(0.5, rng.normal(size=(4, 3)), rng.normal(size=(4, 3)),
                        np.array([True, True, False, True]),
                        np.array([False, True, False, False]),
                        np.array([False, False, True, False]))




def _contacts(t: float, touchdown, liftoff) -> ContactState:
    rng = np.random.default_rng(7)
    return ContactState(t, rng.normal(size=(4, 3)), rng.normal(size=(4, 3)),
                        np.array([True, False, True, True]), np.array(touchdown),
                        np.array(liftoff))


def test_contacts_table_round_trip_and_events():
    cs = _some_contacts()
    msg = through_wire(contacts_to_msg(cs))
    assert isinstance(msg, PointCloud2) and msg.width == 4
    assert [f.name for f in msg.fields][:3] == ['x', 'y', 'z']
    back = contacts_from_msg(msg)
    np.testing.assert_array_equal(back.foot_position, cs.foot_position)
    np.testing.assert_array_equal(back.force, cs.force)
    np.testing.assert_array_equal(back.contact, cs.contact)
    events = contact_events_from_msg(contact_events_to_msg(cs))
    assert [(leg, kind) for leg, kind, _, _ in events] == [(1, 'touchdown'), (2, 'liftoff')]
    cs.touchdown[:] = False
    cs.liftoff[:] = False
    assert contact_events_to_msg(cs) is None


@pytest.mark.parametrize('t', STAMPS)
def test_contact_tables_are_rclpys(t):
    cs = _contacts(t, [False, True, False, False], [False, False, False, True])
    same_bytes_as_rclpy(encode_contacts(cs), contacts_to_msg(cs), PointCloud2)
    same_bytes_as_rclpy(encode_contact_events(cs), contact_events_to_msg(cs),
                         PointCloud2)
    msg = contacts_to_msg(cs)
    msg.header.stamp = ns_to_stamp(123)
    same_bytes_as_rclpy(encode_contacts(cs, 123), msg, PointCloud2)
    quiet = _contacts(t, [False] * 4, [False] * 4)
    assert encode_contact_events(quiet) is None
    one = _contacts(t, [True, False, False, False], [False] * 4)
    same_bytes_as_rclpy(encode_contact_events(one), contact_events_to_msg(one),
                         PointCloud2)


@pytest.mark.parametrize('t', STAMPS)
def test_contacts_decode_as_the_generic_decoder(t):
    cs = _contacts(t, [False, True, False, False], [False, False, False, True])
    for data in (encode_contacts(cs), bytes(serialize_message(contacts_to_msg(cs)))):
        stamp_ns, fast = contacts_from_cdr(data)
        msg = deserialize_message(data, PointCloud2)
        generic = contacts_from_msg(msg)
        assert stamp_ns == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        assert fast.stamp == generic.stamp
        for name in ('foot_position', 'force', 'contact', 'touchdown', 'liftoff'):
            np.testing.assert_array_equal(getattr(fast, name), getattr(generic, name))
            assert getattr(fast, name).dtype == getattr(generic, name).dtype
    # Rows out of leg order (not ours, still a valid table): sorted as the generic decoder.
    shuffled = _encode_table(round(t * 1e9), contact_rows(cs, np.array([2, 0, 3, 1])))
    _, fast = contacts_from_cdr(shuffled)
    generic = contacts_from_msg(deserialize_message(shuffled, PointCloud2))
    for name in ('foot_position', 'force', 'contact', 'touchdown', 'liftoff'):
        np.testing.assert_array_equal(getattr(fast, name), getattr(generic, name))
    np.testing.assert_array_equal(fast.foot_position, cs.foot_position)
    events = encode_contact_events(cs)       # two rows: not a contacts table
    with pytest.raises(ValueError, match='one row per leg'):
        contacts_from_cdr(events)
    bad = _contacts(t, [False] * 4, [False] * 4)
    bad.force[2, 1] = math.nan
    with pytest.raises(ValueError, match='non-finite fy'):
        contacts_from_cdr(encode_contacts(bad))
    with pytest.raises(ValueError, match='cannot deserialize'):
        contacts_from_cdr(encode_contacts(cs)[:50])
