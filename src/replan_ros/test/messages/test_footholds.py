"""footholds: a plan through its table and back."""

from __future__ import annotations

import numpy as np
import pytest
from wire_checks import through_wire

from replan_core.common.types import FootholdPlan, Step
from replan_ros.messages.footholds import footholds_from_msg, footholds_to_msg


def test_footholds_round_trip():
    feet = np.array([[0.37, 0.3, 0.0], [0.37, -0.3, 0.0], [-0.37, 0.3, 0.0], [-0.37, -0.3, 0.0]])
    steps = [Step(leg, 10.2 + i, 10.7 + i, feet[leg] + [0.1, 0, 0], 0.1, i % 2 == 0, i == 0,
                  0.05 * i) for i, leg in enumerate([2, 0, 3, 1])]
    plan = FootholdPlan(10.0, feet, 0.0, steps, min_swing_fraction=0.4, max_extension=0.25)
    back = footholds_from_msg(through_wire(footholds_to_msg(plan)))
    assert (back.min_swing_fraction, back.max_extension) == (0.4, 0.25)
    assert back.start_time == pytest.approx(10.0)
    np.testing.assert_array_equal(back.initial_feet, feet)
    assert [s.leg for s in back.steps] == [2, 0, 3, 1]
    for a, b in zip(back.steps, steps, strict=True):
        assert a.liftoff_time == pytest.approx(b.liftoff_time, abs=1e-12)
        assert a.touchdown_time == pytest.approx(b.touchdown_time, abs=1e-12)
        assert (a.haptic, a.replan) == (b.haptic, b.replan)
        np.testing.assert_array_equal(a.target, b.target)
