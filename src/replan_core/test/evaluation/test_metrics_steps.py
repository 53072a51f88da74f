"""Stance intervals and executed steps for the gait diagram (replan_core.evaluation.metrics)."""

import numpy as np

from replan_core.evaluation.metrics import executed_steps, flag_intervals, touchdown_timing


def test_flag_intervals():
    times = np.arange(8) * 0.1
    assert np.allclose(flag_intervals(times, [1, 1, 0, 0, 1, 0, 1, 1]),
                       [(0.0, 0.2), (0.4, 0.5), (0.6, 0.7)])
    assert flag_intervals(times, np.zeros(8)) == []
    assert flag_intervals(times[:0], []) == []


def test_executed_steps_follow_touchdown_timing():
    # Two plans: the first one's second step is superseded (it lifts off after plan 2).
    planned = [(0.0, 2, 0.25, 0.75), (0.0, 0, 1.0, 1.5),
               (0.8, 0, 1.05, 1.55), (0.8, 3, 1.8, 2.3)]
    touchdowns = [(0.6, 2), (0.72, 2), (1.6, 0), (5.0, 3)]   # rh never touches in time
    steps = executed_steps(touchdowns, planned)
    assert steps == [(2, 0.25, 0.75, 0.6), (0, 1.05, 1.55, 1.6), (3, 1.8, 2.3, None)]
    errors, actual = touchdown_timing(touchdowns, planned)
    matched = [(a, a - td) for _, _, td, a in steps if a is not None]
    assert np.allclose(actual, [a for a, _ in matched])
    assert np.allclose(errors, [e for _, e in matched])


def test_no_plans_means_no_executed_steps():
    """A run whose controller died before the first plan: nothing to match, no error."""
    from replan_core.evaluation.metrics import executed_steps, touchdown_timing
    assert executed_steps([(1.0, 0)], []) == []
    errors, times = touchdown_timing([(1.0, 0)], [])
    assert len(errors) == 0 and len(times) == 0
