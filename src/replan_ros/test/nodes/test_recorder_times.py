"""The recorder's log times: a message's arrival placed between two takes' clock readings."""

from __future__ import annotations

from itertools import pairwise

from replan_ros.nodes.recorder_node import arrival_time

SIM = 1_000_000_000          # ns


def test_arrival_is_placed_linearly_between_the_takes():
    previous, take = (10_000, 4 * SIM), (10_400, 5 * SIM)       # 400 ns wall, 1 s sim
    assert arrival_time(10_100, previous, take) == 4 * SIM + SIM // 4
    assert arrival_time(10_400, previous, take) == 5 * SIM
    # Arrived before the previous take (taken late) or stamped after this one: clamped.
    assert arrival_time(9_000, previous, take) == 4 * SIM
    assert arrival_time(11_000, previous, take) == 5 * SIM


def test_first_take_no_reception_time_or_no_wall_progress_give_the_take_time():
    take = (10_400, 5 * SIM)
    assert arrival_time(10_100, None, take) == 5 * SIM
    assert arrival_time(0, (10_000, 4 * SIM), take) == 5 * SIM
    assert arrival_time(10_100, (10_400, 4 * SIM), take) == 5 * SIM


def test_log_times_never_decrease_over_takes_in_reception_order():
    takes = [(1_000 * k, 20_000_000 * (k // 3)) for k in range(1, 12)]   # sim clock steps
    times = []
    for previous, take in pairwise(takes):
        for received in range(previous[0] - 200, take[0] + 1, 50):
            times.append(arrival_time(received, previous, take))
    assert times == sorted(times)
    assert times[0] == takes[0][1] and times[-1] == takes[-1][1]
