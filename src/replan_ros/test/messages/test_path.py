"""nav_msgs/Path: the hand-written CDR is rclpy's bytes."""

from __future__ import annotations

import numpy as np
import pytest
from nav_msgs.msg import Path
from rclpy.serialization import deserialize_message, serialize_message

from replan_ros.messages.path import encode_path, path_msg
from replan_ros.messages.stamps import sec_to_stamp, stamp_to_ns


@pytest.mark.parametrize('frame_id', ['odom', 'abcdefg', ''])
@pytest.mark.parametrize('width', [2, 3])
def test_path_bytes_are_rclpys(frame_id, width):
    rng = np.random.default_rng(width)
    points = rng.normal(size=(201, width))
    start = 3.3300000001
    msg = path_msg(start, 0.04, points, frame_id)
    msg.header.stamp = sec_to_stamp(start)
    data = encode_path(stamp_to_ns(msg.header.stamp), start, 0.04, points, frame_id)
    assert len(data) == len(serialize_message(msg))
    assert deserialize_message(data, Path) == msg
