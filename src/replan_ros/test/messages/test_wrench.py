"""Wrenches through their message (one encoding for the sim, the push tool and scenarios)."""

from __future__ import annotations

import numpy as np
import pytest

from replan_ros.messages.wrench import wrench_from_msg, wrench_to_msg


def test_a_wrench_goes_through_its_message_unchanged():
    msg = wrench_to_msg(1_250_000_000, np.array([0.0, 150.0, -2.5]), np.array([1.0, 0.0, 3.0]))
    assert msg.header.frame_id == 'odom'
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1, 250_000_000)
    stamp, force, torque = wrench_from_msg(msg)
    assert stamp == 1_250_000_000
    assert force.tolist() == [0.0, 150.0, -2.5] and torque.tolist() == [1.0, 0.0, 3.0]
    assert wrench_from_msg(wrench_to_msg(0, (1, 2, 3)))[2].tolist() == [0.0, 0.0, 0.0]


def test_a_wrench_in_another_frame_or_not_finite_is_refused():
    msg = wrench_to_msg(0, (1.0, 0.0, 0.0))
    msg.header.frame_id = 'base_link'
    with pytest.raises(ValueError, match="frame 'base_link': only 'odom'"):
        wrench_from_msg(msg)
    msg.header.frame_id = ''                   # no frame: the world
    assert wrench_from_msg(msg)[1][0] == 1.0
    with pytest.raises(ValueError, match='non-finite'):
        wrench_from_msg(wrench_to_msg(0, (float('nan'), 0.0, 0.0)))
