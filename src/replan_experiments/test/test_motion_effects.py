"""motion_effects: how the trunk travels between its footholds, from known states."""

from __future__ import annotations

import math

import numpy as np
import pytest

from replan_core.common.types import BaseState, ContactState
from replan_experiments.motion_effects import cached_motion_effects, motion_from_states

FEET = np.array([[0.4, 0.3, 0.0], [0.4, -0.3, 0.0], [-0.4, 0.3, 0.0], [-0.4, -0.3, 0.0]])
DT = 0.01          # s between states
CYCLE = 3.0        # s: one leg swings for 0.5 s of each 0.75 s step


def crawl(speed_of, yaw: float = 0.0, duration: float = 12.0, stride: float = 0.3):
    """A crawl of known timing: in each 0.75 s step the four feet stand for 0.25 s, then leg
    (step number mod 4) swings for 0.5 s and lands ``stride`` m further along the heading.
    The trunk moves along the heading at ``speed_of(t, swinging)`` m/s."""
    heading = np.array([math.cos(yaw), math.sin(yaw)])
    quat = np.array([0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])
    base, contacts = {}, {}
    feet = FEET.copy()
    along = 0.0
    was_down = np.ones(4, bool)
    for k in range(round(duration / DT) + 1):
        t = round(k * DT, 6)
        step, into = divmod(t, CYCLE / 4)
        leg = int(step) % 4
        down = np.ones(4, bool)
        if into >= 0.25 - 1e-9:
            down[leg] = False
        touchdown = down & ~was_down
        for landed in np.flatnonzero(touchdown):
            feet[landed, :2] += stride * heading
        was_down = down
        if k:
            along += speed_of(t, not down.all()) * DT
        position = np.array([*(along * heading), 0.55])
        base[t] = BaseState(t, position, quat, np.zeros(3), np.zeros(3))
        contacts[t] = ContactState(t, feet.copy(), np.zeros((4, 3)), down, touchdown,
                                   np.zeros(4, bool))
    return base, contacts


def test_a_trunk_that_keeps_its_speed_makes_the_swings_share_of_its_travel():
    base, contacts = crawl(lambda t, swinging: 0.1, yaw=0.7)
    out = motion_from_states(base, contacts, 3.0, 12.0, (1.0, 0.0))
    assert out['swing_time_share'] == pytest.approx(2 / 3, abs=0.01)
    assert out['swing_travel_share'] == pytest.approx(out['swing_time_share'], abs=1e-6)
    assert out['backward_travel_m'] == pytest.approx(0.0, abs=1e-9)
    assert out['progress_m'] == pytest.approx(0.9, abs=1e-6)
    assert out['stride_length_m'] == pytest.approx(0.3)


def test_a_trunk_that_stops_while_a_leg_swings_and_steps_back_is_measured_so():
    # Moves at 0.3 m/s with four feet down, 0.02 m/s back while a leg swings.
    base, contacts = crawl(lambda t, swinging: -0.02 if swinging else 0.3)
    out = motion_from_states(base, contacts, 3.0, 12.0)
    forward, back = 0.3 * 9.0 / 3, 0.02 * 9.0 * 2 / 3
    assert out['progress_m'] == pytest.approx(forward - back, abs=0.01)
    assert out['backward_travel_m'] == pytest.approx(back, abs=0.005)
    assert out['swing_travel_share'] == pytest.approx(-back / (forward - back), abs=0.01)


def test_the_direction_is_the_set_points_in_the_body_frame():
    # Walking along the body's y (sideways) at 0.1 m/s, heading 0.7 rad: progress along
    # body x is none; along body y it is the walk.
    base, contacts = crawl(lambda t, swinging: 0.1, yaw=0.7 + math.pi / 2)
    yaw_only = {t: BaseState(t, b.position, np.array([0.0, 0.0, math.sin(0.35),
                                                     math.cos(0.35)]), b.linear_velocity,
                             b.angular_velocity) for t, b in base.items()}
    assert motion_from_states(yaw_only, contacts, 3.0, 12.0, (1.0, 0.0)) is None
    sideways = motion_from_states(yaw_only, contacts, 3.0, 12.0, (0.0, 2.0))
    assert sideways['progress_m'] == pytest.approx(0.9, abs=1e-6)


def test_no_states_or_no_bag_give_none(tmp_path):
    base, contacts = crawl(lambda t, swinging: 0.1, duration=2.0)
    assert motion_from_states(base, contacts, 5.0, 9.0) is None
    assert motion_from_states(base, contacts, 0.0, 2.0, (0.0, 0.0)) is None
    assert cached_motion_effects(tmp_path, 0.0, 2.0) is None
