"""push_effects: what a sustained push does to the support, from known states."""

from __future__ import annotations

import numpy as np
import pytest

from replan_core.common.types import BaseState, ContactState
from replan_experiments.push_effects import cached_push_effects, effects_from_states

FEET = np.array([[0.4, 0.3, 0.0], [0.4, -0.3, 0.0], [-0.4, 0.3, 0.0], [-0.4, -0.3, 0.0]])
QUAT = np.array([0.0, 0.0, 0.0, 1.0])       # x y z w: yaw 0


def states(shift_of, contact_of=lambda t: (1, 1, 1, 1), velocity_of=lambda t: (0.0, 0.0)):
    """A robot standing at the origin, 0.55 m high, its trunk moved sideways by shift_of(t)."""
    base, contacts = {}, {}
    for k in range(0, 1001):
        t = round(k * 0.01, 6)
        position = np.array([0.0, shift_of(t), 0.55])
        velocity = np.array([*velocity_of(t), 0.0])
        base[t] = BaseState(t, position, QUAT, velocity, np.zeros(3))
        contacts[t] = ContactState(t, FEET.copy(), np.zeros((4, 3)),
                                   np.array(contact_of(t), bool), np.zeros(4, bool),
                                   np.zeros(4, bool))
    return base, contacts


def test_a_trunk_moved_over_its_feet_is_measured_in_the_body_frame():
    base, contacts = states(lambda t: 0.12 if 4.0 <= t < 6.0 else 0.0)
    out = effects_from_states(base, contacts, push_start=3.0, push_duration=1.0, horizon=3.0)
    assert out['trunk_shift_max_m'] == pytest.approx(0.12)
    # Inside the rectangle of the four feet: 0.3 m from the sides, 0.18 m when moved.
    assert out['com_margin_min_m'] == pytest.approx(0.18)
    assert out['capture_margin_min_m'] == pytest.approx(0.18)
    # The feet stayed where they were, so each moved 0.12 m about the trunk for 2 of 4 s...
    # on the side it moved to (closer) and away from the other: |y| changes by 0.12 either way.
    assert out['foot_offset_change_m'] == pytest.approx(0.12 * 200 / 401, abs=1e-3)


def test_the_capture_point_leads_the_base_by_its_velocity_over_omega():
    # Moving left at 0.5 m/s on three feet (lf lifted): omega = sqrt(9.81 / 0.55).
    base, contacts = states(lambda t: 0.0, contact_of=lambda t: (0, 1, 1, 1),
                            velocity_of=lambda t: (0.0, 0.5))
    out = effects_from_states(base, contacts, 3.0, 1.0, 3.0)
    lead = 0.5 / np.sqrt(9.81 / 0.55)
    # Triangle rf (0.4, -0.3), lh (-0.4, 0.3), rh (-0.4, -0.3): its hypotenuse passes through
    # the origin; the capture point (0, lead) is outside by lead * cos(atan(0.6 / 0.8)).
    assert out['capture_margin_min_m'] == pytest.approx(-lead * 0.8, abs=1e-4)
    assert out['com_margin_min_m'] == pytest.approx(0.0, abs=1e-9)


def test_a_window_the_bag_does_not_cover_gives_none(tmp_path):
    base, contacts = states(lambda t: 0.0)
    assert effects_from_states(base, contacts, 9.0, 1.0, 3.0) is None       # ends at 10 s
    assert effects_from_states({}, {}, 3.0, 1.0, 3.0) is None
    assert cached_push_effects(tmp_path, 3.0, 1.0) is None                  # no bag
