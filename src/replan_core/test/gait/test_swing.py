"""Swing-foot reference (swing.py)."""

import numpy as np
import pytest

from replan_core.gait.swing import ground_crossing_fraction, swing_trajectory

START = np.array([0.3, 0.2, 0.02])
TARGET = np.array([0.9, 0.25, 0.05])
T_LO, T_TD, H = 1.0, 1.5, 0.1


def ref(t):
    return swing_trajectory(START, TARGET, T_LO, T_TD, H, t)


def test_end_points_and_apex():
    p, v, a = ref(T_LO)
    np.testing.assert_allclose(p, START, atol=1e-12)
    np.testing.assert_allclose(v, 0.0, atol=1e-12)
    np.testing.assert_allclose(a, 0.0, atol=1e-12)
    p, v, a = ref(T_TD)
    np.testing.assert_allclose(p, TARGET, atol=1e-12)
    np.testing.assert_allclose(v, 0.0, atol=1e-12)
    p, v, _ = ref(0.5 * (T_LO + T_TD))
    assert p[2] == pytest.approx(max(START[2], TARGET[2]) + H)
    assert v[2] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(p[:2], 0.5 * (START[:2] + TARGET[:2]), atol=1e-12)


def test_outside_the_swing_holds_the_end_points():
    for t, expected in ((0.0, START), (T_LO - 1e-3, START), (T_TD + 1e-3, TARGET), (9.0, TARGET)):
        p, v, a = ref(t)
        np.testing.assert_allclose(p, expected, atol=1e-12)
        assert not v.any() and not a.any()
    p, v, _ = swing_trajectory(START, TARGET, 1.0, 1.0, H, 1.0)   # degenerate: at the target
    np.testing.assert_allclose(p, TARGET)


def test_continuous_and_consistent_derivatives():
    dt = 1e-5
    ts = np.arange(T_LO - 0.05, T_TD + 0.05, dt)
    samples = [ref(t) for t in ts]
    pos = np.array([s[0] for s in samples])
    vel = np.array([s[1] for s in samples])
    acc = np.array([s[2] for s in samples])
    # Finite differences agree with the analytic derivatives (so both are continuous).
    np.testing.assert_allclose(np.diff(pos, axis=0) / dt, 0.5 * (vel[1:] + vel[:-1]), atol=1e-5)
    np.testing.assert_allclose(np.diff(vel, axis=0) / dt, 0.5 * (acc[1:] + acc[:-1]), atol=1e-3)
    # No jumps in velocity or acceleration anywhere, the apex and the end points included.
    assert np.max(np.abs(np.diff(vel, axis=0))) < 1e-3
    assert np.max(np.abs(np.diff(acc, axis=0))) < 1e-2
    # Foot above both end points inside the swing, never below the lower one.
    inside = (ts > T_LO) & (ts < T_TD)
    assert np.all(pos[inside, 2] > min(START[2], TARGET[2]))


def test_apex_above_the_higher_end_when_stepping_down():
    p, _, _ = swing_trajectory(TARGET, START, 0.0, 0.6, 0.08, 0.3)
    assert p[2] == pytest.approx(TARGET[2] + 0.08)


@pytest.mark.parametrize('start_z, target_z', [(0.02, 0.02), (0.05, 0.02), (0.02, 0.06)])
def test_a_haptic_swing_is_over_its_foothold_when_it_meets_its_height(start_z, target_z):
    """Aimed ``depth`` below the foothold, the descent passes the foothold's height at
    ``ground_crossing_fraction``; the horizontal blend ended there is then at the foothold's
    x, y, at rest, and the height is the one the full blend gives."""
    height, depth, t_lo, t_td = 0.08, 0.015, 1.0, 1.5
    start = np.array([0.0, 0.0, start_z])
    aimed = np.array([0.2, -0.05, target_z - depth])
    fraction = ground_crossing_fraction(start_z, target_z, height, depth)
    assert 0.5 < fraction < 1.0
    t = t_lo + fraction * (t_td - t_lo)
    p, v, a = swing_trajectory(start, aimed, t_lo, t_td, height, t, horizontal_fraction=fraction)
    assert p[2] == pytest.approx(target_z, abs=1e-9)
    assert p[:2] == pytest.approx(aimed[:2], abs=1e-12)
    assert v[:2] == pytest.approx([0.0, 0.0], abs=1e-9)
    assert a[:2] == pytest.approx([0.0, 0.0], abs=1e-6)
    full, _, _ = swing_trajectory(start, aimed, t_lo, t_td, height, t)
    assert p[2] == full[2]
    assert full[0] < aimed[0] - 1e-3      # the whole-swing blend: still short of it there


def test_no_depth_crosses_at_the_touchdown_and_a_bad_fraction_is_refused():
    assert ground_crossing_fraction(0.02, 0.02, 0.08, 0.0) == 1.0
    with pytest.raises(ValueError, match='horizontal_fraction'):
        swing_trajectory(START, TARGET, T_LO, T_TD, H, 0.5 * (T_LO + T_TD), horizontal_fraction=0.0)
