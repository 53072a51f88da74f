"""The set-point of a re-plan, decided in sim time."""

import numpy as np

from replan_core.gait.setpoints import GaitArbiter, SetpointArbiter

MS = 1_000_000  # ns


def test_no_setpoint_is_zero():
    value, source = SetpointArbiter(0.5).at(100 * MS)
    assert value.tolist() == [0.0, 0.0, 0.0] and source == 'none'


def test_stamped_setpoints_hold_from_their_stamp_in_stamp_order():
    arbiter = SetpointArbiter(0.5)
    arbiter.add_stamped(2000 * MS, [0.2, 0.0, 0.0])      # arrives first, later stamp
    arbiter.add_stamped(1000 * MS, [0.1, 0.0, 0.0])
    arbiter.add_stamped(1000 * MS, [0.15, 0.0, 0.0])     # same stamp, came later: wins
    assert arbiter.at(999 * MS)[1] == 'none'
    assert arbiter.at(1000 * MS)[1] == 'cmd_vel_stamped'
    assert arbiter.at(1500 * MS)[0].tolist() == [0.15, 0.0, 0.0]
    assert arbiter.at(2000 * MS)[0].tolist() == [0.2, 0.0, 0.0]
    # Stamped set-points never time out.
    assert arbiter.at(60_000 * MS)[0].tolist() == [0.2, 0.0, 0.0]


def test_live_setpoint_wins_when_newer_and_times_out_in_sim_time():
    arbiter = SetpointArbiter(0.5)
    arbiter.add_stamped(1000 * MS, [0.1, 0.0, 0.0])
    arbiter.set_live(np.array([0.0, 0.1, 0.0]), 1.2)
    value, source = arbiter.at(1300 * MS)
    assert value.tolist() == [0.0, 0.1, 0.0] and source == 'cmd_vel'
    assert arbiter.at(1690 * MS)[1] == 'cmd_vel'          # within 0.5 s of its arrival
    value, source = arbiter.at(1701 * MS)
    assert value.tolist() == [0.0, 0.0, 0.0] and source == 'cmd_vel timed out'
    arbiter.timeout = 5.0                                  # a run-time parameter change
    assert arbiter.at(1800 * MS)[1] == 'cmd_vel'
    # A stamped set-point newer than the live one takes over.
    arbiter.add_stamped(2000 * MS, [0.3, 0.0, 0.0])
    assert arbiter.at(2000 * MS)[1] == 'cmd_vel_stamped'


def test_a_returned_setpoint_is_a_copy():
    arbiter = SetpointArbiter(0.5)
    arbiter.add_stamped(0, [0.1, 0.0, 0.0])
    arbiter.at(0)[0][0] = 9.0
    assert arbiter.at(0)[0][0] == 0.1


def test_the_gait_in_force_is_the_last_requested_at_or_before_the_replan():
    arbiter = GaitArbiter('crawl')
    assert arbiter.at(0) == 'crawl'
    arbiter.add(2_000_000_000, 'trot')
    arbiter.add(5_000_000_000, 'crawl')
    arbiter.add(2_000_000_000, 'walking_trot')       # same stamp, came later: wins
    assert arbiter.at(1_999_999_999) == 'crawl'
    assert arbiter.at(2_000_000_000) == 'walking_trot'
    assert arbiter.at(4_000_000_000) == 'walking_trot'
    assert arbiter.at(6_000_000_000) == 'crawl'
