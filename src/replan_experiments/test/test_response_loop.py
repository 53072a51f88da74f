"""response_loop: the robots page's response runs through the gait's and the MPC's cores."""

from __future__ import annotations

import numpy as np
import pytest

from replan_core.common.types import LEGS
from replan_experiments.planner_loop import run_values
from replan_experiments.response_loop import (
    first_swing,
    loop_run,
    main,
    speed_along,
    steady_cycle_travel,
    step_excess,
    tally,
)

FORWARD = [(0.5, np.array([0.05, 0.0, 0.0]))]


def test_the_gait_core_walks_the_crawl_at_the_set_point_on_the_plan():
    """Go1 told 0.05 m/s forward at 0.5 s: it stands until then, walks its crawl sequence one
    leg at a time, each foot landing `late` after its plan, and gets to the set-point, ticking
    at the sim's control period."""
    touchdowns, times, bases, yaws, _ = loop_run('go1', 'realistic', FORWARD, 12.0,
                                                 late=0.04)
    tick = float(run_values('go1', 'realistic')[0]['sim']['control_period'])
    assert np.diff(times) == pytest.approx(np.full(len(times) - 1, tick))
    assert times[-1] == pytest.approx(12.0)
    assert touchdowns[0][0] > 0.5                         # still until told
    legs = [leg for _, leg in touchdowns]
    order = [LEGS.index(name) for name in ('lh', 'lf', 'rh', 'rf')]
    assert legs == [order[k % 4] for k in range(len(legs))]
    # The last whole cycle of lh (from one of its touchdowns to its next): at the set-point.
    lh = [t for t, leg in touchdowns if leg == order[0]]
    i0, i1 = np.searchsorted(times, lh[-2]), np.searchsorted(times, lh[-1])
    speed = (bases[i1] - bases[i0]) / (times[i1] - times[i0])
    assert speed[0] == pytest.approx(0.05, rel=0.03) and abs(speed[1]) < 0.002
    assert np.all(yaws == 0.0)


def test_the_later_touchdown_stretches_the_step_period():
    """Feet landing 60 ms after their plan: the steps follow one another that much later
    (the re-plan times the next steps from the actual touchdown)."""
    on_time = loop_run('go1', 'realistic', FORWARD, 8.0, late=0.0)[0]
    late = loop_run('go1', 'realistic', FORWARD, 8.0, late=0.06)[0]
    period = [np.median(np.diff([t for t, _ in run])[2:]) for run in (on_time, late)]
    assert period[1] - period[0] == pytest.approx(0.06, abs=0.005)


def test_a_wrong_setting_or_phase_is_one_line(capsys):
    assert main(['--robot', 'go1', '--set', 'gait.no_such_key=1']) == 2
    assert 'unknown parameters' in capsys.readouterr().err
    assert main(['--robot', 'go1', '--phase', '9']) == 2
    assert 'response phase 9 is not one of' in capsys.readouterr().err


def test_step_excess_is_each_steps_travel_against_the_steady_step_at_its_phase():
    """A trunk at 0.1 m/s sideways with a sway of the 4 s cycle that falls 2 cm behind in the
    first step after the change at 0.5 s and makes it up in the third."""
    times = np.arange(0.0, 24.0, 0.004)
    sway = 0.03 * np.sin(2 * np.pi * times / 4.0)
    lag = -0.02 * np.clip(times - 1.0, 0.0, 1.0) + 0.02 * np.clip(times - 3.0, 0.0, 1.0)
    bases = np.column_stack([np.zeros_like(times), 0.1 * times + sway + lag])
    touchdowns = [(float(k), k % 4) for k in range(24)]
    excess = step_excess(touchdowns, times, bases, 0.5, [0.0, 0.1])
    assert [t for t, _ in excess] == pytest.approx([0.5, 1.5, 2.5, 3.5])
    assert [dx for _, dx in excess] == pytest.approx([-0.02, 0.0, 0.02, 0.0], abs=1e-9)
    # At 1.252 s (a tick) the trunk walks 0.1 m/s, less the lag's 0.02 m/s, plus the sway's.
    expected = 0.1 - 0.02 + 0.03 * 2 * np.pi / 4.0 * np.cos(2 * np.pi * 1.252 / 4.0)
    assert speed_along(times, bases, 1.252, [0.0, 1.0]) == pytest.approx(expected, abs=1e-5)


def test_the_steady_cycle_and_the_first_steps_swinging_leg():
    """The trunk of the step_excess test: its steady cycle (4 steps, 3 cycles on) travels
    0.4 m; the first step after 0.5 s ends with leg 2's touchdown, whose foot stands ahead of
    the base along the set-point (+y) in one layout and behind it in the other."""
    times = np.arange(0.0, 24.0, 0.004)
    bases = np.column_stack([np.zeros_like(times), 0.1 * times])
    touchdowns = [(float(k), k % 4) for k in range(24)]
    assert steady_cycle_travel(touchdowns, times, bases, 0.5, [0.0, 0.1]) == \
        pytest.approx(0.4)
    assert steady_cycle_travel(touchdowns, times, bases, 20.5, [0.0, 0.1]) is None
    feet = np.array([[0.3, 0.2], [0.3, -0.2], [-0.3, 0.2], [-0.3, -0.2]])
    assert first_swing(touchdowns, 0.5, feet, [0.0, 0.1]) == (LEGS[2], 'leading')
    assert first_swing(touchdowns, 0.5, feet, [0.0, -0.1]) == (LEGS[2], 'trailing')


def test_the_tally_counts_cells_by_the_pages_rule_and_with_the_first_cycle_short():
    """A first cycle off alone is allowed in the second count; a later one or an overshoot
    fails both."""
    verdicts = [('forward', []), ('lateral', ['first']), ('lateral', ['first', 'overshoot']),
                ('forward', ['later']), ('lateral', ['no whole cycle'])]
    assert tally(verdicts) == (
        "cells met by the page's rule: forward 1 of 2, lateral 0 of 3; with the first "
        "cycle's shortfall allowed (from the second cycle within 5 %, none over 105 %): "
        "forward 1 of 2, lateral 1 of 3")
