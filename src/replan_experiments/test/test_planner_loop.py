"""planner_loop: the planner alone in a closed loop (footholds and the MPC, no graph)."""

from __future__ import annotations

import numpy as np
import pytest

from replan_experiments.planner_loop import cycle_velocities, main, trunk_offsets, walk

SIDEWAYS = [(0.5, np.array([0.0, 0.1, 0.0]))]


def test_the_walk_reaches_its_set_point_and_correction_shortens_the_first_cycle():
    """The planner alone walks at the set-point within three cycles; the foothold correction
    places the first strides about the hips after the walk-off, which the foot-relative
    placement (correction off) does not: docs/gait.md, "The way to a new speed"."""
    on = cycle_velocities(walk('hyq', 'realistic', SIDEWAYS, 14.0), 0.5)
    off = cycle_velocities(walk('hyq', 'realistic', SIDEWAYS, 14.0,
                                {'gait': {'foothold_correction': False}}), 0.5)
    for cycles in (on, off):
        assert len(cycles) >= 3
        assert cycles[2][1] == pytest.approx(0.1, abs=0.002)
        assert abs(cycles[2][0]) < 0.002 and abs(cycles[2][2]) < 1e-6
    assert on[0][1] < off[0][1] - 0.005


def test_without_the_correction_the_trunk_stays_beside_its_feet():
    """The paper's MPC (position term off) has no position target: walking off forward, the
    trunk drifts sideways in the first cycle and, with the footholds placed about the feet
    (correction off), stays there (9.8 cm measured); the foothold correction brings it back
    over them (1.5 cm)."""
    forward = [(0.5, np.array([0.15, 0.0, 0.0]))]
    paper = {'position_weight': 0.0, 'position_sway': 0.0}
    on = trunk_offsets(walk('hyq', 'realistic', forward, 14.0, {'mpc': paper}), 0.5)
    off = trunk_offsets(walk('hyq', 'realistic', forward, 14.0,
                             {'gait': {'foothold_correction': False}, 'mpc': paper}), 0.5)
    assert len(on) >= 3 and len(off) == len(on)
    assert abs(off[2][1]) > 0.05 and abs(off[3][1] - off[2][1]) < 0.005   # it stays
    assert abs(on[2][1]) < 0.03


def test_the_position_term_keeps_the_trunk_over_its_feet_without_the_correction():
    """``mpc.position_weight`` (on by default) gives the MPC the position target the paper's
    lacks: with the correction off, the forward walk's trunk stays within 2 cm of the centre
    of its feet instead of 9.8 cm, at the same speed."""
    forward = [(0.5, np.array([0.15, 0.0, 0.0]))]
    params = {'gait': {'foothold_correction': False}}
    log = walk('hyq', 'realistic', forward, 14.0, params)
    offsets = trunk_offsets(log, 0.5)
    assert len(offsets) >= 3
    assert all(abs(y) < 0.02 for _, y in offsets[1:])
    assert cycle_velocities(log, 0.5)[2][0] == pytest.approx(0.15, abs=0.002)


def test_trunk_offsets_of_a_known_walk():
    """A trunk heading along world +y with the centre of its feet at world -x from it: the
    centre is on the trunk's left, (0, +0.1) m in its body frame."""
    yaw = np.pi / 2
    log = [(float(k), np.array([0.0, k * 0.1]), yaw, np.array([-0.1, k * 0.1]))
           for k in range(9)]
    offsets = trunk_offsets(log, 0.0)
    assert len(offsets) == 2
    for x, y in offsets:
        assert x == pytest.approx(0.0, abs=1e-12) and y == pytest.approx(0.1)


def test_a_turning_walk_is_measured_in_the_body_frame():
    cycles = cycle_velocities(walk('hyq', 'realistic', [(0.5, np.array([0.1, 0.0, 0.15]))],
                                   14.0), 0.5)
    assert cycles[2][0] == pytest.approx(0.1, abs=0.01)
    assert cycles[2][2] == pytest.approx(0.15, abs=1e-3)


def test_a_base_apart_from_the_com_crabs_in_an_in_place_turn():
    """The paper's MPC (position term off), footholds laid out about a base 3.9 cm behind and
    1.5 cm right of the CoM (HyQ's CoM over its base in the standing pose): turning in place,
    the base crabs sideways over 1 cm/s on average (docs/gait.md, "Why the CoM
    offset"); with the base at the CoM every cycle moves it under 1 cm/s."""
    turn = [(0.5, np.array([0.0, 0.0, 0.2]))]
    paper = {'mpc': {'position_weight': 0.0, 'position_sway': 0.0}}
    at_com = cycle_velocities(walk('hyq', 'realistic', turn, 30.0, paper), 18.0)
    apart = cycle_velocities(walk('hyq', 'realistic', turn, 30.0, paper,
                                  base_offset=(0.039, 0.015)), 18.0)
    assert len(apart) >= 3 and len(at_com) == len(apart)
    assert all(np.hypot(c[0], c[1]) < 0.01 for c in at_com)           # under 1 cm/s
    assert np.mean([c[1] for c in apart]) < -0.01
    assert all(c[2] == pytest.approx(0.2, abs=1e-3) for c in apart)


def test_the_position_term_with_the_com_offset_turns_in_place_without_crabbing():
    """The same base apart from the CoM, the position term on: with ``mpc.com_offset`` the
    term's reference is where the CoM stands over its feet and the base stays under 0.5 cm/s
    in every cycle; with the offset taken as 0 (the reference the centre of the feet) the term
    pulls the CoM 4 cm back over the feet, and the base crabs over 1 cm/s."""
    turn = [(0.5, np.array([0.0, 0.0, 0.2]))]
    term = {'position_weight': 10000.0, 'position_sway': 0.5}
    known = cycle_velocities(walk('hyq', 'realistic', turn, 30.0, {'mpc': term},
                                  base_offset=(0.039, 0.015)), 18.0)
    unknown = cycle_velocities(walk('hyq', 'realistic', turn, 30.0,
                                    {'mpc': dict(term, com_offset=[0.0, 0.0])},
                                    base_offset=(0.039, 0.015)), 18.0)
    assert len(known) >= 3 and len(unknown) == len(known)
    assert all(np.hypot(c[0], c[1]) < 0.005 for c in known)
    assert np.mean([c[1] for c in unknown]) < -0.01


def test_cycle_velocities_of_a_known_arc():
    """A trunk on an arc of constant twist (0.1 m/s, 0.2 rad/s: 0.55 rad per 2.75 s cycle),
    logged at its touchdowns: the speed along the arc exactly, where one chord per cycle
    reads it 1.3 % low, and nothing across."""
    vx, wz, step = 0.1, 0.2, 2.75 / 4
    radius = vx / wz
    log = []
    for k in range(13):
        yaw = wz * step * k
        position = radius * np.array([np.sin(yaw), 1.0 - np.cos(yaw)])
        log.append((step * k, position, yaw, position))
    cycles = cycle_velocities(log, 0.0)
    assert len(cycles) == 3
    for cycle in cycles:
        assert cycle == pytest.approx([vx, 0.0, wz], abs=1e-12)


def test_a_misspelt_parameter_is_a_config_error(capsys):
    assert main(['--set', 'gait.foothold_corection=false', '--duration', '4']) == 2
    assert 'config error: planner_loop: unknown parameters' in capsys.readouterr().err
    assert main(['--set', 'foothold_correction', '--duration', '4']) == 2


@pytest.mark.parametrize('argv', [['--late', '-0.1'], ['--duration', '0']])
def test_a_negative_lateness_or_no_duration_is_refused(argv):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
