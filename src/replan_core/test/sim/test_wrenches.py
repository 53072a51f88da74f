"""The external wrench acting at a tick, decided in sim time."""

from replan_core.sim.wrenches import WrenchSchedule

MS = 1_000_000  # ns


def test_the_latest_due_wrench_acts_and_ties_keep_arrival_order():
    schedule = WrenchSchedule()
    schedule.add(8 * MS, [0.0, 150.0, 0.0], [0.0, 0.0, 0.0])
    schedule.add(4 * MS, [1.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    schedule.add(8 * MS, [0.0, 0.0, 0.0], [0.0, 0.0, 1.0])   # same stamp, later: wins
    assert schedule.due(0) is None and len(schedule) == 3
    force, _ = schedule.due(4 * MS)
    assert force.tolist() == [1.0, 0.0, 0.0]
    assert schedule.due(4 * MS) is None                       # taken once
    force, torque = schedule.due(12 * MS)                     # both of 8 ms due: the later
    assert force.tolist() == [0.0, 0.0, 0.0] and torque.tolist() == [0.0, 0.0, 1.0]
    assert len(schedule) == 0
